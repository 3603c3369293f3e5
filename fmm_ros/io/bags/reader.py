"""Read rosbag2 bags (MCAP or sqlite3) without ROS: raw messages, aligned sample batches, results.

An intact bag is read with rosbags. A bag that rosbags cannot open or read to the end (a
crashed recording has no metadata.yaml and no MCAP footer; a corrupt chunk stops it) is
read by scanning its MCAP file record by record (mcapscan.py) or its sqlite3 database row
by row (sqlitescan.py): every message before the damage is delivered,
then, with strict=True (the default), a BagDamagedError names the problem; with
strict=False reading goes on past damage where the file's framing allows and the problems
are listed in `problems`.

Messages are decoded with the definitions the bag carries (a bag stays readable after the
.msg files change), falling back to this installation's fmm_interfaces. float64[] fields
come out as numpy arrays viewing the serialized bytes: no copy.
"""

import functools
import sqlite3
from collections import Counter, deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import Reader
from rosbags.typesys import TypesysError, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from fmm_ros.constants import FORCE, FORCE_TOPIC, FRF_TOPIC, IMPACTS_TOPIC, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.signal.stream import (
    DEFAULT_RULES,
    AlignedStream,
    Batch,
    ChannelLedger,
    StreamRules,
)
from fmm_ros.io.bags.definitions import (
    BASE_STORE,
    FRF_SUMMARY,
    IMPACT_RESULT,
    SAMPLE_BATCH,
    fmm_typestore,
)
from fmm_ros.io.bags.errors import BagDamagedError, BagError, MessageTypeError, MissingTopicError
from fmm_ros.io.bags.mcapscan import Damage, McapScan
from fmm_ros.io.bags.metadata import custom_ledger, read_information
from fmm_ros.io.bags.sqlitescan import SqliteScan

if TYPE_CHECKING:  # arrays.py: imported by a whole read only
    from fmm_ros.io.bags.arrays import ChannelArrays

# What rosbags raises on a damaged bag: its own ReaderError, or whatever its parsers meet on
# bad bytes (a KeyError from a corrupt QoS string, apsw.CorruptError from a damaged database
# page, MemoryError or OverflowError when a corrupt length asks for gigabytes). Each means
# the same: the file is read on by scanning, which checks every length against the file.
_ROSBAGS_FAILURES = (Exception,)


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag: its message type and how many messages it holds."""

    topic: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class BagMessage:
    """One stored message: topic, type, log time [ns] and serialized CDR bytes."""

    topic: str
    msgtype: str
    log_time_ns: int
    data: bytes | memoryview


@dataclass(frozen=True)
class ChannelBatch:
    """One SampleBatch of one channel; samples [unit] view the message bytes (read-only)."""

    topic: str
    first_sample_index: int
    samples: np.ndarray
    sample_rate_hz: float
    quantity: str
    unit: str
    full_scale: float
    frame_id: str
    stamp_ns: int
    log_time_ns: int

    @property
    def end_index(self) -> int:
        """Index one past the last sample."""
        return self.first_sample_index + len(self.samples)


@dataclass(frozen=True)
class AlignedBatch:
    """Force [N] and velocity [m/s] over the same sample indices, as the analyzer pairs them.

    gap_samples: samples missing between the previous aligned batch and this one (0 when
    contiguous, and at the start of each acquisition): a dropped batch on either channel shows
    up here. acquisition: which acquisition of the bag it belongs to (1, 2, ... : a DAQ
    restarted mid-recording starts the next).
    """

    first_sample_index: int
    force: np.ndarray
    velocity: np.ndarray
    sample_rate_hz: float
    gap_samples: int
    full_scale_force: float
    full_scale_velocity: float
    acquisition: int = 1

    @property
    def end_index(self) -> int:
        """Index one past the last sample."""
        return self.first_sample_index + len(self.force)


Definitions = tuple[tuple[str, str], ...]  # a bag's embedded (msgtype, .msg text) pairs


@functools.lru_cache(maxsize=16)
def _embedded_types(definitions: Definitions) -> tuple[dict, tuple[str, ...]]:
    """The rosbags field definitions a bag embeds (its (msgtype, text) pairs), and the problems.

    Parsed only, no typestore: a few milliseconds, cached for every bag a recorder wrote.
    """
    embedded: dict = {}
    problems = []
    for msgtype, text in definitions:
        if text:
            try:
                embedded.update(get_types_from_msg(text, msgtype))
            except TypesysError as error:
                problems.append(
                    f'the definition of {msgtype} in the bag cannot be '
                    f"parsed ({error}); using this installation's"
                )
    return embedded, tuple(problems)


@functools.lru_cache(maxsize=16)
def _embedded_typestore(definitions: Definitions) -> Typestore:
    """The typestore of a bag's embedded definitions, this installation's for the rest.

    Registering the definitions took ~20 ms a bag opened, the same for every bag a recorder
    wrote: bags with the same definitions share one store (only read from).
    Raises TypesysError for a standard type defined differently (never kept).
    """
    embedded, _ = _embedded_types(definitions)
    if not embedded:
        return fmm_typestore()
    store = get_typestore(BASE_STORE)
    own = fmm_typestore().fielddefs
    store.register(embedded)
    store.register({name: own[name] for name in own.keys() - store.fielddefs.keys()})
    return store


class BagReader:
    """A rosbag2 bag opened for reading; use as a context manager.

    path: a bag directory (with or without metadata.yaml), or a single .mcap or .db3 file.
    """

    def __init__(self, path: str | Path, *, strict: bool = True) -> None:
        self.path = Path(path)
        self.strict = strict
        self.problems: list[str] = []
        self.storage = ''
        self.recovered = False  # True when read by scanning instead of through the index
        self._reader: Reader | None = None
        self._storage_file: Path | None = None
        self._scan: McapScan | SqliteScan | None = None
        self._topics: dict[str, TopicInfo] = {}
        self._messages_read = 0
        self._definitions: Definitions = ()  # the bag's embedded ones (none: this installation's)
        self._typestore: Typestore | None = None
        # What batches() counted per channel (taken, missing, refused): filled as it reads.
        self.ledger: dict[str, ChannelLedger] = {}
        # From metadata.yaml: rosbag2's custom_data, the ROS distribution, and the ledger the
        # recorder wrote into custom_data (what the bag says of its own completeness).
        self.custom_data: dict[str, str] = {}
        self.ros_distro = ''
        self.recorded_ledger: dict[str, ChannelLedger] = {}

    def __enter__(self) -> 'BagReader':
        self.open()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    # -- opening ----------------------------------------------------------------------------

    def open(self) -> None:
        """Open the bag: through rosbags when it is intact, else by scanning its MCAP file."""
        target = self._storage_target()
        if self.path.is_dir():
            information = read_information(self.path)
            self.custom_data = dict(information.get('custom_data') or {})
            self.ros_distro = str(information.get('ros_distro') or '')
            try:
                self.recorded_ledger = custom_ledger(self.custom_data)
            except ValueError as error:
                self._note(str(error))
        if self.storage == 'sqlite3':
            _roll_back_unfinished_transaction(target)
        try:
            self._reader = Reader(target)
            self._reader.open()
        except _ROSBAGS_FAILURES as error:
            self._reader = None
            self._note(
                f'rosbags cannot open it ({error or type(error).__name__}): read by scanning '
                f'the {self.storage} file'
            )
            self._start_scan()
        else:
            self._topics = {
                conn.topic: TopicInfo(conn.topic, conn.msgtype, conn.msgcount)
                for conn in self._reader.connections
            }
            self._read_definitions(
                {
                    conn.msgtype: (
                        conn.msgdef.data
                        if conn.msgdef.format == MessageDefinitionFormat.MSG
                        else ''
                    )
                    for conn in self._reader.connections
                }
            )

    def _storage_target(self) -> Path:
        """What rosbags should open: the directory, or its storage file when unfinished."""
        path = self.path
        if not path.exists():
            raise FileNotFoundError(f'bag {path} does not exist')
        if path.is_file():
            self.storage = {'.mcap': 'mcap', '.db3': 'sqlite3'}.get(path.suffix, '')
            if not self.storage:
                raise BagError(
                    f'{path} is not a bag: expected a bag directory, a .mcap or a .db3 file'
                )
            self._storage_file = path
            return path
        files = sorted(path.glob('*.mcap')) + sorted(path.glob('*.db3'))
        if not files:
            raise BagError(f'{path} is not a rosbag2 bag: no .mcap or .db3 file in it')
        self.storage = 'mcap' if files[0].suffix == '.mcap' else 'sqlite3'
        self._storage_file = files[0]
        if (path / 'metadata.yaml').is_file():
            return path
        if len(files) > 1:
            raise BagError(
                f'bag {path} has no metadata.yaml and {len(files)} storage files '
                f'({", ".join(f.name for f in files)}): open one of them directly'
            )
        self.problems.append(
            'the recording was not closed: no metadata.yaml (the writer '
            'crashed, was killed, or is still writing)'
        )
        return files[0]

    def _new_scan(self) -> McapScan | SqliteScan:
        """A sequential, damage-tolerant reader of the storage file."""
        self.recovered = True
        scan = McapScan if self.storage == 'mcap' else SqliteScan
        return scan(self._storage_file)

    def _start_scan(self) -> None:
        """Read the storage file sequentially: a first pass collects topics and counts."""
        self._scan = self._new_scan()
        counts: Counter = Counter()
        for item in self._scan.records():
            if isinstance(item, Damage):
                self._note(item.problem)
            else:
                counts[item.channel.topic] += 1
        schemas = self._scan.schemas
        msgtypes = {}
        for channel in self._scan.channels.values():
            schema = schemas.get(channel.schema_id)
            msgtype = schema.name if schema else ''
            msgtypes[msgtype] = schema.data if schema and schema.encoding == 'ros2msg' else ''
            self._topics[channel.topic] = TopicInfo(channel.topic, msgtype, counts[channel.topic])
        self._read_definitions(msgtypes)

    def _read_definitions(self, definitions: dict[str, str]) -> None:
        """Take the bag's embedded definitions (msgtype -> .msg text, '' for none) to decode by.

        A definition that cannot be parsed is a problem now; the typestore waits for the
        first message decoded (`typestore`).
        """
        self._definitions = tuple(sorted(definitions.items()))
        self._typestore = None
        self.problems += _embedded_types(self._definitions)[1]

    @property
    def typestore(self) -> Typestore:
        """What messages are decoded with: the bag's embedded definitions, else this installation's.

        Built on first use, not on opening: a typestore imports and registers rosbags' ROS 2
        standard types (a quarter of a second), which a clean recording read whole
        (`channel_arrays`) never needs. BagError when the bag defines a standard type
        differently.
        """
        if self._typestore is None:
            try:
                self._typestore = _embedded_typestore(self._definitions)
            except TypesysError as error:
                raise BagError(
                    f'bag {self.path} defines a standard type differently: {error}'
                ) from None
        return self._typestore

    def close(self) -> None:
        """Release the storage file."""
        if self._reader is not None:
            self._reader.close()
            self._reader = None
        self._scan = None

    # -- what is in it ------------------------------------------------------------------------

    @property
    def topics(self) -> dict[str, TopicInfo]:
        """Every topic in the bag, by name (counts of a recovered bag: what was readable)."""
        return dict(self._topics)

    def find(self, topic: str, msgtype: str) -> str:
        """The bag's topic for `topic`: itself, or the one whose name ends in it.

        A relative name (`fmm/force`, as the constants hold it) matches a topic of msgtype
        recorded under any namespace (`/fmm/force`, `/rig2/fmm/force`), so a bag of a rig run
        under a namespace reads like any other. Several matches are an error naming them.
        """
        if topic.startswith('/'):
            self.require(topic, msgtype)
            return topic
        tail = '/' + topic
        matches = [
            name
            for name, info in self._topics.items()
            if name.endswith(tail) and info.msgtype == msgtype
        ]
        if len(matches) == 1:
            return matches[0]
        if matches:
            raise BagError(
                f'bag {self.path} has {len(matches)} {msgtype} topics ending in {tail}: '
                f'{", ".join(sorted(matches))}; name the one to read'
            )
        named = [name for name in self._topics if name.endswith(tail)]
        self.require(named[0] if named else tail, msgtype)
        return named[0]

    def require(self, topic: str, msgtype: str) -> None:
        """Check the bag has topic with msgtype; the error names what it has instead."""
        info = self._topics.get(topic)
        if info is None:
            have = (
                ', '.join(f'{t.topic} ({t.msgtype}, {t.count})' for t in self._topics.values())
                or 'no topics at all'
            )
            damage = f' (and it is damaged: {"; ".join(self.problems)})' if self.problems else ''
            raise MissingTopicError(f'bag {self.path} has no topic {topic}; it has: {have}{damage}')
        if info.msgtype != msgtype:
            raise MessageTypeError(
                f'topic {topic} in bag {self.path} has type '
                f'{info.msgtype or "(none recorded)"}, expected {msgtype}'
            )

    # -- messages -------------------------------------------------------------------------------

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[BagMessage]:
        """The stored messages of topics (default: all), serialized, in storage order."""
        wanted = set(self._topics) if topics is None else set(topics)
        delivered: Counter = Counter()
        if self._reader is not None:
            connections = [c for c in self._reader.connections if c.topic in wanted]
            if not connections:
                return
            try:
                for conn, log_time, data in self._reader.messages(connections=connections):
                    delivered[conn.topic] += 1
                    self._messages_read += 1
                    yield BagMessage(conn.topic, conn.msgtype, log_time, data)
                return
            except _ROSBAGS_FAILURES as error:
                self._note(
                    f'rosbags stopped reading it ({error or type(error).__name__}): '
                    'read on by scanning'
                )
            # Scan the file for what rosbags could not read, past what it delivered.
            self._scan = self._new_scan()
        yield from self._scanned(wanted, delivered)

    def _scanned(self, wanted: set[str], skip: Counter) -> Iterator[BagMessage]:
        """Messages by scanning; skip: per-topic counts already delivered through rosbags."""
        for item in self._scan.records():
            if isinstance(item, Damage):
                if item.unfinished:
                    self._note(item.problem)
                else:
                    self._damage(item.problem)
                continue
            topic = item.channel.topic
            if topic not in wanted:
                continue
            if skip[topic]:
                skip[topic] -= 1
                continue
            self._messages_read += 1
            yield BagMessage(topic, self._topics[topic].msgtype, item.log_time_ns, item.data)

    def _damage(self, problem: str) -> None:
        """Raise (strict) or note damage met while reading."""
        if self.strict:
            raise BagDamagedError(self.path, [problem], self._messages_read)
        self._note(problem)

    def _note(self, problem: str) -> None:
        """Remember a problem once, for `problems`."""
        if problem not in self.problems:
            self.problems.append(problem)

    def decode(self, message: BagMessage):
        """The message as a rosbags object; float64[] fields are numpy views of its bytes."""
        if message.msgtype not in self.typestore.fielddefs:
            raise MessageTypeError(
                f'topic {message.topic} in bag {self.path} has message type '
                f'{message.msgtype or "(none recorded)"}, which neither the bag nor '
                'fmm_interfaces defines'
            )
        try:
            return self.typestore.deserialize_cdr(message.data, message.msgtype)
        except Exception as error:  # the generated deserializers raise many error types
            raise BagDamagedError(
                self.path,
                [
                    f'a {message.msgtype} message on {message.topic} at log time '
                    f'{message.log_time_ns} ns cannot be decoded ({type(error).__name__}: '
                    f'{error})'
                ],
                self._messages_read,
            ) from None

    def _decode_each(self, messages: Iterable[BagMessage]) -> Iterator[tuple[BagMessage, object]]:
        """Each message with its decoding; one that cannot be decoded is damage."""
        for message in messages:
            try:
                yield message, self.decode(message)
            except BagDamagedError as error:
                if self.strict:
                    raise
                self._note(error.problems[0])

    def decoded(self, topic: str, msgtype: str) -> Iterator[tuple[int, object]]:
        """(log time [ns], message) of every message on topic (see `find`) of msgtype."""
        topic = self.find(topic, msgtype)
        for message, decoded in self._decode_each(self.messages([topic])):
            yield message.log_time_ns, decoded

    def impacts(self, topic: str = IMPACTS_TOPIC) -> Iterator[object]:
        """The recorded ImpactResult messages, in order."""
        for _, message in self.decoded(topic, IMPACT_RESULT):
            yield message

    def frf_summaries(self, topic: str = FRF_TOPIC) -> Iterator[object]:
        """The recorded FrfSummary messages, in order."""
        for _, message in self.decoded(topic, FRF_SUMMARY):
            yield message

    # -- sample batches -----------------------------------------------------------------------

    def sample_batches(
        self, topics: Iterable[str] = (FORCE_TOPIC, VELOCITY_TOPIC)
    ) -> Iterator[ChannelBatch]:
        """Every SampleBatch of the topics (see `find`), interleaved in storage (arrival) order.

        This is what a live subscriber saw, message by message: the form to feed a streaming
        consumer that aligns channels by sample index itself, as the analyzer does.
        """
        topics = [self.find(topic, SAMPLE_BATCH) for topic in topics]
        for message, batch in self._decode_each(self.messages(topics)):
            yield channel_batch(message, batch, self.path)

    def channel_arrays(
        self,
        force_topic: str = FORCE_TOPIC,
        velocity_topic: str = VELOCITY_TOPIC,
        rules: StreamRules = DEFAULT_RULES,
    ) -> 'ChannelArrays | None':
        """Both channels read whole into two arrays, when the bag is a clean recording.

        None unless the bag is one intact MCAP file, read without a problem so far, whose
        batches the stream rules would take whole (see `fmm_ros.io.bags.arrays`): then
        read batch by batch (`sample_batches`), where every fault has its rule.
        """
        topics = (self.find(force_topic, SAMPLE_BATCH), self.find(velocity_topic, SAMPLE_BATCH))
        single = not self.path.is_dir() or len(list(self.path.glob('*.mcap'))) == 1
        if self._reader is None or self.storage != 'mcap' or self.problems or not single:
            return None
        from fmm_ros.io.bags.arrays import read_channel_arrays

        embedded, _ = _embedded_types(self._definitions)
        return read_channel_arrays(self._storage_file, topics, embedded, rules)

    def channel(self, topic: str) -> Iterator[ChannelBatch]:
        """Every SampleBatch of one channel topic, in storage order."""
        return self.sample_batches([topic])

    def batches(
        self,
        force_topic: str = FORCE_TOPIC,
        velocity_topic: str = VELOCITY_TOPIC,
        rules: StreamRules = DEFAULT_RULES,
    ) -> Iterator[AlignedBatch]:
        """Force and velocity paired by first_sample_index, as the live analyzer pairs them.

        The channels follow the stream rules (`fmm_ros.core.signal.stream`): a repeated, late
        or stray batch is refused, a new acquisition starts the next `acquisition`, and what
        was refused or missing is counted in `ledger` (filled as reading goes). Equal batches
        on both channels come out as they are (views, no copy); unequal ones are cut to their
        overlap. A sample present on one channel only is dropped and shows as gap_samples.
        """
        force_topic = self.find(force_topic, SAMPLE_BATCH)
        velocity_topic = self.find(velocity_topic, SAMPLE_BATCH)
        aligner = BatchAligner(rules)
        self.ledger = aligner.ledger
        for batch in self.sample_batches([force_topic, velocity_topic]):
            yield from aligner.add(0 if batch.topic == force_topic else 1, batch)
        aligner.finish()


def channel_batch(message: BagMessage, batch, bag: str | Path = '') -> ChannelBatch:
    """A decoded SampleBatch message as a ChannelBatch (samples stay a read-only view).

    BagError (naming the bag) when the message lacks a field read here: the bag's embedded
    definition of the type is not ours (damaged bytes in it decode to other field names).
    """
    try:
        samples = batch.samples
        samples.flags.writeable = False
        stamp = batch.header.stamp
        return ChannelBatch(
            message.topic,
            int(batch.first_sample_index),
            samples,
            float(batch.sample_rate_hz),
            batch.quantity,
            batch.unit,
            float(batch.full_scale),
            batch.header.frame_id,
            stamp.sec * 10**9 + stamp.nanosec,
            message.log_time_ns,
        )
    except AttributeError as error:
        raise BagError(
            f'{f"bag {bag}: " if bag else ""}a {message.msgtype} message on {message.topic} '
            f'has no field {error.name!r}: the bag defines the type differently (a damaged or '
            'foreign definition)'
        ) from None


class BatchAligner:
    """Pairs force and velocity batches by sample index: the streaming half of BagReader.batches.

    The stream rules decide what each channel takes; this pairs what both took.
    """

    def __init__(self, rules: StreamRules = DEFAULT_RULES) -> None:
        self.stream = AlignedStream(self, rules)
        self._pending = {FORCE.quantity: deque(), VELOCITY.quantity: deque()}
        self._next = dict.fromkeys(self._pending, 0)
        self._out: list[AlignedBatch] = []
        self._rate = 0.0
        self._last_end: int | None = None

    @property
    def ledger(self) -> dict[str, ChannelLedger]:
        """What each channel received, missed and refused (the stream's ledger)."""
        return self.stream.ledger

    def add(self, channel: int, batch: ChannelBatch) -> list[AlignedBatch]:
        """Take one batch of channel 0 (force) or 1 (velocity); return what is now paired."""
        self.stream.feed(
            (FORCE.quantity, VELOCITY.quantity)[channel],
            Batch(
                batch.first_sample_index,
                batch.samples,
                batch.sample_rate_hz,
                batch.full_scale,
                batch.frame_id,
                batch.stamp_ns,
            ),
        )
        out, self._out = self._out, []
        return out

    def finish(self) -> None:
        """End of the stream: a batch still held as a possible new acquisition is refused."""
        self.stream.finish()

    # -- the stream's sink ------------------------------------------------------------------------

    def begin(self, sample_rate_hz: float, first_index: int) -> None:
        """An acquisition begins: nothing pending, no gap before its first pair."""
        self._rate = sample_rate_hz
        self._last_end = None
        for quantity, queue in self._pending.items():
            queue.clear()
            self._next[quantity] = first_index

    def end(self, reason: str) -> None:
        """The acquisition ends: samples of one channel still unpaired never will be."""

    def take(self, quantity: str, first_index: int, samples: np.ndarray, full_scale: float) -> None:
        """Samples of a channel at its watermark: pair what both channels now hold."""
        self._pending[quantity].append((first_index, samples, full_scale))
        self._next[quantity] = first_index + len(samples)
        self._pair()

    def missing(self, quantity: str, start: int, stop: int) -> None:
        """Samples that never came: the other channel's samples there stay unpaired."""
        self._next[quantity] = stop
        self._pair()

    def _pair(self) -> None:
        forces, velocities = self._pending[FORCE.quantity], self._pending[VELOCITY.quantity]
        while forces and velocities:
            (f_start, f_samples, f_scale), (v_start, v_samples, v_scale) = forces[0], velocities[0]
            start = max(f_start, v_start)
            stop = min(f_start + len(f_samples), v_start + len(v_samples))
            if stop > start:
                gap = 0 if self._last_end is None else start - self._last_end
                self._last_end = stop
                self._out.append(
                    AlignedBatch(
                        start,
                        _cut(f_samples, f_start, start, stop),
                        _cut(v_samples, v_start, start, stop),
                        self._rate,
                        gap,
                        f_scale,
                        v_scale,
                        self.stream.acquisitions,
                    )
                )
            # The head ending first is used up (or had no partner); the other moves on.
            for queue in (forces, velocities):
                head_start, head, scale = queue[0]
                if head_start + len(head) <= stop:
                    queue.popleft()
                elif head_start < stop:
                    queue[0] = (stop, head[stop - head_start :], scale)
        # Samples below the other channel's watermark that found no partner never will.
        for queue, other in ((forces, VELOCITY.quantity), (velocities, FORCE.quantity)):
            watermark = self._next[other]
            while queue and queue[0][0] < watermark:
                head_start, head, scale = queue[0]
                if head_start + len(head) <= watermark:
                    queue.popleft()
                else:
                    queue[0] = (watermark, head[watermark - head_start :], scale)


def _cut(samples: np.ndarray, first: int, start: int, stop: int) -> np.ndarray:
    """Samples (from index first) over [start, stop): the whole array when it fits."""
    if start == first and stop == first + len(samples):
        return samples
    return samples[start - first : stop - first]


def _roll_back_unfinished_transaction(db_path: Path) -> None:
    """Let sqlite roll back what a crashed writer left uncommitted, as sqlite itself would.

    rosbags reads a .db3 as immutable, which would ignore a hot journal and could show
    half-written pages; opening it once normally restores the last committed state.
    """
    files = [db_path] if db_path.is_file() else sorted(db_path.glob('*.db3'))
    for db in files:
        if db.with_name(db.name + '-journal').exists():
            connection = sqlite3.connect(db)
            try:
                connection.execute('SELECT count(*) FROM sqlite_master').fetchone()
            finally:
                connection.close()
