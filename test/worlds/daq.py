"""The acquisition chain: continuous sensor signals in, two sampled ADC channels out.

Per channel (force in N, velocity in m/s), in the order the hardware applies them:

1. The continuous signal (`ContinuousSignal`: a baseline plus a deviation that is zero outside
   known windows) is evaluated at `oversampling` times the output rate.
2. An analog anti-alias filter (`AnalogFilter`: Butterworth, Bessel, Chebyshev I or elliptic,
   designed in the s-domain) acts on it, discretised at the high rate by first-order hold
   in partial-fraction form (`DiscreteFilter`: exact for an input linear between the
   oversampled points; the transfer function's residual error is (pi f / f_high)^2 / 3, 5e-4
   at 1 kHz and 8e-3 at 4 kHz for 8x oversampling of 10 kHz, exact at DC, for any order).
   The filter may differ between channels or be absent.
3. Decimation: every `oversampling`-th filtered point is an output sample (t_n = n / rate).
4. Interference, referred to the ADC input: mains hum (the mains frequency and harmonics with
   random amplitudes and phases, passed through the filter's analog response), a constant
   offset, a slow random-walk drift, white noise and optional pink (1/f) noise.
5. The ADC: clipped to its full scale and rounded to its step (2 full_scale / 2^bits).

The clock is ideal (no jitter, no rate error). Only the windows where a signal moves are
oversampled and filtered: outside them the deviation is zero, so by linearity the filter's
output there is its DC gain times the baseline; each window runs on until the filter's slowest
pole has decayed by 1e-15. A 33 s record thus costs what its few seconds of motion cost.
"""

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.signal

FILTER_KINDS = ('butterworth', 'bessel', 'chebyshev1', 'elliptic')
_SETTLE_DECADES = 15.0
_DRIFT_KNOT_S = 0.1
"""The drift's random walk is drawn at this spacing and interpolated linearly."""


@dataclass(frozen=True)
class AnalogFilter:
    """An analog low-pass (cutoff: -3 dB for Butterworth and Bessel, ripple edge otherwise)."""

    kind: str = 'butterworth'
    order: int = 4
    cutoff_hz: float = 4000.0
    passband_ripple_db: float = 0.1
    stopband_attenuation_db: float = 80.0

    def __post_init__(self) -> None:
        if self.kind not in FILTER_KINDS:
            raise ValueError(f'unknown filter kind {self.kind!r}; known: {", ".join(FILTER_KINDS)}')
        if not (self.order >= 1 and self.cutoff_hz > 0):
            raise ValueError(
                f'filter needs order >= 1 and cutoff > 0, got {self.order}, {self.cutoff_hz} Hz'
            )

    def zpk(self) -> tuple[np.ndarray, np.ndarray, float]:
        """Zeros, poles [rad/s] and gain of the s-domain design."""
        wc = 2.0 * np.pi * self.cutoff_hz
        common = {'analog': True, 'output': 'zpk'}
        if self.kind == 'butterworth':
            return scipy.signal.butter(self.order, wc, **common)
        if self.kind == 'bessel':
            return scipy.signal.bessel(self.order, wc, norm='mag', **common)
        if self.kind == 'chebyshev1':
            return scipy.signal.cheby1(self.order, self.passband_ripple_db, wc, **common)
        return scipy.signal.ellip(
            self.order, self.passband_ripple_db, self.stopband_attenuation_db, wc, **common
        )

    def response(self, frequency_hz: np.ndarray | float) -> np.ndarray:
        """Complex analog frequency response H(j 2 pi f)."""
        _, h = scipy.signal.freqs_zpk(*self.zpk(), 2.0 * np.pi * np.atleast_1d(frequency_hz))
        return h

    def discretised(self, rate_hz: float) -> 'DiscreteFilter':
        """The first-order-hold discretisation at `rate_hz` (see `DiscreteFilter`), cached."""
        if not self.cutoff_hz < 0.5 * rate_hz:
            raise ValueError(
                f'cutoff {self.cutoff_hz} Hz is not below half the filter rate '
                f'{rate_hz} Hz: raise the oversampling'
            )
        return _discretised(self, rate_hz)


@dataclass(frozen=True)
class DiscreteFilter:
    """An analog filter discretised exactly for inputs linear between samples, in parallel form.

    H(s) = D + sum r_i / (s - p_i) (partial fractions from the zeros and poles, never through
    polynomial coefficients, which lose precision at high order). Each term x' = p x + r u is
    stepped exactly for a linearly interpolated input: x[n+1] = e^(pT) x[n] + r (b0 u[n] +
    b1 u[n+1]), b1 = (e^(pT) - 1 - pT) / (p^2 T), b0 = (e^(pT) - 1) / p - b1. Conjugate pairs
    are combined into real second-order sections run in parallel.
    """

    sections: tuple[tuple[np.ndarray, np.ndarray], ...]
    direct: float
    settle_samples: int
    """Samples after which the slowest pole has decayed by 1e-15."""

    @classmethod
    def first_order_hold(
        cls, zeros: np.ndarray, poles: np.ndarray, gain: float, rate_hz: float
    ) -> 'DiscreteFilter':
        """Discretise the s-domain (zeros, poles [rad/s], gain) at `rate_hz`."""
        # Work in time scaled by the fastest pole's magnitude, so the numbers stay near 1.
        scale = float(np.max(np.abs(poles)))
        zeros, poles = np.asarray(zeros) / scale, np.asarray(poles) / scale
        gain = gain / scale ** (poles.size - zeros.size)
        step = scale / rate_hz
        sections = []
        for i, pole in enumerate(poles):
            if pole.imag < -1e-12 * abs(pole):
                continue  # the conjugate's section covers it
            others = np.delete(poles, i)
            residue = gain * np.prod(pole - zeros) / np.prod(pole - others)
            q = pole * step
            growth = np.expm1(q)
            b1 = (growth - q) / (pole * q)
            b0 = growth / pole - b1
            phi = growth + 1.0
            if abs(pole.imag) <= 1e-12 * abs(pole):
                sections.append(
                    (np.array([residue * b1, residue * b0]).real, np.array([1.0, -phi.real]))
                )
                continue
            conj = np.conj(phi)
            numerator = (
                2.0
                * np.array([residue * b1, residue * (b0 - b1 * conj), -residue * b0 * conj]).real
            )
            sections.append((numerator, np.array([1.0, -2.0 * phi.real, abs(phi) ** 2])))
        radius = float(np.max(np.abs(np.exp(poles * step))))
        settle = math.ceil(_SETTLE_DECADES * math.log(10.0) / -math.log(radius))
        direct = float(np.real(gain)) if zeros.size == poles.size else 0.0
        return cls(tuple(sections), direct, settle)

    def apply(self, samples: np.ndarray) -> np.ndarray:
        """Filter samples taken at the discretisation rate, from rest."""
        out = self.direct * samples
        for numerator, denominator in self.sections:
            out += scipy.signal.lfilter(numerator, denominator, samples)
        return out

    def response(self, frequency_hz: np.ndarray, rate_hz: float) -> np.ndarray:
        """Complex frequency response of the discrete filter at `rate_hz`."""
        z = np.exp(2j * np.pi * np.asarray(frequency_hz, dtype=float) / rate_hz)
        total = np.full(z.shape, self.direct, dtype=complex)
        for numerator, denominator in self.sections:
            total += np.polyval(numerator[::-1], 1 / z) / np.polyval(denominator[::-1], 1 / z)
        return total


@functools.cache
def _discretised(analog: AnalogFilter, rate_hz: float) -> DiscreteFilter:
    return DiscreteFilter.first_order_hold(*analog.zpk(), rate_hz)


@dataclass(frozen=True)
class ChannelChain:
    """One channel from sensor to ADC; amplitudes in the channel's unit (N or m/s).

    `hum_amplitude` is the mains fundamental's amplitude; each harmonic gets a random fraction
    (5-50 %, divided by its order) of it and every component a random phase.
    `drift_per_sqrt_s` is the random walk's standard deviation after one second.
    """

    anti_alias: AnalogFilter | None = AnalogFilter()
    noise_std: float = 0.0
    pink_noise_std: float = 0.0
    offset: float = 0.0
    hum_amplitude: float = 0.0
    drift_per_sqrt_s: float = 0.0
    full_scale: float = 1.0
    adc_bits: int = 16

    def __post_init__(self) -> None:
        for name in ('noise_std', 'pink_noise_std', 'hum_amplitude', 'drift_per_sqrt_s'):
            if not getattr(self, name) >= 0:
                raise ValueError(f'{name} must be >= 0, got {getattr(self, name)}')
        if not (self.full_scale > 0 and 2 <= self.adc_bits <= 32):
            raise ValueError(
                f'ADC needs full scale > 0 and 2-32 bits, got {self.full_scale}, {self.adc_bits}'
            )

    @property
    def adc_step(self) -> float:
        """One ADC count, in the channel's unit."""
        return 2.0 * self.full_scale / 2.0**self.adc_bits


FORCE_CHAIN = ChannelChain(noise_std=0.2, offset=0.05, hum_amplitude=0.05, full_scale=5000.0)
"""Force defaults: the paper's 0.2 N noise, a small offset and hum, +-5 kN at 16 bits."""
VELOCITY_CHAIN = ChannelChain(
    noise_std=1e-4, hum_amplitude=2e-5, drift_per_sqrt_s=1e-6, full_scale=0.5
)
"""Velocity defaults: the paper's 1e-4 m/s noise, hum, slow drift, +-0.5 m/s at 16 bits."""


@dataclass(frozen=True)
class DaqChain:
    """Sample rate, oversampling, mains, and the two channels' chains."""

    sample_rate_hz: float = 10_000.0
    oversampling: int = 8
    mains_hz: float = 50.0
    hum_harmonics: tuple[int, ...] = (1, 2, 3, 5)
    force: ChannelChain = FORCE_CHAIN
    velocity: ChannelChain = VELOCITY_CHAIN

    def __post_init__(self) -> None:
        if not (self.sample_rate_hz > 0 and self.oversampling >= 1 and self.mains_hz > 0):
            raise ValueError(
                f'DAQ needs a positive rate, oversampling >= 1 and mains > 0, got '
                f'{self.sample_rate_hz} Hz, {self.oversampling}, {self.mains_hz} Hz'
            )


DEFAULT_DAQ = DaqChain()
"""10 kHz, 8x oversampled, 50 Hz mains, the default force and velocity chains."""


@dataclass(frozen=True)
class ContinuousSignal:
    """baseline + deviation(t): the deviation is zero outside the (a, b) windows [s]."""

    windows: tuple[tuple[float, float], ...]
    deviation: Callable[[np.ndarray], np.ndarray]
    baseline: float = 0.0


@dataclass(frozen=True)
class HumComponent:
    """One realised mains component at the ADC input (before the filter)."""

    frequency_hz: float
    amplitude: float
    phase_rad: float


@dataclass(frozen=True)
class AnalogChannel:
    """One channel before the ADC: the filtered sensor signal and the added interference."""

    signal: np.ndarray
    interference: np.ndarray
    hum: tuple[HumComponent, ...] = field(default=())

    @property
    def total(self) -> np.ndarray:
        """What reaches the ADC."""
        return self.signal + self.interference


def _merged(windows, gap_s: float) -> list[list[float]]:
    merged: list[list[float]] = []
    for a, b in sorted(windows):
        if merged and a <= merged[-1][1] + gap_s:
            merged[-1][1] = max(merged[-1][1], b)
        else:
            merged.append([a, b])
    return merged


def _filtered_signal(
    signal: ContinuousSignal,
    anti_alias: AnalogFilter | None,
    daq: DaqChain,
    n_samples: int,
    start_s: float,
) -> np.ndarray:
    """The signal through the filter, sampled at start_s + n / rate (see module, step 1-3)."""
    rate = daq.sample_rate_hz
    if anti_alias is None:
        out = np.full(n_samples, float(signal.baseline))
        for a, b in _merged(signal.windows, 0.0):
            first = max(math.ceil((a - start_s) * rate), 0)
            last = min(math.floor((b - start_s) * rate), n_samples - 1)
            if last >= first:
                index = np.arange(first, last + 1)
                out[first : last + 1] += signal.deviation(start_s + index / rate)
        return out
    factor = daq.oversampling
    high_rate = rate * factor
    discrete = anti_alias.discretised(high_rate)
    settle = discrete.settle_samples
    dc_gain = float(anti_alias.response(0.0)[0].real)
    out = np.full(n_samples, dc_gain * signal.baseline)
    for a, b in _merged(signal.windows, settle / high_rate):
        first = max(math.floor((a - start_s) * high_rate), 0)
        last = min(math.ceil((b - start_s) * high_rate) + settle, n_samples * factor - 1)
        if last < first:
            continue
        filtered = discrete.apply(
            signal.deviation(start_s + np.arange(first, last + 1) / high_rate)
        )
        kept = -(-first // factor)
        picked = filtered[kept * factor - first :: factor]
        out[kept : kept + picked.size] += picked
    return out


def _hum(
    chain: ChannelChain, daq: DaqChain, n_samples: int, start_s: float, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[HumComponent, ...]]:
    """Mains hum at the ADC, through the filter's analog response, and its components."""
    if not chain.hum_amplitude:
        return np.zeros(n_samples), ()
    components = tuple(
        HumComponent(
            daq.mains_hz * h,
            chain.hum_amplitude * (1.0 if h == 1 else rng.uniform(0.05, 0.5) / h),
            rng.uniform(0.0, 2.0 * np.pi),
        )
        for h in daq.hum_harmonics
    )
    frequencies = np.array([c.frequency_hz for c in components])
    response = (
        chain.anti_alias.response(frequencies)
        if chain.anti_alias is not None
        else np.ones(frequencies.size)
    )
    # Hum repeats after `period` samples when rate / mains is rational with a small
    # denominator (50 Hz at 10 kHz: 200 samples); one period is computed and tiled.
    ratio = daq.sample_rate_hz / daq.mains_hz
    period = next((k for k in range(1, 101) if abs(ratio * k - round(ratio * k)) < 1e-9), None)
    length = min(n_samples, round(ratio * period)) if period else n_samples
    t_s = start_s + np.arange(length) / daq.sample_rate_hz
    hum = np.zeros(length)
    for component, h in zip(components, response, strict=True):
        hum += (
            component.amplitude
            * abs(h)
            * np.sin(2.0 * np.pi * component.frequency_hz * t_s + component.phase_rad + np.angle(h))
        )
    return np.tile(hum, -(-n_samples // hum.size))[:n_samples], components


def _pink(n_samples: int, std: float, rng: np.random.Generator) -> np.ndarray:
    """Zero-mean noise with a 1/f power spectrum, scaled to `std`."""
    spectrum = np.fft.rfft(rng.standard_normal(n_samples))
    scale = np.zeros(spectrum.size)
    scale[1:] = 1.0 / np.sqrt(np.arange(1, spectrum.size))
    noise = np.fft.irfft(spectrum * scale, n_samples)
    return noise * (std / noise.std())


def _random_walk(
    n_samples: int, rate_hz: float, std_per_sqrt_s: float, rng: np.random.Generator
) -> np.ndarray:
    """A random walk from 0 with knots every `_DRIFT_KNOT_S`, linear between them."""
    knots = math.ceil(n_samples / rate_hz / _DRIFT_KNOT_S) + 1
    walk = np.concatenate(([0.0], np.cumsum(rng.standard_normal(knots - 1)))) * (
        std_per_sqrt_s * math.sqrt(_DRIFT_KNOT_S)
    )
    return np.interp(
        np.arange(n_samples) * (1.0 / (rate_hz * _DRIFT_KNOT_S)), np.arange(knots), walk
    )


def _interference(
    chain: ChannelChain, daq: DaqChain, n_samples: int, start_s: float, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[HumComponent, ...]]:
    total, components = _hum(chain, daq, n_samples, start_s, rng)
    dc_gain = float(chain.anti_alias.response(0.0)[0].real) if chain.anti_alias is not None else 1.0
    total += dc_gain * chain.offset
    if chain.drift_per_sqrt_s:
        total += dc_gain * _random_walk(n_samples, daq.sample_rate_hz, chain.drift_per_sqrt_s, rng)
    if chain.noise_std:
        noise = rng.standard_normal(n_samples)
        noise *= chain.noise_std
        total += noise
    if chain.pink_noise_std:
        total += _pink(n_samples, chain.pink_noise_std, rng)
    return total, components


def analog_channel(
    signal: ContinuousSignal,
    chain: ChannelChain,
    daq: DaqChain,
    n_samples: int,
    rng: np.random.Generator,
    start_s: float = 0.0,
) -> AnalogChannel:
    """One channel at the ADC input, sampled at start_s + n / rate for n < n_samples."""
    filtered = _filtered_signal(signal, chain.anti_alias, daq, n_samples, start_s)
    interference, hum = _interference(chain, daq, n_samples, start_s, rng)
    return AnalogChannel(filtered, interference, hum)


def digitise(values: np.ndarray, chain: ChannelChain) -> np.ndarray:
    """The ADC: clip to [-full_scale, full_scale - step] and round to whole steps."""
    step = chain.adc_step
    counts = np.multiply(values, 1.0 / step)
    np.rint(counts, out=counts)
    counts *= step
    return np.clip(counts, -chain.full_scale, chain.full_scale - step, out=counts)
