"""A clean recording read whole: the same records and results as batch by batch.

`BagReader.channel_arrays` finds both channels of a clean MCAP bag in the file, and replay
copies them out and feeds them to the capture in blocks. These tests hold that road to the old one
(every batch decoded and fed in delivery order): equal results field by field, equal ledgers
and counts, and no whole read at all where a bag is not clean (a gap, a skew, damage,
another storage), so every fault keeps its rule.
"""

import dataclasses
import json

import numpy as np
import pytest
from reference_analysis import numpy_steps

from fmm_ros.cli import main
from fmm_ros.constants import FORCE, FORCE_TOPIC, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.signal.analysis import AnalysisConfig, analyze_impact, paper_levels, summarize
from fmm_ros.core.signal.capture import CaptureConfig, ImpactCapture
from fmm_ros.core.signal.records import stable_impact_id
from fmm_ros.io.bags import SAMPLE_BATCH, BagReader, BagWriter
from fmm_ros.io.bags.arrays import LAYOUT_MSG
from fmm_ros.sim.session import simulated_session, write_session_bag
from fmm_ros.workflows.replay import Fed, bag_impact_records, capture_records, replay_bag
from fmm_ros.workflows.session import analyse, impact_ids

CAPTURE = CaptureConfig(window_s=5.0)
ANALYSIS = AnalysisConfig(levels=paper_levels())
BATCH = 500


@pytest.fixture(scope='module')
def session():
    return simulated_session(2, spacing_s=6.0, seed=5)


@pytest.fixture(scope='module')
def session_bag(session, tmp_path_factory):
    return write_session_bag(tmp_path_factory.mktemp('whole') / 'session', session)


def batch_by_batch(bag, capture=CAPTURE):
    """Today's road: every batch decoded and fed (an on_batch observer keeps replay on it)."""
    impacts, fed, results = ImpactCapture(capture), Fed(), []
    with BagReader(bag, strict=False) as reader:
        for record in capture_records(
            reader, impacts, reuse_buffers=True, on_batch=lambda _: None, fed=fed
        ):
            results.append(
                analyze_impact(record, capture, ANALYSIS, impact_id=stable_impact_id(record))
            )
        problems = list(reader.problems)
    return results, impacts.ledger, fed, problems


def assert_same_results(ours, theirs):
    assert len(ours) == len(theirs) > 0
    for mine, old in zip(ours, theirs, strict=True):
        for field in dataclasses.fields(mine):
            a, b = getattr(mine, field.name), getattr(old, field.name)
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b, err_msg=field.name)
            elif isinstance(a, float) and np.isnan(a):
                assert np.isnan(b), field.name
            else:
                assert a == b, field.name


def write_batches(path, session, *, skip=(), order='interleaved', scale_change_at=None):
    """A bag of the session's batches; skip: (topic, first index) pairs left out."""
    starts = range(0, len(session.force_n), BATCH)
    rows = [
        (topic, start)
        for start in starts
        for topic in (FORCE_TOPIC, VELOCITY_TOPIC)
        if (topic, start) not in skip
    ]
    if order == 'channel after channel':
        rows.sort(key=lambda row: row[0] != FORCE_TOPIC)
    with BagWriter(path, time_origin_ns=0) as writer:
        for row, (topic, start) in enumerate(rows):  # logged in the order written
            force = topic == FORCE_TOPIC
            scale = 5000.0 if scale_change_at is None or start < scale_change_at else 6000.0
            writer.write_sample_batch(
                topic,
                (session.force_n if force else session.velocity_m_s)[start : start + BATCH],
                quantity=FORCE if force else VELOCITY,
                sample_rate_hz=session.sample_rate_hz,
                first_sample_index=start,
                full_scale=scale if force else 0.0,
                log_time_ns=row * 25_000_000,
            )
    return path


def test_a_clean_bag_is_read_whole_into_the_recorded_samples(session, session_bag):
    with BagReader(session_bag) as reader:
        whole = reader.channel_arrays()
    assert whole is not None
    np.testing.assert_array_equal(whole.force, session.force_n)
    np.testing.assert_array_equal(whole.velocity, session.velocity_m_s)
    assert whole.first_sample_index == 0 and whole.sample_rate_hz == session.sample_rate_hz
    assert whole.batches == 2 * -(-len(session.force_n) // BATCH)


@pytest.mark.parametrize('size', [777, BATCH, 65536])
def test_a_clean_bag_is_copied_out_block_by_block_into_the_recorded_samples(
    session, session_bag, size
):
    """Blocks of any size, their edges inside a batch or on one, join into the recording."""
    with BagReader(session_bag) as reader:
        blocks = list(reader.channel_arrays().blocks(size))
    assert [low for low, *_ in blocks] == list(range(0, len(session.force_n), size))
    np.testing.assert_array_equal(np.concatenate([f for _, f, _ in blocks]), session.force_n)
    np.testing.assert_array_equal(np.concatenate([v for *_, v in blocks]), session.velocity_m_s)


@pytest.mark.parametrize('case', ['clean', 'dropped velocity batch', 'short batches'])
def test_the_chunks_are_walked_to_every_message_the_mcap_library_finds(
    session, session_bag, tmp_path, case
):
    """The walk takes repeating records in runs (`_message_run`): where the pattern breaks (a
    dropped batch, batches of other sizes) it finds the same messages, in the same order."""
    from mcap.reader import make_reader

    from fmm_ros.io.bags.arrays import _messages

    if case == 'clean':
        bag = session_bag
    elif case == 'dropped velocity batch':
        hit = int(session.hit_start_indices[1]) // BATCH * BATCH
        bag = write_batches(tmp_path / 'bag', session, skip={(VELOCITY_TOPIC, hit)})
    else:
        bag = tmp_path / 'bag'
        with BagWriter(bag, time_origin_ns=0) as writer:
            writer.write_signals(session.force_n, session.velocity_m_s, 10_000.0, batch_size=333)
    mcap = next(bag.glob('*.mcap'))
    with mcap.open('rb') as stream:
        reader = make_reader(stream)
        topics = {c.id: c.topic for c in reader.get_summary().channels.values()}
        stored = [(topics[c.id], m.log_time, len(m.data)) for _, c, m in reader.iter_messages()]
    stored.sort(key=lambda row: row[1])  # delivery order: by log time, ties in file order
    names = ('/' + FORCE_TOPIC, '/' + VELOCITY_TOPIC)
    channel, _, lengths, _ = _messages(np.fromfile(mcap, dtype=np.uint8), names)
    assert [(names[c], n) for c, n in zip(channel, lengths, strict=True)] == [
        (topic, n) for topic, _, n in stored if topic in names
    ]


@pytest.mark.slow
def test_replay_of_a_clean_bag_equals_replay_batch_by_batch(session_bag):
    replay = replay_bag(session_bag, CAPTURE, ANALYSIS)
    results, ledger, fed, problems = batch_by_batch(session_bag)
    assert_same_results(replay.results, results)
    assert replay.signal_s == fed.signal_s and replay.batches == fed.batches
    assert {q: v.to_dict() for q, v in replay.ledger.items()} == {
        q: v.to_dict() for q, v in ledger.items()
    }
    assert replay.problems == problems == []
    # The records a campaign session reads take the same road.
    records, _ = bag_impact_records(session_bag, CAPTURE)
    with BagReader(session_bag) as reader:
        old = list(capture_records(reader, CAPTURE, on_batch=lambda _: None))
    assert [r.trigger_sample_index for r in records] == [r.trigger_sample_index for r in old]
    for mine, theirs in zip(records, old, strict=True):
        np.testing.assert_array_equal(mine.velocity_m_s, theirs.velocity_m_s)
        assert mine.source == theirs.source and mine.force_gaps == theirs.force_gaps


@pytest.mark.slow
@pytest.mark.parametrize('threads', [1, 2, 3])
def test_replay_analyses_in_threads_with_the_results_of_one_record_at_a_time(session_bag, threads):
    """Records analysed side by side while later ones are captured: the same results to the
    bit, handed on in capture order, as the serial road (one thread) gives them."""
    handed = []
    replay = replay_bag(session_bag, CAPTURE, ANALYSIS, on_result=handed.append, threads=threads)
    results, *_ = batch_by_batch(session_bag)
    assert_same_results(replay.results, results)
    assert handed == replay.results
    # A campaign session (or `fmm report`) reads the same records and analyses them in
    # threads too, each under its id on the session's axis, as the replay names them.
    records, _ = bag_impact_records(session_bag, CAPTURE)
    summary = analyse(records, CAPTURE, ANALYSIS)
    ids = impact_ids(records, CAPTURE)
    serial = summarize(
        [
            analyze_impact(r, CAPTURE, ANALYSIS, impact_id=i)
            for i, r in zip(ids, records, strict=True)
        ],
        ANALYSIS,
    )
    assert [impact.impact_id for impact in summary.impacts] == [
        result.impact_id for result in replay.results
    ]
    assert_same_results(summary.impacts, serial.impacts)
    assert_same_results(summary.levels, serial.levels)


@pytest.mark.slow
def test_fmm_replay_prints_what_it_printed_before_its_analysis_was_made_faster(session_bag, capsys):
    """With the faster analysis steps swapped back for their numpy definitions
    (`reference_analysis`), replay gives the same results to the bit and prints the same JSON
    (all but how fast it ran)."""
    argv = ['replay', str(session_bag), '--paper-levels', '--window-s', '5', '--json']

    def replayed():
        assert main(argv) == 0
        document = json.loads(capsys.readouterr().out)
        del document['replay']['times_real_time'], document['replay']['wall_s']
        return replay_bag(session_bag, CAPTURE, ANALYSIS), document

    fast, printed = replayed()
    with numpy_steps():
        numpy_defined, printed_before = replayed()
    assert_same_results(fast.results, numpy_defined.results)
    assert printed == printed_before and len(printed['impacts']) == 6


@pytest.mark.slow
@pytest.mark.parametrize(
    'case',
    ['dropped velocity batch', 'channel after channel', 'full scale changes', 'corrupt chunk'],
)
def test_a_bag_that_is_not_clean_is_read_batch_by_batch(session, tmp_path, case):
    hit = int(session.hit_start_indices[1]) // BATCH * BATCH
    if case == 'dropped velocity batch':
        bag = write_batches(tmp_path / 'bag', session, skip={(VELOCITY_TOPIC, hit)})
    elif case == 'channel after channel':  # the velocity lags far beyond max_skew_s
        bag = write_batches(tmp_path / 'bag', session, order=case)
    elif case == 'full scale changes':
        bag = write_batches(tmp_path / 'bag', session, scale_change_at=hit)
    else:
        bag = write_batches(tmp_path / 'bag', session)
        mcap = next(bag.glob('*.mcap'))
        data = bytearray(mcap.read_bytes())
        data[len(data) // 2] ^= 0x40  # one flipped bit in a stored sample
        mcap.write_bytes(bytes(data))
    with BagReader(bag, strict=False) as reader:
        assert reader.channel_arrays() is None
    replay = replay_bag(bag, CAPTURE, ANALYSIS)
    results, ledger, fed, problems = batch_by_batch(bag)
    assert_same_results(replay.results, results)
    assert replay.batches == fed.batches and replay.problems[: len(problems)] == problems
    assert {q: v.to_dict() for q, v in replay.ledger.items()} == {
        q: v.to_dict() for q, v in ledger.items()
    }


def test_a_bag_that_defines_the_layout_otherwise_is_read_batch_by_batch(session_bag):
    """A SampleBatch the bag defines with other fields is not parsed by the whole read, and
    the clean bag's own definitions build no typestore on the way (replay's start-up)."""
    with BagReader(session_bag) as reader:
        assert reader.channel_arrays() is not None and reader._typestore is None
        narrower = LAYOUT_MSG.replace('float64 full_scale', 'float32 full_scale')
        reader._read_definitions({SAMPLE_BATCH: narrower})
        assert reader.problems == [] and reader.channel_arrays() is None


def test_a_sqlite3_bag_is_read_batch_by_batch(session, tmp_path):
    bag = write_session_bag(tmp_path / 'db', session, storage='sqlite3')
    with BagReader(bag) as reader:
        assert reader.channel_arrays() is None
