"""Keep the memory a command frees for its next allocations (glibc's malloc on Linux).

The estimators work a chunk of the log at a time, allocating and freeing dozens of arrays of a
few MB per chunk. glibc hands such blocks back to the kernel when they are freed (mapped alone
above its threshold, or trimmed off the top of the heap), and the next chunk faults every page
in again, zero-filled: a diagnose of an 8-hour log (one worker) took 770 000 page faults, 9 s of
system time and 49 s of wall time. With blocks up to 32 MB served from the heap, the heap's free
top kept up to 1 GB and grown 256 MB at a time, the same diagnose took 170 000-180 000 faults,
3-9 s of system time (the kernel's share varies from run to run) and 30-39 s, at a peak memory
~1 % higher (benchmarks/long_log.py). Elsewhere than glibc: nothing is changed.
"""
from __future__ import annotations

import ctypes
import sys

# mallopt parameters (malloc.h)
M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_THRESHOLD = -1, -2, -3
SETTINGS = ((M_MMAP_THRESHOLD, 32 << 20),  # glibc's largest: bigger arrays are still mapped alone
            (M_TRIM_THRESHOLD, 1 << 30),
            (M_TOP_PAD, 256 << 20))


def glibc_mallopt():
    """glibc's mallopt, or None (not Linux, or another C library: musl has none)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):
        return None
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return mallopt


def keep_freed_memory() -> bool:
    """Set glibc's malloc to keep freed blocks; True where it did."""
    mallopt = glibc_mallopt()
    return mallopt is not None and all(mallopt(param, value) == 1 for param, value in SETTINGS)
