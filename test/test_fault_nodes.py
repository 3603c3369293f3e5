"""Fault families in the nodes: each family in a graph, every member that matters.

In-process graphs (one domain each) for what a scripted node can provoke: an offset above
the trigger, every unit of the table against the SI run, a unit no table knows, two sources
and two rates, a lab's twenty service clients and an id named three times, a recorder
respawned on its own bag, a full disk under the recorder, a gap of any length in rig_sim's
force. The multi-process rig under SIGSTOP / SIGKILL is test_fault_rig.py.
"""

import subprocess
import threading
import time

import numpy as np
import pytest
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rig_graph import FAST_ANALYZER, FAST_HAMMER, Listener, params, wait_for

from fmm_interfaces.msg import SampleBatch, StreamProgress
from fmm_interfaces.srv import FitFriction, RecallSamples
from fmm_ros.constants import (
    FIT_SERVICE,
    FORCE,
    FORCE_TOPIC,
    RECALL_SERVICE,
    STREAM_PROGRESS_TOPIC,
    VELOCITY,
    VELOCITY_TOPIC,
)
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.io.bags.writer import BagWriter
from fmm_ros.ros import msgs
from fmm_ros.ros.common import SAMPLE_QOS
from fmm_ros.ros.graph import InProcessGraph
from fmm_ros.ros.health import ERROR, WARN
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.nodes.fitter import Fitter
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.recorder import Recorder
from fmm_ros.ros.nodes.rig_sim import RigSim
from fmm_ros.ros.qos import PROGRESS_QOS

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def session(graph, hammer=None, rig=None, analyzer=None):
    """The fast session's graph: hammer, rig, analyzer, listener (started)."""
    graph.add(HammerSim, parameter_overrides=params(**dict(FAST_HAMMER, **(hammer or {}))))
    graph.add(RigSim, parameter_overrides=params(**(rig or {})))
    node = graph.add(
        Analyzer, parameter_overrides=params(**dict(FAST_ANALYZER, **(analyzer or {})))
    )
    listener = graph.add(Listener)
    return node, listener


def statuses(node):
    """The node's /diagnostics statuses now, by part."""
    return {status.name.rsplit(': ', 1)[1]: status for status in node.health.statuses()}


def test_an_offset_above_the_trigger_flags_one_record_and_loses_no_hit(ros_graph):
    analyzer, listener = session(ros_graph, hammer={'offset_n': 30.0})
    ros_graph.start()
    assert wait_for(lambda: len(listener.impacts) == 4), f'{len(listener.impacts)} reported'
    first, *hits = listener.impacts
    assert 'truncated_start' in first.flags and first.record_start_sample_index == 0
    assert [h.level for h in hits] == ['low', 'medium', 'high']
    assert all('truncated_start' not in h.flags for h in hits)
    assert analyzer.callback_faults.count == 0


def _impacts(hammer=None, rig=None):
    with InProcessGraph() as graph:
        _, listener = session(graph, hammer, rig)
        graph.start()
        assert wait_for(lambda: len(listener.impacts) == 3), f'{len(listener.impacts)} reported'
        return list(listener.impacts)


@pytest.mark.parametrize(('force_unit', 'velocity_unit'), [('kN', 'in/s'), ('lbf', 'mm/s')])
def test_a_daq_in_other_units_gives_the_si_results(force_unit, velocity_unit):
    """Converted once at the node input: hits, flags, impulses, |X/F| as in N and m/s."""
    want = _impacts()
    got = _impacts({'force_unit': force_unit}, {'velocity_unit': velocity_unit})
    for a, b in zip(got, want, strict=True):
        assert (a.trigger_sample_index, a.level, list(a.flags)) == (
            b.trigger_sample_index,
            b.level,
            list(b.flags),
        )
        assert a.impulse_n_s == pytest.approx(b.impulse_n_s, rel=1e-9)
        assert a.peak_receptance_m_per_n == pytest.approx(b.peak_receptance_m_per_n, rel=1e-9)


class Scripted(Node):
    """Publishes given batches of force and velocity (units and rates as asked)."""

    def __init__(self, **kwargs):
        super().__init__('scripted', **kwargs)
        self.force = self.create_publisher(SampleBatch, FORCE_TOPIC, SAMPLE_QOS)
        self.velocity = self.create_publisher(SampleBatch, VELOCITY_TOPIC, SAMPLE_QOS)

    def send(self, channel, first, rate_hz, unit, count=500):
        message = msgs.sample_batch(
            np.zeros(count),
            quantity=channel,
            sample_rate_hz=rate_hz,
            first_sample_index=first,
            stamp=msgs.time_msg(1_764_000_000_000_000_000 + round(first / rate_hz * 1e9)),
            frame_id='scripted',
        )
        message.unit = unit
        (self.force if channel is FORCE else self.velocity).publish(message)


def test_a_unit_no_table_knows_and_channels_at_two_rates_are_named(ros_graph):
    analyzer = ros_graph.add(Analyzer)
    source = ros_graph.add(Scripted)
    ros_graph.start()
    for k in range(4):
        source.send(FORCE, 500 * k, 10_000.0, 'N')
        source.send(VELOCITY, 250 * k, 5_000.0, 'kp')
    assert wait_for(lambda: analyzer.ledger['velocity'].faults.get('unit') == 4)
    stream = statuses(analyzer)['stream']
    assert stream.level == ERROR
    assert {v.key: v.value for v in stream.values}['velocity fault unit'] == '4'
    for k in range(4, 8):
        source.send(VELOCITY, 250 * k, 5_000.0, 'mm/s')
    assert wait_for(
        lambda: 'different sample rates' in ' '.join(analyzer.inputs.sources.problems())
    )
    assert 'force 10000 Hz, velocity 5000 Hz' in analyzer.inputs.sources.problems()[0]


def test_two_sources_on_one_topic_are_named(ros_graph):
    analyzer = ros_graph.add(Analyzer)
    first, second = ros_graph.add(Scripted), ros_graph.add(Scripted)
    ros_graph.start()
    assert wait_for(lambda: analyzer.inputs.sources.problems())
    problems = analyzer.inputs.sources.problems()
    assert any(p.startswith(f'two sources publish /{FORCE_TOPIC}: ') for p in problems), problems
    first.destroy_node(), second.destroy_node()


class BestEffort(Node):
    """Publishes force best-effort, as a sensor driver may: the reliable reader cannot match."""

    def __init__(self, **kwargs):
        super().__init__('lossy_daq', **kwargs)
        self.create_publisher(SampleBatch, FORCE_TOPIC, 10)
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        self.create_publisher(SampleBatch, VELOCITY_TOPIC, qos)


def test_a_source_the_flow_control_cannot_hold_back_is_named_before_its_first_batch(ros_graph):
    """A plain publisher (no fmm/stream_progress) is WARN with the contract; a paced one is not."""
    analyzer = ros_graph.add(Analyzer)
    ros_graph.add(Scripted)
    ros_graph.start()

    def sources():
        return statuses(analyzer)['sources']

    assert wait_for(lambda: sources().level == WARN)
    assert 'a KEEP_LAST writer loses what it sends faster than this node takes' in sources().message
    assert analyzer.ledger['force'].received_samples == 0  # named before any batch came
    held = params(**FAST_HAMMER, wait_for_consumers=['nobody'], start_timeout_s=0.0)
    ros_graph.add(HammerSim, parameter_overrides=held)  # listens to fmm/stream_progress
    assert wait_for(lambda: sources().level == ERROR)  # two sources publish force now
    values = {v.key: v.value for v in sources().values}
    assert values['unpaced publishers'] == '/scripted', values  # hammer_sim is not named
    assert '/scripted publishes /fmm/force without flow control' in sources().message


def test_a_best_effort_source_is_an_error_since_none_of_its_batches_arrive(ros_graph):
    analyzer = ros_graph.add(Analyzer)
    ros_graph.start()
    ros_graph.add(BestEffort)  # after start: its velocity publisher never matches
    assert wait_for(lambda: statuses(analyzer)['sources'].level == ERROR)
    message = statuses(analyzer)['sources'].message
    assert f'/lossy_daq publishes /{VELOCITY_TOPIC} best-effort' in message, message
    assert f'/lossy_daq publishes /{FORCE_TOPIC} without flow control' in message, message


def test_twenty_clients_at_once_are_answered_and_a_repeated_id_counts_once(ros_graph):
    _, listener = session(ros_graph)
    fitter = ros_graph.add(Fitter)
    caller = ros_graph.add(Node, node_name='lab')
    clients = [caller.create_client(FitFriction, FIT_SERVICE) for _ in range(20)]
    ros_graph.start()
    assert wait_for(lambda: len(fitter.impacts) == 3)
    ids = list(fitter.impacts)
    assert all(client.wait_for_service(timeout_sec=10.0) for client in clients)
    futures = [
        client.call_async(FitFriction.Request(impact_ids=[ids[k % 3]]))
        for k, client in enumerate(clients)
    ]
    done = threading.Event()
    answered = []
    for future in futures:
        future.add_done_callback(lambda f: (answered.append(f), len(answered) == 20 and done.set()))
    assert done.wait(120.0), f'{len(answered)} of 20 answered'
    assert all(f.result().success for f in futures)
    alone = futures[0].result()
    thrice = ros_graph.call(clients[0], FitFriction.Request(impact_ids=[ids[0]] * 3), 60.0)
    assert list(thrice.impact_ids) == [ids[0]]
    assert thrice.mu_stderr == pytest.approx(alone.mu_stderr, rel=1e-9)
    assert f'counted once: {ids[0]} (3 times)' in thrice.message


def test_a_respawned_recorder_records_beside_its_old_bag(tmp_path):
    for _ in range(2):
        with InProcessGraph() as graph:
            graph.add(Recorder, parameter_overrides=params(bag_path=str(tmp_path / 'bag')))
    assert sorted(p.name for p in tmp_path.iterdir()) == ['bag', 'bag_1']
    for bag in ('bag', 'bag_1'):
        assert (tmp_path / bag / 'metadata.yaml').is_file()


def test_a_respawned_recorder_copies_the_unclosed_bag_of_the_one_killed(tmp_path):
    """A killed recorder's bag (never closed) is read into the new one first: one bag whole."""
    old = BagWriter(tmp_path / 'bag')
    old.open()
    for k in range(4):
        old.write_sample_batch(
            FORCE_TOPIC,
            np.full(1000, float(k)),
            quantity=(FORCE.quantity, FORCE.unit),
            sample_rate_hz=10_000.0,
            first_sample_index=1000 * k,
        )
    old.flush()  # as the recorder does every flush_interval_s
    old.abandon()  # as SIGKILL leaves it: no summary, no metadata.yaml
    before = {p.name: p.read_bytes() for p in (tmp_path / 'bag').iterdir()}
    with InProcessGraph() as graph:
        recorder = graph.add(Recorder, parameter_overrides=params(bag_path=str(tmp_path / 'bag')))
        assert recorder.bag_path == tmp_path / 'bag_1'
        assert recorder.ledger['/fmm/force'].received_samples == 4000
    assert {p.name: p.read_bytes() for p in (tmp_path / 'bag').iterdir()} == before
    with BagReader(tmp_path / 'bag_1') as reader:
        firsts = [b.first_sample_index for b in reader.sample_batches([FORCE_TOPIC])]
        assert firsts == [0, 1000, 2000, 3000]
        assert reader.recorded_ledger['/fmm/force'].received_samples == 4000


RATE_HZ = 10_000.0


def _signal(quantity, first, count=1000):
    """Distinct samples per channel and index, so a misplaced sample shows."""
    index = np.arange(first, first + count, dtype=float)
    return index * (1.0 if quantity is FORCE else -1e-6)


def _unclosed_bag(path, batches):
    """A killed recorder's bag: force and velocity batches 0..batches, flushed, never closed."""
    old = BagWriter(path, time_origin_ns=time.time_ns() - 100 * 10**9)  # 100 s ago
    old.open()
    for k in range(batches):
        for topic, channel in ((FORCE_TOPIC, FORCE), (VELOCITY_TOPIC, VELOCITY)):
            old.write_sample_batch(
                topic,
                _signal(channel, 1000 * k),
                quantity=(channel.quantity, channel.unit),
                sample_rate_hz=RATE_HZ,
                first_sample_index=1000 * k,
                frame_id='scripted',
            )
    old.flush()
    old.abandon()
    return old.time_origin_ns


class Clocked(Node):
    """Publishes force and velocity batches of `_signal`, stamped from one acquisition origin."""

    def __init__(self, origin_ns, **kwargs):
        super().__init__('clocked', **kwargs)
        self.origin_ns = origin_ns
        self.topics = {
            FORCE: self.create_publisher(SampleBatch, FORCE_TOPIC, SAMPLE_QOS),
            VELOCITY: self.create_publisher(SampleBatch, VELOCITY_TOPIC, SAMPLE_QOS),
        }

        self.progress = []  # the recorder's reports on /fmm/force: (node, next index)
        self.create_subscription(
            StreamProgress,
            STREAM_PROGRESS_TOPIC,
            lambda msg: self.progress.extend(
                (msg.node, index)
                for topic, index in zip(msg.topics, msg.next_sample_indices, strict=True)
                if topic == '/fmm/force'
            ),
            PROGRESS_QOS,
        )

    def send(self, k, channels=(FORCE, VELOCITY)):
        for channel in channels:
            publisher = self.topics[channel]
            first = 1000 * k
            publisher.publish(
                msgs.sample_batch(
                    _signal(channel, first),
                    quantity=channel,
                    sample_rate_hz=RATE_HZ,
                    first_sample_index=first,
                    stamp=msgs.time_msg(self.origin_ns + round(first / RATE_HZ * 1e9)),
                    frame_id='scripted',
                )
            )


@pytest.mark.parametrize(('history_s', 'down'), [(120.0, 10), (1.0, 25)])
def test_a_respawned_recorder_stores_what_it_missed_from_the_fitters_history(
    tmp_path, history_s, down
):
    """The killed recorder's bag ends at 4,000; batches 4 to `down` went out while none ran.

    A fitter that still holds them (120 s of history): the new bag holds every sample whole,
    in order, as sent, its ledger 0 missing. One whose history is shorter than the downtime
    (1 s: 10,000 samples) fills what it still holds; the ledger counts the rest missing.
    """
    origin_ns = _unclosed_bag(tmp_path / 'bag', 4)
    end = 1000 * (down + 6)
    with InProcessGraph() as graph:
        fitter = graph.add(Fitter, parameter_overrides=params(history_s=history_s))
        source = graph.add(Clocked, origin_ns=origin_ns)
        graph.start()
        for k in range(down):
            source.send(k)
        assert wait_for(
            lambda: (
                fitter.history.next_index('force')
                == fitter.history.next_index('velocity')
                == 1000 * down
            )
        )
        recorder = graph.add(Recorder, parameter_overrides=params(bag_path=str(tmp_path / 'bag')))
        graph.wait_for_discovery(10.0)
        # The force's first live batch well before the velocity's: its recall is answered
        # before the velocity's gap shows, and must wait for it.
        source.send(down, channels=(FORCE,))
        time.sleep(1.0)
        source.send(down, channels=(VELOCITY,))
        for k in range(down + 1, down + 6):
            source.send(k)
        assert wait_for(
            lambda: all(
                recorder.ledger[t].span == (0, end) for t in ('/fmm/force', '/fmm/velocity')
            )
        ), recorder.ledger
        assert not recorder._recall.waiting
        # Held batches are reported taken, and the report never goes back as they are stored
        # (a consumer reporting backwards is taken for one restarted).
        reports = [index for node, index in source.progress if node == '/recorder']
        assert reports and reports == sorted(reports), reports
        # A request the history cannot answer is refused by name, never an empty success.
        client = graph.add(Node, node_name='asks').create_client(RecallSamples, RECALL_SERVICE)
        for topic, span, why in (
            ('/fmm/force', (9000, 8000), 'end_sample_index 8000 must be above first_sample_index'),
            ('/fmm/other', (0, 1000), '/fmm/other is not held here'),
            ('/fmm/force', (end, end + 1000), f'samples {end}..{end + 1000} of /fmm/force are not'),
        ):
            request = RecallSamples.Request(
                topic=topic, first_sample_index=span[0], end_sample_index=span[1]
            )
            answer = graph.call(client, request)
            assert not answer.success and why in answer.message, answer.message
    with BagReader(tmp_path / 'bag_1') as reader:
        ledger = reader.recorded_ledger
        # Stored with the channels together, as they came: never the downtime (6,000) apart,
        # at most the two batches two live subscriptions may deliver out of step.
        reached = {FORCE_TOPIC: 0, VELOCITY_TOPIC: 0}
        for batch in reader.sample_batches([FORCE_TOPIC, VELOCITY_TOPIC]):
            reached[batch.topic.lstrip('/')] = batch.end_index
            if history_s > 1:
                assert abs(reached[FORCE_TOPIC] - reached[VELOCITY_TOPIC]) <= 2000, reached
        for topic, channel in ((FORCE_TOPIC, FORCE), (VELOCITY_TOPIC, VELOCITY)):
            batches = list(reader.sample_batches([topic]))
            firsts = [b.first_sample_index for b in batches]
            assert firsts == sorted(firsts), f'{topic} out of order: {firsts}'
            index = np.concatenate([np.arange(b.first_sample_index, b.end_index) for b in batches])
            values = np.concatenate([b.samples for b in batches])
            # Where the bag goes on after 4,000: at once, or where the short history began.
            resumed = int(index[index >= 4000][0])
            held_from = 1000 * down - round(history_s * RATE_HZ)
            assert resumed == max(4000, held_from) or 4000 < held_from < resumed, resumed
            assert np.array_equal(index, np.r_[0:4000, resumed:end]), topic
            assert np.array_equal(values, _signal(channel, 0, end)[index]), topic
            assert ledger['/' + topic].missing_samples == resumed - 4000, ledger


def test_a_respawned_fitter_holds_again_what_it_held_with_its_live_mu(ros_graph, tmp_path):
    state = params(state_dir=str(tmp_path / 'state'))
    session(ros_graph)
    fitter = ros_graph.add(Fitter, parameter_overrides=state)
    ros_graph.start()
    assert wait_for(lambda: 'over 3 impacts' in fitter.live_mu, timeout_s=120.0), fitter.impacts
    held = {i: h.record.trigger_sample_index for i, h in fitter.impacts.items()}
    mu = fitter.live_mu
    with InProcessGraph() as graph:  # the respawn: a new process would start the same way
        again = graph.add(Fitter, parameter_overrides=state)
        listener = graph.add(Listener)
        client = graph.add(Node, node_name='client').create_client(FitFriction, FIT_SERVICE)
        graph.start()
        assert {i: h.record.trigger_sample_index for i, h in again.impacts.items()} == held
        assert again.live_mu == mu  # the restored fits, not fitted again
        assert wait_for(lambda: listener.friction and listener.friction[-1].count == 3)
        response = graph.call(client, FitFriction.Request(), timeout_s=60.0)
        assert response.success and sorted(response.impact_ids) == sorted(held), response.message


@pytest.fixture
def small_disk(tmp_path):
    """A 2 MB tmpfs (CI runs as root), unmounted after the test."""
    mount = tmp_path / 'disk'
    mount.mkdir()
    subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=2m', 'tmpfs', str(mount)], check=True)
    yield mount
    subprocess.run(['umount', str(mount)], check=True)


def test_a_full_disk_stops_the_recording_not_the_rig(ros_graph, small_disk):
    analyzer, listener = session(ros_graph)
    recorder = ros_graph.add(Recorder, parameter_overrides=params(bag_path=str(small_disk / 'bag')))
    ros_graph.start()
    assert wait_for(lambda: recorder.failed, timeout_s=60.0)
    assert 'No space left on device' in recorder.failed
    status = statuses(recorder)['recorder']
    assert status.level == ERROR and status.message.startswith('not recording')
    assert wait_for(lambda: len(listener.impacts) == 3), 'the rig went on'
    with BagReader(small_disk / 'bag', strict=False) as reader:
        batches = sum(1 for _ in reader.sample_batches([FORCE_TOPIC]))
    assert batches > 0 and recorder.callback_faults.count == 0


def test_a_gap_of_any_length_in_the_applied_force_leaves_rig_sim_working(ros_graph):
    rig = ros_graph.add(RigSim)
    ros_graph.start()
    rate = 10_000.0

    def force(first):
        return msgs.sample_batch(
            np.zeros(1000),
            quantity=FORCE,
            sample_rate_hz=rate,
            first_sample_index=first,
            stamp=msgs.time_msg(1_764_000_000_000_000_000 + round(first / rate * 1e9)),
            frame_id='hammer',
        )

    # 70 s, 10 min and 3 h of signal missing (a stall of any length at any pace).
    starts = [0, 1000, 701_000, 702_000, 6_702_000, 6_703_000, 114_703_000, 114_704_000]
    for first in starts:
        rig._on_force(force(first))
    ledger = rig.stream.ledger['force']
    assert ledger.faults.get('malformed', 0) == 0
    assert ledger.received_samples == 8000
    assert ledger.missing_samples == 114_705_000 - 8000
    assert rig.gate.published_end == 114_705_000


def test_a_record_the_analysis_cannot_take_is_dropped_and_the_next_reported(ros_graph, monkeypatch):
    """The analyzer's last resort: one broken record named once, ERROR, the rest go on."""
    from fmm_ros.ros.nodes import analyzer as analyzer_module

    real = analyzer_module.analyze_impact
    calls = []

    def first_breaks(record, *args, **kwargs):
        calls.append(record.trigger_sample_index)
        if len(calls) == 1:
            raise ZeroDivisionError('a fault no rule foresaw')
        return real(record, *args, **kwargs)

    monkeypatch.setattr(analyzer_module, 'analyze_impact', first_breaks)
    analyzer, listener = session(ros_graph)
    ros_graph.start()
    assert wait_for(lambda: len(listener.impacts) == 2), f'{len(listener.impacts)} reported'
    assert [m.trigger_sample_index for m in listener.impacts] == calls[1:]
    faults = statuses(analyzer)['faults']
    assert faults.level == ERROR and 'ZeroDivisionError: a fault no rule foresaw' in faults.message
    assert analyzer.capture.open_impacts == 0 and analyzer.callback_faults.count == 1


def test_an_exception_in_any_callback_is_survived_by_a_ros_run_node():
    """run_node's spin: the fault is counted (ERROR), the node's other callbacks go on."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from fmm_ros.ros.common import _spin_guarded
    from fmm_ros.ros.health import Health

    class Faulty(Node):
        def __init__(self, **kwargs):
            super().__init__('faulty', **kwargs)
            Health(self)
            self.ticks = 0
            self.create_timer(0.01, self._tick)

        def _tick(self):
            self.ticks += 1
            if self.ticks % 2:
                raise RuntimeError(f'tick {self.ticks}')

    context = Context()
    rclpy.init(context=context, domain_id=InProcessGraph().domain_id)
    executor = SingleThreadedExecutor(context=context)
    node = Faulty(context=context)
    executor.add_node(node)
    try:
        while node.ticks < 10:
            _spin_guarded(executor, node, 0.05)
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    assert node.callback_faults.count == 5
    level, message, values = node.callback_faults.status()
    assert (
        level == ERROR and message == '5 exceptions survived; last: callback: RuntimeError: tick 9'
    )
    assert values == {'callback: RuntimeError': 5}
