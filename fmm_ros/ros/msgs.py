"""numpy <-> fmm_interfaces message conversion: the only module that knows field layouts.

Large float64[] fields go in through `array.array('d', x.tobytes())` (one memcpy, no Python
floats) and come out through `np.frombuffer` (no copy at all), as the brief measured that
Python lists cost orders of magnitude more.
"""

import array
import dataclasses
import math

import numpy as np
from builtin_interfaces.msg import Time

from fmm_interfaces.msg import (
    FrfSummary,
    FrictionEstimate,
    ImpactDecision,
    ImpactResult,
    SampleBatch,
)
from fmm_interfaces.msg import SessionInfo as SessionInfoMsg
from fmm_ros.constants import Channel
from fmm_ros.core import diagnose
from fmm_ros.core.identify.running import LevelEstimate, RunningEstimate
from fmm_ros.core.physics.rig import Rig
from fmm_ros.core.results_schema import ASCII_PM, format_with_uncertainty
from fmm_ros.core.signal import analysis, frf, judging
from fmm_ros.core.signal.stream import Batch
from fmm_ros.errors import BadInputError
from fmm_ros.io.session_info import FIELDS, SessionInfo
from fmm_ros.units import sample_si_factor
from fmm_ros.workflows.results import FrictionResult, detection_limit_dict, json_safe


def float64_field(values: np.ndarray) -> array.array:
    """A float64[] message field holding a copy of values."""
    return array.array('d', np.ascontiguousarray(values, dtype=np.float64).tobytes())


def field_array(field: array.array) -> np.ndarray:
    """A read-only float64 view of a float64[] message field, without copying."""
    view = np.frombuffer(field, dtype=np.float64)
    view.flags.writeable = False
    return view


def sample_batch(
    samples: np.ndarray,
    *,
    quantity: Channel,
    sample_rate_hz: float,
    first_sample_index: int,
    stamp: Time,
    frame_id: str,
    full_scale: float = 0.0,
) -> SampleBatch:
    """A SampleBatch message of one channel (`fmm_ros.constants.FORCE` or `VELOCITY`)."""
    msg = _stamped(SampleBatch(), stamp, frame_id)
    msg.quantity, msg.unit = quantity
    msg.sample_rate_hz = float(sample_rate_hz)
    msg.first_sample_index = int(first_sample_index)
    msg.full_scale = float(full_scale)
    msg.samples = float64_field(samples)
    return msg


def batch_samples(msg: SampleBatch) -> np.ndarray:
    """The samples of a SampleBatch as a read-only float64 view (no copy)."""
    return field_array(msg.samples)


def _stamped(msg: object, stamp: Time, frame_id: str) -> object:
    """The message with its header's stamp and frame_id set (returned)."""
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    return msg


def stamp_ns(stamp: Time) -> int:
    """A builtin_interfaces/Time as nanoseconds."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def time_msg(nanoseconds: int) -> Time:
    """Nanoseconds as a builtin_interfaces/Time."""
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def stream_batch(msg: SampleBatch) -> Batch:
    """A SampleBatch as the signal core's stream takes it (samples viewed, not copied)."""
    return Batch(
        msg.first_sample_index,
        field_array(msg.samples),
        msg.sample_rate_hz,
        msg.full_scale,
        msg.header.frame_id,
        stamp_ns(msg.header.stamp),
    )


def si_stream_batch(msg: SampleBatch, quantity: str) -> Batch:
    """`stream_batch` in SI: samples and range converted from msg.unit (`units.sample_si_factor`).

    Raises UnitError, naming the unit, for a unit the table does not know as a `quantity` unit.
    A batch already in SI is viewed, not copied.
    """
    batch = stream_batch(msg)
    factor = sample_si_factor(quantity, msg.unit)
    if factor == 1.0:
        return batch
    return dataclasses.replace(
        batch, samples=batch.samples * factor, full_scale=batch.full_scale * factor
    )


def _set_complex(msg: object, name: str, values: np.ndarray) -> None:
    """Set the `<name>_real` / `<name>_imag` float64[] pair of msg from a complex array."""
    setattr(msg, f'{name}_real', float64_field(values.real))
    setattr(msg, f'{name}_imag', float64_field(values.imag))


def fill_from(msg: object, result: object) -> object:
    """Set every field of msg that the dataclass result has under the same name (returned).

    The message types are declared to match the core's results (`ImpactAnalysis` and
    ImpactResult.msg, `LevelSummary` and FrfSummary.msg): a field added to both is filled
    here without a line of its own. Complex arrays go to the `<name>_real` / `<name>_imag`
    float64[] pair; fields the message lacks (spectra kept for averaging) are left out.
    """
    types = msg.get_fields_and_field_types()
    for field in dataclasses.fields(result):
        name, value = field.name, getattr(result, field.name)
        if f'{name}_real' in types and np.iscomplexobj(value):
            _set_complex(msg, name, np.asarray(value))
        elif name in types:
            setattr(msg, name, _field_value(types[name], value))
    return msg


def _field_value(kind: str, value: object) -> object:
    """Value as a message field of ROS type kind ('double', 'sequence<string>', ...) takes it."""
    if kind.startswith('sequence<double'):
        return float64_field(np.asarray(value, dtype=np.float64))
    if kind.startswith('sequence<string'):
        return [str(item) for item in value]
    if kind.startswith('sequence<'):
        return [int(item) for item in value]
    if kind in ('double', 'float'):
        return float(value)
    if kind == 'boolean':
        return bool(value)
    if kind == 'string':
        return str(value)
    return int(value)


def impact_result_msg(
    result: analysis.ImpactAnalysis, *, stamp: Time, frame_id: str = 'fmm'
) -> ImpactResult:
    """An ImpactResult message from the signal core's result (same field names)."""
    return fill_from(_stamped(ImpactResult(), stamp, frame_id), result)


def frf_summary_msg(
    level: analysis.LevelSummary, linearity: frf.LinearFit, *, stamp: Time, frame_id: str = 'fmm'
) -> FrfSummary:
    """A FrfSummary message: one level's averages plus the linearity fit over all levels."""
    msg = fill_from(_stamped(FrfSummary(), stamp, frame_id), level)
    msg.linearity_slope_m_per_n2_s = float(linearity.slope)
    msg.linearity_intercept_m_per_n = float(linearity.intercept)
    msg.linearity_r2 = float(linearity.r2)
    msg.linearity_levels = int(linearity.count)
    return msg


def friction_estimate_msg(
    estimate: RunningEstimate, *, stamp: Time, frame_id: str = 'fmm'
) -> FrictionEstimate:
    """A FrictionEstimate message from the running estimate (same field names)."""
    msg = _stamped(FrictionEstimate(), stamp, frame_id)
    msg.impact_id = int(estimate.impact_id)
    msg.count = int(estimate.count)
    for name in (
        'mu',
        'mu_stderr',
        'consistency_chi2',
        'consistency_p_value',
        'impact_mu',
        'impact_mu_stderr',
    ):
        setattr(msg, name, float(getattr(estimate, name)))
    msg.level_names = [level.level for level in estimate.levels]
    msg.level_counts = [int(level.count) for level in estimate.levels]
    msg.level_mu = float64_field([level.mu for level in estimate.levels])
    msg.level_mu_stderr = float64_field([level.mu_stderr for level in estimate.levels])
    msg.impact_ids = [int(impact_id) for impact_id in estimate.impact_ids]
    return msg


def running_estimate(msg: FrictionEstimate) -> RunningEstimate:
    """The running estimate a FrictionEstimate message carries."""
    return RunningEstimate(
        impact_id=int(msg.impact_id),
        impact_mu=msg.impact_mu,
        impact_mu_stderr=msg.impact_mu_stderr,
        count=int(msg.count),
        mu=msg.mu,
        mu_stderr=msg.mu_stderr,
        consistency_chi2=msg.consistency_chi2,
        consistency_p_value=msg.consistency_p_value,
        levels=tuple(
            LevelEstimate(name, int(count), float(mu), float(stderr))
            for name, count, mu, stderr in zip(
                msg.level_names,
                msg.level_counts,
                field_array(msg.level_mu),
                field_array(msg.level_mu_stderr),
                strict=True,
            )
        ),
        impact_ids=tuple(int(i) for i in msg.impact_ids),
    )


def decision_msg(decision: judging.Decision, *, frame_id: str = 'fmm') -> ImpactDecision:
    """An ImpactDecision message of a decision (same field names; stamp: when decided)."""
    msg = _stamped(ImpactDecision(), time_msg(decision.stamp_ns), frame_id)
    msg.impact_id = decision.impact_id
    msg.trigger_sample_index = max(0, decision.trigger_sample_index)
    msg.verdict = decision.verdict
    msg.decided_by = decision.decided_by
    msg.reason = decision.reason
    msg.mode = decision.mode
    return msg


def decision(msg: ImpactDecision) -> judging.Decision:
    """The decision an ImpactDecision message carries (BadInputError for a malformed one)."""
    return judging.Decision(
        int(msg.impact_id),
        msg.verdict,
        msg.decided_by,
        msg.reason,
        msg.mode,
        int(msg.trigger_sample_index),
        stamp_ns(msg.header.stamp),
    )


def complex_field(msg: object, name: str) -> np.ndarray:
    """The complex array stored in msg's `<name>_real` / `<name>_imag` pair."""
    real = field_array(getattr(msg, f'{name}_real'))
    return real + 1j * field_array(getattr(msg, f'{name}_imag'))


def fill_diagnose_response(response: object, result: diagnose.Diagnosis) -> object:
    """Copy a Diagnosis into a DiagnoseModel response (success = True); returns it."""
    response.success = True
    response.message = result.verdict
    response.missing_effect = result.missing_effect
    response.parameter_names = [p.name for p in result.parameters]
    response.parameter_values = float64_field([p.value for p in result.parameters])
    response.parameter_units = [p.unit for p in result.parameters]
    response.parameter_stderr = float64_field([p.stderr for p in result.parameters])
    response.parameter_at_bound = [p.at_bound for p in result.parameters]
    response.mu, response.mu_stderr = result.mu, result.mu_stderr
    response.gap_before, response.gap_after = result.gap_before, result.gap_after
    response.frf_gap_before, response.frf_gap_after = (result.frf_gap_before, result.frf_gap_after)
    response.where = result.where.summary
    response.candidate_effects = [c.effect for c in result.candidates]
    response.candidate_scores = float64_field([c.score for c in result.candidates])
    response.candidate_gap_after = float64_field([c.gap_after for c in result.candidates])
    response.candidate_parameter_counts = [len(c.parameters) for c in result.candidates]
    response.candidate_parameter_names = [p.name for c in result.candidates for p in c.parameters]
    response.candidate_parameter_values = float64_field(
        [p.value for c in result.candidates for p in c.parameters]
    )
    response.candidate_detection_limits = float64_field(
        [c.detection_limit for c in result.candidates]
    )
    curves = [c.detection_limit_by_frequency for c in result.candidates]
    response.candidate_limit_curve_counts = [len(curve) for curve in curves]
    response.candidate_limit_curve_frequencies_hz = float64_field(
        [f for curve in curves for f, _ in curve]
    )
    response.candidate_limit_curve_values = float64_field([v for curve in curves for _, v in curve])
    response.candidate_unobservable = [c.unobservable for c in result.candidates]
    response.noise_std_m_s = result.noise_std_m_s
    response.residual_noise_std_m_s = result.residual_noise_std_m_s
    response.starts = result.starts
    response.required_score = result.required_score
    response.verdict = result.verdict
    named = result.missing_effects
    response.missing_effects = [n.effect for n in named]
    response.missing_effect_scores = float64_field([n.score for n in named])
    response.missing_effect_drop_scores = float64_field([n.drop_score for n in named])
    response.missing_effect_parameter_counts = [len(n.parameters) for n in named]
    response.missing_effect_parameter_names = [p.name for n in named for p in n.parameters]
    response.missing_effect_parameter_values = float64_field(
        [p.value for n in named for p in n.parameters]
    )
    response.missing_effect_parameter_stderr = float64_field(
        [p.stderr for n in named for p in n.parameters]
    )
    response.missing_effect_parameter_at_bound = [p.at_bound for n in named for p in n.parameters]
    unexplained = [n for n in named if n.where is not None]
    response.unexplained = bool(unexplained)
    response.unexplained_where = unexplained[0].where.summary if unexplained else ''
    trend = result.mu_trend
    response.mu_per_hit = float64_field(trend.mu if trend else ())
    response.mu_per_hit_stderr = float64_field(trend.mu_stderr if trend else ())
    response.mu_slope_per_hit = trend.slope_per_hit if trend else math.nan
    response.mu_slope_stderr = trend.slope_stderr if trend else math.nan
    response.mu_trend_p_value = trend.p_value if trend else math.nan
    speed, position = result.friction_map.speed, result.friction_map.position
    response.friction_speed_m_s = float64_field(speed.centres)
    response.friction_speed_mu = float64_field(speed.mu)
    response.friction_speed_mu_stderr = float64_field(speed.mu_stderr)
    response.friction_position_m = float64_field(position.centres)
    response.friction_position_mu = float64_field(position.mu)
    response.friction_position_mu_stderr = float64_field(position.mu_stderr)
    response.selection = list(result.selection)
    return response


def fill_fit_response(response: object, result: FrictionResult) -> object:
    """Copy a FrictionResult into a FitFriction response (success = True); returns it."""
    response.success = True
    response.message = (
        f'mu = {format_with_uncertainty(result.mu, result.mu_stderr, ASCII_PM)} over '
        f'{len(result.impact_ids)} '
        f'impacts; one mu serves all: p = {result.consistency_p_value:.3g}'
    )
    response.mu, response.mu_stderr = result.mu, result.mu_stderr
    response.damping_n_s_per_m = result.damping_n_s_per_m
    response.damping_stderr_n_s_per_m = (
        result.damping_stderr_n_s_per_m if result.damping_fitted else 0.0
    )
    response.damping_fitted = result.damping_fitted
    response.mass_kg = result.rig.mass_kg
    response.stiffness_n_per_m = result.rig.stiffness_n_per_m
    response.normal_force_n = result.rig.normal_force_n
    response.residual_rms_m_s = result.residual_rms_m_s
    response.residual_normalized = result.normalised_residual
    response.noise_std_m_s = result.noise_std_m_s
    response.consistency_chi2 = result.consistency_chi2
    response.consistency_p_value = result.consistency_p_value
    response.misfit = result.misfit
    response.impact_ids = [int(i) for i in result.impact_ids]
    response.per_impact_mu = float64_field(result.per_impact_mu)
    response.per_impact_mu_stderr = float64_field(result.per_impact_mu_stderr)
    response.per_impact_impulse_n_s = float64_field(result.impulses_n_s)
    response.per_impact_residual_rms_m_s = float64_field(result.per_impact_residual_rms_m_s)
    response.per_impact_residual_normalized = float64_field(result.per_impact_normalised_residual)
    response.per_impact_initial_position_m = float64_field(result.initial_positions_m)
    response.per_impact_impulse_scale = float64_field(result.impulse_scales)
    return response


def friction_result(response: object) -> FrictionResult:
    """The FrictionResult a successful FitFriction response carries (ValueError if refused)."""
    if not response.success:
        raise BadInputError(f'the fit was refused: {response.message}')
    ids = tuple(int(i) for i in response.impact_ids)
    return FrictionResult(
        mu=response.mu,
        mu_stderr=response.mu_stderr,
        rig=Rig(
            mass_kg=response.mass_kg,
            stiffness_n_per_m=response.stiffness_n_per_m,
            damping_n_s_per_m=response.damping_n_s_per_m,
            normal_force_n=response.normal_force_n,
        ),
        impact_ids=ids,
        per_impact_mu=tuple(field_array(response.per_impact_mu).tolist()),
        per_impact_mu_stderr=tuple(field_array(response.per_impact_mu_stderr).tolist()),
        initial_positions_m=tuple(field_array(response.per_impact_initial_position_m).tolist()),
        impulse_scales=tuple(field_array(response.per_impact_impulse_scale).tolist()),
        sources=tuple(f'impact {i}' for i in ids),
        impulses_n_s=tuple(field_array(response.per_impact_impulse_n_s).tolist()),
        per_impact_residual_rms_m_s=tuple(
            field_array(response.per_impact_residual_rms_m_s).tolist()
        ),
        per_impact_normalised_residual=tuple(
            field_array(response.per_impact_residual_normalized).tolist()
        ),
        damping_fitted=response.damping_fitted,
        damping_stderr_n_s_per_m=(
            response.damping_stderr_n_s_per_m if response.damping_fitted else math.nan
        ),
        residual_rms_m_s=response.residual_rms_m_s,
        normalised_residual=response.residual_normalized,
        noise_std_m_s=response.noise_std_m_s,
        consistency_chi2=response.consistency_chi2,
        consistency_p_value=response.consistency_p_value,
        misfit=response.misfit or 'time',
    )


def _candidates_list(response: object) -> list[dict]:
    """A DiagnoseModel response's candidate effects, as `fmm diagnose --json` lists them.

    The message carries each candidate's parameters and limit curve flattened, with counts
    per candidate: they are cut back into one entry per candidate here.
    """
    names, values = (
        response.candidate_parameter_names,
        field_array(response.candidate_parameter_values),
    )
    frequencies, masses = (
        field_array(response.candidate_limit_curve_frequencies_hz).tolist(),
        field_array(response.candidate_limit_curve_values).tolist(),
    )
    curves = [
        tuple(zip(frequencies[span], masses[span], strict=True))
        for span in _spans(response.candidate_limit_curve_counts)
    ]
    return [
        {
            'effect': effect,
            'score': score,
            'gap_after': gap_after,
            'parameters': dict(zip(names[span], values[span].tolist(), strict=True)),
            'detection_limit': detection_limit_dict(effect, limit, curve),
            **({'unobservable': unobservable} if unobservable else {}),
        }
        for effect, score, gap_after, limit, curve, span, unobservable in zip(
            response.candidate_effects,
            field_array(response.candidate_scores).tolist(),
            field_array(response.candidate_gap_after).tolist(),
            field_array(response.candidate_detection_limits).tolist(),
            curves,
            _spans(response.candidate_parameter_counts),
            response.candidate_unobservable,
            strict=True,
        )
    ]


def diagnose_response_dict(response: object) -> dict:
    """A DiagnoseModel response as the JSON keys of `fmm diagnose --json` it carries.

    JSON-ready as `diagnosis_dict` is: undefined numbers (an 'unexplained' entry's score, the
    trend of fewer than four hits) are None.
    """
    if not response.success:
        raise BadInputError(f'the diagnosis was refused: {response.message}')
    return json_safe(
        {
            'missing_effect': response.missing_effect,
            'parameters': dict(
                zip(
                    response.parameter_names,
                    field_array(response.parameter_values).tolist(),
                    strict=True,
                )
            ),
            'parameter_units': dict(
                zip(response.parameter_names, response.parameter_units, strict=True)
            ),
            'parameter_stderr': dict(
                zip(
                    response.parameter_names,
                    field_array(response.parameter_stderr).tolist(),
                    strict=True,
                )
            ),
            'parameter_at_bound': dict(
                zip(
                    response.parameter_names,
                    (bool(flag) for flag in response.parameter_at_bound),
                    strict=True,
                )
            ),
            'mu': response.mu,
            'mu_stderr': response.mu_stderr,
            'gap_before': response.gap_before,
            'gap_after': response.gap_after,
            'frf_gap_before': response.frf_gap_before,
            'frf_gap_after': response.frf_gap_after,
            'where': {'summary': response.where},
            'candidates': _candidates_list(response),
            'noise_std_m_s': response.noise_std_m_s,
            'residual_noise_std_m_s': response.residual_noise_std_m_s,
            'starts': response.starts,
            'required_score': response.required_score,
            'verdict': response.verdict,
            **_open_world_dict(response),
        }
    )


def _spans(counts: object) -> list[slice]:
    """Where each entry's run lies in a flat message array that `counts` splits.

    A message cannot carry a list of lists: the runs are concatenated, and a counts field
    says how long each is (the candidates' parameters, their limit curves, the named
    effects' parameters).
    """
    ends = np.cumsum(np.asarray(counts, dtype=int))
    return [slice(int(end) - int(count), int(end)) for count, end in zip(counts, ends, strict=True)]


def _open_world_dict(response: object) -> dict:
    """The list of effects, the trend and the friction map of a DiagnoseModel response."""
    names = list(response.missing_effect_parameter_names)
    values = field_array(response.missing_effect_parameter_values).tolist()
    errors = field_array(response.missing_effect_parameter_stderr).tolist()
    bounded = [bool(flag) for flag in response.missing_effect_parameter_at_bound]
    units = dict(zip(response.parameter_names, response.parameter_units, strict=True))
    trend = {
        'mu_per_hit': field_array(response.mu_per_hit).tolist(),
        'mu_per_hit_stderr': field_array(response.mu_per_hit_stderr).tolist(),
        'slope_per_hit': response.mu_slope_per_hit,
        'slope_stderr': response.mu_slope_stderr,
        'trend_p_value': response.mu_trend_p_value,
    }
    effects = list(response.missing_effects)
    named = []
    for effect, score, drop, span in zip(
        effects,
        field_array(response.missing_effect_scores).tolist(),
        field_array(response.missing_effect_drop_scores).tolist(),
        _spans(response.missing_effect_parameter_counts),
        strict=True,
    ):
        entry = {
            'effect': effect,
            'score': score,
            'drop_score': drop,
            'partial': response.unexplained and effect != diagnose.UNEXPLAINED,
            'parameters': dict(zip(names[span], values[span], strict=True)),
            'parameter_stderr': dict(zip(names[span], errors[span], strict=True)),
            'parameter_units': {name: units.get(name, '') for name in names[span]},
            'parameter_at_bound': dict(zip(names[span], bounded[span], strict=True)),
        }
        if effect == diagnose.MU_DRIFT:
            entry.update(trend)
        if effect == diagnose.UNEXPLAINED:
            entry['where'] = {'summary': response.unexplained_where}
        named.append(entry)
    return {
        'missing_effects': named,
        'selection': list(response.selection),
        'mu_trend': trend if trend['mu_per_hit'] else None,
        'friction_map': {
            'speed': {
                'speed_m_s': field_array(response.friction_speed_m_s).tolist(),
                'mu': field_array(response.friction_speed_mu).tolist(),
                'mu_stderr': field_array(response.friction_speed_mu_stderr).tolist(),
            },
            'position': {
                'position_m': field_array(response.friction_position_m).tolist(),
                'mu': field_array(response.friction_position_mu).tolist(),
                'mu_stderr': field_array(response.friction_position_mu_stderr).tolist(),
            },
        },
    }


def session_info_msg(info: SessionInfo, *, stamp: Time, frame_id: str = 'fmm') -> SessionInfoMsg:
    """A SessionInfo message of validated metadata (its fields named as `FIELDS`)."""
    msg = _stamped(SessionInfoMsg(), stamp, frame_id)
    for info_field in FIELDS:
        value = info[info_field.name]
        setattr(msg, info_field.name, float(value) if info_field.numeric else str(value))
    return msg
