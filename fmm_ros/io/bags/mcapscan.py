"""Read what can be read of a damaged or unfinished MCAP file, record by record.

rosbags (and the mcap library) need an MCAP file's footer and summary, and decode a chunk
whole: a recording whose writer was killed has neither footer nor summary, and one bad byte
in a chunk loses the chunk. This scanner walks the file from the start instead, yields every
message it can frame, and reports the first thing that stops it as a `Damage` with its byte
offset. A chunk whose own framing is intact but whose content is bad is skipped after the
messages before the bad spot; damage to the framing between records ends the scan.

Record layout from the MCAP specification (https://mcap.dev/spec): magic, then records of
opcode (uint8), content length (uint64 little endian) and content.
"""

import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from fmm_ros.errors import BadInputError

MAGIC = b'\x89MCAP0\r\n'

HEADER, FOOTER, SCHEMA, CHANNEL, MESSAGE, CHUNK = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06
DATA_END = 0x0F
RECORD_NAMES = {
    0x01: 'header',
    0x02: 'footer',
    0x03: 'schema',
    0x04: 'channel',
    0x05: 'message',
    0x06: 'chunk',
    0x07: 'message index',
    0x08: 'chunk index',
    0x09: 'attachment',
    0x0A: 'attachment index',
    0x0B: 'statistics',
    0x0C: 'metadata',
    0x0D: 'metadata index',
    0x0E: 'summary offset',
    0x0F: 'data end',
}

_RECORD_HEAD = struct.Struct('<BQ')
_MESSAGE_HEAD = struct.Struct('<HIQQ')  # channel id, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct('<QQQI')  # start time, end time, uncompressed size, crc32


@dataclass(frozen=True)
class Schema:
    """An MCAP schema record: a message type and its definition text."""

    id: int
    name: str
    encoding: str
    data: str


@dataclass(frozen=True)
class Channel:
    """An MCAP channel record: a topic, its schema and its metadata (e.g. offered QoS)."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ScannedMessage:
    """One message as stored: its channel, log time [ns] and serialized bytes (a view)."""

    channel: Channel
    log_time_ns: int
    data: memoryview


@dataclass(frozen=True)
class Damage:
    """Why scanning stopped or skipped: the byte offset in the file and the problem.

    unfinished: the file simply ends after a complete record (a writer that never closed
    it); nothing that was written is lost, unlike truncation inside a record or corruption.
    """

    offset: int
    problem: str
    unfinished: bool = False


class _Truncated(Exception):
    """A record inside a buffer claims more bytes than the buffer holds."""


def _string(buf: memoryview, pos: int) -> tuple[str, int]:
    (size,) = struct.unpack_from('<I', buf, pos)
    end = pos + 4 + size
    if end > len(buf):
        raise _Truncated
    return bytes(buf[pos + 4 : end]).decode('utf-8'), end


def _parse_schema(content: memoryview) -> Schema:
    (schema_id,) = struct.unpack_from('<H', content, 0)
    name, pos = _string(content, 2)
    encoding, pos = _string(content, pos)
    data, _ = _string(content, pos)
    return Schema(schema_id, name, encoding, data)


def _parse_channel(content: memoryview) -> Channel:
    channel_id, schema_id = struct.unpack_from('<HH', content, 0)
    topic, pos = _string(content, 4)
    encoding, pos = _string(content, pos)
    (map_size,) = struct.unpack_from('<I', content, pos)
    pos += 4
    end = pos + map_size
    metadata = {}
    while pos < end:
        key, pos = _string(content, pos)
        metadata[key], pos = _string(content, pos)
    return Channel(channel_id, schema_id, topic, encoding, metadata)


class McapScan:
    """A sequential, damage-tolerant pass over one MCAP file.

    Iterating `records()` yields ScannedMessage and Damage items in file order; schemas and
    channels met on the way are collected in `schemas` and `channels`. `closed` tells
    whether the data section ended properly (the writer finished the file).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.closed = False

    def records(self) -> Iterator[ScannedMessage | Damage]:
        """Every message that can be framed, with a Damage item where something is wrong."""
        self.closed = False
        with self.path.open('rb') as stream:
            size = stream.seek(0, 2)
            stream.seek(0)
            if stream.read(len(MAGIC)) != MAGIC:
                yield Damage(0, 'not an MCAP file (bad magic bytes at the start)')
                return
            pos = len(MAGIC)
            while True:
                head = stream.read(_RECORD_HEAD.size)
                if not head:
                    yield Damage(
                        pos,
                        'the recording was not closed: the file ends after its '
                        'last complete record, with no summary or footer (the '
                        'writer crashed, was killed, or is still writing)',
                        unfinished=True,
                    )
                    return
                if len(head) < _RECORD_HEAD.size:
                    yield Damage(pos, f'the file ends inside a record header at byte {pos}')
                    return
                opcode, length = _RECORD_HEAD.unpack(head)
                name = RECORD_NAMES.get(opcode, f'opcode 0x{opcode:02x}')
                if opcode == 0:
                    yield Damage(pos, f'corrupt record at byte {pos}: opcode 0x00 is invalid')
                    return
                content_pos = pos + _RECORD_HEAD.size
                if content_pos + length > size:  # a file still being written grows meanwhile
                    size = os.fstat(stream.fileno()).st_size
                available = max(0, size - content_pos)
                if opcode == DATA_END:
                    self.closed = True
                    return
                if length > available:
                    recovered = 0
                    if opcode == CHUNK:  # a chunk cut short: keep the messages written whole
                        content = memoryview(stream.read(available))
                        for item in self._chunk(content, content_pos, complete=False):
                            recovered += isinstance(item, ScannedMessage)
                            yield item
                    yield Damage(
                        pos,
                        f'the {name} record at byte {pos} claims {length} bytes '
                        f'but only {available} remain: the file is truncated or '
                        f'the record is corrupt'
                        + (f' ({recovered} messages recovered from it)' if opcode == CHUNK else ''),
                    )
                    return
                content = memoryview(stream.read(length))
                if opcode == CHUNK:
                    yield from self._chunk(content, content_pos)
                else:
                    yield from self._record(opcode, content, content_pos)
                pos = content_pos + length

    def _record(
        self, opcode: int, content: memoryview, offset: int
    ) -> Iterator[ScannedMessage | Damage]:
        """Schema, channel or message record at file offset; others are skipped."""
        try:
            if opcode == SCHEMA:
                schema = _parse_schema(content)
                self.schemas[schema.id] = schema
            elif opcode == CHANNEL:
                channel = _parse_channel(content)
                self.channels[channel.id] = channel
            elif opcode == MESSAGE:
                channel_id, _, log_time, _ = _MESSAGE_HEAD.unpack_from(content, 0)
                channel = self.channels.get(channel_id)
                if channel is None:
                    yield Damage(
                        offset,
                        f'message at byte {offset} is on channel {channel_id}, '
                        'which no channel record defines',
                    )
                    return
                yield ScannedMessage(channel, log_time, content[_MESSAGE_HEAD.size :])
        except (struct.error, _Truncated, UnicodeDecodeError):
            yield Damage(offset, f'corrupt {RECORD_NAMES[opcode]} record at byte {offset}')

    def _chunk(
        self, content: memoryview, offset: int, complete: bool = True
    ) -> Iterator[ScannedMessage | Damage]:
        """The records inside one chunk; of an incomplete one, those written whole."""
        where = f'chunk at byte {offset - _RECORD_HEAD.size}'
        try:
            _, _, uncompressed_size, crc = _CHUNK_HEAD.unpack_from(content, 0)
            compression, pos = _string(content, _CHUNK_HEAD.size)
            (compressed_size,) = struct.unpack_from('<Q', content, pos)
        except (struct.error, _Truncated, UnicodeDecodeError):
            yield Damage(offset, f'{where}: corrupt chunk header')
            return
        pos += 8
        data = content[pos : pos + compressed_size]
        if complete and pos + compressed_size > len(content):
            yield Damage(offset, f'{where}: its data runs past the end of the chunk record')
            return
        if compression == '':
            records = data
        elif not complete:
            return  # a compressed stream cut short: nothing in it can be framed
        else:
            try:
                records = memoryview(_decompress(compression, data, uncompressed_size))
            except Exception as error:  # each codec raises its own error type
                yield Damage(offset, f'{where}: cannot decompress ({compression}): {error}')
                return
        if complete:
            if len(records) != uncompressed_size:
                yield Damage(
                    offset,
                    f'{where}: {len(records)} bytes of records, the chunk '
                    f'header says {uncompressed_size}',
                )
                return
            if crc and zlib.crc32(records) != crc:
                yield Damage(offset, f'{where}: checksum mismatch, its messages are corrupt')
                return
        inner = 0
        record_base = offset + pos
        while inner < len(records):
            if inner + _RECORD_HEAD.size > len(records):
                break
            opcode, length = _RECORD_HEAD.unpack_from(records, inner)
            start = inner + _RECORD_HEAD.size
            if opcode == 0 or start + length > len(records):
                if complete:
                    yield Damage(
                        offset,
                        f'{where}: corrupt record at chunk byte {inner} '
                        f'(opcode 0x{opcode:02x}, {length} bytes)',
                    )
                    return
                break  # a truncated chunk: the rest of this record was never written
            for item in self._record(opcode, records[start : start + length], record_base + start):
                yield item
                if isinstance(item, Damage):
                    return
            inner = start + length


def _decompress(compression: str, data: memoryview, size: int) -> bytes:
    """Chunk records compressed with zstd or lz4 (the two codecs MCAP defines)."""
    if compression == 'zstd':
        import zstandard

        return zstandard.ZstdDecompressor().decompress(bytes(data), max_output_size=size)
    if compression == 'lz4':
        import lz4.frame

        return lz4.frame.decompress(bytes(data))
    raise BadInputError(f'unknown chunk compression {compression!r}')
