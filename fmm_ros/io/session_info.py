"""A session's metadata: who ran it, on which pin, counterface and lubricant, under what load.

Tribology software tags every test with its specimen, lubricant and load. `FIELDS`
is the one declaration of that metadata: the station's form, the SessionInfo message (its
fields carry these names), the bag's metadata (custom_data key `SESSION_KEY`, JSON), the
report's header and a campaign's session table all follow from it. `validated` refuses what
cannot be stored as entered (a field unknown, too long, a number out of range) with a message
naming each problem, so nothing is cut short silently.
"""

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass

from fmm_ros.errors import BadInputError

SESSION_KEY = 'fmm.session'
"""custom_data key of a bag's metadata.yaml holding the session's metadata (JSON)."""


@dataclass(frozen=True)
class InfoField:
    """One metadata field: text (at most max_chars) or a number (within limits, in unit)."""

    name: str
    label: str
    max_chars: int = 0
    unit: str = ''
    limits: tuple[float, float] | None = None

    @property
    def numeric(self) -> bool:
        """A number (NaN: not entered) rather than text."""
        return self.limits is not None


FIELDS: tuple[InfoField, ...] = (
    InfoField('operator_name', 'operator', max_chars=64),
    InfoField('pin', 'pin', max_chars=128),
    InfoField('counterface', 'counterface', max_chars=128),
    InfoField('lubricant', 'lubricant', max_chars=128),
    InfoField('normal_load_n', 'normal load', unit='N', limits=(0.0, 1e5)),
    InfoField('temperature_c', 'temperature', unit='°C', limits=(-60.0, 300.0)),
    InfoField('relative_humidity_percent', 'relative humidity', unit='%', limits=(0.0, 100.0)),
    InfoField('notes', 'notes', max_chars=2000),
)
BY_NAME = {field.name: field for field in FIELDS}

SessionInfo = dict[str, str | float]
"""Field name -> text or number (NaN: not entered), every field of FIELDS present."""


def empty() -> SessionInfo:
    """Nothing entered."""
    return {field.name: math.nan if field.numeric else '' for field in FIELDS}


def validated(values: Mapping[str, object]) -> SessionInfo:
    """Every field checked and normalised (text stripped, numbers as floats, '' as NaN).

    BadInputError names every problem: an unknown field, text too long or holding control
    characters (a newline is allowed in notes), a number that is not one or out of range.
    """
    problems = [f'unknown field {name!r}' for name in values if name not in BY_NAME]
    info = empty()
    for name, value in values.items():
        field = BY_NAME.get(name)
        if field is None:
            continue
        if field.numeric:
            number, problem = _number(field, value)
            info[name] = number
        else:
            text, problem = _text(field, value)
            info[name] = text
        if problem:
            problems.append(problem)
    if problems:
        raise BadInputError(f'session metadata refused: {"; ".join(problems)}')
    return info


def _number(field: InfoField, value: object) -> tuple[float, str]:
    if value is None or (isinstance(value, str) and not value.strip()):
        return math.nan, ''
    if isinstance(value, bool):
        return math.nan, f'{field.label} {value!r} is not a number [{field.unit}]'
    try:
        number = float(value)
    except (TypeError, ValueError):
        return math.nan, f'{field.label} {str(value)[:40]!r} is not a number [{field.unit}]'
    if math.isnan(number):
        return number, ''
    low, high = field.limits
    if not low <= number <= high:
        return math.nan, f'{field.label} {number:g} {field.unit} is outside [{low:g}, {high:g}]'
    return number, ''


def _text(field: InfoField, value: object) -> tuple[str, str]:
    if value is None:
        return '', ''
    if not isinstance(value, str):
        return '', f'{field.label} is not text'
    text = value.strip()
    if len(text) > field.max_chars:
        return '', f'{field.label} is {len(text)} characters long (at most {field.max_chars})'
    allowed = '\n\t' if field.name == 'notes' else ''
    if any(ord(char) < 32 and char not in allowed for char in text):
        return '', f'{field.label} holds control characters'
    return text, ''


def from_message(msg: object) -> SessionInfo:
    """The metadata of a SessionInfo message (rclpy's or a bag's), validated."""
    return validated({field.name: getattr(msg, field.name) for field in FIELDS})


def to_json(info: SessionInfo) -> str:
    """The metadata as JSON (NaN as null), as the bag's metadata stores it."""
    return json.dumps(
        {
            name: None if isinstance(value, float) and math.isnan(value) else value
            for name, value in info.items()
        },
        ensure_ascii=False,
    )


def from_json(text: str) -> SessionInfo:
    """The metadata stored by `to_json` (BadInputError when it is not such JSON)."""
    try:
        values = json.loads(text)
    except json.JSONDecodeError as error:
        raise BadInputError(f'session metadata is not JSON: {error}') from None
    if not isinstance(values, dict):
        raise BadInputError('session metadata is not a JSON object')
    return validated(values)


def describe(info: SessionInfo) -> list[tuple[str, str]]:
    """(label, text with unit) of every field entered, for a report's header."""
    rows = []
    for field in FIELDS:
        value = info.get(field.name)
        if field.numeric and isinstance(value, float) and not math.isnan(value):
            rows.append((field.label, f'{value:g} {field.unit}'))
        elif not field.numeric and value:
            rows.append((field.label, str(value)))
    return rows
