"""A model of every impact of a session, as the diagnosis grows it: terms, and mu per hit or not.

`SessionModel` is one step of the forward selection: the base model (Eq. 3, one mu) plus the
terms named so far, fitted jointly by `fit_model`, and, once `mu_drift` is named, each hit's
own mu refitted with the terms held (`with_mu_per_hit`, as `fit_friction` does for its
per-impact mu). Its residuals are on the cropped records the diagnosis fits, and its
information criteria count every fitted parameter, start positions included.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from fmm_ros.constants import MU_DRIFT
from fmm_ros.core._threads import thread_map
from fmm_ros.core.diagnose.result import ParameterEstimate
from fmm_ros.core.identify.conditioning import ConditionedImpact
from fmm_ros.core.identify.friction import ModelFit, fit_model
from fmm_ros.core.identify.lsq import inner
from fmm_ros.core.identify.spec import FitSpec
from fmm_ros.core.physics.model import Simulation, simulate
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.physics.terms import ModelTerm

DIAGNOSTIC_FIT = FitSpec(judge_hit=True)
"""How the diagnosis fits every model: `fit_model`'s spec with the hit windows judged."""


def diagnostic_fit(
    impacts: Sequence[ConditionedImpact],
    *,
    rig: Rig,
    fit_initial_position: bool,
    mu0: float | None = None,
    terms: Sequence[ModelTerm] = (),
    fixed_effects: Sequence[ModelTerm] = (),
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> ModelFit:
    """`fit_model` as the diagnosis fits every model: the velocity judged while the hammer acts.

    `fit_model` leaves the hit windows (each pulse and 1 ms after it) out by default, since
    their shape carries nothing about friction. A missing effect may show mostly there: a
    channel delay shifts the velocity most where it changes fastest, in the hit. The
    diagnosis compares models by their residuals over the whole motion (screen, gaps,
    information criteria), so every fit it makes judges the same samples.

    In a chained session (`ConditionedImpact.follows_previous`) every model also fits each
    hit's impulse scale: the rest a hit leaves moves with its amplitude, e times 20 mm for a
    relative impulse error e, so the measured impulse's 1e-4 to 2e-3 misstate the next start
    by as much as a friction asymmetry moves it (1e-5 to 7e-5 m). Measured on `steps`, a
    tuning world: with measured impulses 16 of 24 asymmetric chained sessions were named,
    with fitted scales 22 of 24, clean ones 16 of 16 `none` either way.

    ranges: the terms' fitting ranges by parameter name (`physical_ranges`), in place of
    their declared bounds.
    """
    return fit_model(
        impacts,
        DIAGNOSTIC_FIT.but(
            fit_initial_position=fit_initial_position,
            fit_impulse_scale=any(impact.follows_previous for impact in impacts),
        ),
        rig=rig,
        mu0=mu0,
        terms=terms,
        fixed_effects=fixed_effects,
        term_bounds=ranges,
    )


@dataclass(frozen=True)
class SessionModel:
    """The joint fit of some terms, and each hit's own mu on top of it when mu drifts."""

    effects: tuple[str, ...]
    """Effects named in this model, in the order they were added."""
    joint: ModelFit
    """One mu for every hit, the terms' parameters, start positions if fitted."""
    per_hit: tuple[ModelFit, ...] = ()
    """With mu_drift: each hit alone, its mu (and start) refitted, the terms held at joint's."""

    @property
    def terms(self) -> tuple[ModelTerm, ...]:
        """The fitted model terms."""
        return self.joint.effects

    @property
    def rig(self) -> Rig:
        """The rig constants of the fitted model."""
        return self.joint.rig

    @property
    def mus(self) -> np.ndarray:
        """Each hit's friction coefficient (all the joint one without mu_drift) [-]."""
        if self.per_hit:
            return np.array([fit.mu for fit in self.per_hit])
        return np.full(len(self.joint.impacts), self.joint.mu)

    @property
    def mu_stderrs(self) -> np.ndarray:
        """Their standard errors [-]."""
        if self.per_hit:
            return np.array([fit.mu_stderr for fit in self.per_hit])
        return np.full(len(self.joint.impacts), self.joint.mu_stderr)

    @property
    def positions_m(self) -> tuple[float, ...]:
        """Where each hit's model starts [m]."""
        if self.per_hit:
            return tuple(fit.initial_positions_m[0] for fit in self.per_hit)
        return self.joint.initial_positions_m

    @property
    def impulse_scales(self) -> tuple[float, ...]:
        """The factor on each hit's measured force (1 where not fitted) [-]."""
        if self.per_hit:
            return tuple(fit.impulse_scales[0] for fit in self.per_hit)
        return self.joint.impulse_scales

    @property
    def residuals_m_s(self) -> tuple[np.ndarray, ...]:
        """Measured minus model velocity of each cropped impact [m/s]."""
        if self.per_hit:
            return tuple(fit.residuals_m_s[0] for fit in self.per_hit)
        return self.joint.residuals_m_s

    @property
    def n_parameters(self) -> int:
        """Fitted parameters: the joint fit's, plus one mu per hit beyond the first."""
        return len(self.joint.names) + max(len(self.per_hit) - 1, 0)

    def chi2(self, noise_std_m_s: float) -> float:
        """Residual sum of squares over the noise variance [-]."""
        return sum(inner(r, r) for r in self.residuals_m_s) / noise_std_m_s**2

    def bic(self, noise_std_m_s: float, n_samples: int) -> float:
        """chi^2 + k ln n, up to a constant common to every model of the same records."""
        return self.chi2(noise_std_m_s) + self.n_parameters * math.log(n_samples)

    def aic(self, noise_std_m_s: float) -> float:
        """chi^2 + 2k, likewise."""
        return self.chi2(noise_std_m_s) + 2.0 * self.n_parameters

    def velocity(
        self,
        index: int,
        force_n: np.ndarray,
        sample_rate_hz: float,
        effects: Sequence[ModelTerm] | None = None,
        mu: float | None = None,
        x0_m: float | None = None,
    ) -> np.ndarray:
        """The model's velocity for hit `index` driven by force_n (any length) [m/s].

        effects, mu and x0_m replace the model's own (a candidate's response, a derivative).
        """
        return self.run(index, force_n, sample_rate_hz, effects, mu, x0_m).velocity_m_s

    def run(
        self,
        index: int,
        force_n: np.ndarray,
        sample_rate_hz: float,
        effects: Sequence[ModelTerm] | None = None,
        mu: float | None = None,
        x0_m: float | None = None,
    ) -> Simulation:
        """The model's run of hit `index` driven by force_n, as `velocity` (its rest too).

        force_n is a measured force: the model scales it by the hit's impulse scale, where it
        fits one (a chained session's models do).
        """
        return simulate(
            force_n * self.impulse_scales[index],
            sample_rate_hz,
            rig=self.rig,
            mu=float(self.mus[index]) if mu is None else mu,
            effects=self.terms if effects is None else tuple(effects),
            x0_m=self.positions_m[index] if x0_m is None else x0_m,
        )

    def rests_m(self, impacts: Sequence[ConditionedImpact]) -> tuple[float, ...]:
        """Where the model's run of each impact leaves the rig [m].

        () unless a hit follows the one before it: only a chain needs them.
        """
        if not any(impact.follows_previous for impact in impacts):
            return ()
        return tuple(
            thread_map(
                lambda index: (
                    self.run(
                        index, impacts[index].force_n, impacts[index].sample_rate_hz
                    ).end_position_m
                ),
                range(len(impacts)),
            )
        )

    def moved_along_chain(
        self,
        impacts: Sequence[ConditionedImpact],
        rests_m: Sequence[float],
        change: Mapping[int, dict],
    ) -> dict[int, np.ndarray]:
        """The velocity of every hit a change moves [m/s], by hit.

        change: hit -> the changed arguments of its run (`run`'s force_n, effects, mu). The
        changed hits run, and after each, while the hits follow their previous one, the hits
        whose start the change moved, from their start moved by as much as the change moved
        the rest before them (`rests_m`, this model's own).
        """
        moved = {}
        shift = 0.0
        for index, impact in enumerate(impacts):
            if not impact.follows_previous:
                shift = 0.0
            if index not in change and shift == 0.0:
                continue
            arguments = {'force_n': impact.force_n, **change.get(index, {})}
            run = self.run(
                index,
                sample_rate_hz=impact.sample_rate_hz,
                x0_m=self.positions_m[index] + shift,
                **arguments,
            )
            moved[index] = run.velocity_m_s
            if rests_m:
                shift = run.end_position_m - rests_m[index]
        return moved

    def estimates(self) -> tuple[ParameterEstimate, ...]:
        """Fitted parameters: the joint fit's (mu, terms, starts), then each hit's mu."""
        joint = self.joint
        values = [
            ParameterEstimate(name, float(value), unit, float(error), name in joint.at_bounds)
            for name, value, unit, error in zip(
                joint.names, joint.values, joint.units, joint.stderr, strict=True
            )
        ]
        for index, fit in enumerate(self.per_hit):
            values.append(ParameterEstimate(f'{MU_DRIFT}.mu[{index}]', fit.mu, '1', fit.mu_stderr))
        return tuple(values)


def with_terms(
    impacts: Sequence[ConditionedImpact],
    model: SessionModel,
    effect: str,
    start: ModelTerm,
    fit_initial_position: bool,
    mu0: float | None = None,
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> SessionModel:
    """The model with one more term: every term refitted jointly from where it stands.

    mu0: where mu starts (default the model's). ranges: the terms' fitting ranges
    (`diagnostic_fit`). A model with mu_drift gets each hit's mu refitted again on top of the
    new joint fit. Raises FitError when the fitter refuses.
    """
    joint = diagnostic_fit(
        impacts,
        rig=model.rig,
        mu0=model.joint.mu if mu0 is None else mu0,
        terms=(*model.terms, start),
        fit_initial_position=fit_initial_position,
        ranges=ranges,
    )
    refitted = SessionModel((*model.effects, effect), joint)
    if MU_DRIFT in model.effects:
        return with_mu_per_hit(impacts, refitted, model.mus, fit_initial_position, add=False)
    return refitted


def with_mu_per_hit(
    impacts: Sequence[ConditionedImpact],
    model: SessionModel,
    mu_starts: Sequence[float],
    fit_initial_position: bool,
    *,
    add: bool = True,
) -> SessionModel:
    """Each hit's mu (and start) refitted alone, the joint fit's terms and rig held.

    add: name mu_drift as the newest effect (False: it is named already). Raises FitError when
    the fitter refuses a hit.
    """
    # A chained hit fitted alone starts where the joint model's chain put it.
    per_hit = tuple(
        diagnostic_fit(
            [replace(impact, start_m=start) if impact.follows_previous else impact],
            rig=model.rig,
            mu0=float(mu0),
            fixed_effects=model.terms,
            fit_initial_position=fit_initial_position,
        )
        for impact, mu0, start in zip(
            impacts, mu_starts, model.joint.initial_positions_m, strict=True
        )
    )
    effects = (*model.effects, MU_DRIFT) if add else model.effects
    return SessionModel(effects, model.joint, per_hit)


def without(
    impacts: Sequence[ConditionedImpact],
    model: SessionModel,
    effect: str,
    fit_initial_position: bool,
    ranges: Mapping[str, tuple[float, float]] | None = None,
) -> SessionModel:
    """The model with one named effect taken out, the rest refitted (the backward check).

    ranges: the terms' fitting ranges (`diagnostic_fit`).
    """
    kept = tuple(name for name in model.effects if name != effect)
    if effect == MU_DRIFT:
        return SessionModel(kept, model.joint)
    joint = diagnostic_fit(
        impacts,
        rig=model.rig,
        mu0=model.joint.mu,
        terms=tuple(term for term in model.terms if term.name != effect),
        fit_initial_position=fit_initial_position,
        ranges=ranges,
    )
    reduced = SessionModel(kept, joint)
    if MU_DRIFT in kept:
        return with_mu_per_hit(impacts, reduced, model.mus, fit_initial_position, add=False)
    return reduced
