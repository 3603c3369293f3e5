"""Argument checks shared by the core modules: each raises ValueError naming the argument.

The scalar checks are declared with the settings (`fmm_ros.core.settings`, numpy-free) and
re-exported here; the array checks below need numpy.
"""

import math

import numpy as np

from fmm_ros.core.settings import require_finite, require_non_negative, require_positive
from fmm_ros.errors import BadInputError

__all__ = [
    'finite_samples',
    'require_finite',
    'require_non_negative',
    'require_positive',
    'sample_rate_from_times',
]


def sample_rate_from_times(time_s: np.ndarray, rtol: float = 1e-3) -> float:
    """Sample rate [Hz] of a uniformly sampled time column; ValueError if not uniform.

    Shared by the physics core and the record reader (`fmm_ros.core.signal.records`), which must not
    pay for importing the compiled model just to read a CSV file.
    """
    time_s = np.asarray(time_s, dtype=float)
    if time_s.ndim != 1 or time_s.size < 2:
        raise BadInputError('a time column needs at least two samples')
    if not np.all(np.isfinite(time_s)):
        raise BadInputError(f'time_s is not finite at sample {int(np.argmin(np.isfinite(time_s)))}')
    steps = np.diff(time_s)
    step = (time_s[-1] - time_s[0]) / (time_s.size - 1)
    if step <= 0.0:
        raise BadInputError('time_s must increase')
    worst = int(np.argmax(np.abs(steps - step)))
    if abs(steps[worst] - step) > rtol * step:
        raise BadInputError(
            f'non-uniform time step: {steps[worst]:.6g} s between samples {worst} '
            f'and {worst + 1}, against {step:.6g} s on average'
        )
    return 1.0 / step


def finite_samples(name: str, values: np.ndarray, overflow: str = 'sum') -> np.ndarray:
    """The values as a contiguous one-dimensional float64 array of finite samples.

    One pairwise sum is cheaper than an isfinite mask and is non-finite if any sample is; only
    then are the bad samples located, and the first named. `overflow` says what a sum that
    overflows on finite samples stops (in the message).
    """
    array = np.ascontiguousarray(values, dtype=np.float64)
    if array.ndim != 1:
        raise BadInputError(f'{name} must be one-dimensional, got shape {array.shape}')
    if not math.isfinite(float(np.add.reduce(array))):
        bad = np.flatnonzero(~np.isfinite(array))
        if bad.size:
            raise BadInputError(
                f'{name} is not finite at sample {int(bad[0])} '
                f'({array[bad[0]]}); {bad.size} bad sample(s)'
            )
        raise BadInputError(f'{name} is too large to {overflow} (its sum overflows)')
    return array
