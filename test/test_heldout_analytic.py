"""The `analytic` held-out world (test/heldout/analytic.py) held to independent computation.

Its closed-form and Radau motions against `heldout.plant.solve_events` (event-located
DOP853, code it does not share) and against each other; the energy balance of each slide;
exact pulse areas; the chain's calibrated DC gain and sampled areas at each lab rate; starts
in the friction band. Which kinds it offers and how the diagnosis does on it are in
test_heldout_worlds.py with the other worlds.
"""

import numpy as np
import pytest
import scipy.integrate
from heldout.analytic import (
    ANALYTIC,
    MASS_KG,
    NORMAL_N,
    RATES_HZ,
    STIFFNESS_N_PER_M,
    Friction,
    Tap,
    closed_form,
    implicit,
    in_band,
    integrate_and_filter,
    motion,
)
from heldout.forces import Hit
from heldout.lab import Effects
from heldout.plant import solve_events
from heldout_contacts import REFERENCE_CONTACTS

TAPS = (
    Tap('skewed_cosine', 1000.0, 1.0e-3, 2.0e-3, 0.15 + 0.37e-4),
    Tap('beta', 1450.0, 0.8e-3, 1.9e-3, 0.15 + 0.81e-4, rebound_ratio=0.05),
)


@pytest.mark.parametrize('tap', TAPS, ids=lambda tap: tap.shape)
def test_tap_impulses_peaks_and_rebounds_are_exact(tap):
    area, _ = scipy.integrate.quad(
        lambda t: float(tap.force(t)), tap.onset_s, tap.end_s, points=tap.edges_s[1:-1], limit=400
    )
    assert area == pytest.approx(tap.impulse_n_s, rel=1e-9)
    middle = 0.5 * (tap.onset_s + tap.end_s)
    assert float(tap.impulse_until(middle)) == pytest.approx(
        scipy.integrate.quad(lambda t: float(tap.force(t)), tap.onset_s, middle, limit=400)[0],
        rel=1e-9,
    )
    peak = tap.force(np.linspace(tap.onset_s, tap.onset_s + tap.main_s, 200_001)).max()
    assert peak == pytest.approx(tap.peak_n, rel=1e-6)
    rebound_top = float(tap.force(tap.rebound_start_s + 0.5 * tap.rebound_s))
    assert rebound_top == pytest.approx(tap.rebound_ratio * tap.peak_n, rel=1e-9)
    assert float(tap.force(tap.rebound_start_s - 0.5 * tap.gap_s)) == 0.0


def _as_hit(tap: Tap) -> Hit:
    """The same force as a `heldout.forces.Hit`, for the DOP853 event solver."""

    class SameForce(Hit):
        def force_at(self, time_s: float) -> float:
            return float(tap.force(time_s))

        def force_n(self, time_s):
            return tap.force(time_s)

        @property
        def end_s(self) -> float:
            return tap.end_s

    return SameForce('half_sine', tap.peak_n, tap.main_s, tap.onset_s)


@pytest.mark.slow
def test_its_motion_matches_an_independent_event_located_dop853():
    """Closed form (Coulomb, damping, asymmetry) and Radau (Stribeck, cubic, wear track)
    against lab's DOP853 slides, which share no code with them: same force, same motion."""
    times = np.linspace(0.14, 6.0, 60_001)
    for index, (effects, contact, plant) in enumerate(REFERENCE_CONTACTS):
        tap = TAPS[index % 2]
        moved = motion(Friction(0.11, effects), tap, 1e-4, 8.0)
        exact = solve_events(plant, contact, _as_hit(tap), 1e-4, 8.0)
        x, v = moved.state(times)
        x_exact, v_exact = exact.evaluate(times)
        assert np.abs(v - v_exact).max() < 1e-8, effects
        assert np.abs(x - x_exact).max() < 1e-10, effects
        assert moved.rest_m == pytest.approx(exact.rest_m, abs=1e-10)


@pytest.mark.slow
def test_the_closed_form_matches_radau_on_a_linear_contact():
    friction = Friction(0.09, Effects(asymmetry=-0.015, added_damping_n_s_per_m=0.2))
    exact = closed_form(friction, TAPS[0], -2e-4, 8.0)
    stepped = implicit(friction, TAPS[0], -2e-4, 8.0)
    times = np.linspace(0.14, 6.0, 60_001)
    assert np.abs(exact.state(times)[1] - stepped.state(times)[1]).max() < 1e-8
    assert exact.rest_m == pytest.approx(stepped.rest_m, abs=1e-10)


def test_each_slide_spends_its_spring_energy_on_friction_and_damping():
    """Stop to stop: k (x_a^2 - x_b^2) / 2 = mu N |x_b - x_a| + c int v^2 dt."""
    damping = 0.275 + 0.3
    friction = Friction(0.12, Effects(added_damping_n_s_per_m=0.3))
    moved = closed_form(friction, TAPS[1], 1.5e-4, 12.0)
    slides = moved.segments[1:]
    assert len(slides) >= 8
    for t0, t1, evaluate in slides[1:]:
        times = np.linspace(t0, t1, 20_001)
        x, v = evaluate(times)
        spring = 0.5 * STIFFNESS_N_PER_M * (x[0] ** 2 - x[-1] ** 2)
        rubbed = 0.12 * NORMAL_N * abs(x[-1] - x[0])
        viscous = damping * scipy.integrate.simpson(v**2, x=times)
        assert spring == pytest.approx(rubbed + viscous, rel=1e-6)
        assert abs(v[0]) < 1e-12 and abs(v[-1]) < 1e-12
    assert STIFFNESS_N_PER_M * abs(moved.rest_m) <= 0.12 * NORMAL_N
    # the hit's impulse is the momentum it leaves (friction's share over the hit aside)
    t_end = moved.segments[0][1]
    momentum = MASS_KG * float(moved.state(np.array([t_end - 1e-12]))[1][0])
    assert momentum == pytest.approx(TAPS[1].impulse_n_s, rel=5e-3)


@pytest.mark.parametrize('rate_hz', RATES_HZ)
def test_the_chain_keeps_areas_at_every_lab_rate(rate_hz):
    """Exact cell means through the DC-calibrated filter: the sampled force's area is the
    impulse, the sampled velocity's area the distance moved, a constant passes unchanged."""
    tap = TAPS[0]
    samples = round(8.0 * rate_hz)
    force = integrate_and_filter(tap.impulse_until, rate_hz, samples, (tap.onset_s, tap.end_s))
    assert force.sum() / rate_hz == pytest.approx(tap.impulse_n_s, rel=1e-6)
    moved = closed_form(Friction(0.11, Effects()), tap, 0.0, 8.0)
    assert moved.last_motion_s < 7.0
    speed = integrate_and_filter(
        lambda t: moved.state(t)[0], rate_hz, samples, (tap.onset_s, moved.last_motion_s)
    )
    assert speed.sum() / rate_hz == pytest.approx(moved.rest_m, abs=1e-9)
    level = integrate_and_filter(lambda t: 3.0 * np.clip(t, 0.5, 2.5), rate_hz, samples, (0.5, 2.5))
    assert level[round(1.5 * rate_hz)] == pytest.approx(3.0, rel=1e-9)


@pytest.mark.slow
def test_sessions_start_in_the_friction_band_at_a_lab_rate():
    rng = np.random.default_rng(5)
    friction = Friction(0.1, Effects())
    half_width = 0.1 * NORMAL_N / STIFFNESS_N_PER_M
    starts = np.array([in_band(friction, rng) for _ in range(200)])
    assert np.all(np.abs(starts) >= 0.2 * half_width)
    assert np.all(np.abs(starts) <= 0.9 * half_width)
    records = ANALYTIC.session(Effects(), 0.1, rng, (450.0, 1000.0, 1450.0))
    assert len({r.sample_rate_hz for r in records}) == 1
    assert records[0].sample_rate_hz in RATES_HZ
    assert all(r.force_n.size == round(12.0 * r.sample_rate_hz) for r in records)
    assert all(r.start_m != 0.0 for r in records)
    centred = ANALYTIC.session(Effects(asymmetry=0.02), 0.1, rng, (450.0, 1000.0))
    assert [r.start_m for r in centred] == [0.0, 0.0]
    chained = ANALYTIC.session(Effects(), 0.1, rng, (450.0, 1000.0, 1450.0), chained=True)
    assert chained[0].start_m == 0.0
    assert [r.start_m for r in chained[1:]] == [r.rest_m for r in chained[:-1]]
