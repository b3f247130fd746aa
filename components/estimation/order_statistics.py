"""The median of a long array, exactly and without a full selection over it.

np.median on the 30 M consecutive differences of an 8-hour log is an introselect over all of
them, twice per channel for the median absolute deviation (2.2 s of each diagnose). Here a
strided sample of the array brackets the middle, one comparison pass counts what lies below the
bracket and gathers what lies inside it (~0.1 % of the values), and the selection runs on those
alone. The counts make the result exact whatever the sample: when the bracket misses the middle
(an unlucky stride), the full selection runs instead. The value is np.median's, bit for bit.

The values need not exist whole: :func:`median_of_pieces` takes them as pieces made afresh at
each pass (a long log's intervals or differences, a piece of the log at a time), so a median
holds one piece and the values inside the bracket. Where the bracket holds too many (a regular
clock's intervals differ only in their last bits: all of them fell inside, 16 bytes a sample at
once), a pass counts them in bins and the bins that hold the middle make the next bracket; and
where the bracket misses the middle, the next one is every value's range, narrowed the same way.
"""
from __future__ import annotations

import numpy as np

from components.logs.spill import gathered, pieces

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
    # a piece at a time: a spilled array's pages go back after each (components.logs.spill; its
    # pages are *values*'s mapping: np.asarray makes a plain array of it, whose pages none gives back)
    # (and the bracket's sample a piece at a time too: every stride-th value of a spilled column
    # is on every page of it, 240 MB faulted in on an 8-hour log)
    sample = gathered(values, np.arange(0, n, stride(n))) if np.ndim(values) == 1 else d[::stride(n)]
    return median_of_pieces(lambda: (d[s] for s in pieces(n, values)), n, sample)


def median_of_pieces(pieces, n: int, sample: np.ndarray) -> float:
    """np.median of the *n* finite values that ``pieces()`` yields as 1-D arrays (a new pass at
    each call, the same values), bit for bit, holding only a piece, the values inside the bracket
    (at most :data:`MOST_INSIDE`) and its bins' counts: a long log's derived values (its
    intervals, its differences) need not exist whole. *sample*: some of the values (every
    :func:`stride`-th, say), which only place the first bracket: the counts decide. Fewer than
    DIRECT_BELOW values: np.median of the pieces joined."""
    if n < DIRECT_BELOW:
        return float(np.median(np.concatenate(list(pieces()))))
    ranks = ((n - 1) // 2, n // 2)
    sample = np.sort(np.asarray(sample, float).ravel())
    m = len(sample)
    if m:
        half = int(BRACKET_SIGMAS * np.sqrt(m) / 2) + 1
        lo, hi = float(sample[max(0, m // 2 - half)]), float(sample[min(m - 1, m // 2 + half)])
    else:
        lo, hi = -np.inf, np.inf
    binned = False
    for _ in range(MOST_PASSES):
        scan = _Scan(lo, hi, binned)
        for p in pieces():
            scan.add(p)
        k0, k1 = ranks[0] - scan.below, ranks[1] - scan.below
        if k0 < 0 or k1 >= scan.inside:
            # the bracket missed the middle (a sample of outliers, or on a tie): every value's range
            lo, hi = _range(pieces)
            continue
        if scan.lowest == scan.highest:  # every value inside alike (one value, or a tie)
            return scan.lowest
        if scan.gathered is not None:
            inside = np.concatenate(scan.gathered) if scan.gathered else np.zeros(0)
            inside.partition([k0, k1])
            # as np.median: the middle value, or the mean of the two middle values of an even count
            return float(inside[k0]) if k0 == k1 else float(np.mean(inside[[k0, k1]]))
        if scan.edges is None:
            # too many inside to hold (a regular clock's intervals, all but alike): counted again
            # in bins, whose counts say which make the next bracket
            lo, hi = (lo, hi) if np.isfinite(lo) and np.isfinite(hi) else _range(pieces)
            binned = True
            continue
        below = np.concatenate([[0], np.cumsum(scan.counts)])
        b0 = int(np.searchsorted(below, k0, side="right")) - 1
        b1 = int(np.searchsorted(below, k1, side="right")) - 1

        def bin_range(b):
            top = scan.hi if b == BINS - 1 else float(np.nextafter(scan.edges[b + 1], -np.inf))
            return float(scan.edges[b]), top

        if b0 != b1:
            # the two middle ranks in different bins: the highest value of the one and the lowest
            # of the other (the ranks are next to each other), in one more pass
            (lo0, hi0), (lo1, hi1) = bin_range(b0), bin_range(b1)
            v0, v1 = -np.inf, np.inf
            for p in pieces():
                a = p[(p >= lo0) & (p <= hi0)]
                c = p[(p >= lo1) & (p <= hi1)]
                v0 = max(v0, float(a.max())) if len(a) else v0
                v1 = min(v1, float(c.min())) if len(c) else v1
            return float(np.mean(np.array([v0, v1])))
        lo, hi = bin_range(b0)
    return float(np.median(np.concatenate(list(pieces()))))  # (not reached: each pass narrows)


def _range(pieces) -> tuple[float, float]:
    lo, hi = np.inf, -np.inf
    for p in pieces():
        if len(p):
            lo, hi = min(lo, float(p.min())), max(hi, float(p.max()))
    return lo, hi


# values a bracket gathers at most (32 MB); more: its bins narrow it. The strided sample's
# bracket holds ~5 % of the values, so a log's static differences fit up to ~85 M samples in
# one pass (at 2^20 the 8-hour log's did not: a second pass for each median, diagnose 1.24x)
MOST_INSIDE = 1 << 22
BINS = 1 << 12         # the bins a bracket with more is counted in
MOST_PASSES = 64


class _Scan:
    """One pass over the values against the bracket [lo, hi]: how many lie below it and inside
    it, the least and most of those inside, those gathered while at most MOST_INSIDE, and, if
    *binned*, their counts in BINS equal bins of the bracket."""

    def __init__(self, lo: float, hi: float, binned: bool = False):
        self.lo, self.hi = lo, hi
        self.below = self.inside = 0
        self.gathered = []
        self.lowest, self.highest = np.inf, -np.inf
        finite = np.isfinite(lo) and np.isfinite(hi) and lo < hi
        self.edges = np.linspace(lo, hi, BINS + 1) if binned and finite else None
        self.counts = np.zeros(BINS, np.int64)

    def add(self, p: np.ndarray) -> None:
        self.below += int(np.count_nonzero(p < self.lo))
        sel = p[(p >= self.lo) & (p <= self.hi)]
        if len(sel) == 0:
            return
        self.inside += len(sel)
        self.lowest, self.highest = min(self.lowest, float(sel.min())), max(self.highest, float(sel.max()))
        if self.gathered is not None:
            if self.inside <= MOST_INSIDE:
                self.gathered.append(sel)
            else:
                self.gathered = None
        if self.edges is not None:
            b = np.searchsorted(self.edges, sel, side="right") - 1
            self.counts += np.bincount(np.minimum(b, BINS - 1), minlength=BINS)
