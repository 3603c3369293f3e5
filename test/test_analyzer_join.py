"""An analyzer that joins an acquisition under way takes what it missed from the recorder's bag.

A respawned analyzer gets no sample sent before it started (VOLATILE). Measured before this
(`benchmarks/fault_respawn.py`, 3 of 3 runs): the hit under way at the kill was never
reported live, and the level averages after the respawn held only the later hits. The bag
the recorder is writing has those samples. Here the bag is a simulated session with the
acquisition clock, and a scripted source plays it into an analyzer from sample J on: the
hits before J come from the bag with the ids `fmm replay` gives them, the later ones live,
and a hit the bag says was reported already is not reported twice.
"""

import numpy as np
import pytest
from rclpy.node import Node
from rig_graph import Listener, params, wait_for

from fmm_interfaces.msg import SampleBatch
from fmm_ros.constants import FORCE, FORCE_TOPIC, IMPACTS_TOPIC, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.signal.capture import CaptureConfig
from fmm_ros.io.bags import BagWriter, fmm_typestore, new_message
from fmm_ros.io.bags.definitions import IMPACT_RESULT
from fmm_ros.ros import msgs
from fmm_ros.ros.common import SAMPLE_QOS
from fmm_ros.ros.nodes import analyzer as analyzer_node
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.sim.session import simulated_session
from fmm_ros.workflows.replay import replay_bag

pytestmark = [pytest.mark.ros, pytest.mark.slow]

T0_NS = 1_764_000_000 * 10**9
RATE_HZ = 10_000.0
WINDOW_S = 6.0
JOIN = 120_000  # 12 s in: the first hit (0.1 s) over, the second (8.1 s) under way
BATCH = 2_000


class Player(Node):
    """Publishes a session's samples from a given index on, with the acquisition clock."""

    def __init__(self, **kwargs):
        super().__init__('player', **kwargs)
        self.force = self.create_publisher(SampleBatch, FORCE_TOPIC, SAMPLE_QOS)
        self.velocity = self.create_publisher(SampleBatch, VELOCITY_TOPIC, SAMPLE_QOS)

    def play(self, session, first: int, stop: int | None = None) -> None:
        for start in range(first, stop or session.force_n.size, BATCH):
            stamp = msgs.time_msg(T0_NS + round(start / RATE_HZ * 1e9))
            for channel, samples, publisher in (
                (FORCE, session.force_n, self.force),
                (VELOCITY, session.velocity_m_s, self.velocity),
            ):
                publisher.publish(
                    msgs.sample_batch(
                        samples[start : start + BATCH],
                        quantity=channel,
                        sample_rate_hz=RATE_HZ,
                        first_sample_index=start,
                        stamp=stamp,
                        frame_id='player',
                    )
                )


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    """A three-hit session's bag, and the ids and triggers `fmm replay` finds in it."""
    session = simulated_session(1, spacing_s=8.0)
    bag = tmp_path_factory.mktemp('join') / 'bag'
    with BagWriter(bag, time_origin_ns=T0_NS) as writer:
        writer.write_signals(session.force_n, session.velocity_m_s, RATE_HZ)
    replay = replay_bag(bag, CaptureConfig(window_s=WINDOW_S), threads=1)
    hits = [(r.impact_id, r.trigger_sample_index) for r in replay.results]
    assert [trigger < JOIN for _, trigger in hits] == [True, True, False]
    return session, bag, hits


def joined(ros_graph, session, bag, stop=None):
    analyzer = ros_graph.add(
        Analyzer, parameter_overrides=params(window_s=WINDOW_S, recorder_bag=str(bag))
    )
    listener = ros_graph.add(Listener)
    player = ros_graph.add(Player)
    ros_graph.start()
    assert wait_for(lambda: player.force.get_subscription_count() > 0, 10.0)
    player.play(session, JOIN, stop)
    return analyzer, listener


def test_the_hits_before_the_join_come_from_the_bag_with_the_replays_ids(ros_graph, recorded):
    session, bag, hits = recorded
    analyzer, listener = joined(ros_graph, session, bag)
    assert wait_for(lambda: len(listener.impacts) == 3, 60.0), listener.impacts
    got = sorted((m.impact_id, m.trigger_sample_index) for m in listener.impacts)
    assert got == sorted(hits)
    assert analyzer.restored_from_bag == 2 and len(analyzer.results) == 3
    assert all(m.accepted for m in listener.impacts)
    (impacts,) = [s for s in analyzer.health.statuses() if s.name.endswith(': impacts')]
    assert "2 hits before it read from the recorder's bag" in impacts.message, impacts.message
    # The level averages take every hit of the session again.
    assert wait_for(lambda: {s.level for s in listener.summaries} >= {'low', 'medium', 'high'})


def test_a_hit_the_bag_says_was_reported_is_not_reported_again(ros_graph, recorded, tmp_path):
    session, _, hits = recorded
    (first_id, _), *_ = hits
    bag = tmp_path / 'bag'
    with BagWriter(bag, time_origin_ns=T0_NS) as writer:
        writer.write_signals(session.force_n, session.velocity_m_s, RATE_HZ)
        store = fmm_typestore()
        writer.write_message(
            IMPACTS_TOPIC, new_message(store, IMPACT_RESULT, impact_id=first_id), T0_NS
        )
    analyzer, listener = joined(ros_graph, session, bag)
    assert wait_for(lambda: analyzer.restored_from_bag == 2, 60.0)
    assert wait_for(lambda: len(listener.impacts) == 2, 30.0), listener.impacts
    assert sorted(m.impact_id for m in listener.impacts) == sorted(i for i, _ in hits[1:])
    assert len(analyzer.results) == 3  # the first is in the averages all the same
    assert np.isfinite([r.impulse_n_s for r in analyzer.results]).all()


def test_a_stream_that_stops_soon_after_the_join_still_gets_the_bags_hits(
    ros_graph, recorded, monkeypatch
):
    """Respawned near a session's end: the stream never gets a record past the join."""
    session, bag, hits = recorded
    monkeypatch.setattr(analyzer_node, 'BAG_WAIT_S', 1.0)
    analyzer, listener = joined(ros_graph, session, bag, stop=JOIN + 3 * BATCH)
    assert wait_for(lambda: len(listener.impacts) == 2, 30.0), listener.impacts
    assert sorted(m.impact_id for m in listener.impacts) == sorted(i for i, _ in hits[:2])
    assert analyzer.restored_from_bag == 2
