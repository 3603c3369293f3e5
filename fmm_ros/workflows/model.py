"""The model beside the measurement: Eq. 3 driven by each hit's force, and how far off it is.

`ModelOverlay` is Eq. 3 (and any extra terms) with a given or fitted mu, driven by each hit's
measured force conditioned exactly as the fitter conditions it (baseline removed, force
outside the hit zeroed: `fmm_ros.core.identify.condition_impact`), so the curve is the one the
fit was judged on. `compare_model` runs it for every hit of a session: each hit's model
velocity goes through `analyze_impact` with the measurement's trigger and configs (so model
and measured FRFs share windows, band and bins, and level means average the same hits), the
RMS of measured minus model over the motion, and each level's mean model mobility. The model
velocities themselves are not kept (2.6 MB a 33 s record): a figure asks the overlay again
(4 ms a record).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from fmm_ros.core._checks import require_non_negative
from fmm_ros.core.identify.conditioning import condition_impact
from fmm_ros.core.physics.model import simulate
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.core.physics.terms import ModelTerm
from fmm_ros.core.signal.analysis import AnalysisConfig, ImpactAnalysis, Summary, analyze_impact
from fmm_ros.core.signal.capture import CaptureConfig
from fmm_ros.core.signal.records import ImpactRecord
from fmm_ros.errors import FitError

# A hit's motion, as plotted and as its residual is judged: past the last sample above the
# rest velocity by this fraction of the motion, and at least MIN_DECAY_S after the trigger.
DECAY_MARGIN = 0.15
MIN_DECAY_S = 0.5


@dataclass(frozen=True)
class ModelOverlay:
    """The model drawn over the measurement: Eq. 3 with this mu, rig and any extra terms.

    `source` says where mu came from ('fitted', 'given', ...) and appears in every legend.
    `initial_positions_m`: where the model starts for an impact id [m] (a fit of the rest
    position the previous hit left); 0 for any other. `impulse_scales`: the factor a fit put
    on an impact id's measured hit [-]; 1 for any other.
    """

    mu: float
    source: str
    rig: Rig = FMM_RIG
    effects: tuple[ModelTerm, ...] = ()
    initial_positions_m: Mapping[int, float] = field(default_factory=dict)
    impulse_scales: Mapping[int, float] = field(default_factory=dict)

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
            conditioned.force_n * self.impulse_scales.get(impact_id, 1.0),
            record.sample_rate_hz,
            rig=self.rig,
            mu=self.mu,
            effects=self.effects,
            x0_m=self.initial_positions_m.get(impact_id, 0.0),
        ).velocity_m_s


@dataclass(frozen=True, eq=False)
class ModelHit:
    """One hit with the model's velocity in place of the measured one."""

    result: ImpactAnalysis
    """The model's velocity analysed by the measurement's pipeline (windows, band, trigger)."""
    residual_rms_m_s: float
    """RMS of measured minus model velocity from the trigger until both are at rest, over
    the samples that arrived [m/s]."""


@dataclass(frozen=True, eq=False)
class ModelComparison:
    """The model run for every hit that can drive it, and each level's mean model mobility."""

    model: ModelOverlay
    hits: dict[int, ModelHit]
    """By impact id; a hit with gaps (or no hit above the noise) has none."""
    level_mobility: dict[str, np.ndarray]
    """Plain-mean model mobility of each level whose every accepted hit has a model [m/(N*s)]."""


def compare_model(
    records: Sequence[ImpactRecord],
    summary: Summary,
    model: ModelOverlay,
    capture: CaptureConfig,
    analysis: AnalysisConfig,
    *,
    progress: Callable[[str], None] | None = None,
) -> ModelComparison:
    """The model driven by every hit of the summary (record i is impact i), analysed."""
    hits = {}
    for position, (impact, record) in enumerate(zip(summary.impacts, records, strict=True)):
        if progress:
            progress(f'model of hit {position + 1}/{len(summary.impacts)}')
        velocity = model.velocity_m_s(record, impact.impact_id)
        if velocity is None:
            continue
        simulated = dataclasses.replace(
            record,
            velocity_m_s=velocity,
            trigger_sample_index=impact.trigger_sample_index,
            record_start_sample_index=impact.record_start_sample_index,
        )
        trigger = trigger_offset(impact)
        rate = record.sample_rate_hz
        end_s = decay_end_s(
            [record.velocity_m_s, velocity], trigger, rate, capture.rest_velocity_m_s
        )
        end = trigger + int(end_s * rate) + 1
        residual = record.velocity_m_s[trigger:end] - velocity[trigger:end]
        received = residual[np.isfinite(residual)]  # velocity samples lost in a gap are NaN
        hits[impact.impact_id] = ModelHit(
            analyze_impact(simulated, capture, analysis, impact_id=impact.impact_id),
            float(np.sqrt(np.mean(received**2))) if received.size else float('nan'),
        )
    level_mobility = {}
    for level in summary.levels:
        members = [hits[i].result for i in level.impact_ids if i in hits]
        if len(members) == level.count:
            level_mobility[level.level] = np.mean([result.mobility for result in members], axis=0)
    return ModelComparison(model, hits, level_mobility)


def trigger_offset(result: ImpactAnalysis) -> int:
    """The trigger's position inside its record [samples]."""
    return result.trigger_sample_index - result.record_start_sample_index


def decay_end_s(
    velocities: Sequence[np.ndarray],
    triggers: Sequence[int] | int,
    sample_rate_hz: float,
    rest_velocity_m_s: float,
) -> float:
    """Where a hit's motion ends [s after the trigger]: past the last motion of any trace.

    The last sample above the rest velocity, plus DECAY_MARGIN of the motion, at least
    MIN_DECAY_S, at most the end of the longest record.
    """
    if isinstance(triggers, int):
        triggers = [triggers] * len(velocities)
    last_s, record_end_s = MIN_DECAY_S, 0.0
    for velocity, trigger in zip(velocities, triggers, strict=True):
        moving = np.flatnonzero(np.abs(velocity[trigger:]) > rest_velocity_m_s)
        if moving.size:
            last_s = max(last_s, moving[-1] / sample_rate_hz * (1 + DECAY_MARGIN))
        record_end_s = max(record_end_s, (velocity.size - 1 - trigger) / sample_rate_hz)
    return min(last_s, record_end_s)
