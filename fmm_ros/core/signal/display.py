"""A sample channel decimated for live plots: one point per interval, the peak kept.

Foxglove, PlotJuggler and a browser plot one number per message against its stamp; a
`SampleBatch` of 500 samples would be one point a batch. So a channel is cut into intervals of
`samples_per_point` samples, aligned on the acquisition's sample index (interval k holds the
samples k*D .. (k+1)*D - 1), and each interval becomes one `DisplayPoint`: its sample of
largest magnitude with its sign (peak hold: a 1 ms hammer pulse keeps its height at any
decimation, where a mean or every D-th sample would lose it) and its smallest and largest
sample (the envelope). Aligning on the index puts force and velocity points at the same
instants, whichever batch sizes the sources use.

An interval that a batch ends inside waits for the next batch; a batch that does not continue
the channel (a gap, a restart) first closes the open interval with the samples it had.
NaN samples (declared missing) are left out of an interval; an interval of only NaN is none.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fmm_ros.errors import BadInputError


@dataclass(frozen=True)
class DisplayPoint:
    """One interval of a channel: where it starts and what it held [the channel's unit]."""

    first_sample_index: int
    sample_count: int
    value: float
    minimum: float
    maximum: float


class PeakDecimator:
    """Turns one channel's batches into `DisplayPoint`s, `samples_per_point` samples each."""

    def __init__(self, samples_per_point: int) -> None:
        if samples_per_point < 1:
            raise BadInputError(
                f'samples_per_point = {samples_per_point}: an interval needs at least 1 sample'
            )
        self.samples_per_point = int(samples_per_point)
        self._open_start: int | None = None  # index of the open interval's first sample
        self._open: list[np.ndarray] = []
        self._next_index: int | None = None

    def feed(self, first_sample_index: int, samples: np.ndarray) -> list[DisplayPoint]:
        """The points this batch completes (a discontinuity closes the open interval first)."""
        samples = np.asarray(samples, dtype=float)
        if samples.ndim != 1:
            raise BadInputError(f'a batch is one-dimensional, not of shape {samples.shape}')
        points: list[DisplayPoint] = []
        if self._next_index is not None and first_sample_index != self._next_index:
            points.extend(self.flush())
        size = self.samples_per_point
        index, end = int(first_sample_index), int(first_sample_index) + samples.size
        while index < end:
            start = index - index % size
            stop = min(start + size, end)
            if self._open_start != start:
                points.extend(self.flush())
                self._open_start = start
            self._open.append(samples[index - first_sample_index : stop - first_sample_index])
            if stop == start + size:
                points.extend(self.flush())
            index = stop
        self._next_index = end
        return points

    def flush(self) -> list[DisplayPoint]:
        """Close the open interval with the samples it has (none open: no point)."""
        if self._open_start is None:
            return []
        start, parts = self._open_start, self._open
        self._open_start, self._open = None, []
        block = np.concatenate(parts) if len(parts) > 1 else parts[0]
        finite = block[np.isfinite(block)]
        if finite.size == 0:
            return []
        peak = finite[np.argmax(np.abs(finite))]
        return [
            DisplayPoint(
                start, int(block.size), float(peak), float(finite.min()), float(finite.max())
            )
        ]


def samples_per_point(sample_rate_hz: float, points_per_s: float) -> int:
    """Samples per interval for points_per_s points a second of signal (at least 1)."""
    return max(1, round(sample_rate_hz / points_per_s))
