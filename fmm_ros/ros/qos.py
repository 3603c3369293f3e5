"""Every QoS profile of the fmm_ros graph, in one place (ARCHITECTURE.md, Conventions).

Sample batches are RELIABLE with a deep queue (a lost batch is a gap in an FRF record);
results are transient-local, so a late subscriber (a plot, a fitter started later) still gets
the latest; the flow-control reports keep the last one per consumer for sources that start
later; /diagnostics is plain reliable, as the ROS tools expect; the recorder asks for the
strongest QoS every publisher of a topic can serve (`recording_qos`).
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

SAMPLE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""Sample batches: every one matters, and a subscriber may lag a burst of them."""

RESULT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Results (impacts, FRFs, mu): a late subscriber still gets the latest ones."""

PROGRESS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""A consumer's progress reports: its last one kept for sources that start later."""

PROGRESS_LISTEN_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""A source's queue of progress reports: deep, since depth counts per topic, not per writer,
and one consumer's reports must not push another's out before the source takes them."""

DIAGNOSTICS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
"""/diagnostics, as rqt_robot_monitor and Foxglove subscribe to it."""

RECORDING_DEPTH = 1000
"""Queue of the recorder's subscriptions (as ros2 bag record)."""


def recording_qos(offered: list[QoSProfile]) -> QoSProfile:
    """The strongest QoS every publisher can serve, with a deep queue (as ros2 bag record)."""
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    durable = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        depth=RECORDING_DEPTH,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
    )
