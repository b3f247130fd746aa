"""Observation blocks: sums of consecutive samples that the estimators fit instead of single
samples.

Why: per-sample gyro predictions during a move are dominated by encoder quantisation (the
interpolated angle is only exact at the logged counts), while the integral of the gimbal rate
between two rest samples is exact. So gyro rows are whole rest-to-rest moves plus static chunks;
accelerometer predictions depend only on the attitude, which the encoder gives to a count, so
accelerometer rows are short chunks everywhere. Static chunks keep time resolution for trends
(drift, temperature) and for locating residuals.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from components.estimation import order_statistics
from components.logs import spill
from components.logs.spill import gathered, is_spilled, pieces, release
from components.model.approach import moving_runs


@dataclass
class Blocks:
    """Index ranges [start, stop) of samples that are summed into one observation row."""

    start: np.ndarray
    stop: np.ndarray
    moving: np.ndarray  # bool per block
    whole_moves: bool = False  # a moving block is a whole rest-to-rest move (gyro rows)

    def __len__(self) -> int:
        return len(self.start)

    def sum(self, per_sample: np.ndarray) -> np.ndarray:
        """Block sums of a per-sample array (N, ...) -> (B, ...). Each block is summed from its
        own samples (not as a difference of running sums): a block's sum then does not depend on
        what precedes it in the array, so a chunk of the log gives the whole log's sums
        (components.estimation.chunks), and no sum loses digits to a running total (a table
        column is a difference of two such sums over a 1e-6 rad step)."""
        if is_spilled(per_sample) and len(self.start) and np.all(np.diff(self.start) >= 0) \
                and np.all(np.diff(self.stop) >= 0):
            return self._sum_in_pieces(per_sample)
        return block_sums(np.asarray(per_sample, float), self.start, self.stop)

    def _sum_in_pieces(self, per_sample) -> np.ndarray:
        # a spilled log (components.logs.spill): the blocks a piece of samples at a time, each
        # summed from its own samples as above, so the sums are the same bits
        out = np.empty((len(self.start),) + per_sample.shape[1:])
        first = 0
        while first < len(self.start):
            last = max(int(np.searchsorted(self.stop, self.start[first] + spill.PIECE, side="right")), first + 1)
            lo, hi = int(self.start[first]), int(max(self.stop[last - 1], self.start[first]))
            out[first:last] = block_sums(np.asarray(per_sample[lo:hi], float), self.start[first:last] - lo,
                                          self.stop[first:last] - lo)
            release(per_sample)
            first = last
        return out

    def subset(self, which: np.ndarray) -> "Blocks":
        """The blocks *which* (a mask or indices), in their order."""
        return Blocks(self.start[which], self.stop[which], self.moving[which], self.whole_moves)

    @property
    def count(self) -> np.ndarray:
        return self.stop - self.start


def block_sums(per_sample: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    """Σ per_sample[start:stop] per block (0 for an empty one), each from its own samples."""
    if len(start) == 0:
        return np.zeros((0,) + per_sample.shape[1:])
    padded = np.concatenate([per_sample, np.zeros((1,) + per_sample.shape[1:])])
    edges = np.empty(2 * len(start), int)
    edges[0::2], edges[1::2] = start, stop
    out = np.add.reduceat(padded, edges, axis=0)[0::2]
    out[stop <= start] = 0.0
    return out


def _chunks(a: int, b: int, n: int) -> list[tuple[int, int]]:
    k = max(1, int(np.ceil((b - a) / n)))
    edges = np.linspace(a, b, k + 1).round().astype(int)
    return list(zip(edges[:-1], edges[1:]))


def observation_blocks(static: np.ndarray, angles: np.ndarray,
                       samples_per_chunk: int, valid: np.ndarray | None = None) -> tuple[Blocks, Blocks]:
    """(gyro blocks, accelerometer blocks) of a log. A log whose table already moves at its first
    sample (a window cut out of a schedule) has neither the angle at the start of that sample's
    interval nor the rate at its first angle: the interpolation takes the table at rest there,
    which is wrong through the whole first move (at 10 cm off the centre, a block residual of
    1.6e-3 m/s that pulled the time offset by 9 us). That move is left out, and any move after
    it before the first rest as long as a block (a settling that pauses and creeps on).

    ``valid`` (N,) bool: samples left out (a gap, a mask, an exclusion) leave every block: a
    static chunk or an accelerometer chunk keeps its usable stretches, a rest-to-rest gyro move
    with a left-out sample is dropped (its integral is no longer the rotation between the rests)."""
    first = 0
    if len(angles) > 1 and np.any(angles[1] != angles[0]):
        runs = moving_runs(static)
        first = runs[0][1] if runs and runs[0][0] <= 1 else 1
        # a table settling at the start can pause within a count and creep on (an encoder error
        # at the start angle: 0.25 s still, then two more counts): the log is known from its
        # first rest as long as a block, not from its first pause
        for a, b in runs[1:]:
            if a - first >= samples_per_chunk:
                break
            first = b
    gb = make_blocks(static, samples_per_chunk, whole_moves=True, start=first)
    ab = make_blocks(static, samples_per_chunk, whole_moves=False, start=first, cut_cost=_JerkNear(angles))
    if valid is None or np.all(valid):
        return gb, ab
    return restrict(gb, valid), restrict(ab, valid)


def restrict(blocks: Blocks, valid: np.ndarray) -> Blocks:
    """*blocks* without the samples that are not *valid*: a moving block of whole moves (gyro) is
    dropped, any other block keeps its stretches of valid samples."""
    c = np.concatenate([[0], np.cumsum(~np.asarray(valid, bool))])
    starts, stops, moving = [], [], []
    for a, b, mv in zip(blocks.start, blocks.stop, blocks.moving):
        if c[b] == c[a]:
            starts.append(a)
            stops.append(b)
            moving.append(mv)
            continue
        if mv and blocks.whole_moves:
            continue
        m = np.concatenate([[False], valid[a:b], [False]]).astype(np.int8)
        d = np.diff(m)
        for s, e in zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0]):
            starts.append(a + int(s))
            stops.append(a + int(e))
            moving.append(mv)
    return Blocks(np.array(starts, int), np.array(stops, int), np.array(moving, bool), blocks.whole_moves)


class _JerkNear:
    """:func:`_jerk_near_of` of a log's angles, computed where it is asked for (the block
    boundaries tried inside moves; the whole log's was an (N+1,) array, 8 bytes a sample, and a
    pass over every angle), from the angles around them with a margin of 8 samples either side:
    the same bits as the whole log's."""

    def __init__(self, angles: np.ndarray):
        self.angles = angles

    def __len__(self) -> int:
        return len(self.angles) + 1

    def __getitem__(self, k):
        """At the boundaries *k* (an int or an array of them)."""
        k = np.asarray(k)
        if k.size == 0:
            return np.zeros(k.shape)
        ka, kb = int(k.min()), int(k.max()) + 1
        lo, hi = max(ka - 8, 0), min(kb + 8, len(self.angles))
        near = _jerk_near_of(self.angles[lo:hi])[k - lo]
        release(self.angles)  # a spilled log's: each read maps a large stretch of the file
        return near


def _jerk_near_of(angles: np.ndarray) -> np.ndarray:
    """(N+1,) per block boundary k (the time of angle k-1): the largest third difference of the
    angles within three samples, i.e. how close the table's angular acceleration jumps. A block
    boundary inside a move needs the rate and angular acceleration there (the lever-arm and
    time-offset terms), which the spline through the angles gets worst next to a jump (the
    servo switching from accelerating to braking at the peak of a fast index: 1e-4 m/s block
    residuals 10 cm off the centre)."""
    a = np.atleast_2d(np.asarray(angles, float))
    n = len(a)
    d3 = np.zeros(n)
    if n >= 4:
        # an axis at a time and in place: the whole log's differences of every axis at once were
        # ~100 bytes a sample
        t, u = np.empty(n - 3), np.empty(n - 3)
        for j in range(a.shape[1]):
            c = a[:, j]
            # ((a3 − 3 a2) + 3 a1) − a0, in that order: the same bits as the expression written out
            np.multiply(c[2:-1], 3.0, out=t)
            np.subtract(c[3:], t, out=t)
            np.multiply(c[1:-2], 3.0, out=u)
            t += u
            t -= c[:-3]
            np.abs(t, out=t)
            d3[2:n - 1] += t
    # near[k] = the largest d3 over samples k-4 ... k+2 (clipped to the log)
    padded = np.concatenate([np.full(4, d3[0] if n else 0.0), d3, np.full(3, d3[-1] if n else 0.0)])
    near = padded[: n + 1].copy()
    for s in range(1, 7):
        np.maximum(near, padded[s:s + n + 1], out=near)
    return near


def _moving_chunks(a: int, b: int, n: int, cut_cost: np.ndarray | None) -> list[tuple[int, int]]:
    """A move in chunks of about *n* samples, each inner boundary moved (by up to n/2) to where
    *cut_cost* is lowest, the nearest such place to the even split."""
    even = _chunks(a, b, n)
    if cut_cost is None or len(even) < 2:
        return even
    edges = [a]
    for _, e in even[:-1]:
        lo, hi = max(edges[-1] + 1, e - n // 2), min(b - 1, e + n // 2)
        if hi < lo:
            continue
        k = np.arange(lo, hi + 1)
        c = cut_cost[k]
        span = float(c.max() - c.min())
        score = (c - c.min()) / span if span > 0 else np.zeros(len(k))
        edges.append(int(k[np.argmin(score + 1e-3 * np.abs(k - e) / n)]))
    edges.append(b)
    return list(zip(edges[:-1], edges[1:]))


def make_blocks(static: np.ndarray, samples_per_chunk: int, whole_moves: bool,
                start: int = 0, cut_cost: np.ndarray | None = None) -> Blocks:
    """Static runs in chunks of at most *samples_per_chunk*; moving runs whole (gyro) or in
    chunks too (accelerometers, cut where *cut_cost* (N+1,) per boundary is low); samples
    before *start* left out."""
    n = len(static)
    runs = [(max(a, start), b) for a, b in moving_runs(static) if b > start]
    spans: list[tuple[int, int, bool]] = []
    pos = start
    for a, b in runs:
        spans += [(s, e, False) for s, e in _chunks(pos, a, samples_per_chunk)] if a > pos else []
        spans += [(a, b, True)] if whole_moves else [
            (s, e, True) for s, e in _moving_chunks(a, b, samples_per_chunk, cut_cost)]
        pos = b
    if pos < n:
        spans += [(s, e, False) for s, e in _chunks(pos, n, samples_per_chunk)]
    arr = np.array(spans, dtype=object) if spans else np.zeros((0, 3), dtype=object)
    return Blocks(arr[:, 0].astype(int), arr[:, 1].astype(int), arr[:, 2].astype(bool), whole_moves)


def samples_per_block(dt: float, block_s: float) -> int:
    """Samples in a static block of *block_s* seconds at the sample interval *dt* (the log's
    median, LogData.sample_interval; NaN for a log of one sample), at least 1."""
    if not (np.isfinite(dt) and dt > 0):
        return 1
    return max(1, int(round(block_s / dt)))


def _pairs_at_rest(static: np.ndarray, s: slice) -> np.ndarray:
    """Of the pairs (k, k+1) for k in *s*, which have both samples static: made a piece at a
    time (the whole log's was a byte a sample beside the mask)."""
    return static[s.start + 1:s.stop + 1] & static[s.start:s.stop]


def _static_differences(x: np.ndarray, static: np.ndarray, centre: float | None = None):
    """The differences x[k+1] - x[k] of the pairs within static runs, a piece at a time; with
    *centre*, their absolute deviations from it."""
    for s in pieces(len(static) - 1, x, static):
        v = np.diff(x[s.start:s.stop + 1])[_pairs_at_rest(static, s)]
        yield v if centre is None else np.abs(v - centre)


def white_noise_sigma(increments: np.ndarray, static: np.ndarray, floor=None) -> np.ndarray:
    """Per-sample white-noise σ of each channel from static data: consecutive differences within
    static runs remove any constant (bias, gravity, Earth rate), var(x_k - x_{k-1}) = 2 σ².
    Returns (channels,). Falls back to NaN where there is no static pair. ``floor`` (channels,):
    the least σ a channel has whatever its scatter (a pulse output's quantization,
    LogData.quantization_floor: counts whose differences are mostly 0 collapse the scatter)."""
    pairs = max(len(static) - 1, 0)
    # a robust scale (median absolute deviation) so that a few steps at a run edge do not count;
    # a channel at a time and a piece at a time: a long log's differences are never made whole
    # (240 MB a channel on an 8-hour log), only those near their medians are kept
    m = sum(int(np.count_nonzero(_pairs_at_rest(static, s))) for s in pieces(pairs, static))
    if m < 2:
        return np.full(increments.shape[1], np.nan)
    # the bracketing sample: the differences at every stride-th static pair
    step, at, seen = order_statistics.stride(m), [], 0
    for s in pieces(pairs, static):
        idx = np.flatnonzero(_pairs_at_rest(static, s))
        at.append(idx[(-seen) % step::step] + s.start)
        seen += len(idx)
    at = np.concatenate(at)
    mad = np.empty(increments.shape[1])
    for k in range(increments.shape[1]):
        sample = gathered(increments[:, k], at + 1) - gathered(increments[:, k], at)
        med = order_statistics.median_of_pieces(partial(_static_differences, increments[:, k], static), m, sample)
        mad[k] = order_statistics.median_of_pieces(partial(_static_differences, increments[:, k], static, med), m,
                                                   np.abs(sample - med))
    sigma = 1.4826 * mad / np.sqrt(2)
    return sigma if floor is None else np.maximum(sigma, floor)
