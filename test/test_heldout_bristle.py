"""The `bristle` held-out world (test/heldout/bristle.py) held to independent computation.

Its LuGre motion against `heldout.plant.solve_events` (lab's event-located DOP853 Coulomb
solver with the stick rule, code it does not share): the bristle world is a Coulomb world to
a few 1e-6 m/s, its pre-sliding far below what a vibrometer resolves, a stuck rig stays
stuck and does not creep. The pulse's area against quadrature; the chain's two exact methods
(partial fractions, first-order hold) against each other and against closed forms (the AC
coupling's step response, DC gains, the second mode against DOP853). How the diagnosis does
on it is measured by benchmarks/bench_diagnose.py (heldout-validation.md).
"""

import dataclasses
import math

import numpy as np
import pytest
import scipy.integrate
import scipy.signal
from heldout.bristle import (
    BRISTLE,
    BRISTLE_N_PER_M,
    DECODER_HZ,
    NORMAL_N,
    RATES_HZ,
    STIFFNESS_N_PER_M,
    Bristles,
    Chain,
    Pulse,
    Rig,
    ac_coupling,
    cascade,
    decoder,
    elliptic,
    exponential_response,
    held_filter,
    mode,
    move,
    resting_bristle,
)
from heldout.lab import Effects
from heldout.plant import solve_events
from heldout_contacts import MIXED_CONTACTS, as_event_hit

PULSE = Pulse(1000.0, 0.6e-3, 0.15e-3, 0.25 + 0.37e-4)
COULOMB_M_S = 5e-6
"""How close the LuGre motion stays to the Coulomb solution [m/s] (the noise is 1e-4)."""


def test_the_pulse_area_and_peak_are_its_closed_forms():
    area, _ = scipy.integrate.quad(
        lambda t: float(PULSE.force(t)), PULSE.onset_s, PULSE.onset_s + 0.1, limit=400
    )
    assert area == pytest.approx(PULSE.impulse_n_s, rel=1e-9)
    times = np.linspace(PULSE.onset_s, PULSE.onset_s + 3e-3, 300_001)
    assert PULSE.force(times).max() == pytest.approx(PULSE.peak_n, rel=1e-8)
    assert PULSE.force_at(PULSE.onset_s + 1e-3) == pytest.approx(
        float(PULSE.force(PULSE.onset_s + 1e-3)), rel=1e-14
    )
    assert PULSE.force_at(PULSE.onset_s - 1e-9) == 0.0


def pulse_hit(pulse: Pulse):
    """The pulse for lab's DOP853 event solver, cut where its force is 4e-18 of the peak."""
    end = pulse.onset_s + 40.0 * pulse.fall_s
    return as_event_hit(pulse.force_at, pulse.force, pulse.peak_n, pulse.onset_s, end)


@pytest.mark.slow
def test_its_motion_is_the_coulomb_motion_of_lab_dop853():
    """A stiff bristle's steady state is the Coulomb law with the stick rule: the LuGre BDF
    motion stays within COULOMB_M_S of lab's event-located DOP853 (0.05 of the velocity
    noise), rests within 1e-7 m of it, stops when it does (1 ms), deflects its bristles at
    most g / sigma0 (2e-12 m: a vibrometer resolves 1e-8 m), and creeps below 1e-7 m/s (1e-3
    of the noise) once stuck."""
    start = 1e-4
    times = np.linspace(0.24, 11.9, 80_001)
    for index, (effects, contact, plant) in enumerate(MIXED_CONTACTS):
        moved = move(Rig(Bristles(0.09, effects), PULSE), (start, 0.0), 12.0)
        exact = solve_events(plant, contact, pulse_hit(PULSE), start, 12.0)
        x, v, z = moved.state(times)
        assert np.abs(v - exact.evaluate(times)[1]).max() < COULOMB_M_S, effects
        assert moved.rest_m == pytest.approx(exact.rest_m, abs=1e-7)
        assert moved.still_s == pytest.approx(exact.rest_s, abs=1e-3)
        largest = NORMAL_N * (0.1 + effects.static_excess) * (1.0 + effects.track_amplitude)
        assert np.abs(z).max() <= largest / BRISTLE_N_PER_M < 2e-12
        assert np.abs(v[times > moved.still_s + 0.01]).max() < 1e-7
        # the velocity channel's area is the distance moved (its filters' DC gain is 1)
        rate = RATES_HZ[index]
        chain = Chain(rate, DECODER_HZ[index], 100.0, 0.0)
        speed = chain.velocity(
            lambda t, m=moved: m.state(t)[1],
            round(12.0 * rate),
            (PULSE.onset_s, moved.still_s + 0.02),
        )
        assert speed.sum() / rate == pytest.approx(moved.rest_m - start, abs=1e-9)


def test_a_stuck_rig_stays_stuck_at_the_edge_of_its_band():
    """From rest at 95 % of the band's half width (the bristles holding the spring), a push
    well below what breaks it loose moves it by no more than the bristles deflect (1e-12 m)
    and leaves it still: the stuck state is stable."""
    effects = Effects(static_excess=0.04)
    bristles = Bristles(0.1, effects)
    x = 0.95 * bristles.holding_n(-1.0, 0.0) / STIFFNESS_N_PER_M
    push = Pulse(0.02, 0.6e-3, 0.15e-3, 0.25)
    moved = move(Rig(bristles, push), (x, resting_bristle(effects, x)), 2.0)
    positions, velocities, _ = moved.state(np.linspace(0.25, 2.0, 20_001))
    assert np.abs(positions - x).max() < 1e-12
    assert np.abs(velocities).max() < 1e-8
    assert abs(moved.rest_m - x) < 1e-12


def test_the_ac_coupling_steps_down_with_its_discharge_time_constant():
    """A unit force step through a first-order high-pass of time constant tau: e^(-t/tau)."""
    u = np.linspace(0.0, 500.0, 1001)
    response = exponential_response(ac_coupling(120.0), ((1.0, 0.0),), u)
    assert response == pytest.approx(np.exp(-u / 120.0), abs=1e-12)
    assert exponential_response(ac_coupling(120.0), ((1.0, 0.0),), np.array([-1.0]))[0] == 0.0


def held_ramp_error_bound(filt: tuple[np.ndarray, np.ndarray, float], step_s: float) -> float:
    """How far a unit ramp through `held_filter(filt, step_s)` may stray from the exact
    response [s], from the rounding of the held filter's own poles.

    The hold is exact in exact arithmetic; in floating point its poles come from the
    eigenvalues of a discretised companion-form state space (coefficients up to 1e30), and
    they miss the exact exp(p dt) by delta_i, about 1e-5, as the BLAS happens to round. The
    ramp's response is its steady part plus one mode c_i z_i^n per pole, where c_i = r_i/p_i^2
    (r_i the analog residue). To first order a pole off by delta_i moves its mode by
    |c_i| n |z_i|^(n-1) delta_i <= |c_i| delta_i / (e (1 - |z_i|)), and the mode's weight moves
    with the poles by about as much again, hence the factor 2. The expansion holds while
    every delta_i is small against its pole's decay per step 1 - |z_i|, which is checked.
    """
    zeros, poles, gain = filt
    exact = np.exp(poles * step_s)
    _, held_poles, _ = scipy.signal.sos2zpk(held_filter(filt, step_s))
    delta = np.array([np.abs(held_poles - z).min() for z in exact])
    decay = 1.0 - np.abs(exact)
    assert np.all(delta < 0.1 * decay), (delta, decay)
    residues = np.array(
        [gain * np.prod(p - zeros) / np.prod(np.delete(p - poles, i)) for i, p in enumerate(poles)]
    )
    return float(2.0 * np.sum(np.abs(residues / poles**2) * delta / (math.e * decay)))


@pytest.mark.parametrize('rate_hz', RATES_HZ)
def test_both_exact_filter_methods_agree_with_lsim(rate_hz):
    """The velocity path's first-order-hold discretisation and the force path's partial
    fractions are two exact ways of running an analog filter; scipy's `lsim` (matrix
    exponentials, the input linear between points) is a third: a ramp through the held
    filter and a step through the partial fractions match it at every point, and the
    filters pass DC unchanged.

    `lsim` meets the ramp's closed form to 1e-15 here, so the ramp's tolerance is the held
    filter's own rounding (`held_ramp_error_bound`, 2e-9 to 2e-8 s): a hold of the wrong
    order stays far outside it (a zero-order hold lags half a step, 3e-6 to 7e-6 s).
    """
    filt = cascade(decoder(5_000.0), elliptic(rate_hz))
    step = 1.0 / (8.0 * rate_hz)
    grid = np.arange(3000) * step
    system = scipy.signal.lti(*filt)
    _, ramp, _ = scipy.signal.lsim(system, grid, grid)
    held = scipy.signal.sosfilt(held_filter(filt, step), grid)
    assert np.abs(held - ramp).max() < held_ramp_error_bound(filt, step)
    _, stepped, _ = scipy.signal.lsim(system, np.ones(grid.size), grid)
    exact = exponential_response(filt, ((1.0, 0.0),), grid)
    assert np.abs(exact - stepped).max() < 1e-9
    assert exact[-1] == pytest.approx(1.0, abs=1e-6)
    settled = exponential_response(elliptic(rate_hz), ((1.0, 0.0),), np.array([0.05]))[0]
    assert settled == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize('rate_hz', RATES_HZ)
def test_the_force_channel_keeps_the_impulse_without_its_coupling(rate_hz):
    """With a discharge time constant far beyond the record the force samples' area is the
    pulse's impulse (the elliptic filter's DC gain is 1); with 60 s it loses the share the
    coupling's tail takes by the record's end, 1 - e^(-T/tau) less the tail after it."""
    samples = round(12.0 * rate_hz)
    for tau, kept in ((1e12, 1.0), (60.0, math.exp(-(12.0 - PULSE.onset_s) / 60.0))):
        chain = Chain(rate_hz, 10_000.0, tau, 0.0)
        force = chain.force(PULSE, samples)
        assert force.sum() / rate_hz == pytest.approx(PULSE.impulse_n_s * kept, rel=2e-4)
        assert force[: round(PULSE.onset_s * rate_hz)] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize('decoder_hz', DECODER_HZ)
def test_the_channels_are_not_delayed_against_each_other(decoder_hz):
    """The same pulse through both channels: the decoder's stated delay taken off, the
    velocity path's centroid is the force path's (both through the elliptic filter) within
    0.2 us, where the decoder alone would delay it 11-43 us."""
    rate = 10_000.0
    chain = Chain(rate, decoder_hz, 1e12, 0.0)
    samples = round(0.4 * rate)
    force = chain.force(PULSE, samples)
    through = chain.velocity(PULSE.force, samples, (PULSE.onset_s, 0.3))
    times = np.arange(samples) / rate

    def centroid(values: np.ndarray) -> float:
        return float(np.sum(times * values) / np.sum(values))

    assert chain.decoder_delay_s > 1e-5
    assert abs(centroid(through) - centroid(force)) < 2e-7


def test_the_second_mode_is_its_ode_under_the_pulse():
    """The mode's exact velocity by partial fractions against DOP853 of m2 y'' + c2 y' + k2 y
    = f(t)."""
    effects = Effects(mode_hz=120.0, mode_damping_ratio=0.01, mode_mass_kg=500.0)
    omega, mass = 2.0 * math.pi * 120.0, 500.0

    def rhs(t, s):
        return (
            s[1],
            (PULSE.force_at(t) - 2.0 * 0.01 * omega * mass * s[1] - omega**2 * mass * s[0]) / mass,
        )

    times = PULSE.onset_s + np.linspace(0.0, 0.2, 4001)
    run = scipy.integrate.solve_ivp(
        rhs,
        (PULSE.onset_s, times[-1]),
        (0.0, 0.0),
        method='DOP853',
        rtol=1e-12,
        atol=1e-16,
        t_eval=times,
    )
    exact = exponential_response(mode(effects), PULSE.exponentials, times - PULSE.onset_s)
    assert np.abs(exact - run.y[1]).max() < 1e-9 * np.abs(run.y[1]).max()


@pytest.mark.slow
def test_sessions_start_in_the_band_or_where_the_last_hit_left():
    world = dataclasses.replace(BRISTLE, duration_s=4.0)
    rng = np.random.default_rng(5)
    effects = Effects()
    records = world.session(effects, 0.1, rng, (450.0, 1450.0))
    half_width = 0.1 * NORMAL_N / STIFFNESS_N_PER_M
    assert len({r.sample_rate_hz for r in records}) == 1
    assert records[0].sample_rate_hz in RATES_HZ
    assert all(r.force_n.size == round(4.0 * r.sample_rate_hz) for r in records)
    assert all(0.0 < abs(r.start_m) <= 0.95 * half_width for r in records)
    centred = world.session(effects, 0.1, rng, (450.0,), centred=True)
    assert [r.start_m for r in centred] == [0.0]
    chained = world.session(effects, 0.1, rng, (1000.0, 450.0), chained=True)
    assert chained[0].start_m == 0.0
    assert [r.start_m for r in chained[1:]] == [r.rest_m for r in chained[:-1]]
