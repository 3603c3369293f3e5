"""Friction of a positioning axis from a lab file: read the channels, identify, serialise.

The one place that turns a lab file (CSV, NPZ, MATLAB, TDMS) into the SI record
`core.identify.axis.identify_axis_friction` takes, and its result into the JSON document
`fmm identify-friction --json` prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core._checks import time_base
from fmm_ros.core.identify.axis import (
    MOTION_KINDS,
    AxisFriction,
    AxisSpec,
    Estimate,
    identify_axis_friction,
)
from fmm_ros.errors import BadInputError
from fmm_ros.io.frf_files import json_number
from fmm_ros.io.labfiles import LabFile, open_lab_file
from fmm_ros.units import SI_UNITS, si_factor

TIME_NAMES = ('time_s', 'time', 't')
"""Channels taken as the time base [s] when none is named."""
MOTION_QUANTITY = {
    'position': 'displacement',
    'velocity': 'velocity',
    'acceleration': 'acceleration',
}


@dataclass(frozen=True)
class AxisRecord:
    """One record of an axis in SI units: drive force [N], one motion channel, its rate."""

    source: str
    force_n: np.ndarray
    motion: np.ndarray
    motion_kind: str
    sample_rate_hz: float
    time_jitter_s: float


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
    force_unit: str = 'N',
    motion_unit: str | None = None,
    force_scale: str | float | None = None,
) -> AxisRecord:
    """The drive force [N] and motion (SI) of one lab file, with its sample rate.

    force_scale multiplies the force channel after its unit (a drive gain in N/V for a
    controller's voltage: a number, or the name of a scalar variable in the file).
    """
    if motion_kind not in MOTION_KINDS:
        raise BadInputError(f'motion kind {motion_kind!r} is none of {", ".join(MOTION_KINDS)}')
    lab = open_lab_file(path)
    quantity = MOTION_QUANTITY[motion_kind]
    unit = motion_unit or SI_UNITS[quantity]
    force_n = lab.vector(force) * si_factor('force', force_unit) * _scale(lab, force_scale)
    values = lab.vector(motion) * si_factor(quantity, unit)
    if values.size != force_n.size:
        raise BadInputError(
            f'{lab.path}: force {force!r} has {force_n.size} samples, {motion_kind} '
            f'{motion!r} {values.size}'
        )
    rate, jitter = _sample_rate(lab, time, sample_rate_hz)
    return AxisRecord(str(path), force_n, values, motion_kind, rate, jitter)


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


def axis_json(result: AxisFriction, record: AxisRecord, spec: AxisSpec) -> dict:
    """The JSON document of `fmm identify-friction`: parameters with standard errors first."""
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
        }
    )
    return document
