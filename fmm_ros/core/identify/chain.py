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
from dataclasses import dataclass, replace

import numpy as np

from fmm_ros.errors import BadInputError

MAINS_FREQUENCIES_HZ = (50.0, 60.0)
"""The mains frequencies a lab may have; the one with hum is found from the data."""


HUM_SEGMENT_S = 2.0
"""Length of the segments whose periods are averaged into one hum waveform [s]."""


HUM_DETECTION_Z = 6.0
"""Hum is present when the averaged waveforms' power exceeds noise's by this many of its
standard deviations (a false detection only costs the degrees of freedom it removes)."""


MAX_PERIOD_CYCLES = 100
"""Mains cycles a hum period may span to be a whole number of samples (else no hum removal)."""


@dataclass(frozen=True, eq=False)
class MainsHum:
    """Mains hum found in a record: a waveform per segment, linear in time between them."""

    mains_hz: float
    period: int
    """Samples in one hum period (whole mains cycles)."""
    periods_per_segment: int
    waveforms: np.ndarray
    """(segments, period) mean waveforms, each of zero mean [m/s]."""

    @property
    def rms_m_s(self) -> float:
        """RMS of the hum [m/s]."""
        return math.sqrt(float(np.mean(self.waveforms**2)))

    def add_to(self, out: np.ndarray) -> None:
        """Add the hum sample by sample to out (`_interpolate`)."""
        hum = np.empty(out.size)
        _interpolate(self.waveforms, self.period, self.periods_per_segment, hum)
        out += hum


@dataclass(frozen=True, eq=False)
class VelocityNuisance:
    """What the chain added to one velocity record, estimated: mains hum and a drifting offset.

    Held as its parameters (a few thousand numbers), its samples made on demand.
    """

    n: int
    sample_rate_hz: float
    hum: MainsHum | None = None
    drift_knots_m_s: np.ndarray | None = None
    """The drift's values at its knots (`DriftBasis`) [m/s]; None where it was not fitted."""

    def plus(self, more: 'VelocityNuisance') -> 'VelocityNuisance':
        """The sum of this estimate and `more`, made on what it left (both are linear in data).

        ValueError for hums of different mains frequencies (look for the first's again).
        """
        hum = self.hum or more.hum
        if self.hum is not None and more.hum is not None:
            if more.hum.mains_hz != self.hum.mains_hz:
                raise BadInputError(
                    f'hum at {more.hum.mains_hz:g} Hz added to hum at {self.hum.mains_hz:g} Hz'
                )
            hum = replace(self.hum, waveforms=self.hum.waveforms + more.hum.waveforms)
        knots = [k for k in (self.drift_knots_m_s, more.drift_knots_m_s) if k is not None]
        return VelocityNuisance(self.n, self.sample_rate_hz, hum, sum(knots) if knots else None)

    @property
    def mains_hz(self) -> float:
        """Mains frequency whose hum was removed [Hz]; 0 where none was found."""
        return self.hum.mains_hz if self.hum is not None else 0.0

    @property
    def hum_rms_m_s(self) -> float:
        """RMS of the removed hum [m/s]; 0 where none."""
        return self.hum.rms_m_s if self.hum is not None else 0.0

    @property
    def offset_m_s(self) -> float:
        """Velocity offset at the record's first sample [m/s]."""
        return float(self.drift_knots_m_s[0]) if self.drift_knots_m_s is not None else 0.0

    @property
    def drift_m_s2(self) -> float:
        """The offset's mean slope over the record [m/s per s]."""
        if self.drift_knots_m_s is None or self.n < 2:
            return 0.0
        knots = self.drift_knots_m_s
        return float(knots[-1] - knots[0]) / (self.n - 1) * self.sample_rate_hz

    @property
    def dof(self) -> int:
        """Degrees of freedom of the residual the estimate used up."""
        hum = self.hum.waveforms.size if self.hum is not None else 0
        return hum + (self.drift_knots_m_s.size if self.drift_knots_m_s is not None else 0)

    @property
    def values_m_s(self) -> np.ndarray:
        """The nuisance sample by sample [m/s]: hum plus drift (a fresh array)."""
        values = np.zeros(self.n)
        if self.hum is not None:
            self.hum.add_to(values)
        if self.drift_knots_m_s is not None:
            values += DriftBasis.of(self.n, self.sample_rate_hz).curve(self.drift_knots_m_s)
        return values


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
    found = mains_hum(residual_m_s, sample_rate_hz, noise_std_m_s, mains_hz) if hum else None
    knots = None
    if drift and n > 1:
        basis = DriftBasis.of(n, sample_rate_hz)
        projected = basis.project(residual_m_s)
        if found is not None:  # the drift of residual - hum
            hum_values = np.zeros(n)
            found.add_to(hum_values)
            projected = projected - basis.project(hum_values)
        knots = basis.solve(projected)
    return VelocityNuisance(n, sample_rate_hz, found, knots)


DRIFT_KNOT_S = 4.0
"""Spacing of the drift's knots [s]: the zero is taken as linear between them."""


@dataclass(frozen=True, eq=False)
class DriftBasis:
    """Hat functions at knots `DRIFT_KNOT_S` apart: a drift linear between its knots.

    Least squares onto them is two sums over each knot interval (of v and of i v: the hats
    are linear in the sample index i there); their Gram matrix is tridiagonal and small (nine
    knots in 33 s). A 33 s record's random-walk zero, which a straight line left at a few
    times 1e-6 m/s and wandering over tens of seconds (where the Welch spectrum behind the
    standard errors cannot resolve it, and it correlates with the rig's slow motion), is
    followed to what wanders within 4 s.
    """

    n: int
    starts: tuple[int, ...]
    """First sample of each knot interval, and n at the end."""
    scale: float
    """Intervals per sample: sample i lies (i scale - j) of the way through interval j."""
    gram: np.ndarray
    """(knots, knots) inner products of the hat functions."""

    @classmethod
    @functools.lru_cache(maxsize=8)
    def of(cls, n: int, sample_rate_hz: float) -> 'DriftBasis':
        """The basis of an n-sample record (made once per length and rate)."""
        intervals = max(1, round((n - 1) / sample_rate_hz / DRIFT_KNOT_S))
        scale = intervals / max(n - 1, 1)
        starts = tuple(math.ceil(j / scale) for j in range(intervals)) + (n,)
        gram = np.zeros((intervals + 1, intervals + 1))
        index = _sample_index(n)
        for j, (first, stop) in enumerate(zip(starts[:-1], starts[1:], strict=True)):
            u = index[first:stop] * scale - j
            gram[j, j] += float(np.sum((1.0 - u) ** 2))
            gram[j + 1, j + 1] += float(np.sum(u**2))
            gram[j, j + 1] = gram[j + 1, j] = float(np.sum(u * (1.0 - u)))
        return cls(n, starts, scale, gram)

    @property
    def size(self) -> int:
        """Number of knots (the degrees of freedom a drift costs)."""
        return len(self.starts)

    def _sums(self, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per interval j: (sum of v (1 - u), sum of v u) of each row, u the hat fraction."""
        index = _sample_index(self.n)
        left = np.empty((rows.shape[0], self.size - 1))
        right = np.empty_like(left)
        for j, (first, stop) in enumerate(zip(self.starts[:-1], self.starts[1:], strict=True)):
            plain = rows[:, first:stop].sum(axis=1)
            weighted = np.einsum('pi,i->p', rows[:, first:stop], index[first:stop])
            right[:, j] = self.scale * weighted - j * plain
            left[:, j] = plain - right[:, j]
        return left, right

    def project(self, values: np.ndarray) -> np.ndarray:
        """B^T values: each knot's hat-weighted sum, along the last axis."""
        rows = np.atleast_2d(values)
        left, right = self._sums(rows)
        out = np.zeros((rows.shape[0], self.size))
        out[:, :-1] += left
        out[:, 1:] += right
        return out if np.ndim(values) > 1 else out[0]

    def solve(self, projected: np.ndarray) -> np.ndarray:
        """Least-squares knot values from `project`'s sums."""
        return np.linalg.solve(self.gram, np.asarray(projected).T).T

    def curve(self, knots: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The drift sample by sample from knot values (along the last axis), into out."""
        knots = np.asarray(knots, dtype=float)
        if out is None:
            out = np.empty((*knots.shape[:-1], self.n))
        index = _sample_index(self.n)
        for j, (first, stop) in enumerate(zip(self.starts[:-1], self.starts[1:], strict=True)):
            u = index[first:stop] * self.scale - j
            step = knots[..., j + 1] - knots[..., j]
            out[..., first:stop] = np.multiply.outer(step, u)
            out[..., first:stop] += knots[..., j, None] if knots.ndim > 1 else knots[j]
        return out

    def remove(self, rows: np.ndarray) -> None:
        """Take each row's least-squares drift off it, in place."""
        rows -= self.curve(self.solve(self.project(rows)))


@functools.lru_cache(maxsize=4)
def _sample_index(n: int) -> np.ndarray:
    """0.0, 1.0, ..., n - 1 (read-only, made once per length)."""
    index = np.arange(n, dtype=float)
    index.flags.writeable = False
    return index


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
) -> MainsHum | None:
    """The mains hum in a residual, or None when none stands out of the noise (module doc)."""
    best = None
    for frequency in MAINS_FREQUENCIES_HZ if mains_hz is None else (mains_hz,):
        period = hum_period_samples(sample_rate_hz, frequency)
        if period is None or 2 * period > residual_m_s.size:
            continue
        waveforms, periods_per_segment = _segment_waveforms(residual_m_s, period, sample_rate_hz)
        excess_z = _detection_z(waveforms, periods_per_segment, noise_std_m_s)
        if excess_z > HUM_DETECTION_Z and (best is None or excess_z > best[0]):
            best = (excess_z, MainsHum(frequency, period, periods_per_segment, waveforms))
    return best[1] if best is not None else None


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
