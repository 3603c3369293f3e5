"""Damaged data: what goes wrong in a real recording, attached to one hit of a session.

Each kind acts where it happens physically:

- `DoubleHit`: the hammer bounces and strikes again (a second pulse, `ratio` times the first,
  `delay_s` after its start). It is part of the force the rig feels, so the motion changes.
- `ForceClip`: the force channel saturates flat at `fraction` of the hit's true peak (an
  amplifier range set for a softer hit); the full scale is not told to the reader.
- `DeadVibrometer`: the vibrometer loses the beam or is unplugged over the hit's span: noise
  and interference only (`constant_m_s` None), or a constant output.
- `VibrometerSaturation`: the vibrometer's range is exceeded: flat at +-`range_m_s`.
- `NonFiniteBurst`: a run of NaN (or Inf) samples in one or both channels (a driver fault).
- `DroppedSamples`: a stretch of samples never recorded: both channels lose it, so the time
  column jumps (the arrays get shorter).

The first is applied to the excitation, the next three to the analog signal before the ADC,
the last two to the digitised samples. A hit's span runs from `SPAN_LEAD_S` before it to the
same distance before the next hit (or the end of the recording).
"""

import math
from dataclasses import dataclass, replace

import numpy as np

from worlds.pulses import PlacedPulse

SPAN_LEAD_S = 0.5
"""A hit's span starts this long before the hit (it covers a record's pre-trigger)."""
CHANNELS = ('force', 'velocity', 'both')


@dataclass
class AnalogArrays:
    """Both channels at the ADC input, and what is known about them, for analog damage."""

    force: np.ndarray
    velocity: np.ndarray
    force_signal: np.ndarray
    velocity_interference: np.ndarray


@dataclass
class DigitalArrays:
    """Both digitised channels and the mask of samples kept, for digital damage."""

    force: np.ndarray
    velocity: np.ndarray
    keep: np.ndarray
    sample_rate_hz: float

    def run(self, hit_time_s: float, offset_s: float, length: int) -> slice:
        """The samples from `offset_s` after the hit, `length` of them (inside the arrays)."""
        size = self.force.size
        first = min(max(math.ceil((hit_time_s + offset_s) * self.sample_rate_hz), 0), size)
        return slice(first, min(first + length, size))


class Damage:
    """Base of the damage kinds; each overrides the stage it acts at."""

    def extra_pulses(self, main: PlacedPulse) -> tuple[PlacedPulse, ...]:
        """Pulses added to the hit's excitation."""
        return ()

    def apply_analog(self, arrays: AnalogArrays, span: slice) -> None:
        """Change the analog channels in place over the hit's span."""

    def apply_digital(self, arrays: DigitalArrays, hit_time_s: float) -> None:
        """Change the digitised channels (or the kept-sample mask) in place."""


@dataclass(frozen=True)
class DoubleHit(Damage):
    """A second strike `delay_s` after the first, `ratio` times its force."""

    ratio: float = 0.7
    delay_s: float = 0.05

    def __post_init__(self) -> None:
        if not (self.ratio > 0 and self.delay_s > 0):
            raise ValueError(
                f'double hit needs ratio > 0 and delay > 0, got {self.ratio}, {self.delay_s}'
            )

    def extra_pulses(self, main: PlacedPulse) -> tuple[PlacedPulse, ...]:
        second = replace(main.pulse, peak_force_n=main.pulse.peak_force_n * self.ratio)
        return (PlacedPulse(second, main.start_s + self.delay_s),)


@dataclass(frozen=True)
class ForceClip(Damage):
    """The force flat at +-`fraction` of the hit's true (filtered) peak."""

    fraction: float = 0.6

    def __post_init__(self) -> None:
        if not 0 < self.fraction < 1:
            raise ValueError(f'clip fraction must be in (0, 1), got {self.fraction}')

    def apply_analog(self, arrays: AnalogArrays, span: slice) -> None:
        level = self.fraction * float(np.max(np.abs(arrays.force_signal[span])))
        np.clip(arrays.force[span], -level, level, out=arrays.force[span])


@dataclass(frozen=True)
class DeadVibrometer(Damage):
    """No velocity signal over the span: noise only (None) or a constant output [m/s]."""

    constant_m_s: float | None = None

    def apply_analog(self, arrays: AnalogArrays, span: slice) -> None:
        if self.constant_m_s is None:
            arrays.velocity[span] = arrays.velocity_interference[span]
        else:
            arrays.velocity[span] = self.constant_m_s


@dataclass(frozen=True)
class VibrometerSaturation(Damage):
    """The velocity flat at +-`range_m_s` wherever it would exceed it."""

    range_m_s: float = 0.05

    def __post_init__(self) -> None:
        if not self.range_m_s > 0:
            raise ValueError(f'vibrometer range must be > 0, got {self.range_m_s}')

    def apply_analog(self, arrays: AnalogArrays, span: slice) -> None:
        np.clip(arrays.velocity[span], -self.range_m_s, self.range_m_s, out=arrays.velocity[span])


@dataclass(frozen=True)
class NonFiniteBurst(Damage):
    """`length_samples` of `value` (NaN, +-Inf) from `offset_s` after the hit."""

    channel: str = 'velocity'
    offset_s: float = 0.2
    length_samples: int = 50
    value: float = math.nan

    def __post_init__(self) -> None:
        if self.channel not in CHANNELS:
            raise ValueError(f'unknown channel {self.channel!r}; known: {", ".join(CHANNELS)}')
        if math.isfinite(self.value) or self.length_samples < 1:
            raise ValueError(
                f'a burst needs a non-finite value and >= 1 sample, got '
                f'{self.value}, {self.length_samples}'
            )

    def apply_digital(self, arrays: DigitalArrays, hit_time_s: float) -> None:
        run = arrays.run(hit_time_s, self.offset_s, self.length_samples)
        for name, array in (('force', arrays.force), ('velocity', arrays.velocity)):
            if self.channel in (name, 'both'):
                array[run] = self.value


@dataclass(frozen=True)
class DroppedSamples(Damage):
    """`length_samples` never recorded, from `offset_s` after the hit."""

    offset_s: float = 0.5
    length_samples: int = 100

    def __post_init__(self) -> None:
        if self.length_samples < 1:
            raise ValueError(f'a drop needs >= 1 sample, got {self.length_samples}')

    def apply_digital(self, arrays: DigitalArrays, hit_time_s: float) -> None:
        arrays.keep[arrays.run(hit_time_s, self.offset_s, self.length_samples)] = False


DAMAGE_KINDS: tuple[type[Damage], ...] = (
    DoubleHit,
    ForceClip,
    DeadVibrometer,
    VibrometerSaturation,
    NonFiniteBurst,
    DroppedSamples,
)


def random_damage(
    rng: np.random.Generator, kinds: tuple[type[Damage], ...] = DAMAGE_KINDS
) -> Damage:
    """One damage of a random kind among `kinds`, with plausible random parameters."""
    kind = kinds[rng.integers(len(kinds))]
    if kind is DoubleHit:
        return DoubleHit(rng.uniform(0.3, 0.9), rng.uniform(0.01, 0.08))
    if kind is ForceClip:
        return ForceClip(rng.uniform(0.4, 0.9))
    if kind is DeadVibrometer:
        return DeadVibrometer(None if rng.random() < 0.5 else float(rng.uniform(-0.01, 0.01)))
    if kind is VibrometerSaturation:
        return VibrometerSaturation(rng.uniform(0.02, 0.08))
    if kind is NonFiniteBurst:
        return NonFiniteBurst(
            str(rng.choice(CHANNELS)),
            rng.uniform(0.0, 2.0),
            int(rng.integers(1, 500)),
            float(rng.choice([math.nan, math.inf, -math.inf])),
        )
    return DroppedSamples(rng.uniform(0.0, 2.0), int(rng.integers(1, 2000)))
