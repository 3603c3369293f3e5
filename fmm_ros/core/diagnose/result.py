"""What a diagnosis returns: the named effect, its parameters, every candidate, where, the gaps.

`fmm_ros.workflows.results.diagnosis_dict` is the JSON of `fmm diagnose --json`; the
DiagnoseModel service response is filled from the same object
(`fmm_ros.ros.msgs.fill_diagnose_response`).
"""

from dataclasses import dataclass, field

import numpy as np

from fmm_ros.core.diagnose import signatures as discrepancy


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
