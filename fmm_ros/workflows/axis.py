"""Friction of a positioning axis from a lab file: read the channels, identify, serialise.

The one place that turns a lab file (CSV, NPZ, MATLAB, TDMS) into the SI record
`core.identify.axis.identify_axis_friction` takes, and its result into the JSON document
`fmm identify-friction --json` prints.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core._checks import time_base
from fmm_ros.core.identify.axis import (
    MOTION_KINDS,
    PRESLIDING_STROKE_FRACTION,
    AxisFriction,
    AxisSpec,
    Estimate,
    ImposedMotionFriction,
    identify_axis_friction,
)
from fmm_ros.errors import BadInputError
from fmm_ros.io.frf_files import json_number
from fmm_ros.io.labfiles import LabFile, open_lab_file
from fmm_ros.units import SI_UNITS, channel_factor, per_unit

TIME_NAMES = ('time_s', 'time', 't')
"""Channels taken as the time base [s] when none is named."""
PARAMETER_NAMES = (
    'mass_kg',
    'viscous_n_s_per_m',
    'coulomb_n',
    'offset_n',
    'coulomb_positive_n',
    'coulomb_negative_n',
    'viscous_positive_n_s_per_m',
    'viscous_negative_n_s_per_m',
    'mass_per_direction_kg',
)
PARAMETER_KEYS = tuple(
    f'{name}{tail}' for name in PARAMETER_NAMES for tail in ('', '_stderr', '_stderr_classic')
)
"""The identified parameters' keys: null in a document whose record the model does not fit."""
MOTION_QUANTITY = {
    'position': 'displacement',
    'velocity': 'velocity',
    'acceleration': 'acceleration',
}


@dataclass(frozen=True)
class AxisRecord:
    """One record of an axis: drive force, one motion channel, its rate.

    SI units (N, m) unless a channel was uncalibrated (a voltage without a scale): then it is
    in force_unit / displacement_unit ('V'), and so is every figure derived from it.
    """

    source: str
    force_n: np.ndarray
    motion: np.ndarray
    motion_kind: str
    sample_rate_hz: float
    time_jitter_s: float
    force_unit: str = 'N'
    displacement_unit: str = 'm'


def _scale(lab: LabFile, scale: str | float | None) -> float:
    """A scale given as a number, or as the name of a scalar variable in the file (EMPS gtau)."""
    if scale is None:
        return 1.0
    try:
        return float(scale)
    except ValueError:
        return lab.scalar(str(scale))


def _sample_rate(lab: LabFile, time: str | None, rate_hz: float | None) -> tuple[float, float]:
    """Sample rate [Hz] and RMS jitter of the stamps [s], from the rate or the time channel."""
    if rate_hz is not None:
        if not (math.isfinite(rate_hz) and rate_hz > 0.0):
            raise BadInputError(f'sample rate must be positive, got {rate_hz}')
        return float(rate_hz), 0.0
    names = lab.names()
    name = time or next((n for n in TIME_NAMES if n in names), None)
    if name is None:
        raise BadInputError(
            f'{lab.path}: no time base: name the time channel with --time NAME or give '
            f'--sample-rate-hz (channels: {", ".join(names) or "none"})'
        )
    clock = time_base(lab.vector(name), f'{lab.path}: time {name!r}', rtol=None)
    return clock.sample_rate_hz, clock.jitter_rms_s


def read_axis_record(
    path: str | Path,
    *,
    force: str,
    motion: str,
    motion_kind: str = 'position',
    time: str | None = None,
    sample_rate_hz: float | None = None,
    force_unit: str | None = None,
    motion_unit: str | None = None,
    force_scale: str | float | None = None,
) -> AxisRecord:
    """The drive force [N] and motion (SI) of one lab file, with its sample rate.

    force_unit and force_scale follow `fmm_ros.units.channel_factor`, as in every command: a
    unit of the table converts to N; force_scale is N per file unit (a drive gain in N/V for
    a controller's voltage: a number, or the name of a scalar variable in the file); a
    voltage without a scale (force_unit or motion_unit 'V') is analysed in volts.
    """
    if motion_kind not in MOTION_KINDS:
        raise BadInputError(f'motion kind {motion_kind!r} is none of {", ".join(MOTION_KINDS)}')
    lab = open_lab_file(path)
    quantity = MOTION_QUANTITY[motion_kind]
    scale = None if force_scale is None else _scale(lab, force_scale)
    force_factor, force_used = channel_factor('force', force_unit, scale, channel=force)
    motion_factor, motion_used = channel_factor(quantity, motion_unit, channel=motion)
    force_n = lab.vector(force) * force_factor
    values = lab.vector(motion) * motion_factor
    if values.size != force_n.size:
        raise BadInputError(
            f'{lab.path}: force {force!r} has {force_n.size} samples, {motion_kind} '
            f'{motion!r} {values.size}'
        )
    rate, jitter = _sample_rate(lab, time, sample_rate_hz)
    seconds = {'position': '', 'velocity': ' s', 'acceleration': ' s^2'}[motion_kind]
    displacement_unit = (
        SI_UNITS['displacement'] if motion_used == SI_UNITS[quantity] else motion_used + seconds
    )
    return AxisRecord(
        str(path), force_n, values, motion_kind, rate, jitter, force_used, displacement_unit
    )


def identify_axis_file(record: AxisRecord, spec: AxisSpec) -> AxisFriction:
    """Identify the axis of one record."""
    return identify_axis_friction(
        record.force_n,
        record.motion,
        record.sample_rate_hz,
        motion_kind=record.motion_kind,
        spec=spec,
    )


def _pair(name: str, estimate: Estimate) -> dict[str, float | None]:
    return {
        name: json_number(estimate.value),
        f'{name}_stderr': json_number(estimate.stderr),
        f'{name}_stderr_classic': json_number(estimate.stderr_classic),
    }


def record_units(record: AxisRecord) -> dict[str, str]:
    """The unit each figure of the document is in, by parameter name (names stay SI-named)."""
    force, length = record.force_unit, record.displacement_unit
    si = (force, length) == (SI_UNITS['force'], SI_UNITS['displacement'])
    return {
        'force': force,
        'displacement': length,
        'velocity': f'{length}/s',
        'acceleration': f'{length}/s^2',
        'mass_kg': 'kg' if si else per_unit(force, length, 2),
        'viscous_n_s_per_m': per_unit(force, length, 1),
        'coulomb_n': force,
        'offset_n': force,
        'stiffness_n_per_m': per_unit(force, length),
        'energy_per_cycle_j': 'J' if si else f'{force} {length}',
    }


def _imposed_json(imposed: ImposedMotionFriction) -> dict:
    """The imposed-motion block: per-direction friction, what is left, the loop and energy."""
    document: dict = {}
    document.update(_pair('coulomb_positive_n', imposed.coulomb_positive_n))
    document.update(_pair('coulomb_negative_n', imposed.coulomb_negative_n))
    document.update(_pair('viscous_positive_n_s_per_m', imposed.viscous_positive_n_s_per_m))
    document.update(_pair('viscous_negative_n_s_per_m', imposed.viscous_negative_n_s_per_m))
    energy = imposed.energy_per_cycle_j
    document.update(
        {
            'coulomb_asymmetry': json_number(imposed.coulomb_asymmetry),
            'relative_error_sliding': json_number(imposed.relative_error_sliding),
            'residual_rms_sliding_n': json_number(imposed.residual_rms_sliding_n),
            'residual_rms_reversals_n': json_number(imposed.residual_rms_reversals_n),
            'samples_sliding': imposed.samples_sliding,
            'samples_reversals': imposed.samples_reversals,
            'presliding_stroke_fraction': PRESLIDING_STROKE_FRACTION,
            'stroke_m': json_number(imposed.stroke_m),
            'energy_per_cycle_j': [json_number(value) for value in energy],
            'energy_per_cycle_mean_j': json_number(float(energy.mean())) if energy.size else None,
            'friction_loop': {
                'displacement_m': imposed.loop_displacement_m.tolist(),
                'force_n': imposed.loop_force_n.tolist(),
            },
        }
    )
    return document


def axis_json(result: AxisFriction, record: AxisRecord, spec: AxisSpec) -> dict:
    """The JSON document of `fmm identify-friction`: parameters with standard errors first.

    When the inertial model does not describe the record (`fits_record` false) its figures
    are not reported as a result: every parameter is null, the rejected fit is kept under
    `rejected` for the reader, `why` says what is wrong, and an imposed-motion fit, when the
    record is one, is under `imposed_motion`.
    """
    if not result.fits_record:
        refused = axis_json(dataclasses.replace(result, fits_record=True, why=''), record, spec)
        document = {
            key: (None if key in PARAMETER_KEYS else value)
            for key, value in refused.items()
            if key not in ('friction_map', 'fits_record', 'why', 'model')
        }
        document.update(
            {
                'fits_record': False,
                'why': result.why,
                'model': 'imposed_motion' if result.imposed_motion else None,
                'rejected': {
                    'model': 'inertia_friction',
                    **{key: refused[key] for key in PARAMETER_KEYS if key in refused},
                    'relative_error': refused['relative_error'],
                },
                'imposed_motion': (
                    _imposed_json(result.imposed_motion) if result.imposed_motion else None
                ),
            }
        )
        return document
    document: dict = {}
    document.update(_pair('mass_kg', result.mass_kg))
    document.update(_pair('viscous_n_s_per_m', result.viscous_n_s_per_m))
    document.update(_pair('coulomb_n', result.coulomb_n))
    document.update(_pair('offset_n', result.offset_n))
    directions = result.directions
    if directions:
        document.update(_pair('coulomb_positive_n', directions['coulomb_positive']))
        document.update(_pair('coulomb_negative_n', directions['coulomb_negative']))
        document.update(_pair('viscous_positive_n_s_per_m', directions['viscous_positive']))
        document.update(_pair('viscous_negative_n_s_per_m', directions['viscous_negative']))
        document.update(_pair('mass_per_direction_kg', directions['mass_kg']))
    friction_map = result.friction_map
    document['friction_map'] = {
        'speed': {
            'speed_m_s': friction_map.speed_m_s.tolist() if friction_map else [],
            'friction_n': friction_map.friction_n.tolist() if friction_map else [],
            'count': friction_map.count.tolist() if friction_map else [],
        }
    }
    document.update(
        {
            'residual_rms_n': json_number(result.residual_rms_n),
            'relative_error': json_number(result.relative_error),
            'stderr_method': 'Newey-West (Bartlett kernel) on the decimated record; '
            '*_stderr_classic: ordinary least squares',
            'samples_used': result.samples_used,
            'samples_standstill': result.samples_standstill,
            'sample_rate_hz': result.sample_rate_hz,
            'time_jitter_s': record.time_jitter_s,
            'cutoff_hz': result.cutoff_hz,
            'decimation': result.decimation,
            'motion': result.motion,
            'stiffness_n_per_m': spec.stiffness_n_per_m,
            'encoder_step_m': json_number(result.encoder_step_m),
            'velocity_noise_m_s': json_number(result.velocity_noise_m_s),
            'acceleration_noise_m_s2': json_number(result.acceleration_noise_m_s2),
            'attenuation_mass': json_number(result.attenuation_mass),
            'attenuation_viscous': json_number(result.attenuation_viscous),
            'condition_number': json_number(result.condition_number),
            'file': record.source,
            'units': record_units(record),
            'fits_record': True,
            'why': '',
            'model': 'inertia_friction',
        }
    )
    return document
