"""Every QoS profile of the fmm_ros graph, in one place (ARCHITECTURE.md, Conventions).

Sample batches are RELIABLE and KEEP_ALL (a lost batch is a gap in an FRF record): a reader
behind a burst keeps what it has not taken yet instead of overwriting it, and when its queue
is full it stops acknowledging, so a KEEP_ALL writer blocks (back-pressure) rather than the
reader dropping (docs/explanation/reliability.md has the contract for sources);
viewers that no source waits for take them KEEP_LAST, so a slow viewer never holds the
acquisition back;
results are transient-local, so a late subscriber (a plot, a fitter started later) still gets
the latest; the flow-control reports keep the last one per consumer for sources that start
later; /diagnostics is plain reliable, as the ROS tools expect; /clock keeps only the newest
time; the recorder asks for the
strongest QoS every publisher of a topic can serve (`recording_qos`).
"""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from fmm_ros.constants import SAMPLE_TOPIC_QOS

SAMPLE_QUEUE_BATCHES = 5000
"""Batches a KEEP_ALL sample reader (and writer) holds at most: Fast DDS's default resource
limit (`max_samples`), which rclpy cannot set. Measured on this middleware: a reader that
takes nothing holds 5,000 batches, the writer 5,000 more, then `publish` blocks 100 ms
(`max_blocking_time`) and raises. So a consumer's queue of one topic is bounded by
5,000 x batch size x 8 bytes: 4 MB in 100-sample batches, 20 MB in 500, 200 MB in 5,000."""

SAMPLE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL if SAMPLE_TOPIC_QOS.keep_all else HistoryPolicy.KEEP_LAST,
    depth=SAMPLE_TOPIC_QOS.depth,
    reliability=ReliabilityPolicy.RELIABLE
    if SAMPLE_TOPIC_QOS.reliable
    else ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.TRANSIENT_LOCAL
    if SAMPLE_TOPIC_QOS.transient_local
    else DurabilityPolicy.VOLATILE,
)
"""Sample batches: every one matters, and a subscriber may lag a burst of them (declared
ROS-free as `constants.SAMPLE_TOPIC_QOS`, so a bag's metadata records the same profile).

KEEP_ALL ignores depth; the flow window (`flow.PacedSource.window_samples`) still counts
half of it, so the graph's own sources never have more than 50 batches in flight."""

VIEW_SAMPLE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""Sample batches for a viewer (live, station) that no source waits for: a viewer behind a
burst loses its oldest batches rather than blocking the sources' KEEP_ALL writers."""

DISPLAY_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=2000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""Display points (the live topics): one number a message, so each batch arrives as a burst of them
(20 at 50 points/s from a 4,000-sample batch, more when a source makes up a stall). At
SAMPLE_QOS's depth of 100 a viewer's subscription lost 80 % of them at x20, the hits' peaks
among them; 2,000 points (under 0.2 MB) is two seconds of both channels at x20."""

RESULT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Results (impacts, FRFs, mu): a late subscriber still gets the latest ones."""

IMPACT_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=100,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Impacts: the analyzer keeps its last 100 for late subscribers, so a fitter or a station
killed and respawned hears every hit of a session again (and holds it again, or names it as
one whose samples it never got). About 25 kB a message with its FRF: 2.5 MB at most per
writer and reader. Compatible with RESULT_QOS readers (depth is not matched)."""

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

DECISION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10_000,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""Decisions about hits: every one matters to a late subscriber (a fitter restarted
mid-session must know every hit the operator rejected), so all are kept for it."""

SESSION_INFO_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
"""The session's metadata: only the newest entry counts, kept for late subscribers."""

DIAGNOSTICS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
"""/diagnostics, as rqt_robot_monitor and Foxglove subscribe to it."""

CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
"""/clock from a source: reliable, so best-effort subscribers (rclpy's and rclcpp's
TimeSource) and reliable ones (the recorder) both match; depth 1, only the newest time counts."""

CLOCK_SUBSCRIPTION_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.BEST_EFFORT
)
"""What a consumer of /clock asks for (`timebase.SignalClock`): matches any publisher."""

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
