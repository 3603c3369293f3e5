"""Impulse, contact, FRFs, windows, averaging and the linear-in-impulse law.

(Hits are grouped into force levels by `levels`.)

Plain functions in the style of scipy.signal: arrays in, arrays out, SI units (named where not
obvious). The FRF method is the paper's (Kossack, Ziegert, Schmitz 2019, Sec. 5): the DFT of the
whole force and velocity records, mobility = V/F, receptance = mobility / (i*omega). Friction
brings the FMM to rest inside the record, so the record is its own period and no window is
needed; the force and exponential windows are here for records that do not settle (a linear
structure, a noisy force channel), as impact-testing users expect.

Sign convention: numpy's DFT, X[k] = sum x[n] exp(-2*pi*i*k*n/N), so a harmonic x = X exp(i w t)
has velocity i w X, and receptance = mobility / (i w), accelerance = i w * mobility.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fmm_ros.core.signal import _kernels
from fmm_ros.errors import BadInputError


def frequency_axis(n_fft: int, sample_rate_hz: float, bins: int | None = None) -> np.ndarray:
    """Frequencies [Hz] of the one-sided DFT bins of an `n_fft`-sample record (the first bins).

    np.fft.rfftfreq's numbers (bin index times 1 / (n_fft d)), only the bins asked for.
    """
    if bins is None:
        return np.fft.rfftfreq(n_fft, d=1.0 / sample_rate_hz)
    return np.arange(min(bins, n_fft // 2 + 1)) * (1.0 / (n_fft * (1.0 / sample_rate_hz)))


def band_bins(n_fft: int, sample_rate_hz: float, band_limit_hz: float | None) -> int:
    """Number of one-sided bins from DC up to and including `band_limit_hz` (None: all)."""
    n_bins = n_fft // 2 + 1
    if band_limit_hz is None:
        return n_bins
    return min(n_bins, int(np.floor(band_limit_hz * n_fft / sample_rate_hz + 1e-9)) + 1)


def first_true(mask: np.ndarray) -> int:
    """Index of the first True in a boolean array, or -1 (no index array is allocated)."""
    if mask.size == 0:
        return -1
    index = int(np.argmax(mask))
    return index if mask[index] else -1


FIRST_CHUNK = 1024
"""`first_where` tests this many values first, then 16 times more at each step."""


def first_where(test: Callable[[np.ndarray], np.ndarray], values: np.ndarray) -> int:
    """`first_true(test(values))` for an elementwise test, testing little past the first True.

    The test runs over chunks growing 16-fold from `FIRST_CHUNK` values: the end of a pulse a
    few samples on costs a thousand values tested, not the whole record's (the same index, as
    each value's verdict is its own). values may be a view, reversed or not.
    """
    low, chunk = 0, FIRST_CHUNK
    while low < values.size:
        high = min(values.size, low + chunk)
        found = first_true(test(values[low:high]))
        if found >= 0:
            return low + found
        low, chunk = high, 16 * chunk
    return -1


def impulse(force_n: np.ndarray, sample_rate_hz: float) -> float:
    """Area under the force record [N*s] by the trapezoid rule, as in the paper (Sec. 5)."""
    return float(np.trapezoid(force_n, dx=1.0 / sample_rate_hz))


def pulse_impulse(
    force_n: np.ndarray, sample_rate_hz: float, threshold_n: float, start_index: int = 0
) -> float:
    """Area under the first force pulse [N*s], trapezoid rule, baseline removed (paper Sec. 5).

    The pulse is `pulse_extent`'s: the pulse's feet count but the rest of the record does
    not: integrated over a 33 s record, 0.2 N of sensor noise alone would add +-0.012 N*s (1 %
    of a paper-level hit) and a 0.1 N offset 3.3 N*s. NaN when the force never reaches the
    threshold.
    """
    extent = pulse_extent(force_n, threshold_n, start_index)
    if extent is None:
        return float('nan')
    low, high, baseline = extent
    with np.errstate(invalid='ignore'):  # an infinite sample makes the impulse NaN, quietly
        return impulse(force_n[low:high] - baseline, sample_rate_hz)


def pulse_extent(
    force_n: np.ndarray, threshold_n: float, start_index: int = 0
) -> tuple[int, int, float] | None:
    """[low, high) of the first force pulse and the baseline under it [N], or None.

    The pulse is the first run at or above `threshold_n` from `start_index`, widened on each
    side to the sample where the force minus the baseline first comes back to zero. Baseline:
    the mean force before the pulse (0 when the record starts in it). None when the force
    never reaches the threshold.
    """
    interval = contact_interval(force_n, threshold_n, start_index)
    if interval is None:
        return None
    start, stop = interval
    with np.errstate(invalid='ignore'):  # NaN or infinite samples: the extent stops there
        baseline = float(np.mean(force_n[:start])) if start else 0.0
        back = force_n[start - 1 :: -1] if start else force_n[:0]
        before = first_where(lambda chunk: chunk - baseline <= 0.0, back)
        low = start - 1 - before if before >= 0 else 0
        after = first_where(lambda chunk: chunk - baseline <= 0.0, force_n[stop:])
        high = stop + after + 1 if after >= 0 else force_n.size
    return low, high, baseline


def pulse_spectrum(
    force_n: np.ndarray, threshold_n: float, n_fft: int | None = None, start_index: int = 0
) -> np.ndarray:
    """One-sided DFT of the first force pulse alone, baseline removed, zero-padded to n_fft.

    The excitation a hit puts in: what the force channel holds outside the pulse (a zero
    offset, drift, hum, noise) excites nothing, but in the whole record's DFT an offset of
    0.05 % of the hit outweighs the hit at DC and collapses a 20 dB band check to 0 Hz.
    Unscaled like `spectra`, on the same bins. NaN when the force never reaches the threshold.
    """
    n = force_n.size if n_fft is None else n_fft
    extent = pulse_extent(force_n, threshold_n, start_index)
    if extent is None:
        return np.full(n // 2 + 1, np.nan, dtype=complex)
    low, high, baseline = extent
    pulse = np.zeros(n)
    pulse[low:high] = force_n[low:high] - baseline
    with np.errstate(invalid='ignore'):  # a NaN sample: NaN bins, as `spectra` gives
        return np.fft.rfft(pulse)


def contact_interval(
    force_n: np.ndarray, threshold_n: float, start_index: int = 0
) -> tuple[int, int] | None:
    """First run of samples at or above `threshold_n` from `start_index`, as [start, stop).

    None when the force never reaches the threshold. A run still going at the end of the
    record stops at its length.
    """
    above = first_where(lambda chunk: chunk >= threshold_n, force_n[start_index:])
    if above < 0:
        return None
    start = start_index + above
    below = first_where(lambda chunk: ~(chunk >= threshold_n), force_n[start:])
    stop = start + below if below >= 0 else force_n.size
    return start, stop


def contact_duration(
    force_n: np.ndarray, sample_rate_hz: float, threshold_n: float, start_index: int = 0
) -> float:
    """Time [s] the first force pulse stays at or above `threshold_n`.

    The up- and down-crossings are interpolated linearly between samples, so the duration is
    not quantised to the sample period (a 3 ms pulse is 30 samples at 10 kHz). NaN when the
    force never reaches the threshold.
    """
    interval = contact_interval(force_n, threshold_n, start_index)
    if interval is None:
        return float('nan')
    start, stop = interval
    rise = float(start)
    with np.errstate(invalid='ignore'):  # NaN or infinite neighbours give NaN, quietly
        if start > 0:
            before, at = force_n[start - 1], force_n[start]
            rise = start - (at - threshold_n) / (at - before)
        fall = float(stop - 1)
        if stop < force_n.size:
            last, after = force_n[stop - 1], force_n[stop]
            fall = stop - 1 + (last - threshold_n) / (last - after)
    return float((fall - rise) / sample_rate_hz)


def spectra(
    force_n: np.ndarray, velocity_m_s: np.ndarray, n_fft: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """One-sided DFTs (F, V) of force and velocity, zero-padded to `n_fft` samples.

    The spectra are left unscaled: only their ratios and products enter the FRFs, where any
    scale cancels. Zero padding appends rest (no force, no motion), which is what a record
    that ended at rest would have contained.
    """
    n = force_n.size if n_fft is None else n_fft
    # numpy's pocketfft (scipy.fft's, to the bit), not scipy's: replay imports no scipy.
    with np.errstate(invalid='ignore'):  # a NaN sample gives NaN bins, the record is flagged
        return np.fft.rfft(force_n, n=n), np.fft.rfft(velocity_m_s, n=n)


def mobility(force_spectrum: np.ndarray, velocity_spectrum: np.ndarray) -> np.ndarray:
    """Mobility V/F [m/(N*s)] bin by bin; NaN where the force spectrum is exactly zero."""
    out = np.full(np.broadcast(force_spectrum, velocity_spectrum).shape, np.nan, dtype=complex)
    with np.errstate(invalid='ignore'):  # NaN spectra (records with gaps) stay NaN
        np.divide(velocity_spectrum, force_spectrum, out=out, where=force_spectrum != 0)
    return out


def receptance_from_mobility(
    mobility_m_per_n_s: np.ndarray, frequency_hz: np.ndarray
) -> np.ndarray:
    """Receptance X/F [m/N] = mobility / (i*omega); 0 at DC, where it is undefined.

    Velocity alone does not determine the mean displacement, so the DC bin carries no
    receptance; 0 (not NaN) keeps averages and peak searches over the array well defined, and
    peak searches start above DC anyway.
    """
    omega = 2 * np.pi * np.asarray(frequency_hz, dtype=float)
    out = np.zeros(np.broadcast(mobility_m_per_n_s, omega).shape, dtype=complex)
    np.divide(mobility_m_per_n_s, 1j * omega, out=out, where=omega != 0)
    return out


def accelerance_from_mobility(
    mobility_m_per_n_s: np.ndarray, frequency_hz: np.ndarray
) -> np.ndarray:
    """Accelerance A/F [m/(N*s^2)] = i*omega * mobility (0 at DC)."""
    return 2j * np.pi * np.asarray(frequency_hz, dtype=float) * mobility_m_per_n_s


def force_window(
    n_samples: int, sample_rate_hz: float, *, start_index: int, width_s: float, taper_s: float = 0.0
) -> np.ndarray:
    """Force window: 1 up to `width_s` after `start_index`, a half-cosine taper, then 0.

    Applied to the force channel only, it zeroes the sensor noise after the hammer pulse (and
    the pre-trigger offset is subtracted by the caller) so the force spectrum is the pulse's.
    """
    if width_s <= 0 or taper_s < 0:
        raise BadInputError(
            f'force window width must be > 0 and taper >= 0, got {width_s} s, {taper_s} s'
        )
    window = np.zeros(n_samples)
    flat_end = min(n_samples, start_index + int(round(width_s * sample_rate_hz)))
    window[:flat_end] = 1.0
    taper = int(round(taper_s * sample_rate_hz))
    if taper > 0 and flat_end < n_samples:
        ramp = 0.5 * (1 + np.cos(np.pi * np.arange(1, taper + 1) / (taper + 1)))
        stop = min(n_samples, flat_end + taper)
        window[flat_end:stop] = ramp[: stop - flat_end]
    return window


def exponential_window(
    n_samples: int, sample_rate_hz: float, *, decay_time_s: float, start_index: int
) -> np.ndarray:
    """Exponential window exp(-(t - t0) / decay_time_s), t0 at `start_index` (the trigger).

    Applied to both channels it makes a lightly damped response die out inside the record.
    Because exp(-(t - t0)/tau) = exp(-(t - s)/tau) * exp(-(s - t0)/tau), the windowed pair of a
    linear system is exactly the input/output pair of the system whose impulse response is
    h(t) exp(-t/tau): the measured FRF is H evaluated at s = i*omega + 1/tau, i.e. every
    mode's decay rate is raised by 1/tau. `exponential_window_damping_ratio` gives the damping
    ratio to subtract from a mode fitted to such an FRF (the usual correction).
    """
    if decay_time_s <= 0:
        raise BadInputError(f'exponential window decay time must be > 0, got {decay_time_s} s')
    t_s = (np.arange(n_samples) - start_index) / sample_rate_hz
    return np.exp(-t_s / decay_time_s)


def exponential_window_damping_ratio(decay_time_s: float, natural_frequency_hz: float) -> float:
    """Damping ratio [-] an exponential window adds to a mode at `natural_frequency_hz`.

    zeta_true = zeta_measured - 1 / (decay_time_s * omega_n).
    """
    return 1.0 / (decay_time_s * 2 * np.pi * natural_frequency_hz)


@dataclass(frozen=True, eq=False)
class FrfAverage:
    """Averages of one group of trials, bin by bin (mobility in m/(N*s), coherence 0..1)."""

    # Plain frequency-domain mean of the trials' V/F: the paper's average (Sec. 5, Fig. 16).
    mean_mobility: np.ndarray
    # Cross-spectrum / force auto-spectrum: unbiased by noise on the velocity.
    h1_mobility: np.ndarray
    # Velocity auto-spectrum / cross-spectrum: unbiased by noise on the force.
    h2_mobility: np.ndarray
    # Ordinary coherence |G_fv|^2 / (G_ff G_vv) = H1/H2; exactly 1 for a single trial.
    coherence: np.ndarray


def average_frf(force_spectra: np.ndarray, velocity_spectra: np.ndarray) -> FrfAverage:
    """Plain mean, H1, H2 and coherence over trials (axis 0) of force and velocity spectra."""
    force = np.atleast_2d(force_spectra)
    velocity = np.atleast_2d(velocity_spectra)
    if force.shape != velocity.shape:
        raise BadInputError(
            f'force spectra {force.shape} and velocity spectra {velocity.shape} '
            'must have the same shape (trials, bins)'
        )
    g_ff = np.sum(np.abs(force) ** 2, axis=0)
    g_vv = np.sum(np.abs(velocity) ** 2, axis=0)
    g_fv = np.sum(np.conj(force) * velocity, axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        h1 = g_fv / g_ff
        h2 = g_vv / np.conj(g_fv)
        coherence = np.abs(g_fv) ** 2 / (g_ff * g_vv)
    return FrfAverage(
        mean_mobility=np.mean(mobility(force, velocity), axis=0),
        h1_mobility=h1,
        h2_mobility=h2,
        coherence=coherence,
    )


REVERSALS = 'reversals'
"""f_n timed by the period between velocity reversals (`natural_frequency`)."""

DFT_PEAK = 'dft_peak'
"""f_n read at the peak of a short ring's spectrum (`dft_peak_frequency`)."""

NATURAL_FREQUENCY_METHODS: dict[str, str] = {
    REVERSALS: 'period between velocity reversals',
    DFT_PEAK: "peak of a short ring's spectrum",
}
"""How f_n was found, by method name: what the results, tables and the report say about it."""


@dataclass(frozen=True)
class NaturalFrequency:
    """A hit's f_n [Hz], its uncertainty [Hz] and how it was found ('' when it was not)."""

    value_hz: float
    uncertainty_hz: float
    method: str


def natural_frequency_of_hit(
    velocity_m_s: np.ndarray,
    sample_rate_hz: float,
    response_spectrum: np.ndarray,
    pulse_spectrum: np.ndarray,
    frequency_hz: np.ndarray,
    band_hz: tuple[float, float],
) -> NaturalFrequency:
    """f_n from the velocity reversals, or, for a ring too short for them, from its DFT peak.

    `natural_frequency` times the reversals when three strong ones follow each other (no
    uncertainty stated: NaN; between reversals the motion is the free oscillator's, and the
    period is good to about 1e-3 in the held-out worlds); a hit that rings one or two cycles
    before it sticks has too few, and its f_n is the peak of |response / pulse| spectrum in
    band_hz with its uncertainty (`dft_peak_frequency`). NaN, method '', when neither finds
    one: the record has no peak.
    """
    value = natural_frequency(velocity_m_s, sample_rate_hz)
    if np.isfinite(value):
        return NaturalFrequency(value, float('nan'), REVERSALS)
    value, uncertainty = dft_peak_frequency(
        response_spectrum, pulse_spectrum, frequency_hz, band_hz, velocity_m_s.size / sample_rate_hz
    )
    if np.isfinite(value):
        return NaturalFrequency(value, uncertainty, DFT_PEAK)
    return NaturalFrequency(float('nan'), float('nan'), '')


PEAK_TOP_SHARE = 0.1
"""`dft_peak_frequency` fits the bins within this share of the peak's height (its top)."""


def dft_peak_frequency(
    response_spectrum: np.ndarray,
    pulse_spectrum: np.ndarray,
    frequency_hz: np.ndarray,
    band_hz: tuple[float, float],
    record_s: float,
) -> tuple[float, float]:
    """f_n [Hz] of a short ring from the peak of |response / pulse| spectrum, and its uncertainty.

    The FRF's magnitude with the hammer pulse alone as the force (`pulse_spectrum`: the force
    channel's noise over a 33 s record ripples |V/F| by a few % from bin to bin, enough to
    move the top of a peak as broad as a 0.8 s ring's). The peak is the largest value in
    band_hz; a parabola fitted by least squares over its top (the bins around it within
    `PEAK_TOP_SHARE` of its height, at least three) places it between bins and gives its
    height M and curvature M''. The uncertainty [Hz] combines two parts:

    - the ring's duration: a ring of T seconds has a lobe 1/T wide, and the tail of its
      negative-frequency image leans on it. For a tone of duration T the image moves the
      peak by at most 12 / (omega T^2) (its slope at the peak over the lobe's curvature),
      and the lobe's curvature measures T: M'' / M = (2 pi T)^2 / 12. So the bound is
      M / (f |M''|), from the peak alone. A friction ring's peak lies above f_n by about
      a fifth of it (a tone whose amplitude falls linearly: 0.18-0.22 at 0.75-4 cycles);
    - the noise: the standard deviation of the parabola's vertex from the scatter of the top
      about the parabola (none with only three bins).

    (NaN, NaN) when the band holds no peak: its largest value lies where the top reaches the
    band's edge (a response that never reverses peaks at DC), or the spectrum is undefined.
    record_s: the record's duration, the scale of the bins' frequency offsets in the fit.
    """
    inside = np.flatnonzero((frequency_hz >= band_hz[0]) & (frequency_hz <= band_hz[1]))
    if inside.size < 3:
        return float('nan'), float('nan')
    with np.errstate(invalid='ignore', divide='ignore'):
        magnitude = np.abs(response_spectrum[inside] / pulse_spectrum[inside])
    if not np.isfinite(magnitude).all():
        return float('nan'), float('nan')
    best = int(np.argmax(magnitude))
    starts, stops = runs(magnitude >= (1.0 - PEAK_TOP_SHARE) * magnitude[best])
    run = int(np.searchsorted(starts, best, side='right')) - 1
    low, high = int(starts[run]), int(stops[run])
    if low == 0 or high == magnitude.size:
        return float('nan'), float('nan')
    low, high = min(low, best - 1), max(high, best + 2)
    # Offsets in units of 1/record_s keep the normal equations well scaled.
    offset = (frequency_hz[inside[low:high]] - frequency_hz[inside[best]]) * record_s
    design = np.vander(offset, 3)
    (curvature, slope, height), residual, *_ = np.linalg.lstsq(design, magnitude[low:high])
    if not curvature < 0:
        return float('nan'), float('nan')
    vertex = -slope / (2.0 * curvature)
    peak_hz = float(frequency_hz[inside[best]] + vertex / record_s)
    top = height - slope**2 / (4.0 * curvature)
    second = 2.0 * curvature * record_s**2  # M'' [1/Hz^2]
    duration_bound = float(top / (peak_hz * abs(second)))
    dof = offset.size - 3
    noise = 0.0
    if dof > 0 and residual.size:
        covariance = residual[0] / dof * np.linalg.inv(design.T @ design)
        gradient = np.array([slope / (2.0 * curvature**2), -1.0 / (2.0 * curvature), 0.0])
        noise = float(np.sqrt(max(gradient @ covariance @ gradient, 0.0))) / record_s
    return peak_hz, float(np.hypot(duration_bound, noise))


REVERSAL_RATE_HZ = 5000.0
"""Rate of the block means `natural_frequency` finds reversals in [Hz]."""


MIN_REVERSAL_RUN = 2
"""Consecutive strong reversals (after the first) a half period is measured over."""


REVERSAL_HYSTERESIS_SIGMA = 4.0
"""A reversal passes from this many noise deviations below zero to as many above, or back."""


REVERSAL_MIN_PEAK_SIGMA = 30.0
"""A half cycle counts when its peak speed exceeds this many noise deviations (its reversal
times are then good to a few 1e-4 of a period)."""


MAX_HALF_PERIOD_RATIO = 2.0
"""Two neighbouring half cycles of one decay last the same (between reversals the motion is
the free linear oscillator's): lengths further apart than this factor end a run of
reversals, as where a hit's decay meets the mains hum of a resting rig."""


def natural_frequency(velocity_m_s: np.ndarray, sample_rate_hz: float) -> float:
    """The rig's natural frequency [Hz] from the time between velocity reversals.

    Between two reversals a Coulomb-damped oscillator (and a viscous one, and both) moves
    exactly as the free linear oscillator about a shifted centre, so successive velocity
    zeros are half a damped period apart, 1 / (2 f_d), with f_d = f_n sqrt(1 - zeta^2) equal
    to f_n within 1e-6 on the FMM. The FFT peaks are not: the receptance peak lies below f_n
    (friction's rest offset and the 1/omega), and the mobility peak of a decay that stops
    after a few seconds lies up to 0.4 % above it (0.2 % with a 1/33 Hz bin between them).
    The velocity is block-averaged to `REVERSAL_RATE_HZ` (a delay common to every reversal,
    which cancels; no wider smoothing, which would move each reversal by an amount that
    changes with the amplitude: the acceleration jumps by 2 mu N / m there), reversal times
    are interpolated between block means, and the half period is the slope of a line through
    the consecutive reversals of the half cycles that peak above `REVERSAL_MIN_PEAK_SIGMA`
    noise deviations and last as long as their neighbours (`MAX_HALF_PERIOD_RATIO`), of the
    runs of at least three the one with the fastest half cycle: a stick at a reversal ends a
    run, and mains hum far above a quiet vibrometer's noise makes runs of its own while the
    rig rests (1e-6 m/s of noise under 5e-5 m/s of 50 Hz hum read 49.8 Hz, the hum's
    reversals and the hit's taken as one run).
    NaN when no three such reversals follow each other (a record that barely moves or never
    reverses).
    """
    velocity = np.asarray(velocity_m_s, dtype=float)
    factor = max(1, int(round(sample_rate_hz / REVERSAL_RATE_HZ)))
    m = velocity.size // factor
    rate = sample_rate_hz / factor
    if m < 16 or not np.isfinite(velocity).all():
        return float('nan')
    smooth = block_means(velocity[: m * factor], factor)
    second = np.diff(smooth, n=2)  # the MAD of it, in place (np.median's numbers)
    np.subtract(second, median_in_place(second), out=second)
    noise = 1.4826 * median_in_place(np.abs(second, out=second)) / np.sqrt(6.0)
    # Reversal times, and the peak speed of the half cycle after each (up to the next one).
    times, _, peaks = _kernels.reversals(smooth, REVERSAL_HYSTERESIS_SIGMA * noise)
    if times.size < 3:
        return float('nan')
    strong = peaks > REVERSAL_MIN_PEAK_SIGMA * noise
    # A reversal counts when the half cycles on both sides of it are strong.
    valid = strong[1:] & strong[:-1]
    lengths = np.diff(times)  # of the half cycles between reversals
    ratio = lengths[1:] / lengths[:-1]
    valid[:-1] &= (ratio <= MAX_HALF_PERIOD_RATIO) & (ratio >= 1.0 / MAX_HALF_PERIOD_RATIO)
    run = _strongest_run(valid, peaks, MIN_REVERSAL_RUN)
    if run is None:
        return float('nan')
    kept = times[1:][run[0] : run[1]]
    half_period = float(np.polyfit(np.arange(kept.size), kept, 1)[0])
    return rate / (2.0 * half_period)


def block_means(samples: np.ndarray, factor: int) -> np.ndarray:
    """Means of consecutive blocks of `factor` samples: `samples.reshape(-1, factor).mean(1)`.

    The same numbers to the bit (a -0.0 included), and for pairs (10 kHz to
    `REVERSAL_RATE_HZ`) over 10x faster: numpy reduces rows of two slowly, and sums a row as its
    first element plus (0.0 + the rest), which the pair sum below repeats.
    """
    if factor == 2:
        return (samples[0::2] + (0.0 + samples[1::2])) / 2
    return samples.reshape(-1, factor).mean(axis=1)


def median_in_place(values: np.ndarray) -> float:
    """np.median of some finite values (reordered in place): the same value, one partition.

    The middle value of an odd count; of an even count the mean of the two middle ones as
    np.median takes it (the first plus 0.0 plus the second, halved), the lower one being the
    largest value left of the partition point.
    """
    middle = values.size // 2
    values.partition(middle)
    upper = values[middle]
    if values.size % 2:
        return float(upper)
    return float((values[:middle].max() + (0.0 + upper)) / 2)


def _strongest_run(valid: np.ndarray, peaks: np.ndarray, length: int = 1) -> tuple[int, int] | None:
    """[start, stop) of the run of valid reversals (at least `length`) with the fastest half.

    Its half cycles are peaks[start : stop + 1]; None without such a run. A stick inside a
    decay (the rig held for a moment at a reversal, noise crossing zero there) ends a run of
    strong reversals; the hit's own run holds its fastest half cycle.
    """
    starts, stops = runs(valid)
    long = np.flatnonzero(stops - starts >= length)
    if long.size == 0:
        return None
    best = max(long, key=lambda k: float(peaks[starts[k] : stops[k] + 1].max()))
    return int(starts[best]), int(stops[best])


def runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[start, stop) of every run of True in a boolean array."""
    edges = np.diff(np.concatenate(([False], mask, [False])).astype(np.int8))
    return np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)


def peak_magnitude(
    values: np.ndarray, frequency_hz: np.ndarray, band_hz: tuple[float, float]
) -> tuple[float, float]:
    """Largest |values| inside `band_hz` (inclusive) and its frequency [Hz].

    NaN bins are skipped; (NaN, NaN) when the band holds no finite bin.
    """
    inside = np.flatnonzero((frequency_hz >= band_hz[0]) & (frequency_hz <= band_hz[1]))
    magnitude = np.abs(values[inside])
    finite = np.isfinite(magnitude)
    if not finite.any():
        return float('nan'), float('nan')
    best = inside[np.flatnonzero(finite)[np.argmax(magnitude[finite])]]
    return float(np.abs(values[best])), float(frequency_hz[best])


def excitation_bandwidth(
    force_spectrum: np.ndarray, frequency_hz: np.ndarray, drop_db: float = 20.0
) -> float:
    """Highest frequency [Hz] up to which the force spectrum stays within `drop_db` of its peak.

    Above it a hammer pulse puts too little energy in (its spectrum rolls off, with nulls
    where V/F is noise divided by almost nothing), so FRF peaks there are not to be trusted:
    impact-testing practice limits the usable band by a 10-20 dB drop of the force spectrum.
    `force_spectrum` may be 2-D (trials, bins): their summed power is used. NaN when the
    spectrum is undefined (a record with missing samples).
    """
    power = np.sum(np.abs(np.atleast_2d(force_spectrum)) ** 2, axis=0)
    if not np.isfinite(power).all():
        return float('nan')
    floor = np.max(power) * 10 ** (-drop_db / 10)
    below = first_true(~(power >= floor))
    return float(frequency_hz[-1] if below < 0 else frequency_hz[max(below - 1, 0)])


@dataclass(frozen=True)
class LinearFit:
    """Least-squares line y = slope * x + intercept over `count` points, with its R^2."""

    slope: float
    intercept: float
    r2: float
    count: int


def linear_fit(x: np.ndarray, y: np.ndarray) -> LinearFit:
    """Least-squares line through (x, y) and its coefficient of determination.

    Used for peak |receptance| against impulse (the paper's Fig. 17). NaN slope and intercept
    with fewer than 2 points; NaN R^2 with fewer than 3 (two points always fit exactly) or
    when y does not vary beyond rounding (a linear structure's peak receptance: R^2 would
    only measure floating-point noise).
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = x.size
    if n < 2 or np.ptp(x) == 0:
        return LinearFit(float('nan'), float('nan'), float('nan'), n)
    slope, intercept = np.polyfit(x, y, 1)
    residual = np.sum((y - (slope * x + intercept)) ** 2)
    total = np.sum((y - y.mean()) ** 2)
    varies = np.ptp(y) > 1e-12 * np.max(np.abs(y))
    r2 = 1 - residual / total if n >= 3 and varies else float('nan')
    return LinearFit(float(slope), float(intercept), float(r2), n)
