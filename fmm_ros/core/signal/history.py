"""The recent past of the force and velocity streams, by acquisition sample index.

The fitter keeps this instead of asking the analyzer for records: when the analyzer reports
an impact (its record start and length), the record is cut from here, so no multi-megabyte
service response crosses the network, and a bag replayed into the graph works the same way.
One ring per channel, preallocated; samples that never arrived are NaN.
"""

import numpy as np

from fmm_ros.constants import CHANNELS
from fmm_ros.core.signal.records import ImpactRecord

QUANTITIES = tuple(channel.quantity for channel in CHANNELS)


class SampleHistory:
    """The last `capacity_samples` of each channel, addressed by absolute sample index."""

    def __init__(self, capacity_samples: int) -> None:
        if capacity_samples < 1:
            raise ValueError(f'capacity_samples must be at least 1, got {capacity_samples}')
        self.capacity = int(capacity_samples)
        self.sample_rate_hz: float | None = None
        self._rings = {name: np.full(self.capacity, np.nan) for name in QUANTITIES}
        # Next index each channel expects; None until its first batch.
        self._next: dict[str, int | None] = dict.fromkeys(QUANTITIES)
        self._full_scale = dict.fromkeys(QUANTITIES, 0.0)

    def next_index(self, quantity: str) -> int | None:
        """The index after the last sample held for a channel (None before any)."""
        return self._next[quantity]

    def feed(
        self,
        quantity: str,
        first_sample_index: int,
        samples: np.ndarray,
        sample_rate_hz: float,
        full_scale: float = 0.0,
    ) -> None:
        """Store a batch; a jump ahead leaves NaN, a batch from the past is refused."""
        if quantity not in QUANTITIES:
            raise ValueError(f"quantity must be 'force' or 'velocity', got {quantity!r}")
        if self.sample_rate_hz is None:
            self.sample_rate_hz = float(sample_rate_hz)
        elif sample_rate_hz != self.sample_rate_hz:
            raise ValueError(
                f'{quantity} batch at {sample_rate_hz} Hz, history at '
                f'{self.sample_rate_hz} Hz: one rate for both channels'
            )
        expected = self._next[quantity]
        if expected is not None and first_sample_index < expected:
            raise ValueError(
                f'{quantity} batch at {first_sample_index} repeats samples '
                f'already held (next expected {expected})'
            )
        start = first_sample_index if expected is None else expected
        self._write(quantity, start, np.full(max(0, first_sample_index - start), np.nan))
        self._write(quantity, first_sample_index, np.asarray(samples, dtype=float))
        self._next[quantity] = first_sample_index + len(samples)
        self._full_scale[quantity] = float(full_scale)

    def _write(self, quantity: str, first: int, values: np.ndarray) -> None:
        """Put values (samples first, first + 1, ...) into the ring; only the last fit."""
        if values.size > self.capacity:
            first += values.size - self.capacity
            values = values[-self.capacity :]
        ring = self._rings[quantity]
        position = first % self.capacity
        head = min(values.size, self.capacity - position)
        ring[position : position + head] = values[:head]
        ring[: values.size - head] = values[head:]

    def covers(self, start: int, stop: int) -> bool:
        """True once both channels have reached `stop` (the record can be cut)."""
        return all(n is not None and n >= stop for n in self._next.values())

    def holds(self, start: int) -> bool:
        """True while sample `start` of both channels is still in the rings."""
        return all(n is not None and n - self.capacity <= start for n in self._next.values())

    def record(
        self, start: int, length: int, *, trigger_sample_index: int | None = None, source: str = ''
    ) -> ImpactRecord:
        """A copy of [start, start + length) of both channels as an ImpactRecord.

        Raises ValueError when the span is not (or no longer) held in full; samples that
        never arrived are NaN and listed as gaps.
        """
        stop = start + length
        if not self.covers(start, stop):
            raise ValueError(f'samples up to {stop} have not all arrived yet')
        if not self.holds(start) or length > self.capacity:
            raise ValueError(
                f'samples from {start} are no longer held (the history keeps '
                f'{self.capacity} samples)'
            )
        position = start % self.capacity
        head = min(length, self.capacity - position)
        channels = {
            name: np.concatenate((ring[position : position + head], ring[: length - head]))
            for name, ring in self._rings.items()
        }
        return ImpactRecord(
            channels['force'],
            channels['velocity'],
            self.sample_rate_hz,
            record_start_sample_index=start,
            trigger_sample_index=trigger_sample_index,
            window_samples=length,
            force_full_scale_n=self._full_scale['force'],
            velocity_full_scale_m_s=self._full_scale['velocity'],
            force_gaps=_nan_runs(channels['force']),
            velocity_gaps=_nan_runs(channels['velocity']),
            source=source,
        )


def _nan_runs(values: np.ndarray) -> tuple[tuple[int, int], ...]:
    """[start, stop) runs of NaN in values."""
    edges = np.diff(np.concatenate(([0], np.isnan(values).view(np.int8), [0])))
    return tuple(
        zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True)
    )
