"""The campaign table: which sessions, where their data are, and the conditions of each.

A CSV file (a header row, one session a row; comma, semicolon or tab separated) or a YAML file
(a list of sessions, or a mapping with `sessions:` and optional `by:`, `trend:`, `mapping:`,
`title:`). Columns:

- `session` (required): the session's data, relative to the table's folder: a bag, a per-impact
  CSV file, a folder of them, or a glob; with a mapping, lab files (see `SessionSpec`).
- `id`: the session's name in tables and plots (default: `session` as written); unique.
- `mapping`: an `fmm import` mapping file for this session's lab files (YAML `mapping:` sets
  one for all).
- `notes`: free text, shown in the report, never analysed.
- Any other column is a condition the lab chooses (lubricant, counterface, operator, date,
  normal_force_n, ...). A column whose every value is a number is numeric, one whose every
  value is an ISO date (2026-11-02, 2026-11-02T14:30) is a date, anything else is text;
  empty cells are missing values.
- Condition columns named as the rig's constants (`normal_force_n`, `mass_kg`,
  `stiffness_n_per_m`, `damping_n_s_per_m`, SI units) also set the rig that session's fit
  uses: mu = F_f / N is computed with the session's own normal force, not the FMM's.

Or a folder of bags the station recorded: one session a bag, its conditions the
session metadata each bag holds (`fmm_ros.io.session_info`: operator, pin, counterface,
lubricant, temperature, humidity; its normal load becomes `normal_force_n`, so each fit uses
the load entered), its notes the bag's notes.
"""

from __future__ import annotations

import csv
import dataclasses
import datetime as dt
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from fmm_ros.campaign.session import RIG_COLUMNS, SessionSpec
from fmm_ros.core.physics.rig import FMM_RIG, Rig
from fmm_ros.errors import BadInputError
from fmm_ros.io import session_info, sniff
from fmm_ros.io.bags.station import bag_session_info

SESSION_COLUMN = 'session'
ID_COLUMN = 'id'
MAPPING_COLUMN = 'mapping'
NOTES_COLUMN = 'notes'
RESERVED_COLUMNS = (SESSION_COLUMN, ID_COLUMN, MAPPING_COLUMN, NOTES_COLUMN)
NUMBER, DATE, TEXT = 'number', 'date', 'text'
BAG_COLUMNS = {'normal_load_n': 'normal_force_n'}
"""Session metadata fields that become another column in a table made from bags: the normal
load entered at the station is the normal force the session's fit uses."""
_YAML_KEYS = {'sessions', 'by', 'trend', 'mapping', 'title'}
_DELIMITERS = ',;\t'

Value = float | dt.datetime | str | None


@dataclass(frozen=True)
class Column:
    """A condition column and what its values are: 'number', 'date' or 'text'."""

    name: str
    kind: str


@dataclass(frozen=True)
class CampaignSession:
    """One row: the task's spec, its condition values (None where empty) and its notes."""

    spec: SessionSpec
    conditions: Mapping[str, Value]
    notes: str = ''
    row: int = 0
    """Its line in a CSV table, or its position (from 1) in a YAML list."""

    @property
    def session_id(self) -> str:
        """The session's name."""
        return self.spec.session_id


@dataclass(frozen=True)
class CampaignTable:
    """A campaign: its sessions in table order and its condition columns."""

    path: Path
    sessions: tuple[CampaignSession, ...]
    columns: tuple[Column, ...]
    by: tuple[str, ...] = ()
    """Columns whose combination is the condition compared (YAML `by:`; empty: not said)."""
    trend: tuple[str, ...] = ()
    """Numeric or date columns mu is regressed on (YAML `trend:`)."""
    title: str = ''
    base_rig: Rig = field(default=FMM_RIG)

    def column(self, name: str) -> Column:
        """A condition column by name; ValueError listing the known ones."""
        for column in self.columns:
            if column.name == name:
                return column
        known = ', '.join(c.name for c in self.columns) or 'none'
        raise BadInputError(f'{self.path}: no condition column {name!r} (the table has: {known})')

    def default_by(self) -> tuple[str, ...]:
        """The condition when none is named: the table's `by`, else every non-date column."""
        return self.by or tuple(c.name for c in self.columns if c.kind != DATE)


def read_campaign_table(path: str | Path, base_rig: Rig = FMM_RIG) -> CampaignTable:
    """Read and check a campaign table (see module); ValueError naming row and column."""
    path = Path(path)
    if path.is_dir():
        rows, options = bag_rows(path), {}
    elif path.suffix.lower() in ('.yaml', '.yml'):
        rows, options = _yaml_rows(path)
    else:
        rows, options = _csv_rows(path), {}
    if not rows:
        raise BadInputError(f'{path}: the campaign table lists no session')
    names = [name for name in dict.fromkeys(key for _, row in rows for key in row)]
    if SESSION_COLUMN not in names:
        raise BadInputError(
            f'{path}: no "{SESSION_COLUMN}" column (where each session\'s data are)'
        )
    condition_names = [name for name in names if name not in RESERVED_COLUMNS]
    columns = tuple(
        Column(name, _column_kind([row.get(name, '') for _, row in rows]))
        for name in condition_names
    )
    for column in columns:
        if column.name in RIG_COLUMNS and column.kind != NUMBER:
            raise BadInputError(f'{path}: column {column.name!r} sets the rig and must be numeric')
    # absolute: workers elsewhere resolve the same paths
    folder = path.absolute() if path.is_dir() else path.absolute().parent
    default_mapping = options.get('mapping')
    sessions = []
    for number, row in rows:
        where = f'{path}: row {number}'
        source = row.get(SESSION_COLUMN, '').strip()
        if not source:
            raise BadInputError(f'{where}: no session given')
        conditions = {c.name: _value(row.get(c.name, ''), c.kind) for c in columns}
        try:
            constants = {name: conditions.get(name) for name in RIG_COLUMNS}
            rig = dataclasses.replace(
                base_rig, **{name: value for name, value in constants.items() if value is not None}
            )
        except ValueError as error:
            raise BadInputError(f'{where}: {error}') from error
        mapping = row.get(MAPPING_COLUMN, '').strip() or default_mapping
        spec = SessionSpec(
            session_id=row.get(ID_COLUMN, '').strip() or source,
            source=folder / source,
            rig=rig,
            mapping=(folder / mapping) if mapping else None,
        )
        sessions.append(CampaignSession(spec, conditions, row.get(NOTES_COLUMN, ''), number))
    ids = [s.session_id for s in sessions]
    repeated = sorted({i for i in ids if ids.count(i) > 1})
    if repeated:
        raise BadInputError(
            f'{path}: session id(s) {", ".join(map(repr, repeated))} appear more than once '
            f'(give each row a unique "{ID_COLUMN}")'
        )
    table = CampaignTable(
        path,
        tuple(sessions),
        columns,
        by=_names(options.get('by'), 'by', path),
        trend=_names(options.get('trend'), 'trend', path),
        title=str(options.get('title') or ''),
        base_rig=base_rig,
    )
    for name in (*table.by, *table.trend):
        table.column(name)
    return table


def bag_rows(folder: Path) -> list[tuple[int, dict[str, str]]]:
    """The rows of a session table made from the bags in folder and their session metadata.

    BadInputError naming a bag whose metadata is not valid; a bag without any has empty cells.
    """
    bags = sorted(entry for entry in folder.iterdir() if sniff.file_kind(entry) == sniff.BAG)
    rows = []
    for number, bag in enumerate(bags, start=1):
        try:
            info = bag_session_info(bag) or session_info.empty()
        except ValueError as error:
            raise BadInputError(f'{bag}: {error}') from error
        row = {SESSION_COLUMN: bag.name}
        for info_field in session_info.FIELDS:
            value = info[info_field.name]
            name = BAG_COLUMNS.get(info_field.name, info_field.name)
            row[name] = '' if isinstance(value, float) and math.isnan(value) else f'{value}'
        rows.append((number, row))
    return rows


def _csv_rows(path: Path) -> list[tuple[int, dict[str, str]]]:
    """Rows of a CSV table with their line numbers; blank and '#' lines skipped."""
    text = path.read_text(encoding='utf-8-sig')
    lines = [
        (number, line)
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith('#')
    ]
    if not lines:
        return []
    try:
        dialect = csv.Sniffer().sniff(lines[0][1], delimiters=_DELIMITERS)
        delimiter = dialect.delimiter
    except csv.Error:
        delimiter = ','
    parsed = list(csv.reader([line for _, line in lines], delimiter=delimiter))
    header = [name.strip() for name in parsed[0]]
    if len(set(header)) != len(header) or '' in header:
        raise BadInputError(f'{path}: the header needs unique, non-empty column names: {header}')
    rows = []
    for (number, _), cells in zip(lines[1:], parsed[1:], strict=True):
        if len(cells) > len(header):
            raise BadInputError(
                f'{path}: row {number} has {len(cells)} cells for {len(header)} columns'
            )
        cells += [''] * (len(header) - len(cells))  # a short row: its last cells are empty
        rows.append(
            (number, {name: cell.strip() for name, cell in zip(header, cells, strict=True)})
        )
    return rows


def _yaml_rows(path: Path) -> tuple[list[tuple[int, dict[str, str]]], dict]:
    """Rows of a YAML table (values as text) and its campaign-wide options."""
    with open(path, encoding='utf-8') as stream:
        document = yaml.safe_load(stream)
    options: dict = {}
    if isinstance(document, dict):
        unknown = set(document) - _YAML_KEYS
        if unknown:
            raise BadInputError(
                f'{path}: unknown key(s) {", ".join(sorted(unknown))} (known: '
                f'{", ".join(sorted(_YAML_KEYS))})'
            )
        options = {key: value for key, value in document.items() if key != 'sessions'}
        document = document.get('sessions')
    if not isinstance(document, list) or not all(isinstance(row, dict) for row in document):
        raise BadInputError(f'{path}: expected a list of sessions, each a mapping of columns')
    rows = [
        (number, {str(key): _text(value) for key, value in row.items()})
        for number, row in enumerate(document, start=1)
    ]
    return rows, options


def _text(value: object) -> str:
    """A YAML scalar as the text a CSV cell would hold."""
    if value is None:
        return ''
    if isinstance(value, dt.date | dt.datetime):
        return value.isoformat()
    if isinstance(value, list | dict):
        raise BadInputError(f'a table cell must be a single value, got {value!r}')
    return str(value)


def _names(value: object, key: str, path: Path) -> tuple[str, ...]:
    """A YAML option naming columns: a name or a list of names."""
    if value is None:
        return ()
    if isinstance(value, str):
        return (value,)
    if isinstance(value, list) and all(isinstance(item, str) for item in value):
        return tuple(value)
    raise BadInputError(f'{path}: "{key}" must be a column name or a list of them, got {value!r}')


def _column_kind(cells: Sequence[str]) -> str:
    """'number' if every non-empty cell is a finite number, 'date' if every one is a date."""
    filled = [cell.strip() for cell in cells if cell.strip()]
    if filled and all(_number(cell) is not None for cell in filled):
        return NUMBER
    if filled and all(_date(cell) is not None for cell in filled):
        return DATE
    return TEXT


def _value(cell: str, kind: str) -> Value:
    """A cell as its column's kind of value (None when empty)."""
    cell = cell.strip()
    if not cell:
        return None
    if kind == NUMBER:
        return _number(cell)
    if kind == DATE:
        return _date(cell)
    return cell


def _number(text: str) -> float | None:
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _date(text: str) -> dt.datetime | None:
    """An ISO date or date-time, as a naive UTC datetime (dates at midnight)."""
    try:
        value = dt.datetime.fromisoformat(text)
    except ValueError:
        return None
    if value.tzinfo is not None:
        value = value.astimezone(dt.timezone.utc).replace(tzinfo=None)
    return value


def format_value(value: Value) -> str:
    """A condition value as people write it: 6.67, 2026-11-02, PTFE; '' when missing."""
    if value is None:
        return ''
    if isinstance(value, float):
        return f'{value:g}'
    if isinstance(value, dt.datetime):
        return value.date().isoformat() if value.time() == dt.time() else value.isoformat()
    return str(value)
