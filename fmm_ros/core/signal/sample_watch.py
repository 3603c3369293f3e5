"""Damaged samples in a stream, wherever they fall: NaN, infinities and stuck runs.

A hit's record is judged by `quality.quality_flags`; samples between records are judged by
nothing else, so a consumer runs every batch of a channel through a `SampleWatch` as it
arrives, inside a record or not. It counts per channel:

- NaN and infinite samples, with the index of the first;
- stuck runs: one exact value repeated for longer than a noisy channel makes by chance. The
  channel's chance p of two consecutive samples being equal is counted over the batches
  seen (runs it called stuck left out); a run of k equal samples then happens by chance
  about once in p^-(k-1) samples, so a run is stuck when p^(k-1) < `STUCK_CHANCE` (and
  k >= `quality.STUCK_MIN_SAMPLES`). A channel without white noise (p above
  `quality.STUCK_MAX_EQUAL_FRACTION`: a simulation with exact-zero quiet stretches, a rig at
  rest quieter than its quantisation step) can hold a value for real, so no run counts there,
  and none counts before `MIN_STEPS` steps have shown what the channel is.

Runs are followed across batch boundaries; a gap in the index ends one. Cost: a few numpy
passes over each batch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fmm_ros.core.signal.quality import STUCK_MAX_EQUAL_FRACTION, STUCK_MIN_SAMPLES

STUCK_CHANCE = 1e-9
"""Chance per sample below which a run of equal samples is not noise but a stuck channel."""
MIN_STEPS = 1000
"""Consecutive pairs seen before the channel's chance of a repeat is trusted."""


@dataclass
class ChannelDamage:
    """What one channel's samples showed: counts, and the index of the first of each kind."""

    nan_samples: int = 0
    inf_samples: int = 0
    stuck_runs: int = 0
    stuck_samples: int = 0
    first_nan_index: int | None = None
    first_inf_index: int | None = None
    first_stuck_index: int | None = None

    @property
    def any(self) -> bool:
        """Whether any damaged sample was seen."""
        return bool(self.nan_samples or self.inf_samples or self.stuck_runs)

    def summary(self, quantity: str) -> str:
        """One phrase: `force: 12 NaN from sample 1000, 1 stuck run (5000 samples) from 9000`."""
        parts = []
        if self.nan_samples:
            parts.append(f'{self.nan_samples} NaN from sample {self.first_nan_index}')
        if self.inf_samples:
            parts.append(f'{self.inf_samples} infinite from sample {self.first_inf_index}')
        if self.stuck_runs:
            parts.append(
                f'{self.stuck_runs} stuck run{"s" * (self.stuck_runs != 1)} '
                f'({self.stuck_samples} samples) from sample {self.first_stuck_index}'
            )
        return f'{quantity}: ' + (', '.join(parts) or 'no damaged sample')


class _Channel:
    def __init__(self) -> None:
        self.damage = ChannelDamage()
        self.next: int | None = None  # index after the last sample seen
        self.last = math.nan  # the last sample seen
        self.run_start = 0  # index where the current run of equal samples began
        self.run_counted = False  # the current run was already counted stuck
        self.steps = 0
        self.equal_steps = 0

    def stuck_length(self) -> int | None:
        """Samples a run must reach to be stuck (None: this channel cannot tell)."""
        if self.steps < MIN_STEPS:
            return None
        p = (self.equal_steps + 1) / (self.steps + 2)
        if p > STUCK_MAX_EQUAL_FRACTION:
            return None
        return max(STUCK_MIN_SAMPLES, 1 + math.ceil(math.log(STUCK_CHANCE) / math.log(p)))


class SampleWatch:
    """Counts NaN, infinite and stuck samples of each channel, batch by batch."""

    def __init__(self) -> None:
        self._channels: dict[str, _Channel] = {}

    @property
    def damage(self) -> dict[str, ChannelDamage]:
        """Each channel's counts, by quantity."""
        return {quantity: channel.damage for quantity, channel in self._channels.items()}

    def watch(self, quantity: str, first_index: int, samples: np.ndarray) -> bool:
        """Look at one batch of a channel (SI samples); True if it held a damaged sample."""
        channel = self._channels.setdefault(quantity, _Channel())
        damage = channel.damage
        before = (damage.nan_samples, damage.inf_samples, damage.stuck_runs)
        x = np.asarray(samples, dtype=float)
        if x.size == 0:
            return False
        if not np.isfinite(np.sum(x)):
            nan = np.isnan(x)
            inf = np.isinf(x)
            if nan.any():
                damage.nan_samples += int(nan.sum())
                if damage.first_nan_index is None:
                    damage.first_nan_index = first_index + int(np.argmax(nan))
            if inf.any():
                damage.inf_samples += int(inf.sum())
                if damage.first_inf_index is None:
                    damage.first_inf_index = first_index + int(np.argmax(inf))
        self._runs(channel, first_index, x)
        return (damage.nan_samples, damage.inf_samples, damage.stuck_runs) != before

    def _runs(self, channel: _Channel, first_index: int, x: np.ndarray) -> None:
        """Follow runs of equal samples; count those a noisy channel cannot make."""
        if channel.next != first_index:  # a gap (or the first batch): a run cannot span it
            channel.last, channel.run_start, channel.run_counted = math.nan, first_index, False
        previous = np.empty(x.size)
        previous[0] = channel.last
        previous[1:] = x[:-1]
        equal = x == previous  # NaN never equals: it ends a run
        breaks = np.flatnonzero(~equal)  # indices (in x) where a new run begins
        # Runs ending in this batch: each from its start up to the next break.
        starts = [channel.run_start] + [first_index + int(k) for k in breaks]
        ends = [first_index + int(k) for k in breaks] + [first_index + x.size]
        needed = channel.stuck_length()
        stuck_here = False
        for k, (start, end) in enumerate(zip(starts, ends, strict=True)):
            counted = channel.run_counted if k == 0 else False
            if counted:  # a stuck run going on: this batch's part of it
                channel.damage.stuck_samples += end - max(start, first_index)
                stuck_here = True
            elif needed is not None and end - start >= needed:
                channel.damage.stuck_runs += 1
                channel.damage.stuck_samples += end - start
                if channel.damage.first_stuck_index is None:
                    channel.damage.first_stuck_index = start
                counted = stuck_here = True
            if k == len(starts) - 1:
                channel.run_counted = counted
        if breaks.size:
            channel.run_start = first_index + int(breaks[-1])
        if not stuck_here:  # the channel's chance of a repeat, from batches without stuck runs
            channel.steps += x.size
            channel.equal_steps += int(equal.sum())
        channel.last = float(x[-1])
        channel.next = first_index + x.size
