"""The `moreau` held-out world (test/heldout/moreau.py) held to independent computation.

Its Moreau-Jean motion against `heldout.plant.solve_events` (event-located DOP853, code it
does not share) under the same contact force; its collision against Hertz's impact solution
and a DOP853 run of the two-body contact; momentum and energy through the collision; each
slide's energy balance; the analyser's FIR (DC gain, no delay, aliases stopped) at every rate;
continuous sessions. How the diagnosis does on it is in test_heldout_worlds.py and the
benchmark.
"""

import math

import numpy as np
import pytest
import scipy.integrate
from heldout.forces import Hit
from heldout.lab import Effects
from heldout.moreau import (
    _C,
    _K,
    _N,
    HERTZ_TIME,
    MASS_KG,
    MOREAU,
    NORMAL_N,
    RATES_HZ,
    STEPS_PER_SAMPLE,
    STIFFNESS_N_PER_M,
    Chain,
    Hammer,
    Rig,
    decimate,
    initial_state,
    launch,
    simulate,
    wait,
)
from heldout.plant import solve_events
from heldout_contacts import REFERENCE_CONTACTS

HAMMER = Hammer(0.2, 6.3e6)
"""A 0.2 kg hammer whose tip makes a 1000 N hit last 2.5 ms."""
STEP_S = 1.0 / 409_600.0
ONSET_S = 1.0e-3 + 0.37 * STEP_S


def _hit(effects: Effects, mu: float, start_m: float, seconds: float, hammer=HAMMER, level=1000.0):
    """A hit from rest at start_m, simulated for `seconds` at STEP_S."""
    state = initial_state(start_m)
    launch(state, hammer.speed_for(level), 0.0, ONSET_S)
    rig = Rig(effects, mu, hammer)
    return simulate(rig.parameters(), state, 0.0, STEP_S, round(seconds / STEP_S)), rig


@pytest.mark.slow
def test_the_collision_is_hertz_impact_conserving_momentum_and_energy():
    """On a free rig (no spring, friction or damping) the tip's contact is an elastic
    two-body Hertz impact: its peak and duration are Hertz's closed form, momentum is
    conserved to rounding and energy to 1e-6, and the force is a DOP853 run of the relative
    motion m_eff delta'' = -k delta^1.5 to 5e-5 of the peak (the step's second-order error)."""
    speed = HAMMER.speed_for(1000.0)
    state = initial_state(0.0)
    launch(state, speed, 0.0, ONSET_S)
    parameters = Rig(Effects(), 0.1, HAMMER).parameters()
    parameters[[_C, _K, _N]] = 0.0
    fine = simulate(parameters, state, 0.0, STEP_S, round(8e-3 / STEP_S))
    hammer_u, rig_v = fine.state[5], fine.state[1]
    assert HAMMER.mass_kg * hammer_u + MASS_KG * rig_v == pytest.approx(
        HAMMER.mass_kg * speed, rel=1e-12
    )
    energy = 0.5 * HAMMER.mass_kg * hammer_u**2 + 0.5 * MASS_KG * rig_v**2
    assert energy == pytest.approx(0.5 * HAMMER.mass_kg * speed**2, rel=1e-6)
    # the impulse the sensor's force carries is the hammer's momentum change (trapezoid: theta
    # = 1/2 weighs the step's two ends alike)
    impulse = scipy.integrate.trapezoid(fine.force_n, fine.time_s)
    assert impulse == pytest.approx(HAMMER.mass_kg * (speed - hammer_u), rel=1e-12)
    assert fine.force_n.max() == pytest.approx(1000.0, rel=1e-4)
    touching = fine.time_s[fine.force_n > 0.0]
    assert touching[-1] - touching[0] == pytest.approx(HAMMER.contact_s(1000.0), rel=2e-3)
    reduced, tip = HAMMER.effective_mass_kg(), HAMMER.tip_n_per_m1_5

    def relative(_t, z):
        return (z[1], -tip * max(z[0], 0.0) ** 1.5 / reduced)

    exact = scipy.integrate.solve_ivp(
        relative,
        (ONSET_S, ONSET_S + 1.2 * HERTZ_TIME * (1000.0 / tip) ** (2 / 3) / speed),
        (0.0, speed),
        method='DOP853',
        rtol=1e-12,
        atol=1e-15,
        dense_output=True,
    )
    inside = (fine.time_s > ONSET_S) & (fine.time_s < exact.t[-1])
    overlap = np.maximum(exact.sol(fine.time_s[inside])[0], 0.0)
    assert np.abs(fine.force_n[inside] - tip * overlap**1.5).max() < 5e-5 * 1000.0


def _same_force(fine) -> Hit:
    """The world's sensed contact force, linear between steps (as theta = 1/2 integrates it),
    as a `heldout.forces.Hit` for the DOP853 event solver."""
    touching = np.flatnonzero(fine.force_n > 0.0)
    first, last = int(touching[0]) - 1, int(touching[-1]) + 1
    times, force = fine.time_s[first : last + 1], fine.force_n[first : last + 1]

    class SameForce(Hit):
        def force_at(self, time_s: float) -> float:
            return float(np.interp(time_s, times, force, left=0.0, right=0.0))

        def force_n(self, time_s):
            return np.interp(time_s, times, force, left=0.0, right=0.0)

        @property
        def end_s(self) -> float:
            return float(times[-1])

    return SameForce('half_sine', 1000.0, float(times[-1] - times[0]), float(times[0]))


@pytest.mark.slow
@pytest.mark.parametrize('index', range(len(REFERENCE_CONTACTS)))
def test_its_motion_matches_an_independent_event_located_dop853(index):
    """Coulomb, damping with asymmetry, Stribeck, a cubic spring, a wear track: the rig's
    Moreau-Jean motion under the contact force it sensed, against lab's DOP853 slides with
    event-located stops and root-bracketed breakaway driven by the same force: the velocity
    within 1.5e-6 m/s of a 0.13 m/s swing (measured 0.6-0.9e-6; a hundredth of the noise),
    the rest within 1e-8 m."""
    effects, contact, plant = REFERENCE_CONTACTS[index]
    fine, _ = _hit(effects, 0.11, 1e-4, 5.0)
    exact = solve_events(plant, contact, _same_force(fine), 1e-4, 5.0)
    rig_velocity = fine.velocity_m_s  # no second mode: the struck point is the rig
    _, v_exact = exact.evaluate(fine.time_s[::40])
    assert np.abs(rig_velocity[::40] - v_exact).max() < 1.5e-6
    assert fine.state[6] == 0.0, 'the rig came to rest for good'
    assert fine.position_m[-1] == pytest.approx(exact.rest_m, abs=1e-8)


@pytest.mark.slow
def test_the_motion_spends_its_energy_on_friction_and_damping():
    """From the end of the hit to rest: the kinetic and spring energy lost is
    int (mu N |v| + c v^2) dt, and the rest is inside the band static friction holds."""
    damping = 0.275 + 0.3
    fine, _ = _hit(Effects(added_damping_n_s_per_m=0.3), 0.12, 1.5e-4, 4.0, level=1450.0)
    after = fine.time_s > ONSET_S + 5e-3
    x, v, t = fine.position_m[after], fine.velocity_m_s[after], fine.time_s[after]
    assert np.count_nonzero(np.diff(np.sign(v[v != 0.0]))) >= 3, 'several reversals'
    energy = 0.5 * MASS_KG * v**2 + 0.5 * STIFFNESS_N_PER_M * x**2
    spent = scipy.integrate.trapezoid(0.12 * NORMAL_N * np.abs(v) + damping * v**2, t)
    assert energy[0] - energy[-1] == pytest.approx(spent, rel=1e-6)
    assert v[-1] == 0.0
    assert STIFFNESS_N_PER_M * abs(x[-1]) <= 0.12 * NORMAL_N


def test_a_ringing_mode_is_the_exact_damped_mode_and_the_wait_steps_it_alike():
    """A second mode ringing alone (rig at rest, hammer gone) against its closed-form damped
    oscillation, to 3e-4 of its amplitude after 0.1 s at 250 Hz (the trapezoid's phase lag,
    (omega h)^2 / 12 a radian: 2e-4); the wait's map power gives the steps' state to 1e-9."""
    effects = Effects(mode_hz=250.0, mode_damping_ratio=0.01, mode_mass_kg=500.0)
    rig = Rig(effects, 0.1, HAMMER)
    state = initial_state(0.0, mode=(1e-6, 2e-3))
    state[6] = 0.0  # the rig at rest for good
    steps = 40_960
    fine = simulate(rig.parameters(), state, 0.0, STEP_S, steps)
    omega, zeta = 2 * math.pi * 250.0, 0.01
    damped = omega * math.sqrt(1 - zeta**2)
    a, b = 1e-6, (2e-3 + zeta * omega * 1e-6) / damped
    t = fine.time_s
    exact = np.exp(-zeta * omega * t) * (
        (b * damped - zeta * omega * a) * np.cos(damped * t)
        - (a * damped + zeta * omega * b) * np.sin(damped * t)
    )
    assert np.abs(fine.velocity_m_s - exact).max() < 3e-4 * 2e-3
    chain = Chain(10_240.0, 0.1, 1e-4, 50.0, (0.0,) * 5, (0.0,) * 5, (0.0,) * 5)
    assert chain.step_s == STEP_S
    waited = wait(rig, state, chain, steps * STEP_S)
    assert waited[2:4] == pytest.approx(fine.state[2:4], rel=1e-9, abs=1e-18)


@pytest.mark.parametrize('rate_hz', RATES_HZ)
def test_the_analyser_passes_dc_without_delay_and_stops_aliases(rate_hz):
    """The decimating FIR: a constant passes unchanged; a 200 Hz tone comes out at the sample
    instants with no delay (compensated) and unit gain; a tone that would alias onto 0.4 of
    the rate (at 0.6 of it) is stopped below 1e-4 (90 dB: 3e-5)."""
    factor, samples = STEPS_PER_SAMPLE[rate_hz], 400
    nodes = (samples + 2 * 29) * factor + 1
    t = (np.arange(nodes) - 29 * factor) / (rate_hz * factor)
    assert decimate(np.full(nodes, 3.0), rate_hz, samples) == pytest.approx(3.0, abs=1e-12)
    at = np.arange(samples) / rate_hz
    tone = decimate(np.sin(2 * math.pi * 200.0 * t + 0.3), rate_hz, samples)
    assert np.abs(tone - np.sin(2 * math.pi * 200.0 * at + 0.3)).max() < 1e-4
    alias = decimate(np.sin(2 * math.pi * 0.6 * rate_hz * t), rate_hz, samples)
    assert np.abs(alias).max() < 1e-4
    step = decimate(np.where(t > 0.02, 1.0, 0.0), rate_hz, samples)
    assert step[: round(0.015 * rate_hz)] == pytest.approx(0.0, abs=1e-12)
    assert step[round(0.025 * rate_hz) :] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.slow
def test_sessions_are_continuous_at_one_rate_with_peaks_at_the_levels():
    levels = (450.0, 1000.0, 1450.0)
    rng = np.random.default_rng(3)
    records = MOREAU.session(Effects(), 0.1, rng, levels)
    assert len({r.sample_rate_hz for r in records}) == 1
    assert records[0].sample_rate_hz in RATES_HZ
    assert all(r.force_n.size == round(12.0 * r.sample_rate_hz) for r in records)
    assert abs(records[0].start_m) <= 0.9 * 0.1 * NORMAL_N / STIFFNESS_N_PER_M
    assert [r.start_m for r in records[1:]] == [r.rest_m for r in records[:-1]]
    for record, level in zip(records, levels, strict=True):
        assert record.force_n.max() == pytest.approx(level, rel=0.05)
        assert 1.2e-3 < record.hammer.contact_s(level) < 4.2e-3
        area = record.force_n.sum() / record.sample_rate_hz
        assert area == pytest.approx(record.impulse_n_s, abs=0.03)  # noise and hum: < 0.01
    centred = MOREAU.session(Effects(asymmetry=0.02), 0.1, rng, levels[:2])
    assert [r.start_m for r in centred] == [0.0, 0.0]
    chained = MOREAU.session(Effects(), 0.1, rng, levels, chained=True)
    assert chained[0].start_m == 0.0
    assert [r.start_m for r in chained[1:]] == [r.rest_m for r in chained[:-1]]
