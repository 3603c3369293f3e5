"""Compiled scans of one record's analysis; use them through `quality` and `frf`.

Each loop replaces a chain of whole-array numpy steps (a mask, a diff of it, the indices of
its edges, a cumulative sum, ...) that a 33 s record paid at every replayed hit, with one
pass giving the same numbers: comparisons and selections exactly as numpy makes them, and
every floating-point operation in numpy's order (a cumulative sum left to right, each
interpolation as `i + a / (a - b)`). `test/test_fast_analysis.py` holds each to the numpy
steps it replaced. They release the GIL (`nogil`): a replay analyses its records in threads
(`fmm_ros.core._threads`).
"""

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def equal_runs(values, min_length):
    """Consecutive equal finite samples: how many pairs, and the long runs of them.

    Pair i is values[i + 1] == values[i] with values[i + 1] finite (NaN never equals; an
    infinity does, but is left out). Returns the count of such pairs and [start, stop) (pair
    indices) of every run of them at least min_length pairs long: `frf.runs` of the pair
    mask, only its long runs.
    """
    size = values.size - 1  # pairs
    count = 0
    for i in range(size):  # a vectorised count first: a noisy channel has few equal pairs
        after = values[i + 1]
        count += (after == values[i]) & (abs(after) < math.inf)
    edges = np.empty(max(size, 0) + 1, np.int64)  # where runs start and stop, alternately
    found = 0
    previous = False
    for i in range(size if count >= max(min_length, 1) else 0):  # else no run is long
        after = values[i + 1]
        equal = (after == values[i]) & (abs(after) < math.inf)
        edges[found] = i  # branch-free: in a quantised channel equal pairs come at random
        found += equal != previous
        previous = equal
    if previous:
        edges[found] = size
        found += 1
    starts, stops = edges[0:found:2], edges[1:found:2]
    long = stops - starts >= min_length
    return count, starts[long], stops[long]


# error_model: 0 / 0 between a -0.0 and a 0.0 gives NaN, as numpy.
@njit(cache=True, nogil=True, error_model='numpy')
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
    bits = smooth.view(np.int64)  # a sign bit is the top bit: negative as an int64
    crossings = np.empty(n, np.int64)  # blocks i whose sign bit differs from block i + 1's
    seen = 0
    for i in range(n - 1):  # branch-free: at rest the sign flips at random
        crossings[seen] = i
        seen += (bits[i] ^ bits[i + 1]) < 0
    crossings = crossings[:seen]
    sums = np.empty(seen + 1, np.float64)  # running sum of the crossing times, from 0
    sums[0] = 0.0
    for k in range(seen):
        i = crossings[k]
        before, after = smooth[i], smooth[i + 1]
        sums[k + 1] = sums[k] + (i + before / (before - after))
    times = np.empty(n, np.float64)
    ends = np.empty(n, np.int64)
    count = 0
    last_beyond, last_side = -1, 0
    for i in range(n):
        side = 1 if smooth[i] > hysteresis else (-1 if smooth[i] < -hysteresis else 0)
        if side == 0:
            continue
        if last_beyond >= 0 and side != last_side:
            first = np.searchsorted(crossings, last_beyond)
            last = np.searchsorted(crossings, i)
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
