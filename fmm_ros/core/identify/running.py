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

from fmm_ros.core.distributions import chi2_sf
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
    impact_ids: tuple[int, ...] = ()
    """The impacts behind the estimate; impact_id absent from them: it was just removed."""


def _weighted(entries: list[tuple[float, float]]) -> tuple[float, float, float]:
    """(weighted mean, its standard error, chi^2 of the mus about it) of (mu, stderr) pairs.

    NaN for none.
    """
    if not entries:
        return math.nan, math.nan, math.nan
    weights = [1.0 / s**2 for _, s in entries]
    total = math.fsum(weights)
    mean = math.fsum(w * m for w, (m, _) in zip(weights, entries, strict=True)) / total
    chi2 = math.fsum(w * (m - mean) ** 2 for w, (m, _) in zip(weights, entries, strict=True))
    return mean, 1.0 / math.sqrt(total), chi2


@dataclass
class RunningFriction:
    """Each impact's own mu by impact id, and the running estimate over them.

    Impacts can be taken out again (`remove`: an operator rejected a hit) and put
    back; the estimate is recomputed from the impacts' own mus, so it is the same as if the
    removed impact had never been added.
    """

    _impacts: dict[int, tuple[str, float, float]] = field(default_factory=dict)

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
        self._impacts[impact_id] = (level, mu, mu_stderr)
        return self.estimate(impact_id, mu, mu_stderr)

    def remove(self, impact_id: int) -> RunningEstimate:
        """Take impact_id out; the estimate without it.

        Its impact_id is the one removed, absent from impact_ids; mu is NaN when none is left.
        KeyError for an id not held.
        """
        _, mu, stderr = self._impacts.pop(impact_id)
        return self.estimate(impact_id, mu, stderr)

    def __contains__(self, impact_id: int) -> bool:
        return impact_id in self._impacts

    def estimate(self, impact_id: int, impact_mu: float, impact_stderr: float) -> RunningEstimate:
        """The estimate over the impacts held, told as the change of impact_id."""
        entries = list(self._impacts.values())
        mean, stderr, chi2 = _weighted([(mu, s) for _, mu, s in entries])
        dof = len(entries) - 1
        by_level: dict[str, list[tuple[float, float]]] = {}
        for level, mu, s in entries:
            by_level.setdefault(level, []).append((mu, s))
        levels = []
        for name, pairs in by_level.items():
            level_mu, level_stderr, _ = _weighted(pairs)
            levels.append(LevelEstimate(name, len(pairs), level_mu, level_stderr))
        return RunningEstimate(
            impact_id=impact_id,
            impact_mu=impact_mu,
            impact_mu_stderr=impact_stderr,
            count=len(entries),
            mu=mean,
            mu_stderr=stderr,
            consistency_chi2=chi2,
            consistency_p_value=float(chi2_sf(chi2, dof)) if dof > 0 else math.nan,
            levels=tuple(levels),
            impact_ids=tuple(self._impacts),
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
