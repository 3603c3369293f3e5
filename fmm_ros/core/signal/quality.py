"""Signs of damaged samples in one channel: a flat top, a stuck stretch, no response to a hit.

Plain functions on arrays, and `quality_flags`, the record's verdict they make (so the analyzer
node, `fmm analyze`, bag replay and every fit see the same one). None of them needs to know
the sensor: a full-scale range, a quantisation step or a noise level, where they matter, are
read from the samples themselves.

- Noise: the white-noise deviation of a channel is the MAD deviation of its second differences
  over sqrt(6) (`white_noise_std`): a few-Hz motion barely changes over two samples at 10 kHz,
  white noise does, and the median ignores the hit and the stops.
- Flat top (`flat_extreme`): a clipped or saturated channel holds its extreme for a stretch of
  samples, equal within a tolerance (half the quantisation step, or `FLAT_NOISE_WIDTH` noise
  deviations when noise rides on the rail). A smooth peak does that too when quantised coarsely
  or very noisy, so the stretch also has to be one no smooth peak can make: a peak that stays
  within the tolerance t for the 2h samples of the stretch has a curvature of at most 2t/h^2,
  so one stretch-length beyond either end (3h from its middle) it can have dropped by at most
  9t. A clipped signal rose into the rail and falls off it: it has dropped by far more.
  `FLAT_DROP_FACTOR` (16) leaves a margin for noise; clipping shallower than about 2 t is not
  seen, and does not matter. A plateau of a few samples is judged again in a band of a few
  noise deviations: the top of a sharp hammer pulse, or of its tip ringing at kHz, can put
  three samples inside the wide band and then fall away steeply.
- Stuck stretch (`stuck_stretch`): a noisy channel (`has_white_noise`) cannot repeat one exact
  value for long. A channel whose consecutive samples are equal with probability p repeats one
  for k samples by chance about n p^(k-1) times in n samples; a run longer than makes that
  `STUCK_FALSE_ALARM` (and at least `STUCK_MIN_SAMPLES`) is samples dropped and filled by the
  acquisition (zeros, or the last value held). Runs on a plateau `flat_extreme` found are
  clipping, not counted again. In a channel without white noise (a simulation, a quantised
  record quieter than its step) a constant can be real, a rig at rest, but the signal then
  reached it in steps like its others: only a stretch entered and left by a jump (zeros where
  the channel sat at an offset or moved) counts there.
- Response (`responds`): a hit moves the rig, so the velocity just after the contact must depart
  from its level just before it by far more than the channel's noise and than its own spread
  before the contact (which holds any hum or drift a disconnected input picks up). A dead or
  disconnected vibrometer shows noise, hum or a constant: the same spread on both sides.
"""

from __future__ import annotations

import math

import numpy as np

from fmm_ros.core.signal import _kernels, pulse
from fmm_ros.core.signal.capture import (
    TriggerDetector,
    below_level,
    contact_start_index,
    resting_force_level,
    with_trigger,
)
from fmm_ros.core.signal.config import DEFAULT_CAPTURE, FLAGS, CaptureConfig
from fmm_ros.core.signal.frf import contact_duration, first_where, median_in_place
from fmm_ros.core.signal.records import Gaps, ImpactRecord

MAD_TO_STD = 1.482602218505602
"""1 / Phi^-1(3/4): the MAD of Gaussian noise times this is its standard deviation."""

ROBUST_SUBSAMPLE_MIN = 5000
"""Above 8 times this many values, robust statistics use every 8th (40,000 values pin a noise
level to about half a per cent; eight times cheaper on a 33 s record)."""

FLAT_MIN_SAMPLES = 3
"""A flat top is at least this many consecutive samples at the extreme."""

FLAT_NOISE_WIDTH = 10.0
"""Samples within this many noise deviations of the extreme count as on it (noise added after
the rail spreads a plateau by a few deviations; the largest of 10^4 samples lies ~4 above it)."""

FLAT_SHORT_SAMPLES = 8
"""A plateau shorter than this many samples in the wide band ..."""

FLAT_SHORT_NOISE_WIDTH = 4.0
"""... is judged again with samples within this many noise deviations of the extreme (a rail's
noisy samples lie within about two; the top of a ringing pulse spreads over six)."""

FLAT_DROP_FACTOR = 16.0
"""A flat top must fall by more than this many tolerances one stretch-length beyond its ends
(a smooth peak falls by at most 9; see the module docstring)."""

STUCK_MIN_SAMPLES = 25
"""Shortest stretch of one repeated value counted as a dropout [samples]."""

STUCK_FALSE_ALARM = 1e-4
"""Expected number of chance repeats of the dropout length in a noisy record."""

STUCK_STEPS = 2.0
"""In a channel without noise, a held stretch must be entered and left by a jump this many
times the largest step of the samples around it (and of the quantisation step)."""

STUCK_SPAN_FRACTION = 0.01
"""... and by more than this fraction of the channel's range: a fill of a moving signal, not a
rounding-level step of a record ending (a noise-free record's smallest step is tiny)."""

STUCK_MAX_EQUAL_FRACTION = 0.9
"""A channel whose consecutive samples are equal more often than this has no noise to judge by."""

RESPONSE_RATIO = 5.0
"""The velocity after a hit must depart from its level by this many times the noise and the
quiet tail's spread."""

SETTLED_TAIL_FRACTION = 0.01
"""An acceleration or displacement record has settled when its last 1 % ..."""

SETTLED_RESPONSE_FRACTION = 0.01
"""... departs from its level before the hit by at most 1 % of its largest departure: the
jump the DFT's wrap-around makes from the record's end to its start, and so the leakage of its
FRF, is then at the per cent level of the peak (a velocity has an absolute rest level instead,
`CaptureConfig.rest_velocity_m_s`)."""

SETTLED_TAIL_MIN_SAMPLES = 8
"""The tail judged is at least this many samples (a short record's 1 % is too few)."""

RESPONSE_PERCENTILE = 90.0
"""The departure after a hit is this percentile of |velocity - level| (robust to a spike)."""


def robust_center_and_std(values: np.ndarray) -> tuple[float, float]:
    """Median and MAD-based deviation of the finite values (every 8th in long arrays)."""
    values = np.asarray(values, dtype=float)
    if values.size > 8 * ROBUST_SUBSAMPLE_MIN:
        values = values[::8]
    return _center_and_std(values)


def _center_and_std(values: np.ndarray) -> tuple[float, float]:
    """`robust_center_and_std` of values already subsampled."""
    values = values[np.isfinite(values)]
    if values.size == 0:
        return math.nan, math.nan
    center = float(np.median(values))
    return center, MAD_TO_STD * float(np.median(np.abs(values - center)))


def mad_std(scratch: np.ndarray) -> float:
    """`robust_center_and_std(values)[1]` of values already subsampled, overwriting them.

    The same number to the bit, about five times faster: each median is one in-place
    partition (`frf.median_in_place`), where np.median copies the values and partitions for
    three ranks. The centre may differ from np.median's in the sign of a zero, which no
    |value - centre| tells apart, so the deviation never does.
    """
    finite = np.isfinite(scratch)
    values = scratch if finite.all() else scratch[finite]
    if values.size == 0:
        return math.nan
    center = median_in_place(values)
    np.subtract(values, center, out=values)
    np.abs(values, out=values)
    return MAD_TO_STD * median_in_place(values)


def white_noise_std(samples: np.ndarray) -> float:
    """White-noise deviation of a channel, blind to slow motion and to a few pulses.

    The MAD deviation of the second differences over sqrt(6) (second differences of white
    noise have variance 6 sigma^2). 0 for a channel without noise, NaN with no finite values.
    """
    samples = np.asarray(samples, dtype=float)
    if samples.size <= 2:
        return 0.0
    return _difference_spread(samples, 2) / math.sqrt(6.0)


def _difference_spread(samples: np.ndarray, order: int) -> float:
    """MAD deviation of the channel's differences of an order (1 or 2), as noise reads them."""
    return mad_std(_read_differences(samples, order))


def _read_differences(samples: np.ndarray, order: int) -> np.ndarray:
    """`np.diff(samples, n=order)` (order 1 or 2) as `robust_center_and_std` reads it.

    Every 8th difference of a long channel, and only those computed, by the subtractions
    np.diff makes (so the same numbers): a tenth of a record's flagging went to differences
    never read.
    """
    count = max(samples.size - order, 0)
    step = 8 if count > 8 * ROBUST_SUBSAMPLE_MIN else 1
    kept = -(-count // step)
    with np.errstate(invalid='ignore'):  # inf - inf in a corrupt stretch: NaN, left out
        first = samples[1::step][:kept] - samples[::step][:kept]
        if order == 1:
            return first
        ahead = samples[2::step][: first.size] - samples[1::step][: first.size]
        return ahead - first


def flat_extreme(
    samples: np.ndarray, sign: float = 1.0, noise_std: float | None = None
) -> float | None:
    """The channel's maximum (sign +1) or minimum (sign -1) if it is a clipped plateau, or None.

    See the module docstring for the rule. noise_std: the channel's white-noise deviation, if
    already known. Non-finite samples are never part of a plateau.
    """
    samples = np.asarray(samples, dtype=float)
    peak_at = _extreme_index(samples, sign)
    if peak_at < 0:
        return None
    level = sign * samples[peak_at]
    noise = white_noise_std(samples) if noise_std is None else noise_std
    noise = noise if np.isfinite(noise) else 0.0
    near = sign * samples[max(0, peak_at - ROBUST_SUBSAMPLE_MIN) : peak_at + ROBUST_SUBSAMPLE_MIN]
    floor = max(0.5 * quantum(near), 1e-12 * abs(level))
    tolerance = max(floor, FLAT_NOISE_WIDTH * noise)
    start, stop = _run_around(samples, sign, peak_at, tolerance)
    if stop - start < FLAT_SHORT_SAMPLES:
        # A few samples in the wide band can be a sharp peak's top, or its tip's ringing: a
        # short plateau must hold within the noise of a few samples.
        tolerance = max(floor, FLAT_SHORT_NOISE_WIDTH * noise)
        start, stop = _run_around(samples, sign, peak_at, tolerance)
    run = stop - start
    if run < FLAT_MIN_SAMPLES:
        return None
    # One stretch-length beyond each end, or the record's first or last sample: nearer the
    # plateau a smooth peak has dropped less, so the clamp never makes one look clipped.
    left, right = max(start - run + 1, 0), min(stop + run - 2, samples.size - 1)
    drop = min(level - sign * samples[left], level - sign * samples[right])
    return float(sign * level) if drop > FLAT_DROP_FACTOR * tolerance else None


def _extreme_index(samples: np.ndarray, sign: float) -> int:
    """Index of the first largest finite value of sign * samples; -1 when none is finite.

    A channel without a NaN or infinity (its sum finite) takes one argmax or argmin pass.
    """
    if sign in (1.0, -1.0) and samples.size and np.isfinite(np.sum(samples)):
        return int(np.argmax(samples) if sign > 0 else np.argmin(samples))
    values = sign * samples
    finite = np.isfinite(values)
    if not finite.any():
        return -1
    return int(np.argmax(np.where(finite, values, -np.inf)))


def _run_around(
    samples: np.ndarray, sign: float, peak_at: int, tolerance: float
) -> tuple[int, int]:
    """[start, stop) of sign * samples around peak_at within tolerance of it (NaN never is).

    Tested outward from peak_at, so a plateau costs its neighbourhood, not the channel.
    """
    level = sign * samples[peak_at]

    def off(chunk: np.ndarray) -> np.ndarray:
        return ~(level - sign * chunk <= tolerance)

    after = first_where(off, samples[peak_at:])
    before = first_where(off, samples[peak_at::-1])
    return (
        0 if before < 0 else peak_at - before + 1,
        samples.size if after < 0 else peak_at + after,
    )


def has_white_noise(samples: np.ndarray, second_spread: float | None = None) -> bool:
    """Whether white noise, not the signal, makes most of the sample-to-sample changes.

    For white noise the MAD of second differences is sqrt(3) times that of first differences
    (quantised noise of about one step: both one step); for a signal smooth at the sample rate
    (a noise-free simulation, a quantised slow signal) it is far smaller, or the first
    differences are mostly zero. second_spread: the MAD deviation of the second differences,
    if already known (`white_noise_std` times sqrt(6) is not always it to the bit).
    """
    samples = np.asarray(samples, dtype=float)
    spread_first = _difference_spread(samples, 1)
    if second_spread is None:
        second_spread = _difference_spread(samples, 2)
    return bool(spread_first > 0 and second_spread >= spread_first)


def quantum(samples: np.ndarray) -> float:
    """Smallest step between distinct finite values (the quantisation step, if any); 0 if none."""
    values = np.unique(np.asarray(samples, dtype=float)[np.isfinite(samples)])
    return float(np.min(np.diff(values))) if values.size > 1 else 0.0


def stuck_stretch(
    samples: np.ndarray, plateaus: tuple[float, ...] = (), second_spread: float | None = None
) -> bool:
    """Whether a channel holds one value where its samples say it cannot.

    See the module docstring for the rule. plateaus: levels already judged clipping
    (`flat_extreme`), whose runs are not counted again. second_spread: as `has_white_noise`.
    """
    values = np.asarray(samples, dtype=float)
    if values.size < STUCK_MIN_SAMPLES:
        return False
    # NaN never equals; inf does, but a corrupt stretch is the nan flag's: not a dropout.
    # Only runs of at least STUCK_MIN_SAMPLES equal samples can count, here or as foreign.
    equal, starts, stops = _kernels.equal_runs(values, STUCK_MIN_SAMPLES - 1)
    if not has_white_noise(values, second_spread):
        return _foreign_stretch(values, starts, stops, plateaus)
    chance = float(equal) / (values.size - 1)
    if chance > STUCK_MAX_EQUAL_FRACTION:
        return False
    need = STUCK_MIN_SAMPLES
    if chance > 0:
        need = max(
            need, math.ceil(math.log(STUCK_FALSE_ALARM / values.size) / math.log(chance)) + 1
        )
    held = values[starts[(stops - starts) >= need - 1]]
    return bool(np.any(~np.isin(held, plateaus)))


def _foreign_stretch(
    values: np.ndarray, starts: np.ndarray, stops: np.ndarray, plateaus: tuple[float, ...]
) -> bool:
    """In a channel without noise: a long constant stretch the signal jumped into and out of.

    A quiet channel is constant for real (a rig at rest, a quantised slow signal), but then it
    came to that value in steps like its others (a decelerating rig, one quantisation step);
    a stretch filled with zeros is entered and left by a jump of more than `STUCK_STEPS` times
    the largest step of the samples just before (and after) it, and of more than
    `STUCK_SPAN_FRACTION` of the channel's range.
    """
    long = (stops - starts) >= STUCK_MIN_SAMPLES - 1
    if not long.any():
        return False
    with np.errstate(invalid='ignore'):  # inf - inf in a corrupt stretch: NaN, left out
        changes = np.abs(np.diff(values))
    positive = changes[np.isfinite(changes) & (changes > 0)]
    step = float(np.min(positive)) if positive.size else 0.0

    finite = values[np.isfinite(values)]
    span = float(np.max(finite) - np.min(finite)) if finite.size else 0.0

    def jumped(jump: float, around: np.ndarray) -> bool:
        around = around[np.isfinite(around)]
        usual = max(float(np.max(around)) if around.size else 0.0, step)
        return bool(jump > STUCK_STEPS * usual and jump > STUCK_SPAN_FRACTION * span)

    for start, stop in zip(starts[long], stops[long], strict=True):
        if values[start] in plateaus:
            continue
        # changes[start - 1] enters the stretch, changes[stop] leaves it (if it ends inside).
        entered = start == 0 or jumped(
            changes[start - 1], changes[max(0, start - 1 - STUCK_MIN_SAMPLES) : start - 1]
        )
        left = stop >= changes.size or jumped(
            changes[stop], changes[stop + 1 : stop + 1 + STUCK_MIN_SAMPLES]
        )
        if entered and left and (start > 0 or stop < changes.size):
            return True
    return False


def responds(
    velocity: np.ndarray,
    contact_start: int,
    contact_end: int,
    window_samples: int,
    noise_std: float | None = None,
) -> bool:
    """Whether the velocity responds to a hit whose contact spans [contact_start, contact_end).

    The same number m of samples (the pre-contact samples, at most window_samples) is taken
    before the contact and after it. The departure is the `RESPONSE_PERCENTILE` of
    |velocity - level| after the contact, the level being the median before it; it must exceed
    `RESPONSE_RATIO` times the white noise and times the same percentile of the samples before
    (which holds any hum or drift a disconnected input picks up: stationary interference shows
    the same spread on both sides of the hit, a response does not). True when too few finite
    samples allow no verdict: missing samples are the gap and nan flags' business.
    """
    velocity = np.asarray(velocity, dtype=float)
    count = min(contact_start, window_samples)
    before = velocity[contact_start - count : contact_start]
    before = before[np.isfinite(before)]
    after = velocity[contact_end : contact_end + count]
    after = after[np.isfinite(after)]
    if before.size < FLAT_MIN_SAMPLES or after.size < FLAT_MIN_SAMPLES:
        return True
    level = float(np.median(before))
    departure = float(np.percentile(np.abs(after - level), RESPONSE_PERCENTILE))
    spread = float(np.percentile(np.abs(before - level), RESPONSE_PERCENTILE))
    noise = white_noise_std(velocity) if noise_std is None else noise_std
    return departure > RESPONSE_RATIO * max(spread, noise if np.isfinite(noise) else 0.0)


def quality_flags(record: ImpactRecord, config: CaptureConfig = DEFAULT_CAPTURE) -> tuple[str, ...]:
    """The quality flags a record raises, in `FLAGS` order (see the module docstring for rules).

    - double_hit: after the force falls below the re-arm level, it rises again within
      min_spacing_s of the trigger to the trigger level or a tenth of the peak, whichever is
      lower (`pulse.rebounds`: a hammer bounce, two inputs in one FRF).
    - clipped: the force reaches its known full-scale range, or its peak is a flat top no
      smooth pulse makes (`flat_extreme`: clipping with the range unknown).
    - coarse: the contact spans too few samples for its impulse and spectrum
      (`pulse.coarse`).
    - saturated: the velocity reaches its known range, or its maximum or minimum is such a
      flat top (the vibrometer's range exceeded).
    - no_response: the velocity does not depart from its level before the hit by more than
      its noise and its own spread there (`responds`): a dead or disconnected
      vibrometer.
    - dropout: a noisy channel holds one exact value for longer than chance allows
      (`stuck_stretch`): samples dropped and filled by zeros or the last value.
    - gap: samples that never arrived inside the record (they are NaN).
    - interrupted: a new acquisition began before the record was complete (its tail is a gap).
    - truncated_start: the acquisition began after the record's start: mid-hit (the force
      never below the re-arm level before the trigger, or above the trigger level from its
      first sample: an offset) or inside the pre-trigger; the record starts at the
      acquisition's first sample.
    - nan: received samples that are NaN or infinite.
    - unsettled: |velocity - its level before the hit| (the level removes a vibrometer
      offset) above rest_velocity_m_s in the last rest_time_s of the record, or before the
      hammer touched, so the record is not one whole transient and its DFT leaks. An
      acceleration or displacement sensor has no velocity threshold: its departure from
      that level over the record's last `SETTLED_TAIL_FRACTION`, or before the hit, must stay
      within `SETTLED_RESPONSE_FRACTION` of its largest departure.
    - overlap: the next impact triggers inside this record.

    The response flags (saturated, no_response, dropout, nan, unsettled) judge the channel the
    sensor measured (`ImpactRecord.measured`), in its own units and range.
    """
    record = with_trigger(record, config)
    trigger = record.trigger_offset
    force = record.force_n - resting_force_level(record.force_n, trigger, config)
    velocity, response_full_scale = record.measured
    samples = config.samples(record.sample_rate_hz)
    flags = set()
    # Each channel's second-difference spread once: its noise, and half the noise test.
    force_spread, velocity_spread = _second_spread(force), _second_spread(velocity)
    force_noise, velocity_noise = (
        0.0 if spread is None else spread / math.sqrt(6.0)
        for spread in (force_spread, velocity_spread)
    )

    contact_start, contact_end = _contact(force, trigger, config)
    flags |= _pulse_flags(force, record.sample_rate_hz, trigger, contact_end, contact_start, config)
    force_plateaus = _plateaus(force, (1.0,), force_noise)
    velocity_plateaus = _plateaus(velocity, (1.0, -1.0), velocity_noise)
    if _beyond(force, record.force_full_scale_n) or force_plateaus:
        flags.add('clipped')
    if _beyond(velocity, response_full_scale) or velocity_plateaus:
        flags.add('saturated')
    if not responds(velocity, contact_start, contact_end, samples.min_spacing, velocity_noise):
        flags.add('no_response')
    if stuck_stretch(force, force_plateaus, force_spread) or stuck_stretch(
        velocity, velocity_plateaus, velocity_spread
    ):
        flags.add('dropout')
    flags |= _recording_flags(record)
    if _non_finite_outside(force, record.force_gaps) or _non_finite_outside(
        velocity, record.velocity_gaps
    ):
        flags.add('nan')
    if _unsettled(record, velocity, trigger, contact_start, samples.rest, config):
        flags.add('unsettled')
    follower = TriggerDetector(config, record.sample_rate_hz, last_trigger=trigger)
    if follower.scan(force[trigger + 1 :], trigger + 1):
        flags.add('overlap')
    return tuple(flag for flag in FLAGS if flag in flags)


def _contact(force: np.ndarray, trigger: int, config: CaptureConfig) -> tuple[int, int]:
    """The contact's first sample and the one after it: the force back below the re-arm level.

    A pulse that is over within its first sample (a record's resting level taken off, or a
    spike) still has one sample of contact: never an empty span.
    """
    after_contact = first_where(
        lambda chunk: below_level(chunk, config.rearm_level_n), force[trigger:]
    )
    contact_end = force.size if after_contact < 0 else trigger + after_contact
    contact_start = contact_start_index(force, trigger, config)
    return contact_start, max(contact_end, min(contact_start + 1, force.size))


def _pulse_flags(
    force: np.ndarray,
    sample_rate_hz: float,
    trigger: int,
    contact_end: int,
    contact_start: int,
    config: CaptureConfig,
) -> set[str]:
    """double_hit and coarse: a rebound after the contact, too few samples in it."""
    flags = set()
    samples = config.samples(sample_rate_hz)
    peak = float(np.nanmax(force[contact_start:contact_end]))
    if pulse.rebounds(
        force,
        contact_end,
        trigger + samples.min_spacing,
        peak,
        config.trigger_level_n,
        config.rearm_level_n,
    ):
        flags.add('double_hit')
    if pulse.coarse(
        contact_duration(force, sample_rate_hz, config.rearm_level_n, contact_start),
        sample_rate_hz,
    ):
        flags.add('coarse')
    return flags


def _recording_flags(record: ImpactRecord) -> set[str]:
    """gap, interrupted and truncated_start: what the acquisition did to the record."""
    flags = set()
    if record.force_gaps or record.velocity_gaps:
        flags.add('gap')
    if record.interrupted:
        flags.add('interrupted')
    if record.truncated_start:
        flags.add('truncated_start')
    return flags


def _unsettled(
    record: ImpactRecord,
    velocity: np.ndarray,
    trigger: int,
    contact_start: int,
    rest_samples: int,
    config: CaptureConfig,
) -> bool:
    """The response moves before the hit or in the record's tail (the unsettled rule).

    Motion is judged about the level at rest before the hit: a vibrometer's offset is not.
    """
    before = velocity[:contact_start]
    finite_before = before[np.isfinite(before)]
    rest_level = float(np.median(finite_before)) if finite_before.size else 0.0
    if record.response is None:
        rest = config.rest_velocity_m_s
        tail = velocity[max(trigger + 1, velocity.size - rest_samples) :]
    else:
        tail_samples = max(SETTLED_TAIL_MIN_SAMPLES, int(SETTLED_TAIL_FRACTION * velocity.size))
        tail = velocity[max(trigger + 1, velocity.size - tail_samples) :]
        with np.errstate(invalid='ignore'):
            rest = SETTLED_RESPONSE_FRACTION * float(np.nanmax(np.abs(velocity - rest_level)))
    return bool(
        np.any(np.abs(before - rest_level) > rest) or np.any(np.abs(tail - rest_level) > rest)
    )


def _second_spread(samples: np.ndarray) -> float | None:
    """`has_white_noise`'s second spread of a channel (None when `white_noise_std` is 0)."""
    return None if samples.size <= 2 else _difference_spread(samples, 2)


def _plateaus(samples: np.ndarray, signs: tuple[float, ...], noise_std: float) -> tuple[float, ...]:
    """Levels of the channel's clipped extremes (`flat_extreme`) on the given sides."""
    levels = (flat_extreme(samples, sign, noise_std) for sign in signs)
    return tuple(level for level in levels if level is not None)


def _beyond(samples: np.ndarray, full_scale: float) -> bool:
    """Whether any sample reaches a known full-scale range (0: unknown, never)."""
    return full_scale > 0 and bool(np.any(np.abs(samples) >= full_scale))


def _non_finite_outside(samples: np.ndarray, gaps: Gaps) -> bool:
    """Whether a sample outside the gap ranges is NaN or infinite."""
    if np.isfinite(np.sum(samples)):
        return False
    bad = ~np.isfinite(samples)
    for start, stop in gaps:
        bad[start:stop] = False
    return bool(bad.any())
