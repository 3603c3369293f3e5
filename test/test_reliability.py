"""The live graph under faults: nothing lost, recovery, signals, namespaces.

Started as a lab starts it: nodes as separate processes in any order, or in-process graphs
on one domain for the faults that need a scripted source. What counts is what the graph
published, what the nodes' ledgers say, and what the recorded bag proves about itself.
"""

import re
import signal
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from rclpy.node import Node
from rig_graph import FAST_ANALYZER, FAST_HAMMER, Listener, params, wait_for

from fmm_interfaces.msg import SampleBatch
from fmm_interfaces.srv import FitFriction
from fmm_ros.constants import FIT_SERVICE, FORCE, FORCE_TOPIC
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.ros import msgs
from fmm_ros.ros.graph import InProcessGraph, private_domain_id
from fmm_ros.ros.launch import (
    SIMULATED_RIG,
    parse_overrides,
    start_processes,
    stop_processes,
    with_wiring,
)
from fmm_ros.ros.nodes import CONSUMERS
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.fitter import Fitter
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.recorder import Recorder
from fmm_ros.ros.nodes.rig_sim import RigSim
from fmm_ros.ros.qos import SAMPLE_QOS
from fmm_ros.workflows.replay import replay_bag

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[1]
SESSION = [
    'hammer_sim.rate_factor=20',
    'hammer_sim.hits_per_level=1',
    'hammer_sim.hit_spacing_s=8.0',
    'hammer_sim.first_hit_s=1.0',
    'hammer_sim.batch_size=1000',
    'analyzer.window_s=6.0',
]


@pytest.fixture
def domain(monkeypatch):
    """A private domain for processes started by the test (and its own graphs)."""
    domain_id = private_domain_id()
    monkeypatch.setenv('ROS_DOMAIN_ID', str(domain_id))
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return domain_id


def published_end(log: Path) -> int:
    """What hammer_sim says it published, from its log line on stopping."""
    found = re.search(r'stopped: samples 0\.\.(\d+) published', log.read_text())
    assert found, log.read_text()
    return int(found.group(1))


def impacts_in(bag: Path) -> int:
    try:
        with BagReader(bag, strict=False) as reader:
            return sum(1 for message in reader.messages() if message.topic.endswith('/impacts'))
    except (ValueError, OSError):
        return 0


@pytest.mark.slow
@pytest.mark.parametrize('first', ['sources', 'consumers'])
def test_a_rig_started_in_any_order_records_every_sample_it_sent(tmp_path, domain, first):
    bag = tmp_path / 'bag'
    overrides = with_wiring(
        SIMULATED_RIG, parse_overrides([*SESSION, f'recorder.bag_path={bag}'], SIMULATED_RIG)
    )
    sources, consumers = ['hammer_sim', 'rig_sim'], ['analyzer', 'fitter', 'recorder']
    early, late = (sources, consumers) if first == 'sources' else (consumers, sources)
    names = early + late
    processes = start_processes(early, None, overrides, log_dir=tmp_path)
    try:
        time.sleep(4.0)  # the early ones are up, discovered and (sources) holding
        processes += start_processes(late, None, overrides, log_dir=tmp_path)
        assert wait_for(lambda: impacts_in(bag) == 3, timeout_s=90.0)
    finally:
        codes = stop_processes(processes, nodes=names)
    assert codes == [0] * len(codes), codes
    sent = published_end(tmp_path / 'hammer_sim.log')
    with BagReader(bag) as reader:
        assert not reader.recovered and reader.ros_distro == 'jazzy'
        ledger = reader.recorded_ledger
    for topic in ('/fmm/force', '/fmm/velocity'):
        entry = ledger[topic]
        assert entry.acquisitions == [[0, sent]], (topic, entry.summary())
        assert (entry.missing_samples, entry.refused_batches, entry.resyncs) == (0, 0, 0)
    for name in ('rig_sim', 'analyzer', 'fitter'):  # each consumer took every sample too
        stopped = re.findall(r'stopped: .*', (tmp_path / f'{name}.log').read_text())
        assert stopped and all(', 0 missing, 0 batches' in line for line in stopped), stopped
    if first == 'sources':
        assert 'holding the first sample' in (tmp_path / 'hammer_sim.log').read_text()


class StraySource(Node):
    """Publishes one batch with a corrupt, far-future index, as a flaky link might."""

    def __init__(self, **kwargs):
        super().__init__('stray_source', **kwargs)
        self.publisher = self.create_publisher(SampleBatch, FORCE_TOPIC, SAMPLE_QOS)

    def send(self):
        self.publisher.publish(
            msgs.sample_batch(
                np.zeros(1000),
                quantity=FORCE,
                sample_rate_hz=10_000.0,
                first_sample_index=10**15,
                stamp=self.get_clock().now().to_msg(),
                frame_id='hammer',
            )
        )


@contextmanager
def hammer_and_plant(domain):
    """hammer_sim and rig_sim in a graph of their own: leaving it ends them (a restart)."""
    with InProcessGraph(domain_id=domain) as rig:
        consumers = ['analyzer', 'fitter']
        rig.add(
            HammerSim,
            parameter_overrides=params(
                **dict(FAST_HAMMER, rate_factor=20.0), wait_for_consumers=['rig_sim', *consumers]
            ),
        )
        rig.add(RigSim, parameter_overrides=params(wait_for_consumers=consumers))
        rig.start()
        yield rig


def _whole(impacts):
    """The impacts not cut short by the end of their acquisition."""
    return [m for m in impacts if 'interrupted' not in m.flags]


@pytest.mark.slow
def test_a_stray_batch_and_a_restarted_source_are_recovered_over_dds(domain):
    """The analyzer used to refuse every batch after either, for good."""
    with InProcessGraph(domain_id=domain) as graph:
        analyzer = graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
        fitter = graph.add(Fitter)
        listener = graph.add(Listener)
        stray = graph.add(StraySource)
        graph.start()
        with hammer_and_plant(domain):
            assert wait_for(lambda: len(listener.impacts) >= 1)
            stray.send()
            assert wait_for(lambda: len(listener.impacts) >= 2)
        # The hammer and the plant restart (index 0 again, a later clock), mid-session. A hit
        # the stop cut short is reported when the new acquisition begins, flagged interrupted.
        before = len(listener.impacts)
        with hammer_and_plant(domain):
            assert wait_for(lambda: len(_whole(listener.impacts[before:])) >= 3)
        force, velocity = analyzer.ledger['force'], analyzer.ledger['velocity']
        fitted = fitter.history.acquisitions
    after = _whole(listener.impacts[before:])
    assert [m.trigger_sample_index for m in after] == [10_001, 90_001, 170_001]
    assert all(m.accepted for m in after)
    assert force.faults.get('stray') == 1 and force.resyncs == 1
    # The new acquisition's reason is counted once, on the channel whose batch declared it:
    # whichever of force and velocity the DDS delivered first after the restart.
    declared = [ledger.faults.get(r, 0) for ledger in (force, velocity) for r in ('reset', 'clock')]
    assert sum(declared) == 1 and velocity.resyncs == 1
    assert force.acquisitions[-1][0] == 0 and fitted == 2


@pytest.mark.slow
@pytest.mark.parametrize('how', ['SIGTERM', 'SIGHUP', 'SIGKILL', 'SIGINT ignored'])
def test_the_launcher_stops_its_nodes_however_it_is_stopped(tmp_path, domain, how):
    """No orphan within 10 s and a closed bag, also when the launcher itself is killed."""
    bag = tmp_path / 'bag'
    command = [
        sys.executable,
        str(REPO / 'launch_scripts' / 'sim_rig.py'),
        '--processes',
        *(item for option in [*SESSION, f'recorder.bag_path={bag}'] for item in ('--set', option)),
    ]
    ignore_sigint = how == 'SIGINT ignored'  # a script's background job inherits SIG_IGN
    log = tmp_path / 'rig.log'  # the nodes inherit it: their last words outlive the launcher
    with log.open('wb') as out:
        launcher = subprocess.Popen(
            command,
            preexec_fn=(lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
            if ignore_sigint
            else None,
            stdout=subprocess.DEVNULL,
            stderr=out,
        )
    try:
        assert wait_for(lambda: _mcap_size(bag) > 100_000, timeout_s=60.0), 'the rig never recorded'
        children = _children(launcher.pid)
        assert len(children) == 5
        signum = signal.SIGINT if ignore_sigint else getattr(signal, how)
        stopped_at = time.monotonic()
        launcher.send_signal(signum)
        assert wait_for(lambda: not any(_alive(pid) for pid in children), timeout_s=10.0), (
            f'nodes still running 10 s after {how}: {[p for p in children if _alive(p)]}'
        )
        launcher.wait(timeout=5.0)
        elapsed = time.monotonic() - stopped_at
    finally:
        if launcher.poll() is None:
            launcher.kill()
        launcher.wait()
    assert launcher.returncode == (-signal.SIGKILL if how == 'SIGKILL' else 0)
    assert elapsed < 10.0
    with BagReader(bag) as reader:  # closed: metadata.yaml and the MCAP summary written
        last_words = '\n'.join(log.read_text(errors='replace').splitlines()[-15:])
        assert not reader.recovered, f'the bag was not closed; the rig said:\n{last_words}'
        assert reader.recorded_ledger['/fmm/force'].missing_samples == 0
    # No node met a callback under way with a destroyed handle (JoiningExecutor).
    assert 'never retrieved' not in log.read_text(errors='replace')


# A node like the fitter (`run_node(threads=2)`): callbacks that take a while, always some
# under way or queued when the stop comes; every one that starts says so, and so does its end.
BUSY_NODE = """
import sys, time
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from std_msgs.msg import Float64
from fmm_ros.ros.common import run_node

class Busy(Node):
    def __init__(self):
        super().__init__('busy')
        self.pub = self.create_publisher(Float64, 'busy', 10)
        self.create_timer(0.02, self._tick, callback_group=ReentrantCallbackGroup())

    def _tick(self):
        print('start', flush=True)
        time.sleep(0.2)
        self.pub.publish(Float64(data=1.0))
        print('end', flush=True)

sys.exit(run_node(Busy, threads=2))
"""


@pytest.mark.slow
@pytest.mark.parametrize('how', ['SIGINT', 'SIGTERM'])
def test_a_multithreaded_node_finishes_its_callbacks_before_it_goes(domain, how):
    """rclpy 7.1's shutdown neither waited for callbacks nor stopped its workers (fitter).

    A callback under way met a destroyed node: 'cannot use Destroyable because destruction
    was requested', printed as an exception 'never retrieved' (a service call lost its
    answer). Now every callback that started ends, and nothing is printed.
    """
    node = subprocess.Popen(
        [sys.executable, '-c', BUSY_NODE],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert node.stdout.readline() == 'start\n', node.stderr.read()
        time.sleep(0.5)
        node.send_signal(getattr(signal, how))
        out, err = node.communicate(timeout=30.0)
    finally:
        if node.poll() is None:
            node.kill()
            node.wait()
    lines = ['start', *out.split()]
    assert node.returncode == 0, err
    assert 'never retrieved' not in err and 'Destroyable' not in err, err
    assert lines.count('start') == lines.count('end') > 1, out


@pytest.mark.slow
def test_two_rigs_in_one_graph_under_namespaces_do_not_cross_talk(tmp_path):
    """Relative names: /rig1 and /rig2 each run their own session, fit their own plant."""
    bag = tmp_path / 'rig2'
    with InProcessGraph() as graph:
        listeners, fits = {}, {}
        for namespace, mu, hits in (('/rig1', 0.113, 1), ('/rig2', 0.2, 2)):
            ns = dict(namespace=namespace)
            graph.add(
                HammerSim,
                parameter_overrides=params(
                    **dict(FAST_HAMMER, hits_per_level=hits),
                    wait_for_consumers=list(CONSUMERS['hammer_sim'][:3]),
                ),
                **ns,
            )
            graph.add(RigSim, parameter_overrides=params(mu=mu), **ns)
            graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER), **ns)
            graph.add(Fitter, **ns)
            listeners[namespace] = graph.add(Listener, **ns)
            fits[namespace] = graph.add(Node, node_name='caller', **ns).create_client(
                FitFriction, FIT_SERVICE
            )
        graph.add(Recorder, parameter_overrides=params(bag_path=str(bag)), namespace='/rig2')
        graph.start()
        assert wait_for(
            lambda: len(listeners['/rig2'].impacts) == 6 == 2 * len(listeners['/rig1'].impacts)
        )
        time.sleep(0.5)
        responses = {
            namespace: graph.call(client, FitFriction.Request(), timeout_s=60.0)
            for namespace, client in fits.items()
        }
    assert responses['/rig1'].mu == pytest.approx(0.113, rel=0.02)
    assert responses['/rig2'].mu == pytest.approx(0.2, rel=0.02)
    assert [len(listener.impacts) for listener in listeners.values()] == [3, 6]
    # The bag recorded under /rig2 is read by its channels' names' tails, as any bag.
    with BagReader(bag) as reader:
        assert {'/rig2/fmm/force', '/rig2/fmm/velocity'} <= set(reader.topics)
    assert len(replay_bag(bag).results) == 6


def _children(pid: int) -> list[int]:
    """Processes whose parent is pid (read from /proc)."""
    found = []
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0]
    except OSError:
        return False
    return state != 'Z'


def _mcap_size(bag: Path) -> int:
    return sum(path.stat().st_size for path in bag.glob('*.mcap')) if bag.exists() else 0
