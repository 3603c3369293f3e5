"""The model a report draws over a session, and the fit and diagnosis it shows.

`ModelOverlay` is Eq. 3 (and any extra terms) with a given or fitted mu, driven by each hit's
measured force conditioned exactly as the fitter conditions it (baseline removed, force
outside the hit zeroed: `fmm_ros.core.identify.condition_impact`), so the overlay is the curve
the fit was judged on. `FrictionSummary` holds the fields of the FitFriction service's
response plus the model it implies, so the report takes a fit made here
(`fit_accepted_impacts`, `FrictionSummary.from_fit`) or one a fitter node returned.
`SessionDiagnosis` is a `Diagnosis` of some of the session's impacts, with their ids
(`diagnose_accepted_impacts`). Every fit here takes its impacts by the signal core's
`select_impacts` (flagged ones left out and named unless include_flagged), as the fitter node
and `fmm fit` do; `select_records` is that rule for callers holding only records.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from fmm_ros.core._checks import require_non_negative
from fmm_ros.core.diagnose.result import Diagnosis
from fmm_ros.core.diagnose.workflow import diagnose
from fmm_ros.core.identify.conditioning import FitError, condition_impact
from fmm_ros.core.identify.friction import MU_BOUNDS, FrictionFit, fit_friction
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import ModelTerm
from fmm_ros.core.signal.analysis import (
    DEFAULT_ANALYSIS,
    AnalysisConfig,
    ImpactSelection,
    Summary,
    analyze_impact,
    select_impacts,
    summarize,
)
from fmm_ros.core.signal.capture import DEFAULT_CAPTURE, CaptureConfig, with_trigger
from fmm_ros.core.signal.records import ImpactRecord


@dataclass(frozen=True)
class ModelOverlay:
    """The model drawn over the measurement: Eq. 3 with this mu, rig and any extra terms.

    `source` says where mu came from ('fitted', 'given', ...) and appears in every legend.
    `initial_positions_m`: where the model starts for an impact id [m] (a fit of the rest
    position the previous hit left); 0 for any other.
    """

    mu: float
    source: str
    rig: Rig = FMM_RIG
    effects: tuple[ModelTerm, ...] = ()
    initial_positions_m: Mapping[int, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        require_non_negative('mu', self.mu)

    @property
    def label(self) -> str:
        """Legend text: 'model, fitted μ = 0.1131'."""
        terms = ''.join(f' + {term.name}' for term in self.effects)
        return f'model, {self.source} μ = {self.mu:.4g}{terms}'

    def velocity_m_s(self, record: ImpactRecord, impact_id: int) -> np.ndarray | None:
        """The model's velocity driven by the record's conditioned force.

        None when the record cannot drive it: samples missing (a gap), or no hit or no
        motion above the noise (what the fitter would refuse too).
        """
        if not (np.isfinite(record.force_n).all() and np.isfinite(record.velocity_m_s).all()):
            return None
        try:
            conditioned = condition_impact(
                record.force_n, record.velocity_m_s, record.sample_rate_hz, source=record.source
            )
        except FitError:
            return None
        return simulate(
            conditioned.force_n,
            record.sample_rate_hz,
            rig=self.rig,
            mu=self.mu,
            effects=self.effects,
            x0_m=self.initial_positions_m.get(impact_id, 0.0),
        ).velocity_m_s


@dataclass(frozen=True)
class FrictionSummary:
    """A friction fit as the report shows it: FitFriction.srv's response plus the model.

    Per-impact tuples are in `impact_ids` order. Standard errors and the consistency p-value
    are NaN where unknown (damping not fitted, a single impact).
    """

    mu: float
    mu_stderr: float
    rig: Rig
    """The fitted model's rig constants, damping included."""
    impact_ids: tuple[int, ...]
    per_impact_mu: tuple[float, ...]
    per_impact_mu_stderr: tuple[float, ...]
    damping_stderr_n_s_per_m: float = math.nan
    effects: tuple[ModelTerm, ...] = ()
    initial_positions_m: tuple[float, ...] = ()
    """Where each impact's model started in the joint fit [m]; empty: all at 0."""
    consistency_p_value: float = math.nan
    """Chance of per-impact mus scattering this much if one mu served all (chi^2 test)."""
    residual_rms_m_s: float = math.nan
    selection: ImpactSelection | None = None
    """Which of the session's impacts were fitted and which left out (flagged), if known."""

    def __post_init__(self) -> None:
        count = len(self.impact_ids)
        lengths = {len(self.per_impact_mu), len(self.per_impact_mu_stderr)}
        if self.initial_positions_m:
            lengths.add(len(self.initial_positions_m))
        if lengths != {count}:
            raise ValueError(
                f'a friction summary needs one value per impact: {count} impact '
                f'ids but per-impact lengths {sorted(lengths)}'
            )

    @classmethod
    def from_fit(
        cls,
        fit: FrictionFit,
        impact_ids: Sequence[int],
        selection: ImpactSelection | None = None,
    ) -> FrictionSummary:
        """The summary of a `fit_friction` result whose impacts were these, in this order."""
        joint = fit.joint
        return cls(
            mu=fit.mu,
            mu_stderr=fit.mu_stderr,
            rig=joint.rig,
            impact_ids=tuple(int(i) for i in impact_ids),
            per_impact_mu=tuple(f.mu for f in fit.per_impact),
            per_impact_mu_stderr=tuple(f.mu_stderr for f in fit.per_impact),
            damping_stderr_n_s_per_m=fit.damping_stderr_n_s_per_m,
            effects=joint.effects,
            initial_positions_m=joint.initial_positions_m,
            consistency_p_value=fit.consistency_p_value,
            residual_rms_m_s=joint.residual_rms_m_s,
            selection=selection,
        )

    def overlay(self) -> ModelOverlay:
        """The fitted model, each impact started where the fit started it."""
        starts = self.initial_positions_m or (0.0,) * len(self.impact_ids)
        return ModelOverlay(
            self.mu,
            'fitted',
            self.rig,
            self.effects,
            dict(zip(self.impact_ids, starts, strict=True)),
        )


def analyse_records(
    records: Sequence[ImpactRecord],
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig = DEFAULT_ANALYSIS,
) -> Summary:
    """The signal core's verdict on every record, impact i being record i."""
    return summarize(
        [
            analyze_impact(record, capture, analysis, impact_id=number)
            for number, record in enumerate(records)
        ],
        analysis,
    )


def select_records(
    records: Sequence[ImpactRecord],
    *,
    capture: CaptureConfig = DEFAULT_CAPTURE,
    analysis: AnalysisConfig = DEFAULT_ANALYSIS,
    include_flagged: bool = False,
    min_clean: int = 1,
) -> tuple[list[ImpactRecord], ImpactSelection]:
    """The records a fit takes (`select_impacts` over their analysis), and the selection.

    Raises FitError (reason 'no_hit') for a record without a hit, which has nothing to judge
    or fit, and `SelectionError` (a ValueError) naming the flagged records when fewer than
    min_clean are clean.
    """
    for record in records:
        try:
            with_trigger(record, capture)
        except ValueError as error:
            raise FitError('no_hit', f'no hit: {error}', record.source) from None
    selection = select_impacts(
        analyse_records(records, capture, analysis),
        include_flagged=include_flagged,
        min_clean=min_clean,
    )
    return [records[i] for i in selection.chosen], selection


def fit_accepted_impacts(
    records: Sequence[ImpactRecord],
    summary: Summary,
    *,
    rig: Rig = FMM_RIG,
    fit_damping: bool = False,
    fit_initial_position: bool = False,
    mu_bounds: tuple[float, float] = MU_BOUNDS,
    include_flagged: bool = False,
) -> FrictionSummary:
    """Fit one mu (and each impact's own) over the clean impacts, as the fitter node does.

    records[i] is impact i of the summary. Flagged impacts are left out (named in the
    result's selection) unless include_flagged. Raises SelectionError (a ValueError) when no
    impact is clean and FitError when friction cannot explain them.
    """
    selection = select_impacts(summary, include_flagged=include_flagged)
    fit = fit_friction(
        [records[i] for i in selection.chosen],
        rig=rig,
        fit_damping=fit_damping,
        fit_initial_position=fit_initial_position,
        mu_bounds=mu_bounds,
    )
    return FrictionSummary.from_fit(fit, selection.chosen, selection)


@dataclass(frozen=True)
class SessionDiagnosis:
    """A diagnosis (`fmm_ros.core.diagnose`) of these impacts of the session, in this order."""

    diagnosis: Diagnosis
    impact_ids: tuple[int, ...]
    rig: Rig = FMM_RIG
    """The rig constants the diagnosis ran with."""
    selection: ImpactSelection | None = None
    """Which of the session's impacts were diagnosed and which left out (flagged), if known."""

    def __post_init__(self) -> None:
        if len(self.diagnosis.base_residuals_m_s) != len(self.impact_ids):
            raise ValueError(
                f'the diagnosis covers {len(self.diagnosis.base_residuals_m_s)} '
                f'impacts but {len(self.impact_ids)} impact ids were given'
            )


def diagnose_accepted_impacts(
    records: Sequence[ImpactRecord],
    summary: Summary,
    *,
    rig: Rig = FMM_RIG,
    fit_initial_position: bool = False,
    include_flagged: bool = False,
) -> SessionDiagnosis:
    """The diagnose workflow over the clean impacts, as the fitter node runs it.

    Flagged impacts are left out unless include_flagged. Raises SelectionError (a
    ValueError) when no impact is clean and FitError when the base model cannot be fitted.
    """
    selection = select_impacts(summary, include_flagged=include_flagged)
    return SessionDiagnosis(
        diagnose(
            [records[i] for i in selection.chosen],
            rig=rig,
            fit_initial_position=fit_initial_position,
        ),
        selection.chosen,
        rig,
        selection,
    )
