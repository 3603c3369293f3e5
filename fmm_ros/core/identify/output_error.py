"""The output-error problem: a parameter vector in, each impact's residual block out.

`OutputError` drives the model with every impact's conditioned force (one simulation buffer
shared by all impacts) and returns measured minus simulated velocity, or the mobility misfit
up to `band_limit_hz`, one block per impact, for `fmm_ros.core.identify.lsq`.

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
"""

import math
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.fft

from fmm_ros._lazy import LazyModule
from fmm_ros.core.identify.chain import DriftBasis
from fmm_ros.core.identify.conditioning import ConditionedImpact, source_prefix
from fmm_ros.core.identify.lsq import (
    LsqSolution,
    inner,
    normal_inverse,
)
from fmm_ros.core.physics.model import Simulation, simulate
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.physics.terms import ModelTerm
from fmm_ros.core.signal.frf import band_bins, mobility, spectra
from fmm_ros.errors import BadInputError, Infeasible

signal = LazyModule('scipy.signal')


@dataclass(frozen=True)
class BuiltModel:
    """What a parameter vector stands for: the model, and each impact's initial position."""

    rig: Rig
    mu: float
    effects: tuple[ModelTerm, ...]
    initial_positions_m: tuple[float, ...] = ()
    """Per impact [m]; empty: every impact starts at x = 0."""
    impulse_scales: tuple[float, ...] = ()
    """Per impact, the factor on its measured hit [-]; empty: every hit as measured."""

    def initial_position_m(self, index: int) -> float:
        """Where impact `index` starts [m]."""
        return self.initial_positions_m[index] if self.initial_positions_m else 0.0

    def impulse_scale(self, index: int) -> float:
        """The factor on impact `index`'s measured hit [-]."""
        return self.impulse_scales[index] if self.impulse_scales else 1.0


ModelBuilder = Callable[[np.ndarray], BuiltModel]
"""theta -> the model a parameter vector stands for."""


class _Lane:
    """One thread's buffers for `OutputError`: a run's output and the force that drives it."""

    def __init__(self, longest: int) -> None:
        self.output = np.empty((2, longest))
        # The force that drives a run: zero but for one impact's gates, scaled (`drive`).
        self.force = np.zeros(longest)
        self.driving: tuple[int, float] | None = None


class OutputError:
    """Residuals of the model driven by each impact's conditioned force, stacked over impacts.

    Time misfit: measured minus simulated velocity, every sample. FRF misfit: measured minus
    simulated mobility, (V_meas - V_model) / F, on the bins from DC to band_limit_hz, real and
    imaginary parts interleaved. Each impact is a block of residuals (`_lsq.Blocks`): a call
    runs one simulation for each impact asked for, into buffers allocated once a thread and
    shared by its runs (each run is consumed before the next), so threads may evaluate
    disjoint blocks at once (`levenberg_marquardt(threads=...)`).
    """

    def __init__(
        self,
        impacts: Sequence[ConditionedImpact],
        build: ModelBuilder,
        misfit: str,
        band_limit_hz: float,
        integrator: str,
        natural_frequency_hz: float,
        *,
        judge_hit: bool = False,
        uncertainty: str = 'spectral',
    ) -> None:
        self.impacts = tuple(impacts)
        self.build = build
        self.misfit = misfit
        self.integrator = integrator
        self.band_limit_hz = band_limit_hz
        self.natural_frequency_hz = natural_frequency_hz
        self.judge_hit = judge_hit
        self.uncertainty = uncertainty
        self._longest = max(impact.force_n.size for impact in self.impacts)
        self._lanes = threading.local()
        self._chained = any(impact.follows_previous for impact in self.impacts[1:])
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
                    raise BadInputError(
                        f'{source_prefix(impact.source)}the force spectrum is zero inside '
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

    def with_impacts(self, impacts: Sequence[ConditionedImpact]) -> 'OutputError':
        """The same problem over other impacts (the same records with a cleaned velocity)."""
        return OutputError(
            impacts,
            self.build,
            self.misfit,
            self.band_limit_hz,
            self.integrator,
            self.natural_frequency_hz,
            judge_hit=self.judge_hit,
            uncertainty=self.uncertainty,
        )

    def _lane(self) -> '_Lane':
        """The calling thread's buffers, made on its first run."""
        lane = getattr(self._lanes, 'lane', None)
        if lane is None:
            lane = self._lanes.lane = _Lane(self._longest)
        return lane

    def model(self, theta: np.ndarray) -> BuiltModel:
        """The model at theta, or Infeasible where it cannot be built.

        Unless theta holds the starts, each impact starts where `starts` puts it.
        """
        return self._placed(self._built(theta))

    def _placed(self, model: BuiltModel) -> BuiltModel:
        """The model with its starts: theta's own, or those `starts` gives."""
        if model.initial_positions_m:
            return model
        return replace(model, initial_positions_m=self.starts(model))

    def _built(self, theta: np.ndarray) -> BuiltModel:
        """The model theta builds, its starts as theta has them (Infeasible if it cannot)."""
        try:
            return self.build(theta)
        except ValueError as error:
            raise Infeasible(str(error)) from None

    def starts(self, model: BuiltModel) -> tuple[float, ...]:
        """Where each impact starts in this model [m].

        At its `start_m`, or, when it `follows_previous`, where the model's own run of the
        impact before it came to rest.

        The model's rest, not the measured one: the integral of a measured velocity wanders
        with its low-frequency noise by more than a friction asymmetry shifts the rest (pink
        noise: 1e-4 m over a 12 s record, against 1e-5 to 7e-5 m), while inside one model
        the chain is exact.
        """
        starts: list[float] = []
        for index, impact in enumerate(self.impacts):
            if not (impact.follows_previous and index):
                starts.append(impact.start_m)
                continue
            run = self.simulate(index - 1, replace(model, initial_positions_m=tuple(starts)))
            starts.append(run.end_position_m)
        return tuple(starts)

    def __call__(
        self, theta: np.ndarray, blocks: Sequence[int], outs: Sequence[np.ndarray]
    ) -> None:
        """The residuals of the impacts `blocks` at theta, into outs (a BlockResidualFunction).

        With chained starts, the impacts up to the last asked for run in order, each once: an
        asked impact's residual run is also where the next one starts.
        """
        model = self._built(theta)
        if model.initial_positions_m or not self._chained:
            model = self._placed(model)
            for index, out in zip(blocks, outs, strict=True):
                self.impact_residual(index, model, out)
            return
        wanted = dict(zip(blocks, outs, strict=True))
        starts: list[float] = []
        end = math.nan
        for index, impact in enumerate(self.impacts[: max(blocks) + 1]):
            chained = impact.follows_previous and index
            starts.append(end if chained else impact.start_m)
            here = replace(model, initial_positions_m=tuple(starts))
            if index in wanted:
                end = self.impact_residual(index, here, wanted[index]).end_position_m
            elif index < max(blocks) and self.impacts[index + 1].follows_previous:
                end = self.simulate(index, here).end_position_m

    def impact_residual(
        self, index: int, model: BuiltModel, out: np.ndarray, force_scale: float = 1.0
    ) -> Simulation:
        """One impact's residual segment into out, and its run (valid until the next run).

        force_scale multiplies its force (a sensitivity).
        """
        impact = self.impacts[index]
        force = self.drive(index, model.impulse_scale(index) * force_scale)
        run = self.simulate(index, model, force)
        velocity = run.velocity_m_s
        if self.misfit == 'time':
            np.subtract(impact.velocity_m_s, velocity, out=out)
            if not self.judge_hit:
                _clear_hit_windows(impact, out)
            return run
        target = self.targets[index]
        spectrum = scipy.fft.rfft(velocity)[: target.size]
        spectrum *= self.inverse_force[index]
        residual = out.view(complex)
        np.subtract(target, spectrum, out=residual)
        residual /= force_scale  # the measured mobility's denominator scales with the force
        return run

    def drive(self, index: int, scale: float) -> np.ndarray:
        """Impact `index`'s conditioned force times `scale`, in this thread's force buffer.

        The conditioned force is zero outside its gates, so only the gates are written (and
        the previous impact's cleared): a few dozen samples, not the record.
        """
        impact = self.impacts[index]
        lane = self._lane()
        if lane.driving != (index, scale):
            if lane.driving is not None:
                for start, stop in self.impacts[lane.driving[0]].gate:
                    lane.force[start:stop] = 0.0
            for start, stop in impact.gate:
                np.multiply(impact.force_n[start:stop], scale, out=lane.force[start:stop])
            lane.driving = (index, scale)
        return lane.force[: impact.force_n.size]

    def simulate(
        self, index: int, model: BuiltModel, force_n: np.ndarray | None = None, samples: int = 0
    ) -> Simulation:
        """Run one impact (or force_n in its place) through the model into this thread's buffer.

        samples: run only the first this many (the model is causal: they are the whole
        run's); 0 for all.
        """
        impact = self.impacts[index]
        n = samples or impact.force_n.size
        if force_n is None:
            force_n = self.drive(index, model.impulse_scale(index))
        output = self._lane().output
        try:
            return simulate(
                force_n[:n],
                impact.sample_rate_hz,
                rig=model.rig,
                mu=model.mu,
                effects=model.effects,
                x0_m=model.initial_position_m(index),
                integrator=self.integrator,
                out=(output[0, :n], output[1, :n]),
            )
        except ValueError as error:  # e.g. a term that makes one direction's friction < 0
            raise Infeasible(str(error)) from None

    def clear_hit_windows(self, residual: np.ndarray) -> np.ndarray:
        """Zero the hit windows of a stacked time residual (in place), as the misfit has it."""
        if self.judge_hit:
            return residual
        for impact, segment in zip(self.impacts, self.segments, strict=True):
            _clear_hit_windows(impact, residual[segment])
        return residual

    def time_residuals(
        self, theta: np.ndarray, residual: np.ndarray | None = None
    ) -> tuple[np.ndarray, ...]:
        """Measured minus simulated velocity of every impact at theta, every sample [m/s].

        The hit windows included (which the time misfit leaves out). residual: the time
        misfit's own stacked residual at theta, if at hand and no longer needed as it is:
        then only the start of each record, up to its last hit window, is run again, the
        windows are filled in in place, and its segments are returned (no copy of a 2.6 MB
        record each); otherwise fresh arrays.
        """
        model = self.model(theta)
        residuals = []
        for index, impact in enumerate(self.impacts):
            if residual is None or self.misfit != 'time':
                run = self.simulate(index, model).velocity_m_s
                residuals.append(impact.velocity_m_s - run)
                continue
            own = residual[self.segments[index]]
            windows = impact.hit_windows
            run = self.simulate(index, model, samples=windows[-1][1]).velocity_m_s
            for start, stop in windows:
                own[start:stop] = impact.velocity_m_s[start:stop] - run[start:stop]
            residuals.append(own)
        return tuple(residuals)

    def scores(self, solution: LsqSolution) -> list[np.ndarray]:
        """Each block's score covariance at a solution (`sandwich_uncertainty`).

        In time from the residual's spectrum (`spectral_score`), for the FRF misfit (and with
        uncertainty='blocks', the reference method) from block sums over a natural period
        or f_n/4 of bins (`block_score`).
        """
        scores = []
        for index, (segment, rows, normal) in enumerate(
            zip(self.segments, solution.jacobian.rows, solution.block_normals, strict=True)
        ):
            residual = solution.residual[segment]
            if self.misfit == 'time' and self.uncertainty == 'spectral':
                impact = self.impacts[index]
                white = impact.velocity_noise_std_m_s**2
                scores.append(spectral_score(rows, residual, white, impact.sample_rate_hz, normal))
            else:
                scores.append(block_score(rows, residual, self.block_lengths[index]))
        return scores

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


def _clear_hit_windows(impact: ConditionedImpact, residual: np.ndarray) -> None:
    """Zero one impact's time residual where the fit does not judge it (the hit windows)."""
    for start, stop in impact.hit_windows:
        residual[start:stop] = 0.0


@dataclass(frozen=True)
class Uncertainty:
    """A fit's parameter covariance, its standard errors, and the white-noise ones beside them."""

    covariance: np.ndarray
    stderr: np.ndarray
    stderr_white: np.ndarray
    stderr_force: np.ndarray


def block_score(rows: np.ndarray, residual: np.ndarray, block: int) -> np.ndarray:
    """Sum over blocks of `block` residuals of the score's outer product, (p, p).

    The score J_i r_i is summed over each block first, so residuals correlated within a
    block count as they do in the fit (a natural period in time, f_n/4 of bins in frequency).
    """
    contributions = rows * residual
    sums = np.add.reduceat(contributions, np.arange(0, contributions.shape[1], block), axis=1)
    return sums @ sums.T


def spectral_score(
    rows: np.ndarray,
    residual: np.ndarray,
    white_variance: float,
    sample_rate_hz: float,
    normal: np.ndarray | None = None,
) -> np.ndarray:
    """Covariance of the score J r for stationary noise of the residual's own spectrum, (p, p).

    var(sum_i J_i e_i) = sum_ij J_i J_j gamma(i - j) = integral of |J(f)|^2 P(f) df, P the
    noise's power spectral density, estimated (Welch) from the residual of the whole record:
    the rest before and after the motion shows the chain's noise as well as the motion does,
    and a record holds tens of seconds of it, so the estimate is steady where block sums over
    the few seconds of motion scatter by tens of per cent. Done on `SPECTRAL_RATE_HZ` block
    means (J's content is the rig's few Hz and its harmonics), plus the white noise's share of
    what the block means smooth away (J's variation inside a block: the hit's fast edge).
    normal: rows @ rows.T where at hand.
    """
    p, n = rows.shape
    factor = max(1, int(sample_rate_hz // SPECTRAL_RATE_HZ))
    m = n // factor
    total = white_variance * (inner(rows, rows) if normal is None else normal)
    segment = 1 << max(4, math.ceil(math.log2(SPECTRAL_SEGMENT_S * sample_rate_hz / factor)))
    if m < 2 * segment:
        return total
    weights = np.full(factor, 1.0 / factor)
    means = np.einsum('pmf,f->pm', rows[:, : m * factor].reshape(p, m, factor), weights)
    residual_means = np.einsum('mf,f->m', residual[: m * factor].reshape(m, factor), weights)
    frequency, one_sided = signal.welch(residual_means, nperseg=segment)
    density = 0.5 * one_sided  # two-sided; welch doubles all but DC and Nyquist
    density[0] = one_sided[0]
    density[-1] = one_sided[-1]
    transform = scipy.fft.rfft(means, axis=1)
    density_at = np.interp(np.arange(transform.shape[1]) / m, frequency, density)
    density_at[1 : (m + 1) // 2] *= 2.0  # the negative frequencies
    weighted = transform * density_at
    coloured = (factor * factor / m) * (weighted @ transform.conj().T).real
    return total - white_variance * factor * inner(means, means) + coloured


SPECTRAL_RATE_HZ = 500.0
"""Rate of the block means `spectral_score` estimates the coloured noise at [Hz]: the rig's
mode and the odd harmonics friction gives it (to ~100 Hz) lie well below its Nyquist."""


SPECTRAL_SEGMENT_S = 4.0
"""Welch segment of `spectral_score` [s]: 0.25 Hz resolution, ~15 averages in 33 s."""


def sandwich_uncertainty(
    solution: LsqSolution,
    scores: Sequence[np.ndarray],
    impulse_terms: Iterable[tuple[int, np.ndarray, float]] = (),
) -> Uncertainty:
    """Covariance of a fit: the velocity residuals' sandwich plus force noise (module doc).

    scores: per block of the Jacobian (`_lsq.Blocks`), the covariance of its score J_k r_k
    over the parameters the block depends on (`block_score`, `spectral_score`). The sandwich
    (J J^T)^-1 S (J J^T)^-1 is scaled up where it falls below the white-noise covariance (it
    cannot be more precise than white noise allows). The force part propagates each impact's
    impulse uncertainty through the fit: d theta / d I = -(J J^T)^-1 J (d r / d I);
    impulse_terms: (block, d r / d I on it, impulse std). Both pieces are summed block by
    block over the parameters each block depends on.
    """
    jacobian, residual = solution.jacobian, solution.residual
    blocks = jacobian.blocks
    p = blocks.n_parameters
    inverse = normal_inverse(jacobian.normal(solution.block_normals))
    white = solution.cost / max(residual.size - p, 1) * inverse
    # A parameter the residuals do not depend on has infinite variance (normal_inverse); the
    # products below run on the finite part (inf x 0 would make its row and column NaN) and
    # the infinity is put back on the diagonal at the end.
    dead = ~np.isfinite(np.diag(inverse))
    inverse = np.where(np.isfinite(inverse), inverse, 0.0)
    score = np.zeros((p, p))
    for indices, block_score_ in zip(blocks.parameters, scores, strict=True):
        score[np.ix_(indices, indices)] += block_score_
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
    return Uncertainty(
        covariance,
        np.sqrt(np.diag(covariance)),
        np.sqrt(np.diag(white)),
        np.sqrt(np.diag(force_part)),
    )


def fit_uncertainty(
    solution: LsqSolution,
    problem: OutputError,
    force_noise: bool = True,
    drift: bool = False,
    projected: bool = False,
) -> Uncertainty:
    """`sandwich_uncertainty` of an output-error fit, force noise included unless told not to.

    force_noise=False where the fit has its own parameter for each hit's impulse: the noise's
    effect on the impulse is then part of what the fit estimates, not an error beside it.
    drift: each impact's velocity drift was estimated too (`chain.DriftBasis`), so the
    Jacobian's part along its basis carries no information: it is projected out first (time
    misfit), as a joint fit of the drift would, in the solution's own Jacobian rows (their
    last use; 2.6 MB a row and impact are not copied); projected: they already were.
    """
    if drift and not projected and problem.misfit == 'time':  # in place: the rows' last use
        for rows, impact in zip(solution.jacobian.rows, problem.impacts, strict=True):
            DriftBasis.of(rows.shape[1], impact.sample_rate_hz).remove(rows)
        solution = replace(solution, block_normals=solution.jacobian.block_normals())
    scores = problem.scores(solution)
    if not force_noise:
        return sandwich_uncertainty(solution, scores)
    stds = [impact.impulse_std_n_s for impact in problem.impacts]
    terms = zip(
        range(len(stds)),
        problem.impulse_jacobians(solution.x, solution.residual),
        stds,
        strict=True,
    )
    return sandwich_uncertainty(solution, scores, terms)
