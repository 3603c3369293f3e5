"""The FMM as a Coulomb-friction oscillator (Kossack, Ziegert, Schmitz 2019, Eqs. 1-3), plus terms.

    m x'' + c x' + k x + F_f sgn(x') = f(t),   F_f = mu N,

with the stick rule: where the velocity reaches zero the mass stays put while the net applied
force |f - k x| does not exceed the static friction force, and breaks away once it does.

Inter-sample assumption: the force is linear between samples (first-order hold, FOH). Outputs
are the state on the sample grid: sample i is the state at t = i / sample_rate_hz, sample 0 the
initial condition.

Integrators:
- 'exact' (default): piecewise-linear models (Coulomb + viscous, asymmetric friction, second
  mode) are solved exactly: between velocity reversals the motion is linear with a constant
  friction force, so each sample interval is one matrix step (FOH matrix exponential); a
  reversal or a rest inside the interval is located on the closed-form solution, the stick test
  applied at that instant, and the interval finished from there. With nonlinear terms
  (Stribeck, cubic stiffness) the same event logic runs on RK4 segments instead.
- 'rk4': the event-located RK4 path for any model (a check on 'exact').
- 'euler': the paper's fixed-step method (acceleration each step, Euler updates), kept as the
  reference and baseline; it is first order, so it needs a step far below the period.

Model terms (`MODEL_TERMS`, by name) compose: each adds to the base model, carries its
parameters with SI units and plausible fitting bounds (`Parameter`), and is rebuilt from a
parameter vector with `from_vector`. The second mode and the sensor terms act on what the
vibrometer reads (`Simulation.velocity_m_s`), not on the friction oscillator.
"""

import functools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields
from typing import ClassVar

import numpy as np
import scipy.linalg

from fmm_ros.core import _kernels as kernels
from fmm_ros.core._checks import (
    finite_samples,
    require_finite,
    require_non_negative,
    require_positive,
)
from fmm_ros.core._checks import sample_rate_from_times as sample_rate_from_times  # re-export

STANDARD_GRAVITY_M_S2 = 9.81
PAPER_MU = 0.113
"""Best-fit Coulomb friction coefficient of the paper's PTFE pin on lubricated steel."""
FMM_NORMAL_LOAD_KG = 0.680
"""Dead-weight mass on the pin's shaft that sets the FMM normal force."""
MIN_SAMPLES_PER_PERIOD = 20
"""Sampling must resolve the rig's natural period this finely (event location, FRFs)."""
INTEGRATORS = ('exact', 'rk4', 'euler')

# RK4 segments are chosen so that (fastest rate) x (segment) stays below this.
_RK4_RATE_STEP = 0.02


@dataclass(frozen=True)
class Rig:
    """Linear constants of the friction oscillator; defaults are the paper's FMM (Sec. 4)."""

    mass_kg: float = 10.391
    stiffness_n_per_m: float = 1982.0
    damping_n_s_per_m: float = 0.275
    normal_force_n: float = FMM_NORMAL_LOAD_KG * STANDARD_GRAVITY_M_S2

    def __post_init__(self) -> None:
        require_positive('mass_kg', self.mass_kg)
        require_positive('stiffness_n_per_m', self.stiffness_n_per_m)
        require_non_negative('damping_n_s_per_m', self.damping_n_s_per_m)
        require_non_negative('normal_force_n', self.normal_force_n)

    @property
    def natural_frequency_hz(self) -> float:
        """Undamped natural frequency f_n = sqrt(k/m) / 2 pi [Hz]."""
        return math.sqrt(self.stiffness_n_per_m / self.mass_kg) / (2.0 * math.pi)

    @property
    def damping_ratio(self) -> float:
        """Viscous damping ratio zeta = c / (2 sqrt(k m))."""
        return self.damping_n_s_per_m / (2.0 * math.sqrt(self.stiffness_n_per_m * self.mass_kg))

    def friction_limit_m(self, mu: float) -> float:
        """x_lim = mu N / k: the rest band half-width of the Coulomb oscillator [m]."""
        return mu * self.normal_force_n / self.stiffness_n_per_m


FMM_RIG = Rig()


# --- model terms ---------------------------------------------------------------------------


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
class _ModelSpec:
    """Flat sum of the base model and its terms: what the kernels are built from."""

    damping_n_s_per_m: float
    mu_positive: float
    mu_negative: float
    mu_static_excess: float = 0.0
    stribeck_velocity_m_s: float = 1.0
    cubic_stiffness_n_per_m3: float = 0.0
    second_mode: 'SecondMode | None' = None
    velocity_offset_m_s: float = 0.0
    delay_s: float = 0.0

    @property
    def nonlinear(self) -> bool:
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

    def _apply(self, spec: _ModelSpec) -> None:
        raise NotImplementedError

    @classmethod
    def from_vector(cls, values: Sequence[float]) -> 'ModelTerm':
        """The term with its parameters in `parameters` order (what a fitter varies)."""
        values = [float(v) for v in values]
        if len(values) != len(cls.parameters):
            raise ValueError(
                f'{cls.name} takes {len(cls.parameters)} parameter(s) '
                f'({", ".join(p.name for p in cls.parameters)}), got {len(values)}'
            )
        return cls(**{p.name: v for p, v in zip(cls.parameters, values, strict=True)})

    def to_vector(self) -> np.ndarray:
        """The parameter values in `parameters` order."""
        return np.array([getattr(self, p.name) for p in self.parameters])

    @classmethod
    def bounds(cls) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) plausible bounds in `parameters` order, as scipy.optimize wants."""
        return (
            np.array([p.lower for p in cls.parameters]),
            np.array([p.upper for p in cls.parameters]),
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

    def _apply(self, spec: _ModelSpec) -> None:
        spec.damping_n_s_per_m += self.damping_n_s_per_m


@_term('stribeck')
class Stribeck(ModelTerm):
    """Static friction above kinetic, decaying with speed: mu(v) = mu + dmu exp(-(v/vs)^2)."""

    mu_static_excess: float = _parameter(
        '1', 0.0, 0.1, 0.02, 'static minus kinetic friction coefficient dmu', 'non-negative'
    )
    stribeck_velocity_m_s: float = _parameter(
        'm/s', 1e-4, 0.05, 2e-3, 'speed vs over which the excess decays', 'positive'
    )

    def _apply(self, spec: _ModelSpec) -> None:
        spec.mu_static_excess += self.mu_static_excess
        spec.stribeck_velocity_m_s = self.stribeck_velocity_m_s


@_term('asymmetric_friction')
class AsymmetricFriction(ModelTerm):
    """Friction differing with sliding direction: mu+ = mu + d/2, mu- = mu - d/2 (mean mu)."""

    mu_difference: float = _parameter(
        '1', -0.05, 0.05, 0.01, 'friction coefficient in +x minus that in -x'
    )

    def _apply(self, spec: _ModelSpec) -> None:
        spec.mu_positive += 0.5 * self.mu_difference
        spec.mu_negative -= 0.5 * self.mu_difference
        if min(spec.mu_positive, spec.mu_negative) < 0.0:
            raise ValueError(
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

    def _apply(self, spec: _ModelSpec) -> None:
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

    def _apply(self, spec: _ModelSpec) -> None:
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

    def _apply(self, spec: _ModelSpec) -> None:
        spec.velocity_offset_m_s += self.offset_m_s


@_term('sensor_delay')
class SensorDelay(ModelTerm):
    """The velocity channel lags the force channel (decoder and anti-alias filter delay).

    Applied as a fractional shift of the vibrometer output, linear between samples; before
    the first sample the output holds the initial velocity.
    """

    delay_s: float = _parameter('s', 0.0, 5e-3, 5e-4, 'velocity lag behind force', 'non-negative')

    def _apply(self, spec: _ModelSpec) -> None:
        spec.delay_s += self.delay_s


def model_term(name: str, values: Sequence[float] | None = None, **parameters: float) -> ModelTerm:
    """Build a term by name: from a parameter vector, from keywords, or with its defaults."""
    if name not in MODEL_TERMS:
        raise ValueError(f'unknown model term {name!r}; known: {", ".join(MODEL_TERMS)}')
    cls = MODEL_TERMS[name]
    if values is not None:
        if parameters:
            raise ValueError(f'{name}: give a parameter vector or keywords, not both')
        return cls.from_vector(values)
    known = {p.name for p in cls.parameters}
    unknown = sorted(set(parameters) - known)
    if unknown:
        raise ValueError(
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
            raise ValueError(f'model term {text!r}: {assignment!r} is not param=number')
    return model_term(name.strip(), **parameters)


def _model_spec(rig: Rig, mu: float, effects: Iterable[ModelTerm]) -> _ModelSpec:
    require_non_negative('mu', mu)
    spec = _ModelSpec(damping_n_s_per_m=rig.damping_n_s_per_m, mu_positive=mu, mu_negative=mu)
    seen = set()
    for effect in effects:
        if not isinstance(effect, ModelTerm):
            raise ValueError(
                f'effects must be model terms ({", ".join(MODEL_TERMS)}), got {effect!r}'
            )
        if effect.name in seen:
            raise ValueError(f'model term {effect.name} given twice')
        seen.add(effect.name)
        effect._apply(spec)
    return spec


# --- discretisation --------------------------------------------------------------------------


@functools.lru_cache(maxsize=512)
def _foh_step(mass_kg: float, damping: float, stiffness: float, step_s: float) -> np.ndarray:
    """Exact FOH step of m x'' + c x' + k x = u (Van Loan): Phi (4), Gamma_u0 (2), Gamma_du (2).

    The augmented system d/dt [z, u, du] = [[A, B, 0], [0, 0, 1/h], [0, 0, 0]] [z, u, du] is
    exact for an input linear over the step, so z(h) = Phi z0 + Gamma_u0 u0 + Gamma_du (u1-u0).
    """
    augmented = np.zeros((4, 4))
    augmented[0, 1] = step_s
    augmented[1, 0] = -stiffness / mass_kg * step_s
    augmented[1, 1] = -damping / mass_kg * step_s
    augmented[1, 2] = step_s / mass_kg
    augmented[2, 3] = 1.0
    exponential = scipy.linalg.expm(augmented)
    step = np.concatenate((exponential[:2, :2].ravel(), exponential[:2, 2], exponential[:2, 3]))
    step.flags.writeable = False
    return step


def _kernel_params(rig: Rig, spec: _ModelSpec, step_s: float, integrator: str) -> np.ndarray:
    p = np.zeros(kernels.PARAM_SIZE)
    p[kernels.MASS] = rig.mass_kg
    p[kernels.DAMPING] = spec.damping_n_s_per_m
    p[kernels.STIFFNESS] = rig.stiffness_n_per_m
    p[kernels.CUBIC] = spec.cubic_stiffness_n_per_m3
    p[kernels.FRICTION_POS] = spec.mu_positive * rig.normal_force_n
    p[kernels.FRICTION_NEG] = spec.mu_negative * rig.normal_force_n
    p[kernels.STATIC_EXCESS] = spec.mu_static_excess * rig.normal_force_n
    p[kernels.STRIBECK_V] = spec.stribeck_velocity_m_s
    p[kernels.STEP] = step_s
    p[kernels.NONLINEAR] = float(spec.nonlinear or integrator == 'rk4')
    # Fastest rate the RK4 segments must resolve: the mode itself, and the steepest slope of
    # the Stribeck curve, dmu N max|d exp(-(v/vs)^2)/dv| / m = 0.858 dmu N / (vs m).
    rate = max(
        2.0 * math.pi * rig.natural_frequency_hz,
        0.858 * p[kernels.STATIC_EXCESS] / (spec.stribeck_velocity_m_s * rig.mass_kg),
    )
    p[kernels.SUBSTEPS] = max(1, math.ceil(rate * step_s / _RK4_RATE_STEP))
    p[kernels.PHI : kernels.PARAM_SIZE] = _foh_step(
        rig.mass_kg, spec.damping_n_s_per_m, rig.stiffness_n_per_m, step_s
    )
    return p


# --- running it --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Simulation:
    """A simulated record on the sample grid (sample 0 is the initial condition)."""

    displacement_m: np.ndarray
    """Displacement of the measured point: friction oscillator plus any second mode [m]."""
    velocity_m_s: np.ndarray
    """What the vibrometer reads: oscillator + second mode, with offset and delay [m/s]."""
    sample_rate_hz: float
    rest_position_m: float
    """Where the friction oscillator came to rest for good; NaN if still sliding at the end."""
    rest_time_s: float
    """When that rest began (located inside the sample interval); NaN if still sliding."""

    @property
    def time_s(self) -> np.ndarray:
        """Sample times from the first sample [s]."""
        return np.arange(self.displacement_m.size) / self.sample_rate_hz

    @property
    def at_rest(self) -> bool:
        """Whether the friction oscillator is at rest at the end of the record."""
        return not math.isnan(self.rest_time_s)


class OscillatorStream:
    """The model as a stream: feed force batches, get displacement and velocity batches.

    The state (oscillator, second mode, delay line, last force sample) carries over between
    calls, and every sample interval is computed the same way whatever the batch boundaries,
    so any split of a record gives the same numbers, to the bit, as one `simulate` call.
    """

    def __init__(
        self,
        sample_rate_hz: float,
        *,
        rig: Rig = FMM_RIG,
        mu: float = PAPER_MU,
        effects: Iterable[ModelTerm] = (),
        x0_m: float = 0.0,
        v0_m_s: float = 0.0,
        integrator: str = 'exact',
    ) -> None:
        if not isinstance(rig, Rig):
            raise ValueError(f'rig must be a Rig, got {rig!r}')
        require_positive('sample_rate_hz', sample_rate_hz)
        if integrator not in INTEGRATORS:
            raise ValueError(
                f'unknown integrator {integrator!r}; choose one of {", ".join(INTEGRATORS)}'
            )
        require_finite('x0_m', x0_m)
        require_finite('v0_m_s', v0_m_s)
        effects = (effects,) if isinstance(effects, ModelTerm) else tuple(effects)
        spec = _model_spec(rig, mu, effects)
        needed_hz = MIN_SAMPLES_PER_PERIOD * rig.natural_frequency_hz
        if sample_rate_hz < needed_hz:
            raise ValueError(
                f'time step too coarse: sample_rate_hz {sample_rate_hz:g} gives fewer than '
                f'{MIN_SAMPLES_PER_PERIOD} samples per period of the {rig.natural_frequency_hz:.4g}'
                f' Hz natural frequency (need >= {needed_hz:.4g} Hz)'
            )
        self.sample_rate_hz = float(sample_rate_hz)
        self.rig = rig
        self.mu = float(mu)
        self.effects = effects
        self.integrator = integrator
        step_s = 1.0 / self.sample_rate_hz
        self._params = _kernel_params(rig, spec, step_s, integrator)
        self._advance = (
            kernels.oscillator_euler if integrator == 'euler' else kernels.oscillator_exact
        )
        self._state = np.zeros(kernels.STATE_SIZE)
        self._state[kernels.STATE_X] = x0_m
        self._state[kernels.STATE_V] = v0_m_s
        self._mode = None
        if spec.second_mode is not None:
            if spec.second_mode.frequency_hz >= 0.5 * self.sample_rate_hz:
                raise ValueError(
                    f'time step too coarse: second_mode.frequency_hz '
                    f'{spec.second_mode.frequency_hz:g} is at or above the Nyquist frequency '
                    f'{0.5 * self.sample_rate_hz:g} Hz'
                )
            self._mode = np.zeros(kernels.MODE_SIZE)
            self._mode[kernels.MODE_PHI :] = _foh_step(*spec.second_mode.constants(), step_s)
        delay_samples = spec.delay_s * self.sample_rate_hz
        if abs(delay_samples - round(delay_samples)) < 1e-9:
            delay_samples = round(delay_samples)  # 3e-4 s at 10 kHz is 3 samples, not 2.999...
        self._delay_whole = int(math.floor(delay_samples))
        self._delay_fraction = delay_samples - self._delay_whole
        self._delay_line = (
            np.full(self._delay_whole + 1, float(v0_m_s)) if spec.delay_s > 0.0 else None
        )
        self._offset = spec.velocity_offset_m_s
        self._buffers = (np.empty(0), np.empty(0))

    @property
    def samples_done(self) -> int:
        """Samples produced so far."""
        return int(self._state[kernels.STATE_INDEX])

    @property
    def rest_time_s(self) -> float:
        """When the current rest of the oscillator began [s]; NaN while it slides."""
        return float(self._state[kernels.STATE_REST_TIME])

    @property
    def rest_position_m(self) -> float:
        """The oscillator's position while at rest [m]; NaN while it slides."""
        if self._state[kernels.STATE_MODE] != 0.0 or self.samples_done == 0:
            return math.nan
        return float(self._state[kernels.STATE_X])

    def step(
        self, force_n: np.ndarray, out: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Advance over a batch of force samples [N]; return (displacement_m, velocity_m_s).

        Without `out` the returned arrays are the stream's own buffers, reused (and
        overwritten) by the next call: copy them to keep them. A bad batch raises ValueError
        before the state changes.
        """
        force = _checked_force(force_n)
        n = force.size
        if out is None:
            if self._buffers[0].size < n:
                self._buffers = tuple(_output_block(n))
            out = (self._buffers[0][:n], self._buffers[1][:n])
        else:
            for name, array in zip(('displacement', 'velocity'), out, strict=True):
                if (
                    not isinstance(array, np.ndarray)
                    or array.shape != (n,)
                    or array.dtype != np.float64
                    or not array.flags.c_contiguous
                    or not array.flags.writeable
                ):
                    raise ValueError(
                        f'out {name} buffer must be a writable contiguous float64 '
                        f'array of shape ({n},)'
                    )
        displacement, velocity = out
        if n == 0:
            return displacement, velocity
        force_before = self._state[kernels.STATE_FORCE]
        first_call = self.samples_done == 0
        self._advance(force, displacement, velocity, self._state, self._params)
        if self._mode is not None:
            kernels.add_linear_mode(
                force, force_before, first_call, displacement, velocity, self._mode
            )
        if self._delay_line is not None:
            kernels.delay_in_place(
                velocity, self._delay_line, self._delay_whole, self._delay_fraction
            )
        if self._offset != 0.0:
            velocity += self._offset
        return displacement, velocity


def simulate(
    force_n: np.ndarray,
    sample_rate_hz: float,
    *,
    rig: Rig = FMM_RIG,
    mu: float = PAPER_MU,
    effects: Iterable[ModelTerm] = (),
    x0_m: float = 0.0,
    v0_m_s: float = 0.0,
    integrator: str = 'exact',
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> Simulation:
    """Response of the model to a sampled force record [N] (linear between samples).

    `effects` are model terms (`model_term(name, ...)`; one term alone is accepted too).
    `out` may pass two float64 arrays of the record's length to fill (no allocation: the
    fitter's hot loop). Raises ValueError on bad input (non-finite force, bad rig constants,
    negative mu, a sample rate too coarse for the natural frequency).
    """
    force = _checked_force(force_n)
    stream = OscillatorStream(
        sample_rate_hz,
        rig=rig,
        mu=mu,
        effects=effects,
        x0_m=x0_m,
        v0_m_s=v0_m_s,
        integrator=integrator,
    )
    if out is None:
        out = tuple(_output_block(force.size))
    displacement, velocity = stream.step(force, out=out)
    return Simulation(
        displacement, velocity, stream.sample_rate_hz, stream.rest_position_m, stream.rest_time_s
    )


def free_vibration(
    x0_m: float,
    duration_s: float,
    sample_rate_hz: float,
    *,
    v0_m_s: float = 0.0,
    rig: Rig = FMM_RIG,
    mu: float = PAPER_MU,
    effects: Iterable[ModelTerm] = (),
    integrator: str = 'exact',
) -> Simulation:
    """Release from x0_m (and v0_m_s) with no applied force (the paper's Figs. 2-4)."""
    return simulate(
        np.zeros(record_length(duration_s, sample_rate_hz)),
        sample_rate_hz,
        rig=rig,
        mu=mu,
        effects=effects,
        x0_m=x0_m,
        v0_m_s=v0_m_s,
        integrator=integrator,
    )


def coulomb_peak_mobility(impulse_n_s: float, *, rig: Rig = FMM_RIG, mu: float = PAPER_MU) -> float:
    """|Y(w_n)| ~ pi I / (8 m mu N): mobility at f_n after an impulse I, undamped Coulomb case.

    Derivation (c = 0, x_lim = mu N / k, w = w_n, pulse short against the period so that
    F(w) ~ I). The impulse starts the mass from x = 0 at v0 = I / m. Between reversals the
    motion is harmonic at w about -s x_lim (s the sliding direction), so the velocity is a
    train of sine arcs at w: first a quarter arc of amplitude w A1, A1 ~ v0 / w (from mid
    stroke to the first turn), then half arcs whose displacement amplitudes fall by 2 x_lim
    each, A1 - 2 x_lim, A1 - 4 x_lim, ... until one ends inside the rest band. The arcs change
    sign every half period, as e^{-i w t} does, so every arc adds in phase to
    V(w) = integral of v e^{-i w t} dt: a half arc of amplitude w A adds (pi / 2) A, the
    quarter arc half of that. The sum is (pi / 2) times the triangle area A1^2 / (4 x_lim),
    up to O(x_lim) (the quarter arc's missing half cancels the staircase's end correction):
    |V(w)| = pi A1^2 / (8 x_lim) = pi I^2 / (8 m^2 w^2 x_lim), and with k = m w^2,
    |Y| = |V| / I = pi I / (8 m mu N). With A1 / (2 x_lim) half cycles, about ten or more,
    the error is well under 1 %; damping c lowers |Y| further (about 2-3 % on the FMM).
    """
    require_positive('impulse_n_s', impulse_n_s)
    require_positive('mu', mu)
    if rig.normal_force_n <= 0.0:
        raise ValueError('coulomb_peak_mobility needs a positive normal force')
    return math.pi * impulse_n_s / (8.0 * rig.mass_kg * mu * rig.normal_force_n)


def record_length(duration_s: float, sample_rate_hz: float) -> int:
    """Samples in a record of duration_s at sample_rate_hz (33 s at 10 kHz: 330,000)."""
    require_positive('duration_s', duration_s)
    require_positive('sample_rate_hz', sample_rate_hz)
    return max(1, round(duration_s * sample_rate_hz))


def _output_block(n: int) -> np.ndarray:
    """Displacement and velocity rows in one allocation.

    A 33 s record's two 2.6 MB arrays cost ~2 ms of page faults when allocated apart; as one
    block above numpy's 4 MiB huge-page threshold they fault in ~0.1 ms (with the kernel's
    transparent huge pages in madvise or always mode).
    """
    return np.empty((2, n))


def _checked_force(force_n: np.ndarray) -> np.ndarray:
    return finite_samples('force_n', force_n, overflow='integrate')
