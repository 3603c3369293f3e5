"""The `karnopp` held-out world (test/heldout/karnopp.py) held to independent computation.

Its RK4 and Karnopp motion against `heldout.plant.solve_events` (lab's event-located DOP853
Coulomb solver with the stick rule, code it does not share) driven by the contact force the
world computed: the same velocity to a few 1e-6 m/s (the noise is 1e-4; the error is the
Karnopp window's, first order in it), the same rest and stop; a breakaway in the middle of a
hit and a stick that holds exactly; halving the steps changes little. The Hunt-Crossley
hammer against solve_ivp of the hammer on a rigid target, its impulse against quadrature of
its force; the Bessel filter against `scipy.signal.freqs` of its analog prototype; the second
mode against DOP853. How the diagnosis does on it is measured by benchmarks/bench_diagnose.py.
"""

import dataclasses
import math

import numpy as np
import pytest
import scipy.integrate
import scipy.interpolate
import scipy.signal
from heldout.karnopp import (
    CONTACT_S,
    KARNOPP,
    NORMAL_N,
    PRETRIGGER_S,
    RATES_HZ,
    SUBSTEPS,
    Chain,
    Hammer,
    Rig,
    analog,
    bessel,
    first_order_hold,
    hammer_for,
    move,
    random_hammer,
)
from heldout.lab import Effects
from heldout.plant import Contact, Plant, solve_events
from heldout_contacts import MIXED_CONTACTS, as_event_hit

HAMMER = hammer_for(1000.0, 0.2, 0.7, 1e-3, PRETRIGGER_S + 0.37e-4)
CHAIN = Chain(10_000.0, 4500.0, 3e-6, 0.0, 0.2)
COULOMB_M_S = 5e-6
"""How close the Karnopp motion stays to DOP853's [m/s] (it is 2e-6; the noise is 1e-4)."""


def strike_hit(strike):
    """The contact force the world computed (a cubic spline through its steps) as a hit for
    lab's DOP853 event solver."""
    spline = scipy.interpolate.CubicSpline(strike.times_s, strike.force_n)
    first, end = float(strike.times_s[0]), strike.end_s

    def force(t):
        t = np.asarray(t, dtype=float)
        return np.where((t >= first) & (t <= end), spline(np.clip(t, first, end)), 0.0)

    return as_event_hit(lambda t: float(force(t)), force, strike.peak_n, first, end)


@pytest.mark.slow
def test_its_motion_is_the_coulomb_motion_of_lab_dop853():
    """RK4 with Karnopp's window against the event-located DOP853 under the same force:
    within COULOMB_M_S, positions within 5e-7 m, rests within 1e-9 m (it is 4e-11), stops
    within 5e-5 s (1e-5); the error is the window's (dv / |a| of friction turned early at
    each reversal): halving the window halves it. The velocity channel's area is the
    distance moved."""
    start = 1e-4
    for index, (effects, contact, plant) in enumerate(MIXED_CONTACTS):
        chain = dataclasses.replace(CHAIN, rate_hz=RATES_HZ[index % 2])
        moved = move(Rig(0.09, effects), HAMMER, start, chain, 3.0, keep=8)
        exact = solve_events(plant, contact, strike_hit(moved.strike), start, 3.0)
        times, x, v = moved.trace[:, 0], moved.trace[:, 1], moved.trace[:, 2]
        exact_x, exact_v = exact.evaluate(times)
        assert np.abs(v - exact_v).max() < COULOMB_M_S, effects
        assert np.abs(x - exact_x).max() < 5e-7, effects
        assert moved.rest_m == pytest.approx(exact.rest_m, abs=1e-9)
        assert moved.rest_s == pytest.approx(exact.rest_s, abs=5e-5)
        area = moved.velocity_m_s.sum() / chain.rate_hz
        assert area == pytest.approx(moved.rest_m - start, abs=1e-9)
    effects, contact, plant = MIXED_CONTACTS[1]
    errors = []
    for window in (1e-6, 0.5e-6):
        moved = move(Rig(0.09, effects, window), HAMMER, start, CHAIN, 3.0, keep=8)
        exact = solve_events(plant, contact, strike_hit(moved.strike), start, 3.0)
        errors.append(np.abs(moved.trace[:, 2] - exact.evaluate(moved.trace[:, 0])[1]).max())
    assert 0.3 < errors[1] / errors[0] < 0.7


@pytest.mark.slow
def test_halving_the_steps_changes_little():
    """RK4 resolves the hit and the swing far below the noise; Karnopp's stops fall on a
    step, so the stop moves by up to a step and the motion after it by its first-order
    error: halving every step moves the velocity channel by under 5e-7 m/s (it is 2e-7),
    the force channel by under 5e-3 N (1e-3), the rest by under 1e-9 m, the stop by under
    a coarse step."""
    effects, _, _ = MIXED_CONTACTS[1]
    coarse = move(Rig(0.09, effects), HAMMER, 1e-4, CHAIN, 2.5)
    fine = move(Rig(0.09, effects), HAMMER, 1e-4, CHAIN, 2.5, refine=2)
    assert np.abs(coarse.velocity_m_s - fine.velocity_m_s).max() < 5e-7
    assert np.abs(coarse.force_n - fine.force_n).max() < 5e-3
    assert abs(coarse.rest_m - fine.rest_m) < 1e-9
    assert abs(coarse.rest_s - fine.rest_s) < 1.01 / (CHAIN.rate_hz * CHAIN.cells)


def test_a_stuck_rig_stays_stuck_and_breaks_away_where_dop853_does():
    """From rest at 95 % of the band's half width a tap well inside the static limit leaves
    the rig exactly where it was, at rest throughout; a 2 N push the other way breaks it
    loose in the middle of the hit (in the grid cell where DOP853 finds it), and the motion is
    DOP853's under the same force; once stuck it stays exactly at rest."""
    effects = Effects(static_excess=0.04)
    rig = Rig(0.1, effects)
    x = 0.95 * rig.half_band_m()
    tap = hammer_for(0.02, 0.2, 0.7, 1e-3, 0.4)
    held = move(rig, tap, x, CHAIN, 0.6, keep=4)
    assert np.all(held.trace[:, 1] == x) and np.all(held.trace[:, 2] == 0.0)
    assert held.rest_m == x and held.rest_s <= tap.onset_s
    push = hammer_for(2.0, 0.2, 0.7, 3e-3, 0.4)
    moved = move(rig, push, x, CHAIN, 1.5, keep=1)
    hit = strike_hit(moved.strike)
    exact = solve_events(Plant(), Contact(0.1, static_excess=0.04), hit, x, 1.5)
    first = exact.pieces[1][0] if exact.pieces[0][2] == 'rest' else exact.pieces[0][0]
    assert push.onset_s + 0.2 * push.contact_s < first < moved.strike.end_s
    times, v = moved.trace[:, 0], moved.trace[:, 2]
    loose = times[np.flatnonzero(v != 0.0)[0]]
    cell = 1.0 / (CHAIN.rate_hz * CHAIN.cells)
    assert first < loose < first + 1.01 * cell
    assert np.abs(v - exact.evaluate(times)[1]).max() < COULOMB_M_S
    assert moved.rest_m == pytest.approx(exact.rest_m, abs=1e-9)
    after = times > moved.rest_s
    assert np.all(moved.trace[after, 1] == moved.rest_m) and np.all(v[after] == 0.0)


def _rigid_target(hammer: Hammer):
    """solve_ivp (DOP853) of m_r d'' = -K d^1.5 (1 + 1.5 (1 - e) d' / V0), d = 0, d' = V0,
    to where d returns to zero: (contact time, peak force, rebound speed)."""
    m, k = hammer.reduced_kg, hammer.stiffness_n_per_m1_5
    alpha = 1.5 * (1.0 - hammer.restitution) / hammer.speed_m_s

    def push(s):
        return k * max(s[0], 0.0) ** 1.5 * (1.0 + alpha * s[1])

    def released(u, s):
        return s[0]

    released.terminal, released.direction = True, -1
    run = scipy.integrate.solve_ivp(
        lambda u, s: (s[1], -push(s) / m),
        (0.0, 1.0),
        (0.0, hammer.speed_m_s),
        method='DOP853',
        rtol=1e-12,
        atol=1e-16,
        events=released,
        dense_output=True,
    )
    end = float(run.t_events[0][0])
    u = np.linspace(0.0, end, 20_001)
    peak = max(push(s) for s in run.sol(u).T)
    return end, peak, float(run.y_events[0][0][1])


@pytest.mark.parametrize(
    ('level', 'mass', 'restitution', 'contact'),
    [(1000.0, 0.2, 0.7, 1e-3), (450.0, 0.1, 0.9, CONTACT_S[0]), (1450.0, 0.3, 0.5, CONTACT_S[1])],
    ids=['1 ms', 'short', 'long'],
)
def test_the_hunt_crossley_hammer_is_its_own_equation(level, mass, restitution, contact):
    """The design (a dimensionless RK4 run, scaled) against solve_ivp of the hammer on a
    rigid target of the reduced mass: contact time and peak within 1e-6. On the moving,
    sprung, rubbing rig the contact lasts and peaks within 1e-3 of that; the impulse
    m_h (V0 - V_after) is the quadrature of the force at the steps (1e-6), and the rebound
    is slower than the impact (0 < e' < 1)."""
    hammer = hammer_for(level, mass, restitution, contact, PRETRIGGER_S + 0.37e-4)
    end, peak, rebound = _rigid_target(hammer)
    assert hammer.contact_s == pytest.approx(contact, rel=1e-9)
    assert end == pytest.approx(contact, rel=1e-6)
    assert peak == pytest.approx(level, rel=1e-6)
    assert -hammer.speed_m_s < rebound < 0.0
    strike = move(Rig(0.12, Effects()), hammer, 0.0, CHAIN, 0.45).strike
    assert strike.peak_n == pytest.approx(level, rel=1e-3)
    assert strike.end_s - strike.onset_s == pytest.approx(contact, rel=1e-3)
    area = np.trapezoid(strike.force_n, strike.times_s)
    assert strike.impulse_n_s == pytest.approx(area, rel=1e-6)


def test_random_hammers_peak_within_3_percent_of_their_level():
    rng = np.random.default_rng(3)
    for level in (450.0, 1000.0, 1450.0):
        for _ in range(2):
            hammer = random_hammer(rng, level, PRETRIGGER_S)
            strike = move(Rig(0.1, Effects()), hammer, 0.0, CHAIN, 0.42).strike
            assert abs(strike.peak_n / level - 1.0) < 0.03
            contact = strike.end_s - strike.onset_s
            assert 0.99 * CONTACT_S[0] < contact < 1.01 * CONTACT_S[1]
            assert 0.1 <= hammer.mass_kg <= 0.3 and 0.5 <= hammer.restitution <= 0.9


@pytest.mark.parametrize('rate_hz', RATES_HZ)
def test_the_bessel_filter_is_its_analog_prototype(rate_hz):
    """The first-order-hold state space at the force's step (a third of a grid cell) and
    the velocity's (a cell): DC gain 1, and up to 0.3 of the rate the analog prototype's
    response times the hold's sinc^2 droop within 1e-5 (the prototype within 5e-4: the droop
    (pi f h)^2 / 3 is 2e-4 there); -3 dB at 0.4 of the rate. The velocity's adds the
    tracking low-pass's 1 / (1 + j f / f_t)."""
    chain = Chain(rate_hz, 3000.0, 2e-6, 0.0, 0.2)
    cell = 1.0 / (rate_hz * chain.cells)
    f = np.linspace(1.0, 0.3 * rate_hz, 2001)
    _, prototype = scipy.signal.freqs_zpk(*bessel(rate_hz), 2.0 * math.pi * f)
    _, corner = scipy.signal.freqs_zpk(*bessel(rate_hz), [2.0 * math.pi * 0.4 * rate_hz])
    assert abs(corner[0]) == pytest.approx(math.sqrt(0.5), rel=1e-9)
    tracking = 1.0 / (1.0 + 1j * f / chain.tracking_hz)
    for step, system, analog_response in (
        (cell / SUBSTEPS, analog(rate_hz), prototype),
        (cell, analog(rate_hz, chain.tracking_hz), prototype * tracking),
    ):
        ad, bd, cd, dd = first_order_hold(system, step)
        z = np.exp(2j * math.pi * f * step)
        digital = np.array(
            [cd @ np.linalg.solve(zk * np.eye(ad.shape[0]) - ad, bd) + dd[0] for zk in z]
        )
        assert abs(cd @ np.linalg.solve(np.eye(ad.shape[0]) - ad, bd) + dd[0]) == pytest.approx(
            1.0, abs=1e-12
        )
        droop = np.sinc(f * step) ** 2
        assert np.abs(digital - analog_response * droop).max() < 1e-5
        assert np.abs(digital - analog_response).max() < 5e-4


@pytest.mark.slow
def test_the_second_mode_is_its_ode_under_the_contact_force():
    """The mode stepped in the loop against DOP853 of m2 y'' + c2 y' + k2 y = F(t) under the
    force the world computed, then ringing freely: within 1e-6 of its largest velocity."""
    effects = Effects(mode_hz=120.0, mode_damping_ratio=0.01, mode_mass_kg=500.0)
    moved = move(Rig(0.09, effects), HAMMER, 0.0, CHAIN, 0.6, keep=4)
    hit = strike_hit(moved.strike)
    omega, mass = 2.0 * math.pi * 120.0, 500.0

    def rhs(t, s):
        return (s[1], hit.force_at(t) / mass - 2.0 * 0.01 * omega * s[1] - omega**2 * s[0])

    times = moved.trace[:, 0]
    spans = ((times[0], hit.end_s), (hit.end_s, times[-1]))
    state, exact = (0.0, 0.0), np.zeros((2, times.size))
    for low, high in spans:
        run = scipy.integrate.solve_ivp(
            rhs, (low, high), state, method='DOP853', rtol=1e-12, atol=1e-18, dense_output=True
        )
        inside = (times >= low) & (times <= high)
        exact[:, inside] = run.sol(times[inside])
        state = run.y[:, -1]
    largest = np.abs(exact[1]).max()
    assert np.abs(moved.trace[:, 4] - exact[1]).max() < 1e-6 * largest
    assert np.abs(moved.trace[:, 3] - exact[0]).max() < 1e-6 * np.abs(exact[0]).max()


@pytest.mark.slow
def test_sessions_start_in_the_band_or_where_the_last_hit_left():
    world = dataclasses.replace(KARNOPP, duration_s=2.0)
    rng = np.random.default_rng(5)
    effects = Effects()
    records = world.session(effects, 0.1, rng, (450.0, 1450.0))
    half_width = 0.1 * NORMAL_N / 1982.0
    assert len({r.sample_rate_hz for r in records}) == 1
    assert records[0].sample_rate_hz in RATES_HZ
    assert all(
        r.force_n.size == r.velocity_m_s.size == round(2.0 * r.sample_rate_hz) for r in records
    )
    assert all(0.0 < abs(r.start_m) <= 0.9 * half_width for r in records)
    assert all(
        PRETRIGGER_S <= r.pulse.onset_s < PRETRIGGER_S + 1.0 / r.sample_rate_hz for r in records
    )
    assert all(
        abs(r.pulse.peak_n / level - 1.0) < 0.03
        for r, level in zip(records, (450, 1450), strict=True)
    )
    centred = world.session(effects, 0.1, rng, (450.0,), centred=True)
    assert [r.start_m for r in centred] == [0.0]
    chained = world.session(effects, 0.1, rng, (1000.0, 450.0), chained=True)
    assert chained[0].start_m == 0.0
    assert [r.start_m for r in chained[1:]] == [r.rest_m for r in chained[:-1]]
    drifting = world.session(Effects(mu_step=0.05), 0.1, rng, (450.0, 1000.0), centred=True)
    assert [r.mu for r in drifting] == pytest.approx([0.1, 0.105])
