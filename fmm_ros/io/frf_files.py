"""Export of FRFs: Universal File Format dataset 58 (via pyuff), CSV and JSON.

UFF 58 is what modal-testing tools exchange (ME'scope, Simcenter Testlab, pyEMA, SDypy read it);
CSV and JSON are for spreadsheets and scripts. All three take the same list of `FrfCurve`s,
built from a `Summary` by `level_curves` (each level's plain mean, H1, H2 and coherence) or
from impacts by `impact_curves`.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fmm_ros.core.signal.analysis import ImpactAnalysis, Summary
from fmm_ros.errors import BadInputError


@dataclass(frozen=True)
class _Quantity:
    """How one FRF quantity is labelled: unit and its UFF 58 codes."""

    unit: str
    # What the numerator is, for the axis labels of UFF readers.
    label: str
    # UFF function type (4 FRF, 6 coherence), ordinate and denominator data types
    # (8 displacement, 11 velocity, 12 acceleration, 13 excitation force, 0 unknown).
    function_type: int
    ordinate_type: int
    ordinate_unit: str
    denominator_type: int


QUANTITIES: dict[str, _Quantity] = {
    'mobility': _Quantity('m/(N*s)', 'Velocity', 4, 11, 'm/s', 13),
    'receptance': _Quantity('m/N', 'Displacement', 4, 8, 'm', 13),
    'accelerance': _Quantity('m/(N*s^2)', 'Acceleration', 4, 12, 'm/s^2', 13),
    'coherence': _Quantity('-', 'Coherence', 6, 0, '-', 0),
}


@dataclass(frozen=True, eq=False)
class FrfCurve:
    """One named FRF (complex) or coherence (real) on a frequency axis [Hz]."""

    name: str
    quantity: str
    frequency_hz: np.ndarray
    values: np.ndarray

    def __post_init__(self) -> None:
        if self.quantity not in QUANTITIES:
            raise BadInputError(
                f'{self.name}: unknown quantity {self.quantity!r}; known: {", ".join(QUANTITIES)}'
            )
        if np.shape(self.frequency_hz) != np.shape(self.values) or np.ndim(self.values) != 1:
            raise BadInputError(
                f'{self.name}: frequency axis and values must be 1-D and of equal length'
            )

    @property
    def unit(self) -> str:
        """SI unit of the values."""
        return QUANTITIES[self.quantity].unit


def level_curves(summary: Summary) -> list[FrfCurve]:
    """Every level's plain-mean mobility and receptance, H1 and H2 mobility, and coherence."""
    curves = []
    for level in summary.levels:
        axis = level.frequency_hz
        curves += [
            FrfCurve(f'{level.level} mean mobility', 'mobility', axis, level.mobility),
            FrfCurve(f'{level.level} mean receptance', 'receptance', axis, level.receptance),
            FrfCurve(f'{level.level} H1 mobility', 'mobility', axis, level.h1_mobility),
            FrfCurve(f'{level.level} H2 mobility', 'mobility', axis, level.h2_mobility),
            FrfCurve(f'{level.level} coherence', 'coherence', axis, level.coherence),
        ]
    return curves


def impact_curves(results: Iterable[ImpactAnalysis]) -> list[FrfCurve]:
    """Each impact's mobility, named by its id (and level, once assigned)."""
    return [
        FrfCurve(
            f'impact {result.impact_id}'
            + (f' {result.level}' if result.level else '')
            + ' mobility',
            'mobility',
            result.frequency_hz,
            result.mobility,
        )
        for result in results
    ]


def write_frfs(path: str | Path, curves: Sequence[FrfCurve]) -> None:
    """Write curves in the format the file name asks for: .uff/.unv, .csv or .json."""
    suffix = Path(path).suffix.lower()
    writers = {
        '.uff': write_uff58,
        '.unv': write_uff58,
        '.csv': write_frf_csv,
        '.json': write_frf_json,
    }
    if suffix not in writers:
        raise BadInputError(
            f'{path}: unknown export format {suffix!r}; use .uff or .unv (UFF 58), .csv or .json'
        )
    writers[suffix](path, curves)


def write_uff58(path: str | Path, curves: Sequence[FrfCurve]) -> None:
    """Write curves as UFF 58 records (ASCII, double precision, even abscissa), SI units.

    Every curve is a drive-point function of the FMM platform, node 1, +X (the hammer and the
    vibrometer act along the flexure's motion), preceded by a dataset 164 declaring SI units.
    """
    import pyuff

    datasets = [
        pyuff.prepare_164(
            units_code=1,
            units_description='SI',
            temp_mode=1,
            length=1.0,
            force=1.0,
            temp=1.0,
            temp_offset=273.15,
        )
    ]
    for number, curve in enumerate(_nonempty(curves), start=1):
        if curve.frequency_hz.size < 2:
            raise BadInputError(f'{curve.name}: UFF 58 needs at least 2 frequency points')
        quantity = QUANTITIES[curve.quantity]
        dataset = pyuff.prepare_58(
            binary=0,
            id1=curve.name[:80],
            id2=f'{curve.quantity} [{curve.unit}]',
            id3='fmm_ros',
            func_type=quantity.function_type,
            rsp_ent_name='FMM',
            rsp_node=1,
            rsp_dir=1,
            ref_ent_name='FMM',
            ref_node=1,
            ref_dir=1,
            abscissa_spacing=1,
            abscissa_spec_data_type=18,
            abscissa_axis_units_lab='Hz',
            ordinate_spec_data_type=quantity.ordinate_type,
            ordinate_len_unit_exp=int(quantity.ordinate_type in (8, 11, 12)),
            ordinate_axis_units_lab=quantity.ordinate_unit,
            orddenom_spec_data_type=quantity.denominator_type,
            orddenom_force_unit_exp=int(quantity.denominator_type == 13),
            orddenom_axis_units_lab='N' if quantity.denominator_type == 13 else '',
            data=np.asarray(curve.values),
            x=np.asarray(curve.frequency_hz, dtype=float),
        )
        # Fields prepare_58 does not take but the writer does.
        dataset.update(
            func_id=number,
            abscissa_axis_lab='Frequency',
            ordinate_axis_lab=quantity.label,
            orddenom_axis_lab='Force' if quantity.denominator_type == 13 else 'NONE',
        )
        datasets.append(dataset)
    pyuff.UFF(str(path)).write_sets(datasets, mode='overwrite')


def write_frf_csv(path: str | Path, curves: Sequence[FrfCurve]) -> None:
    """Write curves as columns: frequency_hz, then <name>_real and <name>_imag (coherence: one).

    All curves must share one frequency axis.
    """
    curves = _nonempty(curves)
    axis = curves[0].frequency_hz
    for curve in curves[1:]:
        if curve.frequency_hz.shape != axis.shape or not np.allclose(curve.frequency_hz, axis):
            raise BadInputError(f'{curve.name}: CSV export needs one frequency axis for all curves')
    names, columns = ['frequency_hz'], [axis]
    for curve in curves:
        label = re.sub(r'\W+', '_', curve.name).strip('_').lower()
        if np.iscomplexobj(curve.values):
            names += [f'{label}_real', f'{label}_imag']
            columns += [curve.values.real, curve.values.imag]
        else:
            names.append(label)
            columns.append(curve.values)
    np.savetxt(
        path,
        np.column_stack(columns),
        delimiter=',',
        header=','.join(names),
        comments='',
        fmt='%.17g',
    )


def write_frf_json(path: str | Path, curves: Sequence[FrfCurve]) -> None:
    """Write {"curves": [{name, quantity, unit, frequency_hz, real, imag}]}; NaN as null."""
    document = {
        'curves': [
            {
                'name': curve.name,
                'quantity': curve.quantity,
                'unit': curve.unit,
                'frequency_hz': _json_list(curve.frequency_hz),
                'real': _json_list(np.real(curve.values)),
                'imag': _json_list(np.imag(curve.values)),
            }
            for curve in _nonempty(curves)
        ]
    }
    Path(path).write_text(json.dumps(document, allow_nan=False))


def json_number(value: float) -> float | None:
    """A float for JSON: NaN and infinities (undefined results) become null."""
    value = float(value)
    return value if math.isfinite(value) else None


def _json_list(values: np.ndarray) -> list[float | None]:
    return [json_number(value) for value in np.asarray(values, dtype=float)]


def _nonempty(curves: Sequence[FrfCurve]) -> list[FrfCurve]:
    if not curves:
        raise BadInputError('nothing to export: no FRF curves (no level had an accepted impact?)')
    return list(curves)
