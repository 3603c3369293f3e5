"""Argument checks shared by the core modules: each raises ValueError naming the argument.

`time_base` is the one check of a time column (uniform clocks and scattered stamps alike).

The scalar checks are declared with the settings (`fmm_ros.core.settings`, numpy-free) and
re-exported here; the array checks below need numpy.
"""

import math
from dataclasses import dataclass

import numpy as np

from fmm_ros.core.settings import require_finite, require_non_negative, require_positive
from fmm_ros.errors import BadInputError

__all__ = [
    'finite_samples',
    'one_dimensional_samples',
    'require_finite',
    'require_non_negative',
    'require_positive',
    'TimeBase',
    'time_base',
]


GAP_STEP_RATIO = 1.5
"""A step this many times the mean step is a dropped sample (a dropped one makes it 2)."""

UNIFORM_STEPS = 1e-6
"""Steps that depart from the mean by at most this fraction of it are reported as uniform."""


@dataclass(frozen=True)
class TimeBase:
    """The sample rate a time column gives, and how much its steps scatter about its step."""

    sample_rate_hz: float
    """One over the mean step over the whole span [Hz]."""
    jitter_rms_s: float
    """Standard deviation of the steps about their mean [s]."""
    jitter_max_s: float
    """Largest departure of a step from the mean [s]."""

    def describe(self) -> str:
        """'jitter 3.1 us rms, 12 us at most (0.5 % / 1.9 % of a step)', or 'uniform steps'.

        Steps within UNIFORM_STEPS of the step (a printed time's rounding) are uniform.
        """
        step = 1.0 / self.sample_rate_hz
        if self.jitter_max_s <= UNIFORM_STEPS * step:
            return 'uniform steps'
        return (
            f'jitter {self.jitter_rms_s * 1e6:.3g} us rms, {self.jitter_max_s * 1e6:.3g} us '
            f'at most ({100 * self.jitter_rms_s / step:.2g} % / '
            f'{100 * self.jitter_max_s / step:.2g} % of a step)'
        )


def time_base(time_s: np.ndarray, what: str = 'time_s', rtol: float | None = 1e-3) -> TimeBase:
    """The rate and jitter of a time column; BadInputError naming `what` and the row if unfit.

    The one check of a time column, wherever one is read (records, lab files, stamps, axes,
    a force to simulate). The rate is the mean step over the whole span, so the rounding of
    each printed time averages out. Refused: fewer than two samples, a time that is not
    finite, one that does not increase (named by its data row, the first sample being row 1),
    and, for a clock that steps uniformly (rtol, relative to the step), a step off by
    more; for stamps from a PC clock (rtol None), which scatter, only a step beyond
    GAP_STEP_RATIO times the mean (samples were dropped).
    """
    time_s = np.asarray(time_s, dtype=float)
    if time_s.ndim != 1 or time_s.size < 2:
        raise BadInputError(f'{what}: a time column needs at least two samples')
    finite = np.isfinite(time_s)
    if not finite.all():
        raise BadInputError(f'{what} is not finite at sample {int(np.argmin(finite))}')
    steps = np.diff(time_s)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        row = int(bad[0])
        raise BadInputError(
            f'{what} goes backwards at data row {row + 2} ({time_s[row + 1]:.9g} s, after '
            f'{time_s[row]:.9g} s at row {row + 1}; {bad.size} such step(s)): the samples '
            'are out of order, repeated, or the clock was reset'
        )
    step = (time_s[-1] - time_s[0]) / (time_s.size - 1)
    deviation = steps - step
    worst = int(np.argmax(np.abs(deviation)))
    if rtol is not None and abs(deviation[worst]) > rtol * step:
        raise BadInputError(
            f'{what}: non-uniform time step: {steps[worst]:.6g} s between samples {worst} '
            f'and {worst + 1}, against {step:.6g} s on average (a dropped or repeated sample?)'
        )
    longest = int(np.argmax(steps))
    if steps[longest] > GAP_STEP_RATIO * step:
        raise BadInputError(
            f'{what}: a step of {steps[longest]:.6g} s at data row {longest + 2}, '
            f'{steps[longest] / step:.2g} times the mean {step:.6g} s: samples were dropped'
        )
    return TimeBase(1.0 / step, float(np.std(deviation)), float(np.abs(deviation[worst])))


def finite_samples(name: str, values: np.ndarray, overflow: str = 'sum') -> np.ndarray:
    """The values as a contiguous one-dimensional float64 array of finite samples.

    One pairwise sum is cheaper than an isfinite mask and is non-finite if any sample is; only
    then are the bad samples located, and the first named. `overflow` says what a sum that
    overflows on finite samples stops (in the message).
    """
    array = one_dimensional_samples(name, values)
    with np.errstate(over='ignore'):  # an overflow is refused below, by name
        total = float(np.add.reduce(array))
    if not math.isfinite(total):
        bad = np.flatnonzero(~np.isfinite(array))
        if bad.size:
            raise BadInputError(
                f'{name} is not finite at sample {int(bad[0])} '
                f'({array[bad[0]]}); {bad.size} bad sample(s)'
            )
        raise BadInputError(f'{name} is too large to {overflow} (its sum overflows)')
    return array


def one_dimensional_samples(name: str, values: np.ndarray) -> np.ndarray:
    """The values as a contiguous one-dimensional float64 array (not checked to be finite)."""
    array = np.ascontiguousarray(values, dtype=np.float64)
    if array.ndim != 1:
        raise BadInputError(f'{name} must be one-dimensional, got shape {array.shape}')
    return array
