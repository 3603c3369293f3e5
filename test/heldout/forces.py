"""Hammer hits as continuous-time forces with a sub-sample onset: half-sine, Hertzian, 2 exp.

Each force is a closed-form function of time that starts at `onset_s`, which need not fall on
a sample: the DAQ samples the force afterwards, so the first recorded sample of a hit holds a
fraction of its rise and the force between samples is never linear. Impulses are exact
(closed form), for the truth beside the records.
"""

import math
from dataclasses import dataclass

import numpy as np
import scipy.special

SHAPES = ('half_sine', 'hertz', 'double_exponential')

TAIL_TIME_CONSTANTS = 16.0
"""A double-exponential hit is cut off this many slow time constants after its onset (the
force there is 1e-7 of its peak)."""


@dataclass(frozen=True)
class Hit:
    """One hammer hit: shape, peak force [N], contact time [s] and onset [s]."""

    shape: str
    peak_n: float
    contact_s: float
    """Half-sine and Hertzian: the contact duration; two exponentials: the fall time constant."""
    onset_s: float
    rise_ratio: float = 0.25
    """Two exponentials only: rise time constant over fall time constant (< 1)."""

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ValueError(f'unknown hit shape {self.shape!r}; known: {SHAPES}')

    @property
    def end_s(self) -> float:
        """When the force is over [s]."""
        if self.shape == 'double_exponential':
            return self.onset_s + TAIL_TIME_CONSTANTS * self.contact_s
        return self.onset_s + self.contact_s

    def _amplitude(self) -> float:
        """The two-exponential amplitude whose difference peaks at peak_n."""
        fall, rise = self.contact_s, self.rise_ratio * self.contact_s
        at = math.log(fall / rise) * fall * rise / (fall - rise)
        return self.peak_n / (math.exp(-at / fall) - math.exp(-at / rise))

    def force_n(self, time_s: np.ndarray | float) -> np.ndarray:
        """The force at any times [N] (0 outside the contact)."""
        t = np.asarray(time_s, dtype=float) - self.onset_s
        inside = (t > 0.0) & (t < self.end_s - self.onset_s)
        out = np.zeros(t.shape)
        u = t[inside]
        if self.shape == 'half_sine':
            out[inside] = self.peak_n * np.sin(math.pi * u / self.contact_s)
        elif self.shape == 'hertz':
            out[inside] = self.peak_n * np.sin(math.pi * u / self.contact_s) ** 1.5
        else:
            fall, rise = self.contact_s, self.rise_ratio * self.contact_s
            out[inside] = self._amplitude() * (np.exp(-u / fall) - np.exp(-u / rise))
        return out

    def force_at(self, time_s: float) -> float:
        """The force at one time [N] (the integrators' scalar path)."""
        u = time_s - self.onset_s
        if u <= 0.0 or time_s >= self.end_s:
            return 0.0
        if self.shape == 'half_sine':
            return self.peak_n * math.sin(math.pi * u / self.contact_s)
        if self.shape == 'hertz':
            return self.peak_n * math.sin(math.pi * u / self.contact_s) ** 1.5
        fall, rise = self.contact_s, self.rise_ratio * self.contact_s
        return self._amplitude() * (math.exp(-u / fall) - math.exp(-u / rise))

    @property
    def impulse_n_s(self) -> float:
        """The exact impulse of the hit [N*s]."""
        if self.shape == 'half_sine':
            return 2.0 * self.peak_n * self.contact_s / math.pi
        if self.shape == 'hertz':
            # integral of sin^1.5 over a half period: sqrt(pi) Gamma(5/4) / Gamma(7/4)
            ratio = scipy.special.gamma(1.25) / scipy.special.gamma(1.75)
            return self.peak_n * self.contact_s * math.sqrt(math.pi) * ratio / math.pi
        fall, rise = self.contact_s, self.rise_ratio * self.contact_s
        span = self.end_s - self.onset_s  # the cut-off tail is not part of the hit
        return self._amplitude() * (
            fall * -math.expm1(-span / fall) - rise * -math.expm1(-span / rise)
        )


LEVELS_N = (450.0, 1000.0, 1450.0)
"""The paper's three hammer levels."""


def random_hit(
    rng: np.random.Generator, level_n: float, onset_s: float, shapes: tuple[str, ...] = SHAPES
) -> Hit:
    """A hit near a level (+-2 %, inside the paper's +-50 N), of a random shape, 1.5-4 ms long."""
    shape = str(rng.choice(shapes))
    peak = level_n * rng.uniform(0.98, 1.02)
    if shape == 'double_exponential':
        return Hit(shape, peak, rng.uniform(0.4e-3, 0.9e-3), onset_s, rng.uniform(0.15, 0.4))
    return Hit(shape, peak, rng.uniform(1.5e-3, 4e-3), onset_s)
