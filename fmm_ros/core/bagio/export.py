"""Impact results and averaged FRFs to CSV files a spreadsheet or MATLAB opens directly.

The columns are the message fields, taken from the fmm_interfaces definitions (so a field
added to ImpactResult.msg appears here without a code change): one table row per impact or
level of its scalar fields, and one table per impact or level of its FRF arrays over
frequency_hz. Any object with those attribute names can be exported, not only messages.
"""

import csv
import re
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from fmm_ros.core.bagio.definitions import FRF_SUMMARY, IMPACT_RESULT, fmm_typestore

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


def write_frf(path: Path, columns: list[str], record) -> Path:
    """The FRF arrays of one record as columns over frequency (full float64 precision)."""
    arrays = [np.asarray(getattr(record, column), dtype=np.float64) for column in columns]
    lengths = {len(array) for array in arrays}
    if len(lengths) != 1:
        raise ValueError(f'{path.name}: FRF arrays of unequal length '
                         f'{dict(zip(columns, map(len, arrays), strict=True))}')
    np.savetxt(path, np.column_stack(arrays) if arrays[0].size else np.zeros((0, len(arrays))),
               delimiter=',', header=','.join(columns), comments='', fmt='%.17g')
    return path


def _safe(name: str) -> str:
    """A level name fit for a file name."""
    return re.sub(r'[^A-Za-z0-9_.-]+', '_', name) or 'unnamed'


def export_results(impacts: Iterable, summaries: Iterable, out_dir: str | Path) -> list[Path]:
    """CSV files of impacts and level FRFs in out_dir; returns the files written.

    impacts.csv (one row per impact) and impact_<id>.csv (its FRF); levels.csv and
    level_<name>.csv for the newest FrfSummary of each level.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    impacts = list(impacts)
    scalars, frf = table_columns(IMPACT_RESULT)
    if impacts:
        written.append(write_rows(out / 'impacts.csv', scalars, impacts))
        written += [write_frf(out / f'impact_{int(record.impact_id)}.csv', frf, record)
                    for record in impacts]
    latest = {record.level: record for record in summaries}  # later ones replace earlier
    scalars, frf = table_columns(FRF_SUMMARY)
    if latest:
        written.append(write_rows(out / 'levels.csv', scalars, latest.values()))
        written += [write_frf(out / f'level_{_safe(level)}.csv', frf, record)
                    for level, record in latest.items()]
    return written
