"""The signal core on records from the physics core: the paper's Coulomb-friction FRF laws.

The FMM's mobility at its natural frequency after an impulse I is pi I / (8 m mu N) for pure
Coulomb friction (the velocity is a train of half-sine arcs whose amplitude falls linearly,
all adding in phase at w_n), so peak |receptance| grows linearly with impulse: the paper's
Fig. 17. The FMM's small viscous damping c lowers it by 2-3 %.
"""

import dataclasses

import numpy as np
import pytest

from fmm_ros.constants import PAPER_MU
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG
from fmm_ros.core.signal import frf
from fmm_ros.core.signal.analysis import AnalysisConfig, analyze_impact, paper_levels, summarize
from fmm_ros.core.signal.capture import capture_impacts
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.sim.excitation import (
    half_sine_pulse,
    hammer_pulse,
    impact_record,
    level_contact_duration_s,
    paper_level,
    tip_contact_duration_s,
)

RATE_HZ = 10_000.0
COULOMB_RIG = dataclasses.replace(FMM_RIG, damping_n_s_per_m=0.0)


def theory_mobility(impulse_n_s, rig=FMM_RIG, mu=PAPER_MU):
    return np.pi * impulse_n_s / (8 * rig.mass_kg * mu * rig.normal_force_n)


def paper_hit(level, rig, mu=PAPER_MU):
    """A half-sine at one of the paper's levels (its peak and mean impulse) and the response."""
    hammer = paper_level(level)
    force = half_sine_pulse(
        hammer.peak_force_n, level_contact_duration_s(hammer), RATE_HZ, 33.0, start_s=0.01
    )
    return ImpactRecord(force, simulate(force, RATE_HZ, rig=rig, mu=mu).velocity_m_s, RATE_HZ)


@pytest.mark.parametrize('level', ['low', 'medium', 'high'])
def test_mobility_at_the_natural_frequency_is_pi_i_over_8_m_mu_n(level):
    result = analyze_impact(paper_hit(level, COULOMB_RIG))
    assert result.flags == ()
    k = round(COULOMB_RIG.natural_frequency_hz / result.frequency_step_hz)
    expected = theory_mobility(result.impulse_n_s, COULOMB_RIG)
    assert abs(result.mobility[k]) == pytest.approx(expected, rel=0.03)
    # With the FMM's viscous damping (zeta 0.1 %) some energy goes elsewhere: a little lower.
    damped = analyze_impact(paper_hit(level, FMM_RIG))
    assert 0.95 * expected < abs(damped.mobility[k]) < abs(result.mobility[k])


def stream_of_hits(levels, spacing_s=40.0, seed=0):
    """One continuous 10 kHz recording of hammer hits on the FMM (mu = 0.113), noisy."""
    seconds = spacing_s * len(levels) + 2.0
    n = round(seconds * RATE_HZ)
    rng = np.random.default_rng(seed)
    force = np.zeros(n)
    for i, level in enumerate(levels):
        peak = paper_level(level).peak_force_n + rng.normal(0, 20)
        force += hammer_pulse(
            peak,
            tip_contact_duration_s(peak),
            RATE_HZ,
            seconds,
            start_s=1.0 + i * spacing_s + rng.uniform(0, 1e-4),
        )
    velocity = simulate(force, RATE_HZ).velocity_m_s
    return force + rng.normal(0, 0.05, n), velocity + rng.normal(0, 1e-5, n)


@pytest.mark.slow
def test_three_levels_give_a_line_through_the_origin_with_r2_above_0_99():
    force, velocity = stream_of_hits(['low', 'medium', 'high'] * 2)
    results = [
        analyze_impact(record, impact_id=i)
        for i, record in enumerate(capture_impacts(force, velocity, RATE_HZ))
    ]
    summary = summarize(results, AnalysisConfig(levels=paper_levels()))
    assert [(r.flags, r.accepted) for r in summary.impacts] == [((), True)] * 6
    assert [(lv.level, lv.count) for lv in summary.levels] == [
        ('low', 2),
        ('medium', 2),
        ('high', 2),
    ]
    fit = summary.linearity
    assert fit.count == 3 and fit.r2 > 0.99
    # Peak receptance = |Y(w_n)| / w_n: slope pi / (8 m mu N w_n), through the origin.
    omega_n = 2 * np.pi * FMM_RIG.natural_frequency_hz
    assert fit.slope == pytest.approx(theory_mobility(1.0) / omega_n, rel=0.05)
    assert abs(fit.intercept) < 0.05 * fit.slope * 1.0
    for level in summary.levels:
        assert level.natural_frequency_hz == pytest.approx(FMM_RIG.natural_frequency_hz, abs=0.05)


@pytest.mark.parametrize('seed', range(6))
def test_clean_physics_records_raise_no_flag(seed):
    level = ['low', 'medium', 'high'][seed % 3]
    # Odd seeds carry the issues' lab noise (0.2 N, 1e-4 m/s): still no flag, no rejection.
    noise = {'force_noise_std_n': 0.2, 'velocity_noise_std_m_s': 1e-4} if seed % 2 else {}
    record = impact_record(paper_level(level).peak_force_n, rng=seed, **noise)
    result = analyze_impact(ImpactRecord(record.force_n, record.velocity_m_s, RATE_HZ))
    assert result.flags == ()
    assert result.impulse_n_s == pytest.approx(record.impulse_n_s, rel=0.01)
    assert result.peak_force_n == pytest.approx(record.peak_force_n, rel=0.01)
    (judged,) = summarize([result], AnalysisConfig(levels=paper_levels())).impacts
    assert (judged.level, judged.accepted) == (level, True)


def linear_h1(rig, analysis):
    """H1 over hits at the three paper peaks on the physics core's linear oscillator (mu = 0)."""
    results = []
    for peak in (450.0, 1000.0, 1450.0):
        force = half_sine_pulse(peak, tip_contact_duration_s(peak), RATE_HZ, 33.0, start_s=0.01)
        velocity = simulate(force, RATE_HZ, rig=rig, mu=0.0).velocity_m_s
        results.append(analyze_impact(ImpactRecord(force, velocity, RATE_HZ), analysis=analysis))
    average = frf.average_frf(
        np.stack([r.force_spectrum for r in results]),
        np.stack([r.velocity_spectrum for r in results]),
    )
    return results, results[0].frequency_hz, average.h1_mobility


def analytic_mobility(rig, s):
    return s / (rig.mass_kg * s**2 + rig.damping_n_s_per_m * s + rig.stiffness_n_per_m)


def test_linear_oscillator_h1_is_the_analytic_frf_around_resonance():
    # mu = 0 and 5 % damping: the response dies out inside the 33 s record, no window needed.
    rig = dataclasses.replace(
        FMM_RIG, damping_n_s_per_m=2 * 0.05 * np.sqrt(FMM_RIG.stiffness_n_per_m * FMM_RIG.mass_kg)
    )
    results, frequency, h1 = linear_h1(rig, AnalysisConfig())
    assert all(r.flags == () for r in results)
    near = np.abs(frequency / rig.natural_frequency_hz - 1) < 0.2
    np.testing.assert_allclose(
        h1[near], analytic_mobility(rig, 2j * np.pi * frequency[near]), rtol=0.01
    )


def test_bare_flexure_needs_the_exponential_window_and_gets_an_exact_frf():
    # The bare flexure (zeta 0.1 %) still rings after 33 s: flagged, and with an exponential
    # window of tau the FRF is exactly the analytic one at s = i w + 1/tau.
    tau = 4.0
    results, frequency, h1 = linear_h1(FMM_RIG, AnalysisConfig(exponential_decay_s=tau))
    assert all(r.flags == ('unsettled',) for r in results)
    near = np.abs(frequency / FMM_RIG.natural_frequency_hz - 1) < 0.2
    exact = analytic_mobility(FMM_RIG, 2j * np.pi * frequency[near] + 1 / tau)
    np.testing.assert_allclose(h1[near], exact, rtol=0.01)
