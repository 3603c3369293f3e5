"""The rig a generator simulates: the plant's constants, its friction law, and extra effects.

`World(plant, friction, effects)` is everything about the physics of a test; effects are small
typed objects, each one thing the lab may have that the bare Coulomb oscillator lacks:

- `ViscousDamping`: more viscous damping than the flexure's own (air drag, lubricant shear).
- `CubicStiffness`: a flexure that stiffens (k3 > 0) or softens with amplitude, k x + k3 x^3.
- `SecondMode`: another structural mode under the hammer, decoupled from the friction contact
  (m2 x2'' + c2 x2' + k2 x2 = f); the vibrometer sees its velocity on top of the rig's.
- `VibrometerLag`: the velocity signal is the rig's velocity a pure delay earlier (the
  vibrometer's decoder and its internal filter), v_meas(t) = v(t - delay).
- `VelocityOffset`: a constant added to the vibrometer output (decoder zero error).

The first two change the plant; the last three change what the vibrometer reports.
"""

import math
from dataclasses import dataclass, replace

from worlds.friction import Coulomb, FrictionLaw

STANDARD_GRAVITY_M_S2 = 9.81
PAPER_MU = 0.113
"""The paper's best-fit Coulomb coefficient (PTFE pin on lubricated steel)."""


@dataclass(frozen=True)
class Plant:
    """m x'' + c x' + k x + k3 x^3 + friction = f(t); defaults are the paper's FMM (Sec. 4)."""

    mass_kg: float = 10.391
    stiffness_n_per_m: float = 1982.0
    damping_n_s_per_m: float = 0.275
    normal_force_n: float = 0.680 * STANDARD_GRAVITY_M_S2
    cubic_stiffness_n_per_m3: float = 0.0

    def __post_init__(self) -> None:
        if not (self.mass_kg > 0 and self.stiffness_n_per_m > 0):
            raise ValueError(
                f'mass and stiffness must be > 0, got {self.mass_kg} kg, '
                f'{self.stiffness_n_per_m} N/m'
            )
        if not (self.damping_n_s_per_m >= 0 and self.normal_force_n >= 0):
            raise ValueError(
                f'damping and normal force must be >= 0, got '
                f'{self.damping_n_s_per_m} N*s/m, {self.normal_force_n} N'
            )

    @property
    def natural_frequency_hz(self) -> float:
        """sqrt(k / m) / 2 pi [Hz]."""
        return math.sqrt(self.stiffness_n_per_m / self.mass_kg) / (2.0 * math.pi)

    def spring_force_n(self, position_m: float) -> float:
        """k x + k3 x^3 [N]."""
        return position_m * (
            self.stiffness_n_per_m + self.cubic_stiffness_n_per_m3 * position_m * position_m
        )


FMM_PLANT = Plant()


@dataclass(frozen=True)
class ViscousDamping:
    """Viscous damping [N*s/m] added to the plant's."""

    damping_n_s_per_m: float = 0.5

    def __post_init__(self) -> None:
        if not self.damping_n_s_per_m >= 0:
            raise ValueError(f'added damping must be >= 0, got {self.damping_n_s_per_m}')


@dataclass(frozen=True)
class CubicStiffness:
    """Cubic spring coefficient k3 [N/m^3] added to the plant's (spring force k x + k3 x^3)."""

    cubic_stiffness_n_per_m3: float = 2e6


@dataclass(frozen=True)
class SecondMode:
    """A decoupled structural mode driven by the hammer: frequency, damping ratio, modal mass."""

    frequency_hz: float = 45.0
    damping_ratio: float = 0.01
    modal_mass_kg: float = 100.0

    def __post_init__(self) -> None:
        if not (self.frequency_hz > 0 and self.modal_mass_kg > 0 and 0 < self.damping_ratio < 1):
            raise ValueError(
                f'second mode needs f > 0, m > 0 and 0 < zeta < 1, got '
                f'{self.frequency_hz} Hz, {self.modal_mass_kg} kg, '
                f'zeta {self.damping_ratio}'
            )

    @property
    def constants(self) -> tuple[float, float, float]:
        """(mass [kg], damping [N*s/m], stiffness [N/m])."""
        omega = 2.0 * math.pi * self.frequency_hz
        mass = self.modal_mass_kg
        return mass, 2.0 * self.damping_ratio * mass * omega, mass * omega * omega


@dataclass(frozen=True)
class VibrometerLag:
    """The vibrometer reports the velocity `delay_s` late (a pure delay)."""

    delay_s: float = 5e-4

    def __post_init__(self) -> None:
        if not self.delay_s >= 0:
            raise ValueError(f'vibrometer lag must be >= 0, got {self.delay_s}')


@dataclass(frozen=True)
class VelocityOffset:
    """A constant [m/s] added to the vibrometer output."""

    offset_m_s: float = 1e-4


Effect = ViscousDamping | CubicStiffness | SecondMode | VibrometerLag | VelocityOffset


@dataclass(frozen=True)
class World:
    """A plant, its friction law and its extra effects: the physics of one generated test."""

    plant: Plant = FMM_PLANT
    friction: FrictionLaw = Coulomb(PAPER_MU)
    effects: tuple[Effect, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, 'effects', tuple(self.effects))
        for effect in self.effects:
            if not isinstance(effect, Effect):
                raise TypeError(f'{effect!r} is not a world effect')

    def _of_type(self, kind: type) -> list:
        return [effect for effect in self.effects if isinstance(effect, kind)]

    @property
    def mechanics(self) -> Plant:
        """The plant with the mechanical effects (damping, cubic stiffness) added."""
        return replace(
            self.plant,
            damping_n_s_per_m=self.plant.damping_n_s_per_m
            + sum(e.damping_n_s_per_m for e in self._of_type(ViscousDamping)),
            cubic_stiffness_n_per_m3=self.plant.cubic_stiffness_n_per_m3
            + sum(e.cubic_stiffness_n_per_m3 for e in self._of_type(CubicStiffness)),
        )

    @property
    def modes(self) -> tuple[SecondMode, ...]:
        """Structural modes the vibrometer sees besides the rig's motion."""
        return tuple(self._of_type(SecondMode))

    @property
    def vibrometer_lag_s(self) -> float:
        """Total pure delay of the velocity signal [s]."""
        return sum(e.delay_s for e in self._of_type(VibrometerLag))

    @property
    def velocity_offset_m_s(self) -> float:
        """Total constant added to the vibrometer output [m/s]."""
        return sum(e.offset_m_s for e in self._of_type(VelocityOffset))

    def static_band_m(self, position_m: float = 0.0) -> float:
        """Half-width [m] of the rest band k x <= mu_s N (the smaller of the two directions)."""
        mechanics = self.mechanics
        mu = min(self.friction.static_mu(d, position_m, 0.0) for d in (1, -1))
        return mu * mechanics.normal_force_n / mechanics.stiffness_n_per_m

    def with_friction(self, friction: FrictionLaw) -> 'World':
        """The same world with another friction law (a hit-to-hit drift of mu)."""
        return replace(self, friction=friction)
