"""Model terms: what can be added to Eq. 3, each with its parameters, units and fitting bounds.

Terms (`MODEL_TERMS`, by name) compose: each adds to the base model, carries its parameters with
SI units and plausible fitting bounds (`Parameter`), and is rebuilt from a parameter vector with
`from_vector`. The second mode and the sensor terms act on what the vibrometer reads
(`Simulation.velocity_m_s`), not on the friction oscillator. Each term's `_apply` adds itself to
the flat `ModelSpec` the compiled kernels are built from; a term given twice is an error.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, ClassVar

from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.settings import (
    require_finite,
    require_non_negative,
    require_positive,
)
from fmm_ros.errors import BadInputError

if TYPE_CHECKING:
    import numpy as np


STRIBECK_EXPONENT_RANGE = (0.5, 2.0)
"""The Stribeck shape delta real contacts show (Armstrong-Helouvry 1991: 0.5 to 2)."""


@dataclass(frozen=True)
class Parameter:
    """One fitted quantity of a model term: SI unit, plausible bounds and a default."""

    name: str
    unit: str
    lower: float
    upper: float
    default: float
    description: str
    domain: str = 'real'
    """Physical limit, enforced on construction: 'real', 'non-negative' or 'positive'."""


_DOMAIN_CHECKS = {
    'real': require_finite,
    'non-negative': require_non_negative,
    'positive': require_positive,
}


def _parameter(
    unit: str, lower: float, upper: float, default: float, description: str, domain: str = 'real'
):
    """Declare a term's dataclass field together with its `Parameter` description."""
    return field(default=default, metadata={'parameter': (unit, lower, upper, description, domain)})


@dataclass
class ModelSpec:
    """Flat sum of the base model and its terms: what the kernels are built from."""

    damping_n_s_per_m: float
    mu_positive: float
    mu_negative: float
    mu_static_excess: float = 0.0
    stribeck_velocity_m_s: float = 1.0
    stribeck_exponent: float = 2.0
    cubic_stiffness_n_per_m3: float = 0.0
    second_mode: SecondMode | None = None
    velocity_offset_m_s: float = 0.0
    delay_s: float = 0.0

    @property
    def nonlinear(self) -> bool:
        """Whether a term makes the model nonlinear (the RK4 path instead of the exact one)."""
        return self.mu_static_excess != 0.0 or self.cubic_stiffness_n_per_m3 != 0.0


class ModelTerm:
    """Base of the composable model terms: a frozen dataclass of SI parameters.

    Subclasses are declared with `@_term(name)`, which fills `name` and `parameters`.
    """

    name: ClassVar[str]
    parameters: ClassVar[tuple[Parameter, ...]]

    def __post_init__(self) -> None:
        # Only the physical domain is enforced: the bounds are plausible ranges for a fitter.
        for parameter in self.parameters:
            value = getattr(self, parameter.name)
            _DOMAIN_CHECKS[parameter.domain](f'{self.name}.{parameter.name}', value)
            object.__setattr__(self, parameter.name, float(value))

    def _apply(self, spec: ModelSpec) -> None:
        raise NotImplementedError

    @classmethod
    def from_vector(cls, values: Sequence[float]) -> ModelTerm:
        """The term with its parameters in `parameters` order (what a fitter varies)."""
        values = [float(v) for v in values]
        if len(values) != len(cls.parameters):
            raise BadInputError(
                f'{cls.name} takes {len(cls.parameters)} parameter(s) '
                f'({", ".join(p.name for p in cls.parameters)}), got {len(values)}'
            )
        return cls(**{p.name: v for p, v in zip(cls.parameters, values, strict=True)})

    def to_vector(self) -> np.ndarray:
        """The parameter values in `parameters` order."""
        import numpy as np  # here: the terms are declared for `fmm --help` without numpy

        return np.array([getattr(self, p.name) for p in self.parameters])

    @classmethod
    def bounds(
        cls, ranges: Mapping[str, tuple[float, float]] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) bounds in `parameters` order, as scipy.optimize wants.

        The declared plausible bounds, or, for a parameter `ranges` holds by its full name
        (`stribeck.mu_static_excess`), that range instead (`physical_ranges`: from the
        physics and the data of a session).
        """
        import numpy as np

        given = ranges or {}
        pairs = [given.get(f'{cls.name}.{p.name}', (p.lower, p.upper)) for p in cls.parameters]
        return (
            np.array([float(low) for low, _ in pairs]),
            np.array([float(high) for _, high in pairs]),
        )


MODEL_TERMS: dict[str, type[ModelTerm]] = {}
"""Every model term class by its name, in the order they are declared."""


def _term(name: str):
    """Class decorator: frozen dataclass, `name`, `parameters` from the fields, registered."""

    def declare(cls):
        cls = dataclass(frozen=True)(cls)
        cls.name = name
        cls.parameters = tuple(
            Parameter(f.name, unit, lower, upper, f.default, description, domain)
            for f in fields(cls)
            for unit, lower, upper, description, domain in [f.metadata['parameter']]
        )
        MODEL_TERMS[name] = cls
        return cls

    return declare


@_term('viscous_damping')
class ViscousDamping(ModelTerm):
    """Viscous damping added to the rig's (air drag, lubricant film shear)."""

    damping_n_s_per_m: float = _parameter(
        'N*s/m', 0.0, 5.0, 0.5, 'added viscous damping c', 'non-negative'
    )

    def _apply(self, spec: ModelSpec) -> None:
        spec.damping_n_s_per_m += self.damping_n_s_per_m


@_term('stribeck')
class Stribeck(ModelTerm):
    """Static friction above kinetic, decaying with speed: mu + dmu exp(-(|v|/vs)^delta).

    delta is the shape (Armstrong-Helouvry's range 0.5-2; 2, the Gaussian, by default).
    """

    mu_static_excess: float = _parameter(
        '1', 0.0, 0.1, 0.02, 'static minus kinetic friction coefficient dmu', 'non-negative'
    )
    stribeck_velocity_m_s: float = _parameter(
        'm/s', 1e-4, 0.05, 2e-3, 'speed vs over which the excess decays', 'positive'
    )
    stribeck_exponent: float = _parameter(
        '1',
        STRIBECK_EXPONENT_RANGE[0],
        STRIBECK_EXPONENT_RANGE[1],
        2.0,
        'shape delta of the decay exp(-(|v|/vs)^delta)',
        'positive',
    )

    def _apply(self, spec: ModelSpec) -> None:
        spec.mu_static_excess += self.mu_static_excess
        spec.stribeck_velocity_m_s = self.stribeck_velocity_m_s
        spec.stribeck_exponent = self.stribeck_exponent


@_term('asymmetric_friction')
class AsymmetricFriction(ModelTerm):
    """Friction differing with sliding direction: mu+ = mu + d/2, mu- = mu - d/2 (mean mu)."""

    mu_difference: float = _parameter(
        '1', -0.05, 0.05, 0.01, 'friction coefficient in +x minus that in -x'
    )

    def _apply(self, spec: ModelSpec) -> None:
        spec.mu_positive += 0.5 * self.mu_difference
        spec.mu_negative -= 0.5 * self.mu_difference
        if min(spec.mu_positive, spec.mu_negative) < 0.0:
            raise BadInputError(
                f'asymmetric_friction.mu_difference {self.mu_difference} makes a '
                f'friction coefficient negative (mu+ {spec.mu_positive:.4g}, '
                f'mu- {spec.mu_negative:.4g})'
            )


@_term('cubic_stiffness')
class CubicStiffness(ModelTerm):
    """Flexure stiffening (k3 > 0) or softening (k3 < 0): spring force k x + k3 x^3."""

    cubic_stiffness_n_per_m3: float = _parameter(
        'N/m^3', -1e7, 1e7, 2e6, 'cubic spring coefficient k3'
    )

    def _apply(self, spec: ModelSpec) -> None:
        spec.cubic_stiffness_n_per_m3 += self.cubic_stiffness_n_per_m3


@_term('second_mode')
class SecondMode(ModelTerm):
    """A second linear mode of the structure, driven by the hammer and seen by the vibrometer.

    Decoupled from the friction contact: m2 x2'' + c2 x2' + k2 x2 = f, with k2 = m2 w2^2 and
    c2 = 2 zeta2 m2 w2; its displacement and velocity add to the measured point's.
    """

    frequency_hz: float = _parameter('Hz', 5.0, 2000.0, 45.0, 'natural frequency f2', 'positive')
    damping_ratio: float = _parameter(
        '1', 1e-4, 0.1, 0.01, 'viscous damping ratio zeta2', 'non-negative'
    )
    modal_mass_kg: float = _parameter(
        'kg', 1.0, 1e4, 100.0, 'modal mass m2 at the hammer point', 'positive'
    )

    def _apply(self, spec: ModelSpec) -> None:
        spec.second_mode = self

    def constants(self) -> tuple[float, float, float]:
        """(mass [kg], damping [N*s/m], stiffness [N/m]) of the mode."""
        omega = 2.0 * math.pi * self.frequency_hz
        return (
            self.modal_mass_kg,
            2.0 * self.damping_ratio * self.modal_mass_kg * omega,
            self.modal_mass_kg * omega * omega,
        )


@_term('velocity_offset')
class VelocityOffset(ModelTerm):
    """A constant offset on the vibrometer output (decoder zero error, drift over a record)."""

    offset_m_s: float = _parameter('m/s', -1e-3, 1e-3, 1e-4, 'added to the measured velocity')

    def _apply(self, spec: ModelSpec) -> None:
        spec.velocity_offset_m_s += self.offset_m_s


@_term('sensor_delay')
class SensorDelay(ModelTerm):
    """The velocity channel lags the force channel (decoder and anti-alias filter delay).

    Applied as a fractional shift of the vibrometer output, linear between samples; before
    the first sample the output holds the initial velocity.
    """

    delay_s: float = _parameter('s', 0.0, 5e-3, 5e-4, 'velocity lag behind force', 'non-negative')

    def _apply(self, spec: ModelSpec) -> None:
        spec.delay_s += self.delay_s


EFFECT_SIZE: dict[str, tuple[str, bool]] = {
    'viscous_damping': ('damping_n_s_per_m', False),
    'stribeck': ('mu_static_excess', False),
    'asymmetric_friction': ('mu_difference', False),
    'cubic_stiffness': ('cubic_stiffness_n_per_m3', False),
    'second_mode': ('modal_mass_kg', True),
    'velocity_offset': ('offset_m_s', False),
    'sensor_delay': ('delay_s', False),
}
"""Per term, (the parameter that sets how large its effect is, whether the effect falls as it
grows): zero size is no effect, and the second mode's response scales as 1 / its mass."""


STATIC_EXCESS_PER_MU = 3.0
"""Stiction may exceed kinetic friction by up to this many times mu (`physical_ranges`): dry
contacts show static/kinetic ratios of 1-4 (a ratio of 1.84 is an excess of 0.84 mu)."""


ASYMMETRY_PER_MU = 1.0
"""mu+ - mu- up to this many times mu either way: mu+ and mu- stay at least mu / 2."""


OFFSET_PER_PEAK_SPEED = 0.1
"""A vibrometer zero error up to this fraction of the session's peak speed either way."""


DELAY_PER_PERIOD = 0.25
"""A velocity channel lag up to this fraction of the rig's natural period: a quarter period
is where a lag turns into a phase no other term could be confused with."""


def physical_ranges(
    mu: float, peak_speed_m_s: float, natural_period_s: float
) -> dict[str, tuple[float, float]]:
    """Fitting ranges of the effect sizes from the physics and a session's data.

    By full parameter name, as `ModelTerm.bounds` and `fit_model`'s term_bounds take them:
    the static friction excess from 0 to STATIC_EXCESS_PER_MU x mu, the asymmetry mu+ - mu-
    within +-ASYMMETRY_PER_MU x mu, the velocity offset within +-OFFSET_PER_PEAK_SPEED x the
    peak speed and the delay from 0 to DELAY_PER_PERIOD x the natural period. Not the draws of
    any test world: what a contact, a vibrometer and a channel can physically do. The other
    parameters keep their declared bounds (a Stribeck speed 0.1-50 mm/s, its shape
    STRIBECK_EXPONENT_RANGE, ...).
    """
    require_positive('mu', mu)
    require_positive('peak_speed_m_s', peak_speed_m_s)
    require_positive('natural_period_s', natural_period_s)
    offset = OFFSET_PER_PEAK_SPEED * peak_speed_m_s
    asymmetry = ASYMMETRY_PER_MU * mu
    return {
        'stribeck.mu_static_excess': (0.0, STATIC_EXCESS_PER_MU * mu),
        'asymmetric_friction.mu_difference': (-asymmetry, asymmetry),
        'velocity_offset.offset_m_s': (-offset, offset),
        'sensor_delay.delay_s': (0.0, DELAY_PER_PERIOD * natural_period_s),
    }


def size_parameter(effect: str) -> Parameter | None:
    """The parameter that sets how large a term's effect is (`EFFECT_SIZE`).

    None for an effect that is no model term (mu_drift).
    """
    if effect not in EFFECT_SIZE:
        return None
    name, _ = EFFECT_SIZE[effect]
    return next(p for p in MODEL_TERMS[effect].parameters if p.name == name)


def model_term(name: str, values: Sequence[float] | None = None, **parameters: float) -> ModelTerm:
    """Build a term by name: from a parameter vector, from keywords, or with its defaults."""
    if name not in MODEL_TERMS:
        raise BadInputError(f'unknown model term {name!r}; known: {", ".join(MODEL_TERMS)}')
    cls = MODEL_TERMS[name]
    if values is not None:
        if parameters:
            raise BadInputError(f'{name}: give a parameter vector or keywords, not both')
        return cls.from_vector(values)
    known = {p.name for p in cls.parameters}
    unknown = sorted(set(parameters) - known)
    if unknown:
        raise BadInputError(
            f'{name} has no parameter {", ".join(unknown)}; '
            f'its parameters: {", ".join(sorted(known))}'
        )
    return cls(**parameters)


def parse_model_term(text: str) -> ModelTerm:
    """A term from its text form `name` or `name:param=value,param=value` (config files, CLI).

    E.g. `stribeck:mu_static_excess=0.02,stribeck_velocity_m_s=0.002`; unnamed parameters
    keep their defaults.
    """
    name, _, assignments = text.strip().partition(':')
    parameters = {}
    for assignment in filter(None, (part.strip() for part in assignments.split(','))):
        key, equals, value = assignment.partition('=')
        try:
            parameters[key.strip()] = float(value)
        except ValueError:
            equals = ''
        if not equals:
            raise BadInputError(f'model term {text!r}: {assignment!r} is not param=number')
    return model_term(name.strip(), **parameters)


def model_spec(rig: Rig, mu: float, effects: Iterable[ModelTerm]) -> ModelSpec:
    """The flat spec the kernels are built from: the rig, mu, and each term applied once."""
    require_non_negative('mu', mu)
    spec = ModelSpec(damping_n_s_per_m=rig.damping_n_s_per_m, mu_positive=mu, mu_negative=mu)
    seen = set()
    for effect in effects:
        if not isinstance(effect, ModelTerm):
            raise BadInputError(
                f'effects must be model terms ({", ".join(MODEL_TERMS)}), got {effect!r}'
            )
        if effect.name in seen:
            raise BadInputError(f'model term {effect.name} given twice')
        seen.add(effect.name)
        effect._apply(spec)
    return spec
