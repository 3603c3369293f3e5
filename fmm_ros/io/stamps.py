"""Date-time stamps as a time column: what NI's text exports write beside each sample.

LabVIEW and NI's loggers export `27/03/2025 10:51:38,2226056` (day first, a decimal comma in
a European locale) or `2025-03-27 10:51:38.2226056`, one per sample. Such a column is read as
seconds since the first stamp (`StampParser`, exact to the 100 ns the stamps carry: seconds
since 1970 would keep only about 0.2 us in a float). The sample rate comes from the stamps
by the one check of a time column (`fmm_ros.core._checks.time_base`, told they scatter): their
mean step over the whole span, with their jitter reported, since a PC clock stamps blocks of
samples and its steps scatter. Stamps that go backwards are refused, naming the row; a step
well beyond the mean is samples that were dropped.

Day and month: `D/M/Y` and `D.M.Y` are read day first (the locales that write a decimal
comma); ISO `Y-M-D` as written. Only differences of stamps are used, so the order matters
only for a record that runs over midnight at the end of a month.
"""

from __future__ import annotations

import datetime
import re

from fmm_ros.errors import BadInputError

_TIME = r'(?P<h>\d{1,2}):(?P<mi>\d{2}):(?P<s>\d{2})(?:[.,](?P<frac>\d+))?'
STAMP = re.compile(
    r'^\s*(?:(?P<d>\d{1,2})[./](?P<m>\d{1,2})[./](?P<y>\d{4})'
    r'|(?P<iy>\d{4})-(?P<im>\d{1,2})-(?P<id>\d{1,2}))[ T]' + _TIME + r'\s*$'
)
"""A date and a time of day, to any fraction of a second."""


def is_stamp(cell: str) -> bool:
    """Whether a text cell is a date-time stamp."""
    return STAMP.match(cell) is not None


def seconds_of_stamp(cell: str) -> tuple[int, float]:
    """(day number, seconds into that day) of a stamp; BadInputError when it is not one."""
    match = STAMP.match(cell)
    if match is None:
        raise BadInputError(f'not a date-time stamp: {cell!r}')
    if match['y']:
        date = datetime.date(int(match['y']), int(match['m']), int(match['d']))
    else:
        date = datetime.date(int(match['iy']), int(match['im']), int(match['id']))
    fraction = match['frac'] or '0'
    seconds = int(match['h']) * 3600 + int(match['mi']) * 60 + int(match['s'])
    return date.toordinal(), seconds + int(fraction) / 10 ** len(fraction)


class StampParser:
    """A converter of stamp cells to seconds since the first stamp it converts."""

    def __init__(self) -> None:
        self.origin: tuple[int, float] | None = None

    def __call__(self, cell: str) -> float:
        """Seconds since the first stamp."""
        day, seconds = seconds_of_stamp(cell)
        if self.origin is None:
            self.origin = (day, seconds)
        return (day - self.origin[0]) * 86400.0 + (seconds - self.origin[1])
