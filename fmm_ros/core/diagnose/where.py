"""Where a model misses: the residual by region of the decay, by band, by speed and position.

Every number is read off the measured velocity, a model's velocity and their difference with
the plain functions of `fmm_ros.core.diagnose.signatures`; nothing here fits a model.
`locate_misfit` describes the base model's misfit with the signatures that start the
candidates; `locate_residual` describes what is left after the best model, for the
'unexplained' verdict.
"""

import math
from collections.abc import Sequence

import numpy as np

from fmm_ros.core.diagnose import signatures as discrepancy
from fmm_ros.core.diagnose.result import ResidualLocation, Where
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.physics.rig import Rig

LOCATION_BINS = 8
"""Speed and position bins of the residual location."""


def locate_misfit(
    impacts: Sequence[ConditionedImpact],
    residuals: Sequence[np.ndarray],
    models: Sequence[np.ndarray],
    hits: Sequence[int],
    rig: Rig,
    noise_std_m_s: float,
) -> Where:
    """Where a model misses: regions, bands, peaks, rest velocity, delay, signatures.

    residuals: measured minus model velocity per impact; models: the model's velocity.
    """
    noise = noise_std_m_s
    rate = impacts[0].sample_rate_hz
    f_n = rig.natural_frequency_hz
    regions = discrepancy.time_regions(residuals, models, hits, noise)
    bands = discrepancy.frequency_bands(residuals, rate, f_n, noise)
    peaks = discrepancy.non_harmonic_peaks(residuals, rate, f_n, noise)
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


def locate_residual(
    impacts: Sequence[ConditionedImpact],
    residuals: Sequence[np.ndarray],
    models: Sequence[np.ndarray],
    positions_m: Sequence[float],
    windows: Sequence[slice],
    hits: Sequence[int],
    rig: Rig,
    noise_std_m_s: float,
) -> ResidualLocation:
    """Where a residual sits: regions of the decay, bands, the model's speed and position.

    Speed bins are logarithmic from 1/300 of the fastest model speed up; position bins split
    the range the model slid over. Only the motion windows count for speed and position, and
    only samples where the model moves; the excess over the whole windows, against the
    noise, is `excess_to_noise`.
    """
    noise = noise_std_m_s
    rate = impacts[0].sample_rate_hz
    regions = discrepancy.time_regions(residuals, models, hits, noise)
    bands = discrepancy.frequency_bands(residuals, rate, rig.natural_frequency_hz, noise)
    speeds, places, inside = [], [], []
    for model, x0, window, residual in zip(models, positions_m, windows, residuals, strict=True):
        displacement = x0 + np.concatenate(([0.0], np.cumsum(0.5 * (model[1:] + model[:-1]))))
        displacement[1:] /= rate
        speed = np.abs(model[window])
        moving = speed > 0.0
        speeds.append(np.where(moving, speed, np.nan))
        places.append(np.where(moving, displacement[window], np.nan))
        inside.append(residual[window])
    top = max(float(np.nanmax(s)) if np.any(np.isfinite(s)) else 0.0 for s in speeds)
    reach = max(float(np.nanmax(np.abs(p))) if np.any(np.isfinite(p)) else 0.0 for p in places)
    speed_bins = position_bins = ()
    if top > 0.0 and reach > 0.0:
        speed_edges = np.geomspace(top / 300.0, top * (1.0 + 1e-9), LOCATION_BINS + 1)
        speed_bins = discrepancy.binned_misfit(inside, speeds, speed_edges, noise)
        place_edges = np.linspace(-reach, reach * (1.0 + 1e-9), LOCATION_BINS + 1)
        position_bins = discrepancy.binned_misfit(inside, places, place_edges, noise)
    excess = discrepancy.excess_rms(np.concatenate(inside), noise) / noise
    summary = _residual_summary(regions, bands, speed_bins, position_bins, excess, noise)
    return ResidualLocation(summary, excess, regions, bands, speed_bins, position_bins)


def _residual_summary(regions, bands, speed_bins, position_bins, excess, noise) -> str:
    parts = [f'{excess:.2f}x the noise RMS beyond the noise over the motion']
    worst = max(regions, key=lambda r: r.share)
    if worst.share > 0.0:
        parts.append(
            f'time: {worst.name} ({100 * worst.share:.0f} %, '
            f'{worst.excess_rms_m_s / noise:.1f}x the noise there)'
        )
        band = max(bands, key=lambda b: b.share)
        parts.append(f'frequency: {band.name} ({100 * band.share:.0f} %)')
    for name, scale, unit, bins in (
        ('speed', 1e3, 'mm/s', speed_bins),
        ('position', 1e3, 'mm', position_bins),
    ):
        if bins and max(b.share for b in bins) > 0.0:
            top = max(bins, key=lambda b: b.excess_rms_m_s)
            parts.append(
                f'{name} {scale * top.low:.3g} to {scale * top.high:.3g} {unit} '
                f'({top.excess_rms_m_s / noise:.1f}x the noise there)'
            )
    return '; '.join(parts)


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
