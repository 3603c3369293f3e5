"""Read what can be read of a damaged sqlite3 bag (.db3), row by row.

rosbags opens a .db3 as immutable and counts every message before it yields one, so a
truncated or corrupt database gives nothing. SQLite itself refuses a file shorter than the
page count its header states. This reads a copy whose header states the pages actually
present, and walks the messages table in insertion order until the first unreadable page,
with the same items as `McapScan.records()`.
"""

import shutil
import sqlite3
import tempfile
from collections.abc import Iterator
from pathlib import Path

from fmm_ros.io.bags.mcapscan import Channel, Damage, ScannedMessage, Schema

_HEADER = b'SQLite format 3\x00'
_PAGE_SIZE_AT, _PAGE_COUNT_AT = 16, 28  # big-endian fields of the database header


class SqliteScan:
    """A damage-tolerant pass over one rosbag2 sqlite3 database (see McapScan)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}

    def records(self) -> Iterator[ScannedMessage | Damage]:
        """Every message row that can be read, then a Damage naming what stopped it."""
        with tempfile.TemporaryDirectory(prefix='fmm_db3_') as folder:
            copy = Path(folder) / self.path.name
            shutil.copyfile(self.path, copy)
            problem = _fit_header_to_file(copy)
            if problem:
                yield Damage(0, problem)
                return
            connection = sqlite3.connect(f'file:{copy}?immutable=1', uri=True)
            try:
                yield from self._rows(connection)
            finally:
                connection.close()

    def _rows(self, connection: sqlite3.Connection) -> Iterator[ScannedMessage | Damage]:
        try:
            definitions = {}
            tables = {
                row[0]
                for row in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")
            }
            if 'message_definitions' in tables:
                rows = connection.execute(
                    'SELECT topic_type, encoding, '
                    'encoded_message_definition FROM message_definitions'
                )
                definitions = {name: (encoding, text) for name, encoding, text in rows}
            for topic_id, name, msgtype, encoding in connection.execute(
                'SELECT id, name, type, serialization_format FROM topics'
            ):
                schema_encoding, text = definitions.get(msgtype, ('', ''))
                self.schemas[topic_id] = Schema(topic_id, msgtype, schema_encoding, text)
                self.channels[topic_id] = Channel(topic_id, topic_id, name, encoding)
        except sqlite3.DatabaseError as error:
            yield Damage(0, f'the topics of the database cannot be read ({error})')
            return
        last = 0
        try:
            for row_id, topic_id, log_time, data in connection.execute(
                'SELECT id, topic_id, timestamp, data FROM messages ORDER BY id'
            ):
                channel = self.channels.get(topic_id)
                if channel is None:
                    yield Damage(
                        0,
                        f'message row {row_id} is on topic id {topic_id}, which '
                        'the topics table does not define',
                    )
                    return
                last = row_id
                yield ScannedMessage(channel, log_time, memoryview(data))
        except sqlite3.DatabaseError as error:
            yield Damage(0, f'the database cannot be read past message row {last} ({error})')


def _fit_header_to_file(path: Path) -> str | None:
    """Cut a copied database to whole pages and make its header state that many."""
    with path.open('r+b') as stream:
        header = stream.read(100)
        if len(header) < 100 or not header.startswith(_HEADER):
            return 'not an SQLite database (bad header)'
        page_size = int.from_bytes(header[_PAGE_SIZE_AT : _PAGE_SIZE_AT + 2], 'big')
        page_size = 65536 if page_size == 1 else page_size
        if page_size < 512 or page_size & (page_size - 1):
            return f'corrupt SQLite header (page size {page_size})'
        pages = stream.seek(0, 2) // page_size
        stream.truncate(pages * page_size)
        stream.seek(_PAGE_COUNT_AT)
        stream.write(pages.to_bytes(4, 'big'))
    return None
