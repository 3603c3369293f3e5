"""Launch scripts: the simulated rig as separate `ros2 run`-style processes, and overrides."""

import signal
import subprocess
import sys
import threading

import pytest
from rig_graph import Listener, wait_for

from fmm_ros.io.bags.reader import BagReader
from fmm_ros.ros.graph import InProcessGraph, private_domain_id
from fmm_ros.ros.launch import (
    SIMULATED_RIG,
    default_params_file,
    node_command,
    parse_overrides,
    start_processes,
    stop_processes,
    wait_for_log,
    with_wiring,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_the_simulated_rig_runs_as_separate_processes(tmp_path, monkeypatch):
    domain = private_domain_id()
    monkeypatch.setenv('ROS_DOMAIN_ID', str(domain))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    overrides = parse_overrides(
        [
            'hammer_sim.rate_factor=50',
            'hammer_sim.hits_per_level=1',
            'hammer_sim.batch_size=2000',
            'hammer_sim.hit_spacing_s=8.0',
            'hammer_sim.first_hit_s=1.0',
            'analyzer.window_s=6.0',
            f'recorder.bag_path={tmp_path / "bag"}',
        ],
        SIMULATED_RIG,
    )
    assert node_command('analyzer')[0].endswith('lib/fmm_ros/analyzer')
    with InProcessGraph(domain_id=domain) as graph:
        listener = graph.add(Listener)
        graph.start()
        processes = start_processes(
            SIMULATED_RIG, default_params_file(), with_wiring(SIMULATED_RIG, overrides)
        )
        try:
            assert wait_for(lambda: len(listener.impacts) == 3, timeout_s=90.0), (
                f'{len(listener.impacts)} of 3 impacts from the processes'
            )
            # The recorder is another process: it may still be writing them (the open bag
            # is read as after a crash, up to the last flushed chunk).
            assert wait_for(lambda: _impacts_in(tmp_path / 'bag') == 3, timeout_s=30.0)
        finally:
            codes = stop_processes(processes)
    assert [m.level for m in listener.impacts] == ['low', 'medium', 'high']
    assert codes == [0] * len(codes), codes  # each node stopped cleanly on SIGINT
    with BagReader(tmp_path / 'bag') as reader:  # closed cleanly on SIGINT
        assert reader.topics['/fmm/impacts'].count == 3 and not reader.recovered


def test_overrides_name_what_is_wrong():
    with pytest.raises(ValueError, match='not node.param=value'):
        parse_overrides(['rate_factor=2'], SIMULATED_RIG)
    with pytest.raises(ValueError, match="no node 'daq' in this rig"):
        parse_overrides(['daq.backend=file'], SIMULATED_RIG)
    (parameter,) = parse_overrides(['rig_sim.effects=[stribeck]'], SIMULATED_RIG)['rig_sim']
    assert (parameter.name, parameter.value) == ('effects', ['stribeck'])
    assert default_params_file().name == 'fmm_rig.yaml' and default_params_file().is_file()


def test_the_wiring_points_analyzer_and_fitter_at_the_recorders_bag_and_a_set_still_wins():
    def fitter_bag(items, nodes=SIMULATED_RIG, node='fitter'):
        wired = with_wiring(nodes, parse_overrides(items, nodes))
        return [p.value for p in wired.get(node, []) if p.name == 'recorder_bag']

    assert fitter_bag(['recorder.bag_path=/data/s1']) == ['/data/s1']
    assert fitter_bag([]) == []  # the recorder names its bag by the time: unknown here
    assert fitter_bag(['recorder.bag_path=/data/s1', 'fitter.recorder_bag=/x'])[-1] == '/x'
    assert fitter_bag(['recorder.bag_path=/data/s1'], ('fitter', 'recorder'))[-1] == '/data/s1'
    assert fitter_bag(['recorder.bag_path=/data/s1'], ('analyzer', 'recorder')) == []
    assert fitter_bag(['recorder.bag_path=/data/s1'], node='analyzer') == ['/data/s1']
    assert fitter_bag(['recorder.bag_path=/data/s1'], node='rig_sim') == []


def _impacts_in(bag):
    try:
        with BagReader(bag, strict=False) as reader:
            return sum(1 for _ in reader.messages(['/fmm/impacts']))
    except (ValueError, OSError):  # not created or not flushed yet
        return 0


def test_wait_for_log_sees_a_line_written_later_and_times_out_on_one_never_written(tmp_path):
    """The log may not exist yet when the wait begins (the node has not opened it)."""

    def write() -> None:
        (tmp_path / 'hammer_sim.log').write_text('[INFO] [1.0] [hammer_sim]: ... starting\n')

    timer = threading.Timer(0.3, write)
    timer.start()
    try:
        assert wait_for_log(tmp_path, 'hammer_sim', 'starting', 10.0)
    finally:
        timer.join()
    assert not wait_for_log(tmp_path, 'hammer_sim', 'stopped', 0.3)
    assert not wait_for_log(tmp_path, 'rig_sim', 'starting', 0.3)


SLOW_STOP = """
import signal, sys, time
def stop(*_):
    time.sleep(float(sys.argv[1]))
    sys.exit(0)
signal.signal(signal.SIGINT, stop)
print('up', flush=True)
time.sleep(60)
"""


def test_each_node_escalates_on_its_own_clock_so_the_last_stage_keeps_its_grace():
    """Three stages, each slow to stop: the last node still gets the whole SIGTERM timeout.

    Counted from the first signal, the fitter (signalled 2.8 s in, 4 s to stop) was killed.
    """
    nodes = ['hammer_sim', 'rig_sim', 'analyzer', 'fitter']
    stop_s = [1.4, 1.4, 1.4, 4.0]  # the last stage: analyzer, fitter
    processes = [
        subprocess.Popen([sys.executable, '-c', SLOW_STOP, str(s)], stdout=subprocess.PIPE)
        for s in stop_s
    ]
    for process in processes:
        assert process.stdout.readline() == b'up\n'
    assert stop_processes(processes, nodes=nodes) == [0, 0, 0, 0]
    # One that never stops on SIGINT still gets SIGTERM (default action: it dies).
    stubborn = subprocess.Popen([sys.executable, '-c', SLOW_STOP, '60'], stdout=subprocess.PIPE)
    assert stubborn.stdout.readline() == b'up\n'
    assert stop_processes([stubborn], sigterm_timeout_s=0.5) == [-signal.SIGTERM]
