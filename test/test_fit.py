"""The fitting core: mu (and c, and model terms) from lab-like records; rig identification."""

import dataclasses
import math
import threading

import numpy as np
import pytest
from fit_records import FORCE_NOISE_N, VELOCITY_NOISE_M_S, lab_impact, lab_levels

from fmm_ros.core import identify as fit
from fmm_ros.core.identify import output_error
from fmm_ros.core.identify.lsq import levenberg_marquardt, normal_inverse
from fmm_ros.core.physics.model import free_vibration, simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import model_term
from fmm_ros.core.signal.capture import capture_impacts
from fmm_ros.errors import BadInputError, FitError, Infeasible
from fmm_ros.sim.session import simulated_session

SCALES = tuple(f'impulse_scale[{i}]' for i in range(3))
"""fit_friction fits each hit's impulse scale."""


@pytest.fixture(scope='module')
def paper_set():
    """Three levels at the paper's mu = 0.113, conditioned once."""
    return [fit.as_conditioned(record) for record in lab_levels(11, mu=0.113)]


# --- mu and c ---------------------------------------------------------------------------------


@pytest.mark.parametrize('mu, seed', [(0.05, 1), (0.113, 2), (0.2, 3)])
def test_one_mu_over_three_levels_within_one_percent(mu, seed):
    result = fit.fit_friction(lab_levels(seed, mu=mu))
    assert result.mu == pytest.approx(mu, rel=0.01)
    # The error is honest too: far inside 1 %, and within a few standard errors.
    assert abs(result.mu - mu) < 4.0 * result.mu_stderr
    assert result.mu_stderr < 1e-3 * mu
    for single in result.per_impact:
        assert single.mu == pytest.approx(mu, rel=0.01)
    assert result.consistency_p_value > 1e-3
    assert math.isnan(result.damping_stderr_n_s_per_m)
    assert result.damping_n_s_per_m == FMM_RIG.damping_n_s_per_m


@pytest.mark.parametrize('mu, damping, seed', [(0.08, 0.275, 4), (0.15, 1.5, 5)])
def test_mu_and_damping_fitted_together(mu, damping, seed):
    rig = dataclasses.replace(FMM_RIG, damping_n_s_per_m=damping)
    result = fit.fit_friction(lab_levels(seed, mu=mu, rig=rig), fit_damping=True)
    assert result.mu == pytest.approx(mu, rel=0.01)
    assert result.damping_n_s_per_m == pytest.approx(damping, rel=0.10)
    assert abs(result.damping_n_s_per_m - damping) < 4.0 * result.damping_stderr_n_s_per_m
    assert result.joint.names == ('mu', 'damping_n_s_per_m', *SCALES)
    # Each impact's own mu is fitted with c held at the joint value.
    assert all(single.names == ('mu', 'impulse_scale[0]') for single in result.per_impact)
    assert all(
        single.rig.damping_n_s_per_m == result.damping_n_s_per_m for single in result.per_impact
    )


def test_frf_misfit_agrees_with_time_misfit(paper_set):
    time = fit.fit_model(paper_set)
    frf = fit.fit_model(paper_set, misfit='frf')
    assert frf.misfit == 'frf'
    assert frf.mu == pytest.approx(0.113, rel=0.01)
    assert frf.mu == pytest.approx(time.mu, abs=3 * math.hypot(frf.mu_stderr, time.mu_stderr))
    # Whatever the misfit, the residuals reported are velocities over every sample.
    assert [r.size for r in frf.residuals_m_s] == [i.force_n.size for i in paper_set]
    assert frf.residual_rms_m_s == pytest.approx(VELOCITY_NOISE_M_S, rel=0.05)


def test_euler_integrator_fits_too(paper_set):
    # The paper's integrator lands the hit half a step late: mu moves, but not by 1 %.
    euler = fit.fit_model(paper_set[:1], integrator='euler')
    assert euler.mu == pytest.approx(0.113, rel=0.01)


@pytest.mark.parametrize('scale', [False, True], ids=['measured_impulse', 'impulse_scale'])
def test_standard_error_matches_the_scatter_over_noise_seeds(scale):
    hit = lab_impact(
        1000.0, 7, mu=0.1, force_noise_std_n=0.0, velocity_noise_std_m_s=0.0, duration_s=8.0
    )  # the rig is at rest after 4 s
    errors, stderrs = [], []
    rng = np.random.default_rng(8)
    for _ in range(12):
        force = hit.force_n + rng.normal(0.0, FORCE_NOISE_N, hit.force_n.size)
        velocity = hit.velocity_m_s + rng.normal(0.0, VELOCITY_NOISE_M_S, hit.force_n.size)
        impact = fit.condition_impact(force, velocity, hit.sample_rate_hz)
        result = fit.fit_model(impact, fit_impulse_scale=scale)
        errors.append(result.mu - 0.1)
        stderrs.append(result.mu_stderr)
        if scale:  # the decay alone fixes mu: the force's noise moves only the scale
            assert result.stderr_force[0] == 0.0
            assert result.value('impulse_scale[0]') == pytest.approx(1.0, abs=1e-3)
        else:  # at 0.2 N the hit's impulse noise, not the velocity noise, limits mu
            assert result.stderr_force[0] > 3.0 * result.stderr_white[0]
    ratio = np.sqrt(np.mean(np.square(errors))) / np.mean(stderrs)
    assert 0.5 < ratio < 1.5
    if scale:  # several times better than taking the measured impulse as exact
        assert np.mean(stderrs) < 3e-5 * 0.1


def test_model_fit_reports_residuals_noise_and_names(paper_set):
    result = fit.fit_model(paper_set)
    assert result.names == ('mu',) and result.units == ('1',)
    assert result.value('mu') == result.mu and result.error('mu') == result.mu_stderr
    with pytest.raises(ValueError, match="no fitted parameter 'c'; fitted: mu"):
        result.value('c')
    assert result.noise_std_m_s == pytest.approx(VELOCITY_NOISE_M_S, rel=0.03)
    assert result.n_samples == sum(i.force_n.size for i in paper_set)
    for index, (impact, residual, rms) in enumerate(
        zip(paper_set, result.residuals_m_s, result.impact_residual_rms_m_s, strict=True)
    ):
        assert result.impacts[index] is impact
        rebuilt = impact.velocity_m_s - result.simulate(index).velocity_m_s
        np.testing.assert_allclose(residual, rebuilt, atol=1e-15)
        assert rms == pytest.approx(np.sqrt(np.mean(residual**2)))
    peak = max(i.peak_velocity_m_s for i in paper_set)
    assert result.normalised_residual == pytest.approx(result.residual_rms_m_s / peak)
    assert all(fraction > 0.999 for fraction in result.explained_fraction)
    assert result.at_bounds == ()


def test_hits_of_a_session_start_where_the_last_one_left_the_rig():
    # One continuous recording: friction holds the rig off centre after each hit, so the next
    # starts there. Fitting each impact's start brings the residual down to the noise.
    session = simulated_session(
        1, seed=3, force_noise_std_n=FORCE_NOISE_N, velocity_noise_std_m_s=VELOCITY_NOISE_M_S
    )
    records = capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    # Where the hits alone (the recorded force gated, as the noise must not drive it) left it.
    hits = fit.condition_impact(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    truth = simulate(hits.force_n, session.sample_rate_hz, mu=session.mu).displacement_m
    starts = [truth[record.record_start_sample_index] for record in records]
    assert max(abs(x) for x in starts) > 0.1e-3
    at_zero = fit.fit_friction(records)
    result = fit.fit_friction(records, fit_initial_position=True)
    assert at_zero.joint.residual_rms_m_s > 1.5 * VELOCITY_NOISE_M_S
    assert result.joint.residual_rms_m_s == pytest.approx(VELOCITY_NOISE_M_S, rel=0.05)
    assert result.mu == pytest.approx(session.mu, rel=0.01)
    assert result.joint.names[1:] == (*(f'initial_position_m[{i}]' for i in range(3)), *SCALES)
    np.testing.assert_allclose(result.joint.initial_positions_m, starts, atol=5e-6)
    assert all(
        single.initial_positions_m[0] == pytest.approx(x, abs=5e-6)
        for single, x in zip(result.per_impact, starts, strict=True)
    )


def test_fitting_the_start_costs_little_when_the_rig_starts_at_centre(paper_set):
    result = fit.fit_model(paper_set, fit_initial_position=True)
    assert result.mu == pytest.approx(0.113, rel=0.01)
    assert np.all(np.abs(result.initial_positions_m) < 5 * result.stderr[1:])


def test_one_mu_is_refused_statistically_when_the_levels_differ():
    records = lab_levels(6, mu=0.113)
    records[2] = lab_impact(records[2].peak_force_n, 60, mu=0.125)
    result = fit.fit_friction(records)
    assert result.consistency_p_value < 1e-6
    assert result.per_impact[2].mu == pytest.approx(0.125, rel=0.01)


# --- the Jacobian's block structure -------------------------------------------------------------


@pytest.fixture(scope='module')
def session_set():
    """Three hits of one continuous session: each starts where friction left the last one."""
    session = simulated_session(
        1, seed=3, force_noise_std_n=FORCE_NOISE_N, velocity_noise_std_m_s=VELOCITY_NOISE_M_S
    )
    records = capture_impacts(session.force_n, session.velocity_m_s, session.sample_rate_hz)
    return [fit.as_conditioned(record) for record in records]


@pytest.mark.parametrize(
    'options',
    [
        dict(),
        dict(fit_damping=True, terms=('velocity_offset',)),
        dict(misfit='frf'),
    ],
    ids=['mu', 'damping_and_a_term', 'frf'],
)
def test_blockwise_jacobian_gives_the_dense_fit(session_set, options):
    blocks = fit.fit_model(session_set, fit_initial_position=True, **options)
    dense = fit.fit_model(session_set, fit_initial_position=True, jacobian='dense', **options)
    assert blocks.names == dense.names
    assert max(abs(x) for x in blocks.initial_positions_m) > 0.1e-3
    np.testing.assert_allclose(blocks.values, dense.values, rtol=1e-9, atol=1e-15)
    for part in ('stderr', 'stderr_white', 'stderr_force'):
        np.testing.assert_allclose(getattr(blocks, part), getattr(dense, part), rtol=1e-6)
    np.testing.assert_allclose(
        blocks.covariance, dense.covariance, rtol=1e-6, atol=1e-9 * np.max(np.abs(dense.covariance))
    )
    # Where start positions are fitted, the sandwich and force parts have off-diagonal
    # blocks between impacts only through the global parameters: check one is not zero.
    assert dense.covariance[-1, -2] != 0.0


def _count_jacobian_runs(monkeypatch) -> list[tuple[int, int]]:
    """Per Jacobian of every later fit: (model runs, floats stored)."""
    from fmm_ros.core.identify import lsq as _lsq

    runs = [0]
    counted = []
    simulate_for_real, jacobian_for_real = output_error.simulate, _lsq._forward_jacobian
    lock = threading.Lock()  # the columns of a Jacobian run in threads

    def counting_simulate(*args, **kwargs):
        with lock:
            runs[0] += 1
        return simulate_for_real(*args, **kwargs)

    def counting_jacobian(*args):
        before = runs[0]
        evaluations = jacobian_for_real(*args)
        stored = sum(rows.size for rows in args[8].rows)  # out
        assert evaluations == runs[0] - before
        counted.append((runs[0] - before, stored))
        return evaluations

    monkeypatch.setattr(output_error, 'simulate', counting_simulate)
    monkeypatch.setattr(_lsq, '_forward_jacobian', counting_jacobian)
    return counted


@pytest.mark.parametrize('n_impacts', [2, 3])
def test_a_start_position_runs_and_stores_only_its_own_impact(session_set, monkeypatch, n_impacts):
    impacts = session_set[:n_impacts]
    samples = sum(impact.force_n.size for impact in impacts)
    n_global = 2  # mu and c
    counted = _count_jacobian_runs(monkeypatch)
    fit.fit_model(impacts, fit_damping=True, fit_initial_position=True)
    assert counted and all(
        counts == (n_global * n_impacts + n_impacts, (n_global + 1) * samples) for counts in counted
    )
    counted.clear()
    fit.fit_model(impacts, fit_damping=True, fit_initial_position=True, jacobian='dense')
    assert counted and all(
        counts == ((n_global + n_impacts) * n_impacts, (n_global + n_impacts) * samples)
        for counts in counted
    )


@pytest.mark.parametrize('threads', [2, 3])
def test_the_thread_count_does_not_change_a_fit(session_set, monkeypatch, threads):
    from fmm_ros.core.identify import friction

    monkeypatch.setattr(friction, 'available_threads', lambda: 1)
    serial = fit.fit_model(session_set[:3], fit_damping=True, fit_initial_position=True)
    monkeypatch.setattr(friction, 'available_threads', lambda: threads)
    shared = fit.fit_model(session_set[:3], fit_damping=True, fit_initial_position=True)
    for part in ('values', 'stderr', 'covariance'):
        np.testing.assert_array_equal(getattr(shared, part), getattr(serial, part))
    for a, b in zip(shared.residuals_m_s, serial.residuals_m_s, strict=True):
        np.testing.assert_array_equal(a, b)


def test_block_jacobian_is_the_dense_one_without_its_zeros():
    from fmm_ros.core.identify.lsq import Blocks

    segments = (slice(0, 3), slice(3, 5))
    blocks = Blocks.global_and_local(segments, 1, [[1], [2]])
    assert blocks.n_parameters == 3
    assert blocks.touched_by(0) == ((0, 0), (1, 0))
    assert blocks.touched_by(2) == ((1, 1),)
    jacobian = blocks.empty_jacobian()
    jacobian.rows[0][:] = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]
    jacobian.rows[1][:] = [[7.0, 8.0], [9.0, 10.0]]
    dense = np.array(
        [[1.0, 2.0, 3.0, 7.0, 8.0], [4.0, 5.0, 6.0, 0.0, 0.0], [0.0, 0.0, 0.0, 9.0, 10.0]]
    )
    residual = np.array([1.0, -1.0, 2.0, 0.5, 3.0])
    np.testing.assert_allclose(jacobian.normal(), dense @ dense.T)
    np.testing.assert_allclose(jacobian.gradient(residual), dense @ residual)
    with pytest.raises(BadInputError, match='not ascending indices below 3'):
        Blocks(segments, (np.array([0, 3]), np.array([1])), 3)


# --- model terms, as the discrepancy workflow uses them ------------------------------------------


def test_fits_the_parameters_of_a_model_term_with_mu():
    delay = model_term('sensor_delay', delay_s=3.3e-4)
    records = lab_levels(9, mu=0.12, effects=(delay,))
    result = fit.fit_model(records, terms=('sensor_delay',))
    assert result.names == ('mu', 'sensor_delay.delay_s')
    assert result.units == ('1', 's')
    assert result.mu == pytest.approx(0.12, rel=0.01)
    assert result.value('sensor_delay.delay_s') == pytest.approx(3.3e-4, rel=0.05)
    assert isinstance(result.effects[0], type(delay))


def test_fixed_effects_are_held_and_term_instances_set_start_values(paper_set):
    offset = model_term('velocity_offset', offset_m_s=0.0)
    result = fit.fit_model(
        paper_set,
        terms=(model_term('asymmetric_friction', mu_difference=0.0),),
        fixed_effects=(offset,),
    )
    assert result.effects[0] is offset
    assert result.value('asymmetric_friction.mu_difference') == pytest.approx(0.0, abs=2e-3)
    assert result.mu == pytest.approx(0.113, rel=0.01)


def test_a_term_far_smaller_in_its_units_still_gets_an_honest_error():
    # dv/dk3 is ~1e-7 of dv/dmu: unscaled, the covariance lost k3's variance to rounding.
    cubic = model_term('cubic_stiffness', cubic_stiffness_n_per_m3=3e4)
    records = lab_levels(5, mu=0.113, effects=(cubic,), duration_s=6.0)
    result = fit.fit_model(records, terms=('cubic_stiffness',))
    value, error = result.value('cubic_stiffness.cubic_stiffness_n_per_m3'), result.stderr[1]
    assert 1.0 < error < 1e3 and abs(value - 3e4) < 5.0 * error
    assert result.mu == pytest.approx(0.113, rel=0.01)


@pytest.mark.parametrize(
    'options, message',
    [
        (dict(terms=('friction_wheel',)), "unknown model term 'friction_wheel'"),
        (dict(terms=('stribeck', 'stribeck')), 'model term stribeck given twice'),
        (dict(terms=('stribeck',), fixed_effects=(model_term('stribeck'),)), 'given twice'),
        (dict(terms=('viscous_damping',), fit_damping=True), 'the same parameter'),
        (dict(fixed_effects=('stribeck',)), 'fixed_effects must be model terms'),
        (dict(misfit='phase'), "unknown misfit 'phase'"),
        (dict(integrator='leapfrog'), "unknown integrator 'leapfrog'"),
        (dict(mu_bounds=(0.3, 0.1)), 'mu_bounds must be'),
        (dict(rig=Rig(normal_force_n=0.0)), 'normal_force_n'),
        (dict(band_limit_hz=-1.0), 'band_limit_hz must be positive'),
        (dict(jacobian='sparse'), "unknown jacobian 'sparse'"),
    ],
)
def test_bad_options_are_refused_by_name(paper_set, options, message):
    with pytest.raises(ValueError, match=message):
        fit.fit_model(paper_set[:1], **options)


# --- conditioning --------------------------------------------------------------------------------


def test_the_force_is_gated_to_the_hit_and_its_baseline_removed():
    record = lab_impact(1000.0, 12, mu=0.113)
    offset = 4.0  # a charge amplifier's zero error [N]
    impact = fit.condition_impact(
        record.force_n + offset, record.velocity_m_s, record.sample_rate_hz, source='hit.csv'
    )
    assert impact.baseline_n == pytest.approx(offset, abs=0.01)
    assert impact.force_noise_std_n == pytest.approx(FORCE_NOISE_N, rel=0.05)
    ((start, stop),) = impact.gate
    assert start < record.trigger_index and stop - start < 80
    assert not impact.force_n[:start].any() and not impact.force_n[stop:].any()
    assert impact.impulse_n_s == pytest.approx(record.impulse_n_s, rel=1e-3)
    assert impact.source == 'hit.csv'
    # Driven by the raw noisy force, the stuck mass creeps and mu is biased; gated, it is not.
    assert fit.fit_model(impact).mu == pytest.approx(0.113, rel=0.003)


def test_a_bounce_is_a_second_gate_and_drives_the_model():
    record = lab_impact(1000.0, 13, mu=0.113, force_noise_std_n=0.0)
    bounce = np.roll(np.where(record.force_n > 0, 0.2 * record.force_n, 0.0), 120)
    impact = fit.condition_impact(
        record.force_n + bounce, record.velocity_m_s, record.sample_rate_hz
    )
    assert len(impact.gate) == 2
    assert impact.impulse_n_s == pytest.approx(1.2 * record.impulse_n_s, rel=1e-6)


def test_velocity_noise_estimate_ignores_the_motion():
    record = lab_impact(1450.0, 14, mu=0.05)
    assert fit.velocity_noise_std(record.velocity_m_s) == pytest.approx(
        VELOCITY_NOISE_M_S, rel=0.02
    )
    assert fit.velocity_noise_std(record.simulation.velocity_m_s) < 1e-6


def test_energy_balance_starts_within_a_few_percent(paper_set):
    assert fit.energy_balance_mu(paper_set) == pytest.approx(0.113, rel=0.03)


def test_plain_records_are_conditioned_on_the_way_in():
    record = lab_impact(450.0, 15, mu=0.113)
    assert fit.fit_model(record).mu == pytest.approx(0.113, rel=0.01)
    with pytest.raises(ValueError, match='must have force_n, velocity_m_s and sample_rate_hz'):
        fit.fit_model([np.zeros(10)])
    with pytest.raises(ValueError, match='no impacts to fit'):
        fit.fit_model([])


@pytest.mark.parametrize(
    'force, velocity, rate, message',
    [
        (np.zeros(100), np.zeros(99), 1e4, 'force has 100 samples but velocity has 99'),
        (np.zeros((2, 50)), np.zeros(100), 1e4, 'force_n must be one-dimensional'),
        (np.r_[np.zeros(50), np.nan], np.zeros(51), 1e4, 'force_n is not finite at sample 50'),
        (
            np.zeros(51),
            np.r_[np.zeros(7), np.inf, np.zeros(43)],
            1e4,
            'velocity_m_s is not finite at sample 7',
        ),
        (np.zeros(8), np.zeros(8), 1e4, 'at least 16 samples'),
        (np.zeros(100), np.zeros(100), 0.0, 'sample_rate_hz must be positive'),
    ],
)
def test_malformed_records_are_refused(force, velocity, rate, message):
    with pytest.raises(ValueError, match=message):
        fit.condition_impact(force, velocity, rate, source='x.csv')


def test_too_short_a_record_is_refused():
    record = lab_impact(1000.0, 16, mu=0.113, duration_s=0.6)
    with pytest.raises(ValueError, match='less than two natural periods'):
        fit.fit_model(record)


# --- clear failures ------------------------------------------------------------------------------


def _noise(seed, n=330_000):
    rng = np.random.default_rng(seed)
    return rng.normal(0.0, FORCE_NOISE_N, n), rng.normal(0.0, VELOCITY_NOISE_M_S, n)


def test_pure_noise_has_no_hit():
    force, velocity = _noise(20)
    with pytest.raises(FitError, match='noise.csv: the force never departs') as failure:
        fit.fit_friction([fit.condition_impact(force, velocity, 1e4, source='noise.csv')])
    assert failure.value.reason == 'no_hit' and failure.value.source == 'noise.csv'


def test_a_force_without_a_hit_is_refused_even_if_the_rig_moved():
    record = lab_impact(1000.0, 21, mu=0.113)
    with pytest.raises(FitError, match='there is no hit') as failure:
        fit.condition_impact(_noise(21)[0], record.velocity_m_s, 1e4)
    assert failure.value.reason == 'no_hit'


def test_a_hit_without_motion_is_refused():
    record = lab_impact(1000.0, 22, mu=0.113)
    with pytest.raises(FitError, match='the rig did not move') as failure:
        fit.condition_impact(record.force_n, _noise(22)[1], 1e4)
    assert failure.value.reason == 'no_motion'


def test_a_frictionless_record_puts_mu_on_its_bound():
    record = lab_impact(1000.0, 23, mu=0.0, duration_s=10.0)
    with pytest.raises(FitError, match='lies on its search bound') as failure:
        fit.fit_model(record)
    assert failure.value.reason == 'mu_at_bound'
    with pytest.raises(FitError, match='lies on its search bound'):
        fit.fit_model(lab_impact(1000.0, 24, mu=0.3, duration_s=10.0), mu_bounds=(0.01, 0.2))


@pytest.mark.parametrize('velocity', ['inverted', 'another hit'])
def test_a_velocity_the_force_did_not_cause_is_unexplained(velocity):
    record = lab_impact(1000.0, 25, mu=0.113, duration_s=10.0)
    measured = (
        -record.velocity_m_s
        if velocity == 'inverted'
        else lab_impact(450.0, 26, mu=0.113, duration_s=10.0).velocity_m_s[::-1]
    )
    impact = fit.condition_impact(record.force_n, measured, 1e4, source='bad.csv')
    with pytest.raises(FitError, match='unexplained.*check the channels') as failure:
        fit.fit_friction([impact])
    assert failure.value.reason == 'unexplained'


def test_fit_errors_are_value_errors_with_known_reasons():
    assert issubclass(FitError, ValueError)
    with pytest.raises(ValueError, match='unknown fit failure reason'):
        FitError('bad_luck', 'nope')


# --- rig identification --------------------------------------------------------------------------


@pytest.fixture(scope='module')
def lifted_rig():
    """A stiffer, more damped flexure than the FMM, hit at three levels with the pin lifted."""
    return Rig(mass_kg=8.2, stiffness_n_per_m=2500.0, damping_n_s_per_m=0.6)


def test_identify_rig_from_frictionless_impacts(lifted_rig):
    records = lab_levels(30, mu=0.0, rig=lifted_rig)
    result = fit.identify_rig(records)
    assert result.method == 'impact'
    assert result.mass_kg == pytest.approx(lifted_rig.mass_kg, rel=0.01)
    assert result.damping_n_s_per_m == pytest.approx(lifted_rig.damping_n_s_per_m, rel=0.10)
    assert result.stiffness_n_per_m == pytest.approx(lifted_rig.stiffness_n_per_m, rel=0.01)
    assert result.natural_frequency_hz == pytest.approx(lifted_rig.natural_frequency_hz, rel=1e-4)
    assert result.damping_ratio == pytest.approx(lifted_rig.damping_ratio, rel=0.05)
    for value, error, truth in (
        (result.mass_kg, result.mass_stderr_kg, lifted_rig.mass_kg),
        (result.stiffness_n_per_m, result.stiffness_stderr_n_per_m, lifted_rig.stiffness_n_per_m),
        (result.damping_n_s_per_m, result.damping_stderr_n_s_per_m, lifted_rig.damping_n_s_per_m),
    ):
        assert 0.0 < error < 0.01 * truth and abs(value - truth) < 5.0 * error
    assert result.residual_rms_m_s == pytest.approx(VELOCITY_NOISE_M_S, rel=0.05)
    rig = result.rig(normal_force_n=6.67)
    assert rig.normal_force_n == 6.67 and rig.mass_kg == result.mass_kg


def test_the_paper_fmm_is_identified_from_one_lifted_impact():
    result = fit.identify_rig(lab_impact(1000.0, 31, mu=0.0))
    assert result.mass_kg == pytest.approx(10.391, rel=0.01)
    assert result.damping_n_s_per_m == pytest.approx(0.275, rel=0.10)
    assert result.stiffness_n_per_m == pytest.approx(1982.0, rel=0.01)


def _free_decay(rig, seed, x0_m=3e-3, release_s=0.2):
    rng = np.random.default_rng(seed)
    decay = free_vibration(x0_m, 33.0 - release_s, 1e4, rig=rig, mu=0.0).velocity_m_s
    velocity = np.concatenate((np.zeros(round(release_s * 1e4)), decay))
    return velocity + rng.normal(0.0, VELOCITY_NOISE_M_S, velocity.size)


def test_free_decay_gives_natural_frequency_and_damping_ratio(lifted_rig):
    result = fit.fit_free_decay(_free_decay(lifted_rig, 40), 1e4)
    assert result.natural_frequency_hz == pytest.approx(lifted_rig.natural_frequency_hz, rel=1e-5)
    assert result.damping_ratio == pytest.approx(lifted_rig.damping_ratio, rel=0.02)
    assert abs(result.damping_ratio - lifted_rig.damping_ratio) < 5 * result.damping_ratio_stderr
    assert result.start_index > 2000  # after the release
    assert result.residual_rms_m_s == pytest.approx(VELOCITY_NOISE_M_S, rel=0.05)
    assert result.damped_frequency_hz < result.natural_frequency_hz


def test_free_decays_need_the_mass_for_k_and_c(lifted_rig):
    class Decay:
        force_n = np.random.default_rng(41).normal(0.0, FORCE_NOISE_N, 330_000)
        velocity_m_s = _free_decay(lifted_rig, 42)
        sample_rate_hz = 1e4
        source = 'decay.csv'

    with pytest.raises(ValueError, match='give mass_kg'):
        fit.identify_rig([Decay()])
    result = fit.identify_rig([Decay()], mass_kg=lifted_rig.mass_kg)
    assert result.method == 'free_decay' and result.sources == ('decay.csv',)
    assert math.isnan(result.mass_stderr_kg)
    assert result.stiffness_n_per_m == pytest.approx(lifted_rig.stiffness_n_per_m, rel=1e-4)
    assert result.damping_n_s_per_m == pytest.approx(lifted_rig.damping_n_s_per_m, rel=0.02)
    # With an impact as well, the impact decides and the decay is kept as a check.
    both = fit.identify_rig([Decay(), lab_impact(1000.0, 43, mu=0.0, rig=lifted_rig)])
    assert both.method == 'impact' and len(both.free_decays) == 1


def test_a_decay_with_too_few_cycles_is_refused():
    noise = np.random.default_rng(3).normal(0.0, VELOCITY_NOISE_M_S, 20_000)
    one_cycle = free_vibration(3e-3, 0.5, 1e4, mu=0.0).velocity_m_s
    with pytest.raises(FitError, match='too few cycles') as failure:
        fit.fit_free_decay(one_cycle + noise[: one_cycle.size], 1e4)
    assert failure.value.reason == 'too_few_cycles'
    heavy = Rig(mass_kg=1.0, stiffness_n_per_m=400.0, damping_n_s_per_m=16.0)  # zeta = 0.4
    gone = free_vibration(1e-3, 2.0, 1e4, rig=heavy, mu=0.0).velocity_m_s
    with pytest.raises(FitError, match='not a lightly damped free decay|too few cycles'):
        fit.fit_free_decay(gone + noise, 1e4)
    with pytest.raises(ValueError, match='start_index 5 lies outside'):
        fit.fit_free_decay(np.zeros(5), 1e4, start_index=5)


def test_a_friction_damped_record_is_not_a_linear_rig():
    with pytest.raises(FitError) as failure:
        fit.identify_rig(lab_impact(1000.0, 44, mu=0.113, duration_s=10.0))
    assert failure.value.reason in ('unexplained', 'too_few_cycles', 'at_bound')


# --- the optimiser ------------------------------------------------------------------------------


def test_normal_inverse_survives_wide_scales_and_marks_dead_parameters():
    normal = np.array([[4e8, 3e-2, 0.0], [3e-2, 1e-11, 0.0], [0.0, 0.0, 0.0]])
    inverse = normal_inverse(normal)
    np.testing.assert_allclose(inverse[:2, :2], np.linalg.inv(normal[:2, :2]), rtol=1e-9)
    assert inverse[2, 2] == np.inf and not inverse[2, :2].any()


def test_levenberg_marquardt_with_an_active_bound_and_an_infeasible_region():
    t = np.linspace(0.0, 1.0, 200)
    data = 2.0 * np.exp(-3.0 * t)

    def residual(x, out):
        if x[1] > 10.0:
            raise Infeasible('too fast')
        np.subtract(data, x[0] * np.exp(-x[1] * t), out=out)

    free = levenberg_marquardt(
        residual,
        np.array([1.0, 1.0]),
        np.array([0.0, 0.0]),
        np.array([5.0, 20.0]),
        np.array([1.0, 1.0]),
        t.size,
    )
    assert free.converged and free.x == pytest.approx([2.0, 3.0], rel=1e-6)
    bounded = levenberg_marquardt(
        residual,
        np.array([1.0, 1.0]),
        np.array([0.0, 0.0]),
        np.array([1.5, 20.0]),
        np.array([1.0, 1.0]),
        t.size,
    )
    assert bounded.converged and bounded.x[0] == 1.5 and 1.0 < bounded.x[1] < 3.0
    with pytest.raises(ValueError, match='cannot be evaluated at the start point'):
        levenberg_marquardt(
            residual,
            np.array([1.0, 15.0]),
            np.array([0.0, 0.0]),
            np.array([5.0, 20.0]),
            np.array([1.0, 1.0]),
            t.size,
        )


def test_a_parameter_the_residuals_ignore_gets_infinite_variance_and_spoils_no_other():
    import dataclasses
    import warnings

    from fmm_ros.core.identify.lsq import BlockJacobian, Blocks, LsqSolution
    from fmm_ros.core.identify.output_error import block_score, sandwich_uncertainty

    rng = np.random.default_rng(0)
    rows = np.vstack([rng.normal(size=(2, 4000)), np.zeros(4000)])
    jacobian = BlockJacobian(Blocks.shared((slice(0, 4000),), 3), (rows,))
    residual = rng.normal(0.0, 0.01, 4000)
    fields = {f.name for f in dataclasses.fields(LsqSolution)}
    values = dict(
        x=np.zeros(3),
        lower=-np.ones(3),
        upper=np.ones(3),
        residual=residual,
        jacobian=jacobian,
        block_normals=jacobian.block_normals(),
        cost=float(residual @ residual),
    )
    solution = LsqSolution(**values, **{name: 0 for name in fields - set(values)})
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        result = sandwich_uncertainty(solution, [block_score(rows, residual, 400)])
    assert np.isinf(result.stderr[2])
    assert np.all(np.isfinite(result.stderr[:2])) and np.all(result.stderr[:2] > 0)
    assert np.all(np.isfinite(result.covariance[:2, :2]))
