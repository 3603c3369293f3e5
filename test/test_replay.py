"""Replay and offline analysis of bags: the live capture's impacts, from the batches."""

import dataclasses
import json

import numpy as np
import pytest

from fmm_ros.cli import main
from fmm_ros.constants import FORCE, FORCE_TOPIC, VELOCITY, VELOCITY_TOPIC
from fmm_ros.core.signal.analysis import AnalysisConfig, analyze_impact, paper_levels, summarize
from fmm_ros.core.signal.capture import CaptureConfig, capture_impacts
from fmm_ros.core.signal.records import write_impact_csv
from fmm_ros.io.bags import BagWriter
from fmm_ros.sim.session import simulated_session, write_session_bag
from fmm_ros.workflows.replay import bag_impact_records, replay_bag

# Short slots keep the tests quick: 6 s apart, 5 s records.
CAPTURE = CaptureConfig(window_s=5.0)
ANALYSIS = AnalysisConfig(levels=paper_levels())


@pytest.fixture(scope='module')
def session():
    return simulated_session(2, spacing_s=6.0, seed=11)


@pytest.fixture(scope='module')
def session_bag(session, tmp_path_factory):
    return write_session_bag(tmp_path_factory.mktemp('replay') / 'session', session)


def test_replay_finds_what_the_capture_finds_in_the_whole_recording(session, session_bag):
    """Batch by batch from the bag, or the original arrays in one block: the same impacts."""
    direct = capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz, CAPTURE)
    records, problems = bag_impact_records(session_bag, CAPTURE)
    assert problems == []
    assert len(records) == len(direct) == 6
    assert [r.trigger_sample_index for r in records] == [r.trigger_sample_index for r in direct]
    # Each trigger is within a sample of the simulated hit's start.
    assert np.all(
        np.abs(np.array([r.trigger_sample_index for r in records]) - session.hit_start_indices) <= 2
    )
    for ours, theirs in zip(records, direct, strict=True):
        np.testing.assert_array_equal(ours.force_n, theirs.force_n)
        np.testing.assert_array_equal(ours.velocity_m_s, theirs.velocity_m_s)
        assert ours.source == f'session@{ours.trigger_sample_index}'

    replay = replay_bag(session_bag, CAPTURE, ANALYSIS)
    assert replay.problems == [] and replay.batches == 2 * -(-len(session.force_n) // 500)
    assert replay.signal_s == pytest.approx(session.duration_s)
    for result, record in zip(replay.results, direct, strict=True):
        expected = analyze_impact(record, CAPTURE, ANALYSIS, impact_id=result.impact_id)
        assert result.impulse_n_s == expected.impulse_n_s
        assert result.flags == expected.flags
        np.testing.assert_array_equal(result.mobility, expected.mobility)
    levels = {level.level: level.count for level in replay.summary.levels}
    assert sum(levels.values()) == sum(r.accepted for r in replay.summary.impacts)
    assert replay.summary.linearity.r2 > 0.99


def test_a_dropped_batch_flags_the_impact_over_it_and_no_other(session, tmp_path):
    bag = tmp_path / 'dropped'
    hit = int(session.hit_start_indices[2])
    dropped = (hit // 500 + 10) * 500  # one velocity batch, 1 s into the third impact
    with BagWriter(bag, time_origin_ns=0) as writer:
        for start in range(0, len(session.force_n), 500):
            writer.write_sample_batch(
                FORCE_TOPIC,
                session.force_n[start : start + 500],
                quantity=FORCE,
                sample_rate_hz=session.sample_rate_hz,
                first_sample_index=start,
            )
            if start != dropped:
                writer.write_sample_batch(
                    VELOCITY_TOPIC,
                    session.velocity_m_s[start : start + 500],
                    quantity=VELOCITY,
                    sample_rate_hz=session.sample_rate_hz,
                    first_sample_index=start,
                )
    replay = replay_bag(bag, CAPTURE, ANALYSIS)
    flags = [result.flags for result in replay.summary.impacts]
    assert len(flags) == 6
    assert 'gap' in flags[2] and not replay.summary.impacts[2].accepted
    assert all('gap' not in f for k, f in enumerate(flags) if k != 2)


def test_fmm_analyze_takes_bags_and_csv_files_together(session, session_bag, tmp_path, capsys):
    record = capture_impacts(
        session.force_n, session.velocity_m_s, session.sample_rate_hz, CAPTURE
    )[0]
    csv_path = tmp_path / 'one.csv'
    write_impact_csv(csv_path, record.force_n, record.velocity_m_s, record.sample_rate_hz)
    code = main(
        ['analyze', str(session_bag), str(csv_path), '--paper-levels', '--json', '--window-s', '5']
    )
    assert code == 0
    impacts = json.loads(capsys.readouterr().out)['impacts']
    assert len(impacts) == 7
    assert impacts[0]['file'] == f'session@{record.trigger_sample_index}'
    # The CSV copy of the first impact gets the bag's verdict and numbers.
    assert impacts[-1]['impulse_n_s'] == impacts[0]['impulse_n_s']
    assert impacts[-1]['flags'] == impacts[0]['flags']


def test_fmm_replay_prints_what_the_analyzer_would_publish(session_bag, capsys):
    assert main(['replay', str(session_bag), '--paper-levels', '--window-s', '5', '--json']) == 0
    document = json.loads(capsys.readouterr().out)
    assert len(document['impacts']) == 6
    assert document['replay']['signal_s'] == pytest.approx(36.1)
    assert document['replay']['times_real_time'] > 1
    assert main(['replay', str(session_bag), '--paper-levels', '--window-s', '5']) == 0
    out = capsys.readouterr().out
    assert 'linearity:' in out and 'x real time' in out


def test_replay_of_a_crashed_recording_analyses_what_was_flushed(session, tmp_path, capsys):
    bag = tmp_path / 'crashed'
    writer = BagWriter(bag, time_origin_ns=0)
    writer.open()
    half = len(session.force_n) // 2 // 500 * 500
    writer.write_signals(
        session.force_n[:half], session.velocity_m_s[:half], session.sample_rate_hz
    )
    writer.flush()  # then the recorder is killed
    assert main(['replay', str(bag), '--window-s', '5', '--json']) == 1
    out, err = capsys.readouterr()
    assert len(json.loads(out)['impacts']) == 3
    assert 'fmm replay: warning: the recording was not closed' in err
    writer.close()


def _write_batches(bag, session, order, *, origin_ns=1_700_000_000 * 10**9, restart_at=None):
    """A bag of the session's batches in the given order of batch starts (both channels),
    logged in that order (as a recorder logs arrivals).

    restart_at: from that batch on, the acquisition restarts at index 0 with a clock 100 s
    later (a DAQ restarted mid-recording).
    """
    rate = session.sample_rate_hz
    with BagWriter(bag, time_origin_ns=origin_ns) as writer:
        for position, start in enumerate(order):
            index, clock = start, origin_ns
            if restart_at is not None and position >= restart_at:
                index, clock = start - order[restart_at], origin_ns + 100 * 10**9
            writer.time_origin_ns = clock
            for topic, data, quantity in (
                (FORCE_TOPIC, session.force_n, FORCE),
                (VELOCITY_TOPIC, session.velocity_m_s, VELOCITY),
            ):
                writer.write_sample_batch(
                    topic,
                    data[start : start + 500],
                    quantity=quantity,
                    sample_rate_hz=rate,
                    first_sample_index=index,
                    log_time_ns=origin_ns + position * 50_000_000,
                )


def test_a_bag_with_a_repeated_and_a_reordered_batch_is_read_not_refused(session, tmp_path):
    """fmm replay used to stop at 'velocity batch starts at sample ... already holds ...'."""
    starts = list(range(0, len(session.force_n), 500))
    order = starts[:100] + [starts[50]] + starts[100:]  # a duplicate of batch 50
    order[200], order[201] = order[201], order[200]  # two batches swapped
    bag = tmp_path / 'messy'
    _write_batches(bag, session, order)
    replay = replay_bag(bag, CAPTURE, ANALYSIS)
    clean = replay_bag(write_session_bag(tmp_path / 'clean', session), CAPTURE, ANALYSIS)
    assert len(replay.results) == len(clean.results) == 6
    force = replay.ledger['force']
    assert force.faults == {'past': 2, 'gap': 1} and force.refused_batches == 2
    assert force.missing_samples == 500  # the swapped batch came after its successor
    assert any('stream: force' in problem for problem in replay.problems)
    flagged = [k for k, result in enumerate(replay.results) if 'gap' in result.flags]
    assert all(
        result.impulse_n_s == reference.impulse_n_s
        for k, (result, reference) in enumerate(zip(replay.results, clean.results, strict=True))
        if k not in flagged
    )


def test_a_daq_restarted_inside_one_bag_gives_the_records_of_both_acquisitions(session, tmp_path):
    starts = list(range(0, len(session.force_n), 500))
    # The acquisition restarts right after the third hit's record (13 s into a 6 s slot).
    cut = (int(session.hit_start_indices[2]) // 500 + 12) * 500 // 500
    bag = tmp_path / 'restarted'
    _write_batches(bag, session, starts[:cut] + starts[cut:], restart_at=cut)
    records, problems = bag_impact_records(bag, CAPTURE)
    assert len(records) == 6
    firsts = [r.trigger_sample_index for r in records]
    assert firsts[:3] == sorted(firsts[:3]) and firsts[3] < firsts[2]  # index 0 again
    assert any('2 acquisitions' in problem for problem in problems)


def same_to_rounding(ours, theirs) -> None:
    """Every field of two impact analyses equal, floats and arrays to rounding (1e-12)."""
    for field in dataclasses.fields(ours):
        mine, other = getattr(ours, field.name), getattr(theirs, field.name)
        if isinstance(mine, np.ndarray) or isinstance(mine, float):
            np.testing.assert_allclose(mine, other, rtol=1e-12, atol=0.0, err_msg=field.name)
        else:
            assert mine == other, field.name


def test_the_default_replay_gives_the_results_of_every_other_path(session_bag):
    """The default (the bag read whole, records on threads, the numpy scans) against: one
    thread, batch by batch through the stream rules, and each analysis step as the numpy
    definition it replaced (`test/reference_analysis.py`)."""
    from reference_analysis import numpy_steps

    from fmm_ros.io.bags import BagReader
    from fmm_ros.workflows.replay import capture_records

    default = replay_bag(session_bag, CAPTURE, ANALYSIS).summary.impacts
    one_thread = replay_bag(session_bag, CAPTURE, ANALYSIS, threads=1).summary.impacts
    with numpy_steps():
        as_defined = replay_bag(session_bag, CAPTURE, ANALYSIS).summary.impacts
    with BagReader(session_bag, strict=False) as reader:  # on_batch: fed batch by batch
        records = list(capture_records(reader, CAPTURE, on_batch=lambda _: None))
    by_batch = summarize(
        [
            analyze_impact(record, CAPTURE, ANALYSIS, impact_id=result.impact_id)
            for record, result in zip(records, default, strict=True)
        ],
        ANALYSIS,
    ).impacts
    assert len(default) == 6
    for other in (one_thread, as_defined, by_batch):
        for ours, theirs in zip(default, other, strict=True):
            same_to_rounding(ours, theirs)


# What `fmm replay` of a clean bag does not import: numba (its import and cache load), the
# scipy stack, ROS, the plots, the fitting and the model terms, and what only decoding a
# message or writing a bag needs (a typestore's standard types, the mcap writer).
NOT_FOR_REPLAY = (
    'numba',
    'scipy',
    'matplotlib',
    'rclpy',
    'fmm_interfaces',
    'fmm_ros.report',
    'fmm_ros.core.identify.friction',
    'fmm_ros.core.physics.terms',
    'rosbags.typesys.stores.ros2_jazzy',
    'mcap.writer',
)


@pytest.mark.slow  # a fresh interpreter replays a bag (a few seconds)
def test_fmm_replay_imports_only_what_it_runs(session_bag):
    """The default path starts at once: it imports none of `NOT_FOR_REPLAY`."""
    import subprocess
    import sys

    probe = (
        'import sys; from fmm_ros.cli import main; '
        f'status = main(["replay", "--quiet", {str(session_bag)!r}]); '
        "print(' '.join(sorted(sys.modules))); "
        'sys.exit(status)'
    )
    run = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    imported = run.stdout.splitlines()[-1].split()
    assert {'numpy', 'fmm_ros', 'fmm_ros.io.bags.arrays'} <= set(imported)  # read whole
    assert [name for name in NOT_FOR_REPLAY if name in imported] == []
