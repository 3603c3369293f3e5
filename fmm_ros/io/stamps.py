"""Date-time stamps as a time column: what NI's text exports write beside each sample.

LabVIEW and NI's loggers export `27/03/2025 10:51:38,2226056` (day first, a decimal comma in
a European locale) or `2025-03-27 10:51:38.2226056`, one per sample. Such a column is read as
seconds since the first stamp (`StampParser`, exact to the 100 ns the stamps carry: seconds
since 1970 would keep only about 0.2 us in a float), and the sample rate comes from the
stamps (`stamp_rate`): their mean step over the whole span, with their jitter reported,
since a PC clock stamps blocks of samples and its steps scatter. Stamps that go backwards
are refused, naming the row; a step well beyond the mean is samples that were dropped.

Day and month: `D/M/Y` and `D.M.Y` are read day first (the locales that write a decimal
comma); ISO `Y-M-D` as written. Only differences of stamps are used, so the order matters
only for a record that runs over midnight at the end of a month.
"""

from __future__ import annotations

import datetime
import re
from dataclasses import dataclass

import numpy as np

from fmm_ros.errors import BadInputError

_TIME = r'(?P<h>\d{1,2}):(?P<mi>\d{2}):(?P<s>\d{2})(?:[.,](?P<frac>\d+))?'
STAMP = re.compile(
    r'^\s*(?:(?P<d>\d{1,2})[./](?P<m>\d{1,2})[./](?P<y>\d{4})'
    r'|(?P<iy>\d{4})-(?P<im>\d{1,2})-(?P<id>\d{1,2}))[ T]' + _TIME + r'\s*$'
)
"""A date and a time of day, to any fraction of a second."""

GAP_STEP_RATIO = 1.5
"""A step this many times the mean step is a dropped sample (a dropped one makes it 2)."""


def is_stamp(cell: str) -> bool:
    """Whether a text cell is a date-time stamp."""
    return STAMP.match(cell) is not None


def seconds_of_stamp(cell: str) -> tuple[int, float]:
    """(day number, seconds into that day) of a stamp; ValueError when it is not one."""
    match = STAMP.match(cell)
    if match is None:
        raise ValueError(f'not a date-time stamp: {cell!r}')
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


@dataclass(frozen=True)
class StampRate:
    """The sample rate the stamps give, and how much their steps scatter."""

    sample_rate_hz: float
    jitter_rms_s: float
    """Standard deviation of the steps about their mean [s]."""
    jitter_max_s: float
    """Largest departure of a step from the mean [s]."""

    def describe(self) -> str:
        """'1600 Hz from the stamps, jitter 3.1 us rms, 12 us at most (0.5 % / 1.9 % of a step)'."""
        step = 1.0 / self.sample_rate_hz
        return (
            f'from the date-time stamps, jitter {self.jitter_rms_s * 1e6:.3g} us rms, '
            f'{self.jitter_max_s * 1e6:.3g} us at most ({100 * self.jitter_rms_s / step:.2g} % / '
            f'{100 * self.jitter_max_s / step:.2g} % of a step)'
        )


def backwards(time_s: np.ndarray, what: str) -> None:
    """BadInputError naming the first data row where a time column does not increase."""
    steps = np.diff(np.asarray(time_s, dtype=float))
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        row = int(bad[0])
        raise BadInputError(
            f'{what} goes backwards at data row {row + 2} ({time_s[row + 1]:.9g} s after the '
            f'first, after {time_s[row]:.9g} s at row {row + 1}; {bad.size} such step(s)): '
            'the samples are out of order or the clock was reset'
        )


def stamp_rate(time_s: np.ndarray, what: str) -> StampRate:
    """The rate of stamped samples: mean step over the span, jitter, refusals (module doc)."""
    time_s = np.asarray(time_s, dtype=float)
    if time_s.size < 2:
        raise BadInputError(f'{what}: a time column needs at least two samples')
    backwards(time_s, what)
    steps = np.diff(time_s)
    step = (time_s[-1] - time_s[0]) / (time_s.size - 1)
    worst = int(np.argmax(steps))
    if steps[worst] > GAP_STEP_RATIO * step:
        raise BadInputError(
            f'{what}: a step of {steps[worst]:.6g} s at data row {worst + 2}, '
            f'{steps[worst] / step:.2g} times the mean {step:.6g} s: samples were dropped'
        )
    deviation = steps - step
    return StampRate(1.0 / step, float(np.std(deviation)), float(np.max(np.abs(deviation))))
