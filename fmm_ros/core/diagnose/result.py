"""What a diagnosis returns: the named effects, their parameters, candidates, where, the gaps.

`fmm_ros.workflows.results.diagnosis_dict` is the JSON of `fmm diagnose --json`; the
DiagnoseModel service response is filled from the same object
(`fmm_ros.ros.msgs.fill_diagnose_response`).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from fmm_ros.core.diagnose import signatures as discrepancy
from fmm_ros.core.diagnose.drift import MuTrend
from fmm_ros.core.diagnose.friction_map import FrictionMap


@dataclass(frozen=True)
class ParameterEstimate:
    """A fitted parameter: name (as the fitter names it), value, SI unit, standard error."""

    name: str
    value: float
    unit: str
    stderr: float
    at_bound: bool = False
    """The fit ended on a bound of the parameter's range (`physical_ranges` for an effect's
    size): the data ask for at least this much, and the value is a limit, not an estimate."""


@dataclass(frozen=True)
class Candidate:
    """One candidate at the first selection step: its score against the base model, its gap."""

    effect: str
    score: float
    """BIC of the base model plus this effect minus the base model's: negative is better [-].
    Refitted, or predicted by the screen (see `message`)."""
    aic_score: float
    """The same with the AIC penalty 2k instead of k ln n [-]."""
    gap_after: float
    """Gap of the refitted model, or the screen's prediction of it [-]."""
    frf_gap_after: float
    """Mobility misfit of the refitted model (NaN when only screened) [-]."""
    parameters: tuple[ParameterEstimate, ...]
    """The refitted model's parameters (mu first), or the screen's start of the effect's."""
    message: str = ''
    """'screened: ...' when not refitted, or why the refit failed (score inf, gaps NaN)."""
    detection_limit: float = math.nan
    """The effect's size at which these records would just show it (its `EFFECT_SIZE`
    parameter, SI, a magnitude; a second mode's modal mass, under which it shows): its
    response beyond what mu and the starts take up would account for `MIN_EXCESS` of the noise
    RMS over the motion, as naming it asks. A smaller effect can hide here: `none` does not
    rule it out. From the screen's linearised probe (Stribeck: its least visible probe speed; a
    second mode: the lightest that could hide anywhere in the band the hits excite, from
    1.5 f_n to a 20 dB fall of their force spectrum, at 3 % damping, where it rings shortest:
    `starts.mode_limit_probes`); NaN without a probe. mu_drift's is a steady
    change of mu a hit, as a fraction of mu [1/hit] (`drift.DRIFT_SIZE`), at which its
    response would account for that much and the hits' own mu would show it as naming a
    drift asks (a trend, or with three hits a spread beyond `MU_SPREAD_FLOOR`)."""
    detection_limit_by_frequency: tuple[tuple[float, float], ...] = ()
    """A second mode's limit at each frequency of the band it is taken over, (frequency [Hz],
    modal mass [kg]) from the lowest: heavier modes show lower in the band. () for the other
    terms."""
    unobservable: str = ''
    """When the detection limit lies outside the effect's physical range (`physical_ranges`,
    or the term's declared bounds): that these records cannot show it, and what would; ''
    otherwise."""


@dataclass(frozen=True)
class ResidualLocation:
    """Where a residual sits beyond the noise: decay regions, bands, the model's speed, position."""

    summary: str
    excess_to_noise: float
    """RMS of the residual beyond the noise over the motion, over the noise RMS [-]."""
    time: tuple[discrepancy.RegionMisfit, ...]
    frequency: tuple[discrepancy.BandMisfit, ...]
    speed: tuple[discrepancy.BinMisfit, ...]
    """By the model's speed [m/s]: where friction's speed dependence would show."""
    position: tuple[discrepancy.BinMisfit, ...]
    """By the model's position [m]: where a wear track would show."""


@dataclass(frozen=True)
class NamedEffect:
    """One missing effect the diagnosis names, in the order forward selection added it."""

    effect: str
    """A term of the vocabulary, 'mu_drift', or 'unexplained'."""
    score: float
    """BIC change when it was added (negative: better); NaN for 'unexplained' [-]."""
    drop_score: float
    """BIC change if it were taken out of the final model again (positive: it earns its
    place); NaN for 'unexplained' [-]."""
    gap_after: float
    """Gap once it was added [-] (the final gap for 'unexplained')."""
    parameters: tuple[ParameterEstimate, ...]
    """Its own parameters in the final model (mu_drift: each hit's mu)."""
    trend: MuTrend | None = None
    """mu_drift: the per-hit mu, their slope in hit order and its significance."""
    where: ResidualLocation | None = None
    """'unexplained': where the residual the vocabulary leaves sits."""
    partial: bool = False
    """Named after 'unexplained': the vocabulary's best partial description of data it does
    not explain, not a finding on its own."""


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
    """What `diagnose` found: the named effects (or 'none'), the gap before and after, why."""

    missing_effect: str
    """The first of missing_effects, or 'none' (what single-answer callers read)."""
    missing_effects: tuple[NamedEffect, ...]
    """Every effect named, in the order added; 'unexplained' first when the best model leaves
    a structured residual or does not halve the gap (the names after it are then only the
    vocabulary's best partial description)."""
    parameters: tuple[ParameterEstimate, ...]
    """The final model's fitted parameters (the base model's when nothing is named)."""
    mu: float
    """Friction coefficient of `fmm fit`'s fit of the same records [-]: each hit's impulse
    scale, mains hum and velocity drift fitted (`FRICTION_FIT`). The selection's base model
    fits mu alone (its value is among `parameters` when nothing is named)."""
    mu_stderr: float
    starts: str
    """Where each hit's model started: 'centre', 'fitted' or 'chained' (`STARTS`). A
    direction-dependent friction can be named only from the centre or chained: fitted starts
    absorb it."""
    gap_before: float
    """RMS velocity residual beyond the noise (`residual_noise_std_m_s`) over the motion, over
    the peak speed, base model [-]."""
    gap_after: float
    """The same with every named effect added (= gap_before when none is) [-]."""
    frf_gap_before: float
    """Normalised mobility misfit beyond the noise, base model [-]."""
    frf_gap_after: float
    where: Where
    candidates: tuple[Candidate, ...]
    """Every candidate at the first selection step (against the base model), best first."""
    selection: tuple[str, ...]
    """What each step of the forward selection and the backward check did, in words."""
    residual_where: ResidualLocation
    """Where the final model's residual sits."""
    mu_trend: MuTrend | None
    """Each hit's mu and its trend in hit order (None for fewer than 3 hits)."""
    friction_map: FrictionMap
    """mu against sliding speed and position, from the records by inverse dynamics."""
    noise_std_m_s: float
    """Velocity noise estimated from the data (its white part, which chi^2 counts) [m/s]."""
    residual_noise_std_m_s: float
    """The noise a residual carries, which every gap is taken beyond [m/s]: the noise where
    the rig rests, coloured noise and hum included (an integrated record's: what it leaves in
    a residual)."""
    force_noise_std_n: float
    input_noise_allowance: float
    """Expected chi^2 the force noise alone puts into the base residual [-]."""
    required_score: float
    """An effect is added only with a score at or below this [-]."""
    verdict: str
    """One sentence: what was named and why, or why nothing was."""
    base_residuals_m_s: tuple[np.ndarray, ...] = field(repr=False)
    """Measured minus base-model velocity per impact [m/s] (for figures)."""
    named_residuals_m_s: tuple[np.ndarray, ...] = field(repr=False)
    """Measured minus final-model velocity per impact [m/s] (base again when none is named)."""

    @property
    def named_effects(self) -> tuple[str, ...]:
        """The named effects, 'unexplained' included, in order."""
        return tuple(named.effect for named in self.missing_effects)
