"""Where each candidate's refit starts: from the signature that points at its effect.

Added damping from the peak-map slope, asymmetry from the centre shift, k3 from the period
slope, offset from the rest velocity, delay from the phase slope, Stribeck at 0.03 / 2 mm/s;
the second mode at the strongest residual peak, its modal mass by linear least squares (which
doubles as a score test that can skip the full refit).
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.core.diagnose import signatures as discrepancy
from fmm_ros.core.diagnose.result import Where
from fmm_ros.core.diagnose.where import base_models
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.identify.friction import ModelFit
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.physics.terms import MODEL_TERMS, ModelTerm, model_term


def start_term(
    effect: str, impacts: Sequence[ConditionedImpact], base: ModelFit, where: Where, rig: Rig
) -> ModelTerm:
    """Where to start the refit of one candidate: from the signature that points at it.

    Each is a rough estimate from the measured-minus-model signatures, clipped into the term's
    plausible bounds; the refit does the rest. The second mode, whose misfit is many-valleyed
    in frequency, starts from the strongest residual peak with its damping ratio and modal
    mass chosen by linear least squares over a few damping ratios.
    """
    cls = MODEL_TERMS[effect]
    lower, upper = cls.bounds()

    def clipped(*values: float) -> ModelTerm:
        return cls.from_vector(np.clip(values, lower, upper))

    pairs = [
        (m, s)
        for m, s in zip(where.measured, where.model, strict=True)
        if m.half_cycles >= 3 and s.half_cycles >= 3
    ]

    def difference(attribute: str) -> float:
        values = [getattr(m, attribute) - getattr(s, attribute) for m, s in pairs]
        values = [v for v in values if math.isfinite(v)]
        return float(np.median(values)) if values else math.nan

    stiffness, mass = rig.stiffness_n_per_m, rig.mass_kg
    if effect == 'viscous_damping':
        slopes = [
            (m.peak_map_slope, s.peak_map_slope)
            for m, s in pairs
            if m.peak_map_slope > 0 and s.peak_map_slope > 0
        ]
        zeta = (
            float(np.median([math.log(s / m) / math.pi for m, s in slopes])) if slopes else math.nan
        )
        added = 2.0 * zeta * math.sqrt(stiffness * mass)
        return clipped(added if math.isfinite(added) and added > 0.01 else 0.2)
    if effect == 'stribeck':
        return clipped(0.03, 2e-3)
    if effect == 'asymmetric_friction':
        # Centres alternate between -mu+ N / k and +mu- N / k: their mean is -d N / (2k).
        shift = difference('centre_m')
        d = -2.0 * stiffness * shift / rig.normal_force_n if math.isfinite(shift) else 0.0
        return clipped(d if abs(d) > 1e-3 else 5e-3)
    if effect == 'cubic_stiffness':
        # Duffing: half period T0 (1 - 3 k3 A^2 / (8 k)), so dT / d(A^2) = -3 k3 T0 / (8 k).
        slope = difference('half_period_amplitude_slope_s_per_m2')
        half_period = math.pi * math.sqrt(mass / stiffness)
        k3 = -8.0 * stiffness * slope / (3.0 * half_period) if math.isfinite(slope) else 0.0
        return clipped(k3 if abs(k3) > 1e3 else 1e4)
    if effect == 'velocity_offset':
        offset = where.rest_velocity_m_s
        return clipped(offset if math.isfinite(offset) else 0.0)
    if effect == 'sensor_delay':
        delay = where.phase_delay_s
        return clipped(
            delay if math.isfinite(delay) and delay > 0.0 else 1.0 / impacts[0].sample_rate_hz
        )
    if effect == 'second_mode':
        return second_mode_start(impacts, base, rig).term
    raise ValueError(f'no start rule for {effect!r}')


SECOND_MODE_DAMPING_RATIOS = (3e-3, 1e-2, 3e-2)
"""Damping ratios tried for the second mode's start (its modal mass solved for each)."""


@dataclass(frozen=True)
class _ModeStart:
    term: ModelTerm
    chi2_gain: float
    """Fall of the residual chi^2 the start mode alone gives, mu held (a score test) [-]."""
    residuals_m_s: tuple[np.ndarray, ...]
    """The base residuals less that mode's response."""


def second_mode_start(impacts: Sequence[ConditionedImpact], base: ModelFit, rig: Rig) -> _ModeStart:
    """Start at the strongest residual peak above 1.5 f_n, with zeta and m2 by least squares.

    The mode is linear and decoupled from the friction contact, so its velocity is the base
    model's with the mode minus the base model's, and scales as 1 / m2: for each trial zeta,
    one simulation per impact with m2 = 1 kg and a one-parameter regression of the residual.
    Without a peak, or where no trial lowers the residual, the start is the mode at its
    heaviest and the gain zero.
    """
    cls = MODEL_TERMS['second_mode']
    noise = base.noise_std_m_s
    rate = impacts[0].sample_rate_hz
    peaks = discrepancy.non_harmonic_peaks(
        base.residuals_m_s,
        rate,
        rig.natural_frequency_hz,
        noise,
        count=1,
        threshold=0.0,
        skip_harmonics=False,
    )
    lower, upper = cls.bounds()
    frequency = peaks[0].frequency_hz if peaks else cls.parameters[0].default
    best = _ModeStart(cls(frequency_hz=frequency, modal_mass_kg=upper[2]), 0.0, base.residuals_m_s)
    if not peaks:
        return best
    models = base_models(impacts, base)
    for zeta in SECOND_MODE_DAMPING_RATIOS:
        unit = model_term(
            'second_mode', frequency_hz=frequency, damping_ratio=zeta, modal_mass_kg=1.0
        )
        shapes = [
            simulate(
                base.force_n(index),
                rate,
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
        mass = float(np.clip(denominator / numerator, lower[2], upper[2]))  # 1 / scale
        residuals = tuple(r - s / mass for r, s in zip(base.residuals_m_s, shapes, strict=True))
        gain = (
            sum(float(r @ r) for r in base.residuals_m_s) - sum(float(r @ r) for r in residuals)
        ) / noise**2
        if gain > best.chi2_gain:
            best = _ModeStart(
                cls(frequency_hz=frequency, damping_ratio=zeta, modal_mass_kg=mass), gain, residuals
            )
    return best
