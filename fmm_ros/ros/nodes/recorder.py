"""recorder: writes live topics to a rosbag2 bag (MCAP by default) with the rosbags library.

Subscribes raw (rclpy hands over the serialized CDR bytes) and stores those bytes as they
came, so recording costs no decode/encode. The fmm topics are subscribed at once with their
known types and QoS (nothing is missed while the graph is discovered); any other topic's
type is read from the graph when a publisher appears, with the subscription QoS following
what the publishers offer, as `ros2 bag record` does. The writer flushes every
`flush_interval_s` (also when the topics go quiet), so a crash loses at most that much.

Every SampleBatch topic also runs through the stream rules for its ledger alone (samples
received, missing, out of sequence, resynchronisations; every message is stored as it came
all the same), the recorder reports its progress to the sources (flow control), and the
ledger goes into the bag's metadata (`custom_data`, key fmm.ledger) when the bag closes:
the bag states its own completeness, which `fmm bag-info` shows. rosbag2 logs only a
dropped count at close and keeps no per-topic loss in the bag (ros2/rosbag2#2007).
The newest session metadata the station published (fmm/session_info) goes into the
metadata too (key fmm.session), so a campaign reads a bag's conditions without decoding it.

A `bag_path` that exists already (a respawned recorder) is never overwritten: the recording
goes to the first free `<bag_path>_<n>` beside it. When the bag before it was never closed
(its recorder was killed) and was written in the last `RESUME_WITHIN_S`, everything it holds
is copied into the new bag first, read by scanning (`_resume`), so the newest bag holds the
whole session: `fmm bag-info` and `fmm replay` of it read every message either recorder
stored, the killed one's bag stays as it was, and the new ledger counts the samples of the
downtime missing, unless the fitter still holds them: the stretch each channel lacks is
recalled from its history (`fmm_ros.ros.recall`) and stored before the live batches after it.
What the new recorder hears again from transient-local publishers
(impacts, decisions) that the copy holds already is not stored twice. Storage that fails
under the recorder (disk full, a read-only path, a vanished mount) ends the recording, not
the node (`_fail`).
"""

import hashlib
import json
import time
from datetime import datetime
from pathlib import Path

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from fmm_interfaces.msg import SampleBatch, SessionInfo
from fmm_ros.constants import (
    APPLIED_FORCE_TOPIC,
    CLOCK_TOPIC,
    DECISIONS_TOPIC,
    DIAGNOSTICS_TOPIC,
    FORCE_TOPIC,
    FRF_TOPIC,
    FRICTION_TOPIC,
    IMPACTS_TOPIC,
    LIVE_TOPICS,
    RECORDED_TOPICS,
    SESSION_INFO_TOPIC,
    VELOCITY_TOPIC,
)
from fmm_ros.core.signal.stream import AlignedStream, LedgerOnly
from fmm_ros.errors import FmmError
from fmm_ros.io.bags.definitions import SAMPLE_BATCH
from fmm_ros.io.bags.errors import BagError
from fmm_ros.io.bags.metadata import LEDGER_KEY, ledger_text
from fmm_ros.io.bags.reader import BagReader
from fmm_ros.io.bags.writer import WRITE_ERRORS, BagWriter, bag_qos, free_bag_path
from fmm_ros.io.session_info import SESSION_KEY, from_message, to_json
from fmm_ros.ros import msgs
from fmm_ros.ros.common import message_class, run_node, shared_params
from fmm_ros.ros.flow import ProgressReporter
from fmm_ros.ros.health import (
    ERROR,
    OK,
    WARN,
    ChannelRate,
    FaultLog,
    Health,
    stream_status,
)
from fmm_ros.ros.params import Param, declare_parameters
from fmm_ros.ros.qos import (
    CLOCK_QOS,
    DECISION_QOS,
    DIAGNOSTICS_QOS,
    DISPLAY_QOS,
    RESULT_QOS,
    SAMPLE_QOS,
    SESSION_INFO_QOS,
    recording_qos,
)
from fmm_ros.ros.recall import GapRecall

PARAMS = (
    Param(
        'topics',
        list(RECORDED_TOPICS),
        'Topics to record (relative names resolve in the node namespace)',
        read_only=True,
    ),
    Param('bag_path', '', 'Bag directory to create; "" for fmm_<date>_<time> here', read_only=True),
    *shared_params('storage'),
    Param(
        'flush_interval_s',
        1.0,
        'Longest stretch of recording a crash can lose [s]',
        limits=(0.01, 3600.0),
        read_only=True,
    ),
    Param(
        'discovery_period_s',
        0.5,
        'How often topics not seen yet are looked for [s]',
        limits=(0.01, 60.0),
        read_only=True,
    ),
)

# A bag never closed and written this recently [s] was a killed recorder's of this session
# (a respawn takes seconds to a minute): copied into the new bag. An older one is another
# session's (a crash yesterday), left alone.
RESUME_WITHIN_S = 600.0

# Topics of this package: type and the QoS their publishers offer.
KNOWN_TOPICS = {
    FORCE_TOPIC: ('fmm_interfaces/msg/SampleBatch', SAMPLE_QOS),
    VELOCITY_TOPIC: ('fmm_interfaces/msg/SampleBatch', SAMPLE_QOS),
    APPLIED_FORCE_TOPIC: ('fmm_interfaces/msg/SampleBatch', SAMPLE_QOS),
    IMPACTS_TOPIC: ('fmm_interfaces/msg/ImpactResult', RESULT_QOS),
    FRF_TOPIC: ('fmm_interfaces/msg/FrfSummary', RESULT_QOS),
    FRICTION_TOPIC: ('fmm_interfaces/msg/FrictionEstimate', RESULT_QOS),
    DIAGNOSTICS_TOPIC: ('diagnostic_msgs/msg/DiagnosticArray', DIAGNOSTICS_QOS),
    CLOCK_TOPIC: ('rosgraph_msgs/msg/Clock', CLOCK_QOS),
    **{topic: ('fmm_interfaces/msg/DisplayPoint', DISPLAY_QOS) for topic in LIVE_TOPICS.values()},
    DECISIONS_TOPIC: ('fmm_interfaces/msg/ImpactDecision', DECISION_QOS),
    SESSION_INFO_TOPIC: ('fmm_interfaces/msg/SessionInfo', SESSION_INFO_QOS),
}


class Recorder(Node):
    """Raw subscriptions on the chosen topics, each message stored as received."""

    def __init__(self, **kwargs) -> None:
        super().__init__('recorder', **kwargs)
        self.config = declare_parameters(self, PARAMS)
        asked = Path(self.config['bag_path'] or datetime.now().strftime('fmm_%Y%m%d_%H%M%S'))
        self.writer = BagWriter(
            free_bag_path(asked),
            storage=self.config['storage'],
            flush_interval_s=self.config['flush_interval_s'],
        )
        self.bag_path = self.writer.path
        if self.bag_path != asked:
            self.get_logger().warning(
                f'{asked} exists already (a recorder before this one): recording to '
                f'{self.bag_path} beside it'
            )
        self.failed = ''
        """Why the bag stopped being written ('' while it is written)."""
        self.messages_recorded = 0
        self._session_info: bytes | None = None  # the newest, serialized
        self.messages_not_recorded = 0
        try:
            self.writer.open()
        except BagError as error:
            self._fail(error)
        self._pending = []
        self._raw_subscriptions = []
        # Per SampleBatch topic (resolved name): the stream rules, for the ledger alone.
        self._streams: dict[str, AlignedStream] = {}
        self._rates: dict[str, ChannelRate] = {}
        self.reporter = ProgressReporter(self, [])
        self.last_batch_at = 0.0  # a consumer of batches: drained before it stops
        self._faults = FaultLog(self)
        health = Health(self)
        health.add('stream', lambda: stream_status(self.ledger, self._rates))
        health.add('recorder', self._status)
        for topic in filter(None, self.config['topics']):
            if topic in KNOWN_TOPICS:
                self._subscribe(topic, *KNOWN_TOPICS[topic])
            else:
                self._pending.append(topic)
        # Digests of transient-local messages copied from a killed recorder's bag: the same
        # bytes heard again from their publisher are not stored twice.
        self._copied: set[tuple[str, bytes]] = set()
        self._recall = GapRecall(self, self._store_sample_batch)
        previous = _predecessor(asked, self.bag_path)
        if previous is not None and not (previous / 'metadata.yaml').exists() and not self.failed:
            written_s = time.time() - max(
                (p.stat().st_mtime for p in previous.iterdir()), default=0.0
            )
            if written_s <= RESUME_WITHIN_S:
                self._resume(previous)
            else:
                self.get_logger().warning(
                    f'{previous} was never closed, but last written {written_s:.0f} s ago: '
                    'another session, not copied into this bag'
                )
        self._discover()
        self._timer = self.create_timer(self.config['discovery_period_s'], self._discover)
        recorded = [sub.topic_name for sub in self._raw_subscriptions]
        self.get_logger().info(
            f'recording {", ".join(recorded) or "nothing yet"} to {self.bag_path} '
            f'({self.config["storage"]})'
            + (f'; waiting for {", ".join(self._pending)}' if self._pending else '')
        )

    @property
    def ledger(self):
        """Each SampleBatch topic's ledger, by resolved topic name."""
        return {topic: stream.ledger[topic] for topic, stream in self._streams.items()}

    def _resume(self, previous: Path) -> None:
        """Copy an unclosed bag (its recorder killed) into this one before recording on.

        Read by scanning up to where the killed recorder got; sample batches go through the
        ledger streams as if heard, so the ledger covers the whole session. A bag that cannot
        be read is named and left; this recording goes on.
        """
        copied = 0
        try:
            with BagReader(previous, strict=False) as reader:
                for message in reader.messages():
                    data = bytes(message.data)
                    if message.topic in self._streams:
                        self._store_batch(message.topic, message.msgtype, data, message.log_time_ns)
                    else:
                        self._store(message.topic, message.msgtype, data, message.log_time_ns)
                        self._copied.add((message.topic, hashlib.sha1(data).digest()))
                    copied += 1
        except (OSError, FmmError) as error:
            self.get_logger().error(
                f'{previous} was not closed and cannot be read ({error}): {copied} messages '
                f'of it copied into {self.bag_path}; the rest is only in {previous}'
            )
            return
        for topic, stream in self._streams.items():
            if stream.started:
                self._recall.expect(topic, stream.next_index(topic))
        self.get_logger().warning(
            f'{previous} was not closed (its recorder was killed): its {copied} messages '
            f'copied into {self.bag_path}, which records on (the session whole in one bag; '
            f'{previous} is left as it was)'
        )

    def _fail(self, error: Exception) -> None:
        """The storage failed (disk full, read-only path, mount gone): close the bag as it is.

        One log line and ERROR on /diagnostics, no traceback; the bag stays readable up to
        where it got (the reader recovers it by scanning); the recorder goes on consuming and
        reporting its progress, so the sources and the other nodes go on.
        """
        self.failed = f'{type(error).__name__}: {error}'
        self.writer.abandon()
        self.get_logger().error(
            f'recording to {self.bag_path} stopped: {self.failed}; the bag is closed as it '
            'stands (readable up to here), the rig goes on unrecorded'
        )

    def _status(self) -> tuple:
        if self.failed:
            return (
                ERROR,
                f'not recording: {self.failed} (bag {self.bag_path} closed after '
                f'{self.writer.messages_written} messages; {self.messages_not_recorded} since)',
                {
                    'bag': str(self.bag_path),
                    'messages written': self.writer.messages_written,
                    'messages not recorded': self.messages_not_recorded,
                    'failure': self.failed,
                },
            )
        since_flush = (
            (time.time_ns() - self.writer.last_flush_wall_ns) / 1e9
            if self.writer.last_flush_wall_ns
            else 0.0
        )
        interval = self.writer.flush_interval_s
        late = interval is not None and self.writer.unflushed and since_flush > 3 * interval
        return (
            WARN if late else OK,
            f'{self.writer.messages_written} messages, {self.writer.bytes_written / 1e6:.1f} MB '
            f'to {self.bag_path}'
            + (
                f'; {self.writer.unflushed} not flushed for {since_flush:.1f} s (flushes every '
                f'{interval:g} s: the executor was busy)'
                if late
                else ''
            ),
            {
                'bag': str(self.bag_path),
                'messages written': self.writer.messages_written,
                'bytes written': self.writer.bytes_written,
                'seconds since last flush': since_flush,
                'messages not flushed yet': self.writer.unflushed,
                'topics recorded': len(self._raw_subscriptions),
                'topics waited for': ', '.join(self._pending) or 'none',
            },
        )

    @property
    def waiting_for(self) -> list[str]:
        """Topics asked for that no publisher has offered yet."""
        return list(self._pending)

    def _bound_silence(self, final: bool = False) -> None:
        """A channel silent while another of its acquisition runs on: named, then counted.

        Each topic has its own stream here, so nothing else would count it (the bag
        of a stalled rig_sim held velocity to sample 726,500 and force to 6,890,000, its
        ledger 0 missing). Channels of one acquisition (one rate, one clock) are partners.
        While recording, a channel more than the stream's max_skew_s behind its leading
        partner is named in the log with the span (it may still come: a stalled relay
        delivers its backlog, which must not then be refused); at the close (final) what it
        still lacks up to the partner's end is declared missing in its ledger.
        """
        started = [(topic, stream) for topic, stream in self._streams.items() if stream.started]
        for topic, stream in started:
            ends = [
                other.next_index(name)
                for name, other in started
                if other is not stream
                and other.sample_rate_hz == stream.sample_rate_hz
                and abs((other.origin_s or 0.0) - (stream.origin_s or 0.0))
                <= stream.rules.clock_tolerance_s
            ]
            if not ends:
                continue
            start, lead = stream.next_index(topic), max(ends)
            if final and lead > start:
                stream.declare_missing(topic, lead)
                self.get_logger().warning(
                    f'{topic}: samples {start}..{lead} missing at the close (its partner ran on)'
                )
            elif lead - start > stream.rules.max_skew_s * stream.sample_rate_hz:
                self.get_logger().warning(
                    f'{topic}: nothing from sample {start} on while another channel of the '
                    f'acquisition is at {lead}',
                    throttle_duration_sec=10.0,
                )

    def _discover(self) -> None:
        """Subscribe to every pending topic that now has a publisher; flush what waited."""
        self._recall.poll()
        self._bound_silence()
        if not self.failed:
            try:
                self.writer.flush_if_due()
            except WRITE_ERRORS as error:
                self._fail(error)
        for topic in list(self._pending):
            publishers = self.get_publishers_info_by_topic(topic)
            types = {info.topic_type for info in publishers}
            if not types:
                continue
            if len(types) > 1:
                self.get_logger().error(
                    f'{topic} is published with several types {types}: not recorded',
                    throttle_duration_sec=30.0,
                )
                continue
            self._subscribe(
                topic, types.pop(), recording_qos([info.qos_profile for info in publishers])
            )
            self._pending.remove(topic)

    def _subscribe(self, topic: str, msgtype: str, qos: QoSProfile) -> None:
        resolved = self.resolve_topic_name(topic)
        self._declare(
            resolved,
            msgtype,
            bag_qos(
                keep_all=qos.history == HistoryPolicy.KEEP_ALL,
                depth=qos.depth,
                reliable=qos.reliability == ReliabilityPolicy.RELIABLE,
                transient_local=qos.durability == DurabilityPolicy.TRANSIENT_LOCAL,
            ),
        )
        store = self._store
        if msgtype == SAMPLE_BATCH:
            self._streams[resolved] = AlignedStream(LedgerOnly(), quantities=(resolved,))
            self.reporter.add(resolved)
            store = self._store_batch
        self._raw_subscriptions.append(
            self.create_subscription(
                message_class(msgtype),
                resolved,
                lambda data, topic=resolved, msgtype=msgtype: store(topic, msgtype, data),
                qos,
                raw=True,
            )
        )

    def _declare(self, topic: str, msgtype: str, qos) -> None:
        """Declare a topic in the bag (nothing once the storage failed)."""
        if self.failed:
            return
        try:
            self.writer.add_topic(topic, msgtype, qos=qos)
        except WRITE_ERRORS as error:
            self._fail(error)

    def _store(self, topic: str, msgtype: str, data: bytes, log_time_ns: int | None = None) -> None:
        if self._copied and log_time_ns is None:
            digest = (topic, hashlib.sha1(data).digest())
            if digest in self._copied:  # a transient-local message the copy holds already
                self._copied.discard(digest)
                return
        if self.failed:
            self.messages_not_recorded += 1
            return
        try:
            self.writer.write_raw(topic, msgtype, data, log_time_ns or time.time_ns())
        except WRITE_ERRORS as error:
            self.messages_not_recorded += 1
            self._fail(error)
            return
        self.messages_recorded += 1
        if msgtype == 'fmm_interfaces/msg/SessionInfo':
            self._session_info = data

    def _store_batch(
        self, topic: str, msgtype: str, data: bytes, log_time_ns: int | None = None
    ) -> None:
        """Store a SampleBatch as it came; account for it by the stream rules.

        A live batch past the stretch a resumed copy lacks waits in `_recall` (reported
        taken) until that stretch is recalled from the fitter, so the bag stays in order.
        """
        self.last_batch_at = time.monotonic()
        msg = deserialize_message(data, SampleBatch)
        if log_time_ns is None and self._recall.take(topic, msgtype, data, msg):
            self.reporter.update(topic, self._recall.ahead[topic], msg.sample_rate_hz)
            return
        self._store_sample_batch(topic, msgtype, data, msg, log_time_ns)

    def _store_sample_batch(
        self, topic: str, msgtype: str, data: bytes, msg: SampleBatch, log_time_ns: int | None
    ) -> None:
        self._store(topic, msgtype, data, log_time_ns)
        stream = self._streams[topic]
        batch = msgs.stream_batch(msg)
        try:
            stream.feed(topic, batch)
        except ValueError:
            stream.refuse_malformed(topic, len(batch.samples))
        self._rates.setdefault(topic, ChannelRate()).newest_stamp_ns = batch.stamp_ns
        taken = max(stream.next_index(topic), self._recall.ahead.get(topic, 0))
        self.reporter.update(topic, taken, stream.sample_rate_hz)
        self._faults.check(stream.ledger, f'at {batch.first_sample_index}')

    def destroy_node(self) -> None:
        """Close the bag (MCAP summary, metadata.yaml with the ledger) before the node goes.

        The bag is closed whatever goes wrong in writing its metadata: a fault there is logged
        and the samples stay readable without a recovery scan.
        """
        try:
            self._write_closing_metadata()
        except Exception as error:  # the last resort: the bag must still be closed
            self.get_logger().error(f'bag metadata incomplete: {type(error).__name__}: {error}')
        try:
            self.writer.close()
        except WRITE_ERRORS as error:  # the storage failed as the bag closed
            self._fail(error)
        super().destroy_node()

    def _write_closing_metadata(self) -> None:
        """The ledger, the session's metadata and the recorder's own line, for metadata.yaml."""
        self._recall.flush()
        for stream in self._streams.values():
            stream.finish()
        self._bound_silence(final=True)
        self.writer.set_custom_data(LEDGER_KEY, ledger_text(self.ledger))
        if self._session_info is not None:
            try:
                info = from_message(deserialize_message(self._session_info, SessionInfo))
                self.writer.set_custom_data(SESSION_KEY, to_json(info))
            except FmmError as error:  # the message itself is in the bag all the same
                self.get_logger().error(f'session metadata not put in the bag metadata: {error}')
        for ledger in self.ledger.values():
            self.get_logger().info(f'stopped: {ledger.summary()}')
        self.writer.set_custom_data(
            'fmm.recorder',
            json.dumps(
                {
                    'node': self.get_fully_qualified_name(),
                    'flush_interval_s': self.config['flush_interval_s'],
                    'closed_ns': time.time_ns(),
                }
            ),
        )


def _predecessor(asked: Path, chosen: Path) -> Path | None:
    """The bag a recorder before this one wrote at `asked` (None when chosen is asked)."""
    if chosen == asked:
        return None
    number = int(chosen.name.rsplit('_', 1)[1])
    return asked if number == 1 else asked.with_name(f'{asked.name}_{number - 1}')


def main(args: list[str] | None = None) -> int:
    """`ros2 run fmm_ros recorder`."""
    return run_node(Recorder, args)


if __name__ == '__main__':
    main()
