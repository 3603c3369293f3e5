"""The live simulated rig, in-process: every hit reported, gaps flagged, bad parameters refused."""

import threading
import time

import pytest
from rclpy.exceptions import InvalidParameterValueException
from rclpy.node import Node
from rig_graph import FAST_ANALYZER, FAST_HAMMER, Listener, LossyLink, params, wait_for

from fmm_ros.core import _threads
from fmm_ros.ros.graph import (
    PRIVATE_DOMAIN_IDS,
    InProcessGraph,
    private_domain_id,
    private_domain_ids,
)
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.rig_sim import RigSim

pytestmark = pytest.mark.ros


def test_every_hit_of_a_session_is_reported_and_judged(ros_graph):
    hammer = ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
    ros_graph.add(RigSim)
    analyzer = ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    listener = ros_graph.add(Listener)
    ros_graph.start()
    assert wait_for(lambda: len(listener.impacts) == 3), f'{len(listener.impacts)} of 3 reported'
    assert hammer.hits_sent == 3 == analyzer.impacts_reported
    assert [(m.level, m.accepted, list(m.flags)) for m in listener.impacts] == [
        ('low', True, []),
        ('medium', True, []),
        ('high', True, []),
    ]
    impulses = [m.impulse_n_s for m in listener.impacts]
    assert impulses == sorted(impulses) and 0.8 < impulses[0] < 1.1
    assert all(abs(m.natural_frequency_hz - 2.2) < 0.15 for m in listener.impacts)
    assert wait_for(lambda: {s.level for s in listener.summaries} == {'low', 'medium', 'high'})
    last = listener.summaries[-1]
    assert last.linearity_levels == 3 and last.linearity_r2 > 0.95


def test_a_dropped_batch_flags_the_impact_as_gap_instead_of_a_wrong_frf(ros_graph):
    ros_graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER | dict(hits_per_level=1)))
    ros_graph.add(RigSim, parameter_overrides=params(output_topic='/test/velocity'))
    link = ros_graph.add(LossyLink, drop_first_indices=[30_000])  # 3.0 s: inside hit 1
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    listener = ros_graph.add(Listener)
    ros_graph.start()
    assert wait_for(lambda: len(listener.impacts) == 3)
    assert link.dropped == 1
    assert [(list(m.flags), m.accepted) for m in listener.impacts] == [
        (['gap'], False),
        ([], True),
        ([], True),
    ]


@pytest.mark.parametrize(
    ('node', 'overrides', 'reason'),
    [
        (HammerSim, dict(rate_factor=5000.0), 'out of range'),
        (HammerSim, dict(level_peak_forces_n=[450.0, -1.0, 1450.0]), 'outside'),
        (RigSim, dict(integrator='rk45'), 'not one of'),
        (RigSim, dict(mu=-0.1), 'out of range'),
        (Analyzer, dict(reject_flags=['gap', 'wobbly']), 'unknown flag'),
        (Analyzer, dict(trigger_level_n=5.0, rearm_level_n=5.0), 'rearm_level_n'),
    ],
)
def test_out_of_range_parameters_are_refused_with_the_reason(ros_graph, node, overrides, reason):
    with pytest.raises((InvalidParameterValueException, ValueError), match=reason):
        ros_graph.add(node, parameter_overrides=params(**overrides))


def test_rig_sim_rejects_unknown_model_terms_naming_them(ros_graph):
    with pytest.raises(ValueError, match="unknown model term 'wobble'"):
        ros_graph.add(RigSim, parameter_overrides=params(effects=['wobble']))


def test_clean_start_and_shutdown_leaves_no_threads_and_no_errors(capfd, tmp_path):
    from fmm_ros.ros.nodes.fitter import Fitter
    from fmm_ros.ros.nodes.recorder import Recorder

    before = set(threading.enumerate())
    with InProcessGraph() as graph:
        graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
        graph.add(RigSim)
        graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
        graph.add(Fitter)
        graph.add(Recorder, parameter_overrides=params(bag_path=str(tmp_path / 'bag')))
        graph.start()
        time.sleep(0.5)
    # The shared worker pools (fmm_ros.core._threads) are kept for the process by design: a
    # fit that runs during the graph (the pace decides whether one does) starts them.
    leaked = [
        t
        for t in threading.enumerate()
        if t not in before and t.is_alive() and not t.name.startswith(_threads._PREFIX)
    ]
    assert not leaked, f'threads left running: {leaked}'
    assert not graph.context.ok()
    output = capfd.readouterr()
    text = output.out + output.err
    for marker in ('Traceback', '[ERROR]', 'Exception', 'RCLError'):
        assert marker not in text, text


def test_no_node_shadows_an_attribute_rclpy_node_keeps(ros_graph):
    """Overwriting e.g. Node._publishers breaks rclpy's teardown: a static check over nodes/."""
    import re
    from pathlib import Path

    import fmm_ros.ros.nodes

    base = set(vars(ros_graph.add(Node, node_name='bare')))
    for path in Path(fmm_ros.ros.nodes.__file__).parent.glob('*.py'):
        assigned = set(re.findall(r'self\.(\w+)\s*(?::[^=\n]+)?=[^=]', path.read_text()))
        clash = assigned & base
        assert not clash, f'{path.name} overwrites rclpy Node attributes {clash}'


def test_parallel_test_workers_draw_domain_ids_that_never_meet(monkeypatch):
    """pytest-xdist worker gwN of M draws from every M-th private id from the N-th: the shares
    cover PRIVATE_DOMAIN_IDS, never overlap, and a process outside xdist draws from all."""
    monkeypatch.delenv('PYTEST_XDIST_WORKER', raising=False)
    monkeypatch.delenv('PYTEST_XDIST_WORKER_COUNT', raising=False)
    assert private_domain_ids() == PRIVATE_DOMAIN_IDS == range(1, 101)
    for workers in (2, 3, 7):
        monkeypatch.setenv('PYTEST_XDIST_WORKER_COUNT', str(workers))
        shares = []
        for index in range(workers):
            monkeypatch.setenv('PYTEST_XDIST_WORKER', f'gw{index}')
            shares.append(set(private_domain_ids()))
            assert private_domain_id() in shares[-1]
            assert InProcessGraph().domain_id in shares[-1]
        assert sum(len(share) for share in shares) == len(PRIVATE_DOMAIN_IDS)
        assert set().union(*shares) == set(PRIVATE_DOMAIN_IDS)
