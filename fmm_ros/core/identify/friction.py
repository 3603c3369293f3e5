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
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from fmm_ros.constants import PAPER_MU
from fmm_ros.core._checks import require_positive
from fmm_ros.core._threads import available_threads
from fmm_ros.core.distributions import chi2_sf
from fmm_ros.core.identify.chain import DriftBasis, VelocityNuisance, estimate_nuisance
from fmm_ros.core.identify.conditioning import (
    ConditionedImpact,
    as_conditioned,
    chained_starts,
    source_prefix,
)
from fmm_ros.core.identify.lsq import (
    BlockJacobian,
    Blocks,
    LsqSolution,
    inner,
    levenberg_marquardt,
    normal_inverse,
)
from fmm_ros.core.identify.output_error import (
    BuiltModel,
    OutputError,
    fit_uncertainty,
)
from fmm_ros.core.identify.spec import (  # noqa: F401 (MU_BOUNDS re-exported)
    FITTED,
    FRICTION_FIT,
    JACOBIANS,
    MISFITS,
    MU_BOUNDS,
    UNCERTAINTIES,
    FitSpec,
)
from fmm_ros.core.physics.model import INTEGRATORS, Simulation, simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import MODEL_TERMS, ModelTerm
from fmm_ros.errors import BadInputError, FitError

DAMPING_BOUNDS_N_S_PER_M = (0.0, 50.0)
"""Search range of the viscous damping c when it is fitted [N*s/m]."""


IMPULSE_SCALE_BOUNDS = (0.5, 1.5)
"""Search range of a hit's impulse scale: the factor between the impulse that moved the rig
and the one its sampled force shows (sampling, filtering and noise make it a few 1e-3; a
hammer whose calibration is off by half is not measuring force)."""


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
    impulse_scales: tuple[float, ...]
    """Per impact, the factor on its measured hit that drove the model [-] (1 unless
    fit_impulse_scale)."""
    velocity_nuisance: tuple[VelocityNuisance, ...]
    """Per impact, the mains hum, offset and drift taken off its measured velocity (zero
    unless remove_mains_hum or fit_velocity_drift); `impacts` hold the velocity without it."""
    misfit: str
    impacts: tuple[ConditionedImpact, ...]
    """The conditioned impacts fitted (their force drives `simulate`; their velocity is the
    measured one less `velocity_nuisance`)."""
    sources: tuple[str, ...]
    residuals_m_s: tuple[np.ndarray, ...]
    """Measured minus simulated velocity per impact at the fitted values, every sample [m/s]
    (the time misfit leaves each impact's `hit_windows` out; these keep them)."""
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
            raise BadInputError(f'no fitted parameter {name!r}; fitted: {", ".join(self.names)}')
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

    def force_n(self, index: int) -> np.ndarray:
        """The force that drove the fitted model in impact `index`: conditioned, scaled [N]."""
        return self.impacts[index].force_n * self.impulse_scales[index]

    def simulate(self, index: int) -> Simulation:
        """The fitted model's response to impact `index` (its driving force, its start)."""
        impact = self.impacts[index]
        return simulate(
            self.force_n(index),
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
    """Impacts whose initial position is fitted (after the global entries of theta); 0: none."""
    impulse_scales: int
    """Impacts whose impulse scale is fitted (the last entries of theta); 0: none."""
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
        position += self.initial_positions
        scales = tuple(float(s) for s in theta[position : position + self.impulse_scales])
        return BuiltModel(rig, float(theta[0]), tuple(effects), positions, scales)

    @property
    def n_global(self) -> int:
        """Parameters that move every impact: mu, c and the terms."""
        return self.start.size - self.initial_positions - self.impulse_scales

    def blocks(self, segments: Sequence[slice], jacobian: str = 'blocks') -> Blocks:
        """Which parameters move which impact's residual segment (`_lsq.Blocks`).

        mu, c and the terms move every impact, initial_position_m[k] and impulse_scale[k]
        only impact k; with jacobian='dense' every parameter is taken to move every impact.
        """
        if jacobian == 'dense':
            return Blocks.shared(segments, self.start.size)
        n_global = self.n_global
        scales = n_global + self.initial_positions
        local = [
            ([n_global + k] if self.initial_positions else [])
            + ([scales + k] if self.impulse_scales else [])
            for k in range(len(segments))
        ]
        return Blocks.global_and_local(segments, n_global, local)


def _space(
    rig: Rig,
    mu0: float,
    mu_bounds: tuple[float, float],
    fit_damping: bool,
    terms: Sequence[str | ModelTerm],
    fixed_effects: Sequence[ModelTerm],
    initial_positions: int,
    impulse_scales: int,
    term_bounds: Mapping[str, tuple[float, float]] | None = None,
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
            raise BadInputError(f'fixed_effects must be model terms, got {effect!r}')
    classes = []
    for term in terms:
        if isinstance(term, ModelTerm):
            cls, values = type(term), term.to_vector()
        elif term in MODEL_TERMS:
            cls = MODEL_TERMS[term]
            values = np.array([p.default for p in cls.parameters])
        else:
            raise BadInputError(f'unknown model term {term!r}; known: {", ".join(MODEL_TERMS)}')
        if cls in classes or any(isinstance(effect, cls) for effect in fixed):
            raise BadInputError(f'model term {cls.name} given twice')
        classes.append(cls)
        low, high = cls.bounds(term_bounds)
        for parameter, value, lo, hi in zip(cls.parameters, values, low, high, strict=True):
            names.append(f'{cls.name}.{parameter.name}')
            units.append(parameter.unit)
            start.append(min(max(value, lo), hi))
            lower.append(lo)
            upper.append(hi)
            typical.append(max(abs(parameter.default), 1e-3 * (hi - lo)))
    if fit_damping and MODEL_TERMS['viscous_damping'] in classes:
        raise BadInputError(
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
    for index in range(impulse_scales):
        names.append(f'impulse_scale[{index}]')
        units.append('1')
        start.append(1.0)
        lower.append(IMPULSE_SCALE_BOUNDS[0])
        upper.append(IMPULSE_SCALE_BOUNDS[1])
        typical.append(1.0)
    return _Space(
        rig,
        fit_damping,
        tuple(classes),
        fixed,
        initial_positions,
        impulse_scales,
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
    spec: FitSpec | None = None,
    *,
    rig: Rig = FMM_RIG,
    mu0: float | None = None,
    terms: Sequence[str | ModelTerm] = (),
    fixed_effects: Sequence[ModelTerm] = (),
    start_values: Mapping[str, float] | None = None,
    term_bounds: Mapping[str, tuple[float, float]] | None = None,
    **changes: Any,
) -> ModelFit:
    """Fit one mu (and c, and the parameters of `terms`) to every impact at once.

    impacts: ConditionedImpacts, or records with force_n, velocity_m_s, sample_rate_hz (they
    are conditioned here). spec: what the fit frees and how it runs (`FitSpec`, whose fields
    may also be given as keywords, which change it: `fit_model(records, fit_damping=True)`).
    terms: names of model terms to fit (started at their defaults) or
    term instances (started at their values); fixed_effects: terms held as given. mu0: start
    value (default: the energy balance). fit_initial_position: also fit where each impact's
    mass rested before the hit (a nuisance parameter per impact, `initial_position_m[i]`):
    friction holds the FMM anywhere within +-mu N / k of centre after the previous hit, and
    the velocity alone does not say where; without it every impact starts at x = 0, as in
    the paper. fit_impulse_scale: also fit a factor on each hit's measured force
    (`impulse_scale[i]`, a nuisance parameter): a sampled, filtered, noisy force misstates the
    impulse by 1e-4 to 1e-2, which the decay, not the force, then decides; mu comes from the
    decay's shape alone. remove_mains_hum, fit_velocity_drift: estimate the mains hum (50 or
    60 Hz, or `mains_hz`) and a drifting velocity offset from the residual and take them off
    the measured velocity, refitting (`chain`); off by default, so that the diagnosis sees an
    offset as the `velocity_offset` it is. judge_hit: also judge the velocity inside each
    `ConditionedImpact.hit_windows` (off: it follows the force between its samples).
    uncertainty: 'spectral' or 'blocks' (`output_error.UNCERTAINTIES`). start_values: start
    values of fitted parameters by name (e.g. 'initial_position_m[0]'). term_bounds: the
    fitting range of a term's parameter by its full name ('stribeck.mu_static_excess'), in
    place of the term's declared plausible bounds (the diagnosis's `physical_ranges`); a fit
    that ends on one lists it in `ModelFit.at_bounds`. jacobian: 'blocks'
    (default) runs each impact's own parameters' Jacobian columns on that impact only;
    'dense' runs every column on every impact (same result, the reference).
    Raises ValueError for bad arguments and FitError when the fit does not converge, puts mu
    on a bound of mu_bounds, or leaves an impact unexplained.
    """
    return _fit(
        _conditioned_list(impacts),
        (spec or FitSpec()).but(**changes),
        rig=rig,
        mu0=mu0,
        terms=terms,
        fixed_effects=fixed_effects,
        start_values=start_values,
        term_bounds=term_bounds,
    ).fit


@dataclass(frozen=True)
class _Fitted:
    """A fit and what it was solved as: its parameter space, problem and last solution."""

    fit: ModelFit
    space: _Space
    problem: OutputError
    solution: LsqSolution


def _fit(
    conditioned: list[ConditionedImpact],
    spec: FitSpec,
    *,
    rig: Rig,
    mu0: float | None,
    terms: Sequence[str | ModelTerm],
    fixed_effects: Sequence[ModelTerm],
    start_values: Mapping[str, float] | None,
    start: tuple[np.ndarray, tuple[np.ndarray, ...]] | None = None,
    drift_estimated: bool = False,
    term_bounds: Mapping[str, tuple[float, float]] | None = None,
) -> _Fitted:
    """`fit_model` on conditioned impacts.

    start: the residual and each block's Jacobian rows at the start values, where another
    fit's solution has them (`fit_friction`'s per-impact fits): no model run is spent on them.
    drift_estimated: the velocities' drift was taken off by an earlier fit (its degrees of
    freedom count in the errors, as with fit_velocity_drift).
    """
    low, high = _checked_mu_bounds(conditioned, spec, rig)
    if spec.chain_starts:
        conditioned = chained_starts(conditioned)
    if any(impact.follows_previous for impact in conditioned):
        # A hit's own parameters (its impulse scale) move every later hit's start too.
        spec, start = spec.but(jacobian='dense'), None
    space = _space(
        rig,
        _start_mu(conditioned, rig, mu0, low, high),
        (low, high),
        spec.fit_damping,
        terms,
        fixed_effects,
        len(conditioned) if spec.starts == FITTED else 0,
        len(conditioned) if spec.fit_impulse_scale else 0,
        term_bounds,
    )
    _set_start_values(space, start_values)
    problem = OutputError(
        conditioned,
        space.build,
        spec.misfit,
        spec.band_limit_hz,
        spec.integrator,
        rig.natural_frequency_hz,
        judge_hit=spec.judge_hit,
        uncertainty=spec.uncertainty,
    )
    blocks = space.blocks(problem.segments, spec.jacobian)
    residual0, jacobian0 = None, None
    if start is not None:
        residual0, jacobian0 = start[0], BlockJacobian(blocks, start[1])
    solution = levenberg_marquardt(
        problem,
        space.start,
        space.lower,
        space.upper,
        space.typical,
        problem.size,
        blocks=blocks,
        residual0=residual0,
        jacobian0=jacobian0,
        threads=available_threads(),
    )
    chain = _VelocityChain(spec.remove_mains_hum, spec.fit_velocity_drift, spec.mains_hz)
    problem, solution, nuisances, projected = chain.fit(problem, solution, space, spec.jacobian)
    # Or rows handed in from a fit that took its drift off them, still the last Jacobian.
    projected = projected or (jacobian0 is not None and solution.jacobian is jacobian0)
    drift = spec.fit_velocity_drift or drift_estimated
    fit = _model_fit(space, problem, solution, nuisances, drift, projected)
    _require_explained(fit, solution, conditioned)
    _require_mu_inside_bounds(fit, low, high, conditioned)
    return _Fitted(fit, space, problem, solution)


def _checked_mu_bounds(
    conditioned: Sequence[ConditionedImpact], spec: FitSpec, rig: Rig
) -> tuple[float, float]:
    """The fit's mu search bounds, once the spec, the rig and the records are found fit to fit.

    Every option is checked before a model run is spent, so bad input fails at once with an
    error naming it rather than deep in the solver.
    """
    _check_options(rig, spec.misfit, spec.band_limit_hz, spec.integrator, spec.jacobian)
    uncertainty, mains_hz, mu_bounds = spec.uncertainty, spec.mains_hz, spec.mu_bounds
    if uncertainty not in UNCERTAINTIES:
        raise BadInputError(
            f'unknown uncertainty {uncertainty!r}; choose one of {", ".join(UNCERTAINTIES)}'
        )
    if mains_hz is not None and not mains_hz > 0:
        raise BadInputError(f'mains_hz must be > 0 (or None to find it), got {mains_hz}')
    low, high = (float(bound) for bound in mu_bounds)
    if not 0.0 <= low < high or not math.isfinite(high):
        raise BadInputError(f'mu_bounds must be 0 <= lower < upper, finite; got {mu_bounds}')
    require_positive('normal_force_n (to fit mu)', rig.normal_force_n)
    _check_durations(conditioned, rig)
    return low, high


def _start_mu(
    conditioned: Sequence[ConditionedImpact], rig: Rig, mu0: float | None, low: float, high: float
) -> float:
    """Where the mu search starts: mu0, else the energy balance's mu, else the paper's.

    It is kept 1 % of the bound span inside the bounds, so the search never starts on a bound.
    """
    if mu0 is None:
        mu0 = energy_balance_mu(conditioned, rig)
        if not math.isfinite(mu0):
            mu0 = PAPER_MU
    return min(max(float(mu0), low + 0.01 * (high - low)), high - 0.01 * (high - low))


def _set_start_values(space: _Space, start_values: Mapping[str, float] | None) -> None:
    """Start the named parameters at the values given, each clipped into its bounds.

    A name that is not fitted is refused rather than ignored, so a misspelt one is seen.
    """
    for name, value in (start_values or {}).items():
        if name not in space.names:
            raise BadInputError(f'start value for {name!r}, which is not fitted: {space.names}')
        at = space.names.index(name)
        space.start[at] = min(max(float(value), space.lower[at]), space.upper[at])


def _require_mu_inside_bounds(
    fit: ModelFit, low: float, high: float, conditioned: Sequence[ConditionedImpact]
) -> None:
    """Refuse a fit whose mu lies on its search bound: friction then does not explain the hits."""
    if 'mu' in fit.at_bounds:
        raise FitError(
            'mu_at_bound',
            f'the best-fit friction coefficient {fit.mu:.4g} lies on '
            f'its search bound [{low:g}, {high:g}]: friction does not explain the '
            'record(s) (no friction, or far more than the rig can show)',
            joined_sources(conditioned),
        )


@dataclass(frozen=True)
class _VelocityChain:
    """What the fit estimates of the velocity channel's chain: mains hum, offset and drift.

    `fit` alternates: the model is fitted, the nuisance estimated from measured minus
    modelled velocity (`chain.estimate_nuisance`) and taken off the measured velocity, and
    the model refitted from where it was, until the nuisance's change would move no
    parameter by more than `CHAIN_TOLERANCE` of its white-noise standard error (predicted
    from the last Jacobian, so a last refit that would change nothing is not run). Both
    estimates are linear in the residual, so each round estimates what is left in the
    current residual and adds it. The hum is orthogonal to the model's few-Hz motion and an
    offset nearly so: one refit (one Gauss-Newton step from the last Jacobian), rarely two.
    """

    hum: bool
    drift: bool
    mains_hz: float | None

    def fit(
        self, problem: OutputError, solution: LsqSolution, space: _Space, jacobian: str
    ) -> tuple[OutputError, LsqSolution, tuple[VelocityNuisance, ...], bool]:
        """The fit with the nuisance taken off.

        Returns the problem with the cleaned velocities, its solution, the nuisances, and
        whether the solution's Jacobian rows already have the drift projected out.
        """
        nuisances = tuple(
            VelocityNuisance(i.velocity_m_s.size, i.sample_rate_hz) for i in problem.impacts
        )
        if not (self.hum or self.drift):
            return problem, solution, nuisances, False
        time_misfit = problem.misfit == 'time'
        projected = None  # the Jacobian whose rows have the drift projected out
        for _ in range(CHAIN_ROUNDS):
            increments = tuple(
                estimate_nuisance(
                    residual,
                    impact.sample_rate_hz,
                    impact.velocity_noise_std_m_s,
                    hum=self.hum,
                    drift=self.drift,
                    mains_hz=total.mains_hz or self.mains_hz,  # once found, that one
                )
                for residual, impact, total in zip(
                    _time_residuals(problem, solution), problem.impacts, nuisances, strict=True
                )
            )
            if time_misfit and self.drift and solution.jacobian is not projected:
                # The drift is re-estimated with the parameters (variable projection): the
                # steps and the stop below use the Jacobian less its part along the drift.
                _project_drift(solution.jacobian, problem.impacts)
                solution = replace(solution, block_normals=solution.jacobian.block_normals())
                projected = solution.jacobian

            # Each change is made when wanted (30 records' at once would be 80 MB).
            def changes(increments=increments):
                return (increment.values_m_s for increment in increments)

            small = all(
                math.sqrt(inner(change, change) / change.size)
                < CHAIN_FLOOR * impact.velocity_noise_std_m_s
                for change, impact in zip(changes(), problem.impacts, strict=True)
            )
            negligible = time_misfit and _negligible(solution, problem.segments, changes())
            if negligible and small:  # nothing worth taking off the velocities as they are
                return problem, solution, nuisances, solution.jacobian is projected
            nuisances = tuple(
                total.plus(increment)
                for total, increment in zip(nuisances, increments, strict=True)
            )
            residual0 = solution.residual if time_misfit else None
            cleaned = []
            for impact, segment, change in zip(
                problem.impacts, problem.segments, changes(), strict=True
            ):
                cleaned.append(replace(impact, velocity_m_s=impact.velocity_m_s - change))
                if time_misfit:  # where it was, the residual falls by the change (in place:
                    residual0[segment] -= change  # the old solution is not used again)
            problem = problem.with_impacts(cleaned)
            if time_misfit:
                problem.clear_hit_windows(residual0)
            if negligible:
                cost = inner(residual0, residual0)
                solution = replace(solution, residual=residual0, cost=cost)
                return problem, solution, nuisances, solution.jacobian is projected
            solution = levenberg_marquardt(
                problem,
                solution.x,
                space.lower,
                space.upper,
                space.typical,
                problem.size,
                blocks=space.blocks(problem.segments, jacobian),
                residual0=residual0,
                jacobian0=solution.jacobian if time_misfit else None,
                threads=available_threads(),
            )
        return problem, solution, nuisances, solution.jacobian is projected


def _project_drift(jacobian: BlockJacobian, impacts: Sequence[ConditionedImpact]) -> None:
    """Take each block's part along its impact's drift basis off its Jacobian rows, in place."""
    for rows, impact in zip(jacobian.rows, impacts, strict=True):
        DriftBasis.of(rows.shape[1], impact.sample_rate_hz).remove(rows)


CHAIN_FLOOR = 0.01
"""A nuisance estimate whose change is below this fraction of the noise (RMS) everywhere,
and would move no parameter, is not taken off: the velocities are used as they are."""


CHAIN_ROUNDS = 3
"""Most refits `_VelocityChain` runs after the first fit."""


CHAIN_TOLERANCE = 0.05
"""A nuisance change that would move no parameter by this much of its white-noise standard
error is taken without refitting."""


def _time_residuals(problem: OutputError, solution: LsqSolution) -> list[np.ndarray]:
    """Measured minus modelled velocity per impact at a solution."""
    if problem.misfit == 'time':
        return [solution.residual[segment] for segment in problem.segments]
    return list(problem.time_residuals(solution.x))


def _negligible(
    solution: LsqSolution, segments: Sequence[slice], changes: Iterable[np.ndarray]
) -> bool:
    """Whether taking `changes` off the measured velocities would leave the fit where it is.

    The residuals fall by the changes: the Gauss-Newton step from there, (J J^T)^-1 J r with
    the solution's Jacobian (the drift projected out where it is fitted, so the step is the
    one the drift's own re-estimate allows), compared with the white-noise standard errors.
    """
    jacobian = solution.jacobian
    gradient = np.zeros(jacobian.blocks.n_parameters)
    for indices, rows, segment, change in zip(
        jacobian.blocks.parameters, jacobian.rows, segments, changes, strict=True
    ):
        gradient[indices] += inner(rows, solution.residual[segment]) - inner(rows, change)
    inverse = normal_inverse(jacobian.normal(solution.block_normals))
    finite = np.isfinite(np.diag(inverse))
    inverse = np.where(np.isfinite(inverse), inverse, 0.0)
    step = inverse @ gradient
    variance = solution.cost / max(solution.residual.size - step.size, 1) * np.diag(inverse)
    with np.errstate(divide='ignore', invalid='ignore'):
        moved = np.abs(step[finite]) / np.sqrt(variance[finite])
    return bool(np.all(np.nan_to_num(moved, nan=0.0) < CHAIN_TOLERANCE))


def _model_fit(
    space: _Space,
    problem: OutputError,
    solution: LsqSolution,
    nuisances: tuple[VelocityNuisance, ...],
    drift: bool,
    projected: bool,
) -> ModelFit:
    uncertainty = fit_uncertainty(
        solution, problem, force_noise=not space.impulse_scales, drift=drift, projected=projected
    )
    model = problem.model(solution.x)
    # The hit windows too, in the solution's own residual (its last use as the misfit's).
    residuals = problem.time_residuals(solution.x, solution.residual)
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
        impulse_scales=tuple(model.impulse_scale(index) for index in range(len(impacts))),
        velocity_nuisance=nuisances,
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
        raise BadInputError('no impacts to fit')
    return conditioned


def _check_options(
    rig: Rig, misfit: str, band_limit_hz: float, integrator: str, jacobian: str
) -> None:
    if not isinstance(rig, Rig):
        raise BadInputError(f'rig must be a Rig, got {rig!r}')
    if misfit not in MISFITS:
        raise BadInputError(f'unknown misfit {misfit!r}; choose one of {", ".join(MISFITS)}')
    require_positive('band_limit_hz', band_limit_hz)
    if integrator not in INTEGRATORS:
        raise BadInputError(
            f'unknown integrator {integrator!r}; choose one of {", ".join(INTEGRATORS)}'
        )
    if jacobian not in JACOBIANS:
        raise BadInputError(f'unknown jacobian {jacobian!r}; choose one of {", ".join(JACOBIANS)}')


def _check_durations(impacts: Sequence[ConditionedImpact], rig: Rig) -> None:
    period_s = 1.0 / rig.natural_frequency_hz
    for impact in impacts:
        if impact.duration_s < 2.0 * period_s:
            raise BadInputError(
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


def _own_fit(joint: _Fitted, index: int, spec: FitSpec) -> ModelFit:
    """Impact `index` fitted alone: mu (c and terms held at the joint values), its start, scale.

    It continues from the joint solution, where this impact's residual and its Jacobian rows
    for mu, start and scale are already known (its own block of the joint Jacobian), on the
    velocity the joint fit cleaned (its hum and drift are not estimated again; its errors
    count the drift's degrees of freedom): usually one Gauss-Newton step, one model run.
    """
    solution = joint.solution
    block = solution.jacobian.blocks.parameters[index]
    wanted = ['mu'] + [
        name
        for name in (f'initial_position_m[{index}]', f'impulse_scale[{index}]')
        if name in joint.space.names
    ]
    rows = [int(np.flatnonzero(block == joint.space.names.index(name))[0]) for name in wanted]
    residual = solution.residual[joint.problem.segments[index]].copy()  # taken over by the fit
    for start, stop in joint.problem.impacts[index].hit_windows:  # the misfit's, not the fit's
        residual[start:stop] = 0.0
    own = spec.but(
        fit_damping=False,
        remove_mains_hum=False,
        fit_velocity_drift=False,
        fit_initial_position=spec.starts == FITTED,
        chain_starts=False,
    )
    impact = joint.problem.impacts[index]
    start = (residual, (solution.jacobian.rows[index][rows],))
    if impact.follows_previous:
        # Alone, a chained hit starts where the joint chain put it; its joint rows moved its
        # start with mu and the earlier hits' scales too, so they are no start for this fit.
        start_m = joint.fit.initial_positions_m[index]
        impact, start = replace(impact, start_m=start_m, follows_previous=False), None
    return _fit(
        [impact],
        own,
        rig=joint.fit.rig,
        mu0=joint.fit.mu,
        terms=(),
        fixed_effects=joint.fit.effects,
        start_values={
            name.replace(f'[{index}]', '[0]'): joint.fit.value(name) for name in wanted[1:]
        },
        start=start,
        drift_estimated=spec.fit_velocity_drift,
    ).fit


def fit_friction(
    impacts: Sequence,
    spec: FitSpec | None = None,
    *,
    rig: Rig = FMM_RIG,
    progress: Callable[[str], None] | None = None,
    **changes: Any,
) -> FrictionFit:
    """The paper's fit: one mu (and optionally c) over all impacts, plus each impact's own mu.

    The records as a data acquisition delivers them: by default (`FRICTION_FIT`) each hit's
    impulse scale is fitted and mains hum, velocity offset and drift are taken off (spec and
    keyword changes as in `fit_model`); each impact's own fit continues from the joint
    solution (`_own_fit`).
    progress, when given, is told of each fit as it starts (a line of text).
    Raises ValueError for bad input and FitError (naming the impact) for any impact, or the
    set, that friction cannot explain.
    """
    say = progress or (lambda _: None)
    conditioned = _conditioned_list(impacts)
    spec = (spec or FRICTION_FIT).but(**changes)
    count = len(conditioned)
    say(f'fitting one mu to {count} impact{"s" if count > 1 else ""}')
    fitted = _fit(
        conditioned, spec, rig=rig, mu0=None, terms=(), fixed_effects=(), start_values=None
    )
    joint = fitted.fit
    if count == 1 and not spec.fit_damping:
        per_impact = (joint,)
    else:
        fits = []
        for index in range(count):
            say(f'fitting mu of impact {index + 1}/{count} alone')
            fits.append(_own_fit(fitted, index, spec))
        per_impact = tuple(fits)
    mus = np.array([fit.mu for fit in per_impact])
    errors = np.array([fit.mu_stderr for fit in per_impact])
    chi2 = float(np.sum(((mus - joint.mu) / errors) ** 2))
    dof = len(per_impact) - 1
    p_value = float(chi2_sf(chi2, dof)) if dof > 0 else math.nan
    return FrictionFit(
        joint=joint,
        per_impact=per_impact,
        consistency_chi2=chi2,
        consistency_p_value=p_value,
        impulses_n_s=tuple(impact.impulse_n_s for impact in conditioned),
    )
