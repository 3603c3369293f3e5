"""The gap between model and measurement beyond the noise: the number a diagnosis must shrink.

The RMS of the velocity residual beyond the noise, sqrt(max(mean r^2 - s^2, 0)), over the
motion (hit to the model's rest + `SETTLE_S`) of every impact, divided by the largest measured
speed; and the mobility misfit beyond the noise over f_n/2 to `MISFIT_BAND_LIMIT_HZ`. The raw
RMS could not halve for effects the size of the noise; the excess can, and reaches the noise
floor when the effect is captured. `input_noise_allowance` is what the force noise alone puts
into a residual, which no model term may claim as evidence.
"""

import math
from collections.abc import Sequence

import numpy as np

from fmm_ros.constants import MISFIT_BAND_LIMIT_HZ, SETTLE_S
from fmm_ros.core.diagnose import signatures as discrepancy
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.identify.friction import ModelFit
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.signal import frf


def motion_window(model_m_s: np.ndarray, hit_index: int, sample_rate_hz: float) -> slice:
    """From the hit to SETTLE_S after the model's last moving sample."""
    moving = np.flatnonzero(model_m_s[hit_index:] != 0.0)
    last = hit_index + (int(moving[-1]) if moving.size else 0)
    return slice(hit_index, min(model_m_s.size, last + 1 + round(SETTLE_S * sample_rate_hz)))


def gap(
    residuals: Sequence[np.ndarray],
    windows: Sequence[slice],
    noise_std_m_s: float,
    peak_speed_m_s: float,
) -> float:
    """RMS of the velocity residual beyond the noise over the motion windows / peak speed [-]."""
    inside = np.concatenate([r[w] for r, w in zip(residuals, windows, strict=True)])
    return discrepancy.excess_rms(inside, noise_std_m_s) / peak_speed_m_s


def frf_gap(
    impacts: Sequence[ConditionedImpact],
    residuals: Sequence[np.ndarray],
    noise_std_m_s: float,
    natural_frequency_hz: float,
) -> float:
    """Mobility misfit beyond the noise, relative to the measured mobility [-].

    sqrt((sum |R/F|^2 - n s^2 sum 1/|F|^2) / sum |V/F|^2) over the bins from f_n / 2 to
    MISFIT_BAND_LIMIT_HZ and over impacts, R, V, F the DFTs of residual, measured velocity and
    conditioned force: the residual is the model's mobility error times F.
    """
    misfit = noise = total = 0.0
    for impact, residual in zip(impacts, residuals, strict=True):
        n = residual.size
        frequency = frf.frequency_axis(n, impact.sample_rate_hz)
        band = (frequency >= 0.5 * natural_frequency_hz) & (frequency <= MISFIT_BAND_LIMIT_HZ)
        force, velocity = frf.spectra(impact.force_n, impact.velocity_m_s)
        _, error = frf.spectra(impact.force_n, residual)
        inverse_power = 1.0 / np.maximum(np.abs(force[band]) ** 2, np.finfo(float).tiny)
        misfit += float(np.sum(np.abs(error[band]) ** 2 * inverse_power))
        noise += n * noise_std_m_s**2 * float(np.sum(inverse_power))
        total += float(np.sum(np.abs(velocity[band]) ** 2 * inverse_power))
    return math.sqrt(max(misfit - noise, 0.0) / total) if total > 0.0 else math.nan


def input_noise_allowance(
    impacts: Sequence[ConditionedImpact], base: ModelFit, noise_std_m_s: float
) -> float:
    """chi^2 the force noise inside the hit puts into the base residual, expected [-].

    Output-error fitting takes the measured force as exact, but its noise changes each
    impulse by `ConditionedImpact.impulse_std_n_s`, and the model's response with it; a
    candidate term can absorb part of that, which is no evidence of the term. The response to
    a relative impulse change, d v / d scale, comes from one extra simulation per impact; the
    allowance is sum_i |d v_i / d scale|^2 (s_I,i / I_i)^2 / s_v^2.
    """
    total = 0.0
    step = 1e-3
    for index, impact in enumerate(impacts):
        relative = impact.impulse_std_n_s / abs(impact.impulse_n_s)
        scaled = simulate(
            base.force_n(index) * (1.0 + step),
            impact.sample_rate_hz,
            rig=base.rig,
            mu=base.mu,
            effects=base.effects,
            x0_m=base.initial_positions_m[index],
        ).velocity_m_s
        sensitivity = (scaled - base.simulate(index).velocity_m_s) / step
        total += float(sensitivity @ sensitivity) * relative**2
    return total / noise_std_m_s**2
