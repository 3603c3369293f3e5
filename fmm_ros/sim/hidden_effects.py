"""Impact sessions with one effect hidden in them: the proof data of the diagnose workflow.

`hidden_effect_case(effect, rng)` simulates a few impacts of the FMM at random hammer levels
with one model term added (or none), and returns the measured force and velocity only; the
truth is kept beside them for the checker. The diagnosis is told nothing about how the data
were made.

Magnitudes are lab-realistic, not gross: the effect's size is scaled so that, after the base
model (Eq. 3) has absorbed what it can by adjusting mu, the noise-free discrepancy left over
the motion (from the hit until 0.5 s after the rig comes to rest) has an RMS of `ratio` times
the velocity noise, with `ratio` drawn from `RATIO_RANGE` (comparable to, or a few times, the
noise). The base model's adjustment is a linearised least-squares step in mu (two Gauss-Newton
iterations, one common mu for all impacts), which is what a fit of mu alone converges to for
effects this small; the size is found by secant steps, within the plausible bounds the fitter
searches. The effect's shape parameters (Stribeck velocity, the second mode's frequency and
damping, signs) are drawn at random from plausible ranges.
"""

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from fmm_ros.constants import MU_DRIFT, PAPER_LEVELS, SETTLE_S
from fmm_ros.core._checks import require_non_negative, require_positive
from fmm_ros.core.physics.model import Simulation, simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import EFFECT_SIZE, MODEL_TERMS, ModelTerm, model_term
from fmm_ros.errors import BadInputError
from fmm_ros.sim.excitation import SimulatedImpact, impact_record, level_peak_force_n

NO_EFFECT = 'none'
HIDDEN_EFFECTS: tuple[str, ...] = (*MODEL_TERMS, NO_EFFECT)
"""What the generator can hide: every model term by name, and 'none' (the base model)."""

RATIO_RANGE = (1.0, 4.0)
"""Discrepancy after the base fit, RMS over the motion, in units of the velocity noise."""
MU_RANGE = (0.08, 0.16)
"""Friction coefficients the sessions are drawn from (around the paper's 0.113)."""
FORCE_NOISE_STD_N = 0.2
VELOCITY_NOISE_STD_M_S = 1e-4

# A starting value of each term's size parameter (`EFFECT_SIZE`) near the middle of the range
# the calibration lands in (the calibration is linear in it, so only its sign matters).
_SIZE_START = {
    'viscous_damping': 0.2,
    'stribeck': 0.05,
    'asymmetric_friction': 0.02,
    'cubic_stiffness': 3e4,
    'velocity_offset': 2e-4,
    'sensor_delay': 1.5e-4,
    'second_mode': 1000.0,  # the mode's velocity scales as 1 / mass
}
_SIGNED = ('asymmetric_friction', 'cubic_stiffness', 'velocity_offset')


@dataclass(frozen=True)
class HiddenEffectCase:
    """A simulated session with its truth: what was hidden, how big, and the records."""

    effect: str
    """The hidden effect's name, or 'none'."""
    term: ModelTerm | None
    """The hidden term with its parameters (None for 'none')."""
    mu: float
    rig: Rig
    ratio: float
    """Realised noise-free discrepancy after the base fit / velocity noise (0 for 'none')."""
    records: tuple[SimulatedImpact, ...]
    """The impacts as measured: noisy force and velocity (and the truth in .simulation)."""


def hidden_effect_case(
    effect: str,
    rng: np.random.Generator | int,
    *,
    n_impacts: int = 3,
    rig: Rig = FMM_RIG,
    ratio: float | None = None,
    force_noise_std_n: float = FORCE_NOISE_STD_N,
    velocity_noise_std_m_s: float = VELOCITY_NOISE_STD_M_S,
    duration_s: float = 33.0,
) -> HiddenEffectCase:
    """A session of n_impacts random-level hits with `effect` hidden at a realistic size.

    `ratio` fixes the discrepancy-to-noise ratio instead of drawing it from RATIO_RANGE. The
    same rng (or seed) gives the same case.
    """
    if effect not in HIDDEN_EFFECTS:
        raise BadInputError(f'unknown effect {effect!r}; known: {", ".join(HIDDEN_EFFECTS)}')
    if n_impacts < 1:
        raise BadInputError(f'n_impacts must be at least 1, got {n_impacts}')
    require_positive('velocity_noise_std_m_s', velocity_noise_std_m_s)
    require_non_negative('force_noise_std_n', force_noise_std_n)
    rng = np.random.default_rng(rng)
    mu = float(rng.uniform(*MU_RANGE))
    levels = rng.choice([level.name for level in PAPER_LEVELS], size=n_impacts)
    peaks = [level_peak_force_n(str(level), rng) for level in levels]
    seeds = rng.integers(0, 2**63, size=n_impacts)
    target = float(rng.uniform(*RATIO_RANGE)) if ratio is None else float(ratio)
    shape = _draw_shape(effect, rng)

    def record(term, *, force_noise, velocity_noise):
        return tuple(
            impact_record(
                peak,
                int(seed),
                rig=rig,
                mu=mu,
                effects=() if term is None else (term,),
                force_noise_std_n=force_noise,
                velocity_noise_std_m_s=velocity_noise,
                duration_s=duration_s,
            )
            for peak, seed in zip(peaks, seeds, strict=True)
        )

    term, realised = None, 0.0
    if effect != NO_EFFECT:
        clean = functools.partial(record, force_noise=0.0, velocity_noise=0.0)
        term, realised = _sized_term(effect, shape, target * velocity_noise_std_m_s, clean, mu, rig)
        realised /= velocity_noise_std_m_s
    return HiddenEffectCase(
        effect=effect,
        term=term,
        mu=mu,
        rig=rig,
        ratio=realised,
        records=record(term, force_noise=force_noise_std_n, velocity_noise=velocity_noise_std_m_s),
    )


def _sized_term(
    effect: str, shape: dict[str, float], target_m_s: float, clean_records, mu: float, rig: Rig
) -> tuple[ModelTerm, float]:
    """The term whose base-fit discrepancy is target_m_s, its size within the term's bounds.

    The discrepancy grows with the size (falls with a second mode's mass), close to linearly
    for small sizes: secant steps in log(size), kept inside a bracket once one is found, and
    clipped to the plausible bounds the fitter searches (so the truth is always reachable).
    Returns the term and its realised discrepancy [m/s].
    """
    name, inverse = EFFECT_SIZE[effect]
    size = _SIZE_START[effect]
    sign = shape.pop('sign', 1.0)
    index = [p.name for p in MODEL_TERMS[effect].parameters].index(name)
    lower, upper = (float(bound[index]) for bound in MODEL_TERMS[effect].bounds())
    limit_high = upper if sign > 0.0 else -lower  # the bound on the side of the drawn sign
    limit_low = max(lower if sign > 0.0 else -upper, 1e-6 * limit_high)

    def realised(size):
        term = model_term(effect, **shape, **{name: sign * size})
        return term, base_fit_discrepancy(clean_records(term), mu, rig)

    return _sized(realised, size, target_m_s, limit_low, limit_high, inverse)


def _sized(realised, size: float, target_m_s: float, low: float, high: float, inverse: bool):
    """(what, discrepancy) of the size in [low, high] whose discrepancy is target_m_s.

    realised(size) -> (what, discrepancy [m/s]). Secant steps in log(size), kept inside a
    bracket once one is found; inverse: the discrepancy falls as the size grows.
    """
    bracket = [low, high]
    for _ in range(12):
        size = min(max(size, low), high)
        what, value = realised(size)
        error = math.log(value / target_m_s) if value > 0.0 else -math.inf
        if abs(error) < 0.02:
            break
        if (error > 0.0) != inverse:
            bracket[1] = min(bracket[1], size)
        else:
            bracket[0] = max(bracket[0], size)
        step = (
            size * math.exp(-error if not inverse else error)
            if math.isfinite(error)
            else 10.0 * size
        )
        if not bracket[0] < step < bracket[1]:
            step = math.sqrt(bracket[0] * bracket[1])
        if step == size:
            break
        size = step
    return what, value


def base_fit_discrepancy(
    records: tuple[SimulatedImpact, ...], mu: float, rig: Rig = FMM_RIG
) -> float:
    """RMS over the motion of (truth - base model with mu re-fitted), noise-free [m/s].

    The truth is each record's noise-free simulation; the base model is Eq. 3 driven by the
    same clean force, with one mu for all records found by two linearised least-squares steps.
    """
    forces = [record.force_n for record in records]
    truths = [record.simulation.velocity_m_s for record in records]
    windows = [motion_window(record) for record in records]
    rate = records[0].sample_rate_hz
    step = 1e-4 * mu
    for _ in range(2):
        residuals, slopes = [], []
        for force, truth, window in zip(forces, truths, windows, strict=True):
            base = simulate(force, rate, rig=rig, mu=mu).velocity_m_s[window]
            up = simulate(force, rate, rig=rig, mu=mu + step).velocity_m_s[window]
            residuals.append(truth[window] - base)
            slopes.append((up - base) / step)
        residual, slope = np.concatenate(residuals), np.concatenate(slopes)
        change = float(residual @ slope / (slope @ slope))
        mu = max(mu + change, 0.0)
    return math.sqrt(float(np.mean((residual - change * slope) ** 2)))


def motion_window(record: SimulatedImpact) -> slice:
    """Samples from the hit until SETTLE_S after the noise-free response came to rest."""
    sim = record.simulation
    end = sim.velocity_m_s.size
    if sim.at_rest:
        end = min(end, math.ceil((sim.rest_time_s + SETTLE_S) * record.sample_rate_hz))
    return slice(record.trigger_index, end)


def _draw_shape(effect: str, rng: np.random.Generator) -> dict[str, float]:
    """The effect's parameters other than its size, at random from plausible ranges."""
    shape: dict[str, float] = {}
    if effect in _SIGNED:
        shape['sign'] = float(rng.choice((-1.0, 1.0)))
    if effect == 'stribeck':
        shape['stribeck_velocity_m_s'] = float(
            math.exp(rng.uniform(math.log(1.5e-3), math.log(6e-3)))
        )
    elif effect == 'second_mode':
        shape['frequency_hz'] = float(math.exp(rng.uniform(math.log(15.0), math.log(300.0))))
        shape['damping_ratio'] = float(math.exp(rng.uniform(math.log(3e-3), math.log(3e-2))))
    return shape


OUT_OF_VOCABULARY: tuple[str, ...] = ('speed_regimes', 'wear_track')
"""Effects no term of the diagnosis expresses, made for the proof only (`RegimeLaw`)."""


SESSION_EFFECTS: tuple[str, ...] = (*MODEL_TERMS, MU_DRIFT, *OUT_OF_VOCABULARY)
"""What `hidden_session` can hide, any several at once (at most one friction law)."""


_MECHANICAL = ('viscous_damping', 'stribeck', 'asymmetric_friction', 'cubic_stiffness')
"""Terms of the oscillator itself, which a friction law restarted at its regime changes keeps."""


MAX_DRIFT = 0.5
"""Largest relative change of mu over a session that mu_drift is sized within [-]."""


MAX_REGIME_CHANGE = 0.5
"""Largest relative step of mu between a friction law's two regimes [-]."""


@dataclass(frozen=True)
class RegimeLaw:
    """Friction with two regimes, mu in the first and factor x mu in the second.

    kind 'speed': the second regime is sliding at |v| >= threshold (a lubricated contact that
    stiffens, velocity strengthening, above a transition speed): the Stribeck term can only
    raise friction towards rest, and smoothly. kind 'position': the second is |x - centre_m| <
    threshold (a worn groove in the counterface where the pin has slid most); no term depends
    on where the pin is. Static friction is the regime's at rest.
    """

    kind: str
    threshold: float
    """Transition speed [m/s] or the groove's half width [m]."""
    factor: float
    centre_m: float = 0.0

    def second(self, displacement_m: np.ndarray, velocity_m_s: np.ndarray) -> np.ndarray:
        """Where the second regime holds (boolean per sample)."""
        if self.kind == 'speed':
            return np.abs(velocity_m_s) >= self.threshold
        return np.abs(displacement_m - self.centre_m) < self.threshold


def regime_simulation(
    force_n: np.ndarray,
    sample_rate_hz: float,
    law: RegimeLaw,
    *,
    rig: Rig = FMM_RIG,
    mu: float,
    effects: tuple[ModelTerm, ...] = (),
    x0_m: float = 0.0,
) -> Simulation:
    """The oscillator under a two-regime friction law, by the product's `simulate` restarted.

    Each run goes on with one regime's mu until the first sample where the regime changes,
    and the next starts there from that sample's state: the change is placed to within one
    sample (0.1 ms at 10 kHz, an impulse error of ~1e-5 N s). Only terms of the oscillator
    itself (`_MECHANICAL`) compose with it.
    """
    extra = [term.name for term in effects if term.name not in _MECHANICAL]
    if extra:
        raise BadInputError(f'a friction law composes only with {", ".join(_MECHANICAL)}: {extra}')
    n = force_n.size
    displacement, velocity = np.empty(n), np.empty(n)
    start, x, v = 0, float(x0_m), 0.0
    while True:
        second = bool(law.second(np.array([x]), np.array([v]))[0])
        run = simulate(
            force_n[start:],
            sample_rate_hz,
            rig=rig,
            mu=mu * (law.factor if second else 1.0),
            effects=effects,
            x0_m=x,
            v0_m_s=v,
        )
        changes = np.flatnonzero(law.second(run.displacement_m, run.velocity_m_s)[1:] != second)
        stop = n - start if not changes.size else int(changes[0]) + 1
        displacement[start : start + stop] = run.displacement_m[:stop]
        velocity[start : start + stop] = run.velocity_m_s[:stop]
        if not changes.size:
            rest_time = run.rest_time_s + start / sample_rate_hz
            return Simulation(
                displacement, velocity, sample_rate_hz, run.rest_position_m, rest_time
            )
        start += stop
        x, v = float(run.displacement_m[stop]), float(run.velocity_m_s[stop])


@dataclass(frozen=True)
class HiddenSession:
    """A simulated session with several effects hidden, and the truth behind it."""

    effects: tuple[str, ...]
    """What was hidden (empty: a clean session)."""
    terms: tuple[ModelTerm, ...]
    mu_per_hit: tuple[float, ...]
    """Each hit's friction coefficient (all equal without mu_drift) [-]."""
    law: RegimeLaw | None
    rig: Rig
    ratios: dict[str, float]
    """Per effect, its noise-free discrepancy after the base fit, hidden alone, in velocity
    noise units."""
    records: tuple[SimulatedImpact, ...]


def hidden_session(
    effects: tuple[str, ...] | list[str],
    rng: np.random.Generator | int,
    *,
    n_impacts: int = 3,
    rig: Rig = FMM_RIG,
    ratio_range: tuple[float, float] = RATIO_RANGE,
    force_noise_std_n: float = FORCE_NOISE_STD_N,
    velocity_noise_std_m_s: float = VELOCITY_NOISE_STD_M_S,
    duration_s: float = 33.0,
) -> HiddenSession:
    """n_impacts random-level hits with every effect of `effects` hidden, each sized alone.

    Each effect is sized as `hidden_effect_case` sizes one (its discrepancy after the base fit,
    with the others absent, drawn from ratio_range in velocity noise units), then all act
    together. mu_drift changes mu linearly over the hits, up or down by up to MAX_DRIFT;
    'speed_regimes' and 'wear_track' are each a `RegimeLaw` with a random transition (20-60 mm/s,
    friction up above it) or groove (half width 1-3 mm, centre within 1 mm of the start,
    friction up or down in it).
    """
    effects = tuple(effects)
    _check_session(effects, n_impacts, force_noise_std_n, velocity_noise_std_m_s)
    rng = np.random.default_rng(rng)
    mu = float(rng.uniform(*MU_RANGE))
    levels = rng.choice([level.name for level in PAPER_LEVELS], size=n_impacts)
    peaks = [level_peak_force_n(str(level), rng) for level in levels]
    seeds = [int(seed) for seed in rng.integers(0, 2**63, size=n_impacts)]
    noise = velocity_noise_std_m_s
    clean = _base_hits(peaks, seeds, rig, mu, duration_s, 0.0, 0.0)
    noisy = _base_hits(peaks, seeds, rig, mu, duration_s, force_noise_std_n, noise)

    def records(terms, mus, law, with_noise):
        return _session_records(clean, noisy, rig, terms, mus, law, with_noise)

    flat = [mu] * n_impacts
    terms, mus, law, ratios = [], flat, None, {}
    for effect in effects:
        target = float(rng.uniform(*ratio_range)) * noise
        if effect in MODEL_TERMS:
            shape = _draw_shape(effect, rng)
            term, value = _sized_term(
                effect, shape, target, lambda t: records((t,), flat, None, False), mu, rig
            )
            terms.append(term)
        elif effect == MU_DRIFT:
            sign = float(rng.choice((-1.0, 1.0)))

            def drifting(size, sign=sign):
                values = [
                    mu * (1.0 + sign * size * (i / (n_impacts - 1) - 0.5)) for i in range(n_impacts)
                ]
                return values, base_fit_discrepancy(records((), values, None, False), mu, rig)

            mus, value = _sized(drifting, 0.05, target, 1e-4, MAX_DRIFT, False)
        else:
            law_shape, sign = _draw_law(effect, rng)

            def changed(size, law_shape=law_shape, sign=sign):
                candidate = replace(law_shape, factor=1.0 + sign * size)
                return candidate, base_fit_discrepancy(records((), flat, candidate, False), mu, rig)

            law, value = _sized(changed, 0.1, target, 1e-3, MAX_REGIME_CHANGE, False)
        ratios[effect] = value / noise
    return HiddenSession(
        effects=effects,
        terms=tuple(terms),
        mu_per_hit=tuple(float(m) for m in mus),
        law=law,
        rig=rig,
        ratios=ratios,
        records=records(tuple(terms), mus, law, True),
    )


def _check_session(
    effects: tuple[str, ...],
    n_impacts: int,
    force_noise_std_n: float,
    velocity_noise_std_m_s: float,
) -> None:
    """BadInputError unless `hidden_session` can hide these effects in n_impacts hits."""
    unknown = [e for e in effects if e not in SESSION_EFFECTS]
    if unknown or len(set(effects)) != len(effects):
        raise BadInputError(
            f'effects must be distinct names of {", ".join(SESSION_EFFECTS)}; got {effects}'
        )
    laws = [e for e in effects if e in OUT_OF_VOCABULARY]
    if len(laws) > 1 or (laws and any(e in MODEL_TERMS and e not in _MECHANICAL for e in effects)):
        raise BadInputError(
            f'at most one friction law, and only with {", ".join(_MECHANICAL)}; got {effects}'
        )
    if n_impacts < (2 if MU_DRIFT in effects else 1):
        raise BadInputError(f'n_impacts must be at least {2 if MU_DRIFT in effects else 1}')
    require_positive('velocity_noise_std_m_s', velocity_noise_std_m_s)
    require_non_negative('force_noise_std_n', force_noise_std_n)


def _base_hits(
    peaks: list[float],
    seeds: list[int],
    rig: Rig,
    mu: float,
    duration_s: float,
    force_noise_std_n: float,
    velocity_noise_std_m_s: float,
) -> list[SimulatedImpact]:
    """The session's hits under the base model, one per peak and seed, with this noise."""
    return [
        impact_record(
            peak,
            seed,
            rig=rig,
            mu=mu,
            force_noise_std_n=force_noise_std_n,
            velocity_noise_std_m_s=velocity_noise_std_m_s,
            duration_s=duration_s,
        )
        for peak, seed in zip(peaks, seeds, strict=True)
    ]


def _session_records(
    clean: list[SimulatedImpact],
    noisy: list[SimulatedImpact],
    rig: Rig,
    terms: tuple,
    mus: list[float],
    law: RegimeLaw | None,
    with_noise: bool,
) -> tuple[SimulatedImpact, ...]:
    """The hits driven by the clean forces through the model (terms, each hit's mu, law).

    with_noise: each hit's force and velocity noise (the noisy draw's, same seed) added.
    """
    made = []
    for index, (quiet, loud) in enumerate(zip(clean, noisy, strict=True)):
        force = quiet.force_n
        if law is None:
            truth = simulate(force, quiet.sample_rate_hz, rig=rig, mu=mus[index], effects=terms)
        else:
            truth = regime_simulation(
                force, quiet.sample_rate_hz, law, rig=rig, mu=mus[index], effects=terms
            )
        made.append(
            replace(
                quiet,
                force_n=loud.force_n if with_noise else force,
                velocity_m_s=truth.velocity_m_s
                + ((loud.velocity_m_s - loud.simulation.velocity_m_s) if with_noise else 0.0),
                simulation=truth,
            )
        )
    return tuple(made)


def _draw_law(effect: str, rng: np.random.Generator) -> tuple[RegimeLaw, float]:
    """A friction law's shape at factor 1, and the sign of its step (its size is found later).

    The speed law always stiffens above its transition: a step down is friction falling with
    speed, which the Stribeck term (v_s up to 50 mm/s) partly expresses.
    """
    if effect == 'speed_regimes':
        return RegimeLaw('speed', float(rng.uniform(0.02, 0.06)), 1.0), 1.0
    law = RegimeLaw(
        'position', float(rng.uniform(1e-3, 3e-3)), 1.0, centre_m=float(rng.uniform(-1e-3, 1e-3))
    )
    return law, float(rng.choice((-1.0, 1.0)))
