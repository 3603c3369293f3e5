"""The open-world diagnosis's parts on plain arrays and single records: fast, no full diagnosis.

The screen's least squares against numpy's, the per-hit mu trend test's size and power over
many seeds, the friction map on a Coulomb and a Stribeck contact, the motion stop, the
out-of-vocabulary friction laws of the proof data, and the input checks.
"""

import math

import numpy as np
import pytest

from fmm_ros.core.diagnose import diagnose
from fmm_ros.core.diagnose.drift import MIN_TREND_HITS, mu_trend
from fmm_ros.core.diagnose.friction_map import SPEED_BINS, MapRecord, friction_map, speed_table
from fmm_ros.core.diagnose.gaps import measured_motion_stop
from fmm_ros.core.diagnose.screen import (
    Linearisation,
    Naming,
    chi2_fall,
    screen_term,
    screened_hits,
)
from fmm_ros.core.diagnose.session_model import SessionModel
from fmm_ros.core.diagnose.workflow import (
    DRIFT_P_VALUE,
    _detectable_drift,
    _drift_and_speed_law_aic,
    _floored,
)
from fmm_ros.core.identify.conditioning import as_conditioned, cropped_impact
from fmm_ros.core.identify.friction import fit_model
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG
from fmm_ros.core.physics.terms import model_term
from fmm_ros.sim.excitation import impact_record
from fmm_ros.sim.hidden_effects import RegimeLaw, regime_simulation

RATE_HZ = 10_000.0
F_N = FMM_RIG.natural_frequency_hz


def test_chi2_fall_is_the_least_squares_fall_with_local_parameters_eliminated():
    rng = np.random.default_rng(1)
    sizes = (50, 70, 60)
    residuals = [rng.normal(size=n) for n in sizes]
    shared = [[rng.normal(size=n), rng.normal(size=n)] for n in sizes]
    own = [[rng.normal(size=n)] for n in sizes[:2]] + [[]]
    fall, solution, local = chi2_fall(residuals, shared, own)
    # The same problem as one dense least squares: shared columns stacked, locals block-diagonal.
    rows = sum(sizes)
    design = np.zeros((rows, 2 + 2))
    start = 0
    for k, n in enumerate(sizes):
        design[start : start + n, 0] = shared[k][0]
        design[start : start + n, 1] = shared[k][1]
        if own[k]:
            design[start : start + n, 2 + k] = own[k][0]
        start += n
    design = design[:, :4]
    target = np.concatenate(residuals)
    coefficients, *_ = np.linalg.lstsq(design, target, rcond=None)
    fitted = design @ coefficients
    assert fall == pytest.approx(target @ target - (target - fitted) @ (target - fitted))
    assert solution == pytest.approx(coefficients[:2])
    assert [c[0] for c in local[:2]] == pytest.approx(coefficients[2:4])
    assert local[2].size == 0


def test_screened_hits_spread_over_the_session():
    assert screened_hits(5) == (0, 1, 2, 3, 4)
    hits = screened_hits(30)
    assert len(hits) == 8 and hits[0] == 0 and hits[-1] == 29
    assert np.all(np.diff(hits) >= 3)


def test_a_trend_in_hit_order_is_found_and_its_slope_measured():
    rng = np.random.default_rng(2)
    hits = np.arange(10)
    mu = 0.113 + 2e-4 * hits + rng.normal(0.0, 1e-4, hits.size)
    trend = mu_trend(mu, np.full(hits.size, 1e-4), refitted=True)
    assert trend.slope_per_hit == pytest.approx(2e-4, abs=3 * trend.slope_stderr)
    assert trend.p_value < 1e-6 and trend.consistency_p_value < 1e-6
    assert trend.trend_per_hit[0] == pytest.approx(trend.intercept)


def test_scatter_without_a_trend_rarely_fakes_one_even_with_optimistic_errors():
    # Per-hit mu scattered 3x more than their stated errors (the force noise's impulse error,
    # a contact varying at random): the slope's error grows with the scatter, so a 1e-3 test
    # fires about once in a thousand sessions, never in most of 400.
    rng = np.random.default_rng(3)
    p_values = [
        mu_trend(0.113 + rng.normal(0.0, 3e-4, 8), np.full(8, 1e-4), refitted=False).p_value
        for _ in range(400)
    ]
    assert sum(p < 1e-3 for p in p_values) <= 2
    assert 0.4 < np.mean(np.array(p_values) < 0.5) < 0.6  # about uniform under no trend


def test_a_trend_needs_three_hits_and_finite_errors():
    with pytest.raises(ValueError, match='at least 3 hits, got 2'):
        mu_trend([0.1, 0.11], [1e-3] * 2, refitted=True)
    with pytest.raises(ValueError, match='finite'):
        mu_trend([0.1, 0.11, 0.12, math.nan], [1e-3] * 4, refitted=True)


def map_records(effects=(), count=8, mus=None, levels_n=None):
    """Noisy 5 s records of the rig at random levels: the friction map's input (mu 0.113, or
    one of mus a record; levels_n the hits' peaks)."""
    records = []
    for seed in range(count):
        record = impact_record(
            levels_n[seed] if levels_n else 450.0 + 130.0 * seed,
            seed,
            mu=mus[seed] if mus else 0.113,
            effects=effects,
            duration_s=5.0,
            force_noise_std_n=0.2,
            velocity_noise_std_m_s=1e-4,
        )
        impact = as_conditioned(record)
        records.append(
            MapRecord(impact.force_n, impact.velocity_m_s, 0.0, impact.hit_end_index + 20)
        )
    return records


def test_the_friction_map_of_a_coulomb_contact_is_flat_at_its_mu():
    result = friction_map(map_records(), RATE_HZ, 1e-4, FMM_RIG)
    for curve in (result.speed, result.position):
        assert len(curve.mu) >= 8
        pulls = (np.array(curve.mu) - 0.113) / np.array(curve.mu_stderr)
        assert np.all(np.abs(pulls) < 4.0), pulls  # honest errors: no bin far off
        assert np.all(np.array(curve.mu_stderr) < 0.01)
    assert np.all(np.diff(result.speed.centres) > 0) and np.all(
        np.diff(result.position.centres) > 0
    )


def test_the_friction_map_of_a_stribeck_contact_rises_toward_low_speed():
    stribeck = model_term('stribeck', mu_static_excess=0.05, stribeck_velocity_m_s=3e-3)
    speed = friction_map(map_records((stribeck,)), RATE_HZ, 1e-4, FMM_RIG).speed
    centres, mu = np.array(speed.centres), np.array(speed.mu)
    truth = 0.113 + 0.05 * np.exp(-((centres / 3e-3) ** 2))
    assert mu[0] - mu[-1] > 0.03
    assert np.abs(mu - truth) == pytest.approx(0.0, abs=0.01)


LEVELS_N = (450.0, 1000.0, 1450.0)


def test_the_speed_table_sets_each_records_curve_on_shared_bins():
    records = map_records(count=3, levels_n=LEVELS_N)
    mu, error = speed_table(records, RATE_HZ, 1e-4, FMM_RIG)
    assert mu.shape == error.shape == (3, SPEED_BINS)
    usable = np.isfinite(mu)
    assert np.all(usable.sum(axis=1) >= 4)  # each hit fills bins of its own
    assert np.count_nonzero(usable.all(axis=0)) >= 6  # the speeds every hit passes
    assert np.all(np.abs((mu[usable] - 0.113) / error[usable]) < 4.0)
    top = [int(np.flatnonzero(row)[-1]) for row in usable]
    assert top[0] < top[2]  # the 1450 N hit reaches speeds the 450 N hit never does


def test_a_mu_per_hit_is_told_from_one_curve_of_speed():
    """Three hits, one a level: a drift (one mu a hit, each flat) fits a mu per hit better; a
    Stribeck law (one curve every hit follows) fits the shared curve better. A single hit's map
    bending at low speed (coloured noise in its displacement) cannot tell them apart; the hits'
    bins side by side can."""
    drift = map_records(count=3, mus=(0.10, 0.106, 0.112), levels_n=LEVELS_N)
    per_hit, shared = _drift_and_speed_law_aic(*speed_table(drift, RATE_HZ, 1e-4, FMM_RIG))
    assert per_hit < shared - 20.0
    stribeck = model_term('stribeck', mu_static_excess=0.05, stribeck_velocity_m_s=3e-3)
    law = map_records((stribeck,), count=3, levels_n=LEVELS_N)
    per_hit, shared = _drift_and_speed_law_aic(*speed_table(law, RATE_HZ, 1e-4, FMM_RIG))
    assert shared < per_hit - 20.0


def test_the_motion_stop_follows_the_measured_decay():
    record = impact_record(1000.0, 4, velocity_noise_std_m_s=1e-4, force_noise_std_n=0.2)
    impact = as_conditioned(record)
    stop = measured_motion_stop(impact, F_N)
    rest = record.simulation.rest_time_s * RATE_HZ
    assert rest + RATE_HZ < stop < rest + 2.5 * RATE_HZ
    moving = impact_record(1000.0, 4, duration_s=2.0)  # cut in the middle of its decay
    assert measured_motion_stop(as_conditioned(moving), F_N) == moving.force_n.size
    with pytest.raises(ValueError, match='cannot crop at sample 10'):
        cropped_impact(impact, 10)


def test_a_friction_law_restarted_at_its_regime_changes_matches_plain_runs():
    force = impact_record(1000.0, 5, duration_s=6.0, force_noise_std_n=0.0).force_n
    never = RegimeLaw('speed', 10.0, 1.3)  # faster than the rig ever slides
    plain = simulate(force, RATE_HZ, mu=0.11)
    assert regime_simulation(force, RATE_HZ, never, mu=0.11).velocity_m_s == pytest.approx(
        plain.velocity_m_s, abs=1e-12
    )
    everywhere = RegimeLaw('position', 1.0, 1.3)  # a groove wider than the stroke
    scaled = simulate(force, RATE_HZ, mu=0.11 * 1.3)
    result = regime_simulation(force, RATE_HZ, everywhere, mu=0.11)
    assert result.velocity_m_s == pytest.approx(scaled.velocity_m_s, abs=1e-12)
    assert result.rest_time_s == pytest.approx(scaled.rest_time_s)
    groove = RegimeLaw('position', 2e-3, 0.7)
    inside = regime_simulation(force, RATE_HZ, groove, mu=0.11)
    # Less friction inside the groove: the decay lasts longer than at mu outside throughout.
    assert inside.rest_time_s > plain.rest_time_s
    with pytest.raises(ValueError, match='composes only with'):
        regime_simulation(force, RATE_HZ, groove, mu=0.11, effects=(model_term('sensor_delay'),))


def small_record(duration_s=5.0, seed=1, **changes):
    record = impact_record(
        1000.0, seed, duration_s=duration_s, force_noise_std_n=0.2, velocity_noise_std_m_s=1e-4
    )
    fields = dict(
        force_n=record.force_n,
        velocity_m_s=record.velocity_m_s,
        sample_rate_hz=record.sample_rate_hz,
        source=f'hit{seed}.csv',
    )
    fields.update(changes)
    return type('Record', (), fields)()


def test_bad_input_gets_a_clear_error_naming_the_problem():
    good = small_record()
    velocity = good.velocity_m_s.copy()
    velocity[1234] = math.nan
    with pytest.raises(ValueError, match=r'hit1\.csv.*velocity_m_s.*1234'):
        diagnose([small_record(velocity_m_s=velocity)])
    with pytest.raises(ValueError, match=r'hit1\.csv: the record runs only .* too short to see'):
        diagnose([small_record(duration_s=1.0)])
    with pytest.raises(ValueError, match='mu_drift needs at least 3 impacts .* got 1'):
        diagnose([good], candidates=('mu_drift',))
    with pytest.raises(ValueError, match='different sample rates'):
        slow = small_record(seed=2)
        slow.sample_rate_hz = 5000.0
        diagnose([good, slow])
    with pytest.raises(ValueError, match='no impacts'):
        diagnose([])


def test_a_modes_and_an_offsets_response_need_no_run_of_the_nonlinear_oscillator():
    # The screen takes the second mode's share with the plain linear model (delayed as the
    # model delays it) and the offset as itself: the same, to rounding, as running the
    # whole nonlinear model with the term added.
    record = small_record()
    impact = cropped_impact(as_conditioned(record), 40_000)
    stribeck = model_term('stribeck', mu_static_excess=0.04, stribeck_velocity_m_s=3e-3)
    delay = model_term('sensor_delay', delay_s=2e-4)
    fit = fit_model([impact], fixed_effects=(stribeck, delay))
    linear = Linearisation([impact], SessionModel(('stribeck', 'sensor_delay'), fit), False)
    for term in (
        model_term('second_mode', frequency_hz=40.0, damping_ratio=0.01, modal_mass_kg=1.0),
        model_term('velocity_offset', offset_m_s=1e-4),
    ):
        full = fit.simulate(0).velocity_m_s
        moved = simulate(
            impact.force_n, RATE_HZ, mu=fit.mu, effects=(*fit.effects, term)
        ).velocity_m_s
        assert linear.response(0, term) == pytest.approx(moved - full, abs=1e-12)


def linearised_hit(peak_n: float):
    """(impact, base fit, its linearisation) of one 5 s hit of the given peak force [N]."""
    hit = impact_record(
        peak_n, 1, duration_s=5.0, force_noise_std_n=0.2, velocity_noise_std_m_s=1e-4
    )
    record = small_record(force_n=hit.force_n, velocity_m_s=hit.velocity_m_s)
    impact = cropped_impact(as_conditioned(record), 40_000)
    fit = fit_model([impact])
    return impact, fit, Linearisation([impact], SessionModel((), fit), False)


@pytest.mark.parametrize(
    ('effect', 'size', 'probe'),
    [
        ('velocity_offset', 'offset_m_s', {'offset_m_s': 1e-4}),
        ('sensor_delay', 'delay_s', {'delay_s': 1e-4}),
        (
            'second_mode',
            'modal_mass_kg',
            {'frequency_hz': 40.0, 'damping_ratio': 0.01, 'modal_mass_kg': 1.0},
        ),
    ],
)
def test_a_detection_limit_is_the_size_whose_own_response_reaches_the_naming_floor(
    effect, size, probe
):
    """The size `screen_term` states is where the part of the term's response that mu cannot
    take up removes the squared misfit asked of a named effect; a second mode's is a mass,
    its response falling as 1 / mass. (Over the whole record, where the fall is the Gram
    matrix's: what the nuisance takes is the least-squares fall of the response on it.)"""
    impact, fit, linear = linearised_hit(1000.0)
    naming = Naming((0.5 * fit.noise_std_m_s) ** 2 * impact.force_n.size, [slice(None)])
    term = model_term(effect, **probe)
    limit = screen_term(effect, [term], linear, fit.noise_std_m_s, naming).detection_limit
    assert math.isfinite(limit) and limit > 0.0
    responses = linear.responses(model_term(effect, **{**probe, size: limit}))
    taken = chi2_fall(responses, *linear.nuisance()).chi2
    own = sum(float(r @ r) for r in responses) - taken
    assert own == pytest.approx(naming.m2_s2, rel=0.02)


def test_a_detection_limit_counts_only_what_the_effect_does_inside_the_motion():
    """Naming is judged on the gap over the motion windows: a velocity offset, as large at
    rest as in motion, must account for the misfit asked inside the window alone. Over a
    window where the hit has stopped (mu moves nothing there), all of the offset is its own:
    the limit is sqrt(asked / samples in the window)."""
    impact, fit, linear = linearised_hit(1000.0)
    rest = slice(30_000, 40_000)
    assert not np.any(linear.mu_columns[0][rest])
    asked = (0.5 * fit.noise_std_m_s) ** 2 * 10_000
    term = model_term('velocity_offset', offset_m_s=1e-4)
    limit = screen_term(
        'velocity_offset', [term], linear, fit.noise_std_m_s, Naming(asked, [rest])
    ).detection_limit
    assert limit == pytest.approx(math.sqrt(asked / 10_000), rel=1e-9)
    whole = Naming(asked, [slice(None)])
    assert (
        screen_term('velocity_offset', [term], linear, fit.noise_std_m_s, whole).detection_limit
        < limit
    )


def test_a_probe_whose_model_run_escapes_screens_nothing_and_raises_nothing():
    # A softening probe beyond its turning point (k3 = -1e7 N/m^3: the spring force turns at
    # 14 mm, the 2 kN hit swings 13 mm plus the probe's softening) runs to infinity. Its
    # regression was NaN and the NaN size raised BadInputError out of the whole diagnosis
    # (held-out `analytic`, seed 2020); now it screens nothing and the other probes go on.
    _, fit, linear = linearised_hit(2000.0)
    escaping = model_term('cubic_stiffness', cubic_stiffness_n_per_m3=-1e7)
    assert not np.all(np.isfinite(linear.response(0, escaping)))
    alone = screen_term('cubic_stiffness', [escaping], linear, fit.noise_std_m_s)
    assert alone.chi2_gain == 0.0 and 'not finite' in alone.note
    sane = model_term('cubic_stiffness', cubic_stiffness_n_per_m3=1e5)
    both = screen_term('cubic_stiffness', [escaping, sane], linear, fit.noise_std_m_s)
    assert math.isfinite(both.chi2_gain) and both.start is not None
    assert math.isfinite(both.start.cubic_stiffness_n_per_m3)


@pytest.mark.parametrize('hits', [3, 4, 8])
def test_a_steady_drift_at_its_stated_limit_just_passes_the_hits_own_test(hits):
    """`_detectable_drift` is the change a hit at which the test `_not_a_drift` puts to the
    hits' own mu sits at DRIFT_P_VALUE: with three hits their spread beyond their errors and
    MU_SPREAD_FLOOR of mu (1.3 % a hit, whatever 1e-5 errors), from four the trend."""
    mus, errors = np.full(hits, 0.12), np.full(hits, 1e-5)
    change = _detectable_drift(mus, errors)
    steady = 0.12 * (1.0 + change * np.arange(hits))
    if hits < MIN_TREND_HITS:
        assert change == pytest.approx(0.0133, abs=2e-4)
        p_value = mu_trend(steady, _floored(steady, errors), refitted=False).consistency_p_value
    else:
        assert change < 2e-3
        p_value = mu_trend(steady, errors, refitted=False).p_value
    assert p_value == pytest.approx(DRIFT_P_VALUE, rel=0.05)


def test_a_drift_too_weak_for_any_change_to_show_states_no_finite_limit():
    """Hits whose own mu are known only to 50 % show no drift even if mu grew by all of itself
    a hit: the limit is inf, not an error out of the whole diagnosis; errors that say nothing
    give NaN."""
    assert _detectable_drift(np.full(3, 0.12), np.full(3, 0.06)) == math.inf
    assert math.isnan(_detectable_drift(np.full(3, 0.12), np.array([1e-5, 0.0, 1e-5])))
