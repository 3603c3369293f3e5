"""The running friction estimate: mu, its error and the one-mu test as the hits come in.

A session's joint fit (`fit_friction`) refits every impact together; done after each hit that
would cost a whole session fit per hit. But each impact's nuisance parameters (its start, its
impulse scale, its chain) are its own and only mu is shared, so the joint mu is, to first
order, the inverse-variance weighted mean of the impacts' own mus, with standard error
(sum 1 / s_i^2)^-1/2, and the one-mu test is chi^2 = sum ((mu_i - mu) / s_i)^2 with n - 1
degrees of freedom. `RunningFriction` keeps the impacts' own mus: one fit of the new impact
alone per hit, then arithmetic. The same per level (each level's own weighted mean), so a lab sees
whether the levels agree while the session runs.
"""

import math
from dataclasses import dataclass, field

import scipy.stats

from fmm_ros.errors import BadInputError


@dataclass(frozen=True)
class LevelEstimate:
    """One level's impacts so far: their weighted mean mu."""

    level: str
    count: int
    mu: float
    mu_stderr: float


@dataclass(frozen=True)
class RunningEstimate:
    """The friction estimate after one more accepted impact."""

    impact_id: int
    """The impact just added."""
    impact_mu: float
    impact_mu_stderr: float
    """Its own mu and standard error."""
    count: int
    """Impacts behind the estimate."""
    mu: float
    mu_stderr: float
    consistency_chi2: float
    consistency_p_value: float
    """Chance of this much scatter if one mu served all (NaN for one impact)."""
    levels: tuple[LevelEstimate, ...]
    """Per level, in the order the levels first appeared."""


@dataclass
class _Impacts:
    """Impacts' own mus and standard errors: their weighted mean, its error and chi^2."""

    mus: list[float] = field(default_factory=list)
    stderrs: list[float] = field(default_factory=list)

    def add(self, mu: float, stderr: float) -> None:
        self.mus.append(mu)
        self.stderrs.append(stderr)

    @property
    def count(self) -> int:
        return len(self.mus)

    def estimate(self) -> tuple[float, float, float]:
        """(weighted mean, its standard error, chi^2 of the mus about it)."""
        weights = [1.0 / s**2 for s in self.stderrs]
        total = math.fsum(weights)
        mean = math.fsum(w * m for w, m in zip(weights, self.mus, strict=True)) / total
        chi2 = math.fsum(w * (m - mean) ** 2 for w, m in zip(weights, self.mus, strict=True))
        return mean, 1.0 / math.sqrt(total), chi2


@dataclass
class RunningFriction:
    """Accumulates each accepted impact's own mu into the running estimate."""

    _all: _Impacts = field(default_factory=_Impacts)
    _levels: dict[str, _Impacts] = field(default_factory=dict)

    def add(self, impact_id: int, level: str, mu: float, mu_stderr: float) -> RunningEstimate:
        """Take in one impact's own fit (mu and its standard error); the estimate now.

        ValueError for a standard error that is not positive and finite (such an impact has
        no weight to give).
        """
        if not (math.isfinite(mu) and math.isfinite(mu_stderr) and mu_stderr > 0.0):
            raise BadInputError(
                f'impact {impact_id}: mu {mu} +- {mu_stderr} cannot be weighted (a positive, '
                'finite standard error is needed)'
            )
        self._all.add(mu, mu_stderr)
        self._levels.setdefault(level, _Impacts()).add(mu, mu_stderr)
        mean, stderr, chi2 = self._all.estimate()
        dof = self._all.count - 1
        levels = []
        for name, impacts in self._levels.items():
            level_mu, level_stderr, _ = impacts.estimate()
            levels.append(LevelEstimate(name, impacts.count, level_mu, level_stderr))
        return RunningEstimate(
            impact_id=impact_id,
            impact_mu=mu,
            impact_mu_stderr=mu_stderr,
            count=self._all.count,
            mu=mean,
            mu_stderr=stderr,
            consistency_chi2=chi2,
            consistency_p_value=float(scipy.stats.chi2.sf(chi2, dof)) if dof else math.nan,
            levels=tuple(levels),
        )


def running_estimates(
    impact_ids: list[int], levels: list[str], mus: list[float], stderrs: list[float]
) -> tuple[RunningEstimate, ...]:
    """The estimate after each impact in turn (a finished session's per-impact fits)."""
    running = RunningFriction()
    return tuple(
        running.add(impact_id, level, mu, stderr)
        for impact_id, level, mu, stderr in zip(impact_ids, levels, mus, stderrs, strict=True)
    )
