"""The discrepancy workflow: fit the base model, find where it misses, name the missing effect.

1. Fit the base model (Eq. 3, mu fitted, rig constants given) to every impact at once, with
   the fitter of `fmm_ros.core.fit`. Its default model fits neither a channel delay nor a
   velocity offset (the velocity is left as measured), so `sensor_delay` and
   `velocity_offset` stay visible to the diagnosis.
2. Find where it disagrees: the residual beyond the noise by region of the decay and by band,
   and the signatures that point at causes (`fmm_ros.core.discrepancy`), measured beside the
   base model's own.
3. Refit the model once per candidate effect (`EFFECTS`, the names of `MODEL_TERMS`), each
   started where its signature points, and score each with the Bayesian information criterion
   BIC = RSS / s^2 + k ln n, s the velocity noise estimated from the data (second
   differences), k the fitted parameters, n the samples.
4. Name the best candidate only when it is clearly better than the base model: its BIC is
   lower by at least `BIC_EVIDENCE` plus `INPUT_NOISE_FACTOR` times what the force noise
   alone could buy (`input_noise_allowance`), and it removes at least `EXPLAINED_GAP` of the
   gap. Otherwise the answer is 'none'.
5. The gap is the same measure before and after: the RMS of the velocity residual beyond the
   noise, over the motion (hit to rest + `SETTLE_S`), over the largest measured speed; and the
   mobility misfit beyond the noise over f_n/2 to `FRF_BAND_LIMIT_HZ`.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from fmm_ros.core import discrepancy, frf
from fmm_ros.core.export import json_number
from fmm_ros.core.fit import ConditionedImpact, FitError, ModelFit, as_conditioned, fit_model
from fmm_ros.core.model import FMM_RIG, MODEL_TERMS, ModelTerm, Rig, model_term, simulate

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
SETTLE_S = 1.0
"""The gap's motion window runs this long past the base model's rest."""
SCREEN_SECOND_MODE = True
"""Screen the second mode with a score test before its full refit (see `_refit`)."""
FRF_BAND_LIMIT_HZ = 20.0
"""Top of the FRF misfit band (f_n and its odd harmonics to the 9th, the paper's Fig. 24)."""


@dataclass(frozen=True)
class ParameterEstimate:
    """A fitted parameter: name (as the fitter names it), value, SI unit, standard error."""

    name: str
    value: float
    unit: str
    stderr: float


@dataclass(frozen=True)
class Candidate:
    """One augmented model, refitted: its score against the base model and its gap."""

    effect: str
    score: float
    """BIC of this model minus the base model's: negative is better [-]."""
    aic_score: float
    """The same with the AIC penalty 2k instead of k ln n [-]."""
    gap_after: float
    frf_gap_after: float
    parameters: tuple[ParameterEstimate, ...]
    """The augmented model's fitted parameters (mu first)."""
    message: str = ''
    """Why the refit failed, if it did (score and gaps are then inf / NaN)."""


@dataclass(frozen=True)
class Where:
    """Where the base model disagrees with the measurement: regions, bands, signatures."""

    summary: str
    time: tuple[discrepancy.RegionMisfit, ...]
    frequency: tuple[discrepancy.BandMisfit, ...]
    peaks: tuple[discrepancy.SpectralPeak, ...]
    """Narrow-band residual peaks that are not odd harmonics of f_n."""
    measured: tuple[discrepancy.DecaySignatures, ...]
    """Decay signatures of each measured record."""
    model: tuple[discrepancy.DecaySignatures, ...]
    """The same signatures of the base model's response to each record's force."""
    rest_velocity_m_s: float
    """Mean measured velocity where the base model is at rest [m/s]."""
    rest_velocity_stderr_m_s: float
    phase_delay_s: float
    """Delay of the measured velocity behind the base model's, from their phase slope [s]."""


@dataclass(frozen=True)
class Diagnosis:
    """What `diagnose` found: the named effect (or 'none'), the gap before and after, why."""

    missing_effect: str
    parameters: tuple[ParameterEstimate, ...]
    """The named model's fitted parameters (the base model's when 'none')."""
    mu: float
    """Friction coefficient of the base fit [-]."""
    mu_stderr: float
    gap_before: float
    """Normalised RMS velocity residual beyond the noise, base model [-]."""
    gap_after: float
    """The same with the named effect added (= gap_before for 'none') [-]."""
    frf_gap_before: float
    """Normalised mobility misfit beyond the noise, base model [-]."""
    frf_gap_after: float
    where: Where
    candidates: tuple[Candidate, ...]
    """Every candidate, best score first."""
    noise_std_m_s: float
    """Velocity noise estimated from the data [m/s]."""
    force_noise_std_n: float
    input_noise_allowance: float
    """Expected chi^2 the force noise alone puts into the base residual [-]."""
    required_score: float
    """A candidate is named only with a score at or below this (and the gap halved) [-]."""
    verdict: str
    """One sentence: what was named and why, or why nothing was."""
    base_residuals_m_s: tuple[np.ndarray, ...] = field(repr=False)
    """Measured minus base-model velocity per impact [m/s] (for figures)."""
    named_residuals_m_s: tuple[np.ndarray, ...] = field(repr=False)
    """Measured minus named-model velocity per impact [m/s] (base again for 'none')."""

    def to_dict(self) -> dict:
        """JSON-ready (undefined numbers are None): the keys of `fmm diagnose --json`."""
        return _json_safe(
            {
                'missing_effect': self.missing_effect,
                'parameters': {p.name: p.value for p in self.parameters},
                'parameter_units': {p.name: p.unit for p in self.parameters},
                'parameter_stderr': {p.name: p.stderr for p in self.parameters},
                'mu': self.mu,
                'mu_stderr': self.mu_stderr,
                'gap_before': self.gap_before,
                'gap_after': self.gap_after,
                'frf_gap_before': self.frf_gap_before,
                'frf_gap_after': self.frf_gap_after,
                'where': _where_dict(self.where),
                'candidates': [
                    {
                        'effect': c.effect,
                        'score': c.score,
                        'aic_score': c.aic_score,
                        'gap_after': c.gap_after,
                        'frf_gap_after': c.frf_gap_after,
                        'parameters': {p.name: p.value for p in c.parameters},
                        'parameter_stderr': {p.name: p.stderr for p in c.parameters},
                        **({'message': c.message} if c.message else {}),
                    }
                    for c in self.candidates
                ],
                'noise_std_m_s': self.noise_std_m_s,
                'force_noise_std_n': self.force_noise_std_n,
                'input_noise_allowance': self.input_noise_allowance,
                'required_score': self.required_score,
                'verdict': self.verdict,
            }
        )


def _json_safe(value):
    """Plain floats all the way down, NaN and infinities as None (JSON has neither)."""
    if isinstance(value, dict):
        return {key: _json_safe(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(item) for item in value]
    if isinstance(value, (float, np.floating)):
        return json_number(value)
    return value


def _where_dict(where: Where) -> dict:
    return {
        'summary': where.summary,
        'time': [
            {
                'region': r.name,
                'share': r.share,
                'excess_rms_m_s': r.excess_rms_m_s,
                'mean_m_s': r.mean_m_s,
                'samples': r.samples,
            }
            for r in where.time
        ],
        'frequency': [
            {'band': b.name, 'low_hz': b.low_hz, 'high_hz': b.high_hz, 'share': b.share}
            for b in where.frequency
        ],
        'non_harmonic_peaks_hz': [p.frequency_hz for p in where.peaks],
        'rest_velocity_m_s': where.rest_velocity_m_s,
        'rest_velocity_stderr_m_s': where.rest_velocity_stderr_m_s,
        'phase_delay_s': where.phase_delay_s,
        'signatures': [
            {'measured': _signature_dict(m), 'model': _signature_dict(s)}
            for m, s in zip(where.measured, where.model, strict=True)
        ],
    }


def _signature_dict(signature: discrepancy.DecaySignatures) -> dict:
    return dict(vars(signature))


# --- the workflow ------------------------------------------------------------------------------


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
        _motion_window(model, hit, impact.sample_rate_hz)
        for model, hit, impact in zip(models, hits, conditioned, strict=True)
    ]
    peak_speed = max(impact.peak_velocity_m_s for impact in conditioned)
    where = _where(conditioned, base, models, hits, rig)
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
            screen = _second_mode_start(impacts, base, rig)
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


# --- gaps ---------------------------------------------------------------------------------------


def _motion_window(model_m_s: np.ndarray, hit_index: int, sample_rate_hz: float) -> slice:
    """From the hit to SETTLE_S after the model's last moving sample."""
    moving = np.flatnonzero(model_m_s[hit_index:] != 0.0)
    last = hit_index + (int(moving[-1]) if moving.size else 0)
    return slice(hit_index, min(model_m_s.size, last + 1 + round(SETTLE_S * sample_rate_hz)))


def gap(
    residuals: Sequence[np.ndarray],
    windows: Sequence[slice],
    noise_std_m_s: float,
    peak_speed_m_s: float,
) -> float:
    """RMS of the velocity residual beyond the noise over the motion windows / peak speed [-]."""
    inside = np.concatenate([r[w] for r, w in zip(residuals, windows, strict=True)])
    return discrepancy.excess_rms(inside, noise_std_m_s) / peak_speed_m_s


def frf_gap(
    impacts: Sequence[ConditionedImpact],
    residuals: Sequence[np.ndarray],
    noise_std_m_s: float,
    natural_frequency_hz: float,
) -> float:
    """Mobility misfit beyond the noise, relative to the measured mobility [-].

    sqrt((sum |R/F|^2 - n s^2 sum 1/|F|^2) / sum |V/F|^2) over the bins from f_n / 2 to
    FRF_BAND_LIMIT_HZ and over impacts, R, V, F the DFTs of residual, measured velocity and
    conditioned force: the residual is the model's mobility error times F.
    """
    misfit = noise = total = 0.0
    for impact, residual in zip(impacts, residuals, strict=True):
        n = residual.size
        frequency = frf.frequency_axis(n, impact.sample_rate_hz)
        band = (frequency >= 0.5 * natural_frequency_hz) & (frequency <= FRF_BAND_LIMIT_HZ)
        force, velocity = frf.spectra(impact.force_n, impact.velocity_m_s)
        _, error = frf.spectra(impact.force_n, residual)
        inverse_power = 1.0 / np.maximum(np.abs(force[band]) ** 2, np.finfo(float).tiny)
        misfit += float(np.sum(np.abs(error[band]) ** 2 * inverse_power))
        noise += n * noise_std_m_s**2 * float(np.sum(inverse_power))
        total += float(np.sum(np.abs(velocity[band]) ** 2 * inverse_power))
    return math.sqrt(max(misfit - noise, 0.0) / total) if total > 0.0 else math.nan


def input_noise_allowance(
    impacts: Sequence[ConditionedImpact], base: ModelFit, noise_std_m_s: float
) -> float:
    """chi^2 the force noise inside the hit puts into the base residual, expected [-].

    Output-error fitting takes the measured force as exact, but its noise changes each
    impulse by `ConditionedImpact.impulse_std_n_s`, and the model's response with it; a
    candidate term can absorb part of that, which is no evidence of the term. The response to
    a relative impulse change, d v / d scale, comes from one extra simulation per impact; the
    allowance is sum_i |d v_i / d scale|^2 (s_I,i / I_i)^2 / s_v^2.
    """
    total = 0.0
    step = 1e-3
    for index, impact in enumerate(impacts):
        relative = impact.impulse_std_n_s / abs(impact.impulse_n_s)
        scaled = simulate(
            impact.force_n * (1.0 + step),
            impact.sample_rate_hz,
            rig=base.rig,
            mu=base.mu,
            effects=base.effects,
            x0_m=base.initial_positions_m[index],
        ).velocity_m_s
        sensitivity = (scaled - base.simulate(index).velocity_m_s) / step
        total += float(sensitivity @ sensitivity) * relative**2
    return total / noise_std_m_s**2


# --- where ---------------------------------------------------------------------------------------


def _where(
    impacts: Sequence[ConditionedImpact],
    base: ModelFit,
    models: Sequence[np.ndarray],
    hits: Sequence[int],
    rig: Rig,
) -> Where:
    noise = base.noise_std_m_s
    rate = impacts[0].sample_rate_hz
    f_n = rig.natural_frequency_hz
    regions = discrepancy.time_regions(base.residuals_m_s, models, hits, noise)
    bands = discrepancy.frequency_bands(base.residuals_m_s, rate, f_n, noise)
    peaks = discrepancy.non_harmonic_peaks(base.residuals_m_s, rate, f_n, noise)
    measured = tuple(
        discrepancy.decay_signatures(i.velocity_m_s, rate, h, f_n)
        for i, h in zip(impacts, hits, strict=True)
    )
    simulated = tuple(
        discrepancy.decay_signatures(m, rate, h, f_n) for m, h in zip(models, hits, strict=True)
    )
    rest = [
        discrepancy.rest_velocity(i.velocity_m_s, m, h, noise)
        for i, m, h in zip(impacts, models, hits, strict=True)
    ]
    weights = np.array([1.0 / e**2 if math.isfinite(e) else 0.0 for _, e in rest])
    if weights.sum() > 0.0:
        rest_mean = float(np.sum(weights * np.nan_to_num([m for m, _ in rest])) / weights.sum())
        rest_error = float(1.0 / math.sqrt(weights.sum()))
    else:
        rest_mean = rest_error = math.nan
    delays = [
        discrepancy.phase_delay_s(i.velocity_m_s, m, rate, f_n)
        for i, m in zip(impacts, models, strict=True)
    ]
    delay = float(np.nanmedian(delays)) if np.any(np.isfinite(delays)) else math.nan
    summary = _summary(regions, bands, peaks, rest_mean, rest_error, noise)
    return Where(summary, regions, bands, peaks, measured, simulated, rest_mean, rest_error, delay)


def _summary(regions, bands, peaks, rest_mean, rest_error, noise) -> str:
    worst = max(regions, key=lambda r: r.share)
    band = max(bands, key=lambda b: b.share)
    if worst.share == 0.0:
        return 'nowhere beyond the noise'
    parts = [
        f'time: {worst.name} ({100 * worst.share:.0f} % of the excess misfit, '
        f'{worst.excess_rms_m_s / noise:.1f}x the noise RMS there)',
        f'frequency: {band.name} ({100 * band.share:.0f} %)',
    ]
    if peaks:
        parts.append(
            'non-harmonic peak at ' + ', '.join(f'{p.frequency_hz:.1f} Hz' for p in peaks[:2])
        )
    if math.isfinite(rest_mean) and abs(rest_mean) > 5.0 * rest_error:
        parts.append(f'velocity at rest {rest_mean:.3g} m/s')
    return '; '.join(parts)


# --- start values -------------------------------------------------------------------------------


def start_term(
    effect: str, impacts: Sequence[ConditionedImpact], base: ModelFit, where: Where, rig: Rig
) -> ModelTerm:
    """Where to start the refit of one candidate: from the signature that points at it.

    Each is a rough estimate from the measured-minus-model signatures, clipped into the term's
    plausible bounds; the refit does the rest. The second mode, whose misfit is many-valleyed
    in frequency, starts from the strongest residual peak with its damping ratio and modal
    mass chosen by linear least squares over a few damping ratios.
    """
    cls = MODEL_TERMS[effect]
    lower, upper = cls.bounds()

    def clipped(*values: float) -> ModelTerm:
        return cls.from_vector(np.clip(values, lower, upper))

    pairs = [
        (m, s)
        for m, s in zip(where.measured, where.model, strict=True)
        if m.half_cycles >= 3 and s.half_cycles >= 3
    ]

    def difference(attribute: str) -> float:
        values = [getattr(m, attribute) - getattr(s, attribute) for m, s in pairs]
        values = [v for v in values if math.isfinite(v)]
        return float(np.median(values)) if values else math.nan

    stiffness, mass = rig.stiffness_n_per_m, rig.mass_kg
    if effect == 'viscous_damping':
        slopes = [
            (m.peak_map_slope, s.peak_map_slope)
            for m, s in pairs
            if m.peak_map_slope > 0 and s.peak_map_slope > 0
        ]
        zeta = (
            float(np.median([math.log(s / m) / math.pi for m, s in slopes])) if slopes else math.nan
        )
        added = 2.0 * zeta * math.sqrt(stiffness * mass)
        return clipped(added if math.isfinite(added) and added > 0.01 else 0.2)
    if effect == 'stribeck':
        return clipped(0.03, 2e-3)
    if effect == 'asymmetric_friction':
        # Centres alternate between -mu+ N / k and +mu- N / k: their mean is -d N / (2k).
        shift = difference('centre_m')
        d = -2.0 * stiffness * shift / rig.normal_force_n if math.isfinite(shift) else 0.0
        return clipped(d if abs(d) > 1e-3 else 5e-3)
    if effect == 'cubic_stiffness':
        # Duffing: half period T0 (1 - 3 k3 A^2 / (8 k)), so dT / d(A^2) = -3 k3 T0 / (8 k).
        slope = difference('half_period_amplitude_slope_s_per_m2')
        half_period = math.pi * math.sqrt(mass / stiffness)
        k3 = -8.0 * stiffness * slope / (3.0 * half_period) if math.isfinite(slope) else 0.0
        return clipped(k3 if abs(k3) > 1e3 else 1e4)
    if effect == 'velocity_offset':
        offset = where.rest_velocity_m_s
        return clipped(offset if math.isfinite(offset) else 0.0)
    if effect == 'sensor_delay':
        delay = where.phase_delay_s
        return clipped(
            delay if math.isfinite(delay) and delay > 0.0 else 1.0 / impacts[0].sample_rate_hz
        )
    if effect == 'second_mode':
        return _second_mode_start(impacts, base, rig).term
    raise ValueError(f'no start rule for {effect!r}')


SECOND_MODE_DAMPING_RATIOS = (3e-3, 1e-2, 3e-2)
"""Damping ratios tried for the second mode's start (its modal mass solved for each)."""


@dataclass(frozen=True)
class _ModeStart:
    term: ModelTerm
    chi2_gain: float
    """Fall of the residual chi^2 the start mode alone gives, mu held (a score test) [-]."""
    residuals_m_s: tuple[np.ndarray, ...]
    """The base residuals less that mode's response."""


def _second_mode_start(
    impacts: Sequence[ConditionedImpact], base: ModelFit, rig: Rig
) -> _ModeStart:
    """Start at the strongest residual peak above 1.5 f_n, with zeta and m2 by least squares.

    The mode is linear and decoupled from the friction contact, so its velocity is the base
    model's with the mode minus the base model's, and scales as 1 / m2: for each trial zeta,
    one simulation per impact with m2 = 1 kg and a one-parameter regression of the residual.
    Without a peak, or where no trial lowers the residual, the start is the mode at its
    heaviest and the gain zero.
    """
    cls = MODEL_TERMS['second_mode']
    noise = base.noise_std_m_s
    rate = impacts[0].sample_rate_hz
    peaks = discrepancy.non_harmonic_peaks(
        base.residuals_m_s,
        rate,
        rig.natural_frequency_hz,
        noise,
        count=1,
        threshold=0.0,
        skip_harmonics=False,
    )
    lower, upper = cls.bounds()
    frequency = peaks[0].frequency_hz if peaks else cls.parameters[0].default
    best = _ModeStart(cls(frequency_hz=frequency, modal_mass_kg=upper[2]), 0.0, base.residuals_m_s)
    if not peaks:
        return best
    models = _base_models(impacts, base)
    for zeta in SECOND_MODE_DAMPING_RATIOS:
        unit = model_term(
            'second_mode', frequency_hz=frequency, damping_ratio=zeta, modal_mass_kg=1.0
        )
        shapes = [
            simulate(
                impact.force_n,
                rate,
                rig=base.rig,
                mu=base.mu,
                effects=(*base.effects, unit),
                x0_m=base.initial_positions_m[index],
            ).velocity_m_s
            - model
            for index, (impact, model) in enumerate(zip(impacts, models, strict=True))
        ]
        numerator = sum(float(s @ r) for s, r in zip(shapes, base.residuals_m_s, strict=True))
        denominator = sum(float(s @ s) for s in shapes)
        if numerator <= 0.0 or denominator == 0.0:
            continue
        mass = float(np.clip(denominator / numerator, lower[2], upper[2]))  # 1 / scale
        residuals = tuple(r - s / mass for r, s in zip(base.residuals_m_s, shapes, strict=True))
        gain = (
            sum(float(r @ r) for r in base.residuals_m_s) - sum(float(r @ r) for r in residuals)
        ) / noise**2
        if gain > best.chi2_gain:
            best = _ModeStart(
                cls(frequency_hz=frequency, damping_ratio=zeta, modal_mass_kg=mass), gain, residuals
            )
    return best


def _base_models(impacts: Sequence[ConditionedImpact], base: ModelFit) -> list[np.ndarray]:
    return [
        impact.velocity_m_s - residual
        for impact, residual in zip(impacts, base.residuals_m_s, strict=True)
    ]
