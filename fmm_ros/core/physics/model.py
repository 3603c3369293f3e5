"""The FMM as a Coulomb-friction oscillator (Kossack, Ziegert, Schmitz 2019, Eqs. 1-3), run in time.

    m x'' + c x' + k x + F_f sgn(x') = f(t),   F_f = mu N,

with the stick rule: where the velocity reaches zero the mass stays put while the net applied
force |f - k x| does not exceed the static friction force, and breaks away once it does. Extra
model terms (`fmm_ros.core.physics.terms`) compose with it.

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
"""

import functools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from fmm_ros.constants import PAPER_MU
from fmm_ros.core._checks import (
    finite_samples,
    one_dimensional_samples,
    require_finite,
    require_non_negative,
    require_positive,
)
from fmm_ros.core.physics import _kernels as kernels
from fmm_ros.core.physics.rig import FMM_RIG, INTEGRATORS, Rig
from fmm_ros.core.physics.terms import ModelSpec, ModelTerm, SecondMode, model_spec
from fmm_ros.errors import BadInputError

MIN_SAMPLES_PER_PERIOD = 20
"""Sampling must resolve the rig's natural period this finely (event location, FRFs)."""


# RK4 segments are chosen so that (fastest rate) x (segment) stays below this.
_RK4_RATE_STEP = 0.02


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


def _stribeck_steepest(delta: float) -> float:
    """The steepest slope of exp(-r^delta) in r = v / vs [-] that the RK4 segments resolve.

    0.858 for the Gaussian (delta = 2, as the kernels always had it); for delta > 1 the slope
    delta r^(delta-1) exp(-r^delta) peaks where r^delta = (delta - 1) / delta; for delta <= 1
    it grows without bound towards rest, where the segments near rest
    (`STRIBECK_ZONE_RATIO`) resolve it, and its value at r = 0.01 is taken.
    """
    if delta == 2.0:
        return 0.858
    peak = ((delta - 1.0) / delta) ** (1.0 / delta) if delta > 1.0 else 0.0
    r = max(peak, 0.01)
    return delta * r ** (delta - 1.0) * math.exp(-(r**delta))


def _kernel_params(rig: Rig, spec: ModelSpec, step_s: float, integrator: str) -> np.ndarray:
    p = np.zeros(kernels.PARAM_SIZE)
    p[kernels.MASS] = rig.mass_kg
    p[kernels.DAMPING] = spec.damping_n_s_per_m
    p[kernels.STIFFNESS] = rig.stiffness_n_per_m
    p[kernels.CUBIC] = spec.cubic_stiffness_n_per_m3
    p[kernels.FRICTION_POS] = spec.mu_positive * rig.normal_force_n
    p[kernels.FRICTION_NEG] = spec.mu_negative * rig.normal_force_n
    p[kernels.STATIC_EXCESS] = spec.mu_static_excess * rig.normal_force_n
    p[kernels.STRIBECK_V] = spec.stribeck_velocity_m_s
    delta = spec.stribeck_exponent
    p[kernels.STRIBECK_DELTA] = delta
    p[kernels.STRIBECK_FLAT_RATIO] = 36.0 ** (1.0 / delta)
    p[kernels.STRIBECK_ZONE_RATIO] = 16.0 ** (1.0 / delta)
    p[kernels.STEP] = step_s
    if integrator == 'rk4' or spec.cubic_stiffness_n_per_m3 != 0.0:
        p[kernels.NONLINEAR] = 1.0
    elif spec.nonlinear:  # a Stribeck contact alone: RK4 only nearer rest
        p[kernels.NONLINEAR] = 2.0
    # Fastest rate the RK4 segments must resolve: the mode itself, and the steepest slope of
    # the Stribeck curve, dmu N max|d exp(-(v/vs)^delta)/dv| / m (0.858 dmu N / (vs m) for
    # delta = 2; `_stribeck_steepest`).
    rate = max(
        2.0 * math.pi * rig.natural_frequency_hz,
        _stribeck_steepest(delta)
        * p[kernels.STATIC_EXCESS]
        / (spec.stribeck_velocity_m_s * rig.mass_kg),
    )
    p[kernels.SUBSTEPS] = max(1, math.ceil(rate * step_s / _RK4_RATE_STEP))
    p[kernels.PHI : kernels.GAMMA_DU + 2] = _foh_step(
        rig.mass_kg, spec.damping_n_s_per_m, rig.stiffness_n_per_m, step_s
    )
    return p


@dataclass(frozen=True)
class _Plan:
    """What every stream of one model at one sample rate is built from."""

    sample_rate_hz: float
    params: np.ndarray
    """The kernels' constants (`_kernel_params`), read-only: streams and threads share them."""
    advance: Callable[..., bool]
    """The oscillator kernel of the integrator."""
    mode_step: np.ndarray | None
    """The second mode's exact step (the MODE_PHI slots on), None without a second mode."""
    delay: bool
    delay_whole: int
    delay_fraction: float
    offset: float


def _plan(
    sample_rate_hz: float, rig: Rig, mu: float, effects: tuple[ModelTerm, ...], integrator: str
) -> _Plan:
    """Check a model at a checked sample rate and integrator, and build its `_Plan`.

    Raises ValueError naming a bad input (mu, a term, a rate too coarse for the model).
    """
    spec = model_spec(rig, mu, effects)
    needed_hz = MIN_SAMPLES_PER_PERIOD * rig.natural_frequency_hz
    if sample_rate_hz < needed_hz:
        raise BadInputError(
            f'time step too coarse: sample_rate_hz {sample_rate_hz:g} gives fewer than '
            f'{MIN_SAMPLES_PER_PERIOD} samples per period of the {rig.natural_frequency_hz:.4g}'
            f' Hz natural frequency (need >= {needed_hz:.4g} Hz)'
        )
    sample_rate_hz = float(sample_rate_hz)
    step_s = 1.0 / sample_rate_hz
    params = _kernel_params(rig, spec, step_s, integrator)
    params.flags.writeable = False
    mode_step = None
    if spec.second_mode is not None:
        mode_step = _mode_step(spec.second_mode, sample_rate_hz)
    whole, fraction = _delay_split(spec.delay_s, sample_rate_hz)
    return _Plan(
        sample_rate_hz,
        params,
        kernels.oscillator_euler if integrator == 'euler' else kernels.oscillator_exact,
        mode_step,
        spec.delay_s > 0.0,
        whole,
        fraction,
        spec.velocity_offset_m_s,
    )


def _mode_step(mode: SecondMode, sample_rate_hz: float) -> np.ndarray:
    """The second mode's exact step at a sample rate; BadInputError at or above Nyquist."""
    if mode.frequency_hz >= 0.5 * sample_rate_hz:
        raise BadInputError(
            f'time step too coarse: second_mode.frequency_hz {mode.frequency_hz:g} is at or '
            f'above the Nyquist frequency {0.5 * sample_rate_hz:g} Hz'
        )
    return _foh_step(*mode.constants(), 1.0 / sample_rate_hz)


def _delay_split(delay_s: float, sample_rate_hz: float) -> tuple[int, float]:
    """A delay as (whole samples, fraction of a sample)."""
    delay_samples = delay_s * sample_rate_hz
    if abs(delay_samples - round(delay_samples)) < 1e-9:
        delay_samples = round(delay_samples)  # 3e-4 s at 10 kHz is 3 samples, not 2.999...
    whole = int(math.floor(delay_samples))
    return whole, delay_samples - whole


_NO_DELAY = np.empty(0)
"""The delay line `add_linear_mode` is given for no delay (it holds nothing, so is shared)."""

# A fitter or a campaign builds a stream per record and trial of the same few models. Typed:
# a bool is refused where the equal int is accepted, so the two must not share an entry.
_cached_plan = functools.lru_cache(maxsize=256, typed=True)(_plan)


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
    def end_position_m(self) -> float:
        """Where the rig is left for the next hit [m].

        Its rest, or where it is at the end if still sliding (a chained start,
        `ConditionedImpact.follows_previous`).
        """
        rest = self.rest_position_m
        return float(rest if math.isfinite(rest) else self.displacement_m[-1])

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
            raise BadInputError(f'rig must be a Rig, got {rig!r}')
        require_positive('sample_rate_hz', sample_rate_hz)
        if integrator not in INTEGRATORS:
            raise BadInputError(
                f'unknown integrator {integrator!r}; choose one of {", ".join(INTEGRATORS)}'
            )
        require_finite('x0_m', x0_m)
        require_finite('v0_m_s', v0_m_s)
        effects = (effects,) if isinstance(effects, ModelTerm) else tuple(effects)
        try:
            plan = _cached_plan(sample_rate_hz, rig, mu, effects, integrator)
        except TypeError:  # an unhashable argument: built, and refused, without the cache
            plan = _plan(sample_rate_hz, rig, mu, effects, integrator)
        self.sample_rate_hz = plan.sample_rate_hz
        self.rig = rig
        self.mu = float(mu)
        self.effects = effects
        self.integrator = integrator
        self._params = plan.params
        self._advance = plan.advance
        self._state = np.zeros(kernels.STATE_SIZE)
        self._state[kernels.STATE_X] = x0_m
        self._state[kernels.STATE_V] = v0_m_s
        self._mode = None
        if plan.mode_step is not None:
            self._mode = np.zeros(kernels.MODE_SIZE)
            self._mode[kernels.MODE_PHI :] = plan.mode_step
        self._delay_whole = plan.delay_whole
        self._delay_fraction = plan.delay_fraction
        self._delay_line = np.full(plan.delay_whole + 1, float(v0_m_s)) if plan.delay else None
        self._offset = plan.offset
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
        return self._step_samples(_checked_force(force_n), out)

    def _step_samples(
        self, force: np.ndarray, out: tuple[np.ndarray, np.ndarray] | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """`step` for contiguous float64 samples (`_samples`), checked as the kernel reads them.

        The kernel flags a non-finite or huge sample; only then is the batch checked in full
        (`_checked_force`, whose error names the sample), before the second mode and the delay
        line change. `simulate`'s record is thus read once, not once more to be checked; `step`
        checks first all the same, since a stream must not change on a bad batch.
        """
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
                    raise BadInputError(
                        f'out {name} buffer must be a writable contiguous float64 '
                        f'array of shape ({n},)'
                    )
        displacement, velocity = out
        if n == 0:
            return displacement, velocity
        force_before = self._state[kernels.STATE_FORCE]
        first_call = self.samples_done == 0
        if self._advance(force, displacement, velocity, self._state, self._params):
            _checked_force(force)
        if self._mode is not None:  # the delay and the offset in the mode's pass
            kernels.add_linear_mode(
                force,
                force_before,
                first_call,
                displacement,
                velocity,
                self._mode,
                _NO_DELAY if self._delay_line is None else self._delay_line,
                self._delay_whole,
                self._delay_fraction,
                self._offset,
            )
            return displacement, velocity
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
    fitter's hot loop; its content is undefined if the force is refused). Raises ValueError on
    bad input (non-finite force, bad rig constants, negative mu, a sample rate too coarse for
    the natural frequency).
    """
    force = _samples(force_n)
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
    displacement, velocity = stream._step_samples(force, out)
    return Simulation(
        displacement, velocity, stream.sample_rate_hz, stream.rest_position_m, stream.rest_time_s
    )


def mode_velocity(
    force_n: np.ndarray, sample_rate_hz: float, mode: SecondMode, delay_s: float = 0.0
) -> np.ndarray:
    """What a second mode alone adds to the vibrometer's reading, from rest [m/s].

    The mode is linear and decoupled from the friction oscillator (`terms.SecondMode`), so its
    share of a run is the same whatever the oscillator does: this is `simulate` with the mode
    less `simulate` without it (the same exact steps and delay, to rounding), in one pass over
    the force and no run of the oscillator. Raises ValueError naming a bad input.
    """
    force = _checked_force(force_n)
    require_positive('sample_rate_hz', sample_rate_hz)
    require_non_negative('delay_s', delay_s)
    rate = float(sample_rate_hz)
    state = np.zeros(kernels.MODE_SIZE)
    state[kernels.MODE_PHI :] = _mode_step(mode, rate)
    whole, fraction = _delay_split(delay_s, rate)
    history = np.zeros(whole + 1) if delay_s > 0.0 else _NO_DELAY
    displacement, velocity = np.zeros(force.size), np.zeros(force.size)
    kernels.add_linear_mode(
        force, 0.0, True, displacement, velocity, state, history, whole, fraction, 0.0
    )
    return velocity


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
        raise BadInputError('coulomb_peak_mobility needs a positive normal force')
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


def _samples(force_n: np.ndarray) -> np.ndarray:
    """The force as contiguous one-dimensional float64 samples, not yet checked to be finite."""
    return one_dimensional_samples('force_n', force_n)
