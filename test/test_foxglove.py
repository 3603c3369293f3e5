"""Foxglove: the rig served over the Foxglove WebSocket protocol, read by Foxglove's own client.

The client is Foxglove's npm `@foxglove/ws-protocol` with Foxglove's ROS 2 decoder
(`@foxglove/rosmsg2-serialization`), run with node (test/foxglove_client/subscribe.js,
installed by launch_scripts/setup_env.sh): an independent consumer that must decode force,
impacts and mu from a running graph to what the graph's own subscribers received, each at
its signal-time stamp. The shipped layout must be the one declared in code, and name only
topics and fields the server offers.
"""

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from rclpy.serialization import serialize_message
from rig_graph import FAST_ANALYZER, FAST_HAMMER, Listener, params, wait_for

from fmm_interfaces.msg import FrictionEstimate
from fmm_ros.io.bags.definitions import fmm_typestore
from fmm_ros.ros import msgs
from fmm_ros.ros.foxglove_layout import LAYOUT_FILE, layout_text
from fmm_ros.ros.nodes.foxglove_server import SERVED_TOPICS, leading_stamp_ns
from fmm_ros.ros.nodes.recorder import KNOWN_TOPICS

CLIENT = Path(__file__).resolve().parent / 'foxglove_client'


def test_the_shipped_layout_is_the_one_declared_in_code():
    assert LAYOUT_FILE.read_text(encoding='utf-8') == layout_text(), (
        'config/foxglove/fmm_rig_layout.json is stale: '
        '.venv/bin/python -m fmm_ros.ros.foxglove_layout'
    )


def test_the_layout_plots_only_fields_the_server_offers():
    """Every message path of the layout is topic.field[...] of a served topic's type."""
    store = fmm_typestore()
    served = {'/' + topic.lstrip('/'): KNOWN_TOPICS[topic][0] for topic in SERVED_TOPICS}
    paths = re.findall(r'"(?:value|topicPath|topicToRender)": "(/[^"]+)"', layout_text())
    assert len(paths) >= 10
    for path in paths:
        topic, _, field_path = path.partition('.')
        assert topic in served, path
        if field_path:
            field = re.sub(r'\[.*\]$', '', field_path.split('.')[0])
            names = [name for name, _ in store.fielddefs[served[topic]][1]]
            assert field in names, f'{path}: {served[topic]} has no field {field}'


def test_the_log_time_is_read_from_the_serialized_stamp():
    message = FrictionEstimate()
    message.header.stamp = msgs.time_msg(1_732_000_123_456_789_012)
    message.mu = 0.113
    assert leading_stamp_ns(serialize_message(message)) == 1_732_000_123_456_789_012
    assert leading_stamp_ns(b'\x00\x01\x00\x00\x01') is None  # too short: no stamp
    assert leading_stamp_ns(b'\x00\x00\x00\x00' + bytes(8)) is None  # big-endian CDR


def _client(url: str, seconds: float, counts: dict[str, int]) -> subprocess.Popen:
    node = shutil.which('node')
    assert node, 'node is not on PATH: launch_scripts/setup_env.sh installs it'
    assert (CLIENT / 'node_modules' / '@foxglove' / 'ws-protocol').is_dir(), (
        'the npm client is not installed: run launch_scripts/setup_env.sh'
    )
    return subprocess.Popen(
        [node, str(CLIENT / 'subscribe.js'), url, str(seconds)]
        + [f'{topic}={count}' for topic, count in counts.items()],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.ros
@pytest.mark.slow
def test_foxglove_s_own_client_decodes_force_impacts_and_mu_from_a_running_graph(ros_graph):
    from fmm_ros.ros.flow import PacedSource
    from fmm_ros.ros.nodes.analyzer import Analyzer
    from fmm_ros.ros.nodes.fitter import Fitter
    from fmm_ros.ros.nodes.foxglove_server import FoxgloveServer
    from fmm_ros.ros.nodes.hammer_sim import HammerSim
    from fmm_ros.ros.nodes.live import Live
    from fmm_ros.ros.nodes.rig_sim import RigSim

    hammer = ros_graph.add(
        HammerSim,
        parameter_overrides=params(**FAST_HAMMER | dict(rate_factor=20.0)),
    )
    ros_graph.add(RigSim)
    ros_graph.add(Analyzer, parameter_overrides=params(**FAST_ANALYZER))
    ros_graph.add(Fitter)
    ros_graph.add(Live)
    server = ros_graph.add(FoxgloveServer, parameter_overrides=params(port=0))
    listener = ros_graph.add(Listener)
    counts = {'/fmm/force': 20, '/fmm/live/force': 200, '/fmm/impacts': 3, '/fmm/friction': 3}
    client = _client(f'ws://127.0.0.1:{server.port}', 90.0, counts)
    # The client subscribes to what the server advertised before the session starts.
    assert wait_for(lambda: server.listener.count == len(counts), 20.0), client.stderr.read()
    ros_graph.start()
    out, err = client.communicate(timeout=120.0)
    assert client.returncode == 0, err
    *messages, times = [json.loads(line) for line in out.splitlines()]
    by_topic = {topic: [m for m in messages if m['topic'] == topic] for topic in counts}
    assert wait_for(lambda: len(listener.friction) == 3, 30.0)

    impacts = [m['message'] for m in by_topic['/fmm/impacts']]
    assert [(m['impact_id'], m['level'], m['accepted'], m['peak_force_n']) for m in impacts] == [
        (m.impact_id, m.level, m.accepted, m.peak_force_n) for m in listener.impacts
    ]
    friction = [m['message'] for m in by_topic['/fmm/friction']]
    assert [(m['impact_id'], m['count'], m['mu'], m['mu_stderr']) for m in friction] == [
        (m.impact_id, m.count, m.mu, m.mu_stderr) for m in listener.friction
    ]
    assert 0.10 < friction[-1]['mu'] < 0.13

    start_ns = hammer._start_stamp.nanoseconds
    size = PacedSource.paced_batch(hammer.config, 1e4, FAST_HAMMER['batch_size'], 20.0)
    for batch in (m['message'] for m in by_topic['/fmm/force']):
        assert (batch['quantity'], batch['unit'], batch['sample_rate_hz']) == ('force', 'N', 1e4)
        assert batch['samples']['length'] == size and batch['first_sample_index'] % size == 0
        stamp_ns = batch['header']['stamp']['sec'] * 10**9 + batch['header']['stamp']['nanosec']
        assert stamp_ns == start_ns + batch['first_sample_index'] * 100_000
    points = [m['message'] for m in by_topic['/fmm/live/force']]
    assert max(p['value'] for p in points) > 400.0  # a hit's peak survives the decimation
    assert all(p['minimum'] <= p['value'] <= p['maximum'] for p in points)
    # None lost on the way: each 4,000-sample batch is a burst of 20 points, which a queue of
    # SAMPLE_QOS's depth dropped four in five of (DISPLAY_QOS).
    assert [p['first_sample_index'] for p in points] == [
        points[0]['first_sample_index'] + sum(p['sample_count'] for p in points[:i])
        for i in range(len(points))
    ]

    # One time base: every message's log time is its header stamp (signal time), the
    # friction estimate's that of the impact it adds, and the server's clock is signal time.
    for message in messages:
        stamp = message['message']['header']['stamp']
        assert int(message['logTimeNs']) == stamp['sec'] * 10**9 + stamp['nanosec'], message
    impact_log = {m['message']['impact_id']: m['logTimeNs'] for m in by_topic['/fmm/impacts']}
    for estimate in by_topic['/fmm/friction']:
        assert estimate['logTimeNs'] == impact_log[estimate['message']['impact_id']]
    signal_end_ns = start_ns + hammer.next_index * 100_000
    server_times = [int(t) for t in times['time']]
    assert server_times and server_times == sorted(server_times)
    assert start_ns < server_times[-1] <= signal_end_ns


@pytest.mark.slow
def test_fmm_foxglove_refuses_a_port_that_is_none(capsys):
    from fmm_ros.cli import main

    assert main(['foxglove', '--port', '70000']) == 2
    assert '--port 70000 is not a TCP port' in capsys.readouterr().err


@pytest.mark.ros
@pytest.mark.slow
def test_a_port_already_served_is_refused_with_the_reason(ros_graph):
    from fmm_ros.errors import BadInputError
    from fmm_ros.ros.nodes.foxglove_server import FoxgloveServer

    first = ros_graph.add(FoxgloveServer, parameter_overrides=params(port=0))
    with pytest.raises(BadInputError, match=f'cannot serve on 127.0.0.1:{first.port}: .*in use'):
        FoxgloveServer(context=ros_graph.context, parameter_overrides=params(port=first.port))
