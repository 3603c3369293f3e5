"""Helpers for in-process graph tests: fast session settings, listeners, a lossy link."""

import time

from rclpy.node import Node
from rclpy.parameter import Parameter

from fmm_interfaces.msg import FrfSummary, FrictionEstimate, ImpactResult, SampleBatch
from fmm_ros.constants import FRF_TOPIC, FRICTION_TOPIC, IMPACTS_TOPIC, VELOCITY_TOPIC
from fmm_ros.ros.qos import RESULT_QOS, SAMPLE_QOS


def params(**values):
    return [Parameter(name, value=value) for name, value in values.items()]


# A short, fast session: 1 hit a level, 6 s records 8 s apart, 100x real time.
FAST_HAMMER = dict(
    rate_factor=100.0, batch_size=1000, hits_per_level=1, hit_spacing_s=8.0, first_hit_s=1.0
)
FAST_ANALYZER = dict(window_s=6.0)


class Listener(Node):
    """Collects what the analyzer and the fitter publish."""

    def __init__(self, **kwargs):
        super().__init__('listener', **kwargs)
        self.impacts: list[ImpactResult] = []
        self.summaries: list[FrfSummary] = []
        self.friction: list[FrictionEstimate] = []
        self.create_subscription(ImpactResult, IMPACTS_TOPIC, self.impacts.append, RESULT_QOS)
        self.create_subscription(FrfSummary, FRF_TOPIC, self.summaries.append, RESULT_QOS)
        self.create_subscription(FrictionEstimate, FRICTION_TOPIC, self.friction.append, RESULT_QOS)


class LossyLink(Node):
    """Forwards velocity batches like a network that loses the ones listed."""

    def __init__(self, drop_first_indices, **kwargs):
        super().__init__('lossy_link', **kwargs)
        self.drop = set(drop_first_indices)
        self.dropped = 0
        self._out = self.create_publisher(SampleBatch, VELOCITY_TOPIC, SAMPLE_QOS)
        self.create_subscription(SampleBatch, '/test/velocity', self._forward, SAMPLE_QOS)

    def _forward(self, msg):
        if msg.first_sample_index in self.drop:
            self.dropped += 1
        else:
            self._out.publish(msg)


def wait_for(condition, timeout_s=60.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True
