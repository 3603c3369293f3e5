"""The live node: a session's force as stamped points a plot can draw, every hit at its height."""

import time

import numpy as np
import pytest
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rig_graph import FAST_HAMMER, params, wait_for

from fmm_interfaces.msg import DisplayPoint, SampleBatch
from fmm_ros.constants import FORCE_TOPIC, LIVE_TOPICS
from fmm_ros.ros import msgs
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.live import Live
from fmm_ros.ros.qos import SAMPLE_QOS

pytestmark = [pytest.mark.ros, pytest.mark.slow]
REAL_TIME_X10 = dict(rate_factor=10.0)


class Collector(Node):
    """Keeps the force batches and the live force points."""

    def __init__(self, **kwargs):
        super().__init__('collector', **kwargs)
        self.batches: list[SampleBatch] = []
        self.points: list[DisplayPoint] = []
        self.create_subscription(SampleBatch, FORCE_TOPIC, self.batches.append, SAMPLE_QOS)
        deep = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)
        self.create_subscription(DisplayPoint, LIVE_TOPICS['force'], self.points.append, deep)


def test_live_points_keep_every_hit_and_are_stamped_in_signal_time(ros_graph):
    # x10: 500 points a wall second, which one executor spinning every node keeps up with.
    hammer = ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER | REAL_TIME_X10))
    ros_graph.add(Live, parameter_overrides=params(points_per_s=50.0))
    collector = ros_graph.add(Collector)
    ros_graph.start()
    assert wait_for(lambda: hammer.schedule_done, 30.0)
    hammer.hold()
    time.sleep(0.2)  # a batch under way when held still goes out
    end = hammer.next_index
    assert wait_for(
        lambda: collector.points and collector.points[-1].first_sample_index == end - 200
    )
    points = list(collector.points)
    assert [p.first_sample_index for p in points] == list(range(0, end, 200))
    values = np.array([p.value for p in points])
    force = np.concatenate([msgs.batch_samples(b) for b in collector.batches])
    # Each hit's peak, as the 10 kHz samples have it, is a point's value: none is lost.
    for hit in hammer.schedule:
        start = int(hit.start_index)
        peak = force[start : start + 200].max()
        assert peak in values and peak > 400.0
    first_stamp = msgs.stamp_ns(collector.batches[0].header.stamp)
    stamps = np.array([msgs.stamp_ns(p.header.stamp) for p in points])
    assert np.array_equal(stamps - first_stamp, np.arange(len(points)) * 20_000_000)
    assert {(p.quantity, p.unit, p.header.frame_id) for p in points} == {('force', 'N', 'hammer')}
