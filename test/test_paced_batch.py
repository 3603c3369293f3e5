"""Batches that grow with the pace (ros/flow.py: PacedSource.paced_batch).

rclpy costs about 120 us of CPU a message in every node that takes it, so a source at x50 in
500-sample batches sent 1,000 messages a second a topic and the five-node graph spent its
cores on message overhead. Above max_batches_per_s a message carries a whole multiple of
batch_size instead, at least four batches within the flow window.
"""

import numpy as np
import pytest
from rclpy.node import Node
from rig_graph import params, wait_for

from fmm_interfaces.msg import SampleBatch
from fmm_ros.constants import FORCE_TOPIC
from fmm_ros.ros.flow import MAX_BATCHES_PARAM, PacedSource
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.qos import SAMPLE_QOS

CONFIG = dict(max_batches_per_s=100.0, flow_window_s=4.0)


@pytest.mark.parametrize(
    ('rate_factor', 'batch_size', 'expected'),
    [
        (1.0, 500, 500),  # real time: 20 messages a second
        (5.0, 500, 500),  # 100 a second: at the cap
        (5.5, 500, 1000),  # just over: two batch sizes a message
        (50.0, 500, 5000),
        (100.0, 1000, 10_000),
        (1000.0, 500, 10_000),  # four of them fill the 4 s flow window: no larger
        (0.1, 500, 500),
    ],
)
def test_a_message_carries_a_whole_multiple_of_batch_size(rate_factor, batch_size, expected):
    size = PacedSource.paced_batch(CONFIG, 10_000.0, batch_size, rate_factor)
    assert size == expected and size % batch_size == 0
    assert 10_000.0 * rate_factor / size <= 100.0 or 4 * size == 40_000


def test_the_default_cap_leaves_four_batches_in_the_window_at_any_pace():
    config = dict(CONFIG, max_batches_per_s=MAX_BATCHES_PARAM.default)
    assert PacedSource.paced_batch(config, 10_000.0, 500, 1.0) == 500  # real time
    for rate_factor in (50.0, 100.0, 1000.0):
        size = PacedSource.paced_batch(config, 10_000.0, 500, rate_factor)
        assert 4 * size <= 40_000  # flow_window_s 4 s of signal


def test_zero_keeps_batch_size_at_any_pace():
    assert PacedSource.paced_batch(dict(CONFIG, max_batches_per_s=0.0), 1e4, 500, 100.0) == 500


class Sizes(Node):
    """Records the size and first index of every force batch."""

    def __init__(self, **kwargs):
        super().__init__('sizes', **kwargs)
        self.batches: list[tuple[int, int]] = []
        self.create_subscription(SampleBatch, FORCE_TOPIC, self._take, SAMPLE_QOS)

    def _take(self, msg: SampleBatch) -> None:
        samples = np.frombuffer(msg.samples, dtype=float) if len(msg.samples) else []
        self.batches.append((msg.first_sample_index, len(samples)))


@pytest.mark.ros
@pytest.mark.slow
@pytest.mark.parametrize(('cap', 'expected'), [(100.0, 10_000), (0.0, 1000)])
def test_hammer_sim_sizes_its_batches_to_the_pace(ros_graph, cap, expected):
    sizes = ros_graph.add(Sizes)
    ros_graph.add(
        HammerSim,
        parameter_overrides=params(
            rate_factor=100.0,
            batch_size=1000,
            max_batches_per_s=cap,
            wait_for_consumers=[''],  # a batch before the match may be lost: not counted
            hits_per_level=1,
            hit_spacing_s=2.0,
        ),
    )
    ros_graph.start()
    assert wait_for(lambda: len(sizes.batches) >= 3)
    (first, _), *_ = batches = sizes.batches[:3]
    assert batches == [(first + k * expected, expected) for k in range(3)]
    assert first % expected == 0
