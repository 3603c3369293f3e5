"""Hammer hits as continuous forces of time, with their exact impulses.

A pulse is a function of continuous time on its contact [0, contact_s], zero outside; the
DAQ samples it afterwards, so its true area is the analytic integral, not a trapezoid sum of
samples. Shapes:

- `HalfSine`: F sin(pi t / T), the textbook hammer pulse (impulse 2 F T / pi).
- `SkewedPulse`: a fast rise and a slower fall, F (u / r)^a ((1 - u) / (1 - r))^b with
  u = t / T, peak at u = r and onset exponent a (default 1.5, Hertzian contact: force grows
  as indentation^1.5; a lower a gives a fuller pulse); b = a (1 - r) / r puts the peak at r.
  Impulse F T B(a+1, b+1) / (r^a (1-r)^b).

Either may carry a little ringing, a multiplicative (1 + eps sin(2 pi f_r t + phi)) from the
tip and hammer-head resonance; its contribution to the impulse is integrated by Gauss
quadrature matched to the shape (Legendre for the half-sine, Jacobi for the skewed pulse),
exact to rounding for these smooth integrands.

The paper's levels (Kossack et al. 2019, Sec. 4-5): peaks 450 / 1000 / 1450 N, accepted
within +-50 N, mean impulses 0.98 / 1.42 / 1.64 N*s (a half-sine lasts 3.4 / 2.2 / 1.8 ms).
"""

import math
from dataclasses import dataclass

import numpy as np
import scipy.special

PAPER_LEVELS: dict[str, tuple[float, float]] = {
    'low': (450.0, 0.98),
    'medium': (1000.0, 1.42),
    'high': (1450.0, 1.64),
}
"""Level name -> (peak force [N], mean impulse [N*s]) of the paper's hits."""
ACCEPTANCE_N = 50.0
"""Hand-swung peaks scatter this far about the level (the paper's acceptance window)."""
ONSET_EXPONENT = 1.5
"""Force ~ t^1.5 at first contact (Hertz: force ~ indentation^1.5, indentation ~ t)."""
_QUADRATURE_NODES = 256


@dataclass(frozen=True)
class Pulse:
    """Base of the pulse shapes: peak force, contact duration and optional ringing."""

    peak_force_n: float
    contact_s: float
    ringing_fraction: float = 0.0
    ringing_hz: float = 0.0
    ringing_phase_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (self.peak_force_n > 0 and self.contact_s > 0):
            raise ValueError(
                f'a pulse needs a positive peak and contact, got '
                f'{self.peak_force_n} N, {self.contact_s} s'
            )
        if not 0 <= self.ringing_fraction < 1:
            raise ValueError(f'ringing fraction must be in [0, 1), got {self.ringing_fraction}')

    def shape(self, u: np.ndarray) -> np.ndarray:
        """The envelope on u = t / contact_s in [0, 1], peak 1."""
        raise NotImplementedError

    def _shape_integral(self) -> float:
        """Integral of `shape` over [0, 1], in closed form."""
        raise NotImplementedError

    def _shape_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        """Nodes u and weights w with sum w g(u) = integral of shape(u) g(u) over [0, 1]."""
        raise NotImplementedError

    def _ringing(self, t_s: np.ndarray) -> np.ndarray:
        return 1.0 + self.ringing_fraction * np.sin(
            2.0 * np.pi * self.ringing_hz * t_s + self.ringing_phase_rad
        )

    def force_n(self, t_s: np.ndarray | float) -> np.ndarray:
        """Force [N] at times `t_s` measured from first contact (0 outside the contact)."""
        t_s = np.asarray(t_s, dtype=float)
        inside = (t_s >= 0.0) & (t_s <= self.contact_s)
        u = np.where(inside, t_s / self.contact_s, 0.0)
        return np.where(inside, self.peak_force_n * self.shape(u) * self._ringing(t_s), 0.0)

    def force_at(self, t_s: float) -> float:
        """`force_n` for one time, with scalar math (the ODE right-hand side calls this)."""
        if not 0.0 <= t_s <= self.contact_s:
            return 0.0
        force = self.peak_force_n * self.shape_at(t_s / self.contact_s)
        if self.ringing_fraction:
            force *= 1.0 + self.ringing_fraction * math.sin(
                2.0 * math.pi * self.ringing_hz * t_s + self.ringing_phase_rad
            )
        return force

    def shape_at(self, u: float) -> float:
        """`shape` of one u in [0, 1], with scalar math."""
        raise NotImplementedError

    @property
    def impulse_n_s(self) -> float:
        """The exact area under the continuous force [N*s]."""
        area = self._shape_integral()
        if self.ringing_fraction:
            nodes, weights = self._shape_quadrature()
            area += self.ringing_fraction * float(
                weights
                @ np.sin(
                    2.0 * np.pi * self.ringing_hz * self.contact_s * nodes + self.ringing_phase_rad
                )
            )
        return self.peak_force_n * self.contact_s * area


@dataclass(frozen=True)
class HalfSine(Pulse):
    """F sin(pi t / T) for 0 <= t <= T: the textbook impact-hammer pulse."""

    def shape(self, u: np.ndarray) -> np.ndarray:
        return np.sin(np.pi * u)

    def shape_at(self, u: float) -> float:
        return math.sin(math.pi * u)

    def _shape_integral(self) -> float:
        return 2.0 / math.pi

    def _shape_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        x, w = scipy.special.roots_legendre(_QUADRATURE_NODES)
        u = 0.5 * (x + 1.0)
        return u, 0.5 * w * np.sin(np.pi * u)

    @classmethod
    def for_impulse(cls, peak_force_n: float, impulse_n_s: float, **ringing) -> 'HalfSine':
        """The half-sine of this peak whose (ringing-free) area is `impulse_n_s`."""
        return cls(peak_force_n, math.pi * impulse_n_s / (2.0 * peak_force_n), **ringing)


@dataclass(frozen=True)
class SkewedPulse(Pulse):
    """A fast-rise, slow-fall pulse peaking at `rise_fraction` of the contact (see module)."""

    rise_fraction: float = 0.25
    onset_exponent: float = ONSET_EXPONENT

    def __post_init__(self) -> None:
        super().__post_init__()
        if not 0.0 < self.rise_fraction < 1.0:
            raise ValueError(f'rise fraction must be in (0, 1), got {self.rise_fraction}')
        if not self.onset_exponent > 0.0:
            raise ValueError(f'onset exponent must be > 0, got {self.onset_exponent}')

    @property
    def exponents(self) -> tuple[float, float]:
        """(a, b) of u^a (1 - u)^b: onset exponent and the fall exponent putting the peak at r."""
        r, a = self.rise_fraction, self.onset_exponent
        return a, a * (1.0 - r) / r

    @property
    def rise_s(self) -> float:
        """Time from first contact to the peak [s]."""
        return self.rise_fraction * self.contact_s

    def shape(self, u: np.ndarray) -> np.ndarray:
        a, b = self.exponents
        r = self.rise_fraction
        return (u / r) ** a * ((1.0 - u) / (1.0 - r)) ** b

    def shape_at(self, u: float) -> float:
        a, b = self.exponents
        r = self.rise_fraction
        return (u / r) ** a * ((1.0 - u) / (1.0 - r)) ** b

    def _norm(self) -> float:
        a, b = self.exponents
        r = self.rise_fraction
        return r**a * (1.0 - r) ** b

    def _shape_integral(self) -> float:
        a, b = self.exponents
        return float(scipy.special.beta(a + 1.0, b + 1.0)) / self._norm()

    def _shape_quadrature(self) -> tuple[np.ndarray, np.ndarray]:
        # Jacobi weight (1 - x)^b (1 + x)^a on [-1, 1]; u = (1 + x) / 2 gives u^a (1 - u)^b.
        a, b = self.exponents
        x, w = scipy.special.roots_jacobi(_QUADRATURE_NODES, b, a)
        return 0.5 * (x + 1.0), w * 2.0 ** (-a - b - 1.0) / self._norm()

    @classmethod
    def for_impulse(
        cls, peak_force_n: float, impulse_n_s: float, rise_fraction: float, **options
    ) -> 'SkewedPulse':
        """The skewed pulse of this peak and rise fraction whose ringing-free area is given.

        `options`: onset_exponent and the ringing fields.
        """
        unit = cls(
            peak_force_n,
            1.0,
            rise_fraction=rise_fraction,
            onset_exponent=options.get('onset_exponent', ONSET_EXPONENT),
        )
        return cls(
            peak_force_n,
            impulse_n_s / (peak_force_n * unit._shape_integral()),
            rise_fraction=rise_fraction,
            **options,
        )


@dataclass(frozen=True)
class PlacedPulse:
    """A pulse whose contact starts at `start_s` on the recording's clock."""

    pulse: Pulse
    start_s: float

    @property
    def stop_s(self) -> float:
        """End of contact [s]."""
        return self.start_s + self.pulse.contact_s

    def force_n(self, t_s: np.ndarray | float) -> np.ndarray:
        """Force [N] at recording times `t_s`."""
        return self.pulse.force_n(np.asarray(t_s, dtype=float) - self.start_s)


def random_ringing(rng: np.random.Generator) -> dict[str, float]:
    """The hammer head's ringing on a third of the hits (1-6 % at 3-9 kHz), else none.

    Keyword arguments of `HalfSine` and `SkewedPulse`.
    """
    if rng.random() >= 1.0 / 3.0:
        return {}
    return {
        'ringing_fraction': rng.uniform(0.01, 0.06),
        'ringing_hz': rng.uniform(3e3, 9e3),
        'ringing_phase_rad': rng.uniform(0.0, 2.0 * np.pi),
    }


def random_pulse(rng: np.random.Generator, level: str | None = None) -> Pulse:
    """A hand-swung hit near one of the paper's levels (random level when None).

    Peak within +-50 N of the level, impulse within +-7 % of the level's mean (the hammer's
    tip and swing vary), a half-sine or a skewed pulse rising over 25-45 % of its contact with
    an onset exponent of 1-2 (rises of 0.6-1.9 ms), and ringing of 1-6 % at 3-9 kHz on a
    third of the hits.
    """
    if level is None:
        level = str(rng.choice(list(PAPER_LEVELS)))
    if level not in PAPER_LEVELS:
        raise ValueError(f'unknown hammer level {level!r}; known: {", ".join(PAPER_LEVELS)}')
    peak_n, impulse_n_s = PAPER_LEVELS[level]
    peak_n += rng.uniform(-ACCEPTANCE_N, ACCEPTANCE_N)
    impulse_n_s *= rng.uniform(0.93, 1.07)
    ringing = random_ringing(rng)
    if rng.random() < 0.5:
        return HalfSine.for_impulse(peak_n, impulse_n_s, **ringing)
    return SkewedPulse.for_impulse(
        peak_n,
        impulse_n_s,
        rng.uniform(0.25, 0.45),
        onset_exponent=rng.uniform(1.0, 2.0),
        **ringing,
    )
