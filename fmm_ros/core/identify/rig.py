"""Rig identification (the paper's Sec. 4): m, c, k with the friction contact lifted.

`identify_rig` fits m, c, k to impacts with the contact lifted (mu = 0), driven by the
measured force, as (m, f_n, zeta), which are nearly orthogonal where (m, c, k) follow a curved
valley; `fit_free_decay` fits f_n and zeta to a free decay (no force) by variable projection.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from fmm_ros.constants import MISFIT_BAND_LIMIT_HZ
from fmm_ros.core._checks import require_positive
from fmm_ros.core.identify.conditioning import (
    ConditionedImpact,
    as_conditioned,
    checked_channel,
    velocity_noise_std,
)
from fmm_ros.core.identify.friction import (
    MIN_DECAY_CROSSINGS,
    MIN_EXPLAINED_FRACTION,
    joined_sources,
    unexplained_message,
)
from fmm_ros.core.identify.lsq import (
    Blocks,
    LsqSolution,
    inner,
    levenberg_marquardt,
)
from fmm_ros.core.identify.output_error import (
    BuiltModel,
    OutputError,
    block_score,
    fit_uncertainty,
    sandwich_uncertainty,
)
from fmm_ros.core.physics.model import INTEGRATORS
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.errors import BadInputError, FitError


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
    velocity = checked_channel('velocity_m_s', velocity_m_s, source)
    require_positive('sample_rate_hz', sample_rate_hz)
    if start_index is None:
        magnitude = np.abs(velocity)
        start_index = int(np.argmax(magnitude >= 0.5 * magnitude.max()))
    if not 0 <= start_index < velocity.size:
        raise BadInputError(
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
    period = max(1, round(sample_rate_hz / solution.x[0]))
    uncertainty = sandwich_uncertainty(
        solution, [block_score(solution.jacobian.rows[0], solution.residual, period)]
    )
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
        raise BadInputError(
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
        raise BadInputError('no records to identify the rig from')
    if impacts:
        return _rig_from_impacts(impacts, tuple(decays), integrator)
    if mass_kg is None:
        raise BadInputError('free decays alone do not determine the mass: give mass_kg')
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

    def build(theta: np.ndarray) -> BuiltModel:
        mass, stiffness, damping = _rig_constants(theta, np.zeros((3, 3)))[0]
        return BuiltModel(Rig(mass, stiffness, damping, 0.0), 0.0, ())

    problem = OutputError(impacts, build, 'time', MISFIT_BAND_LIMIT_HZ, integrator, frequency0)
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
        joined_sources(impacts),
    )
    uncertainty = fit_uncertainty(solution, problem)
    values, errors = _rig_constants(solution.x, uncertainty.covariance)
    residuals = [solution.residual[segment] for segment in problem.segments]
    for impact, r in zip(impacts, residuals, strict=True):
        explained = 1.0 - inner(r, r) / inner(impact.velocity_m_s, impact.velocity_m_s)
        if explained < MIN_EXPLAINED_FRACTION:
            raise FitError(
                'unexplained',
                unexplained_message('linear oscillator', explained)
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
