"""Force and velocity as one index-aligned stream: the rules every consumer of batches shares.

The live analyzer's capture, the fitter's history, bag reading (`BagReader.batches`) and bag
replay all receive the same thing, two channels of `SampleBatch` messages counted on one acquisition
sample index, and all must agree on what a batch means. These rules live here and only here:

- **Watermark.** Each channel has one: every sample below it has been taken or declared
  missing. A batch that starts at the watermark continues the channel.
- **Gap.** A batch starting past the watermark leaves the samples in between missing: they
  are declared missing once, the sink fills them with NaN, and the ledger counts them. An
  index that runs ahead never starts a new acquisition, however far and whatever its clock:
  only the source can declare one (below), so the ledger never calls lost samples another
  acquisition's. A jump further than `max_gap_s` is held first (see Discontinuity), so a
  single corrupt index is refused instead of costing 10^15 samples.
- **Past batch.** A batch starting before the watermark, within `max_gap_s`, repeats samples
  already taken or arrives after they were declared missing: its old samples are refused and
  counted; a tail beyond the watermark is taken.
- **Discontinuity.** A jump far ahead, or what the source declares a new acquisition by
  (the index going back, a changed sample rate, a new sender in `header.frame_id`, or,
  within `max_gap_s` back, a clock that says another acquisition), may also be a single
  corrupt batch. The batch is held, never applied at once. If the next batch of the channel
  continues it, it stands: a jump ahead is a gap of the same acquisition (its samples
  missing, fault `jump`); anything else is a new acquisition, and the stream
  resynchronises (the sink ends what is open and begins again at the new index), so
  recovery costs one batch. If the next batch continues the old sequence instead, the held
  one was a stray and is refused. So one stray batch (an index of 10^15) can neither blind
  the stream nor restart it.
- **Clock.** A batch's acquisition origin is its stamp minus its index over the rate (the
  time of sample 0). Every fmm source stamps batches that way, so a repeat has the origin of
  its original and a restarted DAQ a later one. A stamp of 0 means no clock: index rules only.
- **New acquisition.** After a resynchronisation the other channel still delivers its old
  acquisition for a moment: those batches are stale and refused until it joins the new one
  (a batch with the new origin, or, without clocks, one that does not continue the old
  sequence). Only a channel that has joined can start the next acquisition, so two channels
  cannot restart each other in turn.
- **Skew.** A channel more than `max_skew_s` behind the other is declared missing up to that
  lag, so a dead sensor cannot make a consumer hoard memory; batches are handed to the sink
  in steps of at most `MAX_STEP_SAMPLES`, the skew bounded after each.

Each channel keeps a `ChannelLedger`: samples taken, declared missing, refused (batches and
samples), resynchronisations, the index span of each acquisition and a count per fault kind.
A node publishes it on /diagnostics, the recorder writes it into the bag's metadata, replay
reports it. The stream raises ValueError only for malformed input (a batch that is not a
one-dimensional array, a rate that is not a positive number, an unknown channel): a
well-formed batch that does not fit is a fault of the stream, refused and counted, never an
exception that would stop a node or a bag.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from fmm_ros.constants import CHANNELS
from fmm_ros.core.signal.config import (  # noqa: F401 (re-exported: declared in config)
    DEFAULT_RULES,
    StreamRules,
)
from fmm_ros.errors import BadInputError

# Largest block a sink is handed in one step: bounds the buffers a huge batch would need.
# As large as replay's whole-bag blocks (`workflows.replay.WHOLE_BLOCK_SAMPLES`): each step
# costs the capture a round of Python work (a 30-hit bag read whole and captured: 0.49 s of
# processor time in 4096-sample steps, 0.33 s in these).
MAX_STEP_SAMPLES = 1 << 16
# Acquisitions a ledger lists (the oldest are dropped; the count of resyncs stays exact).
LEDGER_ACQUISITIONS = 16

# Fault kinds, with what each means (the ledger counts them; nodes log them once per kind).
FAULTS: dict[str, str] = {
    'gap': 'samples never arrived (a jump ahead in the index)',
    'skew': 'samples declared missing because the other channel ran too far ahead',
    'past': 'a batch from the past (a repeat, or late after its samples were declared missing)',
    'stray': 'a batch that broke the sequence once and was refused when the next continued it',
    'stale': 'a batch of the previous acquisition after the stream had resynchronised',
    'mismatch': 'a batch at another sample rate than the acquisition the stream follows',
    'malformed': 'a batch that is no sample batch (rate not positive, wrong shape or channel)',
    'unit': 'a batch in a unit the unit table (fmm_ros.units) does not know for its channel',
    'unconfirmed': 'a discontinuous batch at the end of the stream, never confirmed',
    'reset': 'a new acquisition: the index went back',
    'jump': 'the index jumped far ahead (the next batch went on from there): samples missing',
    'rate': 'a new acquisition: the sample rate changed',
    'sender': 'a new acquisition: the sender (header.frame_id) changed',
    'clock': 'a new acquisition: the clock says sample 0 was taken at another time',
}
RESYNC_REASONS = ('reset', 'rate', 'sender', 'clock')


@dataclass(frozen=True, eq=False)
class Batch:
    """One batch of one channel as the stream sees it (a SampleBatch's fields)."""

    first_sample_index: int
    samples: np.ndarray
    sample_rate_hz: float
    full_scale: float = 0.0
    # header.frame_id: who sent it ('' unknown); header.stamp [ns]: time of samples[0] (0: none).
    sender: str = ''
    stamp_ns: int = 0

    @classmethod
    def of(
        cls,
        first_sample_index: int,
        samples: np.ndarray,
        sample_rate_hz: float,
        full_scale: float = 0.0,
        sender: str = '',
        stamp_ns: int = 0,
    ) -> Batch:
        """A batch from loose values (indices of any integer type, samples as floats)."""
        return cls(
            int(first_sample_index),
            np.asarray(samples, dtype=float),
            sample_rate_hz,
            float(full_scale),
            sender,
            int(stamp_ns),
        )

    @property
    def end_index(self) -> int:
        """Index one past the last sample."""
        return self.first_sample_index + len(self.samples)

    @property
    def origin_s(self) -> float | None:
        """Time of sample 0 of its acquisition [s] by its stamp, or None without a stamp."""
        if not self.stamp_ns:
            return None
        return self.stamp_ns / 1e9 - self.first_sample_index / self.sample_rate_hz


@dataclass
class ChannelLedger:
    """What one channel of a stream received, missed and refused: a stream's account.

    received_samples: taken in sequence; missing_samples: declared missing (gaps, skew, end of
    stream); refused_*: batches (and samples) not taken (past, stray, stale, unconfirmed;
    a past batch's new tail is taken, its old part counts as refused samples only);
    acquisitions: [first, end) index span of each acquisition followed, oldest first.
    """

    quantity: str
    received_samples: int = 0
    missing_samples: int = 0
    refused_batches: int = 0
    refused_samples: int = 0
    resyncs: int = 0
    acquisitions: list[list[int]] = field(default_factory=list)
    faults: dict[str, int] = field(default_factory=dict)

    @property
    def span(self) -> tuple[int, int] | None:
        """[first, end) of the acquisition being followed, or None before any sample."""
        return tuple(self.acquisitions[-1]) if self.acquisitions else None

    def to_dict(self) -> dict:
        """Plain data (JSON, the bag's metadata)."""
        return {
            'quantity': self.quantity,
            'received_samples': self.received_samples,
            'missing_samples': self.missing_samples,
            'refused_batches': self.refused_batches,
            'refused_samples': self.refused_samples,
            'resyncs': self.resyncs,
            'acquisitions': [list(span) for span in self.acquisitions],
            'faults': dict(self.faults),
        }

    @classmethod
    def from_dict(cls, data: dict) -> ChannelLedger:
        """The ledger to_dict wrote (unknown keys are ignored, missing ones default)."""
        known = {name: data[name] for name in cls.__dataclass_fields__ if name in data}
        return cls(**known)

    def summary(self) -> str:
        """One line: `force 0..N (1 acquisition), N received, 0 missing, 0 refused`."""
        spans = ', '.join(f'{first}..{end}' for first, end in self.acquisitions) or 'nothing'
        count = self.resyncs + 1 if self.acquisitions else 0
        faults = ', '.join(f'{kind} {n}' for kind, n in sorted(self.faults.items()))
        return (
            f'{self.quantity} {spans} ({count} acquisition{"s" * (count != 1)}), '
            f'{self.received_samples} samples received, {self.missing_samples} missing, '
            f'{self.refused_batches} batches ({self.refused_samples} samples) refused'
            + (f'; faults: {faults}' if faults else '')
        )

    def _fault(self, kind: str, count: int = 1) -> None:
        self.faults[kind] = self.faults.get(kind, 0) + count

    def _refuse(self, kind: str, samples: int, batches: int = 1) -> None:
        self.refused_batches += batches
        self.refused_samples += samples
        self._fault(kind)

    def _begin(self, first: int) -> None:
        self.acquisitions.append([first, first])
        del self.acquisitions[:-LEDGER_ACQUISITIONS]

    def _reach(self, end: int) -> None:
        if self.acquisitions and end > self.acquisitions[-1][1]:
            self.acquisitions[-1][1] = end


class StreamSink(Protocol):
    """What a stream hands its consumer (the capture, the history, the bag aligner)."""

    def begin(self, sample_rate_hz: float, first_index: int) -> None:
        """An acquisition begins at this index and rate: (re)start empty, watermarks here."""

    def end(self, reason: str) -> None:
        """The acquisition ends (a new one was recognised): close what is open."""

    def take(self, quantity: str, first_index: int, samples: np.ndarray, full_scale: float) -> None:
        """Samples of a channel at its watermark (at most MAX_STEP_SAMPLES)."""

    def missing(self, quantity: str, start: int, stop: int) -> None:
        """Samples [start, stop) of a channel will never come (the range may be huge)."""


@dataclass(frozen=True)
class _Acquisition:
    """What the stream follows: its rate, and its origin [s] (None without a clock)."""

    sample_rate_hz: float
    origin_s: float | None


class _Channel:
    """One channel's state under the rules: watermark, clock, sender, held batch, ledger."""

    def __init__(self, quantity: str) -> None:
        self.quantity = quantity
        self.ledger = ChannelLedger(quantity)
        self.next = 0  # the watermark (meaningful once the stream has begun)
        # Of the last batch taken: rate, acquisition origin [s] (None: no clock), sender, range.
        self.rate: float | None = None
        self.origin_s: float | None = None
        self.sender = ''
        self.full_scale = 0.0
        # A discontinuous batch waiting for the next one to confirm it, and why it broke off.
        self.held: Batch | None = None
        self.held_reason = ''
        # Whether the channel follows the stream's acquisition yet; until it does, its batches
        # are judged against that acquisition (join) and its own previous one (stale).
        self.joined = False
        self.first_acquisition = True  # the very first: joins whatever its clock
        self.old_next: int | None = None  # watermark in the previous acquisition
        # The index ranges it jumped over that another channel may not have passed yet: no
        # signal, so they do not count towards how far this channel leads (skew).
        self.gaps: list[tuple[int, int]] = []

    def follow(self, batch: Batch) -> None:
        """Adopt a taken batch's rate, clock, sender and range."""
        self.rate = batch.sample_rate_hz
        self.origin_s = batch.origin_s
        self.sender = batch.sender
        self.full_scale = batch.full_scale


class AlignedStream:
    """Force and velocity batches in, the sink's calls out, by the rules of this module.

    `feed(quantity, batch)` takes one batch of one channel (channels may be out of step by up
    to `max_skew_s`); `finish` and `declare_missing` end a stream. The sink sees only
    in-order samples of the acquisition being followed, each channel from its watermark.
    Not thread-safe.
    """

    def __init__(
        self,
        sink: StreamSink,
        rules: StreamRules = DEFAULT_RULES,
        quantities: Sequence[str] = tuple(channel.quantity for channel in CHANNELS),
    ) -> None:
        self.sink = sink
        self.rules = rules
        self._channels = {quantity: _Channel(quantity) for quantity in quantities}
        self._acquisition: _Acquisition | None = None
        self._max_skew = 0
        self._max_gap = 0
        self.acquisitions = 0
        """Acquisitions followed so far (1 + the resynchronisations)."""
        self._skew_deferred = False

    # -- what it knows ---------------------------------------------------------------------------

    @property
    def started(self) -> bool:
        """True once a first batch has begun an acquisition."""
        return self._acquisition is not None

    @property
    def sample_rate_hz(self) -> float | None:
        """Rate of the acquisition being followed (None before the first batch)."""
        return self._acquisition.sample_rate_hz if self._acquisition else None

    @property
    def origin_s(self) -> float | None:
        """Time of sample 0 of the acquisition followed [s] (None: no clock, or not started).

        From the clock of the batch that began the acquisition.
        """
        return self._acquisition.origin_s if self._acquisition else None

    @property
    def ledger(self) -> dict[str, ChannelLedger]:
        """Each channel's ledger, by quantity."""
        return {quantity: channel.ledger for quantity, channel in self._channels.items()}

    def next_index(self, quantity: str) -> int | None:
        """A channel's watermark (None before the stream began)."""
        return self._channels[quantity].next if self.started else None

    def full_scale(self, quantity: str) -> float:
        """The sensor range of a channel's latest batch taken (0: unknown)."""
        return self._channels[quantity].full_scale

    def sender(self, quantity: str) -> str:
        """Who sent a channel's latest batch taken (its header.frame_id; '' unknown)."""
        return self._channels[quantity].sender

    # -- input -----------------------------------------------------------------------------------

    def feed(self, quantity: str, batch: Batch) -> None:
        """Apply one batch of one channel; its faults go to the ledger, never raise."""
        channel = self._channel(quantity)
        check(quantity, batch)
        if channel.held is not None:
            self._resolve_held(channel, batch)
        else:
            self._judge(channel, batch)

    def feed_together(self, batches: Sequence[tuple[str, Batch]]) -> None:
        """Apply batches of several channels that cover the same indices as one step.

        The skew is bounded after all of them, so aligned blocks of any length stay aligned
        (a recording fed whole, block by block).
        """
        self._skew_deferred = True
        try:
            for quantity, batch in batches:
                self.feed(quantity, batch)
        finally:
            self._skew_deferred = False
        if self.started:
            self._bound_skew()

    def refuse_malformed(self, quantity: str, samples: int, kind: str = 'malformed') -> None:
        """Count a batch the caller could not even make a Batch of (see `check` for why).

        kind: the FAULTS kind ('unit': a unit no table converts).
        """
        self._channel(quantity).ledger._refuse(kind, samples)

    def finish(self) -> None:
        """End of stream: a batch still held was never confirmed, so it is refused."""
        for channel in self._channels.values():
            if channel.held is not None:
                channel.ledger._refuse('unconfirmed', len(channel.held.samples))
                channel.held = None

    def end_acquisition(self) -> None:
        """The acquisition ended by statement (one recording of several joined).

        The next batch begins a new one at whatever index, with nothing to confirm and no
        resync counted. A batch still held is refused as unconfirmed.
        """
        self.finish()
        self._acquisition = None
        for channel in self._channels.values():
            channel.joined = False
            channel.first_acquisition = True
            channel.old_next = None

    def declare_missing(self, quantity: str, stop: int) -> None:
        """Samples of a channel from its watermark to `stop` will never come (end of stream)."""
        if self.started:
            self._missing(self._channel(quantity), stop, 'gap')

    # -- the rules -------------------------------------------------------------------------------

    def _channel(self, quantity: str) -> _Channel:
        try:
            return self._channels[quantity]
        except KeyError:
            names = ' or '.join(repr(q) for q in self._channels)
            raise BadInputError(f'quantity must be {names}, got {quantity!r}') from None

    def _judge(self, channel: _Channel, batch: Batch) -> None:
        """A batch with nothing held: take it, refuse it, or hold it as a discontinuity."""
        if self._acquisition is None:
            self._begin(channel, batch, reason='')
        elif not channel.joined:
            self._judge_joining(channel, batch)
        else:
            kind = self._continuity(channel, batch)
            if kind in ('next', 'past'):
                self._take(channel, batch)
            else:
                channel.held, channel.held_reason = batch, kind

    def _continuity(self, channel: _Channel, batch: Batch) -> str:
        """'next' (continues, maybe after a gap), 'past', or why the batch breaks off."""
        if batch.sample_rate_hz != channel.rate:
            return 'rate'
        if batch.sender != channel.sender and batch.sender and channel.sender:
            return 'sender'
        step = batch.first_sample_index - channel.next
        if step >= 0:  # ahead: this acquisition still, only a far jump waits for the next
            return 'next' if step <= self._max_gap else 'jump'
        if -step > self._max_gap:
            return 'reset'
        same = self.rules.same_clock(batch.origin_s, channel.origin_s)
        return 'clock' if same is False else 'past'

    def _resolve_held(self, channel: _Channel, batch: Batch) -> None:
        """The batch after a held one decides: new acquisition, or the held one was a stray."""
        held, reason = channel.held, channel.held_reason
        channel.held = None
        confirmed = (
            batch.first_sample_index == held.end_index
            and batch.sample_rate_hz == held.sample_rate_hz
            and batch.sender == held.sender
            and self.rules.same_clock(batch.origin_s, held.origin_s) is not False
        )
        if not confirmed:
            channel.ledger._refuse('stray', len(held.samples))
            self._judge(channel, batch)
            return
        if not channel.joined:
            self._join(channel, held)
        elif reason == 'jump':
            channel.ledger._fault('jump')  # the same acquisition goes on: the samples are missing
        else:
            channel.ledger._fault(reason)
            self._begin(channel, held, reason)
            self._rejudge_others(channel)
            self._take(channel, batch)
            return
        self._take(channel, held)
        self._take(channel, batch)

    def _judge_joining(self, channel: _Channel, batch: Batch) -> None:
        """A batch of a channel that does not follow the stream's acquisition yet."""
        acquisition = self._acquisition
        if batch.sample_rate_hz != acquisition.sample_rate_hz:
            channel.ledger._refuse(
                'mismatch' if channel.first_acquisition else 'stale', len(batch.samples)
            )
            return
        new = self.rules.same_clock(batch.origin_s, acquisition.origin_s)
        old = self.rules.same_clock(batch.origin_s, channel.origin_s)
        continues_old = (
            batch.first_sample_index == channel.old_next and batch.sample_rate_hz == channel.rate
        )
        if channel.first_acquisition or new or (new is None and not continues_old):
            self._join(channel, batch)
            self._take(channel, batch)
        elif old or (old is None and continues_old):
            channel.ledger._refuse('stale', len(batch.samples))
            channel.old_next = batch.end_index
        else:
            channel.held, channel.held_reason = batch, 'stale'

    def _begin(self, channel: _Channel, batch: Batch, reason: str) -> None:
        """Follow a new acquisition from batch on (taken here); the other channels must join."""
        first, rate = batch.first_sample_index, batch.sample_rate_hz
        if self._acquisition is not None:
            self.sink.end(reason)
        self._acquisition = _Acquisition(rate, batch.origin_s)
        self.acquisitions += 1
        self._max_skew = int(round(self.rules.max_skew_s * rate))
        self._max_gap = int(round(self.rules.max_gap_s * rate))
        self.sink.begin(rate, first)
        for other in self._channels.values():
            other.gaps = []
            other.old_next = None if reason == '' else other.next
            other.next = first
            other.joined = False
        self._join(channel, batch)
        self._take(channel, batch)

    def _rejudge_others(self, channel: _Channel) -> None:
        """After a resynchronisation, another channel's held batch may be its first: judge it."""
        for other in self._channels.values():
            if other is not channel and other.held is not None:
                held, other.held = other.held, None
                self._judge(other, held)

    def _join(self, channel: _Channel, batch: Batch) -> None:
        """The channel follows the stream's acquisition, from batch on."""
        if not channel.first_acquisition:
            channel.ledger.resyncs += 1
        channel.joined = True
        channel.first_acquisition = False
        channel.follow(batch)
        channel.ledger._begin(max(batch.first_sample_index, channel.next))

    def _take(self, channel: _Channel, batch: Batch) -> None:
        """Take a batch at the watermark: a gap before it is declared, a part below refused."""
        samples = batch.samples
        first = batch.first_sample_index
        if first != channel.next:
            if first < channel.next:
                old = min(channel.next - first, len(samples))
                channel.ledger._refuse('past', old, batches=int(old == len(samples)))
                if old == len(samples):
                    return
                samples, first = samples[old:], channel.next
            else:
                self._missing(channel, first, 'gap')
        channel.follow(batch)
        sink, quantity, count = self.sink, channel.quantity, len(samples)
        for low in range(0, count, MAX_STEP_SAMPLES):
            block = samples[low : low + MAX_STEP_SAMPLES] if count > MAX_STEP_SAMPLES else samples
            sink.take(quantity, channel.next, block, batch.full_scale)
            channel.next += len(block)
            if not self._skew_deferred:
                self._bound_skew()
        channel.ledger.received_samples += count
        channel.ledger._reach(channel.next)

    def _missing(self, channel: _Channel, stop: int, kind: str) -> None:
        """Declare a channel's samples from its watermark up to stop missing."""
        start = channel.next
        if stop <= start:
            return
        channel.next = stop
        channel.ledger.missing_samples += stop - start
        channel.ledger._fault(kind)
        if kind == 'gap':
            channel.gaps.append((start, stop))
        if channel.joined:
            channel.ledger._reach(stop)
        self.sink.missing(channel.quantity, start, stop)

    def _bound_skew(self) -> None:
        """Declare a lagging channel missing up to max_skew of signal behind the leading one.

        Signal the leader has: its gaps (an index jump) are not, so a jump of one channel
        never makes the other's batches still in flight before the jump count as lagging.
        """
        channels = self._channels.values()
        trailing = min(channel.next for channel in channels)
        leader = max(channels, key=lambda channel: channel.next)
        leader.gaps = [gap for gap in leader.gaps if gap[1] > trailing]
        for channel in channels:
            if leader.next - channel.next > self._max_skew:
                stop = self._behind_signal(leader, self._max_skew)
                if stop > channel.next:
                    self._missing(channel, stop, 'skew')

    @staticmethod
    def _behind_signal(leader: _Channel, samples: int) -> int:
        """The index `samples` of the leader's signal (its gaps not counted) behind its mark."""
        stop = leader.next
        for start, end in reversed(leader.gaps):
            if stop - end >= samples:
                break
            samples -= stop - end
            stop = start
        return stop - samples


class LedgerOnly:
    """A sink that keeps no samples: a stream run for its ledger alone.

    The recorder stores every batch as it came (a recording must not drop what a consumer
    would refuse); its ledger is the stream's account of what it recorded.
    """

    def begin(self, sample_rate_hz: float, first_index: int) -> None:
        """Nothing to size."""

    def end(self, reason: str) -> None:
        """Nothing to close."""

    def take(self, quantity: str, first_index: int, samples: np.ndarray, full_scale: float) -> None:
        """Nothing to keep."""

    def missing(self, quantity: str, start: int, stop: int) -> None:
        """Nothing to mark."""


def check(quantity: str, batch: Batch) -> None:
    """Malformed input is a caller's mistake, not a fault of the stream: ValueError."""
    if batch.samples.ndim != 1:
        raise BadInputError(
            f'{quantity} samples must be one-dimensional, got shape {batch.samples.shape}'
        )
    if not 0 < batch.sample_rate_hz < math.inf:  # also refuses NaN
        raise BadInputError(
            f'{quantity} sample_rate_hz must be positive, got {batch.sample_rate_hz}'
        )
    if batch.first_sample_index < 0:
        raise BadInputError(
            f'{quantity} first_sample_index must be >= 0, got {batch.first_sample_index}'
        )
