"""recorder and player nodes: a live session recorded, analysed offline and played back."""

import time

import numpy as np
import pytest
import yaml
from rclpy.parameter import Parameter
from rig_graph import FAST_ANALYZER, FAST_HAMMER, Listener, params, wait_for

from fmm_ros.io.bags.reader import BagReader
from fmm_ros.io.bags.writer import BagWriter
from fmm_ros.ros import msgs
from fmm_ros.ros.graph import InProcessGraph, private_domain_id
from fmm_ros.ros.nodes.analyzer import Analyzer, configs_from_parameters
from fmm_ros.ros.nodes.hammer_sim import HammerSim
from fmm_ros.ros.nodes.player import Player
from fmm_ros.ros.nodes.recorder import Recorder
from fmm_ros.ros.nodes.rig_sim import RigSim
from fmm_ros.ros.qos import RESULT_QOS, SAMPLE_QOS
from fmm_ros.workflows.replay import replay_bag

pytestmark = pytest.mark.ros
CLOCK, DIAG = 'rosgraph_msgs/msg/Clock', 'diagnostic_msgs/msg/DiagnosticArray'


@pytest.fixture(scope='module')
def recorded_session(tmp_path_factory):
    """A fast 3-hit session through the live graph, recorded; with what the analyzer published."""
    bag = tmp_path_factory.mktemp('session') / 'bag'
    with InProcessGraph() as graph:
        graph.add(HammerSim, parameter_overrides=params(**FAST_HAMMER))
        graph.add(RigSim)
        analyzer = graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
        listener = graph.add(Listener)
        recorder = graph.add(Recorder, parameter_overrides=params(bag_path=str(bag)))
        graph.start()
        assert wait_for(lambda: len(listener.impacts) == 3)
        # The results' last messages reach the recorder too, and every node's health (once a
        # second) is recorded at least once.
        time.sleep(1.2)
        live = list(listener.impacts)
        config = analyzer.config
    assert recorder.messages_recorded > 0
    return bag, live, config


def test_the_recorded_bag_holds_every_topic_and_is_closed(recorded_session):
    bag, live, _ = recorded_session
    assert (bag / 'metadata.yaml').is_file()
    with BagReader(bag) as reader:
        assert set(reader.topics) == {
            '/fmm/force',
            '/fmm/velocity',
            '/fmm/impacts',
            '/fmm/frf',
            '/fmm/friction',
            '/diagnostics',
            '/clock',
            '/fmm/impact_decisions',
            '/fmm/session_info',
        }
        assert reader.topics['/fmm/impacts'].count == len(live) == 3
        assert not reader.problems
        batches = list(reader.channel('/fmm/force'))
        indices = [batch.first_sample_index for batch in batches]
        ends = [batch.first_sample_index + len(batch.samples) for batch in batches]
        assert indices == [0, *ends[:-1]]  # contiguous, whatever the paced batch size
        total = ends[-1]
        # The bag states its own completeness: the recorder's ledger, in its metadata.
        assert reader.ros_distro == 'jazzy'
        ledger = reader.recorded_ledger
        assert set(ledger) == {'/fmm/force', '/fmm/velocity'}
        force = ledger['/fmm/force']
        assert force.acquisitions == [[0, total]]
        assert force.received_samples == total
        assert (force.missing_samples, force.refused_batches, force.resyncs) == (0, 0, 0)


def offered_profiles(bag) -> dict[str, list[dict]]:
    """Each topic's offered QoS profiles, as the bag's metadata.yaml records them."""
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    return {
        entry['topic_metadata']['name']: entry['topic_metadata']['offered_qos_profiles']
        for entry in info['topics_with_message_count']
    }


def as_recorded(profile) -> dict:
    """The fields of an rclpy profile a bag's metadata records, spelled as it spells them."""
    return {
        'history': profile.history.name.lower(),
        'depth': profile.depth,
        'reliability': profile.reliability.name.lower(),
        'durability': profile.durability.name.lower(),
    }


def test_the_bags_record_the_qos_the_sample_topics_are_declared_with(recorded_session, tmp_path):
    """The recorder's bag and an offline one (`fmm simulate`) both say what SAMPLE_QOS is."""
    offline = tmp_path / 'offline'
    with BagWriter(offline) as writer:
        writer.write_signals(np.zeros(10), np.zeros(10), 10_000.0)
    assert SAMPLE_QOS.history.name == 'KEEP_ALL'
    fields = ('history', 'depth', 'reliability', 'durability')
    for bag in (recorded_session[0], offline):
        profiles = offered_profiles(bag)
        for topic in ('/fmm/force', '/fmm/velocity'):
            assert [{k: p[k] for k in fields} for p in profiles[topic]] == [
                as_recorded(SAMPLE_QOS)
            ], (bag, topic)
    recorded = offered_profiles(recorded_session[0])['/fmm/impacts'][0]
    assert (recorded['history'], recorded['durability']) == (
        as_recorded(RESULT_QOS)['history'],
        as_recorded(RESULT_QOS)['durability'],
    )


def test_every_stamp_in_the_bag_is_signal_time(recorded_session):
    """One time base: /clock, /diagnostics and the results are stamped in the samples' time.

    At x100 signal time runs 100 times faster than the wall clock, so a wall-clock stamp
    (as /diagnostics had) would lie seconds after the start while the hits lie up to 17 s.
    """
    bag, live, _ = recorded_session
    with BagReader(bag) as reader:
        force = list(reader.channel('/fmm/force'))
        clock = [msgs.stamp_ns(m.clock) for _, m in reader.decoded('/clock', CLOCK)]
        health = [msgs.stamp_ns(m.header.stamp) for _, m in reader.decoded('/diagnostics', DIAG)]
    start_ns = force[0].stamp_ns  # sample 0 of the acquisition
    end_ns = start_ns + (force[-1].first_sample_index + len(force[-1].samples)) * 100_000
    # The source runs at most its flow window (4 s of signal) ahead of what the recorder took.
    assert clock == sorted(clock) and start_ns < clock[0] and clock[-1] <= end_ns + 4 * 10**9
    last_hit_ns = msgs.stamp_ns(live[-1].header.stamp)
    assert start_ns + 16 * 10**9 < last_hit_ns  # the third hit, 17 s into the signal
    assert last_hit_ns <= health[-1] <= end_ns + 4 * 10**9


def test_bag_info_shows_the_ledger_and_the_health_the_bag_holds(recorded_session, capsys):
    from fmm_ros.cli import main

    bag, _, _ = recorded_session
    assert main(['bag-info', str(bag), '-q']) == 0
    out = capsys.readouterr().out
    assert 'ros:       jazzy' in out
    assert '/fmm/force 0..' in out and ', 0 missing, 0 batches (0 samples) refused' in out
    assert 'health:    last status on /diagnostics' in out
    assert '/analyzer: stream' in out and '/recorder: recorder' in out


def test_offline_analysis_of_the_bag_equals_the_live_run(recorded_session):
    bag, live, config = recorded_session
    capture, analysis = configs_from_parameters(config)
    offline = replay_bag(bag, capture, analysis)
    judged = offline.summary.impacts
    assert len(judged) == len(live)
    for off, on in zip(judged, live, strict=True):
        assert (off.level, off.accepted, list(off.flags)) == (on.level, on.accepted, list(on.flags))
        assert (off.trigger_sample_index, off.impulse_n_s, off.peak_receptance_m_per_n) == (
            on.trigger_sample_index,
            on.impulse_n_s,
            on.peak_receptance_m_per_n,
        )
        assert off.mobility.tobytes() == msgs.complex_field(on, 'mobility').tobytes()
    # The offline tools (fmm analyze, fit, report) read the bag's hits under the live ids.
    from fmm_ros.workflows.inputs import InputOptions, read_inputs
    from fmm_ros.workflows.session import analyse

    read = read_inputs([bag], InputOptions(capture=capture))
    offline_ids = [impact.impact_id for impact in analyse(read.records, capture, analysis).impacts]
    live_ids = [on.impact_id for on in live]
    assert offline_ids == [off.impact_id for off in judged] == live_ids
    assert len(set(live_ids)) == len(live_ids)


def test_the_player_replays_the_session_into_a_live_analyzer(recorded_session):
    bag, live, _ = recorded_session
    with InProcessGraph() as graph:
        player = graph.add(
            Player,
            parameter_overrides=params(
                bag_path=str(bag), rate_factor=100.0, topics=['/fmm/force', '/fmm/velocity']
            ),
        )
        graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
        listener = graph.add(Listener)
        graph.start()
        assert wait_for(lambda: len(listener.impacts) == 3)
        assert player.finished or wait_for(lambda: player.finished)
    for again, on in zip(listener.impacts, live, strict=True):
        assert again.impulse_n_s == on.impulse_n_s
        assert np.array_equal(
            msgs.complex_field(again, 'receptance'), msgs.complex_field(on, 'receptance')
        )


def test_player_names_what_a_bag_lacks(recorded_session, ros_graph):
    bag, _, _ = recorded_session
    with pytest.raises(
        ValueError, match='has no topic /fmm/torque; it has /clock, /diagnostics, /fmm/force'
    ):
        ros_graph.add(Player, parameter_overrides=params(bag_path=str(bag), topics=['/fmm/torque']))
    with pytest.raises(ValueError, match='set the bag_path parameter'):
        ros_graph.add(Player)


def test_recorder_refuses_an_unknown_storage(ros_graph, tmp_path):
    with pytest.raises(Exception, match='not one of mcap, sqlite3'):
        ros_graph.add(
            Recorder,
            parameter_overrides=[
                Parameter('bag_path', value=str(tmp_path / 'b')),
                Parameter('storage', value='zip'),
            ],
        )


def test_the_bag_is_closed_when_its_closing_metadata_fails(ros_graph, tmp_path, monkeypatch):
    """A fault while writing the ledger into the metadata must not leave the bag unclosed."""
    bag = tmp_path / 'bag'
    recorder = ros_graph.add(Recorder, parameter_overrides=params(bag_path=str(bag)))

    def broken_ledger_text(ledger):
        raise RuntimeError('ledger unwritable')

    monkeypatch.setattr('fmm_ros.ros.nodes.recorder.ledger_text', broken_ledger_text)
    recorder.destroy_node()
    with BagReader(bag) as reader:
        assert not reader.recovered


@pytest.mark.slow
@pytest.mark.parametrize('signum', ['SIGINT', 'SIGTERM'])
def test_fmm_record_records_live_topics_until_interrupted(tmp_path, signum):
    """`fmm record` in its own process beside a simulated rig; Ctrl-C or SIGTERM (what a
    process manager sends) closes the bag and exits 0."""
    import os
    import signal
    import subprocess
    import sys

    from fmm_ros.ros.launch import parse_overrides, start_processes, stop_processes

    env = dict(
        os.environ,
        ROS_DOMAIN_ID=str(private_domain_id()),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
    )
    os.environ.update({k: env[k] for k in ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE')})
    bag = tmp_path / 'live'
    fmm = os.path.join(os.path.dirname(sys.executable), 'fmm')
    recorder = subprocess.Popen([fmm, 'record', str(bag), '--topics', '/fmm/force'], env=env)
    rig = start_processes(
        ['hammer_sim', 'rig_sim'],
        None,
        parse_overrides(
            [
                'hammer_sim.rate_factor=10',
                "hammer_sim.wait_for_consumers=['recorder', 'rig_sim']",
            ],
            ['hammer_sim', 'rig_sim'],
        ),
    )
    try:
        assert wait_for(
            lambda: (bag / 'metadata.yaml').exists() or _mcap_size(bag) > 200_000, timeout_s=60.0
        )
    finally:
        stop_processes(rig)
        recorder.send_signal(getattr(signal, signum))
        assert recorder.wait(30) == 0
    with BagReader(bag) as reader:
        assert list(reader.topics) == ['/fmm/force'] and reader.topics['/fmm/force'].count > 0
        assert not reader.recovered


def _mcap_size(bag):
    return sum(path.stat().st_size for path in bag.glob('*.mcap')) if bag.exists() else 0
