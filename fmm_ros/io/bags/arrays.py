"""A clean recording's two channels read whole, straight from the MCAP chunks into two arrays.

Reading a session batch by batch costs a rosbags deserialization, a ChannelBatch and a trip
through the stream rules per message (~40,000 for a 16-minute session): several times the
time it takes to read the file. A bag recorded without a fault needs none of that. This
reader walks the chunks of an intact, uncompressed MCAP file (the layout fmm writes),
parses every SampleBatch's CDR header in place (all at once, in numpy) and copies the float64
samples straight out of the mapped file, a block of both channels at a time. No numba: a
replay process would pay its start-up (half a second) for a loop saving a few milliseconds.

It only answers for a recording the stream rules (`fmm_ros.core.signal.stream`) would take
whole, in the order a batch-by-batch reader delivers it (by log time, ties in file order):
one rate, each channel contiguous from one common first index, one sender and one full
scale per channel, and the channels never further apart than `max_skew_s`. Then feeding the
arrays as aligned blocks gives the capture exactly the samples, indices and ranges it gets
batch by batch. Anything else (a gap, a restart, damage, a checksum mismatch, a compressed
chunk, a type defined differently, a single-channel tail) returns None and the caller reads
batch by batch, where every such case has its rule.

CDR layout of fmm_interfaces/SampleBatch (little-endian, offsets after the 4-byte
encapsulation header, each field aligned to its size): header.stamp (int32 sec, uint32
nanosec), header.frame_id, quantity, unit (uint32 length with NUL, bytes), float64
sample_rate_hz, uint64 first_sample_index, float64 full_scale, uint32 count, float64[count].
"""

from __future__ import annotations

import functools
import mmap
import struct
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rosbags.typesys import get_types_from_msg

from fmm_ros.constants import FORCE, VELOCITY
from fmm_ros.core._threads import in_background
from fmm_ros.core.signal.stream import StreamRules
from fmm_ros.io.bags.definitions import SAMPLE_BATCH
from fmm_ros.io.bags.mcapscan import CHANNEL, CHUNK, DATA_END, MAGIC, MESSAGE, _parse_channel
from fmm_ros.units import sample_si_factor

_RECORD_HEAD = struct.Struct('<BQ')
_CHUNK_HEAD = struct.Struct('<QQQI')  # start time, end time, uncompressed size, crc32
# The `quantity` each channel's batches carry (what replay counts signal seconds by).
QUANTITIES = (FORCE.quantity, VELOCITY.quantity)
# The layout parsed here, as a bag embeds it (SampleBatch, then the standard types in it).
# Declared, not taken from a typestore, which would cost a replay a quarter of a second of
# start-up to build; test_bagio holds it to fmm_interfaces' SampleBatch and ROS 2's types.
LAYOUT_MSG = """\
std_msgs/Header header
string quantity
string unit
float64 sample_rate_hz
uint64 first_sample_index
float64 full_scale
float64[] samples
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
# What `_batch_layout` reports per message (int64 columns).
_FIRST, _COUNT, _SAMPLES_AT, _FRAME_AT, _FRAME_LEN, _QUANTITY_AT, _QUANTITY_LEN = range(7)
_RATE_AT, _SCALE_AT, _BAD, _UNIT_AT, _UNIT_LEN = range(7, 12)
_COLUMNS = 12


@dataclass(frozen=True)
class ChannelArrays:
    """Force and velocity of a clean recording, found in its file, with the batches they came in.

    The samples stay in the mapped file until asked for: `blocks` copies them out a block at
    a time (what replay feeds its capture), `force` / `velocity` whole (once, on first use).
    A 16-minute session's two whole channels are 160 MB of fresh memory, whose first touch
    cost a fresh `fmm replay` process more than copying the samples does; blocks reuse a
    few hundred kB. Samples from `first_sample_index` on (force [N], velocity [m/s]).
    stamp_ns: header stamp of the first force batch, the time of sample first_sample_index
    (0: none), so the acquisition's clock, and the impact ids it gives, match a batch read.
    fed: the batches in the order a batch-by-batch reader delivers them, as rows of
    (channel 0 force / 1 velocity, sample count).
    """

    topics: tuple[str, str]
    first_sample_index: int
    samples: int
    sample_rate_hz: float
    full_scale: tuple[float, float]
    fed: np.ndarray
    stamp_ns: int
    buf: np.ndarray
    """The mapped file (its bytes): every chunk's checksum held."""
    rows: tuple[np.ndarray, np.ndarray]
    """Of each channel's batches in index order, (byte offset of the samples, first sample
    counted from first_sample_index, count) as rows."""

    @property
    def batches(self) -> int:
        """Batches of both channels."""
        return len(self.fed)

    @property
    def force_signal_s(self) -> float:
        """Seconds of force signal, summed batch by batch in delivery order (as replay counts)."""
        counts = self.fed[self.fed[:, 0] == 0, 1]
        return float(np.cumsum(counts / self.sample_rate_hz)[-1]) if counts.size else 0.0

    @functools.cached_property
    def force(self) -> np.ndarray:
        """The whole force channel [N]."""
        return self.span(0, 0, self.samples)

    @functools.cached_property
    def velocity(self) -> np.ndarray:
        """The whole velocity channel [m/s]."""
        return self.span(1, 0, self.samples)

    def blocks(self, size: int) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
        """(low, force, velocity) of samples [low, low + size) for each low from 0 on, copied."""
        for low in range(0, self.samples, size):
            high = min(low + size, self.samples)
            yield low, self.span(0, low, high), self.span(1, low, high)

    def span(self, channel: int, low: int, high: int) -> np.ndarray:
        """Samples [low, high) of channel 0 (force) or 1 (velocity), copied from the file.

        The batches over the span are copied whole (`_copy_rows`) and the span's part of
        them returned: a view, the few samples of its two edge batches beyond it aside.
        """
        if high <= low:  # (a recording of empty batches only)
            return np.empty(0)
        rows = self.rows[channel]
        targets = rows[:, 1]
        first = max(int(np.searchsorted(targets, low, side='right')) - 1, 0)
        stop = int(np.searchsorted(targets, high, side='left'))
        origin = int(targets[first])
        last = rows[stop - 1]
        out = np.empty(int(last[1] + last[2]) - origin)
        part = rows[first:stop]
        _copy_rows(self.buf, part[:, 0], part[:, 1] - origin, part[:, 2], out.view(np.uint8))
        return out[low - origin : high - origin]


@functools.cache
def layout_types() -> dict:
    """The rosbags field definitions of the layout parsed here (`LAYOUT_MSG`), by type name."""
    return get_types_from_msg(LAYOUT_MSG, SAMPLE_BATCH)


def read_channel_arrays(
    storage_file: Path, topics: tuple[str, str], embedded: Mapping, rules: StreamRules
) -> ChannelArrays | None:
    """Both channels of an intact MCAP file read whole, or None if it is not a clean recording.

    topics: the force and the velocity topic, as stored. embedded: the field definitions the
    bag carries (a type it does not define is decoded with this installation's, which are
    the layout's): another SampleBatch layout is not parsed here.
    """
    if any(embedded.get(name, fields) != fields for name, fields in layout_types().items()):
        return None
    if storage_file.stat().st_size <= len(MAGIC):
        return None
    # Mapped, not read: the samples are copied once, from the page cache to their arrays.
    # The pages are mapped in one go (MAP_POPULATE), not faulted in one by one.
    with storage_file.open('rb') as stream:
        mapped = mmap.mmap(
            stream.fileno(),
            0,
            flags=mmap.MAP_SHARED | getattr(mmap, 'MAP_POPULATE', 0),
            prot=mmap.PROT_READ,
        )
    # The map is released with the last view of it (the arrays' `buf`).
    return _read(np.frombuffer(mapped, dtype=np.uint8), topics, rules)


def _read(buf: np.ndarray, topics: tuple[str, str], rules: StreamRules) -> ChannelArrays | None:
    """The channel arrays, or None; given only once every chunk's checksum held.

    The layout is parsed and checked while another thread checks the chunks' CRCs (zlib
    releases the GIL): reading costs the longer of the two, not their sum.
    """
    messages = _messages(buf, topics)
    if messages is None:
        return None
    channel, offsets, lengths, checks = messages
    verified = in_background(_checksums_hold, buf, checks)
    try:
        arrays = _arrays(buf, topics, rules, channel, offsets, lengths)
    finally:
        intact = verified.result()  # the checking thread is done with buf either way
    return arrays if intact else None


def _checksums_hold(buf: np.ndarray, checks: list[tuple[int, int, int]]) -> bool:
    """Whether every chunk's records [start, stop) have their stored CRC-32."""
    return all(zlib.crc32(buf[start:stop]) == crc for start, stop, crc in checks)


def _arrays(
    buf: np.ndarray,
    topics: tuple[str, str],
    rules: StreamRules,
    channel: np.ndarray,
    offsets: np.ndarray,
    lengths: np.ndarray,
) -> ChannelArrays | None:
    """The channel arrays of the messages found (the checksums aside), or None.

    None when the stream rules would not take the recording whole.
    """
    if not offsets.size:
        return None
    layout = _batch_layout(buf, offsets, lengths)
    if layout[:, _BAD].any():
        return None
    rates = _gather(buf, layout[:, _RATE_AT], '<f8')
    scales = _gather(buf, layout[:, _SCALE_AT], '<f8')
    first, count = layout[:, _FIRST], layout[:, _COUNT]
    if not (rates == rates[0]).all() or not 0 < rates[0] < np.inf:
        return None
    rate = float(rates[0])
    spans = []
    for index in (0, 1):
        mine = channel == index
        if not mine.any() or (scales[mine] != scales[mine][0]).any():
            return None
        starts, ends = first[mine], first[mine] + count[mine]
        frames = layout[mine][:, (_FRAME_AT, _FRAME_LEN)]
        quantities = layout[mine][:, (_QUANTITY_AT, _QUANTITY_LEN)]
        units = layout[mine][:, (_UNIT_AT, _UNIT_LEN)]
        if (
            (starts[1:] != ends[:-1]).any()
            or not _same_strings(buf, frames)
            or not _same_strings(buf, quantities)
            or _string(buf, quantities[0]) != QUANTITIES[index]
            or not _same_strings(buf, units)
            or sample_si_factor(QUANTITIES[index], _string(buf, units[0])) != 1.0
        ):  # anything but one SI unit a channel is converted batch by batch
            return None
        spans.append((int(starts[0]), int(ends[-1]), float(scales[mine][0])))
    (start, force_end, force_scale), (velocity_start, velocity_end, velocity_scale) = spans
    if velocity_start != start or force_end != velocity_end:
        return None
    if not _within_skew(channel, first + count, start, int(round(rules.max_skew_s * rate))):
        return None
    head = int(offsets[np.flatnonzero(channel == 0)[0]]) + 4  # CDR header.stamp: sec, nanosec
    seconds = int.from_bytes(bytes(buf[head : head + 4]), 'little', signed=True)
    nanoseconds = int.from_bytes(bytes(buf[head + 4 : head + 8]), 'little')
    return ChannelArrays(
        topics,
        start,
        force_end - start,
        rate,
        (force_scale, velocity_scale),
        np.column_stack((channel, count)),
        seconds * 1_000_000_000 + nanoseconds,
        buf,
        tuple(  # a channel's batches are in index order already (contiguous, checked above)
            layout[channel == index][:, (_SAMPLES_AT, _FIRST, _COUNT)] - (0, start, 0)
            for index in (0, 1)
        ),
    )


def _messages(
    buf: np.ndarray, topics: tuple[str, str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[int, int, int]]] | None:
    """Channel (0/1), CDR offset and length of every message of the topics, and the CRCs.

    The checksums to verify: (start, stop, CRC-32) of each chunk's records that has one.
    Delivery order is a batch-by-batch reader's: by log time, ties in file order. None when
    the file is not an intact, uncompressed, chunked MCAP file (the chunks are walked with
    every length checked, so a damaged one is found by its checksum, not read out of bounds).
    """
    if bytes(buf[: len(MAGIC)]) != MAGIC:
        return None
    wanted: dict[int, int] = {}  # MCAP channel id -> 0 force / 1 velocity
    parts = []
    checks = []
    pos = len(MAGIC)
    size = len(buf)
    while True:
        if pos + _RECORD_HEAD.size > size:
            return None
        opcode, length = _RECORD_HEAD.unpack_from(buf, pos)
        content = pos + _RECORD_HEAD.size
        if content + length > size:
            return None
        if opcode == DATA_END:
            break
        if opcode == MESSAGE:
            return None  # a message outside a chunk: not the layout read here
        if opcode == CHANNEL:
            _register(buf[content : content + length], topics, wanted)
        elif opcode == CHUNK:
            records = _chunk_records(buf, content, length)
            if records is None:
                return None
            start, stop, crc = records
            if crc:
                checks.append(records)
            parts.append(_chunk_messages(buf, (start, stop), topics, wanted))
            if parts[-1] is None:
                return None
        pos = content + length
    if not parts:
        return None
    columns = zip(*parts, strict=True)
    channel_ids, log_times, offsets, lengths = (np.concatenate(column) for column in columns)
    keep = np.isin(channel_ids, np.fromiter(wanted, dtype=np.int64, count=len(wanted)))
    order = np.argsort(log_times[keep], kind='stable')
    channel = np.array([wanted.get(i, -1) for i in range(int(channel_ids.max(initial=0)) + 1)])
    return channel[channel_ids[keep][order]], offsets[keep][order], lengths[keep][order], checks


def _register(content: np.ndarray, topics: tuple[str, str], wanted: dict[int, int]) -> None:
    """Note a channel record whose topic is one of ours."""
    channel = _parse_channel(memoryview(content))
    if channel.topic in topics:
        wanted[channel.id] = topics.index(channel.topic)


def _chunk_records(buf: np.ndarray, content: int, length: int) -> tuple[int, int, int] | None:
    """[start, stop) of an uncompressed chunk's records and their CRC-32 (0: none), else None."""
    _, _, uncompressed_size, crc = _CHUNK_HEAD.unpack_from(buf, content)
    pos = content + _CHUNK_HEAD.size
    (name_length,) = struct.unpack_from('<I', buf, pos)
    if name_length:  # compressed
        return None
    (records_length,) = struct.unpack_from('<Q', buf, pos + 4)
    start = pos + 12
    stop = start + records_length
    if records_length != uncompressed_size or stop > content + length:
        return None
    return start, stop, crc


def _chunk_messages(
    buf: np.ndarray, records: tuple[int, int], topics: tuple[str, str], wanted: dict[int, int]
) -> tuple[np.ndarray, ...] | None:
    """(channel id, log time, CDR offset, CDR length) of every message in a chunk."""
    start, stop = records
    walked = _walk_chunk(buf, start, stop)
    if walked is None:
        return None
    table, others = walked
    for offset, length, opcode in others:
        if opcode == CHANNEL:
            _register(buf[offset : offset + length], topics, wanted)
    return table[:, 0], table[:, 1], table[:, 2], table[:, 3]


_MESSAGE_HEAD = struct.Struct('<HIQ')  # a message record's channel id, sequence, log time
_MESSAGE_HEAD_SIZE = 22  # and its publish time (8 bytes) before the data
_MAX_OTHERS = 64  # records in a chunk besides messages: more than a bag's channels and schemas


_PATTERN = 2  # message records after which a chunk's next ones are taken as repeating them


def _walk_chunk(
    buf: np.ndarray, start: int, stop: int
) -> tuple[np.ndarray, list[tuple[int, int, int]]] | None:
    """Messages (channel id, log time, CDR offset, CDR length) and other records of a chunk.

    None when a record runs past the chunk, or there are more other records than a bag has.
    A record's length says where the next one starts, so records are walked one by one;
    but once two messages are walked, the rest of the chunk is tried as repeating their
    lengths (a recorder's force and velocity batches alternate, each the same size): the
    records where the pattern puts them are checked all at once (`_message_run`), and those
    up to the first that breaks it are taken as the walk would take them. So a chunk costs
    a few numpy calls, not a few microseconds a message, and no compiled loop (numba's
    start-up would cost a replay more than it saves).
    """
    parts: list[np.ndarray] = []
    rows: list[tuple[int, int, int, int]] = []  # walked one by one, since the last part
    others: list[tuple[int, int, int]] = []
    recent: list[int] = []  # lengths of the messages walked one by one just before pos
    record_head, message_head = _RECORD_HEAD.unpack_from, _MESSAGE_HEAD.unpack_from
    pos = start
    while pos < stop:
        if len(recent) == _PATTERN:
            recent, run = [], _message_run(buf, pos, stop, recent)
            if run is not None:
                parts += [np.array(rows, dtype=np.int64).reshape(-1, 4), run[0]]
                rows, pos = [], run[1]
                continue
        if pos + _RECORD_HEAD.size > stop:
            return None
        opcode, length = record_head(buf, pos)
        content = pos + _RECORD_HEAD.size
        if content + length > stop:
            return None
        if opcode == MESSAGE and length >= _MESSAGE_HEAD_SIZE:
            channel, _, log_time = message_head(buf, content)
            at = content + _MESSAGE_HEAD_SIZE
            rows.append((channel, log_time, at, length - _MESSAGE_HEAD_SIZE))
            recent.append(length)
        else:
            recent = []
            if opcode != MESSAGE:
                if len(others) == _MAX_OTHERS:
                    return None
                others.append((content, length, opcode))
        pos = content + length
    parts.append(np.array(rows, dtype=np.int64).reshape(-1, 4))
    return np.concatenate(parts), others


def _message_run(
    buf: np.ndarray, pos: int, stop: int, lengths: list[int]
) -> tuple[np.ndarray, int] | None:
    """The messages from pos on that repeat the record lengths given, and where they end.

    Rows as `_walk_chunk` makes them, of every record up to the first (in whole repeats
    before stop) that is not a message of its length or whose log time would not fit an
    int64 (left to the walk, which fails on it as before); None when the first is not.
    """
    sizes = np.array(lengths) + _RECORD_HEAD.size
    period = int(sizes.sum())
    repeats = (stop - pos) // period
    offsets = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    at = (pos + period * np.arange(repeats)[:, None] + offsets).ravel()
    expected = np.tile(np.array(lengths), repeats)
    fits = (buf[at] == MESSAGE) & (_ints(buf, at + 1, 8) == expected)
    fits &= buf[at + _RECORD_HEAD.size + 13] < 0x80  # the log time's top byte
    taken = int(np.argmin(fits)) if not fits.all() else fits.size
    if not taken:
        return None
    at, length = at[:taken], expected[:taken]
    content = at + _RECORD_HEAD.size
    table = np.column_stack(
        (
            _ints(buf, content, 2),
            _ints(buf, content + 6, 8),
            content + _MESSAGE_HEAD_SIZE,
            length - _MESSAGE_HEAD_SIZE,
        )
    )
    return table, int(content[-1] + length[-1])


def _ints(buf: np.ndarray, positions: np.ndarray, size: int) -> np.ndarray:
    """The little-endian ints of size bytes at each position (2, 4: unsigned; 8: signed)."""
    raw = buf[positions[:, None] + np.arange(size)]
    return raw.view({2: '<u2', 4: '<u4', 8: '<i8'}[size])[:, 0].astype(np.int64)


def _string_end(
    buf: np.ndarray, origin: np.ndarray, pos: np.ndarray, end: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where each CDR string at pos (aligned to 4 from origin) starts, and the end of it.

    The end is -1 where pos is -1 already or the string's length runs past end.
    """
    aligned = origin + ((pos - origin + 3) & ~3)
    fits = (pos >= 0) & (aligned + 4 <= end)
    length = _ints(buf, np.where(fits, aligned, 0), 4)
    return aligned, np.where(fits, aligned + 4 + length, -1)


def _batch_layout(buf: np.ndarray, offsets: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Where each SampleBatch's fields are (see _FIRST..._BAD); _BAD 1 when it does not parse.

    Every message at once, field after field (a string's length says where the next field
    is); a row already bad reads from a safe place and stays bad.
    """
    out = np.zeros((offsets.shape[0], _COLUMNS), dtype=np.int64)
    at, end = offsets, offsets + lengths
    # Little-endian CDR only; offsets align from after the 4-byte encapsulation header.
    long_enough = lengths >= 12
    head = np.where(long_enough, at, 0)
    bad = ~long_enough | (buf[head] != 0) | (buf[head + 1] != 1)
    origin = at + 4
    frame = origin + 8
    _, pos = _string_end(buf, origin, np.where(bad, -1, frame), end)
    out[:, _FRAME_AT], out[:, _FRAME_LEN] = frame + 4, pos - frame - 4
    quantity, pos = _string_end(buf, origin, pos, end)
    out[:, _QUANTITY_AT], out[:, _QUANTITY_LEN] = quantity + 4, pos - quantity - 4
    unit, pos = _string_end(buf, origin, pos, end)
    out[:, _UNIT_AT], out[:, _UNIT_LEN] = unit + 4, pos - unit - 4
    pos = origin + ((pos - origin + 7) & ~7)
    bad |= (out[:, _UNIT_LEN] < 0) | (pos + 28 > end)
    pos = np.where(bad, 0, pos)
    first = _ints(buf, pos + 8, 8)
    count = _ints(buf, pos + 24, 4)
    samples = origin + ((pos + 28 - origin + 7) & ~7)
    stop = samples + 8 * count
    bad |= (first < 0) | (stop > end) | ((count > 0) & (stop != end))
    out[:, _RATE_AT], out[:, _FIRST], out[:, _SCALE_AT] = pos, first, pos + 16
    out[:, _COUNT], out[:, _SAMPLES_AT] = count, samples
    out[:, _BAD] = bad
    return out


def _string(buf: np.ndarray, span: np.ndarray) -> str:
    """A CDR string at (offset, length with its NUL)."""
    at, length = int(span[0]), int(span[1])
    return bytes(buf[at : at + max(length - 1, 0)]).decode('utf-8', 'replace')


def _gather(buf: np.ndarray, positions: np.ndarray, dtype: str) -> np.ndarray:
    """The 8-byte values at each position (any alignment)."""
    return buf[positions[:, None] + np.arange(8)].copy().view(dtype)[:, 0]


def _same_strings(buf: np.ndarray, spans: np.ndarray) -> bool:
    """Whether the strings at (offset, length) rows are all equal."""
    length = int(spans[0, 1])
    if (spans[:, 1] != length).any():
        return False
    text = buf[spans[:, :1] + np.arange(length)]
    return bool((text == text[0]).all())


def _within_skew(channel: np.ndarray, ends: np.ndarray, start: int, max_skew: int) -> bool:
    """Whether, batch after batch, neither channel ran more than max_skew samples ahead.

    Each channel's batches are contiguous from start here, so the end a channel reached
    after each batch is the running maximum of its batches' ends.
    """
    reached = [np.maximum.accumulate(np.where(channel == k, ends, start)) for k in (0, 1)]
    return not (np.abs(reached[0] - reached[1]) > max_skew).any()


def _copy_rows(
    buf: np.ndarray, sources: np.ndarray, targets: np.ndarray, counts: np.ndarray, out: np.ndarray
) -> None:
    """Copy counts[k] float64s from byte sources[k] of buf to sample targets[k] of out (bytes).

    Run by run: a run is batches of one size, evenly spaced in the file and back to back in
    out (a chunk's batches of a channel, as a recorder writes them), copied in one strided
    copy, so a session costs a few hundred copies, not one a batch.
    """
    if not sources.size:
        return
    stride = np.diff(sources)
    joined = (counts[1:] == counts[:-1]) & (np.diff(targets) == counts[:-1])
    joined[1:] &= stride[1:] == stride[:-1]
    cuts = np.flatnonzero(~joined) + 1
    for first, stop in zip((0, *cuts), (*cuts, sources.size), strict=True):
        rows, size = stop - first, 8 * int(counts[first])
        if not size:
            continue
        step = int(stride[first]) if rows > 1 else 0
        source = np.lib.stride_tricks.as_strided(
            buf[sources[first] :], shape=(rows, size), strides=(step, 1), writeable=False
        )
        target = out[8 * targets[first] : 8 * targets[first] + rows * size]
        target.reshape(rows, size)[...] = source
