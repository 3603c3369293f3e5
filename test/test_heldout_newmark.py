"""The `newmark` held-out world (test/heldout/newmark.py) held to independent computation.

Its Newmark-beta motion against `heldout.plant.solve_events` (lab's event-located DOP853
Coulomb solver with the stick rule, code it does not share): the same velocity to a few
1e-8 m/s (the noise is 1e-4), the same rest and stop, a breakaway in the middle of a hit
where DOP853 finds it, and halving the steps changes little. The Kelvin-Voigt hammer's
closed forms against DOP853 of the hammer's own equation, quadrature and dense sampling; the
bilinear filter against `scipy.signal.freqs_zpk` of its analog prototype; the second mode
against DOP853. How the diagnosis does on it is measured by benchmarks/bench_diagnose.py
(heldout-validation.md).
"""

import dataclasses
import math

import numpy as np
import pytest
import scipy.integrate
import scipy.signal
from heldout.lab import Effects
from heldout.newmark import (
    COARSE_STEP_S,
    CONTACT_S,
    FINE_STEP_S,
    NEWMARK,
    NORMAL_N,
    OVERSAMPLE,
    PRETRIGGER_S,
    RATES_HZ,
    STIFFNESS_N_PER_M,
    Chain,
    Hammer,
    Rig,
    chebyshev,
    floor_noise,
    hammer_for,
    mode_response,
    move,
    random_hammer,
    tustin,
)
from heldout.plant import Contact, Plant, solve_events
from heldout_contacts import MIXED_CONTACTS, as_event_hit

HAMMER = hammer_for(1000.0, 0.2, 0.12, 1e-3, PRETRIGGER_S + 0.37e-4)
HAMMERS = (
    HAMMER,
    hammer_for(450.0, 0.1, 0.05, CONTACT_S[0], 0.4),
    hammer_for(1450.0, 0.3, 0.2, CONTACT_S[1], 0.4),
)
COULOMB_M_S = 1e-6
"""How close the Newmark motion stays to DOP853's [m/s] (the noise is 1e-4)."""


def _hammer_ode(hammer: Hammer):
    """DOP853 of m_h d'' + c_t d' + k_t d = 0 from d = 0, d' = V, to where k_t d + c_t d'
    returns to zero: (contact time, rebound speed d' there, dense solution)."""
    m, k, c = hammer.mass_kg, hammer.stiffness_n_per_m, hammer.damping_n_s_per_m

    def released(u, s):
        return k * s[0] + c * s[1]

    released.terminal, released.direction = True, -1
    run = scipy.integrate.solve_ivp(
        lambda u, s: (s[1], -(k * s[0] + c * s[1]) / m),
        (0.0, 1.0),
        (0.0, hammer.speed_m_s),
        method='DOP853',
        rtol=1e-13,
        atol=1e-18,
        events=released,
        dense_output=True,
    )
    return float(run.t_events[0][0]), float(run.y_events[0][0][1]), run.sol


@pytest.mark.parametrize('hammer', HAMMERS, ids=['1 ms', 'short', 'long'])
def test_the_hammer_tip_is_its_own_equation_in_closed_form(hammer):
    """Contact time and rebound against DOP853 of the hammer's ODE (its release an event);
    the force k_t d + c_t d' against that solution; the impulse m_h (V - d'(T)) against
    quadrature of the force; the peak against dense sampling; the force jumps to c_t V at the
    touch and the contact lasts as drawn."""
    contact, rebound, dense = _hammer_ode(hammer)
    assert hammer.contact_s == pytest.approx(contact, rel=1e-10)
    assert rebound < 0.0
    assert hammer.impulse_n_s == pytest.approx(hammer.mass_kg * (hammer.speed_m_s - rebound))
    u = np.linspace(0.0, contact, 2001)
    d, speed = dense(u)
    on_target = hammer.stiffness_n_per_m * d + hammer.damping_n_s_per_m * speed
    assert np.abs(hammer.force(hammer.onset_s + u) - on_target).max() < 1e-9 * hammer.peak_n
    area, _ = scipy.integrate.quad(hammer.force_at, hammer.onset_s, hammer.end_s, limit=200)
    assert area == pytest.approx(hammer.impulse_n_s, rel=1e-10)
    half, _ = scipy.integrate.quad(hammer.force_at, hammer.onset_s, hammer.onset_s + contact / 2)
    assert float(hammer.impulse_until(hammer.onset_s + contact / 2)) == pytest.approx(half)
    assert float(hammer.impulse_until(hammer.end_s + 1.0)) == hammer.impulse_n_s
    assert float(hammer.impulse_until(hammer.onset_s - 1.0)) == 0.0
    times = hammer.onset_s + np.linspace(0.0, contact, 400_001)
    assert hammer.force(times).max() == pytest.approx(hammer.peak_n, rel=1e-9)
    assert hammer.force_at(hammer.onset_s) == pytest.approx(
        hammer.damping_n_s_per_m * hammer.speed_m_s, rel=1e-12
    )
    assert hammer.force_at(hammer.onset_s - 1e-9) == 0.0
    assert hammer.force_at(hammer.end_s + 1e-9) == 0.0


def test_random_hammers_peak_within_3_percent_of_their_level():
    rng = np.random.default_rng(3)
    for level in (450.0, 1000.0, 1450.0):
        for _ in range(50):
            hammer = random_hammer(rng, level, 0.4)
            assert abs(hammer.peak_n / level - 1.0) <= 0.03 + 1e-12
            assert CONTACT_S[0] - 1e-15 <= hammer.contact_s <= CONTACT_S[1] + 1e-15
            assert 0.05 <= hammer.zeta <= 0.2 and 0.1 <= hammer.mass_kg <= 0.3


def hammer_hit(hammer: Hammer):
    """The hammer's force for lab's DOP853 event solver."""
    return as_event_hit(hammer.force_at, hammer.force, hammer.peak_n, hammer.onset_s, hammer.end_s)


@pytest.mark.slow
def test_its_motion_is_the_coulomb_motion_of_lab_dop853():
    """Newmark with Newton and the located stop against the event-located DOP853: within
    COULOMB_M_S (1e-2 of the velocity noise; it is 2e-8 m/s), rests within 1e-8 m of it,
    stops when it does (10 us); the velocity channel's area is the distance moved."""
    start = 1e-4
    times = np.linspace(PRETRIGGER_S - 0.01, 11.9, 100_001)
    for index, (effects, contact, plant) in enumerate(MIXED_CONTACTS):
        moved = move(Rig(0.09, effects), HAMMER, start, 12.0)
        exact = solve_events(plant, contact, hammer_hit(HAMMER), start, 12.0)
        x, v = moved.state(times)
        exact_x, exact_v = exact.evaluate(times)
        assert np.abs(v - exact_v).max() < COULOMB_M_S, effects
        assert np.abs(x - exact_x).max() < 1e-8, effects
        assert moved.rest_m == pytest.approx(exact.rest_m, abs=1e-8)
        assert moved.rest_s == pytest.approx(exact.rest_s, abs=1e-5)
        rate = RATES_HZ[index % 2]
        chain = Chain(rate, 0.0, 10.0, 10.0, 2.0, 0.3)
        speed = chain.filtered(
            lambda t, m=moved: m.state(t)[0] - start,
            round(12.0 * rate),
            (HAMMER.onset_s, moved.rest_s + 0.05),
        )
        assert speed.sum() / rate == pytest.approx(moved.rest_m - start, abs=1e-9)


def test_a_reversal_at_a_step_boundary_is_judged_by_the_stick_rule():
    """A 1450 N hit of a bench sweep (seed 2021, velocity_offset case 13, its third hit):
    one reversal fell where a step began, the velocity a hair short of zero. The loop took it
    for a slide that could not start and, the hammer gone, for the final rest: the rig stuck
    at 1.43 mm, where the spring pulls 3.2 times what friction can hold, and its motion
    ended 0.46 s early. The stick rule now decides there, as at every other velocity zero:
    rest and stop where DOP853 has them."""
    hammer = Hammer(
        0.27284767883836, 1495.94202157187, 0.122866201001119, 2.8162334675151, 0.40003689772850
    )
    start, mu = -3.906967657803393e-4, 0.13167003858195536
    moved = move(Rig(mu, Effects()), hammer, start, 12.0)
    exact = solve_events(Plant(), Contact(mu), hammer_hit(hammer), start, 12.0)
    assert moved.rest_m == pytest.approx(exact.rest_m, abs=1e-8)
    assert moved.rest_s == pytest.approx(exact.rest_s, abs=1e-5)
    assert STIFFNESS_N_PER_M * abs(moved.rest_m) <= NORMAL_N * mu


def test_halving_the_steps_changes_little():
    """Newmark average acceleration is second order: halving both steps moves the velocity by
    under 1e-7 m/s (1e-3 of the noise) and the rest by under 1e-9 m."""
    effects, _, _ = MIXED_CONTACTS[1]
    times = np.linspace(PRETRIGGER_S, 8.0, 40_001)
    coarse = move(Rig(0.09, effects), HAMMER, 1e-4, 8.0)
    fine = move(Rig(0.09, effects), HAMMER, 1e-4, 8.0, FINE_STEP_S / 2, COARSE_STEP_S / 2)
    assert np.abs(coarse.state(times)[1] - fine.state(times)[1]).max() < 1e-7
    assert abs(coarse.rest_m - fine.rest_m) < 1e-9


def test_a_stuck_rig_stays_stuck_and_breaks_away_where_dop853_does():
    """From rest at 95 % of the band's half width a tap well inside the static limit leaves
    the rig exactly where it was; a push of 2 N the other way breaks it loose during the hit,
    the breakaway bisected within a step, and the motion is DOP853's."""
    effects = Effects(static_excess=0.04)
    rig = Rig(0.1, effects)
    x = 0.95 * rig.half_band_m()
    tap = hammer_for(0.02, 0.2, 0.1, 1e-3, 0.4)
    held = move(rig, tap, x, 2.0)
    assert np.all(held.positions_m == x) and np.all(held.velocities_m_s == 0.0)
    assert held.rest_m == x and held.rest_s == pytest.approx(tap.end_s)
    push = hammer_for(2.0, 0.2, 0.1, 3e-3, 0.4)
    moved = move(rig, push, x, 2.0)
    exact = solve_events(Plant(), Contact(0.1, static_excess=0.04), hammer_hit(push), x, 2.0)
    first = exact.pieces[1][0] if exact.pieces[0][2] == 'rest' else exact.pieces[0][0]
    assert push.onset_s < first < push.end_s
    times = np.linspace(0.39, 1.9, 30_001)
    assert np.abs(moved.state(times)[1] - exact.evaluate(times)[1]).max() < 1e-8
    assert moved.rest_m == pytest.approx(exact.rest_m, abs=1e-10)


@pytest.mark.parametrize('rate_hz', RATES_HZ)
def test_the_bilinear_filter_is_its_analog_prototype(rate_hz):
    """DC gain 1; at every frequency the discretised filter is the prewarped prototype at the
    bilinear map's frequency 2 F tan(pi f / F) (to rounding); at the Nyquist frequency (the
    stopband edge, where the prewarping pins it) it is the prototype's -60 dB; up to 0.2 of
    the rate (the -3 dB corner is at 0.26) it is the prototype within 1e-3 in magnitude and
    2 us in group delay (120-200 us; the prewarping scales frequency by 0.3 %)."""
    sos = tustin(rate_hz)
    zeros, poles, gain = scipy.signal.sos2zpk(sos)
    assert abs(gain * np.prod(1.0 - zeros) / np.prod(1.0 - poles) - 1.0) < 1e-12
    fine = OVERSAMPLE * rate_hz
    f = np.linspace(1.0, rate_hz / 2.0, 4001)
    _, digital = scipy.signal.sosfreqz(sos, worN=f, fs=fine)
    warped_edge = fine / math.pi * math.tan(math.pi * rate_hz / 2.0 / fine)
    _, warped = scipy.signal.freqs_zpk(
        *chebyshev(rate_hz, warped_edge), 2.0 * fine * np.tan(math.pi * f / fine)
    )
    assert np.abs(digital - warped).max() < 1e-10
    _, analog = scipy.signal.freqs_zpk(*chebyshev(rate_hz), 2.0 * math.pi * f)
    assert abs(digital[-1]) == pytest.approx(abs(analog[-1]), rel=1e-9)
    assert abs(analog[-1]) == pytest.approx(10 ** (-60.0 / 20.0), rel=1e-9)
    assert abs(analog[0]) == pytest.approx(1.0, abs=1e-9)
    band = f < 0.2 * rate_hz
    assert np.abs(np.abs(digital[band]) - np.abs(analog[band])).max() < 1e-3
    step = 2.0 * math.pi * (f[1] - f[0])
    delay_digital = -np.diff(np.unwrap(np.angle(digital[band]))) / step
    delay_analog = -np.diff(np.unwrap(np.angle(analog[band]))) / step
    assert np.abs(delay_digital - delay_analog).max() < 2e-6


@pytest.mark.parametrize('rate_hz', RATES_HZ)
def test_the_force_channel_keeps_the_impulse(rate_hz):
    """The samples' area is the impulse to the aliasing the 60 dB stopband lets through
    (2e-4), nothing before the hit, and the charge amplifier's zero settles as e^(-t/tau)."""
    chain = Chain(rate_hz, 0.15, 5.0, 10.0, 2.0, 0.3)
    samples = round(1.0 * rate_hz)
    for hammer in HAMMERS:
        force = chain.filtered(hammer.impulse_until, samples, (hammer.onset_s, hammer.end_s + 0.05))
        assert force.sum() / rate_hz == pytest.approx(hammer.impulse_n_s, rel=2e-4)
        assert np.all(force[: math.floor(hammer.onset_s * rate_hz)] == 0.0)
    zero = chain.zero(samples)
    assert zero[0] == 0.15 and zero[-1] == pytest.approx(
        0.15 * math.exp(-(samples - 1) / rate_hz / 5.0)
    )


def test_the_second_mode_is_its_ode_under_the_hammer():
    """The mode's exact response by partial fractions and free ringing against DOP853 of
    m2 y'' + c2 y' + k2 y = f(t), stepped to the contact's end and on from there."""
    effects = Effects(mode_hz=120.0, mode_damping_ratio=0.01, mode_mass_kg=500.0)
    omega, mass = 2.0 * math.pi * 120.0, 500.0

    def rhs(t, s):
        push = HAMMER.force_at(t)
        return (s[1], (push - 2.0 * 0.01 * omega * mass * s[1] - omega**2 * mass * s[0]) / mass)

    def run(span, state):
        return scipy.integrate.solve_ivp(
            rhs, span, state, method='DOP853', rtol=1e-12, atol=1e-18, dense_output=True
        )

    during = run((HAMMER.onset_s, HAMMER.end_s), (0.0, 0.0))
    after = run((HAMMER.end_s, HAMMER.onset_s + 0.2), during.y[:, -1])
    times = HAMMER.onset_s + np.linspace(-1e-3, 0.2, 4001)
    inside = times < HAMMER.end_s
    exact = np.where(
        inside,
        during.sol(np.clip(times, HAMMER.onset_s, HAMMER.end_s)),
        after.sol(np.maximum(times, HAMMER.end_s)),
    )
    exact[:, times < HAMMER.onset_s] = 0.0
    x, v = mode_response(effects, HAMMER, times)
    assert np.abs(v - exact[1]).max() < 1e-9 * np.abs(exact[1]).max()
    assert np.abs(x - exact[0]).max() < 1e-9 * np.abs(exact[0]).max()


def test_the_floor_vibration_rings_at_its_centre_with_its_rms():
    rng = np.random.default_rng(11)
    rate = 10_000.0
    noise = floor_noise(rng, round(200.0 * rate), rate, 20.0, 2.0, 3e-5)
    assert noise.std() == pytest.approx(3e-5, rel=0.05)
    f, power = scipy.signal.welch(noise, rate, nperseg=2**16)
    assert f[np.argmax(power)] == pytest.approx(20.0, abs=1.0)


@pytest.mark.slow
def test_sessions_start_in_the_band_or_where_the_last_hit_left():
    world = dataclasses.replace(NEWMARK, duration_s=4.0)
    rng = np.random.default_rng(5)
    effects = Effects()
    records = world.session(effects, 0.1, rng, (450.0, 1450.0))
    half_width = 0.1 * NORMAL_N / STIFFNESS_N_PER_M
    assert len({r.sample_rate_hz for r in records}) == 1
    assert records[0].sample_rate_hz in RATES_HZ
    assert all(
        r.force_n.size == r.velocity_m_s.size == round(4.0 * r.sample_rate_hz) for r in records
    )
    assert all(0.0 < abs(r.start_m) <= 0.95 * half_width for r in records)
    assert all(
        PRETRIGGER_S <= r.pulse.onset_s < PRETRIGGER_S + 1.0 / r.sample_rate_hz for r in records
    )
    centred = world.session(effects, 0.1, rng, (450.0,), centred=True)
    assert [r.start_m for r in centred] == [0.0]
    chained = world.session(effects, 0.1, rng, (1000.0, 450.0), chained=True)
    assert chained[0].start_m == 0.0
    assert [r.start_m for r in chained[1:]] == [r.rest_m for r in chained[:-1]]
    drifting = world.session(Effects(mu_step=0.05), 0.1, rng, (450.0, 1000.0))
    assert [r.mu for r in drifting] == pytest.approx([0.1, 0.105])
