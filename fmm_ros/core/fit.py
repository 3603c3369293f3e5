"""Best-fit friction (and damping, and any model term) from measured force and velocity; rig ID.

The paper's step (Kossack, Ziegert, Schmitz 2019, Sec. 5): drive Eq. 3 with the measured force
and choose mu so the simulated velocity matches the measured one. Here that is an output-error
least-squares fit over one or more impacts, in the time domain (velocity residual, default) or
on the mobility FRF (0 to `band_limit_hz`), of mu alone, mu and the viscous damping c, and the
parameters of any model term (`fmm_ros.core.model.MODEL_TERMS`), with standard errors.

Conditioning of the force (`condition_impact`), because the model integrates every sample it
is given: a 0.2 N noise floor over 33 s would drive the stuck mass into creep and bias mu.
- Baseline: the mean of the force outside the hit, subtracted.
- Gate: the hit is where the force departs from the baseline by more than
  `HIT_THRESHOLD_SIGMA` robust noise deviations (median absolute deviation); each such run
  of samples is widened by a quarter of its length (at least `GATE_MIN_MARGIN_S`) each side to
  take in the pulse's low-level edges, and the force is zeroed everywhere else. A bounce is a
  second run and is kept, as it drives the rig too.
- The velocity is left as measured: an offset or a lag in it is a model term the diagnosis
  must be able to see, not something conditioning may hide.
- No trigger index is used: the hit is found in the force itself, so a pre-trigger segment
  of any length and a trigger that fired some samples (or a fraction of one) after the hit
  began need no parameter; the model starts at rest at the first sample (at x = 0, or where
  `fit_initial_position` finds the previous hit left it). A lag of the velocity channel
  behind the force channel is the `sensor_delay` term, fitted on request.

Uncertainty, two parts added:
- Velocity: the residuals of an output-error fit are not independent (a model error is smooth
  in time, and so are a vibrometer's low-frequency errors), so the white-noise covariance
  s^2 (J^T J)^-1 is optimistic. Used instead is the sandwich (J^T J)^-1 S (J^T J)^-1 with S
  summed over blocks of the score J_i r_i (one natural period in time, a quarter of f_n in
  frequency), valid for residuals correlated within a block, and never below the white one.
- Force: noise inside the gate is part of the input, so no residual shows it; it changes the
  hit's impulse by sigma_F / f_s sqrt(gate samples from the onset), which moves the fit by
  -(J J^T)^-1 J dr/dI per N*s (dr/dI found by scaling the hit). At 0.2 N this part dominates
  the error of mu for one record (about 1e-4 of mu), and it is what makes per-impact mu's
  scatter.
The standard errors were checked against the scatter of fits over noise seeds (test_fit.py).

Failures: bad input (shapes, non-finite samples, bad constants) is a ValueError; a record that
friction cannot explain is a `FitError` (a ValueError too) whose `reason` is one of
`FIT_FAILURES` and whose message says why, so the CLI and the fitter service can report it.

Rig identification (the paper's Sec. 4): `identify_rig` fits m, c, k to impacts with the
contact lifted (mu = 0), driven by the measured force; `fit_free_decay` fits f_n and zeta to
a free decay (no force) by variable projection.
"""

import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.fft
import scipy.stats

from fmm_ros.core._checks import finite_samples, require_positive
from fmm_ros.core._lsq import (
    Blocks,
    Infeasible,
    LsqSolution,
    inner,
    levenberg_marquardt,
    normal_inverse,
)
from fmm_ros.core.frf import band_bins, impulse, mobility, spectra
from fmm_ros.core.model import (
    FMM_RIG,
    INTEGRATORS,
    MODEL_TERMS,
    PAPER_MU,
    ModelTerm,
    Rig,
    Simulation,
    simulate,
)

MU_BOUNDS = (1e-3, 1.0)
"""Default search range of the friction coefficient; a best fit on either end is a failure."""
DAMPING_BOUNDS_N_S_PER_M = (0.0, 50.0)
"""Search range of the viscous damping c when it is fitted [N*s/m]."""
MISFITS = ('time', 'frf')
JACOBIANS = ('blocks', 'dense')
"""How fit_model builds its Jacobian: 'blocks' runs and stores an impact's own parameters
(its start position) on that impact alone; 'dense' runs every column over every impact (the
plain way, kept as the reference the blocks are checked and benchmarked against)."""
DEFAULT_BAND_LIMIT_HZ = 20.0
"""Upper end of the mobility misfit band: f_n and its odd harmonics to the 9th (paper Fig. 24)."""

HIT_THRESHOLD_SIGMA = 10.0
"""A hit departs from the force baseline by more than this many noise deviations (Gaussian
noise reaches ~5 of them once in a 33 s record)."""
GATE_MARGIN_FRACTION = 0.25
GATE_MIN_MARGIN_S = 0.5e-3
"""Each run above the hit threshold is widened by this fraction of its length, and at least
this long, on both sides: the pulse's feet lie below the threshold."""
MOTION_THRESHOLD_SIGMA = 10.0
"""The velocity must exceed this many noise deviations somewhere for a record to show motion."""
MIN_EXPLAINED_FRACTION = 0.5
"""A fit must remove at least this fraction of each record's velocity sum of squares (the
misfit of predicting no motion at all), or the model does not explain the record."""
FIT_FAILURES = (
    'no_hit',
    'no_motion',
    'mu_at_bound',
    'at_bound',
    'unexplained',
    'no_convergence',
    'too_few_cycles',
)
MIN_DECAY_CROSSINGS = 6
"""A free decay must cross zero this often above its noise (three cycles) to be fitted."""

_MAD_TO_STD = 1.482602218505602  # 1 / Phi^-1(3/4): MAD of Gaussian noise -> its deviation
_ROBUST_SUBSAMPLE_MIN = 5000


class FitError(ValueError):
    """A record or set of records the model cannot explain; `reason` is one of FIT_FAILURES."""

    def __init__(self, reason: str, message: str, source: str = '') -> None:
        if reason not in FIT_FAILURES:
            raise ValueError(f'unknown fit failure reason {reason!r}')
        self.reason = reason
        self.source = source
        super().__init__(f'{source}: {message}' if source else message)


# --- conditioning ------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ConditionedImpact:
    """One impact made ready for fitting: the force that drives the model, the velocity to match."""

    force_n: np.ndarray
    """Measured force minus its baseline inside the gate, zero outside [N]."""
    velocity_m_s: np.ndarray
    """Measured velocity, untouched [m/s]."""
    sample_rate_hz: float
    gate: tuple[tuple[int, int], ...]
    """[start, stop) sample ranges where the measured force is kept."""
    onset_index: int
    """First sample of the hit above the threshold (the rig is at rest before it)."""
    baseline_n: float
    force_noise_std_n: float
    """Robust (MAD) deviation of the force about its baseline [N]."""
    velocity_noise_std_m_s: float
    """White-noise level of the velocity channel, from its second differences [m/s]."""
    impulse_n_s: float
    """Trapezoid-rule impulse of the conditioned force [N*s]."""
    peak_force_n: float
    """Largest |conditioned force| [N]."""
    peak_velocity_m_s: float
    """Largest |measured velocity| [m/s]."""
    source: str = ''

    @property
    def hit_end_index(self) -> int:
        """First sample after the last gate: from here on no force acts."""
        return self.gate[-1][1]

    @property
    def impulse_std_n_s(self) -> float:
        """Standard deviation the force noise gives the impulse that moves the rig [N*s].

        sigma_F / f_s times the root of the gated samples from the onset on: the noise in the
        gate's lead-in falls on a mass held by static friction (at 0.2 N it stays far below
        mu N), so it moves nothing.
        """
        samples = sum(stop - start for start, stop in self.gate) - (
            self.onset_index - self.gate[0][0]
        )
        return self.force_noise_std_n / self.sample_rate_hz * math.sqrt(samples)

    @property
    def duration_s(self) -> float:
        """Record length [s]."""
        return self.force_n.size / self.sample_rate_hz


def condition_impact(
    force_n: np.ndarray, velocity_m_s: np.ndarray, sample_rate_hz: float, *, source: str = ''
) -> ConditionedImpact:
    """Baseline-correct and gate a measured force; estimate both channels' noise.

    Raises ValueError for malformed input and FitError ('no_hit', 'no_motion') for a force with
    no hit above its noise or a velocity with no response above its noise.
    """
    force = _checked_channel('force_n', force_n, source)
    velocity = _checked_channel('velocity_m_s', velocity_m_s, source)
    require_positive('sample_rate_hz', sample_rate_hz)
    if force.size != velocity.size:
        raise ValueError(
            f'{_where(source)}force has {force.size} samples but velocity has '
            f'{velocity.size}: the channels must be sample-aligned'
        )
    if force.size < 16:
        raise ValueError(f'{_where(source)}a record needs at least 16 samples, got {force.size}')
    center, noise_n = _robust_center_and_std(force)
    peak = max(float(force.max()) - center, center - float(force.min()))
    if peak <= HIT_THRESHOLD_SIGMA * noise_n or peak == 0.0:
        raise FitError(
            'no_hit',
            f'the force never departs from its baseline {center:.4g} N by '
            f'more than {HIT_THRESHOLD_SIGMA:g} noise deviations ({noise_n:.3g} N; '
            f'largest departure {peak:.3g} N): there is no hit to drive the model',
            source,
        )
    threshold = max(HIT_THRESHOLD_SIGMA * noise_n, 1e-3 * peak)
    hit = (force >= center + threshold) | (force <= center - threshold)
    gate = _gate(hit, sample_rate_hz)
    outside = np.ones(force.size, dtype=bool)
    for start, stop in gate:
        outside[start:stop] = False
    baseline = float(np.mean(force[outside])) if outside.any() else 0.0
    conditioned = np.zeros(force.size)
    for start, stop in gate:
        conditioned[start:stop] = force[start:stop] - baseline
    velocity_noise = velocity_noise_std(velocity)
    peak_velocity = float(np.max(np.abs(velocity)))
    if peak_velocity <= MOTION_THRESHOLD_SIGMA * velocity_noise or peak_velocity == 0.0:
        raise FitError(
            'no_motion',
            f'the velocity never exceeds {MOTION_THRESHOLD_SIGMA:g} '
            f'times its noise ({velocity_noise:.3g} m/s; peak {peak_velocity:.3g} '
            'm/s): the rig did not move',
            source,
        )
    return ConditionedImpact(
        force_n=conditioned,
        velocity_m_s=velocity,
        sample_rate_hz=float(sample_rate_hz),
        gate=gate,
        onset_index=int(np.argmax(hit)),
        baseline_n=baseline,
        force_noise_std_n=noise_n,
        velocity_noise_std_m_s=velocity_noise,
        impulse_n_s=impulse(conditioned, sample_rate_hz),
        peak_force_n=float(np.max(np.abs(conditioned))),
        peak_velocity_m_s=peak_velocity,
        source=source,
    )


def velocity_noise_std(velocity_m_s: np.ndarray) -> float:
    """White-noise deviation of a velocity record [m/s], blind to the motion itself.

    The MAD deviation of the second differences over sqrt(6): the rig's few-Hz motion barely
    changes over two samples at 10 kHz, white noise does, and the median ignores the hit and
    the stops.
    """
    second = np.diff(np.asarray(velocity_m_s, dtype=float), n=2)
    if second.size == 0:
        return 0.0
    return _robust_center_and_std(second)[1] / math.sqrt(6.0)


def _robust_center_and_std(values: np.ndarray) -> tuple[float, float]:
    """Median and MAD-based deviation (of every 8th sample in long records).

    Eight times cheaper, and 40,000 samples pin a noise level to about half a per cent.
    """
    if values.size > 8 * _ROBUST_SUBSAMPLE_MIN:
        values = values[::8]
    center = float(np.median(values))
    return center, _MAD_TO_STD * float(np.median(np.abs(values - center)))


def as_conditioned(impact) -> ConditionedImpact:
    """A ConditionedImpact as is, or any record with force_n, velocity_m_s, sample_rate_hz.

    Records (`fmm_ros.core.records.ImpactRecord`, `excitation.SimulatedImpact`) are conditioned
    with `condition_impact`, their `source` (if any) naming them in errors.
    """
    if isinstance(impact, ConditionedImpact):
        return impact
    try:
        force, velocity, rate = impact.force_n, impact.velocity_m_s, impact.sample_rate_hz
    except AttributeError:
        raise ValueError(
            f'an impact must have force_n, velocity_m_s and sample_rate_hz, got '
            f'{type(impact).__name__}'
        ) from None
    return condition_impact(force, velocity, rate, source=str(getattr(impact, 'source', '')))


def _checked_channel(name: str, values: np.ndarray, source: str) -> np.ndarray:
    try:
        return finite_samples(name, values)
    except ValueError as error:
        raise ValueError(f'{_where(source)}{error}') from None


def _gate(hit: np.ndarray, sample_rate_hz: float) -> tuple[tuple[int, int], ...]:
    """Runs of True, each widened by GATE_MARGIN_FRACTION of its length, overlaps merged."""
    edges = np.flatnonzero(np.diff(np.concatenate(([0], hit.view(np.int8), [0]))))
    minimum = max(1, math.ceil(GATE_MIN_MARGIN_S * sample_rate_hz))
    merged: list[list[int]] = []
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        margin = max(minimum, math.ceil(GATE_MARGIN_FRACTION * (stop - start)))
        start, stop = max(0, int(start) - margin), min(hit.size, int(stop) + margin)
        if merged and start <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], stop)
        else:
            merged.append([start, stop])
    return tuple((start, stop) for start, stop in merged)


def _where(source: str) -> str:
    return f'{source}: ' if source else ''


# --- the output-error problem ---------------------------------------------------------------


@dataclass(frozen=True)
class _Model:
    """What a parameter vector stands for: the model, and each impact's initial position."""

    rig: Rig
    mu: float
    effects: tuple[ModelTerm, ...]
    initial_positions_m: tuple[float, ...] = ()
    """Per impact [m]; empty: every impact starts at x = 0."""

    def initial_position_m(self, index: int) -> float:
        return self.initial_positions_m[index] if self.initial_positions_m else 0.0


ModelBuilder = Callable[[np.ndarray], _Model]
"""theta -> the model a parameter vector stands for."""


class _OutputError:
    """Residuals of the model driven by each impact's conditioned force, stacked over impacts.

    Time misfit: measured minus simulated velocity, every sample. FRF misfit: measured minus
    simulated mobility, (V_meas - V_model) / F, on the bins from DC to band_limit_hz, real and
    imaginary parts interleaved. Each impact is a block of residuals (`_lsq.Blocks`): a call
    runs one simulation for each impact asked for, into one buffer allocated once and shared
    (each run is consumed before the next).
    """

    def __init__(
        self,
        impacts: Sequence[ConditionedImpact],
        build: ModelBuilder,
        misfit: str,
        band_limit_hz: float,
        integrator: str,
        natural_frequency_hz: float,
    ) -> None:
        self.impacts = tuple(impacts)
        self.build = build
        self.misfit = misfit
        self.integrator = integrator
        self.buffer = np.empty((2, max(impact.force_n.size for impact in self.impacts)))
        self.targets: list[np.ndarray] = []
        self.inverse_force: list[np.ndarray] = []
        self.segments: list[slice] = []
        self.block_lengths: list[int] = []
        start = 0
        for impact in self.impacts:
            if misfit == 'time':
                length = impact.force_n.size
                block = round(impact.sample_rate_hz / natural_frequency_hz)
            else:
                n = impact.force_n.size
                bins = band_bins(n, impact.sample_rate_hz, band_limit_hz)
                force_spectrum, velocity_spectrum = spectra(impact.force_n, impact.velocity_m_s)
                target = mobility(force_spectrum[:bins], velocity_spectrum[:bins])
                if np.isnan(target).any():
                    raise ValueError(
                        f'{_where(impact.source)}the force spectrum is zero inside '
                        f'the {band_limit_hz:g} Hz band: no mobility there'
                    )
                self.inverse_force.append(1.0 / force_spectrum[:bins])
                self.targets.append(target)
                length = 2 * bins
                block = 2 * round(0.25 * natural_frequency_hz * n / impact.sample_rate_hz)
            self.segments.append(slice(start, start + length))
            self.block_lengths.append(max(1, block))
            start += length
        self.size = start

    def model(self, theta: np.ndarray) -> _Model:
        """The model at theta, or Infeasible where it cannot be built."""
        try:
            return self.build(theta)
        except ValueError as error:
            raise Infeasible(str(error)) from None

    def __call__(
        self, theta: np.ndarray, blocks: Sequence[int], outs: Sequence[np.ndarray]
    ) -> None:
        """The residuals of the impacts `blocks` at theta, into outs (a BlockResidualFunction)."""
        model = self.model(theta)
        for index, out in zip(blocks, outs, strict=True):
            self.impact_residual(index, model, out)

    def impact_residual(
        self, index: int, model: _Model, out: np.ndarray, force_scale: float = 1.0
    ) -> None:
        """One impact's residual segment; force_scale multiplies its force (sensitivity)."""
        impact = self.impacts[index]
        force = impact.force_n if force_scale == 1.0 else impact.force_n * force_scale
        velocity = self.simulate(index, model, force).velocity_m_s
        if self.misfit == 'time':
            np.subtract(impact.velocity_m_s, velocity, out=out)
            return
        target = self.targets[index]
        spectrum = scipy.fft.rfft(velocity)[: target.size]
        spectrum *= self.inverse_force[index]
        residual = out.view(complex)
        np.subtract(target, spectrum, out=residual)
        residual /= force_scale  # the measured mobility's denominator scales with the force

    def simulate(self, index: int, model: _Model, force_n: np.ndarray | None = None) -> Simulation:
        """Run one impact (or force_n in its place) through the model into the shared buffer."""
        impact = self.impacts[index]
        n = impact.force_n.size
        try:
            return simulate(
                impact.force_n if force_n is None else force_n,
                impact.sample_rate_hz,
                rig=model.rig,
                mu=model.mu,
                effects=model.effects,
                x0_m=model.initial_position_m(index),
                integrator=self.integrator,
                out=(self.buffer[0, :n], self.buffer[1, :n]),
            )
        except ValueError as error:  # e.g. a term that makes one direction's friction < 0
            raise Infeasible(str(error)) from None

    def time_residuals(self, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """Measured minus simulated velocity of every impact at theta (fresh arrays) [m/s]."""
        model = self.model(theta)
        return tuple(
            impact.velocity_m_s - self.simulate(index, model).velocity_m_s
            for index, impact in enumerate(self.impacts)
        )

    def impulse_jacobians(
        self, theta: np.ndarray, residual: np.ndarray, relative_step: float = 1e-4
    ) -> Iterator[np.ndarray]:
        """Impact by impact, d residual / d impulse [residual units per N*s] on its segment.

        The hit is short against the rig's period, so what force noise inside the gate does
        to the response is what a change of impulse does: the force is scaled to find it.
        `residual` is the stacked residual at theta. One array is reused: each is valid until
        the next is asked for.
        """
        model = self.model(theta)
        scratch = np.empty(max(segment.stop - segment.start for segment in self.segments))
        for index, impact in enumerate(self.impacts):
            segment = self.segments[index]
            shifted = scratch[: segment.stop - segment.start]
            self.impact_residual(index, model, shifted, 1.0 + relative_step)
            shifted -= residual[segment]
            shifted /= relative_step * impact.impulse_n_s
            yield shifted


@dataclass(frozen=True)
class _Uncertainty:
    covariance: np.ndarray
    stderr: np.ndarray
    stderr_white: np.ndarray
    stderr_force: np.ndarray


def _uncertainty(
    solution: LsqSolution,
    block_lengths: Sequence[int],
    impulse_terms: Iterable[tuple[int, np.ndarray, float]] = (),
) -> _Uncertainty:
    """Covariance of a fit: velocity residuals (block sandwich) plus force noise (module doc).

    The sandwich is scaled up where it falls below the white-noise covariance (its block sums
    are few, so it is noisy, and it cannot be more precise than white noise allows). The force
    part propagates each impact's impulse uncertainty through the fit: d theta / d I =
    -(J J^T)^-1 J (d r / d I). block_lengths: per block of the Jacobian (`_lsq.Blocks`), the
    score's summing length; impulse_terms: (block, d r / d I on it, impulse std). Both pieces
    are summed block by block over the parameters each block depends on.
    """
    jacobian, residual = solution.jacobian, solution.residual
    blocks = jacobian.blocks
    p = blocks.n_parameters
    inverse = normal_inverse(jacobian.normal())
    white = solution.cost / max(residual.size - p, 1) * inverse
    # A parameter the residuals do not depend on has infinite variance (normal_inverse); the
    # products below run on the finite part (inf x 0 would make its row and column NaN) and
    # the infinity is put back on the diagonal at the end.
    dead = ~np.isfinite(np.diag(inverse))
    inverse = np.where(np.isfinite(inverse), inverse, 0.0)
    score = np.zeros((p, p))
    for segment, indices, rows, block in zip(
        blocks.segments, blocks.parameters, jacobian.rows, block_lengths, strict=True
    ):
        contributions = rows * residual[segment]
        sums = np.add.reduceat(contributions, np.arange(0, contributions.shape[1], block), axis=1)
        score[np.ix_(indices, indices)] += sums @ sums.T
    sandwich = inverse @ score @ inverse
    with np.errstate(divide='ignore', invalid='ignore'):
        raise_to_white = np.sqrt(np.maximum(1.0, np.diag(white) / np.diag(sandwich)))
    raise_to_white = np.where(np.isfinite(raise_to_white), raise_to_white, 1.0)
    velocity_part = sandwich * np.outer(raise_to_white, raise_to_white)
    force_part = np.zeros((p, p))
    for block, impulse_jacobian, std in impulse_terms:
        along = np.zeros(p)
        along[blocks.parameters[block]] = inner(jacobian.rows[block], impulse_jacobian)
        sensitivity = inverse @ along
        force_part += std**2 * np.outer(sensitivity, sensitivity)
    covariance = velocity_part + force_part
    covariance[dead, dead] = np.inf
    return _Uncertainty(
        covariance,
        np.sqrt(np.diag(covariance)),
        np.sqrt(np.diag(white)),
        np.sqrt(np.diag(force_part)),
    )


def _fit_uncertainty(solution: LsqSolution, problem: _OutputError) -> _Uncertainty:
    """`_uncertainty` of an output-error fit, force noise included."""
    stds = [impact.impulse_std_n_s for impact in problem.impacts]
    terms = zip(
        range(len(stds)),
        problem.impulse_jacobians(solution.x, solution.residual),
        stds,
        strict=True,
    )
    return _uncertainty(solution, problem.block_lengths, terms)


# --- fitting mu, c and model terms ---------------------------------------------------------------


@dataclass(frozen=True)
class ModelFit:
    """One output-error fit: parameter values and errors, the fitted model, its residuals."""

    names: tuple[str, ...]
    """'mu', then 'damping_n_s_per_m' if fitted, then '<term>.<parameter>' per fitted term."""
    units: tuple[str, ...]
    values: np.ndarray
    stderr: np.ndarray
    """Standard errors, from `covariance`."""
    stderr_white: np.ndarray
    """Velocity white-noise part alone, s (J^T J)^-1/2 (optimistic where residuals correlate)."""
    stderr_force: np.ndarray
    """Force-noise part alone: the impulse uncertainty of each hit, propagated."""
    covariance: np.ndarray
    """Velocity residuals (block sandwich, at least white) plus force noise in the gates."""
    rig: Rig
    """The rig constants of the fitted model (damping included)."""
    mu: float
    effects: tuple[ModelTerm, ...]
    """Model terms of the fitted model: the fixed ones, then the fitted ones."""
    initial_positions_m: tuple[float, ...]
    """Where each impact's model started [m] (0 unless fit_initial_position)."""
    misfit: str
    impacts: tuple[ConditionedImpact, ...]
    """The conditioned impacts fitted (their force drives `simulate`)."""
    sources: tuple[str, ...]
    residuals_m_s: tuple[np.ndarray, ...]
    """Measured minus simulated velocity per impact at the fitted values [m/s]."""
    residual_rms_m_s: float
    """RMS of the velocity residual over every sample of every impact [m/s]."""
    normalised_residual: float
    """residual_rms_m_s divided by the largest measured |velocity| [-]."""
    impact_residual_rms_m_s: tuple[float, ...]
    impact_normalised_residual: tuple[float, ...]
    explained_fraction: tuple[float, ...]
    """Per impact, 1 - (residual sum of squares) / (sum of squared measured velocity)."""
    noise_std_m_s: float
    """Velocity white-noise level from the data alone (pooled over impacts) [m/s]."""
    n_samples: int
    """Velocity samples behind the fit (all impacts)."""
    misfit_sum_of_squares: float
    """The minimised sum of squares, in the misfit's own units."""
    n_misfit_residuals: int
    at_bounds: tuple[str, ...]
    """Fitted parameters that ended on a search bound."""
    evaluations: int
    """Model runs the optimiser made, one an impact simulated (standard errors not counted)."""
    iterations: int

    def index(self, name: str) -> int:
        """Position of a parameter in `names`; ValueError naming the known ones."""
        if name not in self.names:
            raise ValueError(f'no fitted parameter {name!r}; fitted: {", ".join(self.names)}')
        return self.names.index(name)

    def value(self, name: str) -> float:
        """A fitted value by name."""
        return float(self.values[self.index(name)])

    def error(self, name: str) -> float:
        """The standard error of a fitted value by name."""
        return float(self.stderr[self.index(name)])

    @property
    def mu_stderr(self) -> float:
        """Standard error of mu [-]."""
        return self.error('mu')

    def simulate(self, index: int) -> Simulation:
        """The fitted model's response to impact `index` (its conditioned force, its start)."""
        impact = self.impacts[index]
        return simulate(
            impact.force_n,
            impact.sample_rate_hz,
            rig=self.rig,
            mu=self.mu,
            effects=self.effects,
            x0_m=self.initial_positions_m[index],
        )


@dataclass(frozen=True)
class _Space:
    """The parameter vector of a friction fit and the model it stands for."""

    rig: Rig
    fit_damping: bool
    terms: tuple[type[ModelTerm], ...]
    fixed_effects: tuple[ModelTerm, ...]
    initial_positions: int
    """Impacts whose initial position is fitted (the last entries of theta); 0: none."""
    names: tuple[str, ...]
    units: tuple[str, ...]
    start: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    typical: np.ndarray

    def build(self, theta: np.ndarray) -> _Model:
        rig = self.rig
        position = 1
        if self.fit_damping:
            rig = replace(rig, damping_n_s_per_m=float(theta[1]))
            position = 2
        effects = list(self.fixed_effects)
        for term in self.terms:
            count = len(term.parameters)
            effects.append(term.from_vector(theta[position : position + count]))
            position += count
        positions = tuple(float(x) for x in theta[position : position + self.initial_positions])
        return _Model(rig, float(theta[0]), tuple(effects), positions)

    def blocks(self, segments: Sequence[slice], jacobian: str = 'blocks') -> Blocks:
        """Which parameters move which impact's residual segment (`_lsq.Blocks`).

        mu, c and the terms move every impact, initial_position_m[k] only impact k; with
        jacobian='dense' every parameter is taken to move every impact.
        """
        if jacobian == 'dense':
            return Blocks.shared(segments, self.start.size)
        n_global = self.start.size - self.initial_positions
        local = [[n_global + k] for k in range(self.initial_positions)] or [()] * len(segments)
        return Blocks.global_and_local(segments, n_global, local)


def _space(
    rig: Rig,
    mu0: float,
    mu_bounds: tuple[float, float],
    fit_damping: bool,
    terms: Sequence[str | ModelTerm],
    fixed_effects: Sequence[ModelTerm],
    initial_positions: int,
) -> _Space:
    names, units = ['mu'], ['1']
    start, lower, upper = [mu0], [mu_bounds[0]], [mu_bounds[1]]
    typical = [max(mu0, 0.01)]
    if fit_damping:
        names.append('damping_n_s_per_m')
        units.append('N*s/m')
        start.append(rig.damping_n_s_per_m)
        lower.append(DAMPING_BOUNDS_N_S_PER_M[0])
        upper.append(DAMPING_BOUNDS_N_S_PER_M[1])
        typical.append(max(rig.damping_n_s_per_m, 0.05))
    fixed = tuple(fixed_effects)
    for effect in fixed:
        if not isinstance(effect, ModelTerm):
            raise ValueError(f'fixed_effects must be model terms, got {effect!r}')
    classes = []
    for term in terms:
        if isinstance(term, ModelTerm):
            cls, values = type(term), term.to_vector()
        elif term in MODEL_TERMS:
            cls = MODEL_TERMS[term]
            values = np.array([p.default for p in cls.parameters])
        else:
            raise ValueError(f'unknown model term {term!r}; known: {", ".join(MODEL_TERMS)}')
        if cls in classes or any(isinstance(effect, cls) for effect in fixed):
            raise ValueError(f'model term {cls.name} given twice')
        classes.append(cls)
        low, high = cls.bounds()
        for parameter, value, lo, hi in zip(cls.parameters, values, low, high, strict=True):
            names.append(f'{cls.name}.{parameter.name}')
            units.append(parameter.unit)
            start.append(min(max(value, lo), hi))
            lower.append(lo)
            upper.append(hi)
            typical.append(max(abs(parameter.default), 1e-3 * (hi - lo)))
    if fit_damping and MODEL_TERMS['viscous_damping'] in classes:
        raise ValueError(
            'fit_damping and a fitted viscous_damping term are the same parameter; choose one'
        )
    # Where the mass can rest before a hit: inside the friction band of the largest mu searched.
    band_m = mu_bounds[1] * rig.normal_force_n / rig.stiffness_n_per_m
    for index in range(initial_positions):
        names.append(f'initial_position_m[{index}]')
        units.append('m')
        start.append(0.0)
        lower.append(-band_m)
        upper.append(band_m)
        typical.append(mu0 * rig.normal_force_n / rig.stiffness_n_per_m)
    return _Space(
        rig,
        fit_damping,
        tuple(classes),
        fixed,
        initial_positions,
        tuple(names),
        tuple(units),
        np.array(start, dtype=float),
        np.array(lower, dtype=float),
        np.array(upper, dtype=float),
        np.array(typical, dtype=float),
    )


def energy_balance_mu(impacts: Sequence[ConditionedImpact], rig: Rig = FMM_RIG) -> float:
    """Friction coefficient from energy: the hits' input less viscous loss, over N x path slid.

    The hit gives the rig I^2 / 2m; friction takes mu N per metre slid (integral of |v|) and
    the viscous damper c times the integral of v^2. Noise adds sigma sqrt(2/pi) per sample to |v|
    and sigma^2 to v^2, which is taken off. A start value for the least-squares fit, good to a
    few per cent; NaN where the record gives no positive estimate.
    """
    energy = path = 0.0
    for impact in impacts:
        v = impact.velocity_m_s
        step_s = 1.0 / impact.sample_rate_hz
        sigma = impact.velocity_noise_std_m_s
        slid = (float(np.sum(np.abs(v))) - v.size * sigma * math.sqrt(2.0 / math.pi)) * step_s
        viscous = rig.damping_n_s_per_m * (inner(v, v) - v.size * sigma**2) * step_s
        energy += impact.impulse_n_s**2 / (2.0 * rig.mass_kg) - viscous
        path += slid
    if rig.normal_force_n <= 0.0 or path <= 0.0 or energy <= 0.0:
        return math.nan
    return energy / (rig.normal_force_n * path)


def fit_model(
    impacts: Sequence,
    *,
    rig: Rig = FMM_RIG,
    mu0: float | None = None,
    mu_bounds: tuple[float, float] = MU_BOUNDS,
    fit_damping: bool = False,
    terms: Sequence[str | ModelTerm] = (),
    fixed_effects: Sequence[ModelTerm] = (),
    fit_initial_position: bool = False,
    misfit: str = 'time',
    band_limit_hz: float = DEFAULT_BAND_LIMIT_HZ,
    integrator: str = 'exact',
    jacobian: str = 'blocks',
) -> ModelFit:
    """Fit one mu (and c, and the parameters of `terms`) to every impact at once.

    impacts: ConditionedImpacts, or records with force_n, velocity_m_s, sample_rate_hz (they
    are conditioned here). terms: names of model terms to fit (started at their defaults) or
    term instances (started at their values); fixed_effects: terms held as given. mu0: start
    value (default: the energy balance). fit_initial_position: also fit where each impact's
    mass rested before the hit (a nuisance parameter per impact, `initial_position_m[i]`):
    friction holds the FMM anywhere within +-mu N / k of centre after the previous hit, and
    the velocity alone does not say where; without it every impact starts at x = 0, as in
    the paper. jacobian: 'blocks' (default) runs each start position's Jacobian column on its
    own impact only; 'dense' runs every column on every impact (same result, the reference).
    Raises ValueError for bad arguments and FitError when the fit does not converge, puts mu
    on a bound of mu_bounds, or leaves an impact unexplained.
    """
    conditioned = _conditioned_list(impacts)
    _check_options(rig, misfit, band_limit_hz, integrator, jacobian)
    low, high = (float(bound) for bound in mu_bounds)
    if not 0.0 <= low < high or not math.isfinite(high):
        raise ValueError(f'mu_bounds must be 0 <= lower < upper, finite; got {mu_bounds}')
    require_positive('normal_force_n (to fit mu)', rig.normal_force_n)
    _check_durations(conditioned, rig)
    if mu0 is None:
        mu0 = energy_balance_mu(conditioned, rig)
        if not math.isfinite(mu0):
            mu0 = PAPER_MU
    mu0 = min(max(float(mu0), low + 0.01 * (high - low)), high - 0.01 * (high - low))
    space = _space(
        rig,
        mu0,
        (low, high),
        fit_damping,
        terms,
        fixed_effects,
        len(conditioned) if fit_initial_position else 0,
    )
    problem = _OutputError(
        conditioned, space.build, misfit, band_limit_hz, integrator, rig.natural_frequency_hz
    )
    solution = levenberg_marquardt(
        problem,
        space.start,
        space.lower,
        space.upper,
        space.typical,
        problem.size,
        blocks=space.blocks(problem.segments, jacobian),
    )
    fit = _model_fit(space, problem, solution)
    _require_explained(fit, solution, conditioned)
    if 'mu' in fit.at_bounds:
        raise FitError(
            'mu_at_bound',
            f'the best-fit friction coefficient {fit.mu:.4g} lies on '
            f'its search bound [{low:g}, {high:g}]: friction does not explain the '
            'record(s) (no friction, or far more than the rig can show)',
            _joined_sources(conditioned),
        )
    return fit


def _model_fit(space: _Space, problem: _OutputError, solution: LsqSolution) -> ModelFit:
    uncertainty = _fit_uncertainty(solution, problem)
    model = space.build(solution.x)
    if problem.misfit == 'time':
        residuals = tuple(solution.residual[segment].copy() for segment in problem.segments)
    else:
        residuals = problem.time_residuals(solution.x)
    squares = [inner(r, r) for r in residuals]
    impacts = problem.impacts
    n_samples = sum(r.size for r in residuals)
    rms = [math.sqrt(s / r.size) for s, r in zip(squares, residuals, strict=True)]
    total_rms = math.sqrt(sum(squares) / n_samples)
    peaks = [impact.peak_velocity_m_s for impact in impacts]
    explained = [
        1.0 - s / inner(impact.velocity_m_s, impact.velocity_m_s)
        for s, impact in zip(squares, impacts, strict=True)
    ]
    noise = math.sqrt(
        sum(i.velocity_noise_std_m_s**2 * i.force_n.size for i in impacts) / n_samples
    )
    span = space.upper - space.lower
    at_bounds = tuple(
        name
        for name, value, lo, hi, width in zip(
            space.names, solution.x, space.lower, space.upper, span, strict=True
        )
        if value <= lo + 1e-9 * width or value >= hi - 1e-9 * width
    )
    return ModelFit(
        names=space.names,
        units=space.units,
        values=solution.x.copy(),
        stderr=uncertainty.stderr,
        stderr_white=uncertainty.stderr_white,
        stderr_force=uncertainty.stderr_force,
        covariance=uncertainty.covariance,
        rig=model.rig,
        mu=model.mu,
        effects=model.effects,
        initial_positions_m=tuple(model.initial_position_m(index) for index in range(len(impacts))),
        misfit=problem.misfit,
        impacts=impacts,
        sources=tuple(i.source for i in impacts),
        residuals_m_s=residuals,
        residual_rms_m_s=total_rms,
        normalised_residual=total_rms / max(peaks),
        impact_residual_rms_m_s=tuple(rms),
        impact_normalised_residual=tuple(r / p for r, p in zip(rms, peaks, strict=True)),
        explained_fraction=tuple(explained),
        noise_std_m_s=noise,
        n_samples=n_samples,
        misfit_sum_of_squares=solution.cost,
        n_misfit_residuals=problem.size,
        at_bounds=at_bounds,
        evaluations=solution.evaluations,
        iterations=solution.iterations,
    )


def _require_explained(
    fit: ModelFit, solution: LsqSolution, impacts: Sequence[ConditionedImpact]
) -> None:
    if not solution.converged:
        raise FitError(
            'no_convergence',
            f'the fit did not converge ({solution.message})',
            _joined_sources(impacts),
        )
    for explained, impact in zip(fit.explained_fraction, impacts, strict=True):
        if explained < MIN_EXPLAINED_FRACTION:
            raise FitError(
                'unexplained',
                _unexplained_message('model', explained)
                + ': the record is not a friction-damped response to its force (check '
                'the channels, their signs and the rig constants)',
                impact.source,
            )


def _unexplained_message(model: str, explained: float) -> str:
    return (
        f'the best-fit {model} leaves {100 * (1 - explained):.0f} % of the velocity sum of '
        f'squares unexplained (predicting no motion at all leaves 100 %; at most '
        f'{100 * (1 - MIN_EXPLAINED_FRACTION):.0f} % allowed)'
    )


def _joined_sources(impacts: Sequence[ConditionedImpact]) -> str:
    return ', '.join(impact.source for impact in impacts if impact.source)


def _conditioned_list(impacts: Sequence) -> list[ConditionedImpact]:
    if isinstance(impacts, ConditionedImpact) or hasattr(impacts, 'force_n'):
        impacts = [impacts]
    conditioned = [as_conditioned(impact) for impact in impacts]
    if not conditioned:
        raise ValueError('no impacts to fit')
    return conditioned


def _check_options(
    rig: Rig, misfit: str, band_limit_hz: float, integrator: str, jacobian: str
) -> None:
    if not isinstance(rig, Rig):
        raise ValueError(f'rig must be a Rig, got {rig!r}')
    if misfit not in MISFITS:
        raise ValueError(f'unknown misfit {misfit!r}; choose one of {", ".join(MISFITS)}')
    require_positive('band_limit_hz', band_limit_hz)
    if integrator not in INTEGRATORS:
        raise ValueError(
            f'unknown integrator {integrator!r}; choose one of {", ".join(INTEGRATORS)}'
        )
    if jacobian not in JACOBIANS:
        raise ValueError(f'unknown jacobian {jacobian!r}; choose one of {", ".join(JACOBIANS)}')


def _check_durations(impacts: Sequence[ConditionedImpact], rig: Rig) -> None:
    period_s = 1.0 / rig.natural_frequency_hz
    for impact in impacts:
        if impact.duration_s < 2.0 * period_s:
            raise ValueError(
                f'{_where(impact.source)}the record lasts {impact.duration_s:.3g} '
                f's, less than two natural periods ({2 * period_s:.3g} s) of the '
                'rig: too short to fit'
            )


@dataclass(frozen=True)
class FrictionFit:
    """One mu for every impact (the paper's claim) and each impact's own mu, side by side."""

    joint: ModelFit
    """mu (and c) fitted to all impacts at once."""
    per_impact: tuple[ModelFit, ...]
    """mu fitted to each impact alone, c and any terms held at the joint values."""
    consistency_chi2: float
    """sum of ((mu_i - mu) / stderr_i)^2: large when one mu does not serve every impact."""
    consistency_p_value: float
    """Chance of a chi^2 this large if one mu did serve all (chi^2 with n - 1 degrees); NaN
    for one impact."""
    impulses_n_s: tuple[float, ...]

    @property
    def mu(self) -> float:
        """The common friction coefficient [-]."""
        return self.joint.mu

    @property
    def mu_stderr(self) -> float:
        """Its standard error [-]."""
        return self.joint.mu_stderr

    @property
    def damping_n_s_per_m(self) -> float:
        """Viscous damping of the model, fitted or as given [N*s/m]."""
        return self.joint.rig.damping_n_s_per_m

    @property
    def damping_stderr_n_s_per_m(self) -> float:
        """Standard error of the fitted damping [N*s/m]; NaN when it was not fitted."""
        if 'damping_n_s_per_m' not in self.joint.names:
            return math.nan
        return self.joint.error('damping_n_s_per_m')


def fit_friction(
    impacts: Sequence,
    *,
    rig: Rig = FMM_RIG,
    fit_damping: bool = False,
    fit_initial_position: bool = False,
    mu_bounds: tuple[float, float] = MU_BOUNDS,
    misfit: str = 'time',
    band_limit_hz: float = DEFAULT_BAND_LIMIT_HZ,
    integrator: str = 'exact',
    jacobian: str = 'blocks',
) -> FrictionFit:
    """The paper's fit: one mu (and optionally c) over all impacts, plus each impact's own mu.

    fit_initial_position and jacobian as in `fit_model` (each impact's own fit then refits its
    own start). Raises ValueError for bad input and FitError (naming the impact) for any
    impact, or the set, that friction cannot explain.
    """
    conditioned = _conditioned_list(impacts)
    options = dict(
        mu_bounds=mu_bounds,
        fit_initial_position=fit_initial_position,
        misfit=misfit,
        band_limit_hz=band_limit_hz,
        integrator=integrator,
        jacobian=jacobian,
    )
    joint = fit_model(conditioned, rig=rig, fit_damping=fit_damping, **options)
    if len(conditioned) == 1:
        per_impact = (
            (joint,)
            if not fit_damping
            else (fit_model(conditioned, rig=joint.rig, mu0=joint.mu, **options),)
        )
    else:
        per_impact = tuple(
            fit_model([impact], rig=joint.rig, mu0=joint.mu, **options) for impact in conditioned
        )
    mus = np.array([fit.mu for fit in per_impact])
    errors = np.array([fit.mu_stderr for fit in per_impact])
    chi2 = float(np.sum(((mus - joint.mu) / errors) ** 2))
    dof = len(per_impact) - 1
    p_value = float(scipy.stats.chi2.sf(chi2, dof)) if dof > 0 else math.nan
    return FrictionFit(
        joint=joint,
        per_impact=per_impact,
        consistency_chi2=chi2,
        consistency_p_value=p_value,
        impulses_n_s=tuple(impact.impulse_n_s for impact in conditioned),
    )


# --- rig identification (paper Sec. 4) ----------------------------------------------------------


@dataclass(frozen=True)
class FreeDecayFit:
    """A damped free oscillation v = exp(-zeta w t)(a cos w_d t + b sin w_d t) + offset."""

    natural_frequency_hz: float
    natural_frequency_stderr_hz: float
    damping_ratio: float
    damping_ratio_stderr: float
    start_index: int
    """First sample fitted; t = 0 of the amplitudes."""
    amplitudes_m_s: tuple[float, float]
    """(a, b) at the start sample [m/s]."""
    offset_m_s: float
    residual_rms_m_s: float
    normalised_residual: float
    source: str = ''

    @property
    def damped_frequency_hz(self) -> float:
        """f_d = f_n sqrt(1 - zeta^2) [Hz]."""
        return self.natural_frequency_hz * math.sqrt(1.0 - self.damping_ratio**2)


def fit_free_decay(
    velocity_m_s: np.ndarray,
    sample_rate_hz: float,
    *,
    start_index: int | None = None,
    source: str = '',
) -> FreeDecayFit:
    """Natural frequency and damping ratio of a free decay of the frictionless rig.

    Fitted from start_index (default: the first sample reaching half the largest |v|, safely
    after a release or a hit) to the end, by variable projection: for each (f_n, zeta) the
    amplitudes and a constant offset are solved linearly. Start values come from the zero
    crossings (period) and the decay of the half-cycle peaks (zeta). Raises FitError
    ('too_few_cycles') when the record holds fewer than about three cycles above its noise.
    """
    velocity = _checked_channel('velocity_m_s', velocity_m_s, source)
    require_positive('sample_rate_hz', sample_rate_hz)
    if start_index is None:
        magnitude = np.abs(velocity)
        start_index = int(np.argmax(magnitude >= 0.5 * magnitude.max()))
    if not 0 <= start_index < velocity.size:
        raise ValueError(
            f'start_index {start_index} lies outside the record ({velocity.size} samples)'
        )
    segment = velocity[start_index:]
    frequency0, zeta0 = _decay_start_values(
        segment, sample_rate_hz, velocity_noise_std(velocity), source
    )
    basis = np.ones((3, segment.size))

    def residual(theta: np.ndarray, out: np.ndarray) -> None:
        _decay_basis(theta[0], theta[1], sample_rate_hz, basis)
        np.subtract(segment, inner(basis.T, _solve_linear(basis, segment)), out=out)

    solution = levenberg_marquardt(
        residual,
        np.array([frequency0, zeta0]),
        np.array([0.8 * frequency0, 0.0]),
        np.array([1.25 * frequency0, 0.5]),
        np.array([frequency0, 1e-3]),
        segment.size,
    )
    _require_inside(
        solution, ('natural frequency', 'damping ratio'), 'a lightly damped free decay', source
    )
    uncertainty = _uncertainty(solution, [max(1, round(sample_rate_hz / solution.x[0]))])
    _decay_basis(solution.x[0], solution.x[1], sample_rate_hz, basis)
    a, b, offset = _solve_linear(basis, segment)
    rms = math.sqrt(solution.cost / segment.size)
    return FreeDecayFit(
        natural_frequency_hz=float(solution.x[0]),
        natural_frequency_stderr_hz=float(uncertainty.stderr[0]),
        damping_ratio=float(solution.x[1]),
        damping_ratio_stderr=float(uncertainty.stderr[1]),
        start_index=start_index,
        amplitudes_m_s=(float(a), float(b)),
        offset_m_s=float(offset),
        residual_rms_m_s=rms,
        normalised_residual=rms / float(np.max(np.abs(segment))),
        source=source,
    )


def _decay_basis(frequency_hz: float, zeta: float, sample_rate_hz: float, out: np.ndarray) -> None:
    """out[0], out[1] = exp(-zeta w t) cos(w_d t), ... sin(w_d t) at t = i / sample_rate_hz.

    As a product of two short tables of exp(s t), s = -zeta w + i w_d (coarse steps times fine
    steps): one complex multiply a sample instead of an exp, a cos and a sin, and no error
    growing along the record as a running product would have.
    """
    omega = 2.0 * math.pi * frequency_hz
    pole = complex(-zeta * omega, omega * math.sqrt(max(1.0 - zeta * zeta, 0.0)))
    n = out.shape[1]
    fine = max(1, math.isqrt(n))
    coarse = -(-n // fine)
    phasor = np.outer(
        np.exp(pole * fine / sample_rate_hz * np.arange(coarse)),
        np.exp(pole / sample_rate_hz * np.arange(fine)),
    ).ravel()[:n]
    out[0] = phasor.real
    out[1] = phasor.imag


def _solve_linear(basis: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Least-squares coefficients of values on the rows of basis (normal equations)."""
    return np.linalg.solve(inner(basis, basis), inner(basis, values))


def _decay_start_values(
    segment: np.ndarray, sample_rate_hz: float, noise_m_s: float, source: str
) -> tuple[float, float]:
    """(f_n, zeta) from the zero crossings and half-cycle peaks of a decaying velocity."""
    level = max(3.0 * noise_m_s, 1e-3 * float(np.max(np.abs(segment))))
    state = np.where(segment > level, 1, np.where(segment < -level, -1, 0))
    signed = np.flatnonzero(state)
    changes = signed[1:][np.diff(state[signed]) != 0]
    if changes.size < MIN_DECAY_CROSSINGS:
        raise FitError(
            'too_few_cycles',
            f'the velocity crosses zero only {changes.size} '
            'times above its noise: too few cycles to fit a free decay',
            source,
        )
    # Each crossing's time: the midpoint of the samples on either side of the dead band.
    before = signed[np.searchsorted(signed, changes) - 1]
    crossings = 0.5 * (before + changes) / sample_rate_hz
    damped_hz = 0.5 / np.polyfit(np.arange(crossings.size), crossings, 1)[0]
    peaks = np.array(
        [np.max(np.abs(segment[a:b])) for a, b in zip(changes[:-1], changes[1:], strict=True)]
    )
    times = 0.5 * (crossings[:-1] + crossings[1:])
    usable = peaks > 10.0 * level
    decay_rate = (
        -np.polyfit(times[usable], np.log(peaks[usable]), 1)[0] if usable.sum() >= 2 else 0.0
    )
    omega_d = 2.0 * math.pi * damped_hz
    zeta = min(max(decay_rate / math.hypot(omega_d, decay_rate), 0.0), 0.3)
    return damped_hz / math.sqrt(1.0 - zeta * zeta), zeta


@dataclass(frozen=True)
class RigIdentification:
    """m, c, k of the frictionless rig, their standard errors, and f_n and zeta derived."""

    mass_kg: float
    stiffness_n_per_m: float
    damping_n_s_per_m: float
    mass_stderr_kg: float
    """NaN for free decays (the mass was given)."""
    stiffness_stderr_n_per_m: float
    damping_stderr_n_s_per_m: float
    natural_frequency_hz: float
    natural_frequency_stderr_hz: float
    damping_ratio: float
    damping_ratio_stderr: float
    method: str
    """'impact' (fitted to forced responses) or 'free_decay' (f_n, zeta fitted; the mass
    given, k = m w^2, c = 2 zeta m w)."""
    residual_rms_m_s: float
    normalised_residual: float
    sources: tuple[str, ...]
    free_decays: tuple[FreeDecayFit, ...] = field(default=())
    """Fits of the records without a hit (with impacts present, a cross-check on f_n, zeta)."""

    def rig(self, normal_force_n: float = FMM_RIG.normal_force_n) -> Rig:
        """These constants as a Rig with the given normal force."""
        return Rig(self.mass_kg, self.stiffness_n_per_m, self.damping_n_s_per_m, normal_force_n)


def identify_rig(
    records: Sequence, *, mass_kg: float | None = None, integrator: str = 'exact'
) -> RigIdentification:
    """Identify the rig from records taken with the friction contact lifted (mu = 0).

    Records with a hit are impacts: m, f_n and zeta (so k and c) are fitted to all of them at
    once by output error, the measured force driving m x'' + c x' + k x = f. Records without a
    hit are free decays (`fit_free_decay`): f_n and zeta are fitted, and m, c, k follow from
    the given mass_kg (a free decay alone cannot tell the mass). With both kinds the impacts
    decide and the decays are reported as a check. FitError for records the linear rig does not
    explain, ValueError for bad input.
    """
    if isinstance(records, ConditionedImpact) or hasattr(records, 'force_n'):
        records = [records]
    if integrator not in INTEGRATORS:
        raise ValueError(
            f'unknown integrator {integrator!r}; choose one of {", ".join(INTEGRATORS)}'
        )
    impacts, decays = [], []
    for record in records:
        try:
            impacts.append(as_conditioned(record))
        except FitError as error:
            if error.reason != 'no_hit':
                raise
            decays.append(
                fit_free_decay(
                    record.velocity_m_s,
                    record.sample_rate_hz,
                    source=str(getattr(record, 'source', '')),
                )
            )
    if not impacts and not decays:
        raise ValueError('no records to identify the rig from')
    if impacts:
        return _rig_from_impacts(impacts, tuple(decays), integrator)
    if mass_kg is None:
        raise ValueError('free decays alone do not determine the mass: give mass_kg')
    return _rig_from_decays(decays, float(mass_kg))


def _rig_from_decays(decays: Sequence[FreeDecayFit], mass_kg: float) -> RigIdentification:
    require_positive('mass_kg', mass_kg)
    frequency, frequency_error = _weighted_mean(
        [d.natural_frequency_hz for d in decays], [d.natural_frequency_stderr_hz for d in decays]
    )
    zeta, zeta_error = _weighted_mean(
        [d.damping_ratio for d in decays], [d.damping_ratio_stderr for d in decays]
    )
    covariance = np.diag([0.0, frequency_error**2, zeta_error**2])
    values, errors = _rig_constants(np.array([mass_kg, frequency, zeta]), covariance)
    squares = sum(d.residual_rms_m_s**2 for d in decays) / len(decays)
    return RigIdentification(
        mass_kg=mass_kg,
        stiffness_n_per_m=values[1],
        damping_n_s_per_m=values[2],
        mass_stderr_kg=math.nan,
        stiffness_stderr_n_per_m=errors[1],
        damping_stderr_n_s_per_m=errors[2],
        natural_frequency_hz=frequency,
        natural_frequency_stderr_hz=frequency_error,
        damping_ratio=zeta,
        damping_ratio_stderr=zeta_error,
        method='free_decay',
        residual_rms_m_s=math.sqrt(squares),
        normalised_residual=max(d.normalised_residual for d in decays),
        sources=tuple(d.source for d in decays),
        free_decays=tuple(decays),
    )


def _require_inside(solution: LsqSolution, names: Sequence[str], what: str, source: str) -> None:
    """FitError unless a rig fit converged away from its search bounds."""
    if not solution.converged:
        raise FitError('no_convergence', f'the fit did not converge ({solution.message})', source)
    for name, value, low, high in zip(
        names, solution.x, solution.lower, solution.upper, strict=True
    ):
        if value <= low or value >= high:
            raise FitError(
                'at_bound',
                f'the best-fit {name} {value:.4g} lies on its search '
                f'bound [{low:.4g}, {high:.4g}]: the record is not {what}',
                source,
            )


def _rig_constants(
    modal: np.ndarray, covariance: np.ndarray
) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(m, k, c) and their standard errors from (m, f_n, zeta) and its covariance.

    k = m w^2 and c = 2 zeta m w with w = 2 pi f_n; errors to first order.
    """
    mass, frequency, zeta = (float(v) for v in modal)
    omega = 2.0 * math.pi * frequency
    values = np.array([mass, mass * omega**2, 2.0 * zeta * mass * omega])
    gradient = np.array(
        [
            [1.0, 0.0, 0.0],
            [omega**2, 4.0 * math.pi * mass * omega, 0.0],
            [2.0 * zeta * omega, 4.0 * math.pi * zeta * mass, 2.0 * mass * omega],
        ]
    )
    errors = np.sqrt(np.diag(gradient @ covariance @ gradient.T))
    return (tuple(float(v) for v in values), tuple(float(e) for e in errors))


def _weighted_mean(values: Sequence[float], errors: Sequence[float]) -> tuple[float, float]:
    """Inverse-variance weighted mean and its standard error (plain mean if errors are 0)."""
    weights = 1.0 / np.square(np.asarray(errors, dtype=float))
    if not np.all(np.isfinite(weights)) or weights.sum() <= 0.0:
        return float(np.mean(values)), 0.0
    return (
        float(np.sum(weights * np.asarray(values)) / weights.sum()),
        float(1.0 / math.sqrt(weights.sum())),
    )


def _rig_from_impacts(
    impacts: Sequence[ConditionedImpact], decays: tuple[FreeDecayFit, ...], integrator: str
) -> RigIdentification:
    """Output-error fit of (m, f_n, zeta), reported as m, k, c.

    In these coordinates the phase (f_n), the decay (zeta) and the amplitude (I / m) are nearly
    independent, where m, c, k make a long curved valley along k / m = const that took the
    optimiser 49 iterations (246 model runs) to follow, against 3 (16) here.
    """
    starts = [_impact_start_values(impact) for impact in impacts]
    start = np.median(np.array(starts), axis=0)
    mass0, frequency0, _ = start

    def build(theta: np.ndarray) -> _Model:
        mass, stiffness, damping = _rig_constants(theta, np.zeros((3, 3)))[0]
        return _Model(Rig(mass, stiffness, damping, 0.0), 0.0, ())

    problem = _OutputError(impacts, build, 'time', DEFAULT_BAND_LIMIT_HZ, integrator, frequency0)
    lower = np.array([0.5 * mass0, 0.8 * frequency0, 0.0])
    upper = np.array([2.0 * mass0, 1.25 * frequency0, 0.5])
    typical = np.array([mass0, frequency0, max(start[2], 1e-4)])
    solution = levenberg_marquardt(
        problem,
        start,
        lower,
        upper,
        typical,
        problem.size,
        blocks=Blocks.shared(problem.segments, start.size),
    )
    _require_inside(
        solution,
        ('mass', 'natural frequency', 'damping ratio'),
        'the frictionless rig hit by its force',
        _joined_sources(impacts),
    )
    uncertainty = _fit_uncertainty(solution, problem)
    values, errors = _rig_constants(solution.x, uncertainty.covariance)
    residuals = [solution.residual[segment] for segment in problem.segments]
    for impact, r in zip(impacts, residuals, strict=True):
        explained = 1.0 - inner(r, r) / inner(impact.velocity_m_s, impact.velocity_m_s)
        if explained < MIN_EXPLAINED_FRACTION:
            raise FitError(
                'unexplained',
                _unexplained_message('linear oscillator', explained)
                + ': not a response of the frictionless rig to its force',
                impact.source,
            )
    rms = math.sqrt(solution.cost / problem.size)
    return RigIdentification(
        mass_kg=values[0],
        stiffness_n_per_m=values[1],
        damping_n_s_per_m=values[2],
        mass_stderr_kg=errors[0],
        stiffness_stderr_n_per_m=errors[1],
        damping_stderr_n_s_per_m=errors[2],
        natural_frequency_hz=float(solution.x[1]),
        natural_frequency_stderr_hz=float(uncertainty.stderr[1]),
        damping_ratio=float(solution.x[2]),
        damping_ratio_stderr=float(uncertainty.stderr[2]),
        method='impact',
        residual_rms_m_s=rms,
        normalised_residual=rms / max(i.peak_velocity_m_s for i in impacts),
        sources=tuple(i.source for i in impacts),
        free_decays=decays,
    )


def _impact_start_values(impact: ConditionedImpact) -> tuple[float, float, float]:
    """Start values (m, f_n, zeta) from a frictionless impact.

    f_n and zeta from the zero crossings and peaks after the hit, m = I / (the velocity
    amplitude extrapolated back to the hit's centroid).
    """
    rate = impact.sample_rate_hz
    segment = impact.velocity_m_s[impact.hit_end_index :]
    frequency, zeta = _decay_start_values(
        segment, rate, impact.velocity_noise_std_m_s, impact.source
    )
    basis = np.ones((3, segment.size))
    _decay_basis(frequency, zeta, rate, basis)
    a, b, _ = _solve_linear(basis, segment)
    force = impact.force_n
    centroid = inner(np.arange(force.size, dtype=float), force) / float(np.sum(force))
    lag_s = (impact.hit_end_index - centroid) / rate
    amplitude = math.hypot(a, b) * math.exp(zeta * 2.0 * math.pi * frequency * lag_s)
    return abs(impact.impulse_n_s) / amplitude, frequency, zeta
