"""Friction laws of the pin-on-counterface contact, as small composable objects.

A law gives two coefficients, multiplied by the normal force N by the plant:

- `sliding_mu(direction, speed_m_s, position_m)`: the kinetic coefficient while the pin
  slides towards `direction` (+1 or -1) at `speed_m_s` >= 0 (the friction force opposes the
  motion; the plant applies the sign). The direction is explicit because the plant asks at
  zero speed too, the instant sliding starts;
- `static_mu(direction, position_m, dwell_s)`: the largest coefficient the contact holds at
  rest before it breaks away towards `direction` (+1 or -1), after sticking for `dwell_s`.

The base laws are `Coulomb` and `AsymmetricCoulomb`; the others wrap a base law and change one
aspect of it, so effects compose: `WearTrack(Stribeck(Coulomb(0.1), 0.02, 2e-3), 0.1, 5e-3)`
is a Stribeck contact sliding over a wavy wear track. `SpeedRegimes` blends two whole laws.

Every law here holds at least as much at rest as it drags when sliding starts
(static_mu(d, x, dwell) >= sliding_mu(d, 0, x)), so a mass that breaks away accelerates.
Coefficients take numpy arrays for direction, speed and position as well as scalars.

A law whose sliding coefficient depends only on the sliding direction
(`constant_sliding_mu(direction)` is not None) lets the plant solve free motion in closed form
(each half cycle is a damped oscillation about a shifted equilibrium); any other law goes the
general (ODE) path. `position_breaks_m` lists positions where the law jumps, so the ODE solver
stops there instead of stepping across a discontinuity.
"""

import math
from dataclasses import dataclass, replace

import numpy as np


class FrictionLaw:
    """Base of the friction laws: the coefficients the plant multiplies by the normal force."""

    def sliding_mu(self, direction: int, speed_m_s: float, position_m: float) -> float:
        """Kinetic coefficient sliding towards `direction` (+1/-1) at this speed and position."""
        raise NotImplementedError

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        """Break-away coefficient towards `direction` (+1/-1) after resting `dwell_s` here."""
        raise NotImplementedError

    def constant_sliding_mu(self, direction: int) -> float | None:
        """The sliding coefficient if it depends on the direction only, else None."""
        raise NotImplementedError

    @property
    def position_breaks_m(self) -> tuple[float, ...]:
        """Positions [m] where the coefficients jump (the ODE solver stops on them)."""
        return ()

    def scaled(self, factor: float) -> 'FrictionLaw':
        """The same law with every friction coefficient multiplied by `factor` (run-in)."""
        raise NotImplementedError

    @property
    def nominal_mu(self) -> float:
        """The one coefficient a Coulomb fit of this contact should find, by this law's account.

        Coulomb: mu; asymmetric: the mean of the two directions; Stribeck and static friction:
        the kinetic base; wear tracks: the track mean; speed regimes: the slow regime's.
        """
        raise NotImplementedError


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise ValueError(message)


@dataclass(frozen=True)
class Coulomb(FrictionLaw):
    """Dry (Coulomb) friction: one coefficient, sliding and static alike (the paper's Eq. 1)."""

    mu: float

    def __post_init__(self) -> None:
        _require(math.isfinite(self.mu) and self.mu >= 0, f'Coulomb mu must be >= 0, got {self.mu}')

    def sliding_mu(self, direction: int, speed_m_s: float, position_m: float) -> float:
        return self.mu

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        return self.mu

    def constant_sliding_mu(self, direction: int) -> float | None:
        return self.mu

    def scaled(self, factor: float) -> 'Coulomb':
        return Coulomb(self.mu * factor)

    @property
    def nominal_mu(self) -> float:
        return self.mu


@dataclass(frozen=True)
class AsymmetricCoulomb(FrictionLaw):
    """Coulomb friction that differs with sliding direction (mu+ in +x, mu- in -x).

    Physically: a tilted pin, a lay (grinding direction) on the counterface, or a pin holder
    that loads the contact differently pushing than pulling.
    """

    mu_positive: float
    mu_negative: float

    def __post_init__(self) -> None:
        _require(
            min(self.mu_positive, self.mu_negative) >= 0,
            f'asymmetric mu must be >= 0, got {self.mu_positive}, {self.mu_negative}',
        )

    def _mu(self, direction: int) -> float:
        return np.where(np.asarray(direction) > 0, self.mu_positive, self.mu_negative)[()]

    def sliding_mu(self, direction: int, speed_m_s: float, position_m: float) -> float:
        return self._mu(direction)

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        return self._mu(direction)

    def constant_sliding_mu(self, direction: int) -> float | None:
        return self.mu_positive if direction > 0 else self.mu_negative

    def scaled(self, factor: float) -> 'AsymmetricCoulomb':
        return AsymmetricCoulomb(self.mu_positive * factor, self.mu_negative * factor)

    @property
    def nominal_mu(self) -> float:
        return 0.5 * (self.mu_positive + self.mu_negative)


@dataclass(frozen=True)
class _Modifier(FrictionLaw):
    """A law that changes one aspect of a base law and passes the rest through."""

    base: FrictionLaw

    def sliding_mu(self, direction: int, speed_m_s: float, position_m: float) -> float:
        return self.base.sliding_mu(direction, speed_m_s, position_m)

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        return self.base.static_mu(direction, position_m, dwell_s)

    def constant_sliding_mu(self, direction: int) -> float | None:
        return self.base.constant_sliding_mu(direction)

    @property
    def position_breaks_m(self) -> tuple[float, ...]:
        return self.base.position_breaks_m

    def scaled(self, factor: float) -> FrictionLaw:
        return replace(self, base=self.base.scaled(factor))

    @property
    def nominal_mu(self) -> float:
        return self.base.nominal_mu


@dataclass(frozen=True)
class StaticFriction(_Modifier):
    """Static friction above kinetic: a jump of `excess_mu` at break-away, none while sliding.

    The classic stick-slip ingredient: the contact holds more than it drags, so the mass
    breaks away with a jerk and stops earlier in a wider band (+-mu_s N / k).
    """

    excess_mu: float = 0.02

    def __post_init__(self) -> None:
        _require(self.excess_mu >= 0, f'static excess must be >= 0, got {self.excess_mu}')

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        return self.base.static_mu(direction, position_m, dwell_s) + self.excess_mu

    def scaled(self, factor: float) -> 'StaticFriction':
        return replace(self, base=self.base.scaled(factor), excess_mu=self.excess_mu * factor)


@dataclass(frozen=True)
class Stribeck(_Modifier):
    """Stribeck friction: mu(v) = mu_base + excess exp(-(v / vs)^2), static = mu_base + excess.

    Boundary lubrication at low speed, a load-carrying film building up with speed: friction
    falls continuously from its static value towards the kinetic one over a speed vs.
    """

    excess_mu: float = 0.02
    stribeck_speed_m_s: float = 2e-3

    def __post_init__(self) -> None:
        _require(self.excess_mu >= 0, f'Stribeck excess must be >= 0, got {self.excess_mu}')
        _require(
            self.stribeck_speed_m_s > 0,
            f'Stribeck speed must be > 0, got {self.stribeck_speed_m_s}',
        )

    def sliding_mu(self, direction: int, speed_m_s: float, position_m: float) -> float:
        ratio = speed_m_s / self.stribeck_speed_m_s
        return self.base.sliding_mu(direction, speed_m_s, position_m) + self.excess_mu * np.exp(
            -ratio * ratio
        )

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        return self.base.static_mu(direction, position_m, dwell_s) + self.excess_mu

    def constant_sliding_mu(self, direction: int) -> float | None:
        return None

    def scaled(self, factor: float) -> 'Stribeck':
        return replace(self, base=self.base.scaled(factor), excess_mu=self.excess_mu * factor)


@dataclass(frozen=True)
class _PositionFactor(_Modifier):
    """A law whose base coefficients are multiplied by a function of position."""

    def position_factor(self, position_m: float) -> float:
        """Multiplier of the base coefficients at this position."""
        raise NotImplementedError

    def sliding_mu(self, direction: int, speed_m_s: float, position_m: float) -> float:
        return self.base.sliding_mu(direction, speed_m_s, position_m) * self.position_factor(
            position_m
        )

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        return self.base.static_mu(direction, position_m, dwell_s) * self.position_factor(
            position_m
        )

    def constant_sliding_mu(self, direction: int) -> float | None:
        return None


@dataclass(frozen=True)
class WearTrack(_PositionFactor):
    """Friction varying along a worn track: mu(x) = mu_base (1 + a sin(2 pi x / lambda + phi)).

    Repeated sliding over the same few millimetres polishes, scores or transfers material
    unevenly, so the coefficient depends on where the pin is, not on how fast it moves.
    """

    relative_amplitude: float = 0.1
    wavelength_m: float = 5e-3
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        _require(
            0 <= self.relative_amplitude < 1,
            f'wear track amplitude must be in [0, 1), got {self.relative_amplitude}',
        )
        _require(self.wavelength_m > 0, f'wavelength must be > 0, got {self.wavelength_m}')

    def position_factor(self, position_m: float) -> float:
        return 1.0 + self.relative_amplitude * np.sin(
            2.0 * np.pi * position_m / self.wavelength_m + self.phase_rad
        )


@dataclass(frozen=True)
class WearPatch(_PositionFactor):
    """A patch [start_m, stop_m) of the track where friction is `factor` times the base.

    A scratch, a lubricant-starved spot or a transfer-film island: sharp-edged, so the
    coefficient jumps where the pin crosses an edge.
    """

    start_m: float = -1e-3
    stop_m: float = 1e-3
    factor: float = 1.3

    def __post_init__(self) -> None:
        _require(
            self.start_m < self.stop_m,
            f'patch start {self.start_m} must be below its stop {self.stop_m}',
        )
        _require(self.factor >= 0, f'patch factor must be >= 0, got {self.factor}')

    def position_factor(self, position_m: float) -> float:
        position = np.asarray(position_m)
        inside = (self.start_m <= position) & (position < self.stop_m)
        return np.where(inside, self.factor, 1.0)[()]

    @property
    def position_breaks_m(self) -> tuple[float, ...]:
        return tuple(sorted({*self.base.position_breaks_m, self.start_m, self.stop_m}))


@dataclass(frozen=True)
class DwellStrengthening(_Modifier):
    """Static friction growing with the time at rest: + b ln(1 + dwell / theta).

    Rate-and-state (Dieterich) ageing: asperity contacts creep and grow while stuck, so a
    contact left at rest longer holds more. Outside the product's model vocabulary. Sliding
    friction is the base law's; only break-away (under the next hammer hit) feels it.
    """

    strengthening_mu: float = 0.01
    time_constant_s: float = 0.1

    def __post_init__(self) -> None:
        _require(
            self.strengthening_mu >= 0,
            f'dwell strengthening must be >= 0, got {self.strengthening_mu}',
        )
        _require(
            self.time_constant_s > 0, f'dwell time constant must be > 0, got {self.time_constant_s}'
        )

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        return self.base.static_mu(direction, position_m, dwell_s) + (
            self.strengthening_mu * np.log1p(np.maximum(dwell_s, 0.0) / self.time_constant_s)
        )

    def scaled(self, factor: float) -> 'DwellStrengthening':
        return replace(
            self, base=self.base.scaled(factor), strengthening_mu=self.strengthening_mu * factor
        )


@dataclass(frozen=True)
class SpeedRegimes(FrictionLaw):
    """Two friction regimes switching at a sliding speed: `slow` below, `fast` above.

    E.g. a lubricated contact that goes from boundary to mixed lubrication (friction drops) or
    a PTFE pin whose transfer film breaks up above a speed (friction rises). The blend is
    w = (1 + tanh((|v| - switch) / width)) / 2, a smooth but narrow switch, unlike Stribeck's
    decay from v = 0. Outside the product's model vocabulary: the decay rate of the amplitude
    changes mid-record when the peak speed falls through the switch.
    """

    slow: FrictionLaw
    fast: FrictionLaw
    switch_speed_m_s: float = 0.05
    width_m_s: float = 0.005

    def __post_init__(self) -> None:
        _require(
            self.switch_speed_m_s > 0 and self.width_m_s > 0,
            f'switch speed and width must be > 0, got {self.switch_speed_m_s}, {self.width_m_s}',
        )

    def _weight(self, speed_m_s: float) -> float:
        return 0.5 * (1.0 + np.tanh((speed_m_s - self.switch_speed_m_s) / self.width_m_s))

    def sliding_mu(self, direction: int, speed_m_s: float, position_m: float) -> float:
        weight = self._weight(speed_m_s)
        return (1.0 - weight) * self.slow.sliding_mu(
            direction, speed_m_s, position_m
        ) + weight * self.fast.sliding_mu(direction, speed_m_s, position_m)

    def static_mu(self, direction: int, position_m: float, dwell_s: float) -> float:
        weight = self._weight(0.0)
        return (1.0 - weight) * self.slow.static_mu(
            direction, position_m, dwell_s
        ) + weight * self.fast.static_mu(direction, position_m, dwell_s)

    def constant_sliding_mu(self, direction: int) -> float | None:
        return None

    @property
    def position_breaks_m(self) -> tuple[float, ...]:
        return tuple(sorted({*self.slow.position_breaks_m, *self.fast.position_breaks_m}))

    def scaled(self, factor: float) -> 'SpeedRegimes':
        return replace(self, slow=self.slow.scaled(factor), fast=self.fast.scaled(factor))

    @property
    def nominal_mu(self) -> float:
        return self.slow.nominal_mu
