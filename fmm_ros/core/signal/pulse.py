"""What one hammer pulse must be: alone (no rebound) and sampled finely enough.

Shared by the impact flags (`capture.quality_flags`) and the check of the hammer alone
(`fmm_ros.core.signal.hammer`), so a hit gets one verdict wherever it is judged.

- double_hit (`rebounds`): after the force falls below the re-arm level it rises again,
  within min_spacing_s of the trigger, to the trigger level or to `REBOUND_FRACTION` of the
  hit's peak, whichever is lower (never below the re-arm level). A light hammer's rebound
  sampled at 1.6 kHz shows one or two samples of a few tens of per cent of the peak, under
  a trigger level set for the hit: it is the hit's rebound, not a new hit, and it spoils it.
  For the FMM's 450-1450 N hits the trigger level (20 N) is the lower: the rule is the
  paper-scale one.
- clipped (`shared_top`): several hits peak at the session's largest force to the last bit.
  A top clipped to one sample is no plateau, but hand-held hits do not peak at one identical
  value unless a rail cut them; `SHARED_TOP_HITS` (3) keeps a chance tie of two hits on a
  coarse ADC's step from alarming (give the sensor's range, `force_full_scale_n`, to catch
  one or two clipped hits).
- coarse (`coarse`): the contact, measured where the force crosses the re-arm level, spans
  fewer than `COARSE_PULSE_SAMPLES` sample intervals. The trapezoid impulse of a half-sine
  pulse of n samples is off by up to -9/+5 % at n = 3, -5/+3 % at 4, -3/+2 % at 5,
  -2.3/+1.2 % at 6 and -1.3/+0.6 % at 8, depending on where the samples fall; the peak
  force is missed by as much, and the force spectrum rolls off before Nyquist.
"""

from __future__ import annotations

import numpy as np

REBOUND_FRACTION = 0.1
"""A rebound reaches this fraction of its hit's peak (or the trigger level, if lower)."""

SHARED_TOP_HITS = 3
"""This many hits peaking at the largest force of a session, to the last bit, were clipped."""

COARSE_PULSE_SAMPLES = 6.0
"""A contact shorter than this many sample intervals is sampled too coarsely (module doc)."""


def rebound_level_n(peak_force_n: float, trigger_level_n: float, rearm_level_n: float) -> float:
    """The force a rebound reaches (see the module doc)."""
    return max(rearm_level_n, min(trigger_level_n, REBOUND_FRACTION * peak_force_n))


def rebounds(
    force_n: np.ndarray,
    contact_end: int,
    stop: int,
    peak_force_n: float,
    trigger_level_n: float,
    rearm_level_n: float,
) -> bool:
    """Whether the force rises to a rebound in [contact_end, stop).

    contact_end: the first sample below the re-arm level after the hit's contact.
    """
    after = force_n[contact_end:stop]
    level = rebound_level_n(peak_force_n, trigger_level_n, rearm_level_n)
    return bool(np.any((after >= level) & np.isfinite(after)))


def shared_top(peak_force_n: np.ndarray) -> np.ndarray:
    """Which hits peak at the session's largest force, shared by `SHARED_TOP_HITS` or more."""
    peaks = np.asarray(peak_force_n, dtype=float)
    finite = np.isfinite(peaks)
    if not finite.any():
        return np.zeros(peaks.shape, dtype=bool)
    top = peaks == np.max(peaks[finite])
    return top if np.count_nonzero(top) >= SHARED_TOP_HITS else np.zeros(peaks.shape, dtype=bool)


def coarse(contact_time_s: float, sample_rate_hz: float) -> bool:
    """Whether a contact of this duration is sampled too coarsely (NaN: not judged)."""
    return bool(contact_time_s * sample_rate_hz < COARSE_PULSE_SAMPLES)
