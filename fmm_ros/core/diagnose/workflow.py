"""The discrepancy workflow: what the base model misses, named effect by effect, or 'unexplained'.

1. Check and condition the records; crop every one to the measured motion (the longest
   record's, `measured_motion_stop`): the rest of a 33 s record is the rig at rest, which
   every model predicts alike, and fitting it cost most of the time.
2. Fit the base model (Eq. 3, mu fitted, rig constants given) to every impact at once with
   `fit_model`. Its default model fits neither a channel delay nor a velocity offset, so
   `sensor_delay` and `velocity_offset` stay visible to the diagnosis.
3. Where it disagrees (`where`), and the signatures that start the candidates (`starts`).
4. Forward selection. At the current model every remaining candidate (`EFFECTS`: the model
   terms, and `mu_drift`, one mu per hit) is screened (`screen`: the chi^2 one linearised
   step could remove); the best `MAX_REFITS` whose screen reaches `SCREEN_FRACTION` of the
   required gain are refitted in full (and, when none of them qualifies while the misfit is
   `MIN_EXCESS` beyond the noise, or the only one that does ends with its size on its
   physical bound, the other screens that reach `SCREEN_FRACTION`, best first, until one
   does within its range), and the best refit within its range is added when it is clearly better
   (BIC lower by `BIC_EVIDENCE` plus `INPUT_NOISE_FACTOR` times what the force noise alone
   explains, the required score), removes at least `MIN_STEP_SHARE` of the squared gap left
   at that step, accounts for at least `MIN_EXCESS` of the noise RMS (sqrt of the fall of
   the squared excess over the motion; from `MIN_WHOLE_EXCESS` when it is the whole misfit,
   removing `WHOLE_MISFIT_SHARE` of the step's squared gap), and, for `mu_drift`, the
   refitted per-hit mu trend
   in hit order (p < `DRIFT_P_VALUE`) from `MIN_TREND_HITS` hits; with fewer (one hit a
   level), the hits' own mu differing beyond their errors and `MU_SPREAD_FLOOR` of mu
   (p < `DRIFT_P_VALUE`), and no hit's own friction map changing with speed
   (p < `SPEED_LAW_P_VALUE`) unless the hits' maps on shared speed bins fit a mu per hit
   better than one curve of speed (a speed law, not a drift, otherwise).
   Repeat until no candidate qualifies.
5. Backward check: with two or more named, each is taken out in turn (the rest refitted);
   one whose removal costs less than the required score is dropped, and the check repeats.
6. Verdict. The named set must at least halve the gap (`EXPLAINED_GAP`), or no vocabulary
   name is given. The data are 'unexplained' when what is left, by the named model or by
   the base model when nothing is named, is still `MIN_EXCESS` times the noise RMS
   beyond the noise over the motion; with names that halve the gap, 'unexplained' comes
   first and the names are marked partial. Where the residual sits (regions, bands, speed,
   position) is reported either way.
7. The friction law the records show (`friction_map`), the per-hit mu trend (`drift`), and
   the residuals of the base and final models over the whole records.
"""

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.optimize

from fmm_ros.constants import MU_DRIFT
from fmm_ros.core._threads import thread_map
from fmm_ros.core.diagnose.calibration import rest_noise_std, without_impulse_error
from fmm_ros.core.diagnose.drift import MIN_DRIFT_HITS, MIN_TREND_HITS, MuTrend, mu_trend
from fmm_ros.core.diagnose.friction_map import (
    HIT_GUARD_S,
    FrictionCurve,
    FrictionMap,
    MapRecord,
    friction_map,
    speed_table,
)
from fmm_ros.core.diagnose.gaps import (
    frf_gap,
    gap,
    input_noise_allowance,
    measured_motion_stop,
    motion_window,
)
from fmm_ros.core.diagnose.result import (
    Candidate,
    Diagnosis,
    NamedEffect,
    ParameterEstimate,
    ResidualLocation,
    Where,
)
from fmm_ros.core.diagnose.screen import (
    Linearisation,
    Naming,
    Screen,
    screen_drift,
    screen_term,
    screened_hits,
)
from fmm_ros.core.diagnose.session_model import (
    SessionModel,
    diagnostic_fit,
    with_mu_per_hit,
    with_terms,
    without,
)
from fmm_ros.core.diagnose.starts import mode_limit_probes, probes
from fmm_ros.core.diagnose.vocabulary import (  # noqa: F401 (VOCABULARY re-exported)
    EFFECTS,
    NONE,
    UNEXPLAINED,
    VOCABULARY,
)
from fmm_ros.core.diagnose.where import locate_misfit, locate_residual
from fmm_ros.core.distributions import chi2_isf, chi2_sf, t_isf
from fmm_ros.core.identify.chain import DRIFT_KNOT_S
from fmm_ros.core.identify.conditioning import (
    ConditionedImpact,
    as_conditioned,
    chained_starts,
    cropped_impact,
    source_prefix,
)
from fmm_ros.core.identify.friction import fit_model
from fmm_ros.core.identify.lsq import inner
from fmm_ros.core.identify.spec import FRICTION_FIT, FitSpec
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import EFFECT_SIZE, MODEL_TERMS, physical_ranges
from fmm_ros.core.signal.response import VELOCITY, converted_noise
from fmm_ros.errors import BadInputError, FitError

BIC_EVIDENCE = 10.0
"""A BIC difference of 10 is 'very strong' evidence (Kass and Raftery 1995)."""


INPUT_NOISE_FACTOR = 3.0
"""Also required: the BIC gain beats this many times the gain the force noise alone explains."""


EXPLAINED_GAP = 0.5
"""The named effects together must at least halve the gap: gap_after <= (1 - this) x before."""


MIN_STEP_SHARE = 0.25
"""Each effect added removes at least this share of the squared gap left at its step: the gap
shrinks clearly. Of the step's gap, not the base model's: of two effects whose signatures
overlap, the first added takes most of the other's share too, and once the first is in, most
of what is left is the second's; a term that only trims a law outside the vocabulary removes
much less."""


MIN_EXCESS = 0.5
"""The smallest misfit the diagnosis speaks of, as RMS beyond the noise over the motion in
units of the noise RMS: an effect is named only if it accounts for this much (or for
MIN_WHOLE_EXCESS as the whole misfit), and what the best model leaves is 'unexplained' from
this much. (A worlds vibrometer whose zero drifts by
0.2 of the noise over a session is real, and BIC over 40,000 samples a hit finds it, but it
is not what a diagnosis of the rig is for; a right answer leaves 0.0-0.15.)"""


WHOLE_MISFIT_SHARE = 0.9
"""An effect smaller than MIN_EXCESS is still named when it is the whole misfit: it removes at
least this share of the squared gap left at its step (and accounts for MIN_WHOLE_EXCESS).

The floor MIN_EXCESS guards against terms that chase the model's own error: a world's
unmodelled DAQ chain leaves a broad misfit of 0.3-0.9x the noise, of which a wrong term
(mu_drift, viscous damping, Stribeck) takes a part. On the tuning worlds (ours, worlds,
steps, ivp, moreau; seed 2019) every wrong term of 0.3-0.5x the noise that the floor alone
refused removed at most 85 % of its step's squared gap (59 of them, all but one at most
77 %); the true effects it refused at the first step (cubic, Stribeck, a second mode and
chained asymmetric friction, 0.39-0.48x the noise) removed 93-100 %, leaving 0.0-0.13x the
noise, as a right answer leaves."""


MIN_WHOLE_EXCESS = 0.3
"""The smallest effect named as the whole misfit, in units of the noise RMS, as MIN_EXCESS: a
worlds vibrometer's zero drifting by 0.2-0.3 of the noise removes up to 80 % of a clean
session's small gap, and is not what a diagnosis of the rig is for; on the tuning worlds the
one wrong term that removed a whole gap accounted for 0.26x the noise."""


DRIFT_P_VALUE = 1e-3
"""mu_drift is named only when the per-hit mu trend in hit order at least this significantly
(from MIN_TREND_HITS hits; with fewer, when they differ beyond their errors this much)."""


MU_SPREAD_FLOOR = 5e-3
"""With fewer than MIN_TREND_HITS hits, the hits' own mu must differ beyond their errors
combined with this fraction of mu: a hit's own mu takes up its impulse misstatement (a
sampled, filtered, gated pulse misstates it by up to 2e-3) and more of the noise's colour
than its standard error says (the per-hit mu of a cubic `steps` session spread 0.5 % with
1e-5 errors; a drift of 4 % a hit is eight times that)."""


SPEED_LAW_P_VALUE = 1e-3
"""With fewer than MIN_TREND_HITS hits, mu_drift is not named when the friction map of any
one hit changes with speed this significantly (a speed law, not a drift), unless the hits'
maps side by side fit a mu per hit better than one curve of speed (`_drift_and_speed_law_aic`:
a hit's map also bends where coloured noise shifts its integrated displacement)."""


SCREEN_FRACTION = 0.5
"""A candidate is refitted only when its screen predicts at least this share of the required
BIC gain (a refit finds more than the linear step, rarely twice as much)."""


MAX_REFITS = 2
"""Candidates refitted in full per selection step, best screens first."""


RUNNER_UP_FRACTION = 0.3
"""A candidate after the best screen is refitted only if its screen reaches this fraction of
the best's: the screen ranks well, and a refit with little to find wanders longest."""


MIN_DECAY_PERIODS = 3.0
"""A record must run this many natural periods after its hit for a decay to be seen."""


Progress = Callable[[str], None]


def diagnose(
    impacts: Sequence,
    *,
    rig: Rig = FMM_RIG,
    candidates: Sequence[str] | None = None,
    fit_initial_position: bool = False,
    chain_starts: bool = False,
    friction_spec: FitSpec | None = None,
    progress: Progress | None = None,
) -> Diagnosis:
    """Find the effects the base model (Eq. 3, mu fitted) misses in these impacts, if any.

    impacts: records with force_n, velocity_m_s and sample_rate_hz (CSV or simulated impact
    records) or ConditionedImpacts, in hit order (mu_drift looks for a trend in it); every
    one is fitted at once. candidates: effects to consider (default: every one of EFFECTS,
    mu_drift only from MIN_DRIFT_HITS hits). fit_initial_position: every model also fits
    where each impact starts (a hit that found the rig held off centre by friction), as
    `fmm fit --fit-initial-position` does. chain_starts: the impacts are one continuous
    session in hit order, nothing moving the rig between records, the first hit from rest
    at the centre: every model starts each later hit where its own run of the hit before
    came to rest (`chained_starts`; replaces fit_initial_position, whose fitted starts
    absorb a direction-dependent friction). friction_spec: the fit `fmm fit` makes of these
    records (default `FRICTION_FIT`: each hit's impulse scale, mains hum and velocity drift
    fitted, starts as fit_initial_position), whose mu the diagnosis reports as its `mu`, so
    the two never disagree on the same records. progress: called with a line of text after each
    screen, refit and selection step. Raises ValueError naming the problem for bad input
    (no impacts, a non-finite sample, a record too short to show a decay, mixed sample rates,
    an unknown candidate, mu_drift with too few hits), and FitError (a ValueError) when the
    base model cannot be fitted at all.
    """
    say = progress or _silent
    starts = FitSpec(fit_initial_position=fit_initial_position, chain_starts=chain_starts).starts
    if isinstance(impacts, ConditionedImpact) or hasattr(impacts, 'force_n'):
        impacts = [impacts]
    checked = _checked_impacts(impacts, rig)
    if chain_starts:
        checked, fit_initial_position = chained_starts(checked), False
    conditioned, residual_noise = _integrated_as_judged(impacts, checked, rig, fit_initial_position)
    candidates = _checked_candidates(candidates, len(conditioned))
    stop = max(measured_motion_stop(impact, rig.natural_frequency_hz) for impact in conditioned)
    cropped = [cropped_impact(impact, stop) for impact in conditioned]
    base = SessionModel(
        (), diagnostic_fit(cropped, rig=rig, fit_initial_position=fit_initial_position)
    )
    say(
        f'base model fitted to {len(cropped)} impact(s), {stop / cropped[0].sample_rate_hz:.1f} s '
        f'each: mu = {base.joint.mu:.5f}'
    )
    spec = friction_spec or FRICTION_FIT.but(fit_initial_position=fit_initial_position)
    friction = fit_model(cropped, spec.but(chain_starts=True) if chain_starts else spec, rig=rig)
    say(f"fmm fit's base fit (impulse scales, hum, drift): mu = {friction.mu:.6f}")
    # An integrated record's noise is described by `converted_noise` (_integrated_as_judged);
    # a measured velocity's is measured where the rig rests (`calibration`).
    rest_noise = (
        rest_noise_std(conditioned, stop, base.joint.noise_std_m_s)
        if residual_noise is None
        else base.joint.noise_std_m_s
    )
    session = _Session(cropped, base, rig, fit_initial_position, residual_noise, rest_noise, say)
    selection = session.select(candidates)
    diagnosis = session.conclude(conditioned, selection, MU_DRIFT in candidates, starts)
    return replace(diagnosis, mu=friction.mu, mu_stderr=friction.mu_stderr)


def _silent(_message: str) -> None:
    """The default progress callback: nothing."""


def _checked_impacts(impacts: Sequence, rig: Rig) -> list[ConditionedImpact]:
    conditioned = [as_conditioned(impact) for impact in impacts]
    if not conditioned:
        raise BadInputError('no impacts to diagnose')
    rates = {impact.sample_rate_hz for impact in conditioned}
    if len(rates) > 1:
        raise BadInputError(
            f'the impacts have different sample rates ({", ".join(f"{r:g}" for r in rates)} '
            'Hz): diagnose records of one rate together'
        )
    need_s = MIN_DECAY_PERIODS / rig.natural_frequency_hz
    for impact in conditioned:
        after_s = (impact.force_n.size - impact.hit_end_index) / impact.sample_rate_hz
        if after_s < need_s:
            raise BadInputError(
                f'{source_prefix(impact.source)}the record runs only {after_s:.3g} s after '
                f'the hit: too short to see a decay (need {need_s:.3g} s, '
                f'{MIN_DECAY_PERIODS:g} natural periods of the rig)'
            )
    return conditioned


def _integrated_as_judged(
    records: Sequence, conditioned: list[ConditionedImpact], rig: Rig, fit_initial_position: bool
) -> tuple[list[ConditionedImpact], tuple[float, ...] | None]:
    """Velocities made from an accelerometer (or a displacement sensor) as the diagnosis judges.

    Such a record carries the sensor's own samples in `response`. Integrating leaves a
    velocity whose offset and slow drift are the sensor's, not the rig's (the offset taken
    before the hit is never exact, and the sensor's zero creeps): the chain's drift handling
    takes them off once, fitted with the base model (`INTEGRATED_FIT`). Its noise is then
    described by `converted_noise`: as the white noise of equal density at the rig's natural
    frequency (the impact's velocity_noise_std_m_s, which every chi^2 is judged against),
    not the white noise its sample-to-sample changes show (the integral of white noise is a
    random walk, far stronger at the rig's few hertz); and, apart, the much smaller variance
    it leaves in a residual, which a misfit's excess beyond the noise is taken over.

    Returns the impacts and each one's residual noise [m/s], or None when no record is
    integrated (the velocity noise is then both).
    """
    described = []
    for record, impact in zip(records, conditioned, strict=True):
        quantity = getattr(record, 'response_quantity', VELOCITY)
        response = getattr(record, 'response', None)
        if quantity != VELOCITY and response is not None:
            noise = converted_noise(
                response, quantity, impact.sample_rate_hz, rig.natural_frequency_hz, DRIFT_KNOT_S
            )
            described.append((impact, noise))
        else:
            described.append((impact, None))
    if all(noise is None for _, noise in described):
        return conditioned, None
    spec = INTEGRATED_FIT.but(fit_initial_position=fit_initial_position)
    fit = fit_model(conditioned, spec, rig=rig)
    judged = [
        impact
        if noise is None
        else replace(
            impact,
            velocity_m_s=impact.velocity_m_s - nuisance.values_m_s,
            velocity_noise_std_m_s=noise.band_std_m_s,
        )
        for (impact, noise), nuisance in zip(described, fit.velocity_nuisance, strict=True)
    ]
    residual = tuple(
        impact.velocity_noise_std_m_s if noise is None else noise.residual_std_m_s
        for impact, noise in described
    )
    return judged, residual


INTEGRATED_FIT = FitSpec(remove_mains_hum=True, fit_velocity_drift=True)
"""The fit whose chain estimate (hum, offset and drift) is taken off an integrated velocity."""


def _checked_candidates(candidates: Sequence[str] | None, hits: int) -> tuple[str, ...]:
    if candidates is None:
        return tuple(e for e in EFFECTS if e != MU_DRIFT or hits >= MIN_DRIFT_HITS)
    if isinstance(candidates, str):
        candidates = (candidates,)
    unknown = [name for name in candidates if name not in EFFECTS]
    if unknown:
        raise BadInputError(
            f'unknown candidate effect(s) {", ".join(map(repr, unknown))}; '
            f'known: {", ".join(EFFECTS)}'
        )
    if MU_DRIFT in candidates and hits < MIN_DRIFT_HITS:
        raise BadInputError(
            f'{MU_DRIFT} needs at least {MIN_DRIFT_HITS} impacts to tell a drift from a '
            f'speed law, got {hits}'
        )
    return tuple(dict.fromkeys(candidates))


@dataclass(frozen=True)
class _Step:
    """One effect added by forward selection."""

    effect: str
    model: SessionModel
    score: float
    gap_after: float


@dataclass(frozen=True)
class _Selection:
    """What forward selection and the backward check left."""

    model: SessionModel
    steps: tuple[_Step, ...]
    candidates: tuple[Candidate, ...]
    log: tuple[str, ...]
    best_partial: str
    """The best named combination when it fails to halve the gap, in words ('' otherwise)."""


class _Session:
    """The cropped impacts, the base model and what every step measures against."""

    def __init__(
        self,
        impacts: list[ConditionedImpact],
        base: SessionModel,
        rig: Rig,
        fit_initial_position: bool,
        residual_noise: Sequence[float] | None,
        rest_noise: float,
        say: Progress,
    ) -> None:
        self.impacts = impacts
        self.base = base
        self.rig = rig
        self.fit_initial_position = fit_initial_position
        self.say = say
        self.noise = base.joint.noise_std_m_s
        self.residual_noise = rest_noise
        """The noise's deviation in a residual sample by sample, pooled as the noise is, which
        every gap is taken beyond: the noise where the rig rests (`calibration`), as the
        verdict's, unless a record is integrated (`_integrated_as_judged`). Not the white
        noise the fit's chi^2 uses: coloured noise and hum left over the motion are noise,
        and beyond white noise alone a clean session kept a gap of 1e-4 to 5e-4 of the peak
        speed (a DSA's band-limited noise), so an effect that more than halved what the
        model could explain did not halve the gap and was not named."""
        if residual_noise is not None:
            sizes = [impact.force_n.size for impact in impacts]
            squares = sum(s**2 * n for s, n in zip(residual_noise, sizes, strict=True))
            self.residual_noise = math.sqrt(squares / sum(sizes))
        self.rest_noise = rest_noise
        """The noise where the rig rests, which the verdict judges against (`calibration`)."""
        self.n_samples = base.joint.n_samples
        self.rate = impacts[0].sample_rate_hz
        self.models = [i.velocity_m_s - r for i, r in zip(impacts, base.residuals_m_s, strict=True)]
        self.hits = [impact.gate[0][0] for impact in impacts]
        self.windows = [
            motion_window(model, hit, self.rate)
            for model, hit in zip(self.models, self.hits, strict=True)
        ]
        self.motion_samples = sum(w.stop - w.start for w in self.windows)
        self.naming = Naming((MIN_EXCESS * self.noise) ** 2 * self.motion_samples, self.windows)
        """What naming an effect asks of the misfit it removes (MIN_EXCESS; `_choose`)."""
        self.peak = max(impact.peak_velocity_m_s for impact in impacts)
        self.ranges = physical_ranges(base.joint.mu, self.peak, 1.0 / rig.natural_frequency_hz)
        """Every fit's, screen's and start's range of the effects' sizes, from mu, the peak
        speed and the natural period (`physical_ranges`), not from any world's draws."""
        self.where: Where = locate_misfit(
            impacts, base.residuals_m_s, self.models, self.hits, rig, self.noise
        )
        self.allowance = input_noise_allowance(impacts, base.joint, self.noise)
        self.required = -(BIC_EVIDENCE + INPUT_NOISE_FACTOR * self.allowance)
        self.gap_before = self.gap(base.residuals_m_s)
        self.cache: dict[frozenset, SessionModel] = {frozenset(): base}
        self.drift_screens: dict[frozenset, Screen] = {}

    def gap(self, residuals: Sequence[np.ndarray]) -> float:
        """Normalised RMS residual beyond the noise over the motion windows [-]."""
        return gap(residuals, self.windows, self.residual_noise, self.peak)

    def frf_gap(self, residuals: Sequence[np.ndarray]) -> float:
        """Normalised mobility misfit beyond the noise [-]."""
        return frf_gap(self.impacts, residuals, self.noise, self.rig.natural_frequency_hz)

    def score(self, model: SessionModel, reference: SessionModel) -> tuple[float, float]:
        """(BIC, AIC) of model minus reference [-]."""
        return (
            model.bic(self.noise, self.n_samples) - reference.bic(self.noise, self.n_samples),
            model.aic(self.noise) - reference.aic(self.noise),
        )

    @staticmethod
    def share(before: float, after: float) -> float:
        """Share of the squared gap removed going from gap before to after [-]."""
        return (before**2 - after**2) / before**2 if before > 0.0 else 0.0

    def predicted_gap(self, residuals: Sequence[np.ndarray], chi2_gain: float) -> float:
        """The gap once chi2_gain is removed from inside the motion windows [-]."""
        inside = sum(inner(r[w], r[w]) for r, w in zip(residuals, self.windows, strict=True))
        mean = (inside - chi2_gain * self.noise**2) / self.motion_samples
        return math.sqrt(max(mean - self.residual_noise**2, 0.0)) / self.peak

    # Forward selection and backward check

    def select(self, candidates: Sequence[str]) -> _Selection:
        """Forward selection, then the backward check (module doc, steps 4 and 5)."""
        current, steps, log, table = self.base, [], [], None
        best_partial = ''
        while True:
            remaining = [e for e in candidates if e not in current.effects]
            if not remaining:
                break
            number = len(steps) + 1
            tried, screens = self._step(number, current, remaining)
            chosen, reason = self._choose(current, tried)
            if chosen is None or _size_at_bound(chosen[0]):
                chosen, reason = self._further(number, current, tried, screens, reason, chosen)
            if table is None:
                table = tuple(sorted((c for c, _ in tried), key=lambda c: c.score))
            if chosen is None:
                log.append(f'step {number}: {reason}')
                self.say(log[-1])
                break
            candidate, model = chosen
            steps.append(_Step(candidate.effect, model, candidate.score, candidate.gap_after))
            log.append(
                f'step {number}: added {candidate.effect} (score {candidate.score:.0f}, gap '
                f'{self.gap(current.residuals_m_s):.3g} -> {candidate.gap_after:.3g})'
            )
            self.say(log[-1])
            current = model
        current, steps = self._backward(current, steps, log)
        if steps and self.gap(current.residuals_m_s) > (1.0 - EXPLAINED_GAP) * self.gap_before:
            best_partial = (
                f'{" + ".join(current.effects)} removes only '
                f'{100 * self.share(self.gap_before, self.gap(current.residuals_m_s)):.0f} % of '
                'the squared gap'
            )
        return _Selection(current, tuple(steps), table or (), tuple(log), best_partial)

    def _step(
        self, number: int, current: SessionModel, remaining: Sequence[str]
    ) -> tuple[list[tuple[Candidate, SessionModel | None]], list[Screen]]:
        """Screen every remaining candidate at the current model; refit the best few.

        Returns the candidates and their screens, both best screen first.
        """
        hits = screened_hits(len(self.impacts))
        linear = Linearisation(self.impacts, current, self.fit_initial_position, hits)
        # Detection limits are reported from the first step (`Candidate`) only.
        naming = self.naming if number == 1 else None
        screens = []
        for effect in remaining:
            if effect == MU_DRIFT:
                every = (
                    linear
                    if linear.scale == 1.0
                    else Linearisation(self.impacts, current, self.fit_initial_position)
                )
                screen = screen_drift(every, self.noise, naming)
                if naming is not None:
                    shown = _detectable_drift(screen.mu_per_hit, screen.mu_per_hit_stderr)
                    screen = replace(screen, detection_limit=max(screen.detection_limit, shown))
                self.drift_screens[frozenset(current.effects)] = screen
            else:
                shapes = probes(
                    effect,
                    linear.impacts,
                    linear.residuals,
                    self.noise,
                    self.where,
                    self.rig,
                    self.ranges,
                )
                # A second mode's limit is taken over the band the hits excite, not at the
                # residual's peaks (hum makes some in a clean session): what could hide.
                limit_shapes = (
                    mode_limit_probes(linear.impacts, self.rig)
                    if effect == 'second_mode' and naming is not None
                    else None
                )
                screen = screen_term(
                    effect, shapes, linear, self.noise, naming, limit_shapes, self.ranges
                )
            self.say(f'step {number}: screened {effect}: chi^2 could fall {screen.chi2_gain:.0f}')
            screens.append(screen)
        screens.sort(key=lambda s: -s.chi2_gain)
        threshold = max(SCREEN_FRACTION * -self.required, RUNNER_UP_FRACTION * screens[0].chi2_gain)
        tried = []
        for rank, screen in enumerate(screens):
            if rank < MAX_REFITS and screen.chi2_gain >= threshold:
                tried.append(self._refit(number, current, screen))
            else:
                tried.append((self._screened(current, screen, threshold), None))
        return tried, screens

    def _further(
        self,
        number: int,
        current: SessionModel,
        tried: list[tuple[Candidate, SessionModel | None]],
        screens: list[Screen],
        reason: str,
        bounded: tuple[Candidate, SessionModel] | None = None,
    ) -> tuple[tuple[Candidate, SessionModel] | None, str]:
        """Refit the screens left unrefitted, best first, until one qualifies (module doc, 4).

        Only where a refit was made and what the model leaves would be called unexplained, or
        where the only refit that qualifies (`bounded`) ends with its size on its physical
        bound: a screen is one linearised step and misranks a large effect (a softening spring
        at 11 mm swings, whose period drifts over the decay), and a term pinned to the edge of
        what the physics allows is standing in for another (an asymmetry of -mu took 37 % of
        that spring's gap, then was dropped once the spring was in). Only screens that reach
        `SCREEN_FRACTION` of the required gain, as every refit must: a wear track outside the
        vocabulary had four more refits of screens predicting 8 to 900 against 1,800
        required, 30 s of its 80. The refits take their screens' places in `tried`. Returns
        the first that qualifies within its range, else `bounded` (None and why none
        qualifies when there is none).
        """
        excess = self.peak * self.gap(current.residuals_m_s) / self.noise
        if excess < MIN_EXCESS or all(model is None for _, model in tried):
            return bounded, '' if bounded is not None else reason
        worth = SCREEN_FRACTION * -self.required
        for rank, screen in enumerate(screens):
            if tried[rank][1] is not None or screen.chi2_gain < worth:
                continue
            why = (
                f'no refit qualifies and the misfit is {excess:.1f}x the noise'
                if bounded is None
                else f'the only refit that qualifies, {bounded[0].effect}, ends at its bound'
            )
            self.say(f'step {number}: {why}: refitting {screen.effect} too')
            tried[rank] = self._refit(number, current, screen)
            chosen, reason = self._choose(current, tried)
            if chosen is not None and not _size_at_bound(chosen[0]):
                return chosen, ''
        return bounded, '' if bounded is not None else reason

    def _screened(self, current: SessionModel, screen: Screen, threshold: float) -> Candidate:
        """A candidate scored by its screen alone: predicted chi^2 fall, parameters counted."""
        gain, k = screen.chi2_gain, screen.added_parameters
        parameters = current.estimates()
        if screen.start is not None:
            parameters += tuple(
                ParameterEstimate(f'{screen.effect}.{p.name}', float(v), p.unit, math.nan)
                for p, v in zip(screen.start.parameters, screen.start.to_vector(), strict=True)
            )
        elif screen.mu_per_hit is not None:
            parameters += tuple(
                ParameterEstimate(f'{MU_DRIFT}.mu[{i}]', float(mu), '1', float(error))
                for i, (mu, error) in enumerate(
                    zip(screen.mu_per_hit, screen.mu_per_hit_stderr, strict=True)
                )
            )
        why = (
            f'below {threshold:.0f} (half the required gain, 30 % of the best screen)'
            if gain < threshold
            else f'not among the {MAX_REFITS} best screens'
        )
        note = f'screened: chi^2 could fall {gain:.0f}, {why}; not refitted'
        if screen.note:
            note += f' ({screen.note})'
        return Candidate(
            screen.effect,
            -gain + k * math.log(self.n_samples),
            -gain + 2.0 * k,
            self.predicted_gap(current.residuals_m_s, gain),
            math.nan,
            parameters,
            note,
            screen.detection_limit,
            screen.detection_limit_by_frequency,
        )

    def _refit(
        self, number: int, current: SessionModel, screen: Screen
    ) -> tuple[Candidate, SessionModel | None]:
        """The current model plus the screened effect, refitted in full (cached by effects)."""
        key = frozenset((*current.effects, screen.effect))
        try:
            if key in self.cache:
                model = self.cache[key]
            elif screen.effect == MU_DRIFT:
                model = with_mu_per_hit(
                    self.impacts, current, screen.mu_per_hit, self.fit_initial_position
                )
            else:
                model = with_terms(
                    self.impacts,
                    current,
                    screen.effect,
                    screen.start,
                    self.fit_initial_position,
                    mu0=current.joint.mu + screen.mu_shift,
                    ranges=self.ranges,
                )
        except FitError as error:
            self.say(f'step {number}: refit of {screen.effect} failed: {error}')
            return Candidate(
                screen.effect,
                math.inf,
                math.inf,
                math.nan,
                math.nan,
                (),
                f'refit failed: {error}',
                screen.detection_limit,
                screen.detection_limit_by_frequency,
            ), None
        self.cache[key] = model
        bic, aic = self.score(model, current)
        self.say(f'step {number}: refitted {screen.effect}: score {bic:.0f}')
        return Candidate(
            screen.effect,
            bic,
            aic,
            self.gap(model.residuals_m_s),
            self.frf_gap(model.residuals_m_s),
            model.estimates(),
            detection_limit=screen.detection_limit,
            detection_limit_by_frequency=screen.detection_limit_by_frequency,
        ), model

    def _choose(
        self, current: SessionModel, tried: list[tuple[Candidate, SessionModel | None]]
    ) -> tuple[tuple[Candidate, SessionModel] | None, str]:
        """The best refit that qualifies (module doc, step 4), or None and why none does."""
        gap_now = self.gap(current.residuals_m_s)
        # A refit whose size ends on its physical bound comes after those within it.
        refits = sorted(
            ((c, m) for c, m in tried if m is not None and math.isfinite(c.score)),
            key=lambda item: (_size_at_bound(item[0]), item[0].score),
        )
        if not refits:
            best = min((c for c, _ in tried), key=lambda c: c.score, default=None)
            if best is None:
                return None, 'no candidate left'
            return None, (
                f'no candidate screens near the required score {self.required:.1f} (best: '
                f'{best.effect}, predicted {best.score:.0f}); the model explains the data '
                'within the noise'
                if not current.effects
                else f'no further candidate screens near the required score (best: '
                f'{best.effect}, predicted {best.score:.0f})'
            )
        reasons = []
        for candidate, model in refits:
            share = self.share(gap_now, candidate.gap_after)
            size = self.peak * math.sqrt(max(gap_now**2 - candidate.gap_after**2, 0.0))
            size /= self.noise
            if candidate.score > self.required:
                reasons.append(
                    f'{candidate.effect} scores {candidate.score:.0f} > required '
                    f'{self.required:.1f}'
                )
            elif share < MIN_STEP_SHARE:
                reasons.append(
                    f'{candidate.effect} scores {candidate.score:.0f} but removes only '
                    f'{100 * share:.1f} % of the squared gap'
                )
            elif size < MIN_EXCESS and (size < MIN_WHOLE_EXCESS or share < WHOLE_MISFIT_SHARE):
                reasons.append(
                    f'{candidate.effect} scores {candidate.score:.0f} but accounts for only '
                    f'{size:.2f}x the noise RMS ({100 * share:.0f} % of the squared gap)'
                )
            elif candidate.effect == MU_DRIFT and (refusal := self._not_a_drift(model)):
                reasons.append(
                    f'one mu does not serve every hit (score {candidate.score:.0f}), but {refusal}'
                )
            else:
                return (candidate, model), ''
        return None, 'nothing more qualifies: ' + '; '.join(reasons)

    def _not_a_drift(self, model: SessionModel) -> str:
        """Why a model with one mu per hit is not a drift ('' when it is; module doc, step 4).

        From MIN_TREND_HITS hits the per-hit mu must trend in hit order. With fewer (one hit
        a level) the hits' own mu must differ beyond their errors and MU_SPREAD_FLOOR of mu,
        and no hit may show a
        speed law of its own: with one hit a level, friction that varies with speed makes
        the hits' mu differ just as a drift does, but only a speed law varies within a hit.
        """
        trend = _trend(model)
        if len(self.impacts) >= MIN_TREND_HITS:
            if trend.p_value >= DRIFT_P_VALUE:
                return f'the per-hit mu show no trend in hit order (p = {trend.p_value:.2g})'
            return ''
        consistency = mu_trend(
            model.mus, _floored(model.mus, model.mu_stderrs), refitted=True
        ).consistency_p_value
        if consistency >= DRIFT_P_VALUE:
            return (
                f"the hits' own mu agree within their errors and {100 * MU_SPREAD_FLOOR:g} % "
                f'of mu (p = {consistency:.2g})'
            )
        records, rig, cubic = self._map_records(model)
        for index, record in enumerate(records):
            curve = friction_map([record], self.rate, self.noise, rig, cubic).speed
            p_value = _flatness_p_value(curve)
            if p_value < SPEED_LAW_P_VALUE:
                per_hit, shared = _drift_and_speed_law_aic(
                    *speed_table(records, self.rate, self.noise, rig, cubic)
                )
                if shared <= per_hit:
                    return (
                        f'the friction within hit {index} changes with sliding speed '
                        f'(p = {p_value:.2g}), and one curve of speed fits the hits at least as '
                        f'well as a mu per hit (AIC {shared:.0f} against {per_hit:.0f}): a '
                        'speed law, not a drift'
                    )
                self.say(
                    f'mu_drift: the friction within hit {index} changes with sliding speed '
                    f'(p = {p_value:.2g}), but a mu per hit fits the hits better than one '
                    f'curve of speed (AIC {per_hit:.0f} against {shared:.0f})'
                )
                return ''
        return ''

    def _backward(
        self, current: SessionModel, steps: list[_Step], log: list[str]
    ) -> tuple[SessionModel, list[_Step]]:
        """Drop any named effect whose removal costs less than the required score."""
        while len(current.effects) >= 2:
            drops = []
            for effect in current.effects:
                reduced = self._without(current, effect)
                if reduced is not None:
                    drops.append((self.score(reduced, current)[0], effect, reduced))
            if not drops:
                break
            cost, effect, reduced = min(drops, key=lambda item: item[0])
            if cost >= -self.required:
                log.append(
                    'backward check: every named effect earns its place (the cheapest to '
                    f'drop, {effect}, would cost {cost:.0f})'
                )
                self.say(log[-1])
                break
            log.append(f'backward check: dropped {effect} (removing it costs only {cost:.0f})')
            self.say(log[-1])
            current = reduced
            steps = [step for step in steps if step.effect != effect]
        return current, steps

    def _without(self, model: SessionModel, effect: str) -> SessionModel | None:
        key = frozenset(model.effects) - {effect}
        if key not in self.cache:
            try:
                self.cache[key] = without(
                    self.impacts, model, effect, self.fit_initial_position, self.ranges
                )
            except FitError:
                return None
        return self.cache[key]

    # The verdict

    def conclude(
        self,
        records: Sequence[ConditionedImpact],
        selection: _Selection,
        drift_asked: bool,
        starts: str,
    ) -> Diagnosis:
        """The verdict (module doc, step 6) and everything reported beside it.

        starts: where each hit's model started (one of STARTS), reported with it.
        """
        final = selection.model
        gap_final = self.gap(final.residuals_m_s)
        halved = gap_final <= (1.0 - EXPLAINED_GAP) * self.gap_before
        explained = final if (final.effects and halved) else self.base
        final_models = [
            i.velocity_m_s - r for i, r in zip(self.impacts, explained.residuals_m_s, strict=True)
        ]
        location = locate_residual(
            self.impacts,
            without_impulse_error(self.impacts, explained, explained.residuals_m_s, self.windows),
            final_models,
            explained.positions_m,
            self.windows,
            self.hits,
            self.rig,
            self.rest_noise,
        )
        named = self._named_effects(selection, explained, location)
        verdict = self._verdict(named, selection, explained, location)
        verdict += _at_bound_note(named)
        candidates = tuple(
            replace(c, unobservable=_unobservable(c, self.ranges)) for c in selection.candidates
        )
        verdict += ''.join(f'; {c.unobservable}' for c in candidates if c.unobservable)
        self.say(verdict)
        trend = None
        if drift_asked:
            trend = (
                _trend(explained)
                if MU_DRIFT in explained.effects
                else self._linear_trend(explained)
            )
        base_full = self._full_residuals(records, self.base)
        final_full = (
            base_full if explained is self.base else self._full_residuals(records, explained)
        )
        return Diagnosis(
            missing_effect=named[0].effect if named else NONE,
            missing_effects=tuple(named),
            parameters=explained.estimates(),
            mu=self.base.joint.mu,
            mu_stderr=self.base.joint.mu_stderr,
            starts=starts,
            gap_before=self.gap_before,
            gap_after=self.gap(explained.residuals_m_s),
            frf_gap_before=self.frf_gap(self.base.residuals_m_s),
            frf_gap_after=self.frf_gap(explained.residuals_m_s),
            where=self.where,
            candidates=candidates,
            selection=selection.log,
            residual_where=location,
            mu_trend=trend,
            friction_map=self._friction_map(explained),
            noise_std_m_s=self.noise,
            residual_noise_std_m_s=self.residual_noise,
            force_noise_std_n=_pooled_force_noise(self.impacts),
            input_noise_allowance=self.allowance,
            required_score=self.required,
            verdict=verdict,
            base_residuals_m_s=base_full,
            named_residuals_m_s=final_full,
        )

    def _named_effects(
        self, selection: _Selection, explained: SessionModel, location: ResidualLocation
    ) -> list[NamedEffect]:
        """The effects the diagnosis names, in the order they were taken.

        An unexplained residual (its excess over the noise at least MIN_EXCESS) comes first,
        with where it is; then, when the selected model halved the gap (`explained` is it),
        each selected effect with its score, how much the fit loses without it (the drop) and
        its parameters, marked partial if a residual is still unexplained.
        """
        final = selection.model
        unexplained = location.excess_to_noise >= MIN_EXCESS
        named = []
        if unexplained:
            named.append(
                NamedEffect(
                    UNEXPLAINED,
                    math.nan,
                    math.nan,
                    self.gap(explained.residuals_m_s),
                    (),
                    where=location,
                )
            )
        for step in selection.steps if explained is final else ():
            drop = math.nan
            reduced = self._without(final, step.effect) if len(final.effects) > 1 else self.base
            if reduced is not None:
                drop = self.score(reduced, final)[0]
            named.append(
                NamedEffect(
                    step.effect,
                    step.score,
                    drop,
                    step.gap_after,
                    _own_parameters(final, step.effect),
                    _trend(final) if step.effect == MU_DRIFT else None,
                    partial=unexplained,
                )
            )
        return named

    def _verdict(self, named, selection, explained, location) -> str:
        if not named and selection.best_partial:
            return (
                f'none: {selection.best_partial}, which does not halve the gap, and the misfit '
                f'is only {location.excess_to_noise:.2f}x the noise beyond it'
            )
        if not named:
            reason = selection.log[-1].split(': ', 1)[-1] if selection.log else ''
            return f'none: {reason}'
        names = [n.effect for n in named if n.effect != UNEXPLAINED]
        gap_after = self.gap(explained.residuals_m_s)
        shrink = (
            f'gap {self.gap_before:.3g} -> {gap_after:.3g} '
            f'({100 * (1 - gap_after / self.gap_before):.0f} % smaller)'
        )
        if named[0].effect != UNEXPLAINED:
            return f'{" + ".join(names)}: {shrink}'
        if names:
            why = (
                f'{" + ".join(names)} describe part of it ({shrink}), and what is left is '
                f'still {location.excess_to_noise:.1f}x the noise beyond it'
            )
        elif selection.best_partial:
            why = f'{selection.best_partial}, which does not halve the gap'
        else:
            why = (
                f'the residual stays {location.excess_to_noise:.1f}x the noise beyond it and '
                'no candidate of the vocabulary clears the required score'
            )
        return f'unexplained: {why}; the residual sits at {location.summary}'

    def _linear_trend(self, model: SessionModel) -> MuTrend | None:
        """Each hit's mu by one linearised step from the model, and its trend."""
        if len(self.impacts) < MIN_DRIFT_HITS:
            return None
        screen = self.drift_screens.get(frozenset(model.effects))
        if screen is None:
            every = Linearisation(self.impacts, model, self.fit_initial_position)
            screen = screen_drift(every, self.noise)
        return mu_trend(screen.mu_per_hit, screen.mu_per_hit_stderr, refitted=False)

    def _full_residuals(
        self, records: Sequence[ConditionedImpact], model: SessionModel
    ) -> tuple[np.ndarray, ...]:
        """Measured minus model velocity over each whole record [m/s]."""
        return tuple(
            thread_map(
                lambda index: (
                    records[index].velocity_m_s
                    - model.velocity(index, records[index].force_n, records[index].sample_rate_hz)
                ),
                range(len(records)),
            )
        )

    def _friction_map(self, model: SessionModel) -> FrictionMap:
        """The friction map, the model's non-friction terms taken off the velocity first."""
        records, rig, cubic = self._map_records(model)
        return friction_map(records, self.rate, self.noise, rig, cubic)

    def _map_records(self, model: SessionModel) -> tuple[list[MapRecord], Rig, float]:
        """Each hit as the friction map takes it, with the rig and cubic stiffness of the model.

        The model's non-friction terms (an offset, a second mode) are taken off the velocity,
        its added damping and cubic stiffness are the map's.
        """
        terms = {term.name: term for term in model.terms}
        records = []
        for index, impact in enumerate(self.impacts):
            velocity = impact.velocity_m_s
            if 'velocity_offset' in terms:
                velocity = velocity - terms['velocity_offset'].offset_m_s
            if 'second_mode' in terms:
                velocity = velocity - (
                    model.velocity(
                        index, impact.force_n, self.rate, effects=(terms['second_mode'],)
                    )
                    - model.velocity(index, impact.force_n, self.rate, effects=())
                )
            records.append(
                MapRecord(
                    impact.force_n,
                    velocity,
                    model.positions_m[index],
                    impact.hit_end_index + round(HIT_GUARD_S * self.rate),
                )
            )
        rig = model.rig
        if 'viscous_damping' in terms:
            rig = replace(
                rig,
                damping_n_s_per_m=rig.damping_n_s_per_m
                + terms['viscous_damping'].damping_n_s_per_m,
            )
        cubic = (
            terms['cubic_stiffness'].cubic_stiffness_n_per_m3 if 'cubic_stiffness' in terms else 0.0
        )
        return records, rig, cubic


def _spread_about_means(
    mu: np.ndarray, error: np.ndarray, axis: int | None = None
) -> tuple[float, int, int]:
    """chi^2 of mu about its inverse-variance weighted means along axis (all of it: None).

    Values with a non-finite mu or error, or no error, are left out. Returns the chi^2, the
    number of means (groups with a usable value) and the number of usable values.
    """
    usable = np.isfinite(mu) & np.isfinite(error) & (error > 0.0)
    weight = np.where(usable, 1.0 / np.where(usable, error, 1.0) ** 2, 0.0)
    values = np.where(usable, mu, 0.0)
    total = weight.sum(axis=axis, keepdims=True)
    mean = (weight * values).sum(axis=axis, keepdims=True) / np.where(total > 0, total, 1.0)
    chi2 = float(np.sum(weight * (values - mean) ** 2))
    return chi2, int(np.count_nonzero(total > 0)), int(np.count_nonzero(usable))


def _flatness_p_value(curve: FrictionCurve) -> float:
    """Chance of mu this spread over a curve's speed bins if it did not change with speed."""
    chi2, _, usable = _spread_about_means(np.asarray(curve.mu), np.asarray(curve.mu_stderr))
    if usable < 2:
        return 1.0
    return float(chi2_sf(chi2, usable - 1))


def _drift_and_speed_law_aic(mu: np.ndarray, error: np.ndarray) -> tuple[float, float]:
    """AIC of two explanations of the hits' friction maps on shared speed bins [1].

    mu, error: a row a hit, a column a speed bin (`speed_table`; NaN where a hit has too few
    runs). A drift gives each hit its own constant mu (a parameter a hit); a speed law one
    curve of speed that every hit follows (a parameter a bin). Returns (AIC of a mu per hit,
    AIC of the shared curve), each chi^2 about its weighted means plus twice its parameters.
    A hit's map can bend at its lowest speeds without a speed law (coloured velocity noise
    integrated into its displacement shifts the k x it subtracts), but only a speed law makes
    the hits agree bin by bin where their speeds overlap.
    """

    def aic(axis: int) -> float:
        chi2, means, _ = _spread_about_means(mu, error, axis)
        return chi2 + 2.0 * means

    return aic(1), aic(0)


def _trend(model: SessionModel) -> MuTrend:
    """The refitted per-hit mu of a model with mu_drift, and their trend."""
    return mu_trend(model.mus, model.mu_stderrs, refitted=True)


def _floored(mus: np.ndarray, mu_stderrs: np.ndarray) -> np.ndarray:
    """Per-hit mu errors combined with MU_SPREAD_FLOOR of mu, as a spread of few hits is judged."""
    return np.hypot(mu_stderrs, MU_SPREAD_FLOOR * mus)


def _detectable_drift(mus: np.ndarray, mu_stderrs: np.ndarray) -> float:
    """The steady change of mu a hit [1/hit] these hits must show to pass `_not_a_drift`.

    A fraction of mu; what the test of the hits' own mu asks of hits with these errors.

    From MIN_TREND_HITS hits a trend at DRIFT_P_VALUE (a steady change leaves no scatter to
    widen the slope's error; its t grows as the change); with fewer, a spread beyond their
    errors and MU_SPREAD_FLOOR of each hit's mu at DRIFT_P_VALUE (solved for: the floor grows
    with the hits' mu). Three hits with 1e-5 errors: 1.3 % a hit. inf when not even a change
    of all of mu a hit would pass; NaN when the errors say nothing (not finite and positive).
    """
    n, mean = len(mus), float(np.mean(mus))
    errors = np.asarray(mu_stderrs, dtype=float)
    if not (mean > 0.0 and np.all(np.isfinite(errors)) and np.all(errors > 0.0)):
        return math.nan

    def steady(change: float) -> np.ndarray:
        return mean * (1.0 + change * np.arange(n))

    if n >= MIN_TREND_HITS:
        trend = mu_trend(steady(1e-3), errors, refitted=False)
        needed = float(t_isf(DRIFT_P_VALUE / 2.0, n - 2))
        return 1e-3 * needed * trend.slope_stderr / abs(trend.slope_per_hit)
    needed = float(chi2_isf(DRIFT_P_VALUE, n - 1))

    def beyond(change: float) -> float:
        mu = steady(change)
        return mu_trend(mu, _floored(mu, errors), refitted=False).consistency_chi2 - needed

    if beyond(1.0) <= 0.0:
        return math.inf
    return float(scipy.optimize.brentq(beyond, 0.0, 1.0, xtol=1e-6))


WOULD_SHOW = {
    'viscous_damping': 'longer decays (harder hits) would',
    'stribeck': 'more slow sliding before each stop (more hits, lighter ones) would',
    'asymmetric_friction': 'chained starts or a position sensor would',
    'cubic_stiffness': 'harder hits that swing the rig further would',
    'second_mode': 'a stiffer hammer tip exciting a wider band would',
    'velocity_offset': 'longer records at rest after each hit would',
    'sensor_delay': 'shorter hits (a stiffer hammer tip) would',
}
"""Per term, what would show an effect these records cannot (`_unobservable`)."""


def _unobservable(candidate: Candidate, ranges: Mapping[str, tuple[float, float]]) -> str:
    """'these records cannot show ...' when a candidate's detection limit is out of its range.

    The range is the session's physical one (`physical_ranges`) or the term's declared bounds:
    an effect that only shows beyond what the physics allows is one these records cannot
    show, whatever the verdict; '' when the limit lies inside it, or there is none.
    """
    effect, limit = candidate.effect, candidate.detection_limit
    if effect not in EFFECT_SIZE or not math.isfinite(limit):
        return ''
    name, inverse = EFFECT_SIZE[effect]
    cls = MODEL_TERMS[effect]
    index = [p.name for p in cls.parameters].index(name)
    low, high = (float(bound[index]) for bound in cls.bounds(ranges))
    if inverse:
        if limit >= low:
            return ''
        beyond = f'under {limit:.2g}, lighter than the lightest physical {low:.2g}'
    else:
        largest = max(abs(low), abs(high))
        if limit <= largest:
            return ''
        beyond = f'from {limit:.2g}, beyond the physical range of {largest:.2g}'
    unit = cls.parameters[index].unit
    unit = '' if unit == '1' else f' {unit}'
    return (
        f'these records cannot show {effect.replace("_", " ")} (its {name} would show {beyond}'
        f'{unit}); {WOULD_SHOW[effect]}'
    )


def _size_at_bound(candidate: Candidate) -> bool:
    """Whether the parameter that sizes a candidate's effect (`EFFECT_SIZE`) ends on a bound."""
    if candidate.effect not in EFFECT_SIZE:
        return False
    name = f'{candidate.effect}.{EFFECT_SIZE[candidate.effect][0]}'
    return any(p.at_bound for p in candidate.parameters if p.name == name)


def _at_bound_note(named: Sequence[NamedEffect]) -> str:
    """'; stribeck.mu_static_excess = 0.5 at its bound' for each named effect sized on a bound.

    Only the parameter that sizes the effect (`EFFECT_SIZE`): a size on the edge of its
    physical range is a limit, not an estimate, and may stand in for another effect. A shape
    parameter on its bound (a Gaussian contact's Stribeck exponent at 2, most of them) is no
    finding; the JSON's `parameter_at_bound` and the table's '(at its bound)' still say it.
    """
    sizes = {
        f'{effect.effect}.{EFFECT_SIZE[effect.effect][0]}'
        for effect in named
        if effect.effect in EFFECT_SIZE
    }
    ends = [
        f'{p.name} = {p.value:.4g} at its bound'
        for effect in named
        for p in effect.parameters
        if p.at_bound and p.name in sizes
    ]
    return ''.join(f'; {end}' for end in ends)


def _own_parameters(model: SessionModel, effect: str) -> tuple[ParameterEstimate, ...]:
    """One effect's parameters in a model: its term's, or each hit's mu for mu_drift."""
    prefix = f'{effect}.'
    return tuple(p for p in model.estimates() if p.name.startswith(prefix))


def _pooled_force_noise(impacts: Sequence[ConditionedImpact]) -> float:
    return math.sqrt(float(np.mean([impact.force_noise_std_n**2 for impact in impacts])))
