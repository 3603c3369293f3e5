"""The live simulated rig, in-process: every hit reported, gaps flagged, bad parameters refused."""

import threading
import time

import pytest
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter

from fmm_interfaces.msg import FrfSummary, ImpactResult, SampleBatch
from fmm_ros.nodes.analyzer import Analyzer
from fmm_ros.nodes.common import (
    FRF_TOPIC,
    IMPACTS_TOPIC,
    RESULT_QOS,
    SAMPLE_QOS,
    VELOCITY_TOPIC,
)
from fmm_ros.nodes.hammer_sim import HammerSim
from fmm_ros.nodes.rig_sim import RigSim
from fmm_ros.ros_graph import InProcessGraph


def params(**values):
    return [Parameter(name, value=value) for name, value in values.items()]


# A short, fast session: 1 hit a level, 6 s records 8 s apart, 100x real time.
FAST_HAMMER = dict(rate_factor=100.0, batch_size=1000, hits_per_level=1, hit_spacing_s=8.0,
                   first_hit_s=1.0)
FAST_ANALYZER = dict(window_s=6.0)


class _Listener(Node):
    """Collects what the analyzer publishes."""

    def __init__(self, **kwargs):
        super().__init__('listener', **kwargs)
        self.impacts: list[ImpactResult] = []
        self.summaries: list[FrfSummary] = []
        self.create_subscription(ImpactResult, IMPACTS_TOPIC, self.impacts.append, RESULT_QOS)
        self.create_subscription(FrfSummary, FRF_TOPIC, self.summaries.append, RESULT_QOS)


class _LossyLink(Node):
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


def test_every_hit_of_a_session_is_reported_and_judged(ros_graph):
    hammer = ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
    ros_graph.add(RigSim)
    analyzer = ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    listener = ros_graph.add(_Listener)
    ros_graph.start()
    assert wait_for(lambda: len(listener.impacts) == 3), f'{len(listener.impacts)} of 3 reported'
    assert hammer.hits_sent == 3 == analyzer.impacts_reported
    assert [(m.level, m.accepted, list(m.flags)) for m in listener.impacts] == [
        ('low', True, []), ('medium', True, []), ('high', True, [])]
    impulses = [m.impulse_n_s for m in listener.impacts]
    assert impulses == sorted(impulses) and 0.8 < impulses[0] < 1.1
    assert all(abs(m.natural_frequency_hz - 2.2) < 0.15 for m in listener.impacts)
    assert wait_for(lambda: {s.level for s in listener.summaries} == {'low', 'medium', 'high'})
    last = listener.summaries[-1]
    assert last.linearity_levels == 3 and last.linearity_r2 > 0.95


def test_a_dropped_batch_flags_the_impact_as_gap_instead_of_a_wrong_frf(ros_graph):
    ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER | dict(hits_per_level=1)))
    ros_graph.add(RigSim, parameter_overrides=params(output_topic='/test/velocity'))
    link = ros_graph.add(_LossyLink, drop_first_indices=[30_000])   # 3.0 s: inside hit 1
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    listener = ros_graph.add(_Listener)
    ros_graph.start()
    assert wait_for(lambda: len(listener.impacts) == 3)
    assert link.dropped == 1
    assert [(list(m.flags), m.accepted) for m in listener.impacts] == [
        (['gap'], False), ([], True), ([], True)]


@pytest.mark.parametrize(('node', 'overrides', 'reason'), [
    (HammerSim, dict(rate_factor=5000.0), 'out of range'),
    (HammerSim, dict(level_peak_forces_n=[450.0, -1.0, 1450.0]), 'outside'),
    (RigSim, dict(integrator='rk45'), 'not one of'),
    (RigSim, dict(mu=-0.1), 'out of range'),
    (Analyzer, dict(reject_flags=['gap', 'wobbly']), 'unknown flag'),
    (Analyzer, dict(trigger_level_n=5.0, rearm_level_n=5.0), 'rearm_level_n'),
])
def test_out_of_range_parameters_are_refused_with_the_reason(ros_graph, node, overrides, reason):
    with pytest.raises((InvalidParameterValueException, ValueError), match=reason):
        ros_graph.add(node, parameter_overrides=params(**overrides))


def test_rig_sim_rejects_unknown_model_terms_naming_them(ros_graph):
    with pytest.raises(ValueError, match="unknown model term 'wobble'"):
        ros_graph.add(RigSim, parameter_overrides=params(effects=['wobble']))


def test_clean_start_and_shutdown_leaves_no_threads():
    before = set(threading.enumerate())
    with InProcessGraph() as graph:
        graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
        graph.add(RigSim)
        graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
        graph.start()
        time.sleep(0.5)
    leaked = [t for t in threading.enumerate() if t not in before and t.is_alive()]
    assert not leaked, f'threads left running: {leaked}'
    assert not graph.context.ok()
