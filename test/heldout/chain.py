"""The acquisition: an analog anti-alias filter, interference and noise, then the ADC.

Each channel's continuous signal is evaluated on a grid `oversample` times finer than the
sample rate over the stretch where it moves, passed through the anti-alias filter there (a
Butterworth or Bessel low-pass run on the fine grid, started in its steady state: the analog
filter, to within the fine grid's step), and read at the sample instants. Outside that stretch
the signal is constant, and so is the filter's output. Then, per channel: a zero offset, a
slow drift (a straight line or a random walk), mains hum (fundamental and third harmonic),
white noise, optionally coloured noise (first-order autoregressive), and rounding to the
ADC's step.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.signal


@dataclass(frozen=True)
class Channel:
    """What one channel adds after its filter (units of the channel)."""

    noise_std: float
    coloured_std: float = 0.0
    coloured_pole: float = 0.9
    """AR(1) coefficient of the coloured part: n[i] = pole n[i-1] + e[i]."""
    offset: float = 0.0
    drift: float = 0.0
    """Change over the record (its sign random): a line, or the spread of a random walk."""
    walk: bool = False
    hum: float = 0.0
    hum_third: float = 0.3
    """Third harmonic's amplitude relative to the fundamental's."""
    full_scale: float = 0.0
    """+- range of a 16-bit ADC (0: no rounding)."""


@dataclass(frozen=True)
class Daq:
    """The acquisition: rate, anti-alias filter, mains, and both channels."""

    force: Channel
    velocity: Channel
    rate_hz: float = 10_000.0
    oversample: int = 8
    filter_kind: str = 'butter'
    filter_order: int = 8
    cutoff_hz: float = 4000.0
    mains_hz: float = 50.0

    def filter(self) -> np.ndarray:
        """The anti-alias filter on the fine grid, as second-order sections."""
        fine = self.rate_hz * self.oversample
        if self.filter_kind == 'bessel':
            return scipy.signal.bessel(
                self.filter_order, self.cutoff_hz, fs=fine, output='sos', norm='delay'
            )
        return scipy.signal.butter(self.filter_order, self.cutoff_hz, fs=fine, output='sos')


def acquire(
    daq: Daq,
    signal: Callable[[np.ndarray], np.ndarray],
    channel: Channel,
    samples: int,
    start_s: float,
    active: tuple[float, float],
    rng: np.random.Generator,
) -> np.ndarray:
    """One channel's record: `samples` samples from start_s, the signal moving inside `active`.

    signal: the continuous signal at any times; constant before active[0] and after active[1].
    """
    rate, factor = daq.rate_hz, daq.oversample
    step = 1.0 / (rate * factor)
    first = max(0, math.floor((active[0] - start_s) * rate) - 20)
    last = min(samples, math.ceil((active[1] - start_s) * rate) + 200)
    before, after = (float(v) for v in signal(np.array([start_s - 1.0, active[1] + 1e3])))
    out = np.full(samples, before)
    out[last:] = after
    if last > first:
        fine_t = start_s + first / rate + step * np.arange((last - first) * factor)
        sos = daq.filter()
        state = scipy.signal.sosfilt_zi(sos) * before
        filtered, _ = scipy.signal.sosfilt(sos, signal(fine_t), zi=state)
        out[first:last] = filtered[::factor]
    return out + interference(daq, channel, samples, rng)


def interference(daq: Daq, channel: Channel, samples: int, rng: np.random.Generator) -> np.ndarray:
    """Offset, drift, hum, noise of one channel over a record (before the ADC)."""
    t = np.arange(samples) / daq.rate_hz
    extra = np.full(samples, channel.offset)
    if channel.drift:
        if channel.walk:
            walk = np.cumsum(rng.normal(size=samples))
            extra += channel.drift * walk / math.sqrt(samples)
        else:
            extra += rng.choice((-1.0, 1.0)) * channel.drift * t / t[-1]
    if channel.hum:
        phase = rng.uniform(0, 2 * math.pi, size=2)
        omega = 2 * math.pi * daq.mains_hz
        extra += channel.hum * (
            np.sin(omega * t + phase[0]) + channel.hum_third * np.sin(3 * omega * t + phase[1])
        )
    extra += rng.normal(0.0, channel.noise_std, samples)
    if channel.coloured_std:
        pole = channel.coloured_pole
        white = rng.normal(0.0, channel.coloured_std * math.sqrt(1 - pole * pole), samples)
        extra += scipy.signal.lfilter([1.0], [1.0, -pole], white)
    return extra


def digitise(values: np.ndarray, channel: Channel) -> np.ndarray:
    """Rounded to a 16-bit ADC's step over +-full_scale (clipped there)."""
    if not channel.full_scale:
        return values
    quantum = 2 * channel.full_scale / 2**16
    return np.clip(np.round(values / quantum) * quantum, -channel.full_scale, channel.full_scale)
