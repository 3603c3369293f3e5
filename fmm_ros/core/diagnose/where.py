"""Where the base model misses: the residual by region of the decay and by band, and signatures.

Every number is read off the measured and the base model's velocity with the plain functions of
`fmm_ros.core.diagnose.signatures`; nothing here fits a model.
"""

import math
from collections.abc import Sequence

import numpy as np

from fmm_ros.core.diagnose import signatures as discrepancy
from fmm_ros.core.diagnose.result import Where
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.identify.friction import ModelFit
from fmm_ros.core.physics.rig import Rig


def locate_misfit(
    impacts: Sequence[ConditionedImpact],
    base: ModelFit,
    models: Sequence[np.ndarray],
    hits: Sequence[int],
    rig: Rig,
) -> Where:
    """Where the base model misses: regions, bands, peaks, rest velocity, delay, signatures."""
    noise = base.noise_std_m_s
    rate = impacts[0].sample_rate_hz
    f_n = rig.natural_frequency_hz
    regions = discrepancy.time_regions(base.residuals_m_s, models, hits, noise)
    bands = discrepancy.frequency_bands(base.residuals_m_s, rate, f_n, noise)
    peaks = discrepancy.non_harmonic_peaks(base.residuals_m_s, rate, f_n, noise)
    measured = tuple(
        discrepancy.decay_signatures(i.velocity_m_s, rate, h, f_n)
        for i, h in zip(impacts, hits, strict=True)
    )
    simulated = tuple(
        discrepancy.decay_signatures(m, rate, h, f_n) for m, h in zip(models, hits, strict=True)
    )
    rest = [
        discrepancy.rest_velocity(i.velocity_m_s, m, h, noise)
        for i, m, h in zip(impacts, models, hits, strict=True)
    ]
    weights = np.array([1.0 / e**2 if math.isfinite(e) else 0.0 for _, e in rest])
    if weights.sum() > 0.0:
        rest_mean = float(np.sum(weights * np.nan_to_num([m for m, _ in rest])) / weights.sum())
        rest_error = float(1.0 / math.sqrt(weights.sum()))
    else:
        rest_mean = rest_error = math.nan
    delays = [
        discrepancy.phase_delay_s(i.velocity_m_s, m, rate, f_n)
        for i, m in zip(impacts, models, strict=True)
    ]
    delay = float(np.nanmedian(delays)) if np.any(np.isfinite(delays)) else math.nan
    summary = _summary(regions, bands, peaks, rest_mean, rest_error, noise)
    return Where(summary, regions, bands, peaks, measured, simulated, rest_mean, rest_error, delay)


def _summary(regions, bands, peaks, rest_mean, rest_error, noise) -> str:
    worst = max(regions, key=lambda r: r.share)
    band = max(bands, key=lambda b: b.share)
    if worst.share == 0.0:
        return 'nowhere beyond the noise'
    parts = [
        f'time: {worst.name} ({100 * worst.share:.0f} % of the excess misfit, '
        f'{worst.excess_rms_m_s / noise:.1f}x the noise RMS there)',
        f'frequency: {band.name} ({100 * band.share:.0f} %)',
    ]
    if peaks:
        parts.append(
            'non-harmonic peak at ' + ', '.join(f'{p.frequency_hz:.1f} Hz' for p in peaks[:2])
        )
    if math.isfinite(rest_mean) and abs(rest_mean) > 5.0 * rest_error:
        parts.append(f'velocity at rest {rest_mean:.3g} m/s')
    return '; '.join(parts)


def base_models(impacts: Sequence[ConditionedImpact], base: ModelFit) -> list[np.ndarray]:
    """The base model's velocity of each impact (measured minus its residual) [m/s]."""
    return [
        impact.velocity_m_s - residual
        for impact, residual in zip(impacts, base.residuals_m_s, strict=True)
    ]
