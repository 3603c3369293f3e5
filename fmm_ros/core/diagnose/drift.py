"""Friction from hit to hit: does one mu serve every hit, and do their own mu trend in hit order.

Wear, run-in and temperature change a contact over a session, so each hit's friction
coefficient drifts with the hit's place in the session. `mu_trend` takes each hit's mu and its
standard error, in hit order, and answers both questions:

- consistency: chi^2 of the mu_i about their weighted mean with the stated errors (n - 1
  degrees of freedom), as `fit_friction` does;
- trend: weighted least squares mu_i = a + b i. Its covariance is scaled up by the reduced
  chi^2 of the line when that exceeds 1, so scatter the stated errors miss (the force noise's
  impulse error, a contact that varies at random from hit to hit) widens the slope's error
  instead of faking a trend; the slope's significance is a two-sided t test with n - 2
  degrees of freedom.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.core.distributions import chi2_sf, t_sf
from fmm_ros.errors import BadInputError

MIN_DRIFT_HITS = 3
"""mu_drift is considered from this many hits (one a level, as the demo diagnoses): each hit's
own mu against their errors, and a line through them with one degree of freedom left."""


MIN_TREND_HITS = 4
"""From this many hits a drift must also trend in hit order (two degrees of freedom left)."""


DRIFT_SIZE = ('change_per_hit', '1/hit')
"""(name, unit) of the size a drift's detection limit is stated in: the steady change of mu
from one hit to the next as a fraction of mu, mu_i = mu (1 + change_per_hit i)."""


@dataclass(frozen=True)
class MuTrend:
    """Each hit's mu in hit order, and whether and how it trends."""

    mu: tuple[float, ...]
    """Each hit's friction coefficient, in hit order [-]."""
    mu_stderr: tuple[float, ...]
    refitted: bool
    """True: each hit's mu refitted alone; False: one linearised step from the joint fit."""
    consistency_chi2: float
    """sum ((mu_i - weighted mean) / stderr_i)^2 [-]."""
    consistency_p_value: float
    """Chance of a chi^2 this large if one mu served every hit (n - 1 degrees)."""
    slope_per_hit: float
    """Change of mu from one hit to the next, fitted over the session [1/hit]."""
    slope_stderr: float
    intercept: float
    """mu at the first hit on the fitted line [-]."""
    p_value: float
    """Two-sided chance of a slope this far from zero with no trend [-]."""

    @property
    def trend_per_hit(self) -> tuple[float, ...]:
        """The fitted line at each hit [-]."""
        return tuple(self.intercept + self.slope_per_hit * i for i in range(len(self.mu)))


def mu_trend(mu: Sequence[float], mu_stderr: Sequence[float], *, refitted: bool) -> MuTrend:
    """Consistency and trend of per-hit mu (module doc); ValueError for fewer than 3 hits."""
    values = np.asarray(mu, dtype=float)
    errors = np.asarray(mu_stderr, dtype=float)
    n = values.size
    if n < MIN_DRIFT_HITS:
        raise BadInputError(
            f'a trend of mu in hit order needs at least {MIN_DRIFT_HITS} hits, got {n}'
        )
    if not (np.all(np.isfinite(values)) and np.all(errors > 0.0) and np.all(np.isfinite(errors))):
        raise BadInputError('per-hit mu and their standard errors must be finite, errors positive')
    weights = 1.0 / errors**2
    mean = float(np.sum(weights * values) / np.sum(weights))
    consistency = float(np.sum(weights * (values - mean) ** 2))
    hits = np.arange(n, dtype=float)
    design = np.column_stack((np.ones(n), hits))
    normal = design.T @ (weights[:, None] * design)
    covariance = np.linalg.inv(normal)
    intercept, slope = covariance @ (design.T @ (weights * values))
    line = intercept + slope * hits
    reduced = float(np.sum(weights * (values - line) ** 2)) / (n - 2)
    covariance *= max(reduced, 1.0)
    slope_error = math.sqrt(covariance[1, 1])
    t = slope / slope_error if slope_error > 0.0 else math.inf
    return MuTrend(
        mu=tuple(float(v) for v in values),
        mu_stderr=tuple(float(e) for e in errors),
        refitted=refitted,
        consistency_chi2=consistency,
        consistency_p_value=float(chi2_sf(consistency, n - 1)),
        slope_per_hit=float(slope),
        slope_stderr=slope_error,
        intercept=float(intercept),
        p_value=float(2.0 * t_sf(abs(t), n - 2)),
    )
