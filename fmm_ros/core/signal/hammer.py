"""The hammer alone: every hit of a force record with its time, peak, impulse, contact and flags.

A lab's first question after a hit is whether the hit was good, and many recordings hold the
force alone (dozens of hits at a low rate, some rebounding, some clipped, sometimes none).
`hammer_hits` answers it without a response channel, by the capture's trigger rule (so a hit
here is an impact there: a rebound is part of its hit, never a new one) and these flags:

- double_hit and coarse: the pulse rules every impact is judged by (`fmm_ros.core.signal.pulse`);
- clipped: the hit's peak reaches the force sensor's full scale, or its top is a flat plateau
  (`quality.flat_extreme`), or several hits share the record's top (`pulse.shared_top`);
- nan: a non-finite sample around the hit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fmm_ros.core.signal import frf, pulse, quality
from fmm_ros.core.signal.capture import (
    DEFAULT_CAPTURE,
    FLAGS,
    CaptureConfig,
    contact_start_index,
    find_triggers,
)

HIT_FLAGS: tuple[str, ...] = ('double_hit', 'clipped', 'coarse', 'nan')
"""The flags a hit of the force alone can raise (a subset of `capture.FLAGS`, in its order)."""


@dataclass(frozen=True)
class Hit:
    """One hammer hit: when, how hard, how long, and what is wrong with it."""

    trigger_sample_index: int
    time_s: float
    peak_force_n: float
    impulse_n_s: float
    contact_time_s: float
    flags: tuple[str, ...]
    accepted: bool
    """As every impact's `accepted`: no rejecting flag raised, its peak and impulse finite."""


def hammer_hits(
    force_n: np.ndarray,
    sample_rate_hz: float,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    *,
    force_full_scale_n: float = 0.0,
    reject_flags: tuple[str, ...] = FLAGS,
) -> list[Hit]:
    """Every hit of a force record [N] (see the module doc); an empty list when there is none.

    Each hit is judged on its own stretch, from the capture's pre-trigger before it to
    min_spacing_s after it: the level before its pulse is its impulse's baseline, and a
    rebound inside the stretch is its double hit. force_full_scale_n: the sensor's range
    (0: unknown). reject_flags: the flags that reject a hit (`AnalysisConfig.reject_flags`),
    so a hit is `accepted` by the rule every impact is.
    """
    force = np.asarray(force_n, dtype=float)
    samples = capture.samples(sample_rate_hz)
    noise = quality.white_noise_std(force)
    judged = []
    for trigger in map(int, find_triggers(force, sample_rate_hz, capture)):
        low = max(0, trigger - samples.pretrigger)
        stretch = force[low : trigger + samples.min_spacing]
        judged.append((trigger, *_judged(stretch, trigger - low, sample_rate_hz, capture, noise)))
    on_top = pulse.shared_top(np.array([peak for _, peak, *_ in judged]))
    hits = []
    for (trigger, peak, impulse, contact, flags), topped in zip(judged, on_top, strict=True):
        if (force_full_scale_n > 0 and peak >= force_full_scale_n) or topped:
            flags.add('clipped')
        raised = tuple(flag for flag in HIT_FLAGS if flag in flags)
        hits.append(
            Hit(
                trigger_sample_index=trigger,
                time_s=trigger / sample_rate_hz,
                peak_force_n=peak,
                impulse_n_s=impulse,
                contact_time_s=contact,
                flags=raised,
                accepted=not set(raised) & set(reject_flags)
                and bool(np.isfinite((peak, impulse)).all()),
            )
        )
    return hits


def _judged(
    stretch: np.ndarray,
    trigger: int,
    sample_rate_hz: float,
    capture: CaptureConfig,
    noise_std: float,
) -> tuple[float, float, float, set[str]]:
    """Peak [N], impulse [N s], contact time [s] and flags of the hit firing at `trigger`."""
    rearm = capture.rearm_level_n
    start = contact_start_index(stretch, trigger, capture)
    interval = frf.contact_interval(stretch, rearm, start)
    end = stretch.size if interval is None else interval[1]
    peak = float(np.nanmax(stretch[start:end]))
    contact = frf.contact_duration(stretch, sample_rate_hz, rearm, start)
    flags = set()
    if pulse.rebounds(stretch, end, stretch.size, peak, capture.trigger_level_n, rearm):
        flags.add('double_hit')
    if quality.flat_extreme(stretch, 1.0, noise_std) is not None:
        flags.add('clipped')
    if pulse.coarse(contact, sample_rate_hz):
        flags.add('coarse')
    if not np.isfinite(stretch).all():
        flags.add('nan')
    impulse = frf.pulse_impulse(stretch, sample_rate_hz, rearm, start)
    return peak, impulse, contact, flags
