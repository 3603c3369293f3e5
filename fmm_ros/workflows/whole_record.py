"""A lab file as one excitation: read force and displacement, fit the whole record, serialise.

`fmm diagnose|fit|identify-rig --whole-record` come here: each file is one excitation (random,
multisine, sweep, a closed-loop move), its measured force driving the model throughout
(`core.identify.whole_record`). Channels follow `fmm_ros.units.channel_factor`, the rule of
every command: a voltage without a scale is analysed in volts and the document's `units`
says so beside the SI-named keys.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core._checks import time_base
from fmm_ros.core.identify.axis import RELATIVE_ERROR_LIMIT
from fmm_ros.core.identify.whole_record import (
    CANDIDATE_TERMS,
    WholeRecordDiagnosis,
    WholeRecordFit,
    diagnose_whole_record,
)
from fmm_ros.errors import BadInputError
from fmm_ros.io.frf_files import json_number
from fmm_ros.io.labfiles import open_lab_file
from fmm_ros.units import SI_UNITS, channel_factor, per_unit

TERM_KEYS = {
    'cubic_stiffness': 'cubic_stiffness_n_per_m3',
    'coulomb_friction': 'coulomb_friction_n',
}
"""The JSON key of each term's coefficient (SI-named; `units` says what it is in)."""
COMMAND_TERMS = {
    'identify-rig': (),
    'fit': ('coulomb_friction',),
    'diagnose': CANDIDATE_TERMS,
}
"""What each command screens a whole record for beyond the linear rig."""


@dataclass(frozen=True)
class WholeRecord:
    """Force and displacement of one file, in the units the analysis uses, and the rate."""

    source: str
    force: np.ndarray
    displacement: np.ndarray
    sample_rate_hz: float
    force_unit: str
    displacement_unit: str


def read_whole_record(
    path: str | Path,
    *,
    force: str | None,
    displacement: str | None,
    force_unit: str | None = None,
    displacement_unit: str | None = None,
    force_scale: float | None = None,
    displacement_scale: float | None = None,
    time: str | None = None,
    sample_rate_hz: float | str | None = None,
) -> WholeRecord:
    """One lab file's force and displacement channels and its rate; BadInputError naming what."""
    if not force or not displacement:
        raise BadInputError(
            f'{path}: a whole record needs its force and displacement channels named '
            '(--force NAME --displacement NAME)'
        )
    lab = open_lab_file(path)
    f_factor, f_unit = channel_factor('force', force_unit, force_scale, channel=force)
    x_factor, x_unit = channel_factor(
        'displacement', displacement_unit, displacement_scale, channel=displacement
    )
    f = lab.vector(force) * f_factor
    x = lab.vector(displacement) * x_factor
    if f.size != x.size:
        raise BadInputError(
            f'{lab.path}: force {force!r} has {f.size} samples, displacement '
            f'{displacement!r} {x.size}'
        )
    if sample_rate_hz is not None:
        try:
            rate = float(sample_rate_hz)
        except ValueError:
            rate = lab.scalar(str(sample_rate_hz))
        if not (math.isfinite(rate) and rate > 0.0):
            raise BadInputError(f'sample rate must be positive, got {sample_rate_hz}')
    elif time:
        rate = time_base(lab.vector(time), f'{lab.path}: time {time!r}', rtol=None).sample_rate_hz
    else:
        raise BadInputError(
            f'{lab.path}: no time base: give --sample-rate-hz or name the time channel --time'
        )
    return WholeRecord(str(path), f, x, rate, f_unit, x_unit)


def _fit_json(fit: WholeRecordFit) -> dict:
    """A fit's rig (the JSON's `rig`), terms, offset, gap and resonance."""
    values, errors = fit.values, fit.stderr
    rig = {
        'mass_kg': json_number(values['mass']),
        'damping_n_s_per_m': json_number(values['damping']),
        'stiffness_n_per_m': json_number(values['stiffness']),
        'mass_kg_stderr': json_number(errors.get('mass', 0.0)),
        'damping_n_s_per_m_stderr': json_number(errors.get('damping', 0.0)),
        'stiffness_n_per_m_stderr': json_number(errors.get('stiffness', 0.0)),
    }
    return {
        'rig': rig,
        'natural_frequency_hz': json_number(fit.natural_frequency_hz),
        'offset_n': json_number(values.get('offset', 0.0)),
        'terms': {
            term: {
                TERM_KEYS[term]: json_number(values[term]),
                f'{TERM_KEYS[term]}_stderr': json_number(errors[term]),
            }
            for term in fit.terms
        },
        'gap': json_number(fit.gap),
        'residual_rms_m': json_number(fit.residual_rms),
    }


def whole_record_json(
    result: WholeRecordDiagnosis, record: WholeRecord, *, fitted_rig: bool
) -> dict:
    """The document of one file: the final fit, the base, the gaps, what was named and why not."""
    force, length = record.force_unit, record.displacement_unit
    si = (force, length) == (SI_UNITS['force'], SI_UNITS['displacement'])
    final = _fit_json(result.final)
    k3 = result.final.values.get('cubic_stiffness')
    return {
        'file': record.source,
        'analysis': 'whole_record',
        'samples': result.samples,
        'sample_rate_hz': result.sample_rate_hz,
        'fitted_rig': fitted_rig,
        **final,
        'named': list(result.named) or ['none'],
        'fits_record': bool(result.final.gap <= RELATIVE_ERROR_LIMIT),
        'why': (
            ''
            if result.final.gap <= RELATIVE_ERROR_LIMIT
            else f'the model leaves {100.0 * result.final.gap:.0f} % of the displacement '
            f'unexplained (more than {100.0 * RELATIVE_ERROR_LIMIT:.0f} %)'
        ),
        'gap_before': json_number(result.base.gap),
        'gap_after': json_number(result.final.gap),
        'cubic_over_linear_stiffness_per_m2': (
            json_number(k3 / result.final.values['stiffness']) if k3 is not None else None
        ),
        'not_named': dict(result.why),
        'base': _fit_json(result.base),
        'units': {
            'force': force,
            'displacement': length,
            'mass_kg': 'kg' if si else per_unit(force, length, 2),
            'damping_n_s_per_m': 'N s/m' if si else per_unit(force, length, 1),
            'stiffness_n_per_m': 'N/m' if si else per_unit(force, length),
            'cubic_stiffness_n_per_m3': 'N/m^3' if si else f'{force}/{length}^3',
            'cubic_over_linear_stiffness_per_m2': 'm^-2' if si else f'{length}^-2',
            'coulomb_friction_n': force,
            'offset_n': force,
            'residual_rms_m': length,
        },
        'method': 'output error, force linear between samples (first-order hold, exact '
        'discretisation of the linear part); Newey-West standard errors; gap = RMS residual / '
        'RMS displacement',
    }


def analyse_whole_record(
    record: WholeRecord, command: str, rig: dict[str, float] | None = None
) -> dict:
    """Fit one record as `command` does and return its document.

    identify-rig: the rig alone; fit: and friction; diagnose: every candidate term. rig: known
    mass, damping, stiffness (None: fitted from the record).
    """
    result = diagnose_whole_record(
        record.force,
        record.displacement,
        record.sample_rate_hz,
        rig=rig,
        candidates=COMMAND_TERMS[command],
    )
    return whole_record_json(result, record, fitted_rig=rig is None)
