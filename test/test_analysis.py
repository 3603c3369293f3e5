"""Per-impact analysis and level summaries: flags, verdicts, numbers, levels, averaging."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from signal_records import analytic_mobility, damping_for_ratio, half_sine, hits, linear_velocity

from fmm_ros.core.signal.analysis import (
    AnalysisConfig,
    ImpactAnalysis,
    LevelSummary,
    analyze_impact,
    paper_levels,
    summarize,
)
from fmm_ros.core.signal.capture import FLAGS, CaptureConfig, ImpactCapture, capture_impacts

RATE_HZ = 10_000.0
CAPTURE = CaptureConfig()  # the paper's 33 s window, 10 ms pre-trigger


def captured(hits_at, seconds=36.0, zeta=0.05, noise=True, **capture_kwargs):
    """Records captured from a stream with the given (time_s, peak_n) hits."""
    n = int(seconds * RATE_HZ)
    force, velocity = hits(n, RATE_HZ, [(int(t * RATE_HZ), p) for t, p in hits_at], zeta=zeta)
    if noise:
        rng = np.random.default_rng(11)
        force = force + rng.normal(0, 0.3, n)
        velocity = velocity + rng.normal(0, 1e-6, n)
    return force, velocity, capture_impacts(force, velocity, RATE_HZ, CAPTURE, **capture_kwargs)


def flags_of(records):
    return [analyze_impact(record, CAPTURE).flags for record in records]


def test_clean_records_raise_no_flag_and_land_in_their_levels():
    _, _, records = captured([(1.0, 450.0), (35.0, 1000.0), (69.0, 1450.0)], seconds=103.0)
    results = [analyze_impact(r, CAPTURE, impact_id=i) for i, r in enumerate(records)]
    assert [r.flags for r in results] == [(), (), ()]
    summary = summarize(results, AnalysisConfig(levels=paper_levels()))
    assert [(r.level, r.accepted, r.flags) for r in summary.impacts] == [
        ('low', True, ()),
        ('medium', True, ()),
        ('high', True, ()),
    ]
    rest = dataclasses.replace(CAPTURE, end_at_rest=True)
    assert [
        analyze_impact(r, rest).flags
        for r in capture_impacts(*captured([(1.0, 1000.0)])[:2], RATE_HZ, rest)
    ] == [()]


def test_double_hit():
    _, _, records = captured([(1.0, 450.0), (1.02, 100.0)])
    assert flags_of(records) == [('double_hit',)]


def test_clipped_force_and_saturated_velocity_at_the_sensor_range():
    force, velocity, _ = captured([(1.0, 450.0)])
    clipped = capture_impacts(
        np.minimum(force, 400.0), velocity, RATE_HZ, CAPTURE, force_full_scale_n=400.0
    )
    assert flags_of(clipped) == [('clipped',)]
    peak_velocity = np.max(np.abs(velocity))
    saturated = capture_impacts(
        force,
        np.clip(velocity, -0.9 * peak_velocity, 0.9 * peak_velocity),
        RATE_HZ,
        CAPTURE,
        velocity_full_scale_m_s=0.9 * peak_velocity,
    )
    assert flags_of(saturated) == [('saturated',)]
    # A known range the signal stays inside raises nothing.
    assert flags_of(
        capture_impacts(
            force,
            velocity,
            RATE_HZ,
            CAPTURE,
            force_full_scale_n=500.0,
            velocity_full_scale_m_s=2 * peak_velocity,
        )
    ) == [()]


def test_gap_from_a_missing_batch():
    force, velocity, _ = captured([(1.0, 450.0)])
    capture = ImpactCapture(CAPTURE)
    records = []
    for first in range(0, force.size, 500):
        records += capture.feed('force', first, force[first : first + 500], RATE_HZ)
        if first != 50_000:  # 5.0 .. 5.05 s of velocity lost
            records += capture.feed('velocity', first, velocity[first : first + 500], RATE_HZ)
    assert flags_of(records + capture.flush()) == [('gap',)]


def test_nan_in_received_samples():
    force, velocity, _ = captured([(1.0, 450.0)])
    velocity[60_000] = np.nan
    assert flags_of(capture_impacts(force, velocity, RATE_HZ, CAPTURE)) == [('nan',)]
    force[70_000] = np.inf
    velocity[60_000] = 0.0
    assert flags_of(capture_impacts(force, velocity, RATE_HZ, CAPTURE)) == [('nan',)]


def test_unsettled_at_the_end_or_moving_before_the_hit():
    # The bare flexure (zeta 0.1 %) still rings after 33 s.
    _, _, ringing = captured([(1.0, 450.0)], zeta=0.001)
    assert flags_of(ringing) == [('unsettled',)]
    # A push below the trigger level sets the rig moving before the hit.
    n = int(36 * RATE_HZ)
    force = half_sine(n, RATE_HZ, 5000, 15.0, 0.05) + half_sine(n, RATE_HZ, 10_000, 450.0, 0.004)
    velocity = linear_velocity(force, RATE_HZ, damping_for_ratio(0.05))
    assert flags_of(capture_impacts(force, velocity, RATE_HZ, CAPTURE)) == [('unsettled',)]


def test_overlap_when_the_next_hit_falls_inside_the_window():
    _, _, records = captured([(1.0, 450.0), (21.0, 1000.0)], seconds=56.0)
    assert flags_of(records) == [('overlap',), ()]


def test_out_of_tolerance_and_configurable_rejection():
    _, _, records = captured([(1.0, 700.0)])
    (result,) = [analyze_impact(r, CAPTURE) for r in records]
    summary = summarize([result], AnalysisConfig(levels=paper_levels()))
    (judged,) = summary.impacts
    assert (judged.level, judged.flags, judged.accepted) == ('', ('out_of_tolerance',), False)
    assert summary.levels == ()
    lenient = summarize([result], AnalysisConfig(levels=paper_levels(), reject_flags=('gap',)))
    assert lenient.impacts[0].accepted and lenient.impacts[0].flags == ('out_of_tolerance',)
    with pytest.raises(ValueError, match='unknown quality flag'):
        AnalysisConfig(reject_flags=('wobbly',))


def test_impact_numbers_and_frf_of_a_linear_oscillator():
    zeta = 0.05
    _, _, records = captured([(1.0, 1000.0)], noise=False, zeta=zeta)
    result = analyze_impact(records[0], CAPTURE, impact_id=7)
    assert result.impact_id == 7 and result.accepted
    assert result.trigger_sample_index - result.record_start_sample_index == 100
    assert result.impulse_n_s == pytest.approx(1000.0 * 0.004 * 2 / np.pi, rel=1e-3)
    assert result.peak_force_n == pytest.approx(1000.0, rel=1e-3)
    assert result.contact_duration_s == pytest.approx(0.004, rel=0.01)
    assert result.record_duration_s == pytest.approx(33.0)
    assert result.frequency_step_hz == pytest.approx(1 / 33.0)
    assert result.frequency_hz[-1] == pytest.approx(100.0) and result.frequency_hz[0] == 0
    assert result.natural_frequency_hz == pytest.approx(2.20, abs=0.02)
    damping = damping_for_ratio(zeta)
    exact = analytic_mobility(result.frequency_hz[1:], damping)
    np.testing.assert_allclose(result.mobility[1:], exact, rtol=1e-3)
    np.testing.assert_allclose(
        result.receptance[1:] * 2j * np.pi * result.frequency_hz[1:], exact, rtol=1e-3
    )
    np.testing.assert_allclose(
        result.accelerance[1:], 2j * np.pi * result.frequency_hz[1:] * exact, rtol=1e-3
    )
    assert result.receptance[0] == 0
    exact_receptance = np.abs(exact / (2j * np.pi * result.frequency_hz[1:]))
    assert result.peak_receptance_m_per_n == pytest.approx(
        np.max(exact_receptance[result.frequency_hz[1:] >= 1]), rel=1e-3
    )


def test_force_window_removes_the_offset_and_noise_after_the_pulse():
    force, velocity, _ = captured([(1.0, 1000.0)], noise=False)
    clean_impulse = 1000.0 * 0.004 * 2 / np.pi
    rng = np.random.default_rng(2)
    dirty = force + 2.0 + rng.normal(0, 1.0, force.size)  # 2 N offset, 1 N noise
    (record,) = capture_impacts(dirty, velocity, RATE_HZ, CAPTURE)
    raw = analyze_impact(record, CAPTURE)
    # The impulse is the pulse's area above the pre-hit baseline, not the record's: the
    # offset (66 N*s over 33 s) and the noise elsewhere stay out of it, window or not.
    assert raw.impulse_n_s == pytest.approx(clean_impulse, rel=0.01)
    windowed = analyze_impact(
        record, CAPTURE, AnalysisConfig(force_window_s=0.02, force_window_taper_s=0.005)
    )
    assert windowed.impulse_n_s == pytest.approx(clean_impulse, rel=0.01)
    assert windowed.force_window_s == 0.02
    assert windowed.peak_receptance_m_per_n == pytest.approx(
        analyze_impact(
            capture_impacts(force, velocity, RATE_HZ, CAPTURE)[0], CAPTURE
        ).peak_receptance_m_per_n,
        rel=0.01,
    )


def test_exponential_window_is_recorded_and_removes_leakage_flagged_as_unsettled():
    _, _, records = captured([(1.0, 1000.0)], zeta=0.001, noise=False)
    windowed = analyze_impact(records[0], CAPTURE, AnalysisConfig(exponential_decay_s=4.0))
    assert windowed.exponential_window_decay_s == 4.0
    assert windowed.flags == ('unsettled',)  # the record itself still did not settle
    near = (windowed.frequency_hz > 1.8) & (windowed.frequency_hz < 2.6)
    exact = analytic_mobility(
        windowed.frequency_hz[near], damping_for_ratio(0.001), extra_decay_per_s=1 / 4.0
    )
    np.testing.assert_allclose(windowed.mobility[near], exact, rtol=0.01)


def test_summary_clusters_levels_averages_and_fits():
    peaks = [450, 470, 1000, 980, 1450, 1430]
    _, _, records = captured(
        [(1 + 34 * i, p) for i, p in enumerate(peaks)], seconds=210.0, noise=False
    )
    results = [analyze_impact(r, CAPTURE, impact_id=i) for i, r in enumerate(records)]
    summary = summarize(results)
    assert [r.level for r in summary.impacts] == [
        'level_1',
        'level_1',
        'level_2',
        'level_2',
        'level_3',
        'level_3',
    ]
    assert [
        (lv.level, lv.count, lv.impact_ids, lv.nominal_peak_force_n) for lv in summary.levels
    ] == [('level_1', 2, (0, 1), 0.0), ('level_2', 2, (2, 3), 0.0), ('level_3', 2, (4, 5), 0.0)]
    low = summary.levels[0]
    impulses = [results[0].impulse_n_s, results[1].impulse_n_s]
    assert low.mean_impulse_n_s == pytest.approx(np.mean(impulses))
    assert low.std_impulse_n_s == pytest.approx(np.std(impulses, ddof=1))
    assert low.mean_peak_force_n == pytest.approx(460, rel=1e-2)
    np.testing.assert_allclose(low.mobility, (results[0].mobility + results[1].mobility) / 2)
    near = (low.frequency_hz > 1.8) & (low.frequency_hz < 2.6)
    np.testing.assert_allclose(
        low.h1_mobility[near],
        analytic_mobility(low.frequency_hz[near], damping_for_ratio(0.05)),
        rtol=0.01,
    )
    assert np.all(low.coherence[near] > 0.999)
    # Linear structure: the peak receptance does not grow with impulse (slope ~ 0).
    assert summary.linearity.count == 3
    assert abs(summary.linearity.slope) * 2 < 0.01 * summary.linearity.intercept


def test_rejected_impacts_stay_reported_but_out_of_the_average():
    _, _, records = captured([(1.0, 1000.0), (35.0, 1010.0)], seconds=70.0)
    results = [analyze_impact(r, CAPTURE, impact_id=i) for i, r in enumerate(records)]
    results[1] = dataclasses.replace(results[1], flags=('clipped',))
    summary = summarize(results)
    assert [r.accepted for r in summary.impacts] == [True, False]
    assert summary.levels[0].count == 1 and summary.levels[0].impact_ids == (0,)
    assert np.isnan(summary.levels[0].std_impulse_n_s)
    assert np.isnan(summary.linearity.slope)


def test_levels_need_one_frequency_grid():
    _, _, records = captured([(1.0, 1000.0)])
    a = analyze_impact(records[0], CAPTURE, impact_id=0)
    shorter = dataclasses.replace(
        records[0],
        force_n=records[0].force_n[:200_000],
        velocity_m_s=records[0].velocity_m_s[:200_000],
        window_samples=200_000,
    )
    b = analyze_impact(shorter, CAPTURE, impact_id=1)
    with pytest.raises(ValueError, match='different frequency grids'):
        summarize([a, b])


def message_fields(name):
    """(type, field) pairs of an fmm_interfaces message definition."""
    text = (Path(__file__).parents[1] / 'fmm_interfaces' / 'msg' / f'{name}.msg').read_text()
    return [
        tuple(line.split()[:2])
        for line in text.splitlines()
        if line.strip() and not line.startswith('#')
    ]


def test_flag_names_match_the_message_definition():
    text = (Path(__file__).parents[1] / 'fmm_interfaces/msg/ImpactResult.msg').read_text()
    listed = text[text.index('# Quality flags:') :].split(':', 1)[1].split('.', 1)[0]
    names = listed.replace('#', ' ').split(',')
    assert [name.strip() for name in names] == list(FLAGS)


@pytest.mark.parametrize(
    'message, dataclass', [('ImpactResult', ImpactAnalysis), ('FrfSummary', LevelSummary)]
)
def test_every_message_field_has_its_dataclass_field(message, dataclass):
    # The ROS shell converts field by field: complex arrays split into _real/_imag, and the
    # linearity fit (one per session) is copied into every FrfSummary.
    names = {field.name for field in dataclasses.fields(dataclass)}
    linearity = {
        f'linearity_{name}' for name in ('slope_m_per_n2_s', 'intercept_m_per_n', 'r2', 'levels')
    }
    for kind, name in message_fields(message):
        if kind == 'std_msgs/Header' or name in linearity:
            continue
        base = name.removesuffix('_real').removesuffix('_imag')
        assert base in names, f'{message}.{name} has no {dataclass.__name__} field'
