"""Levenberg-Marquardt for the fitter's tall problems: a few parameters, up to ~10^6 residuals.

Why not scipy.optimize.least_squares: its trust-region solver works on the full (residuals x
parameters) Jacobian at every step (SVDs, products, quadratic evaluations) through BLAS, whose
threads stall when the shared cores are busy. Measured on three 33 s impacts, mu and c: 171 ms
with one BLAS thread, 398 ms with the default threads, against 67 ms here; for mu alone on
one impact it is as fast as this (14-17 ms against 20 ms with the standard errors). Here the
Jacobian is formed once per iteration by forward differences into a reused (p, n) block, the
long products run in einsum (`inner`), only the p x p normal equations are solved, the stop is
statistical (a step worth < 1e-3 of the residual variance) and a model that cannot be built
at a trial point is a rejected step rather than an error.

Box bounds are kept by clipping each trial point and freezing, for that step, any parameter
that sits on a bound with the gradient pushing it out (a minimal active set). A trial point at
which the model cannot be built (`Infeasible`) is treated like one that raised the cost.

Block structure (`Blocks`): the residuals come in blocks (the fitter's: one impact each), and
block k depends only on some of the parameters (the fitter's: the global ones, mu, c, the
terms, and that impact's own start position). A Jacobian column is then computed only on the
blocks it touches (a start position re-simulates its own impact, not all of them), stored as
one (parameters of k, samples of k) array a block (`BlockJacobian`), and the p x p normal
matrix and gradient are summed block by block. On 30 impacts of 330,000 samples with mu and
30 start positions that is 60 runs a Jacobian instead of 930 and 2 rows a sample instead of
31 (160 MB instead of 2.5 GB). `Blocks.shared` (every block depends on every parameter) is
the plain dense Jacobian, cut into blocks.
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.core._threads import thread_map
from fmm_ros.errors import BadInputError, Infeasible


def inner(a: np.ndarray, b: np.ndarray) -> np.ndarray | float:
    """Products over the last (sample) axis, a . b or a @ b.T, by einsum's own loop, not BLAS.

    OpenBLAS splits long products across threads; on this shared two-core machine, loaded by
    other jobs, a 330,000-sample dot product took 16 ms that way against 0.08 ms in einsum,
    and a one-impact fit 150 ms against 40 ms. Vectors give a float, (p, n) rows an array.
    """
    if a.ndim == 1 and b.ndim == 1:
        return float(np.einsum('i,i->', a, b))
    if a is b and a.ndim == 2:  # a Gram matrix: its upper triangle, pair by pair (40 % less)
        gram = np.empty((a.shape[0], a.shape[0]))
        for i in range(a.shape[0]):
            for k in range(i, a.shape[0]):
                gram[i, k] = gram[k, i] = np.einsum('j,j->', a[i], a[k])
        return gram
    return np.einsum('...j,kj->...k' if b.ndim == 2 else '...j,j->...', a, b)


ResidualFunction = Callable[[np.ndarray, np.ndarray], None]
"""fun(x, out): write the residuals at parameters x into out; raise Infeasible if it cannot."""

BlockResidualFunction = Callable[[np.ndarray, Sequence[int], Sequence[np.ndarray]], None]
"""fun(x, blocks, outs): write the residuals of each block in blocks at x into the matching
out; raise Infeasible if it cannot."""


def _run_blocks(
    fun: BlockResidualFunction,
    x: np.ndarray,
    which: Sequence[int],
    outs: Sequence[np.ndarray],
    threads: int,
) -> None:
    """Run fun over some blocks, shared out between threads (each a share of the blocks).

    An Infeasible from any share is raised here, after every share has finished (no thread
    still writes into outs: `thread_map`).
    """
    shares = max(1, min(threads, len(which)))
    thread_map(
        lambda share: fun(x, which[share::shares], outs[share::shares]), range(shares), threads
    )


@dataclass(frozen=True)
class Blocks:
    """Which parameters each block of residuals depends on (the Jacobian's non-zero pattern).

    Block k is the residual slice segments[k]; its residuals depend only on the parameters
    whose indices are in parameters[k] (ascending), so d r_k / d x_j is zero for any other j.
    """

    segments: tuple[slice, ...]
    parameters: tuple[np.ndarray, ...]
    n_parameters: int

    def __post_init__(self) -> None:
        if len(self.segments) != len(self.parameters):
            raise BadInputError(
                f'{len(self.segments)} segments but {len(self.parameters)} '
                'parameter lists: one a block'
            )
        for indices in self.parameters:
            if indices.size and (
                np.any(np.diff(indices) <= 0) or indices[0] < 0 or indices[-1] >= self.n_parameters
            ):
                raise BadInputError(
                    f'block parameters {indices} are not ascending indices below '
                    f'{self.n_parameters}'
                )

    @classmethod
    def shared(cls, segments: Sequence[slice], n_parameters: int) -> 'Blocks':
        """Every block depends on every parameter: the dense Jacobian, cut into blocks."""
        return cls.global_and_local(segments, n_parameters, [()] * len(segments))

    @classmethod
    def global_and_local(
        cls, segments: Sequence[slice], n_global: int, local: Sequence[Sequence[int]]
    ) -> 'Blocks':
        """Parameters 0..n_global-1 touch every block; block k also has its own local[k]."""
        shared = np.arange(n_global)
        parameters = tuple(np.concatenate((shared, np.asarray(own, dtype=int))) for own in local)
        n_parameters = n_global + sum(len(own) for own in local)
        return cls(tuple(segments), parameters, n_parameters)

    def touched_by(self, j: int) -> tuple[tuple[int, int], ...]:
        """(block, row) of every block that parameter j moves, row its place in that block."""
        touched = []
        for k, indices in enumerate(self.parameters):
            row = int(np.searchsorted(indices, j))
            if row < indices.size and indices[row] == j:
                touched.append((k, row))
        return tuple(touched)

    def empty_jacobian(self) -> 'BlockJacobian':
        """A Jacobian of this block pattern, its blocks allocated once and reused."""
        return BlockJacobian(
            self,
            tuple(
                np.empty((indices.size, segment.stop - segment.start))
                for segment, indices in zip(self.segments, self.parameters, strict=True)
            ),
        )


@dataclass(frozen=True)
class BlockJacobian:
    """d residual / d x stored block by block.

    rows[k][i] = d r[segments[k]] / d x[parameters[k][i]]; everything else is zero by
    `Blocks`, and never stored.
    """

    blocks: Blocks
    rows: tuple[np.ndarray, ...]

    def block_normals(self) -> tuple[np.ndarray, ...]:
        """J_k J_k^T of each block, over the parameters it depends on."""
        return tuple(inner(rows, rows) for rows in self.rows)

    def normal(self, block_normals: Sequence[np.ndarray] | None = None) -> np.ndarray:
        """J J^T (p x p), summed block by block (from `block_normals` where at hand)."""
        p = self.blocks.n_parameters
        normal = np.zeros((p, p))
        if block_normals is None:
            block_normals = self.block_normals()
        for indices, block in zip(self.blocks.parameters, block_normals, strict=True):
            normal[np.ix_(indices, indices)] += block
        return normal

    def gradient(self, residual: np.ndarray) -> np.ndarray:
        """J r (p), summed block by block."""
        gradient = np.zeros(self.blocks.n_parameters)
        for segment, indices, rows in zip(
            self.blocks.segments, self.blocks.parameters, self.rows, strict=True
        ):
            gradient[indices] += inner(rows, residual[segment])
        return gradient


@dataclass(frozen=True)
class LsqSolution:
    """Result of `levenberg_marquardt`."""

    x: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    """The search bounds."""
    residual: np.ndarray
    """Residuals at x."""
    jacobian: BlockJacobian
    """d residual / d x by blocks, at the last linearisation point: the start of the last
    step (a negligible one, or one over which the model was linear)."""
    block_normals: tuple[np.ndarray, ...]
    """`jacobian.block_normals()`, as the last iteration computed them."""
    cost: float
    """Sum of squared residuals at x."""
    evaluations: int
    """Block residual evaluations (for the fitter, model runs: one an impact)."""
    iterations: int
    converged: bool
    message: str


def levenberg_marquardt(
    fun: ResidualFunction | BlockResidualFunction,
    x0: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    typical: np.ndarray,
    n_residuals: int,
    *,
    blocks: Blocks | None = None,
    chi2_tolerance: float = 1e-3,
    relative_step: float = 1e-4,
    max_iterations: int = 60,
    residual0: np.ndarray | None = None,
    jacobian0: BlockJacobian | None = None,
    threads: int = 1,
) -> LsqSolution:
    """Minimise sum(fun(x)^2) over lower <= x <= upper from x0.

    `typical` is each parameter's scale (finite-difference steps are relative_step x max(|x|,
    typical)). Converged when an accepted step lowers the cost by less than chi2_tolerance
    times the residual variance per sample, i.e. moves the parameters by about
    sqrt(chi2_tolerance) of their (white-noise) standard errors, or when no step can lower
    it, or when the next step would gain less than that (`_converged`: a new Jacobian costs
    a model run per parameter and impact).
    Without `blocks`, fun(x, out) writes every residual (one dense block); with them, fun is
    a BlockResidualFunction and a Jacobian column runs only the blocks its parameter touches.
    residual0, jacobian0: the residuals and the Jacobian (of `blocks`' pattern) at x0 where
    the caller has them (a fit continued from another's solution): no model run is spent on
    them. residual0 is taken over (later trials overwrite it); jacobian0 is left as it is.
    threads: blocks evaluated in this many threads at once (Jacobian columns, and the blocks
    of a trial point): fun must then be safe to call from several threads on disjoint blocks
    and outs (`OutputError` is). The numbers are the same whatever the count: every block is
    computed alone, and the sums over blocks keep their order.
    """
    lower, upper, typical = (np.asarray(a, dtype=float) for a in (lower, upper, typical))
    x = np.clip(np.asarray(x0, dtype=float), lower, upper)
    p, bounds = x.size, (lower, upper)
    fun, blocks = _in_blocks(fun, blocks, n_residuals, p)
    every = tuple(range(len(blocks.segments)))
    trial, jacobian = np.empty(n_residuals), jacobian0
    touched = [blocks.touched_by(j) for j in range(p)]

    def evaluate(x: np.ndarray, out: np.ndarray) -> None:
        _run_blocks(fun, x, every, [out[segment] for segment in blocks.segments], threads)

    evaluations, residual = 0, residual0
    if residual is None:
        residual = _start_residual(evaluate, x, n_residuals)
        evaluations = len(every)
    cost, damping = inner(residual, residual), 1e-3

    def finish(iterations: int, converged: bool, message: str) -> LsqSolution:
        reached = (x, lower, upper, residual, jacobian, block_normals, cost, evaluations)
        return LsqSolution(*reached, iterations, converged, message)

    for iteration in range(1, max_iterations + 1):
        if iteration > 1 or jacobian is None:  # jacobian0 serves the first step
            if jacobian is None or jacobian is jacobian0:
                jacobian = blocks.empty_jacobian()
            evaluations += _forward_jacobian(
                fun, x, residual, lower, upper, typical, relative_step, touched, jacobian, threads
            )
        block_normals = jacobian.block_normals()
        normal = jacobian.normal(block_normals)
        gradient = jacobian.gradient(residual)
        enough = chi2_tolerance * (cost / max(n_residuals - p, 1))  # of the noise variance
        candidate, new_cost, damping, spent, stop = _lowering_step(
            evaluate, normal, gradient, x, bounds, damping, cost, trial, len(every)
        )
        evaluations += spent
        if candidate is None:
            return finish(iteration, True, stop)
        stop = _converged(
            jacobian, normal, gradient, x, candidate, cost - new_cost, trial, bounds, enough
        )
        x, cost, residual, trial = candidate, new_cost, trial, residual
        damping = max(damping / 10.0, 1e-9)
        if stop:
            return finish(iteration, True, stop)
    return finish(max_iterations, False, f'not converged after {max_iterations} iterations')


def _in_blocks(
    fun: ResidualFunction | BlockResidualFunction, blocks: Blocks | None, n_residuals: int, p: int
) -> tuple[BlockResidualFunction, Blocks]:
    """The residual function and its blocks: without blocks, one dense block of them all."""
    if blocks is None:
        blocks = Blocks.shared((slice(0, n_residuals),), p)
        fun = _one_block(fun)
    if blocks.n_parameters != p:
        raise BadInputError(f'the blocks describe {blocks.n_parameters} parameters, x0 has {p}')
    return fun, blocks


def _converged(
    jacobian: BlockJacobian,
    normal: np.ndarray,
    gradient: np.ndarray,
    before: np.ndarray,
    after: np.ndarray,
    reduction: float,
    residual: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray],
    threshold: float,
) -> str:
    """Why the fit stops after an accepted step from before to after, or ''.

    reduction: what the step took off the cost; residual: at after; threshold: the gain not worth
    another step (chi2_tolerance times the residual variance per sample). The cost stopped
    falling where the step gained less; and where the step (taken with a Jacobian made at
    its start) gained what the linear model promised (`LINEAR_GAIN_RATIO`), that Jacobian
    still holds: if the next Gauss-Newton step, predicted from it at the new residual (no
    model runs), would gain less, the fit stops there too.
    """
    taken = after - before
    expected = -float(2.0 * gradient @ taken + taken @ normal @ taken)
    if reduction < threshold:
        return 'the cost stopped falling'
    if expected > 0.0 and reduction > LINEAR_GAIN_RATIO * expected:
        gradient = jacobian.gradient(residual)
        step = _damped_step(normal, gradient, after, bounds[0], bounds[1], 0.0)
        if -float(gradient @ step) < threshold:
            return 'the next step would gain nothing'
    return ''


def _start_residual(
    evaluate: Callable[[np.ndarray, np.ndarray], None], x: np.ndarray, n_residuals: int
) -> np.ndarray:
    """The residuals at the start point; BadInputError where the model cannot run there."""
    residual = np.empty(n_residuals)
    try:
        evaluate(x, residual)
    except Infeasible as error:
        raise BadInputError(
            f'the model cannot be evaluated at the start point {x}: {error}'
        ) from None
    return residual


def _lowering_step(
    evaluate: Callable[[np.ndarray, np.ndarray], None],
    normal: np.ndarray,
    gradient: np.ndarray,
    x: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray],
    damping: float,
    cost: float,
    trial: np.ndarray,
    runs_per_trial: int,
) -> tuple[np.ndarray | None, float, float, int, str]:
    """The damped step that lowers the cost, the damping raised tenfold until one does.

    Returns (the new point, its cost, the damping it took, the block runs spent, ''), its
    residuals written into trial; or (None, cost, damping, runs, why) where no step moves
    the parameters or lowers the cost.
    """
    lower, upper = bounds
    spent = 0
    while True:
        step = _damped_step(normal, gradient, x, lower, upper, damping)
        candidate = np.clip(x + step, lower, upper)
        if np.array_equal(candidate, x):
            return (
                None,
                cost,
                damping,
                spent,
                'no step moves the parameters (at a bound or converged)',
            )
        try:
            evaluate(candidate, trial)
            new_cost = inner(trial, trial)
        except Infeasible:
            new_cost = np.inf
        spent += runs_per_trial
        if new_cost < cost:
            return candidate, new_cost, damping, spent, ''
        damping *= 10.0
        if damping > 1e10:
            return None, cost, damping, spent, 'no step lowers the cost'


LINEAR_GAIN_RATIO = 0.9
"""A step that gained this much of what the linearised model promised shows the model linear
over it: `levenberg_marquardt` may judge the next step from the same Jacobian."""


def _one_block(fun: ResidualFunction) -> BlockResidualFunction:
    """A dense residual function as the block function of its one block."""

    def block_function(x: np.ndarray, _: Sequence[int], outs: Sequence[np.ndarray]) -> None:
        fun(x, outs[0])

    return block_function


def _forward_jacobian(
    fun: BlockResidualFunction,
    x: np.ndarray,
    residual: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    typical: np.ndarray,
    relative_step: float,
    touched: Sequence[Sequence[tuple[int, int]]],
    out: BlockJacobian,
    threads: int = 1,
) -> int:
    """Fill d r_k / d x_j = (r_k(x + h_j e_j) - r_k(x)) / h_j on the blocks k x_j touches.

    touched[j]: (block, row) pairs of parameter j (`Blocks.touched_by`). Steps inward at an
    upper bound. Returns the number of block evaluations. Where neither side of x_j is
    feasible the rows are 0. threads: columns computed in this many threads at once (each
    column writes its own rows only).
    """
    segments = out.blocks.segments

    def column(j: int) -> int:
        which = [k for k, _ in touched[j]]
        rows = [out.rows[k][row] for k, row in touched[j]]
        h = relative_step * max(abs(x[j]), typical[j])
        if x[j] + h > upper[j]:
            h = -h
        shifted = x.copy()
        evaluations = 0
        for signed_step in (h, -h):
            shifted[j] = x[j] + signed_step
            evaluations += len(which)
            try:
                fun(shifted, which, rows)
            except Infeasible:
                continue
            for k, row in zip(which, rows, strict=True):
                np.subtract(row, residual[segments[k]], out=row)
                row /= signed_step
            break
        else:
            for row in rows:
                row[:] = 0.0
        return evaluations

    columns = [j for j in range(x.size) if touched[j]]
    return sum(thread_map(column, columns, threads))


def _damped_step(
    normal: np.ndarray,
    gradient: np.ndarray,
    x: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    damping: float,
) -> np.ndarray:
    """Marquardt step -(A + damping diag A)^-1 g over the parameters free to move.

    Solved in parameters scaled to unit diagonal, so that a term whose Jacobian is 1e7 times
    smaller than mu's (a cubic stiffness in N/m^3) is not lost to rounding.
    """
    free = ~(((x <= lower) & (gradient > 0.0)) | ((x >= upper) & (gradient < 0.0)))
    step = np.zeros_like(x)
    if not free.any():
        return step
    scale = _unit_diagonal_scale(normal[np.ix_(free, free)])
    system = normal[np.ix_(free, free)] / np.outer(scale, scale)
    system[np.diag_indices_from(system)] += damping
    scaled_gradient = gradient[free] / scale
    try:
        step[free] = -np.linalg.solve(system, scaled_gradient) / scale
    except np.linalg.LinAlgError:
        step[free] = -np.linalg.lstsq(system, scaled_gradient, rcond=None)[0] / scale
    return step


def normal_inverse(normal: np.ndarray) -> np.ndarray:
    """(J J^T)^-1 for a covariance, pseudo-inverted in unit-diagonal scaling.

    A parameter the residuals do not depend on (zero row) gets infinite variance, not zero.
    """
    scale = _unit_diagonal_scale(normal)
    inverse = np.linalg.pinv(normal / np.outer(scale, scale), hermitian=True)
    inverse /= np.outer(scale, scale)
    dead = np.diag(normal) <= 0.0
    inverse[dead, :] = 0.0
    inverse[:, dead] = 0.0
    inverse[dead, dead] = np.inf
    return inverse


def _unit_diagonal_scale(normal: np.ndarray) -> np.ndarray:
    diagonal = np.sqrt(np.clip(np.diag(normal), 0.0, None))
    return np.where(diagonal > 0.0, diagonal, 1.0)
