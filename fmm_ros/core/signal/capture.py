"""Impact capture from continuous force/velocity streams, and the quality flags of a record.

One trigger rule serves every path: the ROS analyzer feeding 500-sample batches as they
arrive, `fmm analyze` on whole records and bag replay all find the same impacts, because the
rule is defined sample by sample on the acquisition's sample index and evaluated with numpy one
block at a time. Channels are aligned by sample index, never by arrival time; a batch that never
arrives is a gap (its samples are NaN in the record and the impact is flagged, never dropped).

Trigger rule (force channel, in sample-index order): an impact triggers at the first sample with
force >= trigger level while armed. The trigger disarms; the force must fall below the re-arm
level (hysteresis) and `min_spacing_s` must have passed since the trigger before the next one
can fire. The record runs from `pretrigger_s` before the trigger for `window_s` (the paper's
33 s), or, with `end_at_rest`, until the velocity has stayed within `rest_velocity_m_s` for
`rest_time_s` after the trigger.

Buffers (the capture runs for hours at 2 x 10 kHz, so no per-batch allocation): one ring per
channel holds the last pre-trigger + skew samples, which a new record copies its start from;
each open record owns a pair of window-length buffers that arriving samples are copied into.
Completed records hand those buffers out as views; `recycle()` returns them to a pool, so a
long session touches warm memory only.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fmm_ros.constants import FORCE, VELOCITY
from fmm_ros.core.signal.config import (  # noqa: F401 (re-exported: declared in config)
    DEFAULT_CAPTURE,
    FLAGS,
    CaptureConfig,
    CaptureSamples,
)
from fmm_ros.core.signal.frf import first_true, first_where
from fmm_ros.core.signal.records import Gaps, ImpactRecord
from fmm_ros.core.signal.stream import (
    MAX_STEP_SAMPLES,
    AlignedStream,
    Batch,
    ChannelLedger,
)
from fmm_ros.errors import BadInputError


class TriggerDetector:
    """The trigger rule as a state machine over force samples in index order.

    `scan` may be called with blocks of any size; the triggers found depend only on the
    samples and their indices, not on how they were split. Non-finite samples (missing or
    corrupt data) neither trigger nor re-arm.

    Two cases of an acquisition that began at a bad moment: a trigger fired within
    `min_spacing_s` of the first sample scanned, before any sample below the re-arm level,
    began mid-hit (or on an offset above the trigger level); its index goes into `truncated`.
    And a force that stays at or above the re-arm level for `min_spacing_s` after a trigger
    sits on an offset (an amplifier not reset): the detector takes the force there as its
    baseline and re-arms, trigger and re-arm levels counting above it from then on, so later
    hits still trigger; a re-arm below the absolute re-arm level drops the baseline again.
    """

    def __init__(
        self, config: CaptureConfig, sample_rate_hz: float, last_trigger: int | None = None
    ) -> None:
        """Start armed, or, given `last_trigger`, just after that trigger fired."""
        self._trigger_n = config.trigger_level_n
        self._rearm_n = config.rearm_level_n
        self._spacing = config.samples(sample_rate_hz).min_spacing
        self._last = last_trigger
        self._armed = last_trigger is None
        self._baseline_n = 0.0
        self._seen_rest = last_trigger is not None
        self._start: int | None = None  # the first index scanned
        self.truncated: set[int] = set()
        """Triggers that fired before the force was ever seen below the re-arm level."""

    def scan(self, force_n: np.ndarray, first_sample_index: int) -> list[int]:
        """Sample indices of the triggers in this block (which follows the previous one)."""
        triggers = []
        pos = 0
        if self._start is None:
            self._start = first_sample_index
        while pos < force_n.size:
            if not self._armed:
                pos = self._rearm(force_n, first_sample_index, pos)
                if pos < 0:
                    break
                continue
            if self._last is not None:
                pos = max(pos, self._last + self._spacing - first_sample_index)
            above = first_true(reaches_level(force_n[pos:], self._baseline_n + self._trigger_n))
            if not self._seen_rest:
                rest = first_true(below_level(force_n[pos:], self._baseline_n + self._rearm_n))
                self._seen_rest = 0 <= rest < above or (rest >= 0 and above < 0)
            if above < 0:
                break
            pos += above
            self._last = first_sample_index + pos
            if not self._seen_rest and self._last - self._start < self._spacing:
                self.truncated.add(self._last)
            self._armed = False
            triggers.append(self._last)
            pos += 1
        return triggers

    def _rearm(self, force_n: np.ndarray, first_sample_index: int, pos: int) -> int:
        """Re-arm from pos if the block allows: the position after it, or -1 (not in block)."""
        below = first_true(below_level(force_n[pos:], self._baseline_n + self._rearm_n))
        relock = None if self._last is None else self._last + self._spacing - first_sample_index
        if below >= 0 and (relock is None or pos + below <= relock):
            pos += below
            if force_n[pos] < self._rearm_n:
                self._baseline_n = 0.0
            self._armed = self._seen_rest = True
            return pos + 1
        if relock is not None and relock < force_n.size:
            at = max(relock, pos)
            finite = first_true(np.isfinite(force_n[at:]))
            if finite >= 0:  # still in contact a whole min_spacing on: an offset
                self._baseline_n = float(force_n[at + finite])
                self._armed = self._seen_rest = True
                return at + finite + 1
        return -1


def find_triggers(
    force_n: np.ndarray,
    sample_rate_hz: float,
    config: CaptureConfig = DEFAULT_CAPTURE,
    first_sample_index: int = 0,
) -> np.ndarray:
    """Sample indices of every impact trigger in a whole force record (the batch form)."""
    detector = TriggerDetector(config, sample_rate_hz)
    return np.asarray(
        detector.scan(np.asarray(force_n, dtype=float), first_sample_index), dtype=np.int64
    )


def with_trigger(record: ImpactRecord, config: CaptureConfig = DEFAULT_CAPTURE) -> ImpactRecord:
    """The record with its trigger located by the capture's rule, if it had none.

    Raises ValueError when the force never reaches the trigger level: such a record holds no
    impact to analyse.
    """
    if record.trigger_sample_index is not None:
        return record
    triggers = TriggerDetector(config, record.sample_rate_hz).scan(record.force_n, 0)
    if not triggers:
        where = f'{record.source}: ' if record.source else ''
        raise BadInputError(
            f'{where}the force never reaches the trigger level '
            f'{config.trigger_level_n} N (peak {np.nanmax(record.force_n):.4g} N)'
        )
    return dataclasses.replace(
        record, trigger_sample_index=record.record_start_sample_index + triggers[0]
    )


def resting_force_level(
    force_n: np.ndarray, trigger_offset: int, config: CaptureConfig = DEFAULT_CAPTURE
) -> float:
    """The force the record rests at before its hit [N]: 0, unless it sits on an offset.

    A record whose force before the trigger never falls below the re-arm level sits on an
    offset (an amplifier not reset; the trigger detector re-armed on it): its pre-trigger
    median, which the analysis subtracts, so impulse, peak, contact and FRF are the hit's.
    """
    before = force_n[:trigger_offset]
    finite = before[np.isfinite(before)]
    if finite.size == 0 or np.any(finite < config.rearm_level_n):
        return 0.0
    return float(np.median(finite))


def contact_start_index(
    force_n: np.ndarray, trigger_offset: int, config: CaptureConfig = DEFAULT_CAPTURE
) -> int:
    """Start of the pulse that fired the trigger (0 if the record starts in contact).

    That is just after the last sample below the re-arm level before the trigger.
    """
    if trigger_offset <= 0:
        return 0
    back = first_where(
        lambda chunk: below_level(chunk, config.rearm_level_n), force_n[trigger_offset - 1 :: -1]
    )
    return trigger_offset - back if back >= 0 else 0


def reaches_level(force_n: np.ndarray, level_n: float) -> np.ndarray:
    """Finite samples at or above a level (the trigger test; `quality` tests bounces by it)."""
    return (force_n >= level_n) & (force_n < np.inf)


def below_level(force_n: np.ndarray, level_n: float) -> np.ndarray:
    """Finite samples below a level (the re-arm test)."""
    return (force_n < level_n) & (force_n > -np.inf)


class _Ring:
    """One channel's recent samples by index, the capture's copy of its watermark, its gaps."""

    def __init__(self, name: str, capacity: int, origin: int) -> None:
        self.name = name
        self.ring = np.full(capacity, np.nan)
        # Every sample below this index has arrived or been declared missing (the stream's
        # watermark, mirrored).
        self.next_index = origin
        self.origin = origin
        self.gaps: list[tuple[int, int]] = []

    def store(self, first: int, samples: np.ndarray) -> None:
        """Write samples at indices first.. into the ring (samples fit in the ring)."""
        capacity = self.ring.size
        at = first % capacity
        head = min(samples.size, capacity - at)
        self.ring[at : at + head] = samples[:head]
        self.ring[: samples.size - head] = samples[head:]

    def load(self, out: np.ndarray, first: int) -> None:
        """Fill `out` with the ring's samples from index `first` (all still in the ring)."""
        capacity = self.ring.size
        assert first >= self.next_index - capacity and first + out.size <= self.next_index
        at = first % capacity
        head = min(out.size, capacity - at)
        out[:head] = self.ring[at : at + head]
        out[head:] = self.ring[: out.size - head]


class _OpenImpact:
    """An impact whose record is still being filled."""

    def __init__(
        self, trigger: int, pretrigger: int, force: np.ndarray, velocity: np.ndarray
    ) -> None:
        self.trigger = trigger
        self.start = trigger - pretrigger
        # Record length [samples]: the window, or shorter once the rig is found at rest.
        self.end = force.size
        self.end_found = False
        self.interrupted = False
        self.truncated_start = False
        self.buffers = {FORCE.quantity: force, VELOCITY.quantity: velocity}
        self.gaps: dict[str, list[tuple[int, int]]] = {FORCE.quantity: [], VELOCITY.quantity: []}
        # Rest search: next record index to examine and the at-rest run ending just before it.
        self.rest_position = pretrigger
        self.rest_run = 0

    def put(self, name: str, first: int, samples: np.ndarray) -> None:
        """Copy the part of samples (starting at index `first`) that falls in the record."""
        offset = first - self.start
        low, high = max(0, offset), min(self.end, offset + samples.size)
        if low < high:
            self.buffers[name][low:high] = samples[low - offset : high - offset]

    def add_gap(self, name: str, start: int, stop: int) -> None:
        """Note missing samples [start, stop) of a channel if they fall in the record."""
        low, high = max(start - self.start, 0), min(stop - self.start, self.end)
        if low < high:
            self.gaps[name].append((low, high))

    def lose(self, name: str, start: int, stop: int) -> None:
        """Samples [start, stop) of a channel will never come: NaN in the record and a gap."""
        self.add_gap(name, start, stop)
        low, high = (
            max(0, start - self.start),
            max(0, min(stop, self.start + self.end) - self.start),
        )
        self.buffers[name][low:high] = np.nan


class ImpactCapture:
    """Finds impacts in force and velocity streams fed in batches of any size.

    Feed each channel's batches with `feed` (the channels may be out of step with each other
    by up to `max_skew_s`), or aligned blocks of both with `feed_both`; each call returns the
    records completed by it, in order of their end. `flush` ends the stream. The channels are
    aligned by the rules of `fmm_ros.core.signal.stream` (gaps, past batches, new acquisitions,
    skew), whose account `ledger` keeps. Records are views of pooled buffers: pass a record
    to `recycle` when done with it to reuse its memory (it must not be used afterwards);
    records never recycled stay valid. Not thread-safe: a node feeds it from one callback
    group that excludes itself.
    """

    def __init__(self, config: CaptureConfig = DEFAULT_CAPTURE) -> None:
        self.config = config
        self.sample_rate_hz: float | None = None
        self._samples: CaptureSamples | None = None
        self._channels: dict[str, _Ring] = {}
        self._detector: TriggerDetector | None = None
        self._open: list[_OpenImpact] = []
        self._pool: list[tuple[np.ndarray, np.ndarray]] = []
        self._done: list[ImpactRecord] = []
        self.stream = AlignedStream(self, config.rules)

    @property
    def open_impacts(self) -> int:
        """Number of impacts triggered whose records are not complete yet."""
        return len(self._open)

    @property
    def ledger(self) -> dict[str, ChannelLedger]:
        """What each channel received, missed and refused (the stream's ledger)."""
        return self.stream.ledger

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
    ) -> list[ImpactRecord]:
        """Add one batch of `quantity` ('force' [N] or 'velocity' [m/s]) samples.

        `first_sample_index` counts from the start of acquisition; `full_scale` is the sensor
        range (0: unknown); `sender` and `stamp_ns` (header.frame_id and .stamp, the time of
        samples[0]) let the stream tell a new acquisition from a repeat. A batch that does not
        fit the stream (from the past, a stray, another acquisition's) is refused and counted
        in `ledger`; ValueError only for malformed input (unknown quantity, a sample array
        that is not one-dimensional, a rate that is not positive), with no state changed.
        """
        batch = Batch.of(first_sample_index, samples, sample_rate_hz, full_scale, sender, stamp_ns)
        return self.feed_batch(quantity, batch)

    def feed_batch(self, quantity: str, batch: Batch) -> list[ImpactRecord]:
        """`feed` for a batch already in the stream's form (a node's message, a bag's)."""
        self.stream.feed(quantity, batch)
        return self._completed()

    def feed_both(
        self,
        first_sample_index: int,
        force_n: np.ndarray,
        velocity_m_s: np.ndarray,
        sample_rate_hz: float,
        force_full_scale_n: float = 0.0,
        velocity_full_scale_m_s: float = 0.0,
        stamp_ns: int = 0,
    ) -> list[ImpactRecord]:
        """Add sample-aligned blocks of both channels (e.g. a whole recording) at once.

        Equivalent to feeding the two channels batch by batch, whatever the block length.
        stamp_ns: time of the first sample [ns] (0: none), the acquisition's clock.
        """
        force_n = np.asarray(force_n, dtype=float)
        velocity_m_s = np.asarray(velocity_m_s, dtype=float)
        if force_n.shape != velocity_m_s.shape:
            raise BadInputError(
                f'force has {force_n.size} samples but velocity has '
                f'{velocity_m_s.size}: feed_both needs aligned blocks'
            )
        first = int(first_sample_index)
        for low in range(0, force_n.size, MAX_STEP_SAMPLES):
            self.stream.feed_together(
                [
                    (
                        quantity,
                        Batch(
                            first + low,
                            samples[low : low + MAX_STEP_SAMPLES],
                            sample_rate_hz,
                            float(full_scale),
                            stamp_ns=stamp_ns + round(low * 1e9 / sample_rate_hz)
                            if stamp_ns
                            else 0,
                        ),
                    )
                    for quantity, samples, full_scale in (
                        (FORCE.quantity, force_n, force_full_scale_n),
                        (VELOCITY.quantity, velocity_m_s, velocity_full_scale_m_s),
                    )
                ]
            )
        return self._completed()

    def flush(self) -> list[ImpactRecord]:
        """End of stream: complete every open record, its missing samples flagged as a gap."""
        self.stream.finish()
        if self._open:
            stop = max(impact.start + impact.end for impact in self._open)
            for quantity in self._channels:
                self.stream.declare_missing(quantity, stop)
        return self._completed()

    def end_acquisition(self) -> list[ImpactRecord]:
        """The acquisition ended (one lab file of several, say): its samples stop here.

        Unlike `flush`, which treats the samples an open record still lacks as lost (a gap),
        here they never existed: each open record ends at the last sample the channels hold,
        shorter like a record ended at rest (its DFT zero-pads it to the window), judged only
        by what its samples show (`unsettled` if the rig was still moving). A channel behind
        the other is declared missing up to it, as by `flush`. The capture then starts afresh:
        the next batch may start at any sample index, with a new trigger state (completed
        records stay valid and can still be recycled). An end stated, not inferred: the
        stream does not count it as a resynchronisation.
        """
        if not self.stream.started:
            return []
        stop = max(channel.next_index for channel in self._channels.values())
        for quantity in self._channels:
            self.stream.declare_missing(quantity, stop)
        for impact in self._open:
            impact.end = min(impact.end, stop - impact.start)
            impact.end_found = True
        self._settle()
        self.stream.end_acquisition()
        return self._completed()

    def recycle(self, record: ImpactRecord) -> None:
        """Return a completed record's buffers to the pool; the record is invalid afterwards."""
        force, velocity = record.force_n.base, record.velocity_m_s.base
        if (
            self._samples is None
            or force is None
            or velocity is None
            or force.shape != (self._samples.window,)
            or any(force is pooled for pooled, _ in self._pool)
        ):
            raise BadInputError('only a record completed by this capture can be recycled, once')
        self._pool.append((force, velocity))

    def _completed(self) -> list[ImpactRecord]:
        done, self._done = self._done, []
        return done

    # -- the stream's sink ------------------------------------------------------------------------

    def begin(self, sample_rate_hz: float, first_index: int) -> None:
        """An acquisition begins: buffers sized for its rate, rings empty from first_index."""
        if sample_rate_hz != self.sample_rate_hz:
            samples = self.config.samples(sample_rate_hz)
            if self._samples is None or samples.window != self._samples.window:
                self._pool = [(np.zeros(samples.window), np.zeros(samples.window))]
            self._samples = samples
            self.sample_rate_hz = float(sample_rate_hz)
        capacity = self._samples.pretrigger + self._samples.max_skew + MAX_STEP_SAMPLES + 1
        self._channels = {
            name: _Ring(name, capacity, first_index) for name in (FORCE.quantity, VELOCITY.quantity)
        }
        self._detector = TriggerDetector(self.config, self.sample_rate_hz)
        # One warm pair of record buffers (page faults now, not on the first impact).
        if not self._pool:
            window = self._samples.window
            self._pool.append((np.zeros(window), np.zeros(window)))

    def end(self, reason: str) -> None:
        """A new acquisition was recognised: open records end here, their tails a gap."""
        for impact in self._open:
            impact.interrupted = True
            for ring in self._channels.values():
                impact.lose(ring.name, ring.next_index, impact.start + impact.end)
        self._done += [self._record(impact) for impact in self._ordered(self._open)]
        self._open = []

    def take(self, quantity: str, first_index: int, samples: np.ndarray, full_scale: float) -> None:
        """Samples at the channel's watermark (at most MAX_STEP_SAMPLES)."""
        channel = self._channels[quantity]
        channel.store(first_index, samples)
        channel.next_index = first_index + samples.size
        for impact in self._open:
            impact.put(quantity, first_index, samples)
        if quantity == FORCE.quantity:
            for trigger in self._detector.scan(samples, first_index):
                self._open_impact(trigger)
        self._settle()

    def missing(self, quantity: str, start: int, stop: int) -> None:
        """Samples [start, stop) will never come: NaN in the ring and open records, a gap."""
        channel = self._channels[quantity]
        channel.gaps.append((start, stop))
        capacity = channel.ring.size
        nan_from = max(start, stop - capacity)
        channel.store(nan_from, np.full(stop - nan_from, np.nan))
        channel.next_index = stop
        for impact in self._open:
            impact.lose(quantity, start, stop)
        oldest = stop - capacity - self._samples.window
        channel.gaps = [gap for gap in channel.gaps if gap[1] > oldest]
        self._settle()

    # -- records ----------------------------------------------------------------------------------

    def _open_impact(self, trigger: int) -> None:
        """Start a record at `trigger`, filling what both channels already hold.

        A record never starts before its acquisition's first sample (there are none): a
        trigger closer to it than the pre-trigger, or one fired mid-hit, is `truncated_start`.
        """
        force, velocity = (
            self._pool.pop()
            if self._pool
            else (np.empty(self._samples.window), np.empty(self._samples.window))
        )
        origin = self._channels[FORCE.quantity].origin
        pretrigger = min(self._samples.pretrigger, trigger - origin)
        impact = _OpenImpact(trigger, pretrigger, force, velocity)
        impact.truncated_start = (
            pretrigger < self._samples.pretrigger or trigger in self._detector.truncated
        )
        self._detector.truncated.discard(trigger)
        for channel in self._channels.values():
            buffer = impact.buffers[channel.name]
            before_origin = min(max(channel.origin - impact.start, 0), impact.end)
            if before_origin:
                buffer[:before_origin] = np.nan
                impact.add_gap(channel.name, impact.start, channel.origin)
            stop = min(channel.next_index - impact.start, impact.end)
            if stop > before_origin:
                channel.load(buffer[before_origin:stop], impact.start + before_origin)
            for start, end in channel.gaps:
                impact.add_gap(channel.name, start, end)
        self._open.append(impact)

    def _settle(self) -> None:
        """After a channel moved: search for rest, complete the records both channels passed."""
        if self.config.end_at_rest:
            velocity_next = self._channels[VELOCITY.quantity].next_index
            for impact in self._open:
                self._search_rest(impact, velocity_next)
        complete_below = min(channel.next_index for channel in self._channels.values())
        done = [impact for impact in self._open if impact.start + impact.end <= complete_below]
        if done:
            self._open = [impact for impact in self._open if impact not in done]
            self._done += [self._record(impact) for impact in self._ordered(done)]

    @staticmethod
    def _ordered(impacts: list[_OpenImpact]) -> list[_OpenImpact]:
        return sorted(impacts, key=lambda impact: (impact.start + impact.end, impact.trigger))

    def _search_rest(self, impact: _OpenImpact, velocity_next: int) -> None:
        """Shorten the record to where the velocity has rested for rest_time_s, once found."""
        stop = min(velocity_next - impact.start, impact.end)
        if impact.end_found or stop <= impact.rest_position:
            return
        block = impact.buffers[VELOCITY.quantity][impact.rest_position : stop]
        moving = np.flatnonzero(~(np.abs(block) <= self.config.rest_velocity_m_s))
        # Runs of rest between moving samples; the first starts rest_run samples back.
        run_starts = np.concatenate(([-impact.rest_run], moving + 1))
        run_stops = np.concatenate((moving, [block.size]))
        long_enough = np.flatnonzero(run_stops - run_starts >= self._samples.rest)
        if long_enough.size:
            impact.end = impact.rest_position + int(run_starts[long_enough[0]]) + self._samples.rest
            impact.end_found = True
        else:
            impact.rest_run = int(run_stops[-1] - run_starts[-1])
            impact.rest_position = stop

    def _record(self, impact: _OpenImpact) -> ImpactRecord:
        """The completed record of an impact, as views of its buffers."""

        def gaps(name: str) -> Gaps:
            merged: list[tuple[int, int]] = []
            for start, stop in sorted(impact.gaps[name]):
                stop = min(stop, impact.end)
                if start >= stop:
                    continue
                if merged and start <= merged[-1][1]:
                    merged[-1] = (merged[-1][0], max(merged[-1][1], stop))
                else:
                    merged.append((start, stop))
            return tuple(merged)

        return ImpactRecord(
            force_n=impact.buffers[FORCE.quantity][: impact.end],
            velocity_m_s=impact.buffers[VELOCITY.quantity][: impact.end],
            sample_rate_hz=self.sample_rate_hz,
            record_start_sample_index=impact.start,
            trigger_sample_index=impact.trigger,
            window_samples=self._samples.window,
            force_full_scale_n=self.stream.full_scale(FORCE.quantity),
            velocity_full_scale_m_s=self.stream.full_scale(VELOCITY.quantity),
            force_gaps=gaps(FORCE.quantity),
            velocity_gaps=gaps(VELOCITY.quantity),
            interrupted=impact.interrupted,
            truncated_start=impact.truncated_start,
            acquisition_origin_s=self.stream.origin_s,
        )


def capture_impacts(
    force_n: np.ndarray,
    velocity_m_s: np.ndarray,
    sample_rate_hz: float,
    config: CaptureConfig = DEFAULT_CAPTURE,
    first_sample_index: int = 0,
    force_full_scale_n: float = 0.0,
    velocity_full_scale_m_s: float = 0.0,
) -> list[ImpactRecord]:
    """Every impact in a whole continuous recording of both channels (then end of stream)."""
    capture = ImpactCapture(config)
    records = capture.feed_both(
        first_sample_index,
        force_n,
        velocity_m_s,
        sample_rate_hz,
        force_full_scale_n,
        velocity_full_scale_m_s,
    )
    return records + capture.flush()
