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
from dataclasses import dataclass

import numpy as np

from fmm_ros.constants import PAPER_LEVELS, SETTLE_S
from fmm_ros.core._checks import require_non_negative, require_positive
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import MODEL_TERMS, ModelTerm, model_term
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

# The parameter scaled to set the size, and a starting value of it near the middle of the
# range the calibration lands in (the calibration is linear in it, so only its sign matters).
_SIZE_PARAMETER = {
    'viscous_damping': ('damping_n_s_per_m', 0.2),
    'stribeck': ('mu_static_excess', 0.05),
    'asymmetric_friction': ('mu_difference', 0.02),
    'cubic_stiffness': ('cubic_stiffness_n_per_m3', 3e4),
    'velocity_offset': ('offset_m_s', 2e-4),
    'sensor_delay': ('delay_s', 1.5e-4),
    'second_mode': ('modal_mass_kg', 1000.0),  # the mode's velocity scales as 1 / mass
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
        raise ValueError(f'unknown effect {effect!r}; known: {", ".join(HIDDEN_EFFECTS)}')
    if n_impacts < 1:
        raise ValueError(f'n_impacts must be at least 1, got {n_impacts}')
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
    name, size = _SIZE_PARAMETER[effect]
    sign = shape.pop('sign', 1.0)
    index = [p.name for p in MODEL_TERMS[effect].parameters].index(name)
    lower, upper = (float(bound[index]) for bound in MODEL_TERMS[effect].bounds())
    limit_high = upper if sign > 0.0 else -lower  # the bound on the side of the drawn sign
    limit_low = max(lower if sign > 0.0 else -upper, 1e-6 * limit_high)
    inverse = name == 'modal_mass_kg'  # a heavier mode is a smaller effect

    def realised(size):
        term = model_term(effect, **shape, **{name: sign * size})
        return term, base_fit_discrepancy(clean_records(term), mu, rig)

    bracket = [limit_low, limit_high]
    for _ in range(12):
        size = min(max(size, limit_low), limit_high)
        term, value = realised(size)
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
    return term, value


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
