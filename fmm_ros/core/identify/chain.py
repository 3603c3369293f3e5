"""What the acquisition chain adds to a velocity record: mains hum and a slowly drifting offset.

Neither is the rig's motion, and neither may bias mu; both are estimated from the residual of
a fit (measured minus modelled velocity), where the rig's own motion is gone, and subtracted
from the measured velocity before the fit is repeated (`fit_model` alternates the two).

- Mains hum (`mains_hum`): the mains frequency and all its harmonics at once, by synchronous
  averaging. The residual is cut into periods of the hum (P samples: the fewest whole mains
  cycles that are a whole number of samples, 200 samples for 50 Hz at 10 kHz, 500 for 60 Hz),
  grouped into segments of about `HUM_SEGMENT_S`, and each segment's periods are averaged
  into one waveform (its mean removed: a constant is the offset's). Between segment centres
  the waveform is interpolated linearly, so a mains frequency off its nominal value by up to
  about 0.05 Hz (a phase walk of 0.1 cycle a segment) is followed. Whether 50 or 60 Hz (when
  not told) and whether there is hum at all is decided by the waveforms' power against what
  noise alone gives a P-sample average (`HUM_DETECTION_Z` standard deviations above it).
  Each segment removes P degrees of freedom of the residual (1 % at 50 Hz and 10 kHz), which
  `VelocityNuisance.dof` reports.
- Drift: an offset that may creep, linear between knots `DRIFT_KNOT_S` apart
  (`DriftBasis`), by least squares. A vibrometer's zero wanders slowly (a random walk of
  1e-6 m/s per root second moves it by 6e-6 m/s in a 33 s record); what the knots leave of
  it wanders within a few seconds, where the residual's spectrum (from which the fit's
  standard errors come, `output_error`) sees it.
"""

import functools
import math
from dataclasses import dataclass

import numpy as np

MAINS_FREQUENCIES_HZ = (50.0, 60.0)
"""The mains frequencies a lab may have; the one with hum is found from the data."""


HUM_SEGMENT_S = 2.0
"""Length of the segments whose periods are averaged into one hum waveform [s]."""


HUM_DETECTION_Z = 6.0
"""Hum is present when the averaged waveforms' power exceeds noise's by this many of its
standard deviations (a false detection only costs the degrees of freedom it removes)."""


MAX_PERIOD_CYCLES = 100
"""Mains cycles a hum period may span to be a whole number of samples (else no hum removal)."""


@dataclass(frozen=True)
class VelocityNuisance:
    """What the chain added to one velocity record, estimated: offset, trend and mains hum."""

    offset_m_s: float
    """Velocity offset at the record's first sample [m/s]."""
    drift_m_s2: float
    """The offset's mean slope over the record [m/s per s]."""
    mains_hz: float
    """Mains frequency whose hum was removed [Hz]; 0 where none was found."""
    hum_rms_m_s: float
    """RMS of the removed hum [m/s]."""
    dof: int
    """Degrees of freedom of the residual the estimate used up."""
    values_m_s: np.ndarray
    """The nuisance sample by sample [m/s]: offset + trend + hum."""

    @classmethod
    def none(cls, n: int) -> 'VelocityNuisance':
        """No nuisance: zero over n samples."""
        return cls(0.0, 0.0, 0.0, 0.0, 0, np.zeros(n))


def estimate_nuisance(
    residual_m_s: np.ndarray,
    sample_rate_hz: float,
    noise_std_m_s: float,
    *,
    hum: bool,
    drift: bool,
    mains_hz: float | None = None,
) -> VelocityNuisance:
    """The hum (if `hum`) and the drifting offset (if `drift`) in a fit's velocity residual.

    noise_std_m_s: the white noise level of the record (decides whether hum is there).
    mains_hz: 50 or 60 to look for that one only; None for whichever shows.
    """
    n = residual_m_s.size
    values = np.zeros(n)
    if not (hum or drift):
        return VelocityNuisance(0.0, 0.0, 0.0, 0.0, 0, values)
    dof = 0
    found_hz, hum_rms = 0.0, 0.0
    if hum:
        found = mains_hum(residual_m_s, sample_rate_hz, noise_std_m_s, mains_hz, out=values)
        if found is not None:
            found_hz, dof = found
            hum_rms = math.sqrt(float(np.einsum('i,i->', values, values)) / n)
    offset = slope = 0.0
    if drift and n:
        basis = DriftBasis.of(n, sample_rate_hz)
        # The drift of residual - hum, from the basis's sums (no array of the difference).
        coefficients = basis.solve(basis.project(residual_m_s) - basis.project(values))
        values += basis.curve(coefficients)
        offset = float(coefficients[0])
        slope = float(coefficients[-1] - coefficients[0]) / max(n - 1, 1)
        dof += coefficients.size
    return VelocityNuisance(offset, slope * sample_rate_hz, found_hz, hum_rms, dof, values)


DRIFT_KNOT_S = 4.0
"""Spacing of the drift's knots [s]: the zero is taken as linear between them."""


@dataclass(frozen=True, eq=False)
class DriftBasis:
    """Hat functions at knots `DRIFT_KNOT_S` apart: a drift linear between its knots.

    Least squares onto them is a few sums over each knot interval; their Gram matrix is
    tridiagonal and small (nine knots in 33 s). A 33 s record's random-walk zero, which a
    straight line left at a few times 1e-6 m/s and wandering over tens of seconds (where the
    Welch spectrum behind the standard errors cannot resolve it, and it correlates with the
    rig's slow motion), is followed to what wanders within 4 s.
    """

    interval: np.ndarray
    """Per sample, the knot interval it lies in."""
    fraction: np.ndarray
    """Per sample, how far into that interval (0 at its left knot, up to 1)."""
    gram: np.ndarray
    """(knots, knots) inner products of the hat functions."""

    @classmethod
    @functools.lru_cache(maxsize=8)
    def of(cls, n: int, sample_rate_hz: float) -> 'DriftBasis':
        """The basis of an n-sample record (made once per length and rate)."""
        intervals = max(1, round((n - 1) / sample_rate_hz / DRIFT_KNOT_S))
        knots = np.linspace(0.0, n - 1, intervals + 1)
        position = np.arange(n) / max(n - 1, 1) * intervals
        interval = np.minimum(position.astype(int), intervals - 1)
        fraction = position - interval
        left, right = 1.0 - fraction, fraction
        gram = np.zeros((knots.size, knots.size))
        diagonal = np.bincount(interval, left * left, knots.size) + np.bincount(
            interval + 1, right * right, knots.size
        )
        off = np.bincount(interval, left * right, intervals)
        gram[np.diag_indices(knots.size)] = diagonal
        gram[np.arange(intervals), np.arange(1, intervals + 1)] = off
        gram[np.arange(1, intervals + 1), np.arange(intervals)] = off
        for array in (interval, fraction):
            array.flags.writeable = False
        return cls(interval, fraction, gram)

    @property
    def size(self) -> int:
        """Number of knots (the degrees of freedom a drift costs)."""
        return self.gram.shape[0]

    def project(self, values: np.ndarray) -> np.ndarray:
        """B^T values: each knot's hat-weighted sum, along the last axis."""
        rows = np.atleast_2d(values)
        out = np.empty((rows.shape[0], self.size))
        for row, target in zip(rows, out, strict=True):
            target[:] = np.bincount(
                self.interval, row * (1.0 - self.fraction), self.size
            ) + np.bincount(self.interval + 1, row * self.fraction, self.size)
        return out if values.ndim > 1 else out[0]

    def solve(self, projected: np.ndarray) -> np.ndarray:
        """Least-squares knot values from `project`'s sums."""
        return np.linalg.solve(self.gram, np.asarray(projected).T).T

    def curve(self, coefficients: np.ndarray) -> np.ndarray:
        """The drift sample by sample from knot values (along the last axis)."""
        coefficients = np.asarray(coefficients)
        return (
            coefficients[..., self.interval] * (1.0 - self.fraction)
            + coefficients[..., self.interval + 1] * self.fraction
        )

    def remove(self, rows: np.ndarray) -> np.ndarray:
        """Rows less their least-squares drift (a fresh array)."""
        return rows - self.curve(self.solve(self.project(rows)))


def hum_period_samples(sample_rate_hz: float, mains_hz: float) -> int | None:
    """The fewest samples spanning a whole number of mains cycles, or None past 100 cycles."""
    ratio = sample_rate_hz / mains_hz
    for cycles in range(1, MAX_PERIOD_CYCLES + 1):
        samples = ratio * cycles
        if abs(samples - round(samples)) < 1e-9 * samples:
            return round(samples)
    return None


def mains_hum(
    residual_m_s: np.ndarray,
    sample_rate_hz: float,
    noise_std_m_s: float,
    mains_hz: float | None = None,
    *,
    out: np.ndarray,
) -> tuple[float, int] | None:
    """Write the hum sample by sample into out; (mains frequency, degrees of freedom used).

    None (out untouched) when no hum stands out of the noise. See the module docstring.
    """
    best = None
    for frequency in MAINS_FREQUENCIES_HZ if mains_hz is None else (mains_hz,):
        period = hum_period_samples(sample_rate_hz, frequency)
        if period is None or 2 * period > residual_m_s.size:
            continue
        waveforms, periods_per_segment = _segment_waveforms(residual_m_s, period, sample_rate_hz)
        excess_z = _detection_z(waveforms, periods_per_segment, noise_std_m_s)
        if excess_z > HUM_DETECTION_Z and (best is None or excess_z > best[0]):
            best = (excess_z, frequency, period, waveforms, periods_per_segment)
    if best is None:
        return None
    _, frequency, period, waveforms, periods_per_segment = best
    _interpolate(waveforms, period, periods_per_segment, out)
    return frequency, waveforms.size


def _segment_waveforms(
    residual_m_s: np.ndarray, period: int, sample_rate_hz: float
) -> tuple[np.ndarray, int]:
    """(segments, period) mean waveforms of the residual's whole periods, and periods a segment.

    The record's last partial segment joins the one before it; samples after the last whole
    period are left out of the averages.
    """
    periods = residual_m_s.size // period
    per_segment = max(1, min(periods, round(HUM_SEGMENT_S * sample_rate_hz / period)))
    segments = max(1, periods // per_segment)
    folded = residual_m_s[: periods * period].reshape(periods, period)
    sums = np.add.reduceat(folded, np.arange(0, segments * per_segment, per_segment), axis=0)
    counts = np.full(segments, per_segment, dtype=float)
    counts[-1] = periods - (segments - 1) * per_segment
    waveforms = sums / counts[:, None]
    waveforms -= waveforms.mean(axis=1, keepdims=True)
    return waveforms, per_segment


def _detection_z(waveforms: np.ndarray, periods_per_segment: int, noise_std_m_s: float) -> float:
    """How far the waveforms' mean power stands above noise's, in its standard deviations."""
    if noise_std_m_s <= 0.0:
        return math.inf if np.any(waveforms) else 0.0
    noise_power = noise_std_m_s**2 / periods_per_segment
    power = float(np.mean(waveforms**2))
    spread = noise_power * math.sqrt(2.0 / waveforms.size)
    return (power - noise_power) / spread


def _interpolate(
    waveforms: np.ndarray, period: int, periods_per_segment: int, out: np.ndarray
) -> None:
    """Hum sample by sample into out: the waveforms, linear in time between segment centres.

    The weight between two neighbouring waveforms is held over each period (a segment spans
    a hundred of them), so each stretch between two centres is one outer product; before the
    first centre and after the last the nearest waveform holds, and samples after the last
    whole period continue the last waveform.
    """
    n = out.size
    segments = waveforms.shape[0]
    periods = n // period
    whole = out[: periods * period].reshape(periods, period)
    centres = [0] + [round((k + 0.5) * periods_per_segment) for k in range(segments)] + [periods]
    centres[-2] = min(centres[-2], periods)
    whole[: centres[1]] = waveforms[0]
    for k in range(segments - 1):
        first, last = centres[k + 1], min(centres[k + 2], periods)
        if last <= first:
            continue
        weight = (np.arange(first, last) + 0.5 - first) / (last - first)
        np.multiply.outer(weight, waveforms[k + 1] - waveforms[k], out=whole[first:last])
        whole[first:last] += waveforms[k]
    whole[centres[-2] :] = waveforms[-1]
    out[periods * period :] = waveforms[-1][: n - periods * period]
