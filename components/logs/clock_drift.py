"""A sensor's clock drifting against the host's that stamps its samples.

A crystal's rate moves with its temperature: a few ppm at room temperature, tens of ppm in a
thermal chamber. The host's stamps of the sensor's samples then bow away from any one regular
grid, by milliseconds over an hour (a rate changing by 20 ppm over 36 minutes: 3.6 ms), and a
grid fitted through them misplaces the samples against the table's motion by as much (on a
26-position log, χ²/dof 130 instead of 0.98). What the stamps show beyond their jitter is the
sensor's time on the host's clock, the clock the table's angles are stamped on too; it is
followed here with a smooth correction of the grid: a quadratic spline of time (the clock's
rate continuous and piecewise linear, so a rate changing steadily is followed exactly), its
knots as far apart as the stamps ask for: the spacing of least Bayesian information criterion
among halvings of the log down to :data:`SHORTEST_KNOT_S`, against no correction at all, so that
a regular clock keeps its one grid (the criterion's ln N per coefficient is far beyond what
jitter alone gains).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SHORTEST_KNOT_S = 10.0   # s: a crystal's rate follows its temperature over minutes, not seconds
FEWEST_PER_KNOT = 200    # stamps per knot at least: the correction averages their jitter
# the uniform quadratic B-splines on a segment, in powers of the position v in it (0 <= v < 1):
# rows b_0 = (1 - v)^2 / 2, b_1 = 1/2 + v - v^2, b_2 = v^2 / 2; columns 1, v, v^2
_PIECE = np.array([[0.5, -1.0, 0.5], [0.5, 1.0, -1.0], [0.0, 0.0, 0.5]])


@dataclass
class ClockDrift:
    origin: float        # s: where the first segment starts
    spacing_s: float     # s: the segments' length
    coefficients: np.ndarray  # the quadratic B-splines' (segments + 2)
    bow_s: float = 0.0   # how far the samples' times bow away from one regular clock

    def at(self, u: np.ndarray) -> np.ndarray:
        """The correction [s] at the times *u* (s, on the stamps' axis)."""
        seg, v = self._where(u)
        powers = np.stack([np.ones_like(v), v, v * v])
        basis = _PIECE @ powers  # (3, n)
        c = self.coefficients
        return c[seg] * basis[0] + c[seg + 1] * basis[1] + c[seg + 2] * basis[2]

    def _where(self, u):
        x = (np.asarray(u, float) - self.origin) / self.spacing_s
        seg = np.clip(np.floor(x).astype(np.int64), 0, len(self.coefficients) - 3)
        return seg, x - seg

    @property
    def segments(self) -> int:
        return len(self.coefficients) - 2

    @property
    def rate_span_ppm(self) -> float:
        """How far the clock's rate moves over the log: the range of the correction's slope,
        which is linear between the knots."""
        return float(np.ptp(np.diff(self.coefficients))) / self.spacing_s * 1e6


def fit_drift(u: np.ndarray, residual: np.ndarray, interval: float) -> ClockDrift | None:
    """The smooth correction of *residual* (stamps minus their regular grid, s) over the stamps'
    times *u* (s, increasing), or None where no correction beats none on the criterion.
    *interval*: the sensor's, to keep FEWEST_PER_KNOT stamps to a knot."""
    n = len(u)
    span = float(u[-1] - u[0]) if n else 0.0
    shortest = max(SHORTEST_KNOT_S, FEWEST_PER_KNOT * interval)
    if n < 4 * FEWEST_PER_KNOT or span < 2 * shortest:
        return None
    finest = 2 ** int(math.floor(math.log2(span / shortest)))
    fine = _FineSums(u - u[0], residual, span, finest)
    total = float(np.dot(residual, residual))
    tiny = np.finfo(float).tiny
    best, best_bic = None, n * math.log(max(total, tiny) / n)
    segments = 1
    while segments <= finest:
        coefficients, rss = fine.fit(segments, total)
        bic = n * math.log(max(rss, tiny) / n) + (segments + 2) * math.log(n)
        if bic < best_bic:
            best, best_bic = (segments, coefficients), bic
        segments *= 2
    if best is None:
        return None
    segments, coefficients = best
    return ClockDrift(float(u[0]), span / segments, coefficients)


class _FineSums:
    """Per bin of the finest spacing: Σw^m (m = 0..4) and Σw^m r (m = 0..2), w the time from the
    bin's left edge. A coarser spacing's segments are unions of these bins, and its spline fit's
    normal equations follow from them exactly, without another pass over the stamps."""

    PIECE = 1 << 20  # stamps summed at a time: a few arrays of a piece, not of the log (8 h at 1 kHz)

    def __init__(self, u: np.ndarray, r: np.ndarray, span: float, bins: int):
        self.width = span / bins
        self.bins = bins
        self.w = np.zeros((5, bins))   # Σ w^m, m = 0..4
        self.wr = np.zeros((3, bins))  # Σ w^m r, m = 0..2
        for lo in range(0, len(u), self.PIECE):
            uu, rr = u[lo:lo + self.PIECE], r[lo:lo + self.PIECE]
            b = np.minimum((uu / self.width).astype(np.int64), bins - 1)
            w = uu - b * self.width
            p = np.ones_like(w)
            for m in range(5):
                self.w[m] += np.bincount(b, p, minlength=bins)
                if m < 3:
                    self.wr[m] += np.bincount(b, p * rr, minlength=bins)
                p *= w

    def fit(self, segments: int, total: float) -> tuple[np.ndarray, float]:
        """(the spline's segments + 2 coefficients, its residual sum of squares)."""
        per = self.bins // segments
        h = self.width * per
        seg = np.arange(self.bins) // per
        delta = (np.arange(self.bins) % per) * self.width  # each fine bin's edge in its segment
        # Σ v^m over a segment, v = (delta + w) / h: the binomial expansion of the fine sums
        moments = np.zeros((5, segments))
        for m in range(5):
            acc = sum(math.comb(m, j) * delta ** (m - j) * self.w[j] for j in range(m + 1)) / h**m
            moments[m] = np.bincount(seg, acc, minlength=segments)
        against = np.zeros((3, segments))
        for m in range(3):
            acc = sum(math.comb(m, j) * delta ** (m - j) * self.wr[j] for j in range(m + 1)) / h**m
            against[m] = np.bincount(seg, acc, minlength=segments)
        # per segment: Gram of its three B-splines and their products with r
        hankel = np.stack([np.stack([moments[i + j] for j in range(3)]) for i in range(3)])  # (3, 3, segs)
        gram = np.einsum("ai,ijs,bj->abs", _PIECE, hankel, _PIECE)
        rhs_seg = _PIECE @ against  # (3, segs)
        size = segments + 2
        bands = np.zeros((3, size))  # upper form for solveh_banded: row 2 the diagonal
        rhs = np.zeros(size)
        first = np.arange(segments)
        for a in range(3):
            np.add.at(rhs, first + a, rhs_seg[a])
            for b in range(a, 3):
                np.add.at(bands[2 - (b - a)], first + b, gram[a, b])
        # a coefficient with no stamp under it (a long gap) places none: a whisper of ridge holds it
        bands[2] += 1e-12 * max(float(bands[2].max()), 1.0)
        from scipy.linalg import solveh_banded

        coefficients = solveh_banded(bands, rhs)
        return coefficients, total - float(np.dot(coefficients, rhs))

