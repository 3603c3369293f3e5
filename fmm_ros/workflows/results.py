"""One result type per concept, and the one place results become JSON.

- `FrictionResult`: a friction fit, whoever made it. `fmm fit --json` prints its `to_dict()`,
  the report draws it, the fitter node fills its FitFriction response from it and the demo
  turns that response back into one (`fmm_ros.ros.msgs.fill_fit_response`, `friction_result`),
  so the page of a demo shows the service's answer, not a second fit.
- `Diagnosis` (`fmm_ros.core.diagnose`): `diagnosis_dict` is the JSON of `fmm diagnose --json`
  and of a session's summary; the DiagnoseModel response is filled from the same object.
- `Summary` (`fmm_ros.core.signal.analysis`): `analysis_dict` is the JSON of `fmm analyze`.
- `ImpactSelection` (`select_impacts`): `selection_dict` names the impacts a fit left out (and
  flagged ones taken on request), in `fmm fit --json` and a session's JSON.
- A hit's and a level's record (`hit_record`, `level_record` over `HIT_FIELDS` and
  `LEVEL_FIELDS`): the scalars of an `ImpactAnalysis` or an ImpactResult message (the same
  names) and of a `LevelSummary` or FrfSummary message, as `fmm analyze --json`, the demo's
  summary and a campaign's hit and level tables show them.
- `RigIdentification`: `rig_identification_dict` is the JSON of `fmm identify-rig --json`.

Undefined numbers (a standard error of something not fitted, R^2 of two levels) are NaN in
the objects and null in JSON.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fmm_ros.core import results_schema as schema
from fmm_ros.core.diagnose import signatures
from fmm_ros.core.diagnose.drift import DRIFT_SIZE, MuTrend
from fmm_ros.core.diagnose.friction_map import FrictionCurve, FrictionMap
from fmm_ros.core.diagnose.result import (
    Diagnosis,
    NamedEffect,
    ParameterEstimate,
    ResidualLocation,
    Where,
)
from fmm_ros.core.identify.chain import VelocityNuisance
from fmm_ros.core.identify.friction import FrictionFit
from fmm_ros.core.identify.rig import RigIdentification
from fmm_ros.core.identify.running import RunningEstimate, running_estimates
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.physics.terms import EFFECT_SIZE, ModelTerm, size_parameter
from fmm_ros.core.signal.analysis import ImpactSelection, Summary
from fmm_ros.core.signal.judging import Decision
from fmm_ros.errors import BadInputError
from fmm_ros.io.frf_files import json_number


@dataclass(frozen=True)
class FrictionResult:
    """One mu for all the fitted impacts and each impact's own, with the model they imply.

    Per-impact tuples follow `impact_ids` (the session's impact numbers). Values not known
    to whoever made the result (a service response has no noise estimate of each record) are
    NaN, or empty tuples for per-impact values.
    """

    mu: float
    mu_stderr: float
    rig: Rig
    """The fitted model's rig constants, its damping fitted or as given."""
    impact_ids: tuple[int, ...]
    per_impact_mu: tuple[float, ...]
    per_impact_mu_stderr: tuple[float, ...]
    initial_positions_m: tuple[float, ...] = ()
    """Where each impact's model started in the joint fit [m]; empty: all at x = 0."""
    sources: tuple[str, ...] = ()
    """Each impact's file (or bag@trigger, or 'impact <id>' for a service)."""
    impulses_n_s: tuple[float, ...] = ()
    per_impact_residual_rms_m_s: tuple[float, ...] = ()
    """RMS velocity residual of each impact at the common mu [m/s]."""
    per_impact_normalised_residual: tuple[float, ...] = ()
    damping_fitted: bool = False
    damping_stderr_n_s_per_m: float = math.nan
    residual_rms_m_s: float = math.nan
    normalised_residual: float = math.nan
    """residual_rms_m_s over the largest measured |velocity| [-]."""
    noise_std_m_s: float = math.nan
    consistency_chi2: float = math.nan
    consistency_p_value: float = math.nan
    """Chance of per-impact mus scattering this much if one mu served all (chi^2 test)."""
    misfit: str = 'time'
    effects: tuple[ModelTerm, ...] = ()
    impulse_scales: tuple[float, ...] = ()
    """The factor the joint fit put on each impact's measured hit [-]; empty: all 1."""
    velocity_nuisance: tuple[VelocityNuisance, ...] = ()
    """What the joint fit took off each impact's velocity (hum, offset, drift); empty where
    not known (a service's answer)."""

    def __post_init__(self) -> None:
        count = len(self.impact_ids)
        lengths = {len(self.per_impact_mu), len(self.per_impact_mu_stderr)}
        for name in (
            'initial_positions_m',
            'sources',
            'impulses_n_s',
            'per_impact_residual_rms_m_s',
            'per_impact_normalised_residual',
            'impulse_scales',
            'velocity_nuisance',
        ):
            if getattr(self, name):
                lengths.add(len(getattr(self, name)))
        if lengths != {count}:
            raise BadInputError(
                f'a friction result needs one value per impact: {count} impact '
                f'ids but per-impact lengths {sorted(lengths)}'
            )

    @classmethod
    def from_fit(cls, fit: FrictionFit, impact_ids: Sequence[int]) -> FrictionResult:
        """The result of a `fit_friction` whose impacts were these, in this order."""
        joint = fit.joint
        return cls(
            mu=fit.mu,
            mu_stderr=fit.mu_stderr,
            rig=joint.rig,
            impact_ids=tuple(int(i) for i in impact_ids),
            per_impact_mu=tuple(f.mu for f in fit.per_impact),
            per_impact_mu_stderr=tuple(f.mu_stderr for f in fit.per_impact),
            initial_positions_m=tuple(joint.initial_positions_m),
            sources=tuple(joint.sources),
            impulses_n_s=tuple(fit.impulses_n_s),
            per_impact_residual_rms_m_s=tuple(joint.impact_residual_rms_m_s),
            per_impact_normalised_residual=tuple(joint.impact_normalised_residual),
            damping_fitted='damping_n_s_per_m' in joint.names,
            damping_stderr_n_s_per_m=fit.damping_stderr_n_s_per_m,
            residual_rms_m_s=joint.residual_rms_m_s,
            normalised_residual=joint.normalised_residual,
            noise_std_m_s=joint.noise_std_m_s,
            consistency_chi2=fit.consistency_chi2,
            consistency_p_value=fit.consistency_p_value,
            misfit=joint.misfit,
            effects=joint.effects,
            impulse_scales=tuple(joint.impulse_scales),
            velocity_nuisance=tuple(joint.velocity_nuisance),
        )

    @property
    def damping_n_s_per_m(self) -> float:
        """Viscous damping of the model, fitted or as given [N*s/m]."""
        return self.rig.damping_n_s_per_m

    def running(self, levels: Sequence[str]) -> tuple[RunningEstimate, ...]:
        """The running estimate after each impact in turn, as the fitter node publishes it.

        levels: each impact's level (`core.identify.running`).
        """
        return running_estimates(
            list(self.impact_ids),
            list(levels),
            list(self.per_impact_mu),
            list(self.per_impact_mu_stderr),
        )

    def per_impact(self) -> list[dict]:
        """One entry per impact: id, file, mu alone, impulse, residual, start, scale, chain."""
        count = len(self.impact_ids)

        def column(values: tuple, default: object = math.nan) -> tuple:
            return values or (default,) * count

        entries = []
        for impact_id, source, mu, impulse, rms, stderr, normalised, start, scale, chain in zip(
            self.impact_ids,
            column(self.sources, ''),
            self.per_impact_mu,
            column(self.impulses_n_s),
            column(self.per_impact_residual_rms_m_s),
            self.per_impact_mu_stderr,
            column(self.per_impact_normalised_residual),
            column(self.initial_positions_m, 0.0),
            column(self.impulse_scales, 1.0),
            column(self.velocity_nuisance, None),
            strict=True,
        ):
            values = (impact_id, source, mu, impulse, rms, stderr, normalised, start, scale)
            entry = dict(zip(schema.keys(schema.FIT_IMPACT), values, strict=True))
            if chain is not None:
                entry.update(
                    mains_hum_hz=chain.mains_hz or None,
                    hum_rms_m_s=chain.hum_rms_m_s,
                    velocity_offset_m_s=chain.offset_m_s,
                    velocity_drift_m_s2=chain.drift_m_s2,
                )
            entries.append(entry)
        return entries

    def to_dict(self) -> dict:
        """The JSON of `fmm fit --json`: the issue's keys first, then errors and the test."""
        return json_safe(
            {
                'mu': self.mu,
                'mu_stderr': self.mu_stderr,
                'damping_n_s_per_m': self.damping_n_s_per_m,
                'residual_rms_m_s': self.residual_rms_m_s,
                'per_file': self.per_impact(),
                'damping_stderr_n_s_per_m': self.damping_stderr_n_s_per_m,
                'damping_fitted': self.damping_fitted,
                'normalised_residual': self.normalised_residual,
                'noise_std_m_s': self.noise_std_m_s,
                'mu_consistency_chi2': self.consistency_chi2,
                'mu_consistency_p_value': self.consistency_p_value,
                'misfit': self.misfit,
                'rig': {
                    'mass_kg': self.rig.mass_kg,
                    'stiffness_n_per_m': self.rig.stiffness_n_per_m,
                    'damping_n_s_per_m': self.rig.damping_n_s_per_m,
                    'normal_force_n': self.rig.normal_force_n,
                },
                'effects': [term.name for term in self.effects],
            }
        )


HIT_FIELDS: tuple[str, ...] = schema.keys(schema.HIT_RECORD)
"""A hit's record: its scalars, named as in ImpactAnalysis and ImpactResult.msg."""

LEVEL_FIELDS: tuple[str, ...] = schema.keys(schema.LEVEL_RECORD)
"""A level's record: its scalars, named as in LevelSummary and FrfSummary.msg."""


def hit_record(result: object, fields: Sequence[str] = HIT_FIELDS) -> dict:
    """The fields (in that order) of an ImpactAnalysis or an ImpactResult message.

    As Python numbers, strings and a tuple of flags (`json_safe` makes it JSON).
    """
    return {name: _plain(getattr(result, name)) for name in fields}


def level_record(level: object, fields: Sequence[str] = LEVEL_FIELDS) -> dict:
    """The fields (in that order) of a LevelSummary or an FrfSummary message, as plain values."""
    return {name: _plain(getattr(level, name)) for name in fields}


def _plain(value: object) -> object:
    """Numpy scalars as Python numbers, sequences of flags as a tuple of str."""
    if isinstance(value, np.integer | np.bool_):
        return value.item()
    if isinstance(value, float | np.floating):
        return float(value)
    if isinstance(value, list | tuple) or hasattr(value, 'tolist'):
        return tuple(value)
    return value


def analysis_dict(summary: Summary) -> dict:
    """The JSON of `fmm analyze`: impacts, levels and linearity (undefined numbers as null)."""
    return json_safe(
        {
            'impacts': [
                {
                    'file': result.source,
                    **hit_record(result, schema.keys(schema.ANALYSIS_IMPACT)),
                }
                for result in summary.impacts
            ],
            'levels': [
                {
                    'name': level.level,
                    **level_record(level, schema.keys(schema.ANALYSIS_LEVEL)),
                }
                for level in summary.levels
            ],
            'linearity': {
                'slope': summary.linearity.slope,
                'intercept': summary.linearity.intercept,
                'r2': summary.linearity.r2,
            },
        }
    )


def selection_dict(selection: ImpactSelection | None) -> dict:
    """JSON keys naming the impacts left out of a fit (and flagged ones taken on request)."""
    if selection is None:
        return {}

    def entries(items: tuple) -> list[dict]:
        return [
            {'impact_id': impact_id, 'file': source or None, 'flags': list(flags)}
            for impact_id, flags, source in items
        ]

    return {
        'left_out': entries(selection.excluded),
        'included_flagged': entries(selection.included_flagged),
        'judged': [decision_dict(decision) for decision in selection.judged],
    }


def decision_dict(decision: Decision) -> dict:
    """A judging decision as JSON (`core.signal.judging.Decision`'s fields)."""
    return dataclasses.asdict(decision)


def diagnosis_dict(diagnosis: Diagnosis) -> dict:
    """The JSON of `fmm diagnose --json` (undefined numbers as null)."""
    return json_safe(
        {
            'missing_effect': diagnosis.missing_effect,
            'missing_effects': [_named_dict(named) for named in diagnosis.missing_effects],
            'parameters': {p.name: p.value for p in diagnosis.parameters},
            'parameter_units': {p.name: p.unit for p in diagnosis.parameters},
            'parameter_stderr': {p.name: p.stderr for p in diagnosis.parameters},
            'parameter_at_bound': {p.name: p.at_bound for p in diagnosis.parameters},
            'mu': diagnosis.mu,
            'mu_stderr': diagnosis.mu_stderr,
            'starts': diagnosis.starts,
            'gap_before': diagnosis.gap_before,
            'gap_after': diagnosis.gap_after,
            'frf_gap_before': diagnosis.frf_gap_before,
            'frf_gap_after': diagnosis.frf_gap_after,
            'where': _where_dict(diagnosis.where),
            'candidates': [
                {
                    'effect': c.effect,
                    'score': c.score,
                    'aic_score': c.aic_score,
                    'gap_after': c.gap_after,
                    'frf_gap_after': c.frf_gap_after,
                    'parameters': {p.name: p.value for p in c.parameters},
                    'parameter_stderr': {p.name: p.stderr for p in c.parameters},
                    'detection_limit': detection_limit_dict(
                        c.effect, c.detection_limit, c.detection_limit_by_frequency
                    ),
                    **({'message': c.message} if c.message else {}),
                    **({'unobservable': c.unobservable} if c.unobservable else {}),
                }
                for c in diagnosis.candidates
            ],
            'noise_std_m_s': diagnosis.noise_std_m_s,
            'residual_noise_std_m_s': diagnosis.residual_noise_std_m_s,
            'force_noise_std_n': diagnosis.force_noise_std_n,
            'input_noise_allowance': diagnosis.input_noise_allowance,
            'required_score': diagnosis.required_score,
            'verdict': diagnosis.verdict,
            'selection': list(diagnosis.selection),
            'residual_where': _location_dict(diagnosis.residual_where),
            'mu_trend': None if diagnosis.mu_trend is None else _trend_dict(diagnosis.mu_trend),
            'friction_map': friction_map_dict(diagnosis.friction_map),
        }
    )


def detection_limit_dict(
    effect: str, value: float, by_frequency: Sequence[tuple[float, float]] = ()
) -> dict | None:
    """A candidate's `detection_limit` as JSON (None when it has none).

    The size parameter it is of (mu_drift's: `DRIFT_SIZE`), its value and unit, and whether
    the effect shows 'above' it or, for a second mode's mass, 'below' it; a second mode's
    also `by_frequency`, its limit at each frequency of the band it is taken over
    (`Candidate.detection_limit_by_frequency`). None: a term with no probe (a second mode in
    a session whose hits excite no band), or a direction nothing of which is its own.
    """
    if not math.isfinite(value):
        return None
    parameter = size_parameter(effect)
    name, unit = DRIFT_SIZE if parameter is None else (parameter.name, parameter.unit)
    limit = {
        'parameter': f'{effect}.{name}',
        'value': value,
        'unit': unit,
        'shows': 'below' if EFFECT_SIZE.get(effect, ('', False))[1] else 'above',
    }
    if by_frequency:
        limit['by_frequency'] = {
            'frequency_hz': [f for f, _ in by_frequency],
            'value': [v for _, v in by_frequency],
        }
    return limit


def detection_limit_text(limit: dict | None) -> str:
    """A `detection_limit_dict` in a few characters: '>= 1.9e+05 N/m^3'; '-' for none.

    A limit taken over a band says which: '<= 86 kg over 5-643 Hz'.
    """
    if limit is None:
        return '-'
    sign = '<=' if limit['shows'] == 'below' else '>='
    unit = '' if limit['unit'] == '1' else f' {limit["unit"]}'
    band = limit.get('by_frequency', {}).get('frequency_hz')
    over = f' over {band[0]:.0f}-{band[-1]:.0f} Hz' if band else ''
    return f'{sign} {limit["value"]:.2g}{unit}{over}'


def friction_map_dict(friction_map: FrictionMap) -> dict:
    """The `friction_map` of `fmm diagnose --json`: bin centres, mu, its error, runs."""

    def curve(values: FrictionCurve, key: str) -> dict:
        return {
            key: list(values.centres),
            'mu': list(values.mu),
            'mu_stderr': list(values.mu_stderr),
            'runs': list(values.runs),
        }

    return {
        'speed': curve(friction_map.speed, 'speed_m_s'),
        'position': curve(friction_map.position, 'position_m'),
    }


def _estimates_dict(parameters: tuple[ParameterEstimate, ...]) -> dict:
    return {
        'parameters': {p.name: p.value for p in parameters},
        'parameter_stderr': {p.name: p.stderr for p in parameters},
        'parameter_units': {p.name: p.unit for p in parameters},
        'parameter_at_bound': {p.name: p.at_bound for p in parameters},
    }


def _named_dict(named: NamedEffect) -> dict:
    entry = {
        'effect': named.effect,
        'score': named.score,
        'drop_score': named.drop_score,
        'gap_after': named.gap_after,
        'partial': named.partial,
        **_estimates_dict(named.parameters),
    }
    if named.trend is not None:
        entry.update(_trend_dict(named.trend))
    if named.where is not None:
        entry['where'] = _location_dict(named.where)
    return entry


def _trend_dict(trend: MuTrend) -> dict:
    return {
        'mu_per_hit': list(trend.mu),
        'mu_per_hit_stderr': list(trend.mu_stderr),
        'mu_per_hit_refitted': trend.refitted,
        'slope_per_hit': trend.slope_per_hit,
        'slope_stderr': trend.slope_stderr,
        'trend_p_value': trend.p_value,
        'consistency_chi2': trend.consistency_chi2,
        'consistency_p_value': trend.consistency_p_value,
    }


def _location_dict(location: ResidualLocation) -> dict:
    def bins(values: Sequence[signatures.BinMisfit], unit: str) -> list[dict]:
        return [
            {
                f'low_{unit}': b.low,
                f'high_{unit}': b.high,
                'samples': b.samples,
                'excess_rms_m_s': b.excess_rms_m_s,
                'share': b.share,
            }
            for b in values
        ]

    return {
        'summary': location.summary,
        'excess_to_noise': location.excess_to_noise,
        'time': [
            {'region': r.name, 'share': r.share, 'excess_rms_m_s': r.excess_rms_m_s}
            for r in location.time
        ],
        'frequency': [
            {'band': b.name, 'low_hz': b.low_hz, 'high_hz': b.high_hz, 'share': b.share}
            for b in location.frequency
        ],
        'speed': bins(location.speed, 'm_s'),
        'position': bins(location.position, 'm'),
    }


def rig_identification_dict(result: RigIdentification) -> dict:
    """The JSON of `fmm identify-rig --json`: the constants, their errors, how they were found."""
    return json_safe(
        {
            'mass_kg': result.mass_kg,
            'stiffness_n_per_m': result.stiffness_n_per_m,
            'damping_n_s_per_m': result.damping_n_s_per_m,
            'natural_frequency_hz': result.natural_frequency_hz,
            'damping_ratio': result.damping_ratio,
            'mass_stderr_kg': result.mass_stderr_kg,
            'stiffness_stderr_n_per_m': result.stiffness_stderr_n_per_m,
            'damping_stderr_n_s_per_m': result.damping_stderr_n_s_per_m,
            'natural_frequency_stderr_hz': result.natural_frequency_stderr_hz,
            'damping_ratio_stderr': result.damping_ratio_stderr,
            'method': result.method,
            'residual_rms_m_s': result.residual_rms_m_s,
            'normalised_residual': result.normalised_residual,
            'files': list(result.sources),
            'free_decays': [
                {
                    'file': decay.source,
                    'natural_frequency_hz': decay.natural_frequency_hz,
                    'damping_ratio': decay.damping_ratio,
                }
                for decay in result.free_decays
            ],
        }
    )


def json_safe(value: object) -> object:
    """Plain floats all the way down, NaN and infinities as None (JSON has neither).

    Tuples become lists, dates ISO text, keys text.
    """
    if isinstance(value, dict):
        return {str(key): json_safe(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(item) for item in value]
    if isinstance(value, float | np.floating):
        return json_number(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, dt.datetime | dt.date):
        return value.isoformat()
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


def _signature_dict(signature: signatures.DecaySignatures) -> dict:
    return dict(vars(signature))
