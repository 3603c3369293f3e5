"""Keep the memory that freed numpy arrays return in this process, for the next ones (glibc).

A record's analysis makes and frees a dozen arrays of a few MB: each DFT's output and work
buffer, the block means, the pulse. glibc's malloc gives a block that large its own
mapping, or trims the free top of its heap once that passes twice the largest block freed
so far, so the arrays of each record came from fresh pages that the kernel faults in and
zeroes. A 30-hit replay took ~200,000 page faults, about 40 % of its CPU time, and which
replay paid them depended on what the process had allocated before. `keep_freed_memory`
sets both thresholds: blocks up to `HEAP_BLOCK_BYTES` come from the heap, and the heap is
trimmed only past `TRIM_BYTES` free, so each record reuses the pages of the one before.
It changes the process, not a module, so the process's owner calls it: the `fmm` command
does, and so do the benchmarks that time what it does.
"""

import ctypes
import sys

M_TRIM_THRESHOLD = -1
"""mallopt's parameter number for the free heap top kept before trimming (malloc.h)."""

M_MMAP_THRESHOLD = -3
"""mallopt's parameter number for the smallest block given its own mapping (malloc.h)."""

HEAP_BLOCK_BYTES = 32 << 20
"""Blocks up to this size come from the heap (glibc's largest allowed threshold on 64 bit)."""

TRIM_BYTES = 256 << 20
"""Free memory at the heap's top is returned to the system only past this much."""


def keep_freed_memory() -> bool:
    """Have malloc keep freed blocks up to `HEAP_BLOCK_BYTES` for reuse; whether it took.

    False (nothing changed) where the C library has no glibc mallopt: another system, or
    another C library.
    """
    if not sys.platform.startswith('linux'):
        return False
    mallopt = getattr(ctypes.CDLL(None), 'mallopt', None)  # the process's own C library
    if mallopt is None:
        return False
    return bool(mallopt(M_MMAP_THRESHOLD, HEAP_BLOCK_BYTES)) and bool(
        mallopt(M_TRIM_THRESHOLD, TRIM_BYTES)
    )
