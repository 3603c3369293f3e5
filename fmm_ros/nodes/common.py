"""What every fmm_ros node shares: QoS profiles, topic names and the `ros2 run` entry point."""

from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

FORCE_TOPIC = '/fmm/force'
VELOCITY_TOPIC = '/fmm/velocity'
APPLIED_FORCE_TOPIC = '/fmm/sim/applied_force'
IMPACTS_TOPIC = '/fmm/impacts'
FRF_TOPIC = '/fmm/frf'
FIT_SERVICE = '/fmm/fit_friction'
DIAGNOSE_SERVICE = '/fmm/diagnose_model'

# Sample batches: every one matters (a lost batch is a gap in an FRF record), and a subscriber
# may lag a burst of them, so RELIABLE with a deep queue.
SAMPLE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)

# Results: a late subscriber (a plot, the fitter started later) still gets the latest ones.
RESULT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


def run_node(node_factory: Callable[[], Node], args: list[str] | None = None) -> None:
    """Init, spin until Ctrl-C or shutdown, destroy the node, shut down (for ros2 run)."""
    rclpy.init(args=args)
    node = None
    try:
        node = node_factory()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
