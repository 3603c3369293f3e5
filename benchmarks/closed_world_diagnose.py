"""The closed-world diagnosis, kept frozen as the yardstick of bench_diagnose.py.

One effect or none: base fit on the whole records, one full refit per model term from its
signature start (the second mode screened by its one-step start, as it was), the best by BIC
named when it beats the required score and halves the gap. This is the algorithm the
open-world diagnosis (`fmm_ros.core.diagnose`) replaced, reduced to what costs time and
what it answers; its numbers are not the product's.
"""

import math
from collections.abc import Sequence

import numpy as np

from fmm_ros.core.diagnose.gaps import gap, input_noise_allowance, motion_window
from fmm_ros.core.diagnose.signatures import non_harmonic_peaks
from fmm_ros.core.diagnose.starts import SECOND_MODE_DAMPING_RATIOS, start_term
from fmm_ros.core.diagnose.where import locate_misfit
from fmm_ros.core.identify.conditioning import as_conditioned
from fmm_ros.core.identify.friction import ModelFit, fit_model
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import MODEL_TERMS
from fmm_ros.errors import FitError

BIC_EVIDENCE = 10.0
INPUT_NOISE_FACTOR = 3.0
EXPLAINED_GAP = 0.5


def diagnose_closed_world(
    impacts: Sequence, *, rig: Rig = FMM_RIG, fit_initial_position: bool = False
) -> str:
    """The one effect the closed-world workflow names in these impacts, or 'none'."""
    conditioned = [as_conditioned(impact) for impact in impacts]
    base = fit_model(conditioned, rig=rig, fit_initial_position=fit_initial_position)
    noise = base.noise_std_m_s
    models = [i.velocity_m_s - r for i, r in zip(conditioned, base.residuals_m_s, strict=True)]
    hits = [impact.gate[0][0] for impact in conditioned]
    rate = conditioned[0].sample_rate_hz
    windows = [motion_window(m, h, rate) for m, h in zip(models, hits, strict=True)]
    peak = max(impact.peak_velocity_m_s for impact in conditioned)
    where = locate_misfit(conditioned, base.residuals_m_s, models, hits, rig, noise)
    required = -(
        BIC_EVIDENCE + INPUT_NOISE_FACTOR * input_noise_allowance(conditioned, base, noise)
    )
    gap_before = gap(base.residuals_m_s, windows, noise, peak)
    base_bic = _bic(base.residuals_m_s, noise, len(base.names), base.n_samples)
    scored = []
    for effect in MODEL_TERMS:
        try:
            if effect == 'second_mode':
                start, gain = _second_mode_start(conditioned, base, models, rig)
                penalty = len(start.parameters) * math.log(base.n_samples)
                if gain < penalty:
                    continue  # screened: scored at its start, never named
            elif effect == 'stribeck':
                start = MODEL_TERMS[effect](mu_static_excess=0.03, stribeck_velocity_m_s=2e-3)
            else:
                start = start_term(effect, conditioned, where, rig)
            refit = fit_model(
                conditioned,
                rig=rig,
                mu0=base.mu,
                terms=(start,),
                fit_initial_position=fit_initial_position,
            )
        except FitError:
            continue
        score = _bic(refit.residuals_m_s, noise, len(refit.names), base.n_samples) - base_bic
        scored.append((score, effect, gap(refit.residuals_m_s, windows, noise, peak)))
    if not scored:
        return 'none'
    score, effect, gap_after = min(scored)
    if score > required or gap_after > (1.0 - EXPLAINED_GAP) * gap_before:
        return 'none'
    return effect


def _bic(residuals, noise: float, k: int, n: int) -> float:
    return sum(float(np.einsum('i,i->', r, r)) for r in residuals) / noise**2 + k * math.log(n)


def _second_mode_start(impacts, base: ModelFit, models, rig: Rig):
    """The mode at the strongest residual peak, zeta and 1 / m2 by least squares, mu held."""
    cls = MODEL_TERMS['second_mode']
    peaks = non_harmonic_peaks(
        base.residuals_m_s,
        impacts[0].sample_rate_hz,
        rig.natural_frequency_hz,
        base.noise_std_m_s,
        count=1,
        threshold=0.0,
        skip_harmonics=False,
    )
    lower, upper = cls.bounds()
    frequency = peaks[0].frequency_hz if peaks else cls.parameters[0].default
    best = (cls(frequency_hz=frequency, modal_mass_kg=upper[2]), 0.0)
    if not peaks:
        return best
    before = sum(float(r @ r) for r in base.residuals_m_s)
    for zeta in SECOND_MODE_DAMPING_RATIOS:
        unit = cls(frequency_hz=frequency, damping_ratio=zeta, modal_mass_kg=1.0)
        shapes = [
            simulate(
                impact.force_n,
                impact.sample_rate_hz,
                rig=base.rig,
                mu=base.mu,
                effects=(*base.effects, unit),
                x0_m=base.initial_positions_m[index],
            ).velocity_m_s
            - model
            for index, (impact, model) in enumerate(zip(impacts, models, strict=True))
        ]
        numerator = sum(float(s @ r) for s, r in zip(shapes, base.residuals_m_s, strict=True))
        denominator = sum(float(s @ s) for s in shapes)
        if numerator <= 0.0 or denominator == 0.0:
            continue
        mass = float(np.clip(denominator / numerator, lower[2], upper[2]))
        after = sum(
            float((r - s / mass) @ (r - s / mass))
            for r, s in zip(base.residuals_m_s, shapes, strict=True)
        )
        gain = (before - after) / base.noise_std_m_s**2
        if gain > best[1]:
            best = (cls(frequency_hz=frequency, damping_ratio=zeta, modal_mass_kg=mass), gain)
    return best
