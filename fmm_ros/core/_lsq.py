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
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


def inner(a: np.ndarray, b: np.ndarray) -> np.ndarray | float:
    """Products over the last (sample) axis, a . b or a @ b.T, by einsum's own loop, not BLAS.

    OpenBLAS splits long products across threads; on this shared two-core machine, loaded by
    other jobs, a 330,000-sample dot product took 16 ms that way against 0.08 ms in einsum,
    and a one-impact fit 150 ms against 40 ms. Vectors give a float, (p, n) rows an array.
    """
    if a.ndim == 1 and b.ndim == 1:
        return float(np.einsum('i,i->', a, b))
    return np.einsum('...j,kj->...k' if b.ndim == 2 else '...j,j->...', a, b)


class Infeasible(Exception):
    """The model cannot be evaluated at these parameters (e.g. a friction coefficient < 0)."""


ResidualFunction = Callable[[np.ndarray, np.ndarray], None]
"""fun(x, out): write the residuals at parameters x into out; raise Infeasible if it cannot."""


@dataclass(frozen=True)
class LsqSolution:
    """Result of `levenberg_marquardt`."""

    x: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    """The search bounds."""
    residual: np.ndarray
    """Residuals at x."""
    jacobian: np.ndarray
    """(p, n): row j is d residual / d x_j, at the last linearisation point (within the final
    step's tolerance of x)."""
    cost: float
    """Sum of squared residuals at x."""
    evaluations: int
    iterations: int
    converged: bool
    message: str


def levenberg_marquardt(fun: ResidualFunction, x0: np.ndarray, lower: np.ndarray,
                        upper: np.ndarray, typical: np.ndarray, n_residuals: int, *,
                        chi2_tolerance: float = 1e-3, relative_step: float = 1e-4,
                        max_iterations: int = 60) -> LsqSolution:
    """Minimise sum(fun(x)^2) over lower <= x <= upper from x0.

    `typical` is each parameter's scale (finite-difference steps are relative_step x max(|x|,
    typical)). Converged when an accepted step lowers the cost by less than chi2_tolerance
    times the residual variance per sample, i.e. moves the parameters by about
    sqrt(chi2_tolerance) of their (white-noise) standard errors, or when no step can lower it.
    """
    lower, upper, typical = (np.asarray(a, dtype=float) for a in (lower, upper, typical))
    x = np.clip(np.asarray(x0, dtype=float), lower, upper)
    p = x.size
    residual = np.empty(n_residuals)
    trial = np.empty(n_residuals)
    jacobian = np.empty((p, n_residuals))
    try:
        fun(x, residual)
    except Infeasible as error:
        raise ValueError(f'the model cannot be evaluated at the start point {x}: {error}') from None
    evaluations = 1
    cost = inner(residual, residual)
    damping = 1e-3

    def finish(iterations: int, converged: bool, message: str) -> LsqSolution:
        return LsqSolution(x, lower, upper, residual, jacobian, cost, evaluations, iterations,
                           converged, message)

    for iteration in range(1, max_iterations + 1):
        evaluations += _forward_jacobian(fun, x, residual, lower, upper, typical, relative_step,
                                         jacobian)
        normal = inner(jacobian, jacobian)
        gradient = inner(jacobian, residual)
        noise_variance = cost / max(n_residuals - p, 1)
        while True:
            step = _damped_step(normal, gradient, x, lower, upper, damping)
            candidate = np.clip(x + step, lower, upper)
            if np.array_equal(candidate, x):
                return finish(iteration, True, 'no step moves the parameters (at a bound or '
                              'converged)')
            try:
                fun(candidate, trial)
                new_cost = inner(trial, trial)
            except Infeasible:
                new_cost = np.inf
            evaluations += 1
            if new_cost < cost:
                break
            damping *= 10.0
            if damping > 1e10:
                return finish(iteration, True, 'no step lowers the cost')
        reduction = cost - new_cost
        x, cost = candidate, new_cost
        residual, trial = trial, residual
        damping = max(damping / 10.0, 1e-9)
        if reduction < chi2_tolerance * noise_variance:
            return finish(iteration, True, 'the cost stopped falling')
    return finish(max_iterations, False, f'not converged after {max_iterations} iterations')


def _forward_jacobian(fun: ResidualFunction, x: np.ndarray, residual: np.ndarray,
                      lower: np.ndarray, upper: np.ndarray, typical: np.ndarray,
                      relative_step: float, out: np.ndarray) -> int:
    """Fill out[j] = (r(x + h_j e_j) - r(x)) / h_j, stepping inward at an upper bound.

    Returns the number of evaluations. Where neither side of x_j is feasible the row is 0.
    """
    evaluations = 0
    for j in range(x.size):
        h = relative_step * max(abs(x[j]), typical[j])
        if x[j] + h > upper[j]:
            h = -h
        shifted = x.copy()
        for signed_step in (h, -h):
            shifted[j] = x[j] + signed_step
            evaluations += 1
            try:
                fun(shifted, out[j])
            except Infeasible:
                continue
            np.subtract(out[j], residual, out=out[j])
            out[j] /= signed_step
            break
        else:
            out[j] = 0.0
    return evaluations


def _damped_step(normal: np.ndarray, gradient: np.ndarray, x: np.ndarray, lower: np.ndarray,
                 upper: np.ndarray, damping: float) -> np.ndarray:
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
