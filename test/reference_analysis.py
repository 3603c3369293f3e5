"""The per-record analysis steps as numpy defines them, before they were made faster.

Each faster step of a record's analysis (`quality.mad_std`, `frf.median_in_place`, ...) has
its definition here: the numpy expression it replaced. Inside `numpy_steps` every one runs
as its definition, so a test can analyse the same records both ways and hold the results
equal to the bit, and bench_replay can time the analysis as it was in the same run.
"""

import contextlib
from collections.abc import Iterator

import numpy as np

from fmm_ros.core.signal import _kernels, frf, quality


def median(values: np.ndarray) -> float:
    """np.median, as the noise estimates took it."""
    return float(np.median(values))


def mad_deviation(values: np.ndarray) -> float:
    """The MAD deviation of the finite values, as `robust_center_and_std` takes it."""
    return quality._center_and_std(values)[1]


def equal_runs(values: np.ndarray, min_length: int) -> tuple[int, np.ndarray, np.ndarray]:
    """Equal finite neighbours: their count, and the runs of them at least min_length long."""
    equal = (values[1:] == values[:-1]) & np.isfinite(values[1:])
    starts, stops = frf.runs(equal)
    long = stops - starts >= min_length
    return int(np.count_nonzero(equal)), starts[long], stops[long]


def reversals(smooth: np.ndarray, hysteresis: float) -> tuple[np.ndarray, ...]:
    """Reversal times and ends, and each half cycle's peak speed, in numpy steps."""
    side = np.where(smooth > hysteresis, 1, np.where(smooth < -hysteresis, -1, 0))
    beyond = np.flatnonzero(side)
    change = np.flatnonzero(side[beyond][1:] != side[beyond][:-1])
    starts, ends = beyond[change], beyond[change + 1]
    sign = np.signbit(smooth)
    crossings = np.flatnonzero(sign[1:] != sign[:-1])
    before, after = smooth[crossings], smooth[crossings + 1]
    zeros = crossings + before / (before - after)
    first = np.searchsorted(crossings, starts)
    last = np.searchsorted(crossings, ends)
    sums = np.concatenate(([0.0], np.cumsum(zeros)))
    times = (sums[last] - sums[first]) / np.maximum(last - first, 1)
    peaks = np.maximum.reduceat(np.abs(smooth), ends) if ends.size else np.zeros(0)
    return times, ends, peaks


NUMPY_STEPS = {
    (frf, 'median_in_place'): median,
    (quality, 'mad_std'): mad_deviation,
    (_kernels, 'equal_runs'): equal_runs,
    (_kernels, 'reversals'): reversals,
}
"""(module, name) of each faster step -> its numpy definition."""


@contextlib.contextmanager
def numpy_steps() -> Iterator[None]:
    """Run every faster step as its numpy definition inside the block (then restore them)."""
    faster = {key: getattr(*key) for key in NUMPY_STEPS}
    try:
        for (module, name), definition in NUMPY_STEPS.items():
            setattr(module, name, definition)
        yield
    finally:
        for (module, name), step in faster.items():
            setattr(module, name, step)
