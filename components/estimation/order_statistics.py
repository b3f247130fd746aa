"""The median of a long array, exactly and without a full selection over it.

np.median on the 30 M consecutive differences of an 8-hour log is an introselect over all of
them, twice per channel for the median absolute deviation (2.2 s of each diagnose). Here a
strided sample of the array brackets the middle, one comparison pass counts what lies below the
bracket and gathers what lies inside it (~0.1 % of the values), and the selection runs on those
alone. The counts make the result exact whatever the sample: when the bracket misses the middle
(an unlucky stride), the full selection runs instead. The value is np.median's, bit for bit.

The values need not exist whole: :func:`median_of_pieces` takes them as pieces made afresh at
each pass (a long log's intervals or differences, a piece of the log at a time), so a median
holds one piece and the values inside the bracket.
"""
from __future__ import annotations

import numpy as np

from components.logs.spill import pieces

DIRECT_BELOW = 1 << 17   # shorter arrays: np.median directly (the bracket would not pay)
SAMPLE = 1 << 14         # values in the strided sample that places the bracket
BRACKET_SIGMAS = 6.0     # half-width of the bracket in standard errors of the sample's median rank


def stride(n: int) -> int:
    """The step of the strided sample that places the bracket for *n* values."""
    return max(1, n // SAMPLE)


def median(values: np.ndarray, *, overwrite_input: bool = False) -> float:
    """np.median(values) of a 1-D finite array, the same value; *overwrite_input* lets a short
    array's selection reorder it (as np.median's argument of that name)."""
    d = np.asarray(values).ravel()
    n = len(d)
    if n < DIRECT_BELOW:
        return float(np.median(d, overwrite_input=overwrite_input))
    # a piece at a time: a spilled array's pages go back after each (components.logs.spill)
    return median_of_pieces(lambda: (d[s] for s in pieces(n, d)), n, d[::stride(n)],
                            whole=lambda: float(np.median(d, overwrite_input=overwrite_input)))


def median_of_pieces(pieces, n: int, sample: np.ndarray, whole=None) -> float:
    """np.median of the *n* finite values that ``pieces()`` yields as 1-D arrays (a new pass at
    each call, the same values), bit for bit, holding only a piece and the bracket's values: a
    long log's derived values (its intervals, its differences) need not exist whole. *sample*:
    some of the values (every :func:`stride`-th, say), which only place the bracket: the counts
    decide. ``whole()``: the median when the bracket misses (default: np.median of the pieces
    joined, once)."""
    if whole is None:
        def whole():
            return float(np.median(np.concatenate(list(pieces()))))
    if n < DIRECT_BELOW:
        return whole()
    ranks = [(n - 1) // 2, n // 2]
    sample = np.sort(np.asarray(sample, float).ravel())
    m = len(sample)
    if m == 0:
        return whole()
    half = int(BRACKET_SIGMAS * np.sqrt(m) / 2) + 1
    lo, hi = sample[max(0, m // 2 - half)], sample[min(m - 1, m // 2 + half)]
    below, equal, inside = 0, 0, []
    for p in pieces():
        below += int(np.count_nonzero(p < lo))
        if lo == hi:
            equal += int(np.count_nonzero(p == lo))
        else:
            inside.append(p[(p >= lo) & (p <= hi)])
    k0, k1 = ranks[0] - below, ranks[1] - below
    if lo == hi:
        if 0 <= k0 and k1 < equal:
            return float(lo)
        return whole()
    inside = np.concatenate(inside) if inside else np.zeros(0)
    if k0 < 0 or k1 >= len(inside):
        return whole()
    inside.partition([k0, k1])
    # as np.median: the middle value, or the mean of the two middle values of an even count
    return float(inside[k0]) if k0 == k1 else float(np.mean(inside[[k0, k1]]))
