"""Compiled scans of one record's analysis; use them through `quality` and `frf`.

Each loop replaces a chain of whole-array numpy steps (a mask, a diff of it, the indices of
its edges, a cumulative sum, ...) that a 33 s record paid at every replayed hit, with one
pass giving the same numbers: comparisons and selections exactly as numpy makes them, and
every floating-point operation in numpy's order (a cumulative sum left to right, each
interpolation as `i + a / (a - b)`). `test/test_fast_analysis.py` holds each to the numpy
steps it replaced.
"""

import math

import numpy as np
from numba import njit


@njit(cache=True)
def equal_runs(values, min_length):
    """Consecutive equal finite samples: how many pairs, and the long runs of them.

    Pair i is values[i + 1] == values[i] with values[i + 1] finite (NaN never equals; an
    infinity does, but is left out). Returns the count of such pairs and [start, stop) (pair
    indices) of every run of them at least min_length pairs long: `frf.runs` of the pair
    mask, only its long runs.
    """
    count = 0
    starts = np.empty(0, np.int64)
    stops = np.empty(0, np.int64)
    found_starts = []
    found_stops = []
    run_start = -1
    for i in range(values.size - 1):
        after = values[i + 1]
        if after == values[i] and math.isfinite(after):
            count += 1
            if run_start < 0:
                run_start = i
        elif run_start >= 0:
            if i - run_start >= min_length:
                found_starts.append(run_start)
                found_stops.append(i)
            run_start = -1
    end = max(values.size - 1, 0)
    if run_start >= 0 and end - run_start >= min_length:
        found_starts.append(run_start)
        found_stops.append(end)
    if found_starts:
        starts = np.array(found_starts, dtype=np.int64)
        stops = np.array(found_stops, dtype=np.int64)
    return count, starts, stops


@njit(cache=True, error_model='numpy')  # 0 / 0 between a -0.0 and a 0.0: NaN, as numpy
def reversals(smooth, hysteresis):
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
    crossings' running sum, left to right, as numpy's cumsum makes it. Also returned: the
    first block past each reversal (the new side's), and the largest |smooth| from it up to
    the next one's (to the end for the last): the peak speed of each half cycle.
    """
    n = smooth.size
    crossings = np.empty(n, np.float64)  # zero-crossing times, in order
    sums = np.empty(n + 1, np.float64)  # their cumulative sum, from 0
    sums[0] = 0.0
    seen = 0
    crossings_before = np.empty(n, np.int64)  # crossings with index below each block
    for i in range(n):
        crossings_before[i] = seen
        if i + 1 < n and np.signbit(smooth[i + 1]) != np.signbit(smooth[i]):
            before, after = smooth[i], smooth[i + 1]
            crossings[seen] = i + before / (before - after)
            sums[seen + 1] = sums[seen] + crossings[seen]
            seen += 1
    times = np.empty(n, np.float64)
    ends = np.empty(n, np.int64)
    count = 0
    last_beyond, last_side = -1, 0
    for i in range(n):
        side = 1 if smooth[i] > hysteresis else (-1 if smooth[i] < -hysteresis else 0)
        if side == 0:
            continue
        if last_beyond >= 0 and side != last_side:
            first, last = crossings_before[last_beyond], crossings_before[i]
            times[count] = (sums[last] - sums[first]) / max(last - first, 1)
            ends[count] = i
            count += 1
        last_beyond, last_side = i, side
    peaks = np.empty(count, np.float64)
    for k in range(count):
        stop = ends[k + 1] if k + 1 < count else n
        peak = abs(smooth[ends[k]])
        for i in range(ends[k] + 1, stop):
            peak = max(peak, abs(smooth[i]))
        peaks[k] = peak
    return times[:count], ends[:count], peaks
