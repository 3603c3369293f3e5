"""Bad bags: clear errors that name the problem, and nothing before the damage lost."""

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.rosbag2 import StoragePlugin, Writer

from fmm_ros.constants import FORCE_TOPIC, IMPACTS_TOPIC
from fmm_ros.io.bags import (
    IMPACT_RESULT,
    BagDamagedError,
    BagError,
    BagReader,
    BagWriter,
    MessageTypeError,
    MissingTopicError,
    fmm_typestore,
    new_message,
)
from fmm_ros.io.bags.mcapscan import Damage, McapScan, ScannedMessage

FS = 10_000.0
BATCH = 500


def ramp(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Force and velocity whose every sample says its own index: easy to check a prefix."""
    index = np.arange(n, dtype=np.float64)
    return index, -index


def write_chunked(path, batches: int = 12, per_chunk: int = 3) -> list:
    """A bag of ramp batches, a chunk every per_chunk batch pairs; returns the chunk indexes."""
    force, velocity = ramp(batches * BATCH)
    with BagWriter(path, time_origin_ns=0, flush_interval_s=None) as writer:
        for k in range(batches):
            writer.write_signals(
                force[k * BATCH : (k + 1) * BATCH],
                velocity[k * BATCH : (k + 1) * BATCH],
                FS,
                first_sample_index=k * BATCH,
            )
            if k % per_chunk == per_chunk - 1:
                writer.flush()
    with (path / f'{path.name}.mcap').open('rb') as stream:
        return sorted(
            make_reader(stream).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset
        )


def read_until_error(path, strict: bool = True):
    """Aligned samples read, and the error that stopped reading (None if none)."""
    force: list[np.ndarray] = []
    gaps = []
    error = None
    reader = BagReader(path, strict=strict)
    try:
        reader.open()
        for batch in reader.batches():
            force.append(batch.force)
            gaps.append(batch.gap_samples)
    except BagError as caught:
        error = caught
    joined = np.concatenate(force) if force else np.zeros(0)
    return joined, gaps, error, reader.problems


def test_truncated_bag_names_the_problem_and_keeps_every_message_before_it(tmp_path):
    bag = tmp_path / 'cut'
    chunks = write_chunked(bag)
    mcap = bag / 'cut.mcap'
    third = chunks[2]
    # Cut in the middle of the third chunk: 2 whole chunks (6 batch pairs) stay, plus the
    # messages of the third that were written whole before the cut.
    cut_at = third.chunk_start_offset + third.chunk_length // 2
    mcap.write_bytes(mcap.read_bytes()[:cut_at])

    force, gaps, error, _ = read_until_error(bag)
    assert isinstance(error, BagDamagedError)
    assert 'claims' in str(error) and 'truncated' in str(error) and str(bag) in str(error)
    assert len(force) >= 6 * BATCH and len(force) % BATCH == 0
    np.testing.assert_array_equal(force, np.arange(len(force)))

    lenient, _, error, problems = read_until_error(bag, strict=False)
    assert error is None
    np.testing.assert_array_equal(lenient, force)
    assert any('truncated' in p for p in problems)
    assert any('rosbags cannot open it' in p for p in problems)


def test_a_truncated_sqlite3_bag_is_read_row_by_row_up_to_the_damage(tmp_path):
    bag = tmp_path / 'db'
    force, velocity = ramp(200 * BATCH)
    with BagWriter(bag, storage='sqlite3', time_origin_ns=0) as writer:
        writer.write_signals(force, velocity, FS)
    database = bag / 'db.db3'
    database.write_bytes(database.read_bytes()[: database.stat().st_size // 2])

    read, _, error, _ = read_until_error(bag)
    assert isinstance(error, BagDamagedError)
    assert 'cannot be read past message row' in str(error)
    assert len(read) > 50 * BATCH  # rosbags alone reads none of a truncated database
    np.testing.assert_array_equal(read, np.arange(len(read)))
    lenient, _, error, problems = read_until_error(bag, strict=False)
    assert error is None and any('rosbags cannot open it' in p for p in problems)
    np.testing.assert_array_equal(lenient, read)


def test_a_corrupt_chunk_is_reported_and_reading_resumes_after_it(tmp_path):
    bag = tmp_path / 'rot'
    chunks = write_chunked(bag)
    mcap = bag / 'rot.mcap'
    data = bytearray(mcap.read_bytes())
    second = chunks[1]
    data[second.chunk_start_offset + second.chunk_length - 100] ^= 0x10  # one flipped bit
    mcap.write_bytes(bytes(data))

    force, _, error, _ = read_until_error(bag)
    assert isinstance(error, BagDamagedError) and 'checksum mismatch' in str(error)
    np.testing.assert_array_equal(force, np.arange(3 * BATCH))  # the first chunk, whole

    force, gaps, error, problems = read_until_error(bag, strict=False)
    assert error is None and any('checksum mismatch' in p for p in problems)
    expected = np.concatenate([np.arange(3 * BATCH), np.arange(6 * BATCH, 12 * BATCH)])
    np.testing.assert_array_equal(force, expected)
    assert sorted(gaps)[-1] == 3 * BATCH  # the lost chunk shows as a gap, not as data


def test_garbage_over_a_record_header_stops_reading_with_its_offset(tmp_path):
    bag = tmp_path / 'garbage'
    chunks = write_chunked(bag)
    mcap = bag / 'garbage.mcap'
    data = bytearray(mcap.read_bytes())
    start = chunks[2].chunk_start_offset
    data[start : start + 64] = b'\xff' * 64
    mcap.write_bytes(bytes(data))
    force, _, error, _ = read_until_error(bag)
    assert isinstance(error, BagDamagedError) and f'byte {start}' in str(error)
    np.testing.assert_array_equal(force, np.arange(6 * BATCH))


def test_not_a_bag_and_a_missing_bag(tmp_path):
    with pytest.raises(FileNotFoundError, match='does not exist'):
        BagReader(tmp_path / 'nowhere').open()
    (tmp_path / 'empty').mkdir()
    with pytest.raises(BagError, match=r'not a rosbag2 bag: no \.mcap or \.db3'):
        BagReader(tmp_path / 'empty').open()
    (tmp_path / 'notes.txt').write_text('hello')
    with pytest.raises(BagError, match='is not a bag'):
        BagReader(tmp_path / 'notes.txt').open()
    fake = tmp_path / 'fake.mcap'
    fake.write_bytes(b'not an mcap file at all')
    with BagReader(fake, strict=False) as reader:
        assert any('bad magic' in p for p in reader.problems)


def test_a_bag_without_the_expected_topics_names_what_it_has(tmp_path):
    bag = tmp_path / 'results_only'
    with BagWriter(bag, time_origin_ns=0) as writer:
        writer.write_message(IMPACTS_TOPIC, new_message(fmm_typestore(), IMPACT_RESULT), 1)
    with BagReader(bag) as reader, pytest.raises(MissingTopicError) as caught:
        list(reader.batches())
    message = str(caught.value)
    assert '/fmm/force' in message
    assert '/fmm/impacts (fmm_interfaces/msg/ImpactResult, 1)' in message


def test_unknown_message_types_are_named(tmp_path):
    with BagWriter(tmp_path / 'w', time_origin_ns=0) as writer:
        with pytest.raises(MessageTypeError, match='lab_msgs/msg/Mystery'):
            writer.write_raw('/lab/thing', 'lab_msgs/msg/Mystery', b'\x00\x01\x00\x00', 0)
        store = fmm_typestore()
        writer.write_message(FORCE_TOPIC, store.types['std_msgs/msg/Float64'](data=1.0), 0)
    with BagReader(tmp_path / 'w') as reader, pytest.raises(MessageTypeError) as caught:
        list(reader.batches())
    assert 'std_msgs/msg/Float64' in str(caught.value)
    assert 'expected fmm_interfaces/msg/SampleBatch' in str(caught.value)

    # A bag (written by some other tool) with a type it does not define.
    bag = tmp_path / 'foreign'
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as foreign:
        conn = foreign.add_connection(
            '/lab/thing', 'lab_msgs/msg/Mystery', msgdef='', rihs01='RIHS01_' + '0' * 64
        )
        foreign.write(conn, 5, b'\x00\x01\x00\x00\x07\x00\x00\x00')
    with BagReader(bag) as reader:
        assert reader.topics['/lab/thing'].msgtype == 'lab_msgs/msg/Mystery'
        message = next(reader.messages())
        with pytest.raises(MessageTypeError, match="'?lab_msgs/msg/Mystery'?, which neither"):
            reader.decode(message)


WRITER_SCRIPT = textwrap.dedent("""
    import sys
    import numpy as np
    from fmm_ros.io.bags import BagWriter
    path, storage = sys.argv[1], sys.argv[2]
    with BagWriter(path, storage=storage, time_origin_ns=0, flush_interval_s=None) as writer:
        for k in range(10**6):
            index = np.arange(k * 500, (k + 1) * 500, dtype=np.float64)
            writer.write_signals(index, -index, 10000.0, first_sample_index=k * 500)
            if k % 4 == 3:
                writer.flush()
                print(k * 500 + 500, flush=True)
""")


@pytest.mark.slow
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_a_killed_recording_is_read_up_to_its_last_flush(tmp_path, storage):
    bag = tmp_path / 'crashed'
    child = subprocess.Popen(
        [sys.executable, '-c', WRITER_SCRIPT, str(bag), storage], stdout=subprocess.PIPE, text=True
    )
    flushed = 0
    try:
        while flushed < 40 * BATCH:
            line = child.stdout.readline()
            assert line, 'the writer died before flushing'
            flushed = int(line)
    finally:
        os.kill(child.pid, signal.SIGKILL)
        child.wait()
        child.stdout.close()
    assert child.returncode == -signal.SIGKILL
    assert not (bag / 'metadata.yaml').exists()

    force, gaps, error, problems = read_until_error(bag, strict=False)
    assert error is None
    assert len(force) >= flushed
    np.testing.assert_array_equal(force, np.arange(len(force)))
    assert set(gaps) == {0}
    assert any('not closed' in p for p in problems)


def test_a_recording_that_grows_while_it_is_scanned_is_read_to_its_new_end(tmp_path):
    """The recorder writes on while a respawned node reads its bag (`io.bags.backfill`).

    The scan took the file's size once: records written after it put the position past that
    size, and the next read asked for a negative length (ValueError), so a respawned
    analyzer could not read the bag it was meant to recover from (fault_respawn, 1 of 1).
    """
    bag = tmp_path / 'grown'
    chunks = write_chunked(bag)
    file = bag / 'grown.mcap'
    whole = file.read_bytes()
    cut, grown = chunks[1].chunk_start_offset, chunks[3].chunk_start_offset
    file.write_bytes(whole[:cut])  # schemas, channels and the first chunk: flushed so far
    items = McapScan(file).records()
    first = next(items)
    with file.open('ab') as stream:  # the writer flushes two chunks more meanwhile
        stream.write(whole[cut:grown])
    scanned = [first, *items]
    messages = [item for item in scanned if isinstance(item, ScannedMessage)]
    assert len(messages) == 3 * 3 * 2  # three chunks of three batch pairs
    (end,) = [item for item in scanned if isinstance(item, Damage)]
    assert end.unfinished and end.offset == grown
