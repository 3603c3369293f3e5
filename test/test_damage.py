"""Damaged hits are flagged, left out of every fit by name, and never fitted confidently.

The records come from damaged_records.py (lab-like hits with a fault done to them as the lab
suffers it, built without the flag code); benchmarks/bench_damage.py runs the same matrix
over many more cases.
"""

import json

import numpy as np
import pytest
from damaged_records import FAULTS, RATE_HZ, damaged_hit, quantise, session, worlds_session

from fmm_ros.cli import main
from fmm_ros.core.identify.friction import fit_friction
from fmm_ros.core.signal import quality
from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    analyze_impact,
    select_impacts,
    summarize,
)
from fmm_ros.core.signal.capture import ImpactCapture
from fmm_ros.core.signal.records import ImpactRecord, write_impact_csv
from fmm_ros.errors import SelectionError
from fmm_ros.workflows.session import impact_ids, select_records

# The flag each fault must raise.
EXPECTED_FLAG = {
    'clipped': 'clipped',
    'double_hit': 'double_hit',
    'dead_sensor': 'no_response',
    'disconnected': 'no_response',
    'saturation': 'saturated',
    'nan_burst': 'nan',
    'dropped_stretch': 'dropout',
}
DAMAGE_FLAGS = set(EXPECTED_FLAG.values()) | {'gap'}
# The independent generator drops samples from the stream (the DAQ's counter jumps): a gap.
WORLDS_FLAG = EXPECTED_FLAG | {'dropped_stretch': 'gap'}


@pytest.mark.parametrize('fault', FAULTS)
def test_every_fault_raises_its_flag(fault):
    for seed in range(6):
        hit = damaged_hit(seed % 3, fault, np.random.default_rng(seed), mu=0.113)
        flags = analyze_impact(hit.record).flags
        assert EXPECTED_FLAG[fault] in flags, (hit.detail, flags)


@pytest.mark.parametrize('fault', FAULTS)
def test_every_fault_of_the_independent_generator_is_flagged_and_left_out(fault):
    hits, mu = worlds_session(fault, seed=31, damaged=(0, 2))
    flags = [analyze_impact(hit.record).flags for hit in hits]
    assert WORLDS_FLAG[fault] in flags[0] and WORLDS_FLAG[fault] in flags[2], flags
    assert not set(flags[1]) & DAMAGE_FLAGS
    records = [hit.record for hit in hits]
    selection = select_records(records)
    assert selection.chosen == (impact_ids(records)[1],)
    assert fit_friction([hits[1].record]).mu == pytest.approx(mu, rel=0.02)


@pytest.mark.slow
def test_clean_records_of_the_independent_generator_raise_no_flag():
    flagged = []
    for seed in range(8):
        hits, _ = worlds_session('', seed=600 + seed, damaged=())
        flagged += [(seed, analyze_impact(hit.record).flags) for hit in hits]
    assert [entry for entry in flagged if entry[1]] == []


def test_clean_lab_records_raise_no_damage_flag():
    # Noise, 16-bit quantisation, hum and offsets drawn per record: nothing damaged.
    flagged = []
    for seed in range(45):
        hit = damaged_hit(seed % 3, '', np.random.default_rng(500 + seed), mu=0.113)
        flags = set(analyze_impact(hit.record).flags)
        if flags & DAMAGE_FLAGS:
            flagged.append((seed, flags))
    assert flagged == []


@pytest.mark.parametrize('fault', FAULTS)
def test_a_damaged_hit_is_left_out_by_name_and_mu_comes_from_the_clean_ones(fault):
    hits, mu = session(fault, seed=77, damaged=(1,))
    records = [hit.record for hit in hits]
    selection = select_records(records)
    ids = impact_ids(records)
    chosen = [records[ids.index(i)] for i in selection.chosen]
    assert selection.chosen == (ids[0], ids[2])
    ((impact_id, flags, source),) = selection.excluded
    assert (impact_id, source) == (ids[1], hits[1].record.source)
    assert EXPECTED_FLAG[fault] in flags
    assert f'impact {ids[1]} ({source}: ' in selection.note
    assert fit_friction(chosen).mu == pytest.approx(mu, rel=0.02)


@pytest.mark.parametrize('fault', FAULTS)
def test_a_session_of_damaged_hits_is_refused_with_the_reason(fault):
    hits, _ = session(fault, seed=78)
    records = [hit.record for hit in hits]
    ids = impact_ids(records)
    with pytest.raises(
        SelectionError, match=f'no clean impact to fit: impact {ids[0]} '
    ) as refused:
        select_records(records)
    assert [entry[0] for entry in refused.value.selection.excluded] == ids


def write_csv(path, record):
    write_impact_csv(path, record.force_n, record.velocity_m_s, record.sample_rate_hz)
    return str(path)


def run(capsys, *args):
    code = main([str(arg) for arg in args])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.slow
def test_fmm_fit_leaves_a_clipped_csv_out_and_refuses_when_all_are_clipped(tmp_path, capsys):
    # The case: forces clipped flat at 60 % of their peak, full scale unknown.
    hits, mu = session('clipped', seed=5, damaged=(1,))
    files = [write_csv(tmp_path / f'hit{i}.csv', hit.record) for i, hit in enumerate(hits)]
    code, out, _ = run(capsys, 'fit', *files, '--json')
    result = json.loads(out)
    assert code == 0 and result['mu'] == pytest.approx(mu, rel=0.02)
    assert [entry['file'] for entry in result['left_out']] == [files[1]]
    assert result['left_out'][0]['flags'] == ['clipped']
    assert [entry['file'] for entry in result['per_file']] == [files[0], files[2]]
    clipped_id = result['left_out'][0]['impact_id']
    code, out, _ = run(capsys, 'fit', *files)
    assert code == 0 and f'left out 1 flagged impact(s): impact {clipped_id} (' in out
    # Taken on request, with a warning in the output.
    code, out, _ = run(capsys, 'fit', *files, '--include-flagged')
    assert code == 0 and 'WARNING: 1 flagged impact(s) included on request' in out

    hits, _ = session('clipped', seed=6)
    files = [write_csv(tmp_path / f'all{i}.csv', hit.record) for i, hit in enumerate(hits)]
    code, out, err = run(capsys, 'fit', *files, '--json')
    refusal = json.loads(out)
    assert code == 1 and err == ''
    assert refusal['error'] == 'no_clean_impact'
    first_id = refusal['left_out'][0]['impact_id']
    assert refusal['message'].startswith(f'no clean impact to fit: impact {first_id} (')
    assert [entry['flags'] for entry in refusal['left_out']] == [['clipped']] * 3
    code, out, err = run(capsys, 'diagnose', *files)
    assert code == 1 and err.startswith('fmm diagnose: cannot fit (no_clean_impact): ')


@pytest.mark.slow
def test_import_of_several_files_keeps_each_an_acquisition_without_nan(tmp_path, capsys):
    # Three files of 6 s: each hit's 33 s window runs past its file's end. Joined on one
    # index without boundaries, records ran into the next file and the last one was padded
    # with NaN (fmm fit refused the session).
    hits, mu = session('', seed=9, damaged=())
    files = [write_csv(tmp_path / f'hit{i}.csv', hit.record) for i, hit in enumerate(hits)]
    bag = tmp_path / 'session'
    code, _, err = run(
        capsys,
        'import',
        *files,
        '-o',
        bag,
        '--force',
        'force_n',
        '--force-unit',
        'N',
        '--velocity',
        'velocity_m_s',
        '--velocity-unit',
        'm/s',
        '--time',
        'time_s',
        '--time-unit',
        's',
        '-q',
    )
    assert code == 0, err
    from fmm_ros.workflows.replay import bag_impact_records

    records, problems = bag_impact_records(bag)
    assert problems == [] and len(records) == 3
    length = hits[0].record.force_n.size
    for number, record in enumerate(records):
        assert np.isfinite(record.force_n).all() and np.isfinite(record.velocity_m_s).all()
        assert record.force_gaps == () and record.velocity_gaps == ()
        # The record ends with its own file: it never reaches the next file's samples.
        assert record.record_start_sample_index + record.force_n.size == (number + 1) * length
        assert analyze_impact(record).flags == ()
    code, out, _ = run(capsys, 'fit', bag, '--json')
    assert code == 0 and json.loads(out)['mu'] == pytest.approx(mu, rel=0.02)
    assert json.loads(out)['left_out'] == []


def test_end_acquisition_ends_open_records_where_the_samples_end():
    hit = damaged_hit(1, '', np.random.default_rng(3), mu=0.113)
    force, velocity = hit.record.force_n, hit.record.velocity_m_s
    capture = ImpactCapture()
    assert capture.feed_both(0, force, velocity, RATE_HZ) == []  # the 33 s window is open
    (record,) = capture.end_acquisition()
    assert record.force_n.size == force.size - record.record_start_sample_index
    assert record.force_gaps == () and np.isfinite(record.velocity_m_s).all()
    assert record.window_samples == round(33.0 * RATE_HZ)
    # The next acquisition may start again at index 0, and is captured on its own.
    capture.feed_both(0, force, velocity, RATE_HZ)
    (again,) = capture.end_acquisition()
    np.testing.assert_array_equal(again.velocity_m_s, record.velocity_m_s)
    capture.recycle(record)


def noisy(n, rng, sigma):
    return rng.normal(0.0, sigma, n)


def test_flat_top_tells_a_rail_from_a_smooth_peak():
    rng = np.random.default_rng(4)
    t = np.arange(20_000) / RATE_HZ
    peak = np.sin(2 * np.pi * 2.0 * t)  # a slow peak: many samples near the top
    assert quality.flat_extreme(peak) is None
    # Quantised to a coarse step without noise, the top holds one code for ~30 samples:
    # still smooth.
    coarse = quantise(0.1 * peak, 0.5 * 2**6)
    assert np.max(np.bincount(np.unique(coarse, return_inverse=True)[1])) > 20
    assert quality.flat_extreme(coarse) is None and quality.flat_extreme(coarse, -1) is None
    # A rail at 95 % of the peak, exact or with noise added after it, is a plateau.
    assert quality.flat_extreme(np.minimum(peak, 0.95)) == pytest.approx(0.95)
    railed = np.minimum(peak, 0.95) + noisy(t.size, rng, 1e-3)
    assert quality.flat_extreme(railed) is not None
    assert quality.flat_extreme(peak + noisy(t.size, rng, 1e-3)) is None


def test_stuck_stretch_needs_noise_to_be_judged():
    rng = np.random.default_rng(5)
    signal = noisy(50_000, rng, 1e-4)
    assert not quality.stuck_stretch(signal)
    held = signal.copy()
    held[20_000:20_030] = held[19_999]
    assert quality.stuck_stretch(held)
    # A noise-free record that comes to rest (friction: a steady deceleration to 0) is
    # constant for real; the same record zeroed while it moves is not.
    motion = np.concatenate((np.linspace(0.1, 0.0, 5000), np.zeros(45_000)))
    assert not quality.has_white_noise(motion) and not quality.stuck_stretch(motion)
    zeroed = motion.copy()
    zeroed[1000:1100] = 0.0
    assert quality.stuck_stretch(zeroed)


def test_response_is_judged_against_hum_and_noise_before_the_hit():
    rng = np.random.default_rng(6)
    t = np.arange(10_000) / RATE_HZ
    hum = 1e-3 * np.sin(2 * np.pi * 50 * t)
    assert not quality.responds(hum + noisy(t.size, rng, 1e-4), 1000, 1030, 5000)
    assert not quality.responds(np.zeros(t.size), 1000, 1030, 5000)
    response = np.where(t > 0.103, 0.05 * np.cos(2 * np.pi * 2.2 * (t - 0.103)), 0.0)
    assert quality.responds(response + hum + noisy(t.size, rng, 1e-4), 1000, 1030, 5000)


class Held:
    """What the fitter node holds of an impact: id, verdict and flags, no source."""

    def __init__(self, impact_id, accepted, flags):
        self.impact_id, self.accepted, self.flags = impact_id, accepted, flags


def test_select_impacts_is_one_rule_for_summaries_and_held_impacts():
    hits, _ = session('double_hit', seed=8, damaged=(2,))
    results = [analyze_impact(hit.record, impact_id=i) for i, hit in enumerate(hits)]
    summary = summarize(results)
    selection = select_impacts(summary)
    assert selection.chosen == (0, 1) and [e[0] for e in selection.excluded] == [2]
    everything = select_impacts(summary, include_flagged=True)
    assert everything.chosen == (0, 1, 2) and everything.excluded == ()
    assert 'WARNING: 1 flagged impact(s) included on request: impact 2 (' in everything.note
    with pytest.raises(SelectionError, match=r'2 clean impact\(s\) of 3, 3 needed'):
        select_impacts(summary, min_clean=3)
    # Which flags reject is the analysis' choice: with none rejecting, nothing is left out.
    lenient = summarize(results, AnalysisConfig(reject_flags=()))
    assert select_impacts(lenient).chosen == (0, 1, 2)
    held = [Held(4, True, ()), Held(7, False, ('no_response',))]
    assert select_impacts(held).note == (
        'left out 1 flagged impact(s): impact 7 (no_response) (--include-flagged takes them)'
    )
    with pytest.raises(SelectionError, match='no impact to fit'):
        select_impacts([])


def test_a_nan_burst_in_a_record_is_flagged_not_a_crash():
    hit = damaged_hit(0, '', np.random.default_rng(2), mu=0.113)
    force = hit.record.force_n.copy()
    force[1500:1510] = np.inf
    record = ImpactRecord(force, hit.record.velocity_m_s, RATE_HZ)
    with np.errstate(all='raise'):  # no warning either: a corrupt stretch is data, not a bug
        flags = analyze_impact(record).flags
    assert 'nan' in flags


@pytest.mark.ros
def test_the_fitter_service_leaves_flagged_impacts_out_unless_asked(ros_graph):
    from rclpy.node import Node

    from fmm_interfaces.srv import FitFriction
    from fmm_ros.constants import FIT_SERVICE
    from fmm_ros.ros.nodes.fitter import Fitter, HeldImpact

    hits, mu = session('dead_sensor', seed=41, damaged=(2,))
    fitter = ros_graph.add(Fitter, parameter_overrides=[])
    client = ros_graph.add(Node, node_name='caller').create_client(FitFriction, FIT_SERVICE)
    ros_graph.start()
    for number, hit in enumerate(hits):  # as if the analyzer had reported them
        flags = analyze_impact(hit.record).flags
        fitter.impacts[number] = HeldImpact(number, '', not flags, flags, hit.record)
    response = ros_graph.call(client, FitFriction.Request(), timeout_s=120.0)
    assert response.success, response.message
    assert list(response.impact_ids) == [0, 1]
    assert response.mu == pytest.approx(mu, rel=0.02)
    assert 'left out 1 flagged impact(s): impact 2 (no_response)' in response.message
    response = ros_graph.call(client, FitFriction.Request(include_flagged=True), timeout_s=120.0)
    assert not response.success  # the dead vibrometer's record shows no motion to fit
    only_flagged = FitFriction.Request(impact_ids=[2])
    response = ros_graph.call(client, only_flagged, timeout_s=120.0)
    assert not response.success
    assert response.message.startswith('no clean impact to fit: impact 2 (no_response)')


@pytest.mark.parametrize('size', [0, 1, 2, 3, 9, 40_001, 40_002, 40_003, 40_010, 330_000])
def test_noise_measures_read_the_differences_numpy_would_give(size):
    """white_noise_std and has_white_noise compute only the differences they read (every 8th
    of a long channel): the same numbers as np.diff's, corrupt samples and all."""
    rng = np.random.default_rng(size)
    samples = rng.normal(0.0, 0.2, size).round(3)  # quantised: some differences exactly 0
    samples[rng.integers(0, max(size, 1), size // 50)] = np.nan
    samples[rng.integers(0, max(size, 1), size // 50)] = np.inf

    def spread(values):
        return quality.robust_center_and_std(values)[1]

    with np.errstate(invalid='ignore'):
        first, second = np.diff(samples), np.diff(samples, n=2)
    expected_noise = spread(second) / np.sqrt(6.0) if second.size else 0.0
    np.testing.assert_equal(quality.white_noise_std(samples), expected_noise)
    assert quality.has_white_noise(samples) == bool(
        spread(first) > 0 and spread(second) >= spread(first)
    )
