"""Two scans of one record's analysis in whole-array numpy steps (use them through `frf`).

They were numba loops once, a fraction of a millisecond faster a record; but a process that
calls a numba function pays numba's import and the loading of its compiled code first
(about half a second, more than a 30-hit replay's whole analysis gains), so the analysis
path imports no numba and `fmm replay` starts at once. Comparisons and selections are
numpy's, every floating-point operation in the order the loops had (a cumulative sum left
to right, each interpolation as `i + a / (a - b)`); `test/test_fast_analysis.py` holds both to
their definitions in `test/reference_analysis.py`. numpy releases the GIL in them, so a
replay's records still analyse in threads (`fmm_ros.core._threads`).
"""

import numpy as np

_NO_RUNS = np.zeros(0, dtype=np.int64)


def equal_runs(values: np.ndarray, min_length: int) -> tuple[int, np.ndarray, np.ndarray]:
    """Consecutive equal finite samples: how many pairs, and the long runs of them.

    Pair i is values[i + 1] == values[i] with values[i + 1] finite (NaN never equals; an
    infinity does, but is left out). Returns the count of such pairs and [start, stop) (pair
    indices) of every run of them at least min_length pairs long: `frf.runs` of the pair
    mask, only its long runs (none looked for when there are fewer pairs than that).
    """
    after = values[1:]
    equal = after == values[:-1]
    equal &= np.abs(after) < np.inf
    count = int(np.count_nonzero(equal))
    if count < max(min_length, 1):
        return count, _NO_RUNS, _NO_RUNS
    edges = np.flatnonzero(np.diff(equal, prepend=False, append=False))
    starts, stops = edges[0::2], edges[1::2]
    long = stops - starts >= min_length
    return count, starts[long], stops[long]


def reversals(smooth: np.ndarray, hysteresis: float) -> tuple[np.ndarray, ...]:
    """Velocity reversals in block means: their times, end blocks and half cycles' peaks.

    A reversal is the velocity passing from beyond -hysteresis to beyond +hysteresis or back
    (a Schmitt trigger): noise crossing zero again near a slow reversal (a low hit's last
    half cycles turn at a few 1e-4 m/s a block, the noise's size) is one reversal, not three
    with two weak half cycles between them that would break a run of strong ones. Its time
    [fractional blocks] is the mean of the zero crossings (sign-bit changes, each at
    i + a / (a - b) between blocks i and i + 1) from the last block beyond the band on the
    old side to the first beyond it on the new: the one crossing of a clean reversal, the
    average of noise's several near a slow one. (Not a line through the band: the
    acceleration jumps by 2 mu N / m at the reversal.) The means are differences of the
    crossings' running sum, left to right. Also returned: the first block past each
    reversal (the new side's), and the largest |smooth| from it up to the next one's (to
    the end for the last): the peak speed of each half cycle.
    """
    side = np.where(smooth > hysteresis, 1, np.where(smooth < -hysteresis, -1, 0))
    beyond = np.flatnonzero(side)
    change = np.flatnonzero(side[beyond][1:] != side[beyond][:-1])
    starts, ends = beyond[change], beyond[change + 1]
    sign = np.signbit(smooth)
    crossings = np.flatnonzero(sign[1:] != sign[:-1])
    before, after = smooth[crossings], smooth[crossings + 1]
    with np.errstate(invalid='ignore', divide='ignore'):  # 0 / 0 between -0.0 and 0.0: NaN
        zeros = crossings + before / (before - after)
    first = np.searchsorted(crossings, starts)
    last = np.searchsorted(crossings, ends)
    sums = np.concatenate(([0.0], np.cumsum(zeros)))
    times = (sums[last] - sums[first]) / np.maximum(last - first, 1)
    peaks = np.maximum.reduceat(np.abs(smooth), ends) if ends.size else np.zeros(0)
    return times, ends, peaks
