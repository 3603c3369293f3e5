"""Recorded impact results and level FRFs to CSV tables, and FRF files (CSV, UFF 58, JSON).

The scalar tables' columns are the message fields, taken from the fmm_interfaces
definitions (a field added to ImpactResult.msg appears without a code change): one row per
impact or level. The FRFs of each impact and level are written by the signal core's
exporters (`fmm_ros.io.frf_files`), so a bag's FRFs and `fmm analyze -o` files match.
"""

import csv
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from fmm_ros.constants import FRF_FORMATS
from fmm_ros.errors import BadInputError
from fmm_ros.io.bags.definitions import FRF_SUMMARY, IMPACT_RESULT, fmm_typestore
from fmm_ros.io.frf_files import FrfCurve, write_frfs

FREQUENCY_FIELD = 'frequency_hz'


def table_columns(msgtype: str, store: Typestore | None = None) -> tuple[list[str], list[str]]:
    """(scalar columns, FRF array columns) of msgtype, in .msg order.

    Scalars include string[] fields (joined with '|') and the header stamp as stamp_ns;
    FRF columns are the float64[] fields, frequency_hz first. Other arrays (impact_ids)
    count as scalars, joined with '|'.
    """
    store = store or fmm_typestore()
    scalars, arrays = [], []
    for name, (kind, detail) in store.fielddefs[msgtype][1]:
        if kind == Nodetype.NAME and detail == 'std_msgs/msg/Header':
            scalars.append('stamp_ns')
        elif kind == Nodetype.SEQUENCE and detail[0] == (Nodetype.BASE, ('float64', 0)):
            arrays.append(name)
        else:
            scalars.append(name)
    if FREQUENCY_FIELD in arrays:
        arrays.remove(FREQUENCY_FIELD)
        arrays.insert(0, FREQUENCY_FIELD)
    return scalars, arrays


def _cell(record, column: str) -> object:
    """One scalar cell: lists joined with '|', the header stamp in nanoseconds."""
    if column == 'stamp_ns':
        header = getattr(record, 'header', None)
        return '' if header is None else header.stamp.sec * 10**9 + header.stamp.nanosec
    value = getattr(record, column)
    if isinstance(value, str | bytes):
        return value
    if isinstance(value, Sequence | np.ndarray):
        return '|'.join(str(item) for item in value)
    return value.item() if isinstance(value, np.generic) else value


def write_rows(path: Path, columns: list[str], records: Iterable) -> Path:
    """One CSV row of scalar columns per record."""
    with path.open('w', newline='', encoding='utf-8') as stream:
        writer = csv.writer(stream)
        writer.writerow(columns)
        for record in records:
            writer.writerow([_cell(record, column) for column in columns])
    return path


# FRF fields of the messages (<field> or <field>_real/_imag), their curve label and quantity.
IMPACT_CURVES = (('mobility', 'mobility', 'mobility'), ('receptance', 'receptance', 'receptance'))
LEVEL_CURVES = (
    ('mobility', 'mean mobility', 'mobility'),
    ('receptance', 'mean receptance', 'receptance'),
    ('h1_mobility', 'H1 mobility', 'mobility'),
    ('h2_mobility', 'H2 mobility', 'mobility'),
    ('coherence', 'coherence', 'coherence'),
)


def message_curves(message, name: str, spec=IMPACT_CURVES) -> list[FrfCurve]:
    """The FRFs of an ImpactResult (spec IMPACT_CURVES) or FrfSummary (LEVEL_CURVES) message.

    Curves the message leaves empty (e.g. H2 of a bag recorded before it existed) are left
    out.
    """
    frequency = np.asarray(message.frequency_hz, dtype=np.float64)
    curves = []
    for field, label, quantity in spec:
        if hasattr(message, f'{field}_real'):
            values = np.asarray(getattr(message, f'{field}_real')) + 1j * np.asarray(
                getattr(message, f'{field}_imag')
            )
        else:
            values = np.asarray(getattr(message, field, ()), dtype=np.float64)
        if values.size:
            curves.append(FrfCurve(f'{name} {label}', quantity, frequency, values))
    return curves


def _safe(name: str) -> str:
    """A level name fit for a file name."""
    return re.sub(r'[^A-Za-z0-9_.-]+', '_', name) or 'unnamed'


def export_results(
    impacts: Iterable, summaries: Iterable, out_dir: str | Path, *, frf_format: str = 'csv'
) -> list[Path]:
    """Tables and FRF files of impacts and levels in out_dir; returns the files written.

    impacts.csv (one row per impact) and impact_<id>.<frf_format> (its mobility and
    receptance); levels.csv and level_<name>.<frf_format> (mean mobility and receptance,
    H1, H2, coherence) for the newest FrfSummary of each level.
    """
    if frf_format not in FRF_FORMATS:
        raise BadInputError(
            f'unknown FRF format {frf_format!r}; use one of {", ".join(FRF_FORMATS)}'
        )
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    impacts = list(impacts)
    latest = {record.level: record for record in summaries}  # later ones replace earlier
    for records, table, spec, name, stem in (
        (
            impacts,
            IMPACT_RESULT,
            IMPACT_CURVES,
            lambda r: f'impact {int(r.impact_id)}',
            lambda r: f'impact_{int(r.impact_id)}',
        ),
        (
            list(latest.values()),
            FRF_SUMMARY,
            LEVEL_CURVES,
            lambda r: r.level,
            lambda r: f'level_{_safe(r.level)}',
        ),
    ):
        if not records:
            continue
        scalars, _ = table_columns(table)
        written.append(
            write_rows(
                out / ('impacts.csv' if table == IMPACT_RESULT else 'levels.csv'), scalars, records
            )
        )
        for record in records:
            curves = message_curves(record, name(record), spec)
            if curves:
                path = out / f'{stem(record)}.{frf_format}'
                write_frfs(path, curves)
                written.append(path)
    return written
