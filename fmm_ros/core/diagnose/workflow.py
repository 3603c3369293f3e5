"""The discrepancy workflow: fit the base model, find where it misses, name the missing effect.

1. Fit the base model (Eq. 3, mu fitted, rig constants given) to every impact at once, with
   the fitter of `fmm_ros.core.identify`. Its default model fits neither a channel delay nor a
   velocity offset (the velocity is left as measured), so `sensor_delay` and
   `velocity_offset` stay visible to the diagnosis.
2. Find where it disagrees: the residual beyond the noise by region of the decay and by band,
   and the signatures that point at causes (`fmm_ros.core.diagnose.signatures`), measured
   beside the base model's own (`where`).
3. Refit the model once per candidate effect (`EFFECTS`, the names of `MODEL_TERMS`), each
   started where its signature points (`starts`), and score each with the Bayesian
   information criterion BIC = RSS / s^2 + k ln n, s the velocity noise estimated from the data
   (second differences), k the fitted parameters, n the samples.
4. Name the best candidate only when it is clearly better than the base model: its BIC is
   lower by at least `BIC_EVIDENCE` plus `INPUT_NOISE_FACTOR` times what the force noise
   alone could buy (`input_noise_allowance`), and it removes at least `EXPLAINED_GAP` of the
   gap. Otherwise the answer is 'none'.
5. The gap is the same measure before and after (`gaps`).
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.core.diagnose.gaps import frf_gap, gap, input_noise_allowance, motion_window
from fmm_ros.core.diagnose.result import Candidate, Diagnosis, ParameterEstimate, Where
from fmm_ros.core.diagnose.starts import second_mode_start, start_term
from fmm_ros.core.diagnose.where import locate_misfit
from fmm_ros.core.identify.conditioning import ConditionedImpact, FitError, as_conditioned
from fmm_ros.core.identify.friction import ModelFit, fit_model
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import MODEL_TERMS

EFFECTS: tuple[str, ...] = tuple(MODEL_TERMS)
"""Candidate effects, by the names of the model terms."""


NONE = 'none'


VOCABULARY: tuple[str, ...] = (*EFFECTS, NONE)


BIC_EVIDENCE = 10.0
"""A BIC difference of 10 is 'very strong' evidence (Kass and Raftery 1995)."""


INPUT_NOISE_FACTOR = 3.0
"""Also required: the BIC gain beats this many times the gain the force noise alone explains."""


EXPLAINED_GAP = 0.5
"""A named effect must at least halve the gap: gap_after <= (1 - this) x gap_before."""


SCREEN_SECOND_MODE = True
"""Screen the second mode with a score test before its full refit (see `_refit`)."""


def diagnose(
    impacts: Sequence,
    *,
    rig: Rig = FMM_RIG,
    candidates: Sequence[str] = EFFECTS,
    fit_initial_position: bool = False,
) -> Diagnosis:
    """Find the effect the base model (Eq. 3, mu fitted) misses in these impacts, if any.

    impacts: records with force_n, velocity_m_s and sample_rate_hz (CSV or simulated impact
    records) or ConditionedImpacts; every one is fitted at once. fit_initial_position: every
    model, base and candidates alike, also fits where each impact starts (a hit that found
    the rig held off centre by friction), as `fmm fit --fit-initial-position` does. Raises
    ValueError for bad input or a candidate outside EFFECTS, and FitError (a ValueError)
    when the base model cannot be fitted at all.
    """
    unknown = [name for name in candidates if name not in EFFECTS]
    if unknown:
        raise ValueError(
            f'unknown candidate effect(s) {", ".join(map(repr, unknown))}; '
            f'known: {", ".join(EFFECTS)}'
        )
    if isinstance(impacts, ConditionedImpact) or hasattr(impacts, 'force_n'):
        impacts = [impacts]
    conditioned = [as_conditioned(impact) for impact in impacts]
    if not conditioned:
        raise ValueError('no impacts to diagnose')
    base = fit_model(conditioned, rig=rig, fit_initial_position=fit_initial_position)
    noise = base.noise_std_m_s
    models = [
        impact.velocity_m_s - residual
        for impact, residual in zip(conditioned, base.residuals_m_s, strict=True)
    ]
    hits = [impact.gate[0][0] for impact in conditioned]
    windows = [
        motion_window(model, hit, impact.sample_rate_hz)
        for model, hit, impact in zip(models, hits, conditioned, strict=True)
    ]
    peak_speed = max(impact.peak_velocity_m_s for impact in conditioned)
    where = locate_misfit(conditioned, base, models, hits, rig)
    allowance = input_noise_allowance(conditioned, base, noise)
    required = -(BIC_EVIDENCE + INPUT_NOISE_FACTOR * allowance)

    def gaps(residuals):
        return (
            gap(residuals, windows, noise, peak_speed),
            frf_gap(conditioned, residuals, noise, rig.natural_frequency_hz),
        )

    gap_before, frf_gap_before = gaps(base.residuals_m_s)
    base_bic, base_aic = _criteria(base.residuals_m_s, noise, len(base.names), base.n_samples)
    tried, fits = [], {}
    for effect in candidates:
        refit, message = _refit(effect, conditioned, base, where, rig, fit_initial_position)
        if refit is None:
            tried.append(Candidate(effect, math.inf, math.inf, math.nan, math.nan, (), message))
            continue
        if isinstance(refit, ModelFit):
            fits[effect] = refit
        bic, aic = _criteria(refit.residuals_m_s, noise, len(refit.names), base.n_samples)
        tried.append(
            Candidate(
                effect,
                bic - base_bic,
                aic - base_aic,
                *gaps(refit.residuals_m_s),
                _estimates(refit),
                message,
            )
        )
    tried.sort(key=lambda c: c.score)
    named, verdict = _decide(tried, gap_before, required)
    chosen = fits[named] if named != NONE else base
    winner = next((c for c in tried if c.effect == named), None)
    return Diagnosis(
        missing_effect=named,
        parameters=_estimates(chosen),
        mu=base.mu,
        mu_stderr=base.mu_stderr,
        gap_before=gap_before,
        gap_after=winner.gap_after if winner else gap_before,
        frf_gap_before=frf_gap_before,
        frf_gap_after=winner.frf_gap_after if winner else frf_gap_before,
        where=where,
        candidates=tuple(tried),
        noise_std_m_s=noise,
        force_noise_std_n=_pooled_force_noise(conditioned),
        input_noise_allowance=allowance,
        required_score=required,
        verdict=verdict,
        base_residuals_m_s=base.residuals_m_s,
        named_residuals_m_s=chosen.residuals_m_s,
    )


def _decide(candidates: Sequence[Candidate], gap_before: float, required: float) -> tuple[str, str]:
    """(name, verdict): the best candidate if clearly better than the base model, else none."""
    usable = [c for c in candidates if math.isfinite(c.score)]
    if not usable:
        return NONE, 'no candidate could be refitted; the base model stands'
    best = usable[0]
    if best.score > required:
        return NONE, (
            f'no candidate beats the base model clearly (best: {best.effect}, score '
            f'{best.score:.1f} > required {required:.1f}): the base model explains '
            'the data within the noise'
        )
    if best.gap_after > (1.0 - EXPLAINED_GAP) * gap_before:
        return NONE, (
            f'{best.effect} scores best ({best.score:.1f}) but removes only '
            f'{100 * (1 - best.gap_after / gap_before):.0f} % of the gap; no single '
            'effect of the vocabulary explains the discrepancy'
        )
    runner = usable[1] if len(usable) > 1 else None
    margin = f', {runner.score - best.score:.0f} ahead of {runner.effect}' if runner else ''
    return best.effect, (
        f'{best.effect}: score {best.score:.0f} (required <= {required:.1f}'
        f'{margin}); gap {gap_before:.3g} -> {best.gap_after:.3g}'
    )


@dataclass(frozen=True)
class _Screened:
    """A candidate scored by its linearised start instead of a full refit (see `_refit`)."""

    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    stderr: np.ndarray
    residuals_m_s: tuple[np.ndarray, ...]


def _refit(
    effect: str,
    impacts: Sequence[ConditionedImpact],
    base: ModelFit,
    where: Where,
    rig: Rig,
    fit_initial_position: bool,
) -> tuple[ModelFit | _Screened | None, str]:
    """(fit, note): the base model plus one effect, refitted from its start.

    The second mode is screened first by a score test: its best start (the strongest residual
    peak, zeta and m2 by linear least squares, mu held) is the one-step estimate of the refit.
    Where that lowers chi^2 by less than the BIC penalty of the mode's three parameters, a
    full refit (many-valleyed in frequency, slow where there is no mode to find) could not
    make it a clear winner, so the candidate is scored at that start: residuals of the base
    model less the regressed mode, all four parameters counted, standard errors NaN. A refit
    the fitter refuses is reported with its reason, never named.
    """
    try:
        if effect == 'second_mode' and SCREEN_SECOND_MODE:
            screen = second_mode_start(impacts, base, rig)
            penalty = len(screen.term.parameters) * math.log(base.n_samples)
            if screen.chi2_gain < penalty:
                term = screen.term
                return _Screened(
                    names=(*base.names, *(f'{term.name}.{p.name}' for p in term.parameters)),
                    units=(*base.units, *(p.unit for p in term.parameters)),
                    values=np.concatenate((base.values, term.to_vector())),
                    stderr=np.concatenate((base.stderr, np.full(len(term.parameters), math.nan))),
                    residuals_m_s=screen.residuals_m_s,
                ), (
                    f'screened: its best start lowers chi^2 by {screen.chi2_gain:.1f}, less '
                    f'than the BIC penalty {penalty:.1f} of its parameters; not refitted'
                )
            start = screen.term
        else:
            start = start_term(effect, impacts, base, where, rig)
        return fit_model(
            impacts, rig=rig, mu0=base.mu, terms=(start,), fit_initial_position=fit_initial_position
        ), ''
    except FitError as error:
        return None, f'refit failed: {error}'


def _criteria(
    residuals: Sequence[np.ndarray], noise_std_m_s: float, k: int, n: int
) -> tuple[float, float]:
    """(BIC, AIC) of a time-domain fit of k parameters over n samples, noise level given.

    Both up to a constant common to every model of the same records.
    """
    chi2 = sum(float(r @ r) for r in residuals) / noise_std_m_s**2
    return chi2 + k * math.log(n), chi2 + 2.0 * k


def _estimates(fit: ModelFit | _Screened) -> tuple[ParameterEstimate, ...]:
    return tuple(
        ParameterEstimate(name, float(value), unit, float(error))
        for name, value, unit, error in zip(
            fit.names, fit.values, fit.units, fit.stderr, strict=True
        )
    )


def _pooled_force_noise(impacts: Sequence[ConditionedImpact]) -> float:
    return math.sqrt(float(np.mean([impact.force_noise_std_n**2 for impact in impacts])))
