"""The gap between model and measurement beyond the noise: the number a diagnosis must shrink.

The RMS of the velocity residual beyond the noise, sqrt(max(mean r^2 - s^2, 0)), over the
motion (hit to the model's rest + `SETTLE_S`) of every impact, divided by the largest measured
speed; and the mobility misfit beyond the noise over f_n/2 to `MISFIT_BAND_LIMIT_HZ`. The raw
RMS could not halve for effects the size of the noise; the excess can, and reaches the noise
floor when the effect is captured. `input_noise_allowance` is what the force noise alone puts
into a residual, which no model term may claim as evidence. `measured_motion_stop` is where a
record's motion (and SETTLE_S after it) ends, read off the measured velocity: the diagnosis
fits the records up to there only.
"""

import math
from collections.abc import Sequence

import numpy as np
import scipy.fft

from fmm_ros.constants import MISFIT_BAND_LIMIT_HZ, SETTLE_S
from fmm_ros.core.diagnose import signatures as discrepancy
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.identify.friction import ModelFit
from fmm_ros.core.identify.lsq import inner
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.signal import frf


def motion_window(model_m_s: np.ndarray, hit_index: int, sample_rate_hz: float) -> slice:
    """From the hit to SETTLE_S after the model's last moving sample."""
    moving = np.flatnonzero(model_m_s[hit_index:] != 0.0)
    last = hit_index + (int(moving[-1]) if moving.size else 0)
    return slice(hit_index, min(model_m_s.size, last + 1 + round(SETTLE_S * sample_rate_hz)))


STOP_MARGIN_S = 0.5
"""Kept beyond the measured motion and SETTLE_S, so that a candidate whose motion lasts a
little longer than the measured one is still seen whole [s]."""


MOVING_SIGMAS = 6.0
"""A block of samples is moving when its mean or variance departs from those at rest by this
many of their standard errors."""


MIN_REST_BLOCKS = 8
"""Blocks at rest needed to measure the spread of their means and variances (fewer: the
spread white noise would give is used)."""


def _robust_spread(values: np.ndarray) -> float:
    """Standard deviation of values from their median absolute deviation."""
    return 1.4826 * float(np.median(np.abs(values - np.median(values))))


def measured_motion_stop(impact: ConditionedImpact, natural_frequency_hz: float) -> int:
    """Samples up to the end of the measured motion, plus SETTLE_S and STOP_MARGIN_S.

    At most the record's length.
    The velocity is cut into quarter-period blocks; the last quarter of the record, where the
    rig rests, gives the level at rest (an offset included) and the variance there (noise,
    hum and all), and, from MIN_REST_BLOCKS blocks on, how much block means and variances
    spread at rest (coloured noise and drift spread them more than white noise). The motion
    ends with the last block whose mean or variance departs from them by MOVING_SIGMAS
    standard errors. A record still moving at its end (its last quarter
    louder than twice the second-difference noise) is kept whole.
    """
    velocity = impact.velocity_m_s
    rate = impact.sample_rate_hz
    size = max(2, round(0.25 * rate / natural_frequency_hz))
    count = velocity.size // size
    if count < 8:
        return velocity.size
    blocks = velocity[: count * size].reshape(count, size)
    means = blocks.mean(axis=1)
    variances = blocks.var(axis=1)
    tail = slice(count - max(2, count // 4), count)
    rest_mean = float(np.median(means[tail]))
    rest_variance = float(np.median(variances[tail]))
    if rest_variance > 4.0 * impact.velocity_noise_std_m_s**2:
        return velocity.size
    mean_spread = math.sqrt(rest_variance / size)
    variance_spread = rest_variance * math.sqrt(2.0 / size)
    if tail.stop - tail.start >= MIN_REST_BLOCKS:
        # Coloured noise and drift move block means and variances more than white noise of
        # the same variance would: their spread at rest is measured, not assumed.
        mean_spread = max(mean_spread, _robust_spread(means[tail]))
        variance_spread = max(variance_spread, _robust_spread(variances[tail]))
    moving = (np.abs(means - rest_mean) > MOVING_SIGMAS * mean_spread) | (
        variances > rest_variance + MOVING_SIGMAS * variance_spread
    )
    moving[: impact.hit_end_index // size + 1] = True
    last = int(np.flatnonzero(moving)[-1]) + 1
    stop = last * size + round((SETTLE_S + STOP_MARGIN_S) * rate)
    # A length with small prime factors: the spectra of the gaps and the signatures are DFTs.
    return min(velocity.size, scipy.fft.next_fast_len(stop, real=True))


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
        total += inner(sensitivity, sensitivity) * relative**2
    return total / noise_std_m_s**2
