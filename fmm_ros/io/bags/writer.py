"""Write rosbag2 bags (MCAP by default, sqlite3 on request) without ROS.

Two ways in: numpy sample batches (serialized once, straight from the arrays, with rosbags'
CDR serializer) and raw CDR bytes (what a raw ROS subscription hands the recorder node, stored
as received). Either way the bag is the one `ros2 bag` and the recorder node write: rosbag2
metadata version 9 with the real ROS distribution, the fmm_interfaces definitions and type
hashes embedded, the offered QoS of each topic, and `custom_data` (the recorder's ledger).
The storage files are written by `storage.py` (the mcap library; sqlite3), no private API.

A recording must survive a crash of the process writing it: the writer flushes the pending
MCAP chunk (or commits the sqlite3 transaction) every `flush_interval_s` seconds of wall
time, so a kill loses at most that much; the reader recovers the rest (see reader.py).
Every MCAP chunk carries its CRC-32, so a flipped bit in a stored sample is reported as
damage instead of read as data.
"""

import sqlite3
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability
from rosbags.interfaces import QosTime as _QosTime
from rosbags.typesys.store import Typestore

from fmm_ros.constants import (
    BAG_STORAGES,
    BATCH_SIZE,
    FORCE,
    FORCE_TOPIC,
    SAMPLE_TOPIC_QOS,
    VELOCITY,
    VELOCITY_TOPIC,
    Channel,
    resolve_name,
)
from fmm_ros.errors import BadInputError
from fmm_ros.io.bags.definitions import SAMPLE_BATCH, fmm_typestore
from fmm_ros.io.bags.errors import BagError, MessageTypeError
from fmm_ros.io.bags.metadata import (
    ROSBAG2_VERSION,
    bag_information,
    metadata_yaml,
    qos_yaml,
    ros_distro,
)
from fmm_ros.io.bags.storage import McapStorage, Sqlite3Storage, TopicRecord

DEFAULT_BATCH_SIZE = BATCH_SIZE
# What writing a bag raises when the storage fails under it (disk full, read-only, gone).
WRITE_ERRORS = (OSError, sqlite3.Error)

_NO_TIME = _QosTime(0, 0)


def offered_qos(msgtype: str) -> Qos:
    """The QoS the fmm nodes offer for msgtype (ARCHITECTURE.md, Conventions).

    Sample batches: `SAMPLE_TOPIC_QOS`, the one declaration `fmm_ros.ros.qos.SAMPLE_QOS` is
    made of (reliable, volatile, keep-all: gaps break FRFs). Results: reliable,
    transient-local, depth 10, so a player republishes them for late subscribers too.
    """
    if msgtype == SAMPLE_BATCH:
        return bag_qos(**SAMPLE_TOPIC_QOS._asdict())
    return bag_qos(keep_all=False, depth=10, reliable=True, transient_local=True)


def bag_qos(*, keep_all: bool, depth: int, reliable: bool, transient_local: bool) -> Qos:
    """A QoS profile as rosbag2 metadata stores it (the player restores it)."""
    return Qos(
        QosHistory.KEEP_ALL if keep_all else QosHistory.KEEP_LAST,
        depth,
        QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        _NO_TIME,
        _NO_TIME,
        QosLiveliness.AUTOMATIC,
        _NO_TIME,
        False,
    )


def free_bag_path(path: Path) -> Path:
    """path, or the first of path_1, path_2, ... that does not exist.

    A respawned recorder starts a new bag beside the one it wrote before, never over it.
    """
    number = 0
    candidate = path
    while candidate.exists():
        number += 1
        candidate = path.with_name(f'{path.name}_{number}')
    return candidate


def sample_stamp_ns(time_origin_ns: int, sample_index: int, sample_rate_hz: float) -> int:
    """Acquisition time [ns] of sample_index when sample 0 was taken at time_origin_ns."""
    return time_origin_ns + round(sample_index * 1e9 / sample_rate_hz)


class BagWriter:
    """A rosbag2 bag being written; use as a context manager (closing writes metadata.yaml).

    path: the bag directory to create (must not exist). storage: 'mcap' or 'sqlite3'.
    time_origin_ns: acquisition time of sample index 0, for headers and log times of batches
    written from arrays (default: now). flush_interval_s: most wall time a crash can lose
    (None: flush only on close). Relative topic names are resolved in the root namespace,
    as a node there would resolve them (`fmm/force` is stored as /fmm/force).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        storage: str = 'mcap',
        time_origin_ns: int | None = None,
        flush_interval_s: float | None = 1.0,
        typestore: Typestore | None = None,
    ) -> None:
        if storage not in BAG_STORAGES:
            raise BagError(f'unknown bag storage {storage!r}: use one of {", ".join(BAG_STORAGES)}')
        if flush_interval_s is not None and flush_interval_s <= 0:
            raise BadInputError(f'flush_interval_s must be positive, got {flush_interval_s}')
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f'cannot create bag {self.path}: it exists already, not overwriting')
        self.storage = storage
        self.typestore = typestore or fmm_typestore()
        self.time_origin_ns = time.time_ns() if time_origin_ns is None else int(time_origin_ns)
        self.flush_interval_s = flush_interval_s
        self.custom_data: dict[str, str] = {}
        """rosbag2's custom_data: strings stored in metadata.yaml when the bag closes."""
        self._file: McapStorage | Sqlite3Storage | None = None
        self._topics: dict[str, dict] = {}
        self._start_ns = 2**63 - 1
        self._end_ns = 0
        self._last_flush = time.monotonic()
        self.last_flush_wall_ns = 0
        """time.time_ns() of the last flush (0: none yet)."""
        self.messages_written = 0
        self.bytes_written = 0
        self.unflushed = 0
        """Messages written since the last flush (what a crash now would lose)."""

    def __enter__(self) -> 'BagWriter':
        self.open()
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    @property
    def storage_file(self) -> Path:
        """The .mcap or .db3 file inside the bag directory."""
        return self.path / f'{self.path.name}.{"mcap" if self.storage == "mcap" else "db3"}'

    def open(self) -> None:
        """Create the bag directory and its storage file."""
        try:
            self.path.mkdir(mode=0o755, parents=True)
        except FileExistsError:
            raise BagError(
                f'cannot create bag {self.path}: it exists already, not overwriting'
            ) from None
        except OSError as error:
            raise BagError(f'cannot create bag {self.path}: {error}') from None
        if self.storage == 'mcap':
            self._file = McapStorage(self.storage_file, library=f'fmm_ros ({ros_distro()})')
        else:
            self._file = Sqlite3Storage(self.storage_file, ros_distro(), ROSBAG2_VERSION)

    def close(self) -> None:
        """Finish the storage file (MCAP summary and index) and write metadata.yaml."""
        if self._file is None:
            return
        storage, self._file = self._file, None
        information = bag_information(
            storage=self.storage,
            file_name=self.storage_file.name,
            topics=list(self._topics.values()),
            start_ns=self._start_ns,
            end_ns=self._end_ns,
            custom_data=self.custom_data,
        )
        storage.close(metadata_yaml(information))
        target = self.path / 'metadata.yaml'
        partial = target.with_suffix('.yaml.tmp')
        partial.write_text(metadata_yaml(information), encoding='utf-8')
        partial.replace(target)

    def abandon(self) -> None:
        """Close the storage file as it is, after a write failed.

        Disk full, path read-only, mount gone: no summary, no metadata.yaml, nothing more
        written; the reader recovers the bag by scanning up to where it got (as after a crash).
        """
        if self._file is None:
            return
        storage, self._file = self._file, None
        storage.abandon()

    def set_custom_data(self, key: str, value: str) -> None:
        """One custom_data entry (a string), stored when the bag closes."""
        if not isinstance(value, str):
            raise TypeError(f'custom_data values are strings, got {type(value).__name__}')
        self.custom_data[key] = value

    def add_topic(self, topic: str, msgtype: str, *, qos: Qos | None = None) -> None:
        """Declare topic with msgtype (done on first write otherwise); qos: the offered QoS."""
        topic = resolve_name(topic)
        if topic in self._topics:
            known = self._topics[topic]['type']
            if known != msgtype:
                raise BagError(
                    f'topic {topic} is already in bag {self.path} as {known}, '
                    f'cannot also write {msgtype}'
                )
            return
        if msgtype not in self.typestore.fielddefs:
            raise MessageTypeError(
                f'unknown message type {msgtype!r} for topic {topic}: the bag writer knows '
                'the fmm_interfaces messages and the ROS 2 Jazzy standard types'
            )
        if self._file is None:
            raise BagError(f'bag {self.path} is not open')
        profiles = [qos or offered_qos(msgtype)]
        msgdef, _ = self.typestore.generate_msgdef(msgtype, ros_version=2)
        type_hash = self.typestore.hash_rihs01(msgtype)
        self._file.add_topic(TopicRecord(topic, msgtype, msgdef, type_hash, qos_yaml(profiles)))
        self._topics[topic] = {
            'name': topic,
            'type': msgtype,
            'hash': type_hash,
            'qos': profiles,
            'count': 0,
        }

    def write_raw(
        self, topic: str, msgtype: str, data: bytes | memoryview, log_time_ns: int
    ) -> None:
        """Store one serialized (CDR) message as received, without decoding it."""
        topic = resolve_name(topic)
        if topic not in self._topics:
            self.add_topic(topic, msgtype)
        if self._file is None:
            raise BagError(f'bag {self.path} is not open')
        log_time_ns = int(log_time_ns)
        self._file.write(topic, log_time_ns, data)
        self._topics[topic]['count'] += 1
        self._start_ns = min(self._start_ns, log_time_ns)
        self._end_ns = max(self._end_ns, log_time_ns)
        self.messages_written += 1
        self.unflushed += 1
        self.bytes_written += len(data)
        self.flush_if_due()

    def flush_if_due(self) -> None:
        """Flush if messages have waited flush_interval_s since the last flush.

        Writing calls it; a writer that may sit idle (a recorder between sessions) should call
        it periodically too, or its last messages wait for the next write or the close.
        """
        if (
            self.unflushed
            and self.flush_interval_s is not None
            and time.monotonic() - self._last_flush >= self.flush_interval_s
        ):
            self.flush()

    def write_message(self, topic: str, message, log_time_ns: int) -> None:
        """Serialize one rosbags message object (e.g. an ImpactResult) and store it."""
        msgtype = message.__msgtype__
        self.write_raw(topic, msgtype, self.typestore.serialize_cdr(message, msgtype), log_time_ns)

    def write_sample_batch(
        self,
        topic: str,
        samples: np.ndarray,
        *,
        quantity: tuple[str, str],
        sample_rate_hz: float,
        first_sample_index: int,
        frame_id: str = '',
        full_scale: float = 0.0,
        log_time_ns: int | None = None,
    ) -> None:
        """One SampleBatch from an array of samples [SI unit of quantity].

        The header stamp is the acquisition time of samples[0]; the log time defaults to
        when the last sample was taken, as a live recording would see it.
        """
        types = self.typestore.types
        stamp_ns = sample_stamp_ns(self.time_origin_ns, first_sample_index, sample_rate_hz)
        if log_time_ns is None:
            log_time_ns = sample_stamp_ns(
                self.time_origin_ns, first_sample_index + len(samples), sample_rate_hz
            )
        header = types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](
                sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9
            ),
            frame_id=frame_id,
        )
        message = types[SAMPLE_BATCH](
            header=header,
            quantity=quantity[0],
            unit=quantity[1],
            sample_rate_hz=float(sample_rate_hz),
            first_sample_index=int(first_sample_index),
            full_scale=float(full_scale),
            samples=np.ascontiguousarray(samples, dtype=np.float64),
        )
        self.write_message(topic, message, log_time_ns)

    def write_signals(
        self,
        force: np.ndarray,
        velocity: np.ndarray,
        sample_rate_hz: float,
        *,
        first_sample_index: int = 0,
        batch_size: int = DEFAULT_BATCH_SIZE,
        full_scale_force: float = 0.0,
        full_scale_velocity: float = 0.0,
        force_frame: str = 'hammer',
        velocity_frame: str = 'vibrometer',
        on_progress: Callable[[int], None] | None = None,
        response: Channel = VELOCITY,
    ) -> int:
        """Whole force [N] and velocity [m/s] records as batches on /fmm/force, /fmm/velocity.

        Both channels share one sample index, as a DAQ publishes them. on_progress gets the
        number of samples written per batch. Returns the index after the last sample.
        response: what the second channel measures (`RESPONSE_CHANNELS`: an accelerometer's
        m/s^2 go on the velocity topic as quantity 'acceleration').
        """
        if len(force) != len(velocity):
            raise BadInputError(
                f'force has {len(force)} samples but velocity {len(velocity)}: '
                'the two channels of one acquisition must be equally long'
            )
        if batch_size < 1:
            raise BadInputError(f'batch_size must be at least 1, got {batch_size}')
        for start in range(0, len(force), batch_size):
            index = first_sample_index + start
            stop = start + batch_size
            self.write_sample_batch(
                FORCE_TOPIC,
                force[start:stop],
                quantity=FORCE,
                sample_rate_hz=sample_rate_hz,
                first_sample_index=index,
                frame_id=force_frame,
                full_scale=full_scale_force,
            )
            self.write_sample_batch(
                VELOCITY_TOPIC,
                velocity[start:stop],
                quantity=response,
                sample_rate_hz=sample_rate_hz,
                first_sample_index=index,
                frame_id=velocity_frame,
                full_scale=full_scale_velocity,
            )
            if on_progress:
                on_progress(len(force[start:stop]))
        return first_sample_index + len(force)

    def flush(self) -> None:
        """Make everything written so far survive a crash of this process.

        MCAP: close the pending chunk (with its message index) and hand it to the OS.
        sqlite3: commit the open transaction.
        """
        if self._file is None:
            return
        self._file.flush()
        self.unflushed = 0
        self._last_flush = time.monotonic()
        self.last_flush_wall_ns = time.time_ns()
