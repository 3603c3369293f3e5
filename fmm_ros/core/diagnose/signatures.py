"""Where a simulation and a measurement disagree, and the signatures that point at a cause.

Plain functions on sample arrays (velocity in m/s, one impact at a time unless said
otherwise), used by the diagnose workflow (`fmm_ros.core.diagnose`) on the base model's
residual and by reports. The noise level they take is the fitter's estimate from the data
(`fmm_ros.core.identify.velocity_noise_std`). Nothing here fits a model: every number is read off
the records.

- `time_regions` / `frequency_bands`: the residual's energy beyond the noise, split by where
  it lies in the decay (early large amplitude, late small amplitude, near reversals, at rest)
  and by band (below f_n, at f_n, at its odd harmonics, elsewhere).
- `signatures`: the decay's shape (linear = Coulomb, exponential = viscous), the successive-
  peak map |X_n+1| against |X_n|, the oscillation centre and its drift, the half period
  against amplitude, the velocity at rest, the delay read from the phase of measured against
  simulated velocity, and narrow-band residual peaks that are not odd harmonics of f_n.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros._lazy import LazyModule

signal = LazyModule('scipy.signal')

HARMONIC_HALF_WIDTH = 0.25
"""Bands around f_n and its odd harmonics are this fraction of f_n wide on each side."""
HIGHEST_ODD_HARMONIC = 25
"""Odd harmonics up to this one count as 'at the odd harmonics'."""
NEAR_REVERSAL = 0.25
"""A sample is near a reversal when the model's speed is below this fraction of its
half-cycle peak."""
LARGE_AMPLITUDE = 0.5
"""Half cycles whose peak speed is at least this fraction of the first one are 'early'."""


def excess_rms(residual: np.ndarray, noise_std_value: float) -> float:
    """RMS of a residual beyond white noise of the given level: sqrt(max(mean r^2 - s^2, 0))."""
    residual = np.asarray(residual, dtype=float)
    if residual.size == 0:
        return 0.0
    # einsum's own loop: a BLAS dot product splits across threads, which stall on busy cores.
    square = float(np.einsum('i,i->', residual, residual))
    return math.sqrt(max(square / residual.size - noise_std_value**2, 0.0))


@dataclass(frozen=True)
class RegionMisfit:
    """The residual's excess over the noise in one part of the records (all impacts pooled)."""

    name: str
    """'early, large amplitude', 'late, small amplitude', 'near reversals' or 'at rest'."""
    samples: int
    excess_rms_m_s: float
    """RMS of the residual beyond the noise in this region [m/s]."""
    mean_m_s: float
    """Mean residual in the region [m/s] (a bias shows here)."""
    share: float
    """Fraction of the excess squared residual of all regions that lies in this one [-]."""


@dataclass(frozen=True)
class BandMisfit:
    """The residual's spectral energy beyond the noise in one band (all impacts pooled)."""

    name: str
    """'below f_n', 'at f_n', 'odd harmonics' or 'elsewhere'."""
    low_hz: float
    high_hz: float
    share: float
    """Fraction of the residual's excess energy in this band [-]."""


REGIONS = ('early, large amplitude', 'late, small amplitude', 'near reversals', 'at rest')
BANDS = ('below f_n', 'at f_n', 'odd harmonics', 'elsewhere')


def region_labels(model_velocity_m_s: np.ndarray, hit_index: int) -> np.ndarray:
    """Index into REGIONS for every sample, from the model's (noise-free) velocity.

    Motion runs from the hit to the model's last moving sample; before and after it the model
    is at rest. Each half cycle (between sign changes of the velocity) is 'early' while its
    peak speed is at least LARGE_AMPLITUDE of the first half cycle's, 'late' after; within
    it, samples slower than NEAR_REVERSAL of its peak are 'near reversals'.
    """
    velocity = np.asarray(model_velocity_m_s, dtype=float)
    labels = np.full(velocity.size, REGIONS.index('at rest'), dtype=np.int8)
    moving = np.flatnonzero(velocity[hit_index:] != 0.0)
    if moving.size == 0:
        return labels
    start, stop = hit_index, hit_index + int(moving[-1]) + 1
    segment = velocity[start:stop]
    sign = np.sign(segment)
    edges = np.concatenate(([0], np.flatnonzero(np.diff(sign) != 0) + 1, [segment.size]))
    first_peak = None
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        speed = np.abs(segment[a:b])
        peak = float(speed.max())
        if peak == 0.0:
            continue  # a stick inside the motion: the model is at rest there
        if first_peak is None:
            first_peak = peak
        label = (
            'early, large amplitude'
            if peak >= LARGE_AMPLITUDE * first_peak
            else 'late, small amplitude'
        )
        part = labels[start + a : start + b]
        part[:] = REGIONS.index(label)
        part[speed < NEAR_REVERSAL * peak] = REGIONS.index('near reversals')
        part[speed == 0.0] = REGIONS.index('at rest')
    return labels


def time_regions(
    residuals: Sequence[np.ndarray],
    model_velocities: Sequence[np.ndarray],
    hit_indices: Sequence[int],
    noise_std_m_s: float,
) -> tuple[RegionMisfit, ...]:
    """The residual (measured - model velocity) beyond the noise, by region of the decay."""
    sums = np.zeros(len(REGIONS))
    squares = np.zeros(len(REGIONS))
    counts = np.zeros(len(REGIONS), dtype=int)
    for residual, model, hit in zip(residuals, model_velocities, hit_indices, strict=True):
        labels = region_labels(model, hit)
        counts += np.bincount(labels, minlength=len(REGIONS))
        sums += np.bincount(labels, weights=residual, minlength=len(REGIONS))
        squares += np.bincount(labels, weights=residual * residual, minlength=len(REGIONS))
    excess = np.maximum(squares - counts * noise_std_m_s**2, 0.0)
    total = float(excess.sum())
    return tuple(
        RegionMisfit(
            name,
            int(counts[i]),
            math.sqrt(excess[i] / counts[i]) if counts[i] else 0.0,
            float(sums[i] / counts[i]) if counts[i] else 0.0,
            float(excess[i] / total) if total > 0.0 else 0.0,
        )
        for i, name in enumerate(REGIONS)
    )


@dataclass(frozen=True)
class BinMisfit:
    """The residual's excess over the noise where the model's speed or position is in a bin."""

    low: float
    high: float
    """Bin edges (m/s for speed, m for position)."""
    samples: int
    excess_rms_m_s: float
    """RMS of the residual beyond the noise in the bin [m/s]."""
    share: float
    """Fraction of the excess squared residual of all bins that lies in this one [-]."""


def binned_misfit(
    residuals: Sequence[np.ndarray],
    keys: Sequence[np.ndarray],
    edges: np.ndarray,
    noise_std_m_s: float,
) -> tuple[BinMisfit, ...]:
    """The residual beyond the noise by bin of a key (the model's speed, its position).

    Samples whose key is NaN or outside the edges are left out (the model at rest, say).
    """
    bins = edges.size - 1
    counts = np.zeros(bins)
    squares = np.zeros(bins)
    for residual, key in zip(residuals, keys, strict=True):
        index = np.searchsorted(edges, key, side='right') - 1
        inside = (index >= 0) & (index < bins) & np.isfinite(key)
        counts += np.bincount(index[inside], minlength=bins)
        squares += np.bincount(index[inside], weights=residual[inside] ** 2, minlength=bins)
    excess = np.maximum(squares - counts * noise_std_m_s**2, 0.0)
    total = float(excess.sum())
    return tuple(
        BinMisfit(
            float(edges[i]),
            float(edges[i + 1]),
            int(counts[i]),
            math.sqrt(excess[i] / counts[i]) if counts[i] else 0.0,
            float(excess[i] / total) if total > 0.0 else 0.0,
        )
        for i in range(bins)
    )


def band_edges_hz(natural_frequency_hz: float) -> dict[str, list[tuple[float, float]]]:
    """The frequency intervals of each band in BANDS ('elsewhere' is what the others leave)."""
    width = HARMONIC_HALF_WIDTH * natural_frequency_hz
    return {
        'below f_n': [(0.0, natural_frequency_hz - width)],
        'at f_n': [(natural_frequency_hz - width, natural_frequency_hz + width)],
        'odd harmonics': [
            (h * natural_frequency_hz - width, h * natural_frequency_hz + width)
            for h in range(3, HIGHEST_ODD_HARMONIC + 1, 2)
        ],
    }


def band_labels(frequency_hz: np.ndarray, natural_frequency_hz: float) -> np.ndarray:
    """Index into BANDS for every frequency."""
    labels = np.full(frequency_hz.size, BANDS.index('elsewhere'), dtype=np.int8)
    for name, intervals in band_edges_hz(natural_frequency_hz).items():
        for low, high in intervals:
            labels[(frequency_hz >= low) & (frequency_hz < high)] = BANDS.index(name)
    return labels


def frequency_bands(
    residuals: Sequence[np.ndarray],
    sample_rate_hz: float,
    natural_frequency_hz: float,
    noise_std_m_s: float,
) -> tuple[BandMisfit, ...]:
    """The residual's spectral energy beyond the noise, by band (DFT of each whole record)."""
    excess = np.zeros(len(BANDS))
    for residual in residuals:
        power, frequency = residual_power(residual, sample_rate_hz, noise_std_m_s)
        excess += np.bincount(
            band_labels(frequency, natural_frequency_hz), weights=power, minlength=len(BANDS)
        )
    excess = np.maximum(excess, 0.0)
    total = float(excess.sum())
    edges = band_edges_hz(natural_frequency_hz)
    nyquist = 0.5 * sample_rate_hz
    limits = {
        name: (max(intervals[0][0], 0.0), intervals[-1][1]) for name, intervals in edges.items()
    }
    limits['elsewhere'] = (0.0, nyquist)
    return tuple(
        BandMisfit(name, *limits[name], float(excess[i] / total) if total > 0.0 else 0.0)
        for i, name in enumerate(BANDS)
    )


def residual_power(
    residual: np.ndarray, sample_rate_hz: float, noise_std_m_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """(|DFT r|^2 minus its white-noise expectation n s^2, frequency [Hz]) on the rfft grid."""
    residual = np.asarray(residual, dtype=float)
    spectrum = np.fft.rfft(residual)
    power = spectrum.real**2 + spectrum.imag**2 - residual.size * noise_std_m_s**2
    return power, np.fft.rfftfreq(residual.size, 1.0 / sample_rate_hz)


@dataclass(frozen=True)
class DecaySignatures:
    """What the shape of a decay says about its damping and spring (one record)."""

    half_cycles: int
    """Half cycles between the first and last displacement extremum found."""
    envelope_shape: str
    """'linear' (Coulomb), 'exponential' (viscous) or 'undetermined' (too few half cycles)."""
    linear_r2: float
    exponential_r2: float
    peak_map_slope: float
    """Slope of the half-swing amplitude map a_n+1 = slope a_n + intercept: 1 for Coulomb,
    exp(-pi zeta) for viscous [-]."""
    peak_map_intercept_m: float
    """Intercept of that map: -2 mu N / k for Coulomb, 0 for viscous [m]."""
    centre_m: float
    """Mean oscillation centre, relative to the position before the hit [m]."""
    centre_drift_m_per_s: float
    """Slope of the half-cycle centres against time [m/s]."""
    half_period_s: float
    """Mean time between successive displacement extrema [s]."""
    half_period_amplitude_slope_s_per_m2: float
    """Slope of the half period against the square of the amplitude: Duffing stiffening
    (k3 > 0) makes it negative [s/m^2]."""


_EMPTY_DECAY = DecaySignatures(
    0,
    'undetermined',
    math.nan,
    math.nan,
    math.nan,
    math.nan,
    math.nan,
    math.nan,
    math.nan,
    math.nan,
)


def decay_signatures(
    velocity_m_s: np.ndarray, sample_rate_hz: float, hit_index: int, natural_frequency_hz: float
) -> DecaySignatures:
    """The decay signatures of one velocity record (measured or simulated).

    The velocity is low-passed (zero-phase, 8 f_n) against the noise, integrated to the
    displacement from the sample before the hit (where the rig is taken at rest at x = 0),
    and its extrema are located where the filtered velocity changes sign, with crossings
    closer than a quarter period merged.
    """
    velocity = np.asarray(velocity_m_s, dtype=float)
    start = max(hit_index - 1, 0)
    if velocity.size - start < 4 * sample_rate_hz / natural_frequency_hz:
        return _EMPTY_DECAY
    cutoff = min(8.0 * natural_frequency_hz, 0.4 * sample_rate_hz)
    sos = signal.butter(4, cutoff, fs=sample_rate_hz, output='sos')
    smooth = signal.sosfiltfilt(sos, velocity[start:])
    displacement = np.concatenate(([0.0], np.cumsum(0.5 * (smooth[1:] + smooth[:-1]))))
    displacement /= sample_rate_hz
    extrema = _extrema(smooth, displacement, sample_rate_hz, natural_frequency_hz)
    if extrema.size < 4:
        return _EMPTY_DECAY
    positions = np.interp(extrema, np.arange(displacement.size), displacement)
    times = extrema / sample_rate_hz
    swings = 0.5 * np.abs(np.diff(positions))  # half swing of each half cycle
    centres = 0.5 * (positions[1:] + positions[:-1])
    mid_times = 0.5 * (times[1:] + times[:-1])
    half_periods = np.diff(times)
    index = np.arange(swings.size, dtype=float)
    linear_r2 = _r_squared(index, swings)
    exponential_r2 = _r_squared(index, np.log(swings)) if np.all(swings > 0) else math.nan
    if swings.size < 4:
        shape = 'undetermined'
    else:
        shape = 'linear' if linear_r2 >= exponential_r2 else 'exponential'
    slope, intercept = (
        np.polyfit(swings[:-1], swings[1:], 1) if swings.size >= 3 else (math.nan, math.nan)
    )
    drift = np.polyfit(mid_times, centres, 1)[0] if centres.size >= 3 else math.nan
    period_slope = np.polyfit(swings**2, half_periods, 1)[0] if swings.size >= 3 else math.nan
    return DecaySignatures(
        half_cycles=int(swings.size),
        envelope_shape=shape,
        linear_r2=linear_r2,
        exponential_r2=exponential_r2,
        peak_map_slope=float(slope),
        peak_map_intercept_m=float(intercept),
        centre_m=float(np.mean(centres)),
        centre_drift_m_per_s=float(drift),
        half_period_s=float(np.mean(half_periods)),
        half_period_amplitude_slope_s_per_m2=float(period_slope),
    )


def _extrema(
    smooth: np.ndarray, displacement: np.ndarray, sample_rate_hz: float, natural_frequency_hz: float
) -> np.ndarray:
    """Times of the displacement extrema [samples, fractional]: where the velocity turns.

    Only motion well above the filtered noise counts. Each turn is the zero crossing of the
    smoothed velocity between two moving stretches of opposite sign (linear between samples);
    the last is where the motion stops for good. Turns closer than a quarter period merge.
    """
    speed_floor = 0.02 * float(np.max(np.abs(smooth)))
    sign = np.sign(np.where(np.abs(smooth) < speed_floor, 0.0, smooth))
    moving = np.flatnonzero(sign != 0.0)
    if moving.size < 2:
        return np.empty(0)
    signs = sign[moving]
    turns = []
    for c in np.flatnonzero(np.diff(signs) != 0):
        a, b = moving[c], moving[c + 1]
        stretch = smooth[a : b + 1] * signs[c]
        i = a + int(np.argmax(stretch <= 0.0)) - 1  # last sample before the crossing
        turns.append(i + smooth[i] / (smooth[i] - smooth[i + 1]))
    last = int(moving[-1])
    quarter = int(0.25 * sample_rate_hz / natural_frequency_hz)
    tail = displacement[last : last + quarter] * signs[-1]
    turns.append(last + float(np.argmax(tail)))
    minimum_gap = 0.25 * sample_rate_hz / natural_frequency_hz
    merged = [turns[0]]
    for turn in turns[1:]:
        if turn - merged[-1] >= minimum_gap:
            merged.append(turn)
    return np.asarray(merged)


def _r_squared(x: np.ndarray, y: np.ndarray) -> float:
    """Coefficient of determination of a straight-line fit of y on x."""
    if x.size < 3:
        return math.nan
    slope, intercept = np.polyfit(x, y, 1)
    total = float(np.sum((y - y.mean()) ** 2))
    if total == 0.0:
        return math.nan
    return 1.0 - float(np.sum((y - slope * x - intercept) ** 2)) / total


def rest_velocity(
    measured_m_s: np.ndarray, model_m_s: np.ndarray, hit_index: int, noise_std_m_s: float
) -> tuple[float, float]:
    """(mean, standard error) of the measured velocity where the model is at rest [m/s]."""
    measured = np.asarray(measured_m_s, dtype=float)
    at_rest = np.asarray(model_m_s) == 0.0
    at_rest[hit_index : hit_index + 1] = False
    count = int(np.count_nonzero(at_rest))
    if count == 0:
        return math.nan, math.nan
    return float(np.mean(measured[at_rest])), noise_std_m_s / math.sqrt(count)


def phase_delay_s(
    measured_m_s: np.ndarray,
    model_m_s: np.ndarray,
    sample_rate_hz: float,
    natural_frequency_hz: float,
) -> float:
    """Delay of the measured velocity behind the model's, from the slope of their phase [s].

    A pure delay tau multiplies the measured spectrum by exp(-i w tau), so the phase of
    V_measured conj(V_model) falls as -w tau (the FRF's phase slope, force spectrum
    cancelled). Least squares through the origin over the bins up to the 25th odd harmonic,
    weighted by |V_model|^2 so that noise-dominated bins hardly count.
    """
    measured = np.fft.rfft(np.asarray(measured_m_s, dtype=float))
    model = np.fft.rfft(np.asarray(model_m_s, dtype=float))
    frequency = np.fft.rfftfreq(np.asarray(measured_m_s).size, 1.0 / sample_rate_hz)
    band = (frequency > 0.0) & (frequency <= (HIGHEST_ODD_HARMONIC + 1) * natural_frequency_hz)
    omega = 2.0 * math.pi * frequency[band]
    cross = measured[band] * np.conj(model[band])
    weight = np.abs(model[band]) ** 2
    phase = np.angle(cross)
    denominator = float(np.sum(weight * omega * omega))
    if denominator == 0.0:
        return math.nan
    return -float(np.sum(weight * omega * phase)) / denominator


@dataclass(frozen=True)
class SpectralPeak:
    """A narrow-band peak of the residual that is not at an odd harmonic of f_n."""

    frequency_hz: float
    excess_power: float
    """Residual power beyond the noise in the peak's bins, summed over impacts [(m/s)^2 s^2]."""
    significance: float
    """That excess over the standard deviation of the noise power in the same bins [-]."""


def non_harmonic_peaks(
    residuals: Sequence[np.ndarray],
    sample_rate_hz: float,
    natural_frequency_hz: float,
    noise_std_m_s: float,
    *,
    lowest_hz: float | None = None,
    highest_hz: float | None = None,
    count: int = 3,
    threshold: float = 8.0,
    skip_harmonics: bool = True,
) -> tuple[SpectralPeak, ...]:
    """The strongest residual peaks away from f_n and its odd harmonics, above `threshold`.

    The residual power beyond the noise is summed over impacts and over a sliding window of
    2 f_n x HARMONIC_HALF_WIDTH; a peak counts when that sum exceeds `threshold` standard
    deviations of the noise's own power in the window (the noise power in one bin is
    exponential, std n s^2) and stands out of its surroundings by half its height. Searched
    from 1.5 f_n (default) to 200 f_n; with skip_harmonics False the odd-harmonic bands are
    searched too.
    """
    lowest_hz = 1.5 * natural_frequency_hz if lowest_hz is None else lowest_hz
    highest_hz = (
        min(200.0 * natural_frequency_hz, 0.45 * sample_rate_hz)
        if highest_hz is None
        else highest_hz
    )
    total = None
    noise_power = 0.0
    for residual in residuals:
        power, frequency = residual_power(residual, sample_rate_hz, noise_std_m_s)
        if total is None:
            total = np.zeros_like(power)
            grid = frequency
        if power.size != total.size:
            power = np.interp(grid, frequency, power)
        total += power
        noise_power += residual.size * noise_std_m_s**2
    if total is None:
        return ()
    step_hz = grid[1] - grid[0]
    width = max(1, round(2 * HARMONIC_HALF_WIDTH * natural_frequency_hz / step_hz))
    window = np.convolve(total, np.ones(width), mode='same')
    significance = window / (noise_power * math.sqrt(width))
    allowed = (grid >= lowest_hz) & (grid <= highest_hz)
    if skip_harmonics:
        allowed &= band_labels(grid, natural_frequency_hz) == BANDS.index('elsewhere')
    # Local maxima of the whole curve that stand out of it by half their height at least, so
    # a ripple on the skirt of a strong peak (at f_n, at a harmonic) is no peak of its own.
    peaks, properties = signal.find_peaks(significance, distance=width, prominence=0.0)
    keep = (
        allowed[peaks]
        & (significance[peaks] >= threshold)
        & (properties['prominences'] >= 0.5 * significance[peaks])
    )
    peaks = peaks[keep]
    strongest = peaks[np.argsort(significance[peaks])[::-1][:count]]
    return tuple(
        SpectralPeak(float(grid[i]), float(window[i]), float(significance[i])) for i in strongest
    )
