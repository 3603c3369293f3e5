"""The two rosbag2 storage files, written with their own libraries' public APIs.

MCAP through the `mcap` package's writer: it computes each chunk's CRC-32 (a flipped bit in
a stored sample is then reported as damage, not read as data) and flushes a chunk on demand,
which is what crash safety needs. sqlite3 through Python's sqlite3 with rosbag2's schema
(version 4, as Jazzy writes it); a commit makes what was written survive a crash.
Both lay out a bag the way rosbag2's own plugins do: `ros2` profile, `ros2msg` schemas,
channel metadata with the offered QoS, and the bag's metadata repeated inside the file.
"""

import sqlite3
from dataclasses import dataclass
from pathlib import Path

from mcap.writer import CompressionType
from mcap.writer import Writer as McapFileWriter

# Chunk size of the MCAP writer [bytes]: rosbag2's default (768 KiB) in round figures.
MCAP_CHUNK_BYTES = 1 << 20
SQLITE_SCHEMA_VERSION = 4  # rosbag2's schema on Jazzy (message definitions, type hashes)


@dataclass(frozen=True)
class TopicRecord:
    """What a storage file stores about a topic."""

    topic: str
    msgtype: str
    msgdef: str  # the ros2msg text, dependencies included
    type_hash: str  # RIHS01_...
    qos_yaml: str  # offered_qos_profiles, as rosbag2 serializes them


class McapStorage:
    """A rosbag2 .mcap file written by the mcap library."""

    suffix = '.mcap'

    def __init__(self, path: Path, library: str) -> None:
        self.path = path
        self._file = path.open('xb')
        self._writer = McapFileWriter(
            self._file,
            chunk_size=MCAP_CHUNK_BYTES,
            compression=CompressionType.NONE,
            enable_crcs=True,
        )
        self._writer.start(profile='ros2', library=library)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}

    def add_topic(self, record: TopicRecord) -> None:
        """Declare a topic (and its type, once)."""
        schema = self._schemas.get(record.msgtype)
        if schema is None:
            schema = self._writer.register_schema(record.msgtype, 'ros2msg', record.msgdef.encode())
            self._schemas[record.msgtype] = schema
        self._channels[record.topic] = self._writer.register_channel(
            record.topic,
            'cdr',
            schema,
            {'offered_qos_profiles': record.qos_yaml, 'topic_type_hash': record.type_hash},
        )

    def write(self, topic: str, log_time_ns: int, data: bytes | memoryview) -> None:
        """Store one serialized message (log and publish time alike, as rosbag2 records)."""
        self._writer.add_message(self._channels[topic], log_time_ns, bytes(data), log_time_ns)

    def flush(self) -> None:
        """Close the pending chunk and hand everything to the OS (no fsync)."""
        self._writer.flush()

    def close(self, serialized_metadata: str) -> None:
        """Write the bag's metadata record, the summary and the footer; close the file."""
        self._writer.add_metadata('rosbag2', {'serialized_metadata': serialized_metadata})
        self._writer.finish()
        self._file.close()

    def abandon(self) -> None:
        """Close the file as it stands after a failed write (the reader recovers it by scanning).

        The buffered rest may fail to reach the disk too; the file is closed all the same.
        """
        try:
            self._file.close()
        except OSError:
            pass  # the disk refuses the rest: the bag reads up to what reached it


class Sqlite3Storage:
    """A rosbag2 .db3 file: rosbag2's tables, one transaction per flush interval."""

    suffix = '.db3'

    SCHEMA = """
    CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
    CREATE TABLE metadata(
      id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, metadata TEXT NOT NULL);
    CREATE TABLE topics(
      id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
      serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL,
      type_description_hash TEXT NOT NULL);
    CREATE TABLE message_definitions(
      id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL, encoding TEXT NOT NULL,
      encoded_message_definition TEXT NOT NULL, type_description_hash TEXT NOT NULL);
    CREATE TABLE messages(
      id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL,
      data BLOB NOT NULL);
    CREATE INDEX timestamp_idx ON messages (timestamp ASC);
    """

    def __init__(self, path: Path, ros_distro: str, metadata_version: int) -> None:
        self.path = path
        if path.exists():
            raise FileExistsError(f'{path} exists')
        self._db = sqlite3.connect(path)
        self._db.executescript(self.SCHEMA)
        self._db.execute(
            'INSERT INTO schema(schema_version, ros_distro) VALUES (?, ?)',
            (SQLITE_SCHEMA_VERSION, ros_distro),
        )
        self._db.commit()
        self._metadata_version = metadata_version
        self._topics: dict[str, int] = {}
        self._types: set[str] = set()

    def add_topic(self, record: TopicRecord) -> None:
        """Declare a topic (and its type, once)."""
        if record.msgtype not in self._types:
            self._types.add(record.msgtype)
            self._db.execute(
                'INSERT INTO message_definitions (topic_type, encoding, '
                'encoded_message_definition, type_description_hash) VALUES (?, ?, ?, ?)',
                (record.msgtype, 'ros2msg', record.msgdef, record.type_hash),
            )
        topic_id = len(self._topics) + 1
        self._db.execute(
            'INSERT INTO topics VALUES (?, ?, ?, ?, ?, ?)',
            (topic_id, record.topic, record.msgtype, 'cdr', record.qos_yaml, record.type_hash),
        )
        self._topics[record.topic] = topic_id

    def write(self, topic: str, log_time_ns: int, data: bytes | memoryview) -> None:
        """Store one serialized message."""
        self._db.execute(
            'INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)',
            (self._topics[topic], log_time_ns, data),
        )

    def flush(self) -> None:
        """Commit what was written since the last commit."""
        self._db.commit()

    def close(self, serialized_metadata: str) -> None:
        """Store the bag's metadata in the file, commit and close."""
        self._db.execute(
            'INSERT INTO metadata(metadata_version, metadata) VALUES (?, ?)',
            (self._metadata_version, serialized_metadata),
        )
        self._db.commit()
        self._db.execute('PRAGMA optimize')
        self._db.close()

    def abandon(self) -> None:
        """Close the database after a failed write: what was committed stays readable."""
        try:
            self._db.close()
        except sqlite3.Error:
            pass  # the uncommitted rest is lost; the committed transactions remain
