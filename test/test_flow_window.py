"""The flow window held under every consumer's max_skew_s (ros/flow.py).

A source runs at most its window ahead of the slowest consumer of any of its channels, and
that is as far as one channel can run ahead of another inside a consumer. Past the
consumer's max_skew_s the lagging channel's samples are declared missing: measured on the
multi-process rig at x50 with flow_window_s 8, the fitter (max_skew_s 5) lost 180,000
velocity samples and refused 36 batches. So each consumer reports its max_skew_s with its
progress, and a source holds its window a batch under the smallest.
"""

import time

import pytest
from rclpy.node import Node
from rig_graph import params, wait_for

from fmm_interfaces.msg import SampleBatch, StreamProgress
from fmm_ros.constants import STREAM_PROGRESS_TOPIC
from fmm_ros.ros.flow import SILENT_AFTER_S, FlowGate, PacedSource, ProgressReporter
from fmm_ros.ros.nodes.analyzer import Analyzer
from fmm_ros.ros.qos import PROGRESS_LISTEN_QOS, PROGRESS_QOS, SAMPLE_QOS

pytestmark = [pytest.mark.ros, pytest.mark.slow]

RATE_HZ = 10_000.0
BATCH = 500
CONFIG = dict(wait_for_consumers=[''], start_timeout_s=0.0, flow_window_s=8.0)


class Reports(Node):
    """Publishes consumers' progress reports and keeps every report it hears."""

    def __init__(self, **kwargs):
        super().__init__('reports', **kwargs)
        self.publisher = self.create_publisher(StreamProgress, STREAM_PROGRESS_TOPIC, PROGRESS_QOS)
        self.heard: list[StreamProgress] = []
        self.create_subscription(
            StreamProgress, STREAM_PROGRESS_TOPIC, self.heard.append, PROGRESS_LISTEN_QOS
        )

    def report(self, node: str, topic: str, max_skew_s: float) -> None:
        message = StreamProgress(node=node, topics=[topic], next_sample_indices=[0])
        message.max_skew_s = max_skew_s
        self.publisher.publish(message)


def test_a_source_holds_its_window_a_batch_under_the_tightest_consumer_skew(ros_graph):
    source = ros_graph.add(Node, node_name='source')
    publisher = source.create_publisher(SampleBatch, 'fmm/test_batches', SAMPLE_QOS)
    reports = ros_graph.add(Reports)
    ros_graph.start()
    paced = PacedSource(
        source,
        [publisher],
        CONFIG,
        batches_per_s=1.0,
        window_samples=PacedSource.window_samples(CONFIG, RATE_HZ, BATCH),
        pace_label='test',
        sample_rate_hz=RATE_HZ,
    )
    # The player paces batches that carry their own rate (sample_rate_hz 0 here).
    player_like = PacedSource(
        source, [publisher], CONFIG, batches_per_s=1.0, window_samples=1, pace_label='player'
    )
    asked = paced.window
    assert paced.window_now(BATCH) == asked  # nobody reported
    for node, skew_s, expected in (
        ('/recorder', 0.0, asked),  # pairs no channels: no limit
        ('/fitter', 5.0, min(asked, 50_000 - BATCH)),
        ('/analyzer', 2.0, 20_000 - BATCH),
        ('/tiny', 0.01, BATCH),  # never under one batch
    ):
        reports.report(node, publisher.topic_name, skew_s)
        assert wait_for(lambda node=node: node in paced.gate.consumers, 10.0), node
        assert paced.window_now(BATCH) == expected, node
    # The same cap, at the batch's own rate and window, for the player (no rate of its own).
    assert wait_for(lambda: '/tiny' in player_like.gate.consumers, 10.0)
    assert player_like.window_now(BATCH) == 1  # no rate: its window as given
    assert player_like.window_now(BATCH, 80_000, RATE_HZ) == BATCH  # /tiny's 0.01 s
    assert player_like.window_now(BATCH, 80_000, 2 * RATE_HZ) == BATCH


def test_a_consumer_reports_its_own_max_skew(ros_graph):
    ros_graph.add(Analyzer, parameter_overrides=params(max_skew_s=3.0))
    reports = ros_graph.add(Reports)
    ros_graph.start()
    assert wait_for(lambda: any(m.node == '/analyzer' for m in reports.heard), 10.0)
    assert {m.max_skew_s for m in reports.heard if m.node == '/analyzer'} == {3.0}


def test_a_consumer_that_pairs_its_channels_reports_both_at_the_slower_one(ros_graph):
    """Force straight from the hammer, velocity through rig_sim: the hammer holds for the pair.

    Reported per channel, the force could run the hammer's window ahead of the velocity and
    rig_sim's window more, past the consumer's max_skew_s (it then declares samples missing).
    """
    pairing = ros_graph.add(Node, node_name='pairing')
    single = ros_graph.add(Node, node_name='single')
    reports = ros_graph.add(Reports)
    topics = ['/fmm/force', '/fmm/velocity']
    paired = ProgressReporter(pairing, topics, max_skew_s=5.0)
    unpaired = ProgressReporter(single, topics)
    ros_graph.start()

    def last(node: str) -> dict[str, int]:
        heard = [m for m in reports.heard if m.node == node]
        if not heard:
            return {}
        return dict(zip(heard[-1].topics, heard[-1].next_sample_indices, strict=True))

    for reporter in (paired, unpaired):
        reporter.update('/fmm/force', 68_000)
    # A channel not begun yet holds nothing back (a force-only rig still runs).
    assert wait_for(lambda: last('/pairing') == {'/fmm/force': 68_000, '/fmm/velocity': -1})
    for reporter in (paired, unpaired):
        reporter.update('/fmm/velocity', 20_000)
    assert wait_for(lambda: last('/pairing') == {'/fmm/force': 20_000, '/fmm/velocity': 20_000})
    assert wait_for(lambda: last('/single') == {'/fmm/force': 68_000, '/fmm/velocity': 20_000})


def progress(node: str, topic: str, index: int) -> StreamProgress:
    return StreamProgress(node=node, topics=[topic], next_sample_indices=[index])


def test_a_source_waits_for_a_killed_consumer_and_counts_it_from_where_it_comes_back(
    ros_graph,
):
    """A respawn: the awaited consumer falls silent, then reports nothing again."""
    source = ros_graph.add(Node, node_name='source')
    publisher = source.create_publisher(SampleBatch, 'fmm/test_batches', SAMPLE_QOS)
    reports = ros_graph.add(Reports)
    consumer = ros_graph.add(Node, node_name='consumer')
    consumer.create_subscription(SampleBatch, 'fmm/test_batches', lambda m: None, SAMPLE_QOS)
    gate = FlowGate(
        source, [publisher], wait_for=['consumer'], start_timeout_s=0.0, silent_after_s=60.0
    )
    ros_graph.start()
    topic = publisher.topic_name
    reports.publisher.publish(progress('/consumer', topic, -1))
    assert wait_for(gate.ready)
    gate.sent(30_000)
    reports.publisher.publish(progress('/consumer', topic, 20_000))
    assert wait_for(lambda: gate.lag() == {'/consumer': 10_000})
    time.sleep(SILENT_AFTER_S + 0.5)  # silent past the default, within silent_after_s
    assert gate.lag() == {'/consumer': 10_000}
    assert not gate.allows(30_000 + BATCH, 10_000)  # the source holds for it
    reports.publisher.publish(progress('/consumer', topic, -1))  # killed and started again
    assert wait_for(lambda: gate.lag() == {'/consumer': 0}), gate.lag()
    gate.sent(31_000)
    assert gate.lag() == {'/consumer': 1000}  # counted from where it came back
    reports.publisher.publish(progress('/consumer', topic, 31_000))
    assert wait_for(lambda: gate.lag() == {'/consumer': 0}), gate.lag()
    # A node that was never awaited (a plot started late) counts from where the source is.
    reports.publisher.publish(progress('/plot', topic, -1))
    assert wait_for(lambda: gate.lag().get('/plot') == 0), gate.lag()


def test_a_consumer_idle_before_the_source_starts_is_not_silent_when_it_starts(ros_graph):
    """Silence counts from when the samples a consumer lags on went out, not its last report.

    Consumers started before the sources report once and then have nothing to say. Counted
    from that report, all of them were left out at the hammer's first batch, and the force
    ran ahead of the velocity in the fitter past its max_skew_s (measured: 10,000 velocity
    samples declared missing, the first impact lost from the live mu).
    """
    source = ros_graph.add(Node, node_name='source')
    publisher = source.create_publisher(SampleBatch, 'fmm/test_batches', SAMPLE_QOS)
    reports = ros_graph.add(Reports)
    gate = FlowGate(source, [publisher], wait_for=[], start_timeout_s=0.0, silent_after_s=1.0)
    ros_graph.start()
    topic = publisher.topic_name
    reports.publisher.publish(progress('/consumer', topic, -1))
    assert wait_for(lambda: gate.consumers == ['/consumer'])
    time.sleep(1.5)  # idle past silent_after_s: nothing was sent
    gate.sent(5_000)
    assert gate.lag() == {'/consumer': 5_000}  # waited for
    time.sleep(1.5)  # now silent with samples outstanding
    assert gate.lag() == {}


def test_a_consumer_known_before_the_acquisition_begins_counts_from_its_first_sample(ros_graph):
    """A relay begins on its first input batch, after its consumers reported nothing taken.

    Their next report of nothing taken (-1) is not a node started late: read as one, rig_sim
    counted the fitter's velocity caught up while the fitter had taken none, the hammer ran on
    and the fitter declared 22,000 velocity samples missing past its max_skew_s.
    """
    source = ros_graph.add(Node, node_name='source')
    publisher = source.create_publisher(SampleBatch, 'fmm/test_batches', SAMPLE_QOS)
    reports = ros_graph.add(Reports)
    consumer = ros_graph.add(Node, node_name='consumer')
    consumer.create_subscription(SampleBatch, 'fmm/test_batches', lambda m: None, SAMPLE_QOS)
    gate = FlowGate(source, [publisher], wait_for=['consumer'], start_timeout_s=0.0)
    ros_graph.start()
    topic = publisher.topic_name
    reports.publisher.publish(progress('/consumer', topic, -1))
    assert wait_for(gate.ready)
    gate.begin(0)
    gate.sent(4_000)
    reports.publisher.publish(progress('/consumer', topic, -1))  # still nothing taken
    time.sleep(0.5)
    assert gate.lag() == {'/consumer': 4_000}
    reports.publisher.publish(progress('/consumer', topic, 4_000))
    assert wait_for(lambda: gate.lag() == {'/consumer': 0}), gate.lag()
