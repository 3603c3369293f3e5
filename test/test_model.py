"""fmm_ros.core.physics: integrators against independent solutions, terms, streaming, bad input."""

import math
from dataclasses import replace

import numpy as np
import pytest
import scipy.signal
from reference_solver import Oscillator, solve

from fmm_ros.constants import PAPER_MU
from fmm_ros.core._checks import time_base
from fmm_ros.core.physics import _kernels, model
from fmm_ros.core.physics.model import INTEGRATORS, OscillatorStream, free_vibration, simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import MODEL_TERMS, ModelTerm, Parameter, model_term
from fmm_ros.sim.excitation import half_sine_pulse

RATE_HZ = 10_000.0
# Every term at its default, but a delay of 2.37 samples: the delay line's fractional path.
ALL_TERMS = tuple(
    model_term(name, delay_s=2.37e-4) if name == 'sensor_delay' else model_term(name)
    for name in MODEL_TERMS
)


def impact(rate_hz=RATE_HZ, duration_s=4.0, peak_n=1000.0, contact_s=2.2e-3, start_s=0.01):
    return half_sine_pulse(peak_n, contact_s, rate_hz, duration_s, start_s=start_s)


def linear_response(force, rate_hz, mass, damping, stiffness):
    """scipy.signal.lsim with interp=True: the exact response to a force linear between samples."""
    system = scipy.signal.StateSpace(
        [[0, 1], [-stiffness / mass, -damping / mass]], [[0], [1 / mass]], np.eye(2), [[0], [0]]
    )
    _, y, _ = scipy.signal.lsim(system, force, np.arange(force.size) / rate_hz, interp=True)
    return y[:, 0], y[:, 1]


def reference_oscillator(rig=FMM_RIG, mu=PAPER_MU, **extra):
    return Oscillator(
        rig.mass_kg,
        rig.damping_n_s_per_m,
        rig.stiffness_n_per_m,
        rig.normal_force_n,
        mu,
        mu,
        **extra,
    )


# --- the rig ---------------------------------------------------------------------------------


def test_rig_defaults_are_the_paper_fmm():
    assert FMM_RIG == Rig(10.391, 1982.0, 0.275, 0.680 * 9.81)
    assert FMM_RIG.friction_limit_m(PAPER_MU) == pytest.approx(PAPER_MU * 6.6708 / 1982.0)


@pytest.mark.parametrize(
    ('field', 'value', 'message'),
    [
        ('mass_kg', 0.0, 'mass_kg must be positive'),
        ('mass_kg', -1.0, 'mass_kg must be positive'),
        ('stiffness_n_per_m', 0.0, 'stiffness_n_per_m must be positive'),
        ('damping_n_s_per_m', -0.1, 'damping_n_s_per_m must not be negative'),
        ('normal_force_n', -1.0, 'normal_force_n must not be negative'),
        ('mass_kg', math.nan, 'mass_kg must be finite'),
        ('stiffness_n_per_m', '1982', 'stiffness_n_per_m must be a number'),
    ],
)
def test_rig_rejects_impossible_constants(field, value, message):
    with pytest.raises(ValueError, match=message):
        Rig(**{field: value})


# --- exactness of the integrators ------------------------------------------------------------


def test_exact_step_is_the_exact_linear_response_without_friction():
    force = impact(duration_s=2.0)
    sim = simulate(force, RATE_HZ, mu=0.0)
    x, v = linear_response(
        force, RATE_HZ, FMM_RIG.mass_kg, FMM_RIG.damping_n_s_per_m, FMM_RIG.stiffness_n_per_m
    )
    np.testing.assert_allclose(sim.displacement_m, x, rtol=0, atol=1e-13 * np.max(np.abs(x)))
    np.testing.assert_allclose(sim.velocity_m_s, v, rtol=0, atol=1e-12 * np.max(np.abs(v)))


@pytest.mark.slow
@pytest.mark.parametrize('damping', [0.0, 0.275, 400.0])  # under-, and over-damped (c_crit 287)
def test_exact_agrees_with_an_event_located_ode_solution(damping):
    rate = 2000.0
    rig = Rig(damping_n_s_per_m=damping)
    force = impact(rate_hz=rate, duration_s=4.0)
    ref_x, ref_v = solve(reference_oscillator(rig), force, rate)
    for integrator in ('exact', 'rk4'):
        sim = simulate(force, rate, rig=rig, integrator=integrator)
        peak = np.max(np.abs(ref_v))
        assert np.max(np.abs(sim.velocity_m_s - ref_v)) <= 1e-7 * peak, integrator
        assert np.max(np.abs(sim.displacement_m - ref_x)) <= 1e-7 * np.max(np.abs(ref_x))
        assert sim.displacement_m[-1] == pytest.approx(ref_x[-1], abs=1e-10)


@pytest.mark.slow
def test_exact_agrees_with_the_paper_euler_method_at_a_tiny_step():
    # Euler holds the force over each step, which shifts the impact by half a step: at 1 MHz
    # that costs about (h/2) f_peak / m, 0.04 % of the peak velocity.
    rate = 1e6
    force = impact(rate_hz=rate, duration_s=3.5)
    exact = simulate(force, rate)
    euler = simulate(force, rate, integrator='euler')
    peak = np.max(np.abs(exact.velocity_m_s))
    assert np.max(np.abs(exact.velocity_m_s - euler.velocity_m_s)) <= 1e-3 * peak
    assert exact.rest_position_m == pytest.approx(euler.rest_position_m, abs=1e-7)
    assert exact.rest_time_s == pytest.approx(euler.rest_time_s, abs=1e-4)


@pytest.mark.slow
def _stribeck_reference(asymmetric: float, cubic: float = 0.0) -> Oscillator:
    """The reference solver's rig with the Stribeck contact these tests use (0.03 excess,
    vs 5 mm/s) and mu PAPER_MU +- asymmetric / 2 by direction."""
    return Oscillator(
        FMM_RIG.mass_kg,
        FMM_RIG.damping_n_s_per_m,
        FMM_RIG.stiffness_n_per_m,
        FMM_RIG.normal_force_n,
        PAPER_MU + asymmetric / 2,
        PAPER_MU - asymmetric / 2,
        cubic=cubic,
        static_excess=0.03,
        stribeck_velocity=5e-3,
    )


def test_nonlinear_terms_agree_with_an_event_located_ode_solution():
    rate = 2000.0
    stribeck = model_term('stribeck', mu_static_excess=0.03, stribeck_velocity_m_s=5e-3)
    cubic = model_term('cubic_stiffness', cubic_stiffness_n_per_m3=5e6)
    asymmetric = model_term('asymmetric_friction', mu_difference=0.02)
    force = impact(rate_hz=rate, duration_s=4.0)
    ref_x, ref_v = solve(_stribeck_reference(0.02, cubic=5e6), force, rate)
    sim = simulate(force, rate, effects=(stribeck, cubic, asymmetric))
    # RK4 is fourth order, not exact, but its segments resolve the Stribeck curve near zero
    # speed (also when leaving rest, where the friction starts at its static value).
    assert np.max(np.abs(sim.velocity_m_s - ref_v)) <= 1e-7 * np.max(np.abs(ref_v))
    assert sim.rest_position_m == pytest.approx(ref_x[-1], abs=1e-10)
    # and against the paper's Euler at a tiny step
    rate = 1e6
    force = impact(rate_hz=rate, duration_s=3.5)
    effects = (stribeck, cubic, asymmetric)
    exact = simulate(force, rate, effects=effects)
    euler = simulate(force, rate, effects=effects, integrator='euler')
    peak = np.max(np.abs(exact.velocity_m_s))
    assert np.max(np.abs(exact.velocity_m_s - euler.velocity_m_s)) <= 1e-3 * peak


@pytest.mark.parametrize('rate_hz', [230.0, 1000.0])  # 20 and 89 samples per period
def test_exact_path_is_exact_to_rounding_at_coarse_sampling(rate_hz):
    # Undamped Coulomb free vibration from 3 mm: half cycles of T/2 about +-x_lim, amplitudes
    # falling by 2 x_lim, rest after eight of them (paper Fig. 2).
    rig = Rig(mass_kg=1.0, stiffness_n_per_m=5000.0, damping_n_s_per_m=0.0, normal_force_n=9.81)
    sim = free_vibration(3e-3, 1.0, rate_hz, rig=rig, mu=0.1)
    period = 1 / rig.natural_frequency_hz
    x_lim = rig.friction_limit_m(0.1)
    t = sim.time_s
    half_cycle = np.minimum(np.floor(t / (period / 2)), 7)
    x = np.where(half_cycle % 2 == 0, x_lim, -x_lim) + (
        3e-3 - x_lim - 2 * x_lim * half_cycle
    ) * np.cos(2 * np.pi * t / period)
    x = np.where(t >= 4 * period, 3e-3 - 16 * x_lim, x)
    np.testing.assert_allclose(sim.displacement_m, x, rtol=0, atol=1e-16)
    assert sim.rest_time_s == pytest.approx(4 * period, abs=1e-14)


@pytest.mark.parametrize('integrator', ['exact', 'rk4'])
def test_a_stop_and_restart_inside_one_sample_interval_is_not_missed(integrator):
    # Sliding at 0.1 mm/s against friction while the force ramps at 104 N/s: the velocity
    # dips through zero 1.5 ms in and is positive again at the 20 ms sample, so no sign
    # change shows at the samples. Really the mass sticks there until the ramp breaks it away.
    rate = 50.0
    force = np.minimum(104.0 * np.arange(50) / rate, 10.0)
    _, ref_v = solve(reference_oscillator(), force, rate, v0=1e-4)
    sim = simulate(force, rate, v0_m_s=1e-4, integrator=integrator)
    tolerance = {'exact': 1e-9, 'rk4': 1e-7}[integrator]  # RK4: 14 segments a sample here
    assert np.max(np.abs(sim.velocity_m_s - ref_v)) <= tolerance * np.max(np.abs(ref_v))


def test_break_away_is_located_inside_the_sample_interval():
    # A ramp r t on a mass resting at x = 0 breaks it away at t_b = mu N / r (between samples),
    # then x = (r / k) [(t - t_b) - sin(w (t - t_b)) / w] while it slides (c = 0).
    rig = Rig(damping_n_s_per_m=0.0)
    ramp = 3.3  # N/s
    t = np.arange(int(0.35 * RATE_HZ)) / RATE_HZ
    sim = simulate(ramp * t, RATE_HZ, rig=rig)
    t_break = PAPER_MU * rig.normal_force_n / ramp
    assert t_break * RATE_HZ % 1 > 0.1  # really between samples
    w = 2 * np.pi * rig.natural_frequency_hz
    tau = np.clip(t - t_break, 0, None)
    expected = ramp / rig.stiffness_n_per_m * (tau - np.sin(w * tau) / w)
    np.testing.assert_allclose(sim.displacement_m, expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        sim.velocity_m_s, ramp / rig.stiffness_n_per_m * (1 - np.cos(w * tau)), rtol=0, atol=1e-13
    )


@pytest.mark.parametrize('asymmetric', [0.0, 0.02])
def test_a_stribeck_contact_alone_slides_exactly_where_its_excess_is_below_rounding(asymmetric):
    """Without a cubic spring, a Stribeck contact takes the closed form above 6 vs (its excess
    there is below the rounding of the kinetic friction) and RK4 nearer rest: the event-located
    ODE solution to 1e-7 of the peak, and the pure RK4 path (integrator='rk4') to RK4's own
    truncation error (1e-9 of the peak at 2 kHz)."""
    rate = 2000.0
    stribeck = model_term('stribeck', mu_static_excess=0.03, stribeck_velocity_m_s=5e-3)
    effects = (stribeck, model_term('asymmetric_friction', mu_difference=asymmetric))
    force = impact(rate_hz=rate, duration_s=4.0)
    ref_x, ref_v = solve(_stribeck_reference(asymmetric), force, rate)
    sim = simulate(force, rate, effects=effects)
    peak = np.max(np.abs(ref_v))
    assert peak > 4 * 6 * 5e-3  # much of the motion is on the closed-form path
    assert np.max(np.abs(sim.velocity_m_s - ref_v)) <= 1e-7 * peak
    assert sim.rest_position_m == pytest.approx(ref_x[-1], abs=1e-10)
    rk4 = simulate(force, rate, effects=effects, integrator='rk4')
    assert np.max(np.abs(sim.velocity_m_s - rk4.velocity_m_s)) <= 1e-8 * peak


@pytest.mark.parametrize('exponent', [0.5, 1.0, 1.5])
def test_a_stribeck_shape_of_any_exponent_agrees_with_an_event_located_ode_solution(exponent):
    """exp(-(|v|/vs)^delta) over Armstrong-Helouvry's 0.5-2: the kernels' segments near rest
    widen with 16^(1/delta) vs and the closed form starts at 36^(1/delta) vs. For delta >= 1
    within 2e-8 of the peak speed and 3e-11 m at rest; for delta = 0.5, whose slope is
    unbounded at rest (both solvers lose their order there), 8e-7 and 2.1e-9 m: 3e-3 of the
    1e-4 m/s velocity noise."""
    rate = 2000.0
    stribeck = model_term(
        'stribeck', mu_static_excess=0.03, stribeck_velocity_m_s=5e-3, stribeck_exponent=exponent
    )
    force = impact(rate_hz=rate, duration_s=4.0)
    reference = Oscillator(
        FMM_RIG.mass_kg,
        FMM_RIG.damping_n_s_per_m,
        FMM_RIG.stiffness_n_per_m,
        FMM_RIG.normal_force_n,
        PAPER_MU,
        PAPER_MU,
        static_excess=0.03,
        stribeck_velocity=5e-3,
        stribeck_exponent=exponent,
    )
    ref_x, ref_v = solve(reference, force, rate)
    sim = simulate(force, rate, effects=(stribeck,))
    peak = np.max(np.abs(ref_v))
    smooth = exponent >= 1.0
    assert np.max(np.abs(sim.velocity_m_s - ref_v)) <= (2e-8 if smooth else 1e-6) * peak
    assert sim.rest_position_m == pytest.approx(ref_x[-1], abs=1e-10 if smooth else 5e-9)
    # and the shape matters: the Gaussian's run differs by far more than that (1.5: 4e-4)
    gaussian = simulate(force, rate, effects=(replace(stribeck, stribeck_exponent=2.0),))
    assert np.max(np.abs(gaussian.velocity_m_s - ref_v)) > 1e-4 * peak


def test_stribeck_raises_the_break_away_force_to_static_friction():
    excess = 0.05
    ramp = 10.0
    t = np.arange(int(0.12 * RATE_HZ)) / RATE_HZ
    stribeck = model_term('stribeck', mu_static_excess=excess, stribeck_velocity_m_s=1e-3)
    sim = simulate(ramp * t, RATE_HZ, effects=(stribeck,))
    first_moving = np.argmax(sim.velocity_m_s > 0)
    t_break = (PAPER_MU + excess) * FMM_RIG.normal_force_n / ramp
    assert t[first_moving - 1] <= t_break < t[first_moving]
    plain = simulate(ramp * t, RATE_HZ)
    assert np.argmax(plain.velocity_m_s > 0) < first_moving


def test_asymmetric_friction_shifts_each_half_cycle_by_its_own_limit():
    difference = 0.04
    asymmetric = model_term('asymmetric_friction', mu_difference=difference)
    x0 = 8e-3
    sim = free_vibration(x0, 10.0, RATE_HZ, effects=(asymmetric,), rig=Rig(damping_n_s_per_m=0))
    # Half cycles by hand: moving in direction s the centre is -s mu_s N / k; the arc ends
    # mirrored about it; rest once the spring force is inside the (asymmetric) static band.
    limit = {
        1: (PAPER_MU + difference / 2) * FMM_RIG.normal_force_n / FMM_RIG.stiffness_n_per_m,
        -1: (PAPER_MU - difference / 2) * FMM_RIG.normal_force_n / FMM_RIG.stiffness_n_per_m,
    }
    x = x0
    while not -limit[-1] <= -x <= limit[1]:  # stick test on the spring force -k x
        direction = -np.sign(x)
        x = 2 * (-direction * limit[direction]) - x
    assert sim.rest_position_m == pytest.approx(x, abs=1e-12)


def test_cubic_stiffness_conserves_energy_without_friction_or_damping():
    k3 = 8e6
    rig = Rig(damping_n_s_per_m=0.0)
    sim = free_vibration(
        10e-3,
        2.0,
        RATE_HZ,
        rig=rig,
        mu=0.0,
        effects=(model_term('cubic_stiffness', cubic_stiffness_n_per_m3=k3),),
    )
    x, v = sim.displacement_m, sim.velocity_m_s
    energy = 0.5 * rig.mass_kg * v**2 + 0.5 * rig.stiffness_n_per_m * x**2 + 0.25 * k3 * x**4
    assert np.ptp(energy) <= 1e-9 * energy[0]
    # Stiffening raises the frequency: the first return to x0 comes before the linear period.
    first_peak = np.argmax((x[1:-1] > x[:-2]) & (x[1:-1] >= x[2:])) + 1
    assert first_peak / RATE_HZ < 1 / rig.natural_frequency_hz


def test_exact_and_rk4_paths_agree_on_piecewise_linear_models():
    force = impact(duration_s=4.0)
    effects = (model_term('asymmetric_friction'), model_term('viscous_damping'))
    exact = simulate(force, RATE_HZ, effects=effects)
    rk4 = simulate(force, RATE_HZ, effects=effects, integrator='rk4')
    assert np.max(np.abs(exact.velocity_m_s - rk4.velocity_m_s)) <= 1e-9
    assert exact.rest_time_s == pytest.approx(rk4.rest_time_s, abs=1e-9)


# --- the terms -------------------------------------------------------------------------------


def test_terms_have_the_names_the_workflows_use():
    assert list(MODEL_TERMS) == [
        'viscous_damping',
        'stribeck',
        'asymmetric_friction',
        'cubic_stiffness',
        'second_mode',
        'velocity_offset',
        'sensor_delay',
    ]


@pytest.mark.parametrize('name', list(MODEL_TERMS))
def test_terms_describe_their_parameters_uniformly(name):
    cls = MODEL_TERMS[name]
    assert cls.name == name
    assert cls.parameters and all(isinstance(p, Parameter) for p in cls.parameters)
    for p in cls.parameters:
        assert p.lower <= p.default <= p.upper and p.lower < p.upper
        assert p.unit and p.description
    lower, upper = cls.bounds()
    assert lower.shape == upper.shape == (len(cls.parameters),)
    vector = (lower + upper) / 2
    term = cls.from_vector(vector)
    np.testing.assert_array_equal(term.to_vector(), vector)
    assert model_term(name, vector) == term
    assert model_term(name) == cls()
    assert isinstance(term, ModelTerm)


def test_viscous_damping_term_adds_to_the_rig_damping():
    force = impact(duration_s=2.0)
    with_term = simulate(
        force, RATE_HZ, effects=(model_term('viscous_damping', damping_n_s_per_m=1.5),)
    )
    in_rig = simulate(force, RATE_HZ, rig=Rig(damping_n_s_per_m=FMM_RIG.damping_n_s_per_m + 1.5))
    np.testing.assert_array_equal(with_term.velocity_m_s, in_rig.velocity_m_s)
    alone = simulate(force, RATE_HZ, effects=model_term('viscous_damping', damping_n_s_per_m=1.5))
    np.testing.assert_array_equal(alone.velocity_m_s, in_rig.velocity_m_s)


def test_second_mode_adds_an_exact_linear_response_to_the_output():
    mode = model_term('second_mode', frequency_hz=37.0, damping_ratio=0.02, modal_mass_kg=20.0)
    force = impact(duration_s=4.0)
    base = simulate(force, RATE_HZ)
    both = simulate(force, RATE_HZ, effects=(mode,))
    m2, c2, k2 = mode.constants()
    x2, v2 = linear_response(force, RATE_HZ, m2, c2, k2)
    np.testing.assert_allclose(
        both.velocity_m_s - base.velocity_m_s, v2, rtol=0, atol=1e-12 * np.max(np.abs(v2))
    )
    np.testing.assert_allclose(
        both.displacement_m - base.displacement_m, x2, rtol=0, atol=1e-12 * np.max(np.abs(x2))
    )
    assert both.at_rest  # the friction oscillator is untouched by the second mode:
    assert (both.rest_position_m, both.rest_time_s) == (base.rest_position_m, base.rest_time_s)


@pytest.mark.parametrize('delay_s', [0.0, 3e-4, 1.37e-4])
def test_a_modes_own_pass_is_its_share_of_a_run(delay_s):
    """`mode_velocity` (one pass, what a screen takes a mode's response from) is a run with
    the mode less the run without, whatever the oscillator does and however the vibrometer
    lags, to rounding."""
    mode = model_term('second_mode', frequency_hz=137.0, damping_ratio=0.01, modal_mass_kg=50.0)
    delay = (model_term('sensor_delay', delay_s=delay_s),) if delay_s else ()
    force = impact(duration_s=4.0)
    with_mode, without = (
        simulate(force, RATE_HZ, effects=(*delay, *m), x0_m=2e-4).velocity_m_s
        for m in ((mode,), ())
    )
    alone = model.mode_velocity(force, RATE_HZ, mode, delay_s)
    np.testing.assert_allclose(with_mode - without, alone, rtol=0, atol=1e-12 * np.max(alone))
    with pytest.raises(ValueError, match='at or above the Nyquist frequency'):
        model.mode_velocity(force, 250.0, mode)
    with pytest.raises(ValueError, match='sample_rate_hz must be positive'):
        model.mode_velocity(force, 0.0, mode)
    with pytest.raises(ValueError, match='delay_s must not be negative'):
        model.mode_velocity(force, RATE_HZ, mode, -1e-4)
    with pytest.raises(ValueError, match='force_n'):
        model.mode_velocity(np.array([0.0, np.nan, 1.0]), RATE_HZ, mode)


def test_velocity_offset_and_delay_act_on_the_vibrometer_output_only():
    force = impact(duration_s=1.0)
    base = simulate(force, RATE_HZ)
    offset = simulate(force, RATE_HZ, effects=(model_term('velocity_offset', offset_m_s=2e-4),))
    np.testing.assert_allclose(offset.velocity_m_s - base.velocity_m_s, 2e-4, rtol=1e-9)
    np.testing.assert_array_equal(offset.displacement_m, base.displacement_m)

    whole = simulate(force, RATE_HZ, effects=(model_term('sensor_delay', delay_s=3e-4),))
    np.testing.assert_array_equal(whole.velocity_m_s[3:], base.velocity_m_s[:-3])
    np.testing.assert_array_equal(whole.velocity_m_s[:3], 0.0)
    np.testing.assert_array_equal(whole.displacement_m, base.displacement_m)

    fraction = simulate(force, RATE_HZ, effects=(model_term('sensor_delay', delay_s=2.25e-4),))
    # v(t - 2.25 h), linear between samples: 0.75 v[i - 2] + 0.25 v[i - 3]
    expected = 0.75 * base.velocity_m_s[1:-2] + 0.25 * base.velocity_m_s[:-3]
    np.testing.assert_allclose(fraction.velocity_m_s[3:], expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    ('build', 'message'),
    [
        (lambda: model_term('coulomb'), "unknown model term 'coulomb'"),
        (lambda: model_term('stribeck', [0.01]), 'stribeck takes 3 parameter'),
        (lambda: model_term('stribeck', speed=1.0), 'stribeck has no parameter speed'),
        (
            lambda: model_term('stribeck', mu_static_excess=-0.01),
            'mu_static_excess must not be neg',
        ),
        (
            lambda: model_term('stribeck', stribeck_velocity_m_s=0.0),
            'stribeck_velocity_m_s must be',
        ),
        (lambda: model_term('second_mode', modal_mass_kg=0.0), 'modal_mass_kg must be positive'),
        (lambda: model_term('sensor_delay', delay_s=-1e-3), 'delay_s must not be negative'),
        (lambda: model_term('velocity_offset', offset_m_s=math.inf), 'offset_m_s must be finite'),
    ],
)
def test_terms_reject_impossible_parameters(build, message):
    with pytest.raises(ValueError, match=message):
        build()


# --- streaming ---------------------------------------------------------------------------------


@pytest.mark.parametrize('integrator', INTEGRATORS)
@pytest.mark.parametrize('effects', [(), ALL_TERMS], ids=['base', 'all_terms'])
def test_streaming_in_batches_is_bit_identical_to_one_call(integrator, effects):
    rng = np.random.default_rng(7)
    force = impact(duration_s=4.0) + rng.normal(0.0, 0.3, int(4.0 * RATE_HZ))
    whole = simulate(force, RATE_HZ, effects=effects, integrator=integrator, x0_m=1e-3)
    for sizes in ([500], [1, 0, 37, 500, 1234]):
        stream = OscillatorStream(RATE_HZ, effects=effects, integrator=integrator, x0_m=1e-3)
        parts, start, k = [], 0, 0
        while start < force.size:
            size = sizes[k % len(sizes)]
            x, v = stream.step(force[start : start + size])
            parts.append((x.copy(), v.copy()))
            start, k = start + size, k + 1
        np.testing.assert_array_equal(np.concatenate([p[0] for p in parts]), whole.displacement_m)
        np.testing.assert_array_equal(np.concatenate([p[1] for p in parts]), whole.velocity_m_s)
        assert stream.samples_done == force.size
        np.testing.assert_equal(stream.rest_time_s, whole.rest_time_s)
        np.testing.assert_equal(stream.rest_position_m, whole.rest_position_m)


def test_stream_reuses_its_buffers_and_fills_given_ones():
    stream = OscillatorStream(RATE_HZ)
    force = impact(duration_s=0.2)
    first = stream.step(force[:500])
    kept = first[1].copy()
    second = stream.step(force[500:1000])
    assert second[1] is not first[1] and np.shares_memory(first[1], second[1])
    assert not np.array_equal(first[1], kept)  # overwritten by the next batch, as documented
    out = (np.empty(500), np.empty(500))
    third = stream.step(force[1000:1500], out=out)
    assert third[0] is out[0] and third[1] is out[1]
    with pytest.raises(ValueError, match='out velocity buffer'):
        stream.step(force[:10], out=(np.empty(10), np.empty(9)))


def test_a_bad_batch_leaves_the_stream_as_it_was():
    force = impact(duration_s=0.5)
    stream = OscillatorStream(RATE_HZ)
    x1, v1 = (a.copy() for a in stream.step(force[:2000]))
    bad = force[2000:2500].copy()
    bad[17] = np.nan
    with pytest.raises(ValueError, match='force_n is not finite at sample 17'):
        stream.step(bad)
    assert stream.samples_done == 2000
    x2, v2 = stream.step(force[2000:])
    whole = simulate(force, RATE_HZ)
    np.testing.assert_array_equal(np.concatenate([v1, v2]), whole.velocity_m_s)


def test_rest_is_reported_only_when_the_mass_has_stopped():
    moving = simulate(impact(duration_s=0.5), RATE_HZ)
    assert not moving.at_rest and math.isnan(moving.rest_position_m)
    stopped = simulate(impact(duration_s=5.0), RATE_HZ)
    assert stopped.at_rest and 1.0 < stopped.rest_time_s < 5.0
    assert abs(stopped.rest_position_m) <= FMM_RIG.friction_limit_m(PAPER_MU)
    assert stopped.time_s[-1] == pytest.approx(5.0 - 1 / RATE_HZ)
    never = OscillatorStream(RATE_HZ)
    assert math.isnan(never.rest_position_m)


# --- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ('call', 'message'),
    [
        (
            lambda f: simulate(np.where(np.arange(f.size) == 5, np.inf, f), RATE_HZ),
            'force_n is not finite at sample 5',
        ),
        (lambda f: simulate(np.full(10, np.nan), RATE_HZ), 'force_n is not finite at sample 0'),
        (lambda f: simulate(f.reshape(2, -1), RATE_HZ), 'force_n must be one-dimensional'),
        (lambda f: simulate(f, RATE_HZ, mu=-0.1), 'mu must not be negative'),
        (lambda f: simulate(f, RATE_HZ, mu=math.nan), 'mu must be finite'),
        (lambda f: simulate(f, 0.0), 'sample_rate_hz must be positive'),
        (lambda f: simulate(f, 40.0), 'time step too coarse'),
        (lambda f: simulate(f, RATE_HZ, integrator='rk45'), "unknown integrator 'rk45'"),
        (lambda f: simulate(f, RATE_HZ, x0_m=math.inf), 'x0_m must be finite'),
        (lambda f: simulate(f, RATE_HZ, effects=('stribeck',)), 'effects must be model terms'),
        (
            lambda f: simulate(
                f, RATE_HZ, effects=(model_term('stribeck'), model_term('stribeck'))
            ),
            'model term stribeck given twice',
        ),
        (
            lambda f: simulate(
                f,
                RATE_HZ,
                mu=0.01,
                effects=(model_term('asymmetric_friction', mu_difference=0.05),),
            ),
            'makes a friction coefficient negative',
        ),
        (
            lambda f: simulate(f, 1000.0, effects=(model_term('second_mode', frequency_hz=600.0),)),
            'at or above the Nyquist frequency',
        ),
        (lambda f: OscillatorStream(FMM_RIG, mu=0.1), 'sample_rate_hz must be a number'),
        (lambda f: simulate(f, RATE_HZ, rig=(10.0, 2000.0)), 'rig must be a Rig'),
        (lambda f: free_vibration(1e-3, -1.0, RATE_HZ), 'duration_s must be positive'),
    ],
)
def test_bad_input_raises_a_value_error_naming_the_problem(call, message):
    with pytest.raises(ValueError, match=message):
        call(impact(duration_s=0.1))


def test_time_columns_must_be_uniform():
    t = np.arange(1000) / RATE_HZ
    assert time_base(t).sample_rate_hz == pytest.approx(RATE_HZ)
    assert time_base(t).jitter_max_s == pytest.approx(0.0, abs=1e-15)
    gap = np.delete(t, 500)
    with pytest.raises(ValueError, match='non-uniform time step: 0.0002 s between samples 499'):
        time_base(gap)
    with pytest.raises(ValueError, match='samples were dropped'):
        time_base(gap, rtol=None)
    with pytest.raises(ValueError, match='time_s goes backwards at data row 2'):
        time_base(t[::-1])
    with pytest.raises(ValueError, match='at least two samples'):
        time_base(t[:1])
    with pytest.raises(ValueError, match='not finite at sample 3'):
        time_base(np.where(np.arange(1000) == 3, np.nan, t))


def test_scattered_stamps_give_their_rate_and_jitter():
    t = np.arange(16_000) / 1600.0  # a PC clock's stamps of a 1.6 kHz record
    scatter = np.random.default_rng(0).uniform(-20e-6, 20e-6, t.size)
    clock = time_base(t + scatter, 'stamps', rtol=None)
    assert clock.sample_rate_hz == pytest.approx(1600.0, rel=1e-5)
    # steps of uniform +-20 us stamps: 20e-6 * sqrt(2 / 3) rms, at most 40 us
    assert clock.jitter_rms_s == pytest.approx(16.3e-6, rel=0.1)
    assert 30e-6 < clock.jitter_max_s < 40e-6
    assert 'jitter 16' in clock.describe()
    assert time_base(t).describe() == 'uniform steps'
    with pytest.raises(ValueError, match='non-uniform time step'):
        time_base(t + scatter)


def test_a_rest_at_the_band_edge_under_a_constant_force_breaks_away_at_once():
    """A rest entered at the band's edge, then a force constant over the next interval.

    Seen on a held-out `moreau` session at 25.6 kHz: the kernel located the
    break-away where g crossed the edge, (edge - g) / (g_end - g_now), and with the force
    constant g_now == g_end: numba raised ZeroDivisionError inside the diagnosis's fit. The
    rig is already at the edge, so it leaves at once.
    """
    mu, force_n = 0.14389866247302455, 4.484282481692489e-05
    plan = model._plan(25600.0, FMM_RIG, mu, (), 'exact')
    x, v, mode, rest_time, _, _ = _kernels._interval(
        -0.0004842975817639637,
        0.0,
        0,
        force_n,
        force_n,
        0.1198046875,
        0.11980468661864734,
        plan.params,
        0.0,
        math.nan,
    )
    assert mode == 1 and 0.0 < v < 1e-10 and math.isnan(rest_time)
    assert x == pytest.approx(-0.0004842975817639637, abs=1e-15)
