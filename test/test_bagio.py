"""Bag I/O: what the core writes, an independent MCAP decoder reads identically."""

from pathlib import Path

import numpy as np
import pytest
import yaml
from bag_helpers import assert_same, random_message
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader

from fmm_ros.constants import FORCE_TOPIC, FRF_TOPIC, IMPACTS_TOPIC, VELOCITY_TOPIC, resolve_name
from fmm_ros.io.bags import (
    FRF_SUMMARY,
    IMPACT_RESULT,
    SAMPLE_BATCH,
    BagError,
    BagReader,
    BagWriter,
    fmm_typestore,
    new_message,
)
from fmm_ros.io.bags.arrays import layout_types
from fmm_ros.io.bags.metadata import load_yaml

# A bag holds the names a node in the root namespace resolves the relative topics to.
FORCE_TOPIC, VELOCITY_TOPIC, IMPACTS_TOPIC, FRF_TOPIC = map(
    resolve_name, (FORCE_TOPIC, VELOCITY_TOPIC, IMPACTS_TOPIC, FRF_TOPIC)
)

FS = 10_000.0
ORIGIN_NS = 1_700_000_000_123_456_789


def signals(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(0.0, 50.0, n), rng.normal(0.0, 1e-3, n)


def write_session(path: Path, n: int = 4_000, *, storage: str = 'mcap'):
    """A small bag of every recorded type: batches from arrays and from raw CDR, results."""
    force, velocity = signals(n)
    rng = np.random.default_rng(7)
    store = fmm_typestore()
    results = [random_message(store, IMPACT_RESULT, rng) for _ in range(3)]
    summaries = [random_message(store, FRF_SUMMARY, rng) for _ in range(2)]
    with BagWriter(path, storage=storage, time_origin_ns=ORIGIN_NS) as writer:
        writer.write_signals(force[: n // 2], velocity[: n // 2], FS)
        # The second half arrives as raw CDR, as a raw subscription hands it to the recorder.
        for start in range(n // 2, n, 500):
            for topic, data, quantity in (
                (FORCE_TOPIC, force, ('force', 'N')),
                (VELOCITY_TOPIC, velocity, ('velocity', 'm/s')),
            ):
                message = new_message(
                    store,
                    SAMPLE_BATCH,
                    quantity=quantity[0],
                    unit=quantity[1],
                    sample_rate_hz=FS,
                    first_sample_index=start,
                    samples=data[start : start + 500],
                )
                raw = bytes(store.serialize_cdr(message, SAMPLE_BATCH))
                writer.write_raw(topic, SAMPLE_BATCH, raw, ORIGIN_NS + start * 100_000)
        for i, result in enumerate(results):
            writer.write_message(IMPACTS_TOPIC, result, ORIGIN_NS + i)
        for i, summary in enumerate(summaries):
            writer.write_message(FRF_TOPIC, summary, ORIGIN_NS + 10 + i)
    return force, velocity, results, summaries


def test_round_trip_mcap_decoder_reads_every_field_identically(tmp_path):
    bag = tmp_path / 'session'
    force, velocity, results, summaries = write_session(bag)
    decoded: dict[str, list] = {}
    with (bag / 'session.mcap').open('rb') as stream:
        reader = make_reader(stream, validate_crcs=True, decoder_factories=[DecoderFactory()])
        for schema, channel, message, value in reader.iter_decoded_messages():
            assert schema.encoding == 'ros2msg' and channel.message_encoding == 'cdr'
            decoded.setdefault(channel.topic, []).append((message.log_time, value))
    for topic, expected in ((FORCE_TOPIC, force), (VELOCITY_TOPIC, velocity)):
        batches = [value for _, value in decoded[topic]]
        assert [b.first_sample_index for b in batches] == list(range(0, len(force), 500))
        np.testing.assert_array_equal(np.concatenate([b.samples for b in batches]), expected)
        assert {b.sample_rate_hz for b in batches} == {FS}
    first = decoded[FORCE_TOPIC][1][1]
    stamp_ns = ORIGIN_NS + 500 * 100_000
    assert (first.header.stamp.sec, first.header.stamp.nanosec) == divmod(stamp_ns, 10**9)
    assert (first.quantity, first.unit, first.header.frame_id) == ('force', 'N', 'hammer')
    for expected, (_, got) in zip(results, decoded[IMPACTS_TOPIC], strict=True):
        assert_same(got, expected)
    for expected, (_, got) in zip(summaries, decoded[FRF_TOPIC], strict=True):
        assert_same(got, expected)


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_rosbags_and_bag_reader_give_the_same_arrays(tmp_path, storage):
    bag = tmp_path / 'session'
    force, velocity, results, summaries = write_session(bag, storage=storage)
    store = fmm_typestore()
    with Reader(bag) as plain:
        assert plain.message_count == 16 + 5
        rosbags_samples = {FORCE_TOPIC: [], VELOCITY_TOPIC: []}
        for conn, _, data in plain.messages():
            if conn.topic in rosbags_samples:
                rosbags_samples[conn.topic].append(
                    store.deserialize_cdr(data, conn.msgtype).samples
                )
    with BagReader(bag) as reader:
        assert reader.storage == storage and not reader.recovered and not reader.problems
        assert {t.topic: t.count for t in reader.topics.values()} == {
            FORCE_TOPIC: 8,
            VELOCITY_TOPIC: 8,
            IMPACTS_TOPIC: 3,
            FRF_TOPIC: 2,
        }
        batches = list(reader.batches())
        assert [b.first_sample_index for b in batches] == list(range(0, 4000, 500))
        assert all(b.gap_samples == 0 and b.sample_rate_hz == FS for b in batches)
        for name, expected in (('force', force), ('velocity', velocity)):
            ours = np.concatenate([getattr(b, name) for b in batches])
            np.testing.assert_array_equal(ours, expected)
            topic = FORCE_TOPIC if name == 'force' else VELOCITY_TOPIC
            np.testing.assert_array_equal(np.concatenate(rosbags_samples[topic]), expected)
        for expected, got in zip(results, reader.impacts(), strict=True):
            assert_same(got, expected)
        for expected, got in zip(summaries, reader.frf_summaries(), strict=True):
            assert_same(got, expected)
        # As a live subscriber received them: both channels, interleaved, in storage order.
        arrived = [(b.topic, b.first_sample_index) for b in reader.sample_batches()]
        assert arrived == [
            (topic, index)
            for index in range(0, 4000, 500)
            for topic in (FORCE_TOPIC, VELOCITY_TOPIC)
        ]


def test_batches_are_views_of_the_stored_bytes(tmp_path):
    write_session(tmp_path / 'bag')
    with BagReader(tmp_path / 'bag') as reader:
        batch = next(reader.batches())
    assert batch.force.base is not None and not batch.force.flags.owndata
    assert not batch.force.flags.writeable


def test_new_message_names_an_unknown_field():
    with pytest.raises(ValueError, match='has no field impulse_ns'):
        new_message(fmm_typestore(), IMPACT_RESULT, impulse_ns=1.0)


def test_metadata_is_parsed_to_what_yaml_safe_load_gives(tmp_path):
    """load_yaml (libyaml where PyYAML has it) reads a bag's metadata.yaml, its
    custom_data included, to yaml.safe_load's document; a damaged one is a YAMLError."""
    bag = tmp_path / 'session'
    write_session(bag, storage='mcap')
    text = (bag / 'metadata.yaml').read_text(encoding='utf-8')
    assert load_yaml(text) == yaml.safe_load(text) != {}
    for damaged in (text[: len(text) // 2] + ': [', 'a: b: c', '\t- x'):
        with pytest.raises(yaml.YAMLError):
            yaml.safe_load(damaged)
        with pytest.raises(yaml.YAMLError):
            load_yaml(damaged)


def test_bags_with_the_same_definitions_share_a_typestore_and_each_hears_of_a_bad_one(tmp_path):
    bag = tmp_path / 'session'
    write_session(bag, n=1_000)
    with BagReader(bag) as first, BagReader(bag) as second:
        assert first.typestore is second.typestore  # parsed once for every bag a recorder wrote
        assert SAMPLE_BATCH in first.typestore.fielddefs and first.problems == []
        for reader in (first, second):
            reader._read_definitions({SAMPLE_BATCH: 'float64[ samples'})
        assert first.typestore is second.typestore is fmm_typestore()  # this installation's
        for reader in (first, second):  # the cached parse's problem told to every reader
            assert [
                f'the definition of {SAMPLE_BATCH} in the bag cannot be' in p
                for p in reader.problems
            ] == [True]
        for reader in (first, second):  # a standard type redefined is refused every time
            reader._read_definitions({'std_msgs/msg/Header': 'int32 seq'})
            with pytest.raises(BagError, match='defines a standard type differently'):
                reader.decode(next(reader.messages()))


def test_the_whole_read_parses_the_layout_of_this_installations_sample_batch():
    """The layout a clean recording is read whole by (arrays.LAYOUT_MSG, declared there so
    replay builds no typestore) is fmm_interfaces' SampleBatch and ROS 2's Header and Time."""
    own = fmm_typestore().fielddefs
    layout = layout_types()
    assert sorted(layout) == sorted(
        [SAMPLE_BATCH, 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time']
    )
    assert {name: own[name] for name in layout} == layout
