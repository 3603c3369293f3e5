"""Best-fit friction (and damping, and any model term) from measured force and velocity.

The paper's step (Kossack, Ziegert, Schmitz 2019, Sec. 5): drive Eq. 3 with the measured force
and choose mu so the simulated velocity matches the measured one. Here that is an output-error
least-squares fit over one or more impacts, in the time domain (velocity residual, default) or
on the mobility FRF (0 to `band_limit_hz`), of mu alone, mu and the viscous damping c, and the
parameters of any model term (`fmm_ros.core.physics.MODEL_TERMS`), with standard errors
(`fit_model`). `fit_friction` is the paper's question: one mu for every impact, each impact's
own mu beside it, and a chi^2 test of whether one mu serves them all.
"""

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.fft
import scipy.stats

from fmm_ros.constants import MISFIT_BAND_LIMIT_HZ, PAPER_MU
from fmm_ros.core._checks import require_positive
from fmm_ros.core.identify.conditioning import (
    ConditionedImpact,
    FitError,
    as_conditioned,
    source_prefix,
)
from fmm_ros.core.identify.lsq import (
    Blocks,
    LsqSolution,
    inner,
    levenberg_marquardt,
)
from fmm_ros.core.identify.output_error import (
    JACOBIANS,
    MISFITS,
    BuiltModel,
    OutputError,
    fit_uncertainty,
)
from fmm_ros.core.physics.model import INTEGRATORS, Simulation, simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import MODEL_TERMS, ModelTerm

MU_BOUNDS = (1e-3, 1.0)
"""Default search range of the friction coefficient; a best fit on either end is a failure."""


DAMPING_BOUNDS_N_S_PER_M = (0.0, 50.0)
"""Search range of the viscous damping c when it is fitted [N*s/m]."""


MIN_EXPLAINED_FRACTION = 0.5
"""A fit must remove at least this fraction of each record's velocity sum of squares (the
misfit of predicting no motion at all), or the model does not explain the record."""


MIN_DECAY_CROSSINGS = 6
"""A free decay must cross zero this often above its noise (three cycles) to be fitted."""


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

    def build(self, theta: np.ndarray) -> BuiltModel:
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
        return BuiltModel(rig, float(theta[0]), tuple(effects), positions)

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
    band_limit_hz: float = MISFIT_BAND_LIMIT_HZ,
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
    problem = OutputError(
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
            joined_sources(conditioned),
        )
    return fit


def _model_fit(space: _Space, problem: OutputError, solution: LsqSolution) -> ModelFit:
    uncertainty = fit_uncertainty(solution, problem)
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
            joined_sources(impacts),
        )
    for explained, impact in zip(fit.explained_fraction, impacts, strict=True):
        if explained < MIN_EXPLAINED_FRACTION:
            raise FitError(
                'unexplained',
                unexplained_message('model', explained)
                + ': the record is not a friction-damped response to its force (check '
                'the channels, their signs and the rig constants)',
                impact.source,
            )


def unexplained_message(model: str, explained: float) -> str:
    """Why a fit whose model explains only `explained` of the velocity is refused."""
    return (
        f'the best-fit {model} leaves {100 * (1 - explained):.0f} % of the velocity sum of '
        f'squares unexplained (predicting no motion at all leaves 100 %; at most '
        f'{100 * (1 - MIN_EXPLAINED_FRACTION):.0f} % allowed)'
    )


def joined_sources(impacts: Sequence[ConditionedImpact]) -> str:
    """The impacts' sources, comma-separated, for a FitError's `source`."""
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
                f'{source_prefix(impact.source)}the record lasts {impact.duration_s:.3g} '
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
    band_limit_hz: float = MISFIT_BAND_LIMIT_HZ,
    integrator: str = 'exact',
    jacobian: str = 'blocks',
    progress: Callable[[str], None] | None = None,
) -> FrictionFit:
    """The paper's fit: one mu (and optionally c) over all impacts, plus each impact's own mu.

    fit_initial_position and jacobian as in `fit_model` (each impact's own fit then refits its
    own start). progress, when given, is told of each fit as it starts (a line of text).
    Raises ValueError for bad input and FitError (naming the impact) for any impact, or the
    set, that friction cannot explain.
    """
    say = progress or (lambda _: None)
    conditioned = _conditioned_list(impacts)
    options = dict(
        mu_bounds=mu_bounds,
        fit_initial_position=fit_initial_position,
        misfit=misfit,
        band_limit_hz=band_limit_hz,
        integrator=integrator,
        jacobian=jacobian,
    )
    count = len(conditioned)
    say(f'fitting one mu to {count} impact{"s" if count > 1 else ""}')
    joint = fit_model(conditioned, rig=rig, fit_damping=fit_damping, **options)
    if count == 1 and not fit_damping:
        per_impact = (joint,)
    else:
        fits = []
        for number, impact in enumerate(conditioned, 1):
            say(f'fitting mu of impact {number}/{count} alone')
            fits.append(fit_model([impact], rig=joint.rig, mu0=joint.mu, **options))
        per_impact = tuple(fits)
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
