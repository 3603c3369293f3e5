"""The station node's judging service and modes, in one process without a rig.

A stand-in analyzer publishes ImpactResults; the station must refuse a decision about a hit
it has not seen or a malformed one (saying why), publish a good one on fmm/impact_decisions,
hold every new hit pending in manual mode, and let a judge function decide once the hit's
record has arrived.
"""

import os
import signal
import subprocess
import sys
import types
import urllib.request

import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rig_graph import wait_for

from fmm_interfaces.msg import ImpactDecision, ImpactResult, SampleBatch
from fmm_interfaces.srv import JudgeImpact
from fmm_ros.constants import DECISIONS_TOPIC, FORCE, IMPACTS_TOPIC, JUDGE_SERVICE, VELOCITY
from fmm_ros.ros import msgs
from fmm_ros.ros.graph import private_domain_id
from fmm_ros.ros.nodes.station import Station
from fmm_ros.ros.qos import DECISION_QOS, RESULT_QOS, SAMPLE_QOS

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RATE_HZ = 1000.0


class StandIn(Node):
    """Publishes impacts and samples as the analyzer and a source would; hears decisions."""

    def __init__(self, **kwargs):
        super().__init__('stand_in', **kwargs)
        self.impacts = self.create_publisher(ImpactResult, IMPACTS_TOPIC, RESULT_QOS)
        self.force = self.create_publisher(SampleBatch, 'fmm/force', SAMPLE_QOS)
        self.velocity = self.create_publisher(SampleBatch, 'fmm/velocity', SAMPLE_QOS)
        self.decisions: list[ImpactDecision] = []
        self.create_subscription(
            ImpactDecision, DECISIONS_TOPIC, self.decisions.append, DECISION_QOS
        )
        self.judge = self.create_client(JudgeImpact, JUDGE_SERVICE)
        self.t0_ns = self.get_clock().now().nanoseconds  # sample 0 of the acquisition

    def impact(self, impact_id: int, peak: float) -> None:
        msg = ImpactResult()
        msg.impact_id = impact_id
        msg.header.stamp = msgs.time_msg(self.t0_ns + round(100 / RATE_HZ * 1e9))
        msg.trigger_sample_index = 100
        msg.record_start_sample_index = 0
        msg.record_duration_s = 1.0
        msg.sample_rate_hz = RATE_HZ
        msg.level = 'low'
        msg.accepted = True
        msg.peak_force_n = peak
        self.impacts.publish(msg)

    def samples(self) -> None:
        """One second of both channels from sample 0: the record of every impact above."""
        stamp = msgs.time_msg(self.t0_ns)
        force = np.zeros(1000)
        force[100:105] = 400.0
        for publisher, channel, values in (
            (self.force, FORCE, force),
            (self.velocity, VELOCITY, np.zeros(1000)),
        ):
            publisher.publish(
                msgs.sample_batch(
                    values,
                    quantity=channel,
                    sample_rate_hz=RATE_HZ,
                    first_sample_index=0,
                    stamp=stamp,
                    frame_id='test',
                )
            )


def station(graph, **values):
    values = {'port': 0, **values}
    return graph.add(
        Station, parameter_overrides=[Parameter(k, value=v) for k, v in values.items()]
    )


def request(impact_id, verdict='reject', decided_by='kb', reason=''):
    return JudgeImpact.Request(
        impact_id=impact_id, verdict=verdict, decided_by=decided_by, reason=reason
    )


def test_the_judge_service_refuses_what_it_cannot_take_and_publishes_the_rest(ros_graph):
    stand_in = ros_graph.add(StandIn)
    node = station(ros_graph)
    ros_graph.start()
    stand_in.impact(3, 455.0)
    assert wait_for(lambda: node.state.known(3) is not None, timeout_s=10.0)
    unknown = ros_graph.call(stand_in.judge, request(7))
    assert not unknown.success and 'impact 7 is not a hit this station has seen' in unknown.message
    nameless = ros_graph.call(stand_in.judge, request(3, decided_by=''))
    assert not nameless.success and 'who decided is not given' in nameless.message
    odd = ros_graph.call(stand_in.judge, request(3, verdict='delete'))
    assert not odd.success and "verdict 'delete'" in odd.message
    done = ros_graph.call(stand_in.judge, request(3, reason='hammer slipped'))
    assert done.success and done.message == 'impact 3 rejected by kb (hammer slipped)'
    assert wait_for(lambda: stand_in.decisions, timeout_s=10.0)
    (decision,) = stand_in.decisions
    assert (decision.impact_id, decision.verdict, decision.trigger_sample_index) == (
        3,
        'reject',
        100,
    )
    assert wait_for(lambda: not node.state.snapshot()['hits'][0]['taken'], timeout_s=10.0)


def test_manual_mode_holds_each_new_hit_pending(ros_graph):
    stand_in = ros_graph.add(StandIn)
    station(ros_graph, judge_mode='manual')
    ros_graph.start()
    stand_in.impact(5, 455.0)
    assert wait_for(lambda: stand_in.decisions, timeout_s=10.0)
    assert [(d.impact_id, d.verdict, d.decided_by) for d in stand_in.decisions] == [
        (5, 'pending', 'station')
    ]


def test_a_judge_function_decides_once_the_hit_record_is_cut(ros_graph, monkeypatch):
    module = types.ModuleType('station_judges')
    module.soft_only = lambda record, result: (
        bool(record.force_n.max() < 1000.0) and result.peak_force_n < 1000.0,
        f'peak {result.peak_force_n:.0f} N',
    )
    monkeypatch.setitem(sys.modules, 'station_judges', module)
    stand_in = ros_graph.add(StandIn)
    station(ros_graph, judge_mode='function', judge_function='station_judges:soft_only')
    ros_graph.start()
    stand_in.impact(8, 1200.0)
    stand_in.samples()
    assert wait_for(lambda: stand_in.decisions, timeout_s=10.0)
    (decision,) = stand_in.decisions
    assert (decision.verdict, decision.decided_by, decision.reason) == (
        'reject',
        'station_judges:soft_only',
        'peak 1200 N',
    )


def test_fmm_station_serves_the_page_and_stops_cleanly(tmp_path):
    """`fmm station` beside a graph: it serves the page, and Ctrl-C ends it with status 0."""
    env = {
        **os.environ,
        'ROS_DOMAIN_ID': str(private_domain_id()),
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST',
    }
    fmm = os.path.join(os.path.dirname(sys.executable), 'fmm')
    log = tmp_path / 'station.log'
    with open(log, 'wb') as out:
        process = subprocess.Popen(
            [fmm, 'station', '--port', '0', '--judge-mode', 'manual'],
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    try:
        assert wait_for(lambda: 'station page on' in log.read_text(), timeout_s=60.0)
        url = log.read_text().split('station page on ', 1)[1].split()[0]
        with urllib.request.urlopen(url, timeout=10) as response:
            page = response.read().decode()
        assert 'vendor/uplot/uPlot.iife.min.js' in page and 'https://' not in page
        assert '(judging: manual)' in log.read_text()
    finally:
        process.send_signal(signal.SIGINT)
        code = process.wait(timeout=30)
    assert code == 0, log.read_text()
