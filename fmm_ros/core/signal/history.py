"""The recent past of the force and velocity streams, by acquisition sample index.

The fitter keeps this instead of asking the analyzer for records: when the analyzer reports
an impact (its record start and length), the record is cut from here, so no multi-megabyte
service response crosses the network, and a bag replayed into the graph works the same way.
One ring per channel, sized from the first batch's rate (every batch carries it), and sized
again when a new acquisition runs at another rate; samples that never arrived are NaN. The
channels are aligned by the rules of `fmm_ros.core.signal.stream`, as the analyzer's are.
"""

import numpy as np

from fmm_ros.constants import CHANNELS, FORCE, VELOCITY
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.core.signal.stream import (
    DEFAULT_RULES,
    AlignedStream,
    Batch,
    ChannelLedger,
    StreamRules,
)
from fmm_ros.errors import BadInputError

QUANTITIES = tuple(channel.quantity for channel in CHANNELS)


class SampleHistory:
    """The last `history_s` seconds of each channel, addressed by absolute sample index."""

    def __init__(self, history_s: float, rules: StreamRules = DEFAULT_RULES) -> None:
        if not history_s > 0:
            raise BadInputError(f'history_s must be positive, got {history_s}')
        self.history_s = float(history_s)
        self.capacity = 0  # samples a ring holds: set by the first batch's rate
        self.sample_rate_hz: float | None = None
        self._rings: dict[str, np.ndarray] = {}
        self._first_index = 0
        self.stream = AlignedStream(self, rules)

    @property
    def ledger(self) -> dict[str, ChannelLedger]:
        """What each channel received, missed and refused (the stream's ledger)."""
        return self.stream.ledger

    @property
    def acquisitions(self) -> int:
        """Acquisitions followed so far: a record spans one of them, never two."""
        return self.stream.acquisitions

    @property
    def first_index(self) -> int:
        """The first sample index of the acquisition held (samples before it never came)."""
        return self._first_index

    @property
    def origin_s(self) -> float | None:
        """Time of sample 0 of the acquisition held [s] by its clock (None: no clock)."""
        return self.stream.origin_s

    def next_index(self, quantity: str) -> int | None:
        """The watermark of a channel (None before any batch)."""
        return self.stream.next_index(quantity)

    def feed(
        self,
        quantity: str,
        first_sample_index: int,
        samples: np.ndarray,
        sample_rate_hz: float,
        full_scale: float = 0.0,
        *,
        sender: str = '',
        stamp_ns: int = 0,
    ) -> None:
        """Store a batch; a jump ahead leaves NaN, a batch that does not fit is refused.

        Refusals are counted in `ledger`; ValueError only for malformed input.
        """
        batch = Batch.of(first_sample_index, samples, sample_rate_hz, full_scale, sender, stamp_ns)
        self.feed_batch(quantity, batch)

    def feed_batch(self, quantity: str, batch: Batch) -> None:
        """`feed` for a batch already in the stream's form (a node's message)."""
        self.stream.feed(quantity, batch)

    # -- the stream's sink ------------------------------------------------------------------------

    def begin(self, sample_rate_hz: float, first_index: int) -> None:
        """An acquisition begins: rings sized for its rate, empty."""
        self.sample_rate_hz = float(sample_rate_hz)
        self._first_index = first_index
        capacity = max(1, int(round(self.history_s * sample_rate_hz)))
        if capacity != self.capacity:
            self.capacity = capacity
            self._rings = {name: np.full(capacity, np.nan) for name in QUANTITIES}
        else:
            for ring in self._rings.values():
                ring.fill(np.nan)

    def end(self, reason: str) -> None:
        """The acquisition held ends: nothing to close (records are cut on request)."""

    def take(self, quantity: str, first_index: int, samples: np.ndarray, full_scale: float) -> None:
        """Samples at the channel's watermark."""
        self._write(quantity, first_index, samples)

    def missing(self, quantity: str, start: int, stop: int) -> None:
        """Samples that will never come are NaN (only the last capacity of them matter)."""
        start = max(start, stop - self.capacity)
        self._write(quantity, start, np.full(stop - start, np.nan))

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

    def recent(self, quantity: str, length: int) -> tuple[int, np.ndarray]:
        """A copy of a channel's last `length` samples up to its watermark, and the first's index.

        Fewer at the start of an acquisition; NaN where samples never arrived.
        """
        stop = self.stream.next_index(quantity)
        if stop is None or not self.capacity:
            return 0, np.empty(0)
        start = max(stop - length, stop - self.capacity, self._first_index)
        return start, self._copy(quantity, start, stop - start)

    def held(self, quantity: str, start: int, stop: int) -> list[tuple[int, np.ndarray]]:
        """The samples of [start, stop) of a channel still held, as (first index, copy) runs.

        Clipped to what the ring holds of the acquisition followed; samples that never
        arrived (NaN here, as are NaN samples a source sent) split the runs and are left out.
        For a recorder filling the stretch it was down: what it stores is what came.
        """
        end = self.stream.next_index(quantity)
        if end is None or not self.capacity:
            return []
        start = max(start, end - self.capacity, self._first_index)
        stop = min(stop, end)
        if stop <= start:
            return []
        values = self._copy(quantity, start, stop - start)
        return [(start + first, values[first:last]) for first, last in _runs(~np.isnan(values))]

    def _copy(self, quantity: str, start: int, count: int) -> np.ndarray:
        """A copy of samples [start, start + count) of a channel's ring (count <= capacity)."""
        position = start % self.capacity
        head = min(count, self.capacity - position)
        ring = self._rings[quantity]
        return np.concatenate((ring[position : position + head], ring[: count - head]))

    # -- records ----------------------------------------------------------------------------------

    def covers(self, start: int, stop: int) -> bool:
        """True once both channels have reached `stop` (the record can be cut)."""
        return all(
            (n := self.stream.next_index(name)) is not None and n >= stop for name in QUANTITIES
        )

    def holds(self, start: int) -> bool:
        """True while sample `start` of both channels is still in the rings."""
        return all(
            (n := self.stream.next_index(name)) is not None and n - self.capacity <= start
            for name in QUANTITIES
        )

    def record(
        self, start: int, length: int, *, trigger_sample_index: int | None = None, source: str = ''
    ) -> ImpactRecord:
        """A copy of [start, start + length) of both channels as an ImpactRecord.

        Raises ValueError when the span is not (or no longer) held in full; samples that
        never arrived are NaN and listed as gaps.
        """
        stop = start + length
        if not self.covers(start, stop):
            raise BadInputError(f'samples up to {stop} have not all arrived yet')
        if start < self._first_index:
            raise BadInputError(
                f'samples from {start} never reached this history: it begins at sample '
                f'{self._first_index} (the node started or restarted after them)'
            )
        if not self.holds(start) or length > self.capacity:
            raise BadInputError(
                f'samples from {start} are no longer held (the history keeps '
                f'{self.capacity} samples)'
            )
        channels = {name: self._copy(name, start, length) for name in self._rings}
        force, velocity = channels[FORCE.quantity], channels[VELOCITY.quantity]
        return ImpactRecord(
            force,
            velocity,
            self.sample_rate_hz,
            record_start_sample_index=start,
            trigger_sample_index=trigger_sample_index,
            window_samples=length,
            force_full_scale_n=self.stream.full_scale(FORCE.quantity),
            velocity_full_scale_m_s=self.stream.full_scale(VELOCITY.quantity),
            force_gaps=_nan_runs(force),
            velocity_gaps=_nan_runs(velocity),
            source=source,
        )


def _nan_runs(values: np.ndarray) -> tuple[tuple[int, int], ...]:
    """[start, stop) runs of NaN in values."""
    return tuple(_runs(np.isnan(values)))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) runs of True in a boolean mask."""
    edges = np.diff(np.concatenate(([0], mask.view(np.int8), [0])))
    return list(
        zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist(), strict=True)
    )
