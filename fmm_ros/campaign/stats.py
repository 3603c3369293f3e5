"""Random-effects meta-regression: per-session estimates, their errors, and scatter between them.

A campaign's sessions each give one mu and its standard error from the fitter. Sessions of one
condition scatter more than those errors say (the contact changes between sessions), so the
model is the textbook mixed-effects meta-regression (Raudenbush 2009; Viechtbauer 2005, 2010):

    y_i = x_i' beta + u_i + e_i,    u_i ~ N(0, tau^2),    e_i ~ N(0, v_i)

y_i the session's estimate, v_i its (known) within-session variance, x_i its row of the design
(condition indicators, a numeric column), tau^2 the between-session variance, one for the
campaign. tau^2 is estimated by restricted maximum likelihood (Fisher scoring, truncated at 0;
DerSimonian-Laird's method of moments is its start and the alternative), beta by weighted
least squares with weights 1 / (v_i + tau^2). Inference on any contrast c' beta follows Knapp
and Hartung (2003): the covariance is scaled by q = sum w_i r_i^2 / (k - p), not below 1 (their
ad hoc rule: never narrower than the model's own errors), and t has k - p degrees of freedom.
With few sessions per condition, normal (z) intervals on an estimated tau^2 cover far less than
they claim; the t intervals hold their level (validated by simulation in the tests).

Plain functions and frozen results on numpy arrays; scipy for the distributions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from fmm_ros.core.distributions import chi2_sf, t_ppf, t_sf
from fmm_ros.errors import BadInputError

TAU2_METHODS = ('reml', 'dl')
# Fisher scoring stops when a step changes tau^2 by less than this fraction of the typical
# total variance (mean v_i + tau^2), or after this many steps.
_REML_RTOL = 1e-10
_REML_MAX_STEPS = 200
CONFIDENCE = 0.95
"""Level of every interval a campaign reports."""


@dataclass(frozen=True)
class Contrast:
    """An estimate of c' beta with its Knapp-Hartung standard error, t test and interval."""

    estimate: float
    stderr: float
    dof: int
    t_value: float
    p_value: float
    """Two-sided, against 0 (NaN without degrees of freedom)."""
    ci_low: float
    ci_high: float


@dataclass(frozen=True)
class MetaRegression:
    """A fitted random-effects meta-regression (see module)."""

    names: tuple[str, ...]
    coefficients: np.ndarray
    covariance: np.ndarray
    """Knapp-Hartung covariance of the coefficients: (X'WX)^-1 times `scale`."""
    model_covariance: np.ndarray
    """(X'WX)^-1, the covariance the random-effects model itself implies."""
    scale: float
    """The Knapp-Hartung factor applied: max(1, q) with the ad hoc rule, else q."""
    q_statistic: float
    """q = sum w_i r_i^2 / (k - p) at the fitted tau^2 (1 expected)."""
    tau2: float
    tau2_stderr: float
    """From the restricted likelihood's Fisher information (NaN for DL or tau^2 = 0)."""
    tau2_method: str
    dof: int
    """k - p: sessions less coefficients."""
    heterogeneity_q: float
    """Cochran's Q_E of the residuals under fixed-effect weights 1/v_i."""
    heterogeneity_p: float
    """Chance of Q_E this large with tau^2 = 0 (chi^2, k - p degrees)."""
    i2: float
    """Share of the residual variance between sessions: tau^2 / (tau^2 + typical v) [-]."""
    count: int

    @property
    def tau(self) -> float:
        """Between-session standard deviation."""
        return math.sqrt(self.tau2)

    def contrast(self, weights: Sequence[float], confidence: float = CONFIDENCE) -> Contrast:
        """The contrast c' beta for coefficient weights c, with its t test and interval."""
        c = np.asarray(weights, dtype=float)
        if c.shape != self.coefficients.shape:
            raise BadInputError(f'a contrast needs {self.coefficients.size} weights, got {c.size}')
        estimate = float(c @ self.coefficients)
        stderr = float(math.sqrt(max(c @ self.covariance @ c, 0.0)))
        if self.dof < 1 or not stderr > 0:
            return Contrast(estimate, stderr, self.dof, math.nan, math.nan, math.nan, math.nan)
        t_value = estimate / stderr
        half = float(t_ppf(0.5 + confidence / 2, self.dof)) * stderr
        return Contrast(
            estimate,
            stderr,
            self.dof,
            t_value,
            float(2 * t_sf(abs(t_value), self.dof)),
            estimate - half,
            estimate + half,
        )

    def coefficient(self, name: str, confidence: float = CONFIDENCE) -> Contrast:
        """One coefficient, by name."""
        weights = np.zeros(self.coefficients.size)
        weights[self.names.index(name)] = 1.0
        return self.contrast(weights, confidence)


def meta_regression(
    estimates: Sequence[float],
    variances: Sequence[float],
    design: np.ndarray,
    names: Sequence[str] | None = None,
    *,
    tau2_method: str = 'reml',
    knapp_hartung_floor: bool = True,
) -> MetaRegression:
    """Fit the random-effects meta-regression of `estimates` (k) with within variances (k).

    design: k x p of full column rank. knapp_hartung_floor: scale by max(1, q) (default)
    rather than q. ValueError for non-finite inputs, non-positive variances or a design that
    does not identify its coefficients.
    """
    y = np.asarray(estimates, dtype=float)
    v = np.asarray(variances, dtype=float)
    x = np.asarray(design, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    k, p = x.shape
    names = tuple(names) if names is not None else tuple(f'b{i}' for i in range(p))
    if y.shape != (k,) or v.shape != (k,) or len(names) != p:
        raise BadInputError(
            f'{y.size} estimates, {v.size} variances, a {k} x {p} design and {len(names)} '
            'names do not match'
        )
    if not (np.isfinite(y).all() and np.isfinite(v).all() and np.isfinite(x).all()):
        raise BadInputError('estimates, variances and design must be finite')
    if not (v > 0).all():
        raise BadInputError('within-session variances must be positive')
    if np.linalg.matrix_rank(x) < p:
        raise BadInputError(f'the design ({", ".join(names)}) does not identify its coefficients')
    if tau2_method not in TAU2_METHODS:
        raise BadInputError(f'tau2_method must be one of {TAU2_METHODS}, got {tau2_method!r}')
    dof = k - p
    fixed_q, fixed_trace = _fixed_effect_moments(y, v, x)
    tau2_dl = max(0.0, (fixed_q - dof) / fixed_trace) if dof > 0 else 0.0
    tau2, tau2_se = tau2_dl, math.nan
    if tau2_method == 'reml' and dof > 0:
        tau2, tau2_se = _reml_tau2(y, v, x, tau2_dl)
    w = 1.0 / (v + tau2)
    model_cov = np.linalg.inv(x.T @ (w[:, None] * x))
    beta = model_cov @ (x.T @ (w * y))
    residual = y - x @ beta
    q = float(np.sum(w * residual**2) / dof) if dof > 0 else math.nan
    scale = (max(1.0, q) if knapp_hartung_floor else q) if dof > 0 else 1.0
    typical_v = dof / fixed_trace if dof > 0 else math.nan
    return MetaRegression(
        names=names,
        coefficients=beta,
        covariance=model_cov * scale,
        model_covariance=model_cov,
        scale=scale,
        q_statistic=q,
        tau2=tau2,
        tau2_stderr=tau2_se,
        tau2_method=tau2_method,
        dof=dof,
        heterogeneity_q=fixed_q,
        heterogeneity_p=float(chi2_sf(fixed_q, dof)) if dof > 0 else math.nan,
        i2=tau2 / (tau2 + typical_v) if dof > 0 else math.nan,
        count=k,
    )


def _projection(v_total: np.ndarray, x: np.ndarray) -> np.ndarray:
    """P = W - W X (X'WX)^-1 X'W with W = diag(1 / v_total): residual maker of the WLS fit."""
    w = 1.0 / v_total
    wx = w[:, None] * x
    return np.diag(w) - wx @ np.linalg.solve(x.T @ wx, wx.T)


def _fixed_effect_moments(y: np.ndarray, v: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """Cochran's Q_E = y'P0 y and tr(P0) under fixed-effect weights (tau^2 = 0)."""
    p0 = _projection(v, x)
    return float(y @ p0 @ y), float(np.trace(p0))


def _restricted_loglik(tau2: float, y: np.ndarray, v: np.ndarray, x: np.ndarray) -> float:
    """The restricted log-likelihood of tau^2, up to a constant."""
    total = v + tau2
    w = 1.0 / total
    xtwx = x.T @ (w[:, None] * x)
    beta = np.linalg.solve(xtwx, x.T @ (w * y))
    residual = y - x @ beta
    return -0.5 * (np.sum(np.log(total)) + np.linalg.slogdet(xtwx)[1] + np.sum(w * residual**2))


def _reml_tau2(y: np.ndarray, v: np.ndarray, x: np.ndarray, start: float) -> tuple[float, float]:
    """REML tau^2 by Fisher scoring from `start` (truncated at 0), and its standard error.

    Step: tau^2 += (y'PPy - tr P) / tr(PP) (Viechtbauer 2005). Should the iteration not settle,
    the restricted likelihood is maximised by a bounded scalar search instead.
    """
    tau2 = start
    typical = float(np.mean(v))
    for _ in range(_REML_MAX_STEPS):
        p = _projection(v + tau2, x)
        py = p @ y
        information = float(np.sum(p * p.T))
        step = (float(py @ py) - float(np.trace(p))) / information
        new = max(0.0, tau2 + step)
        if abs(new - tau2) <= _REML_RTOL * (typical + tau2):
            tau2 = new
            break
        tau2 = new
    else:
        upper = 10.0 * (float(np.var(y)) + float(np.max(v)))
        found = scipy.optimize.minimize_scalar(
            lambda t: -_restricted_loglik(t, y, v, x),
            bounds=(0.0, upper),
            method='bounded',
            options={'xatol': _REML_RTOL * typical},
        )
        tau2 = (
            float(found.x)
            if _restricted_loglik(found.x, y, v, x) > _restricted_loglik(0.0, y, v, x)
            else 0.0
        )
    p = _projection(v + tau2, x)
    information = float(np.sum(p * p.T))
    stderr = math.sqrt(2.0 / information) if tau2 > 0 and information > 0 else math.nan
    return tau2, stderr


def holm(p_values: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values (family-wise error), NaN kept where given."""
    p = np.asarray(p_values, dtype=float)
    adjusted = np.full(p.shape, np.nan)
    known = np.flatnonzero(np.isfinite(p))
    order = known[np.argsort(p[known], kind='stable')]
    m = order.size
    running = 0.0
    for rank, index in enumerate(order):
        running = max(running, min(1.0, (m - rank) * p[index]))
        adjusted[index] = running
    return adjusted
