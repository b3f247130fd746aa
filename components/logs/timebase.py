"""A logger's clock in the files users bring: stamps with jitter and gaps.

A sensor that samples on its own clock, time-stamped by a host, has regular samples and
irregular stamps. ``regularise`` fits t_k = t_0 + k Δ by least squares over each run between
gaps (an interval above ``max_interval``) and replaces the stamps; the fitted rate and the
stamps' RMS deviation are reported. Where the stamps bow away from that grid (a sensor's clock
drifting against the host's), a smooth correction follows them (components.logs.clock_drift).
A table recorded on another clock: components.logs.table_clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from components.logs.clock_drift import ClockDrift, fit_drift


@dataclass
class Regularised:
    time: np.ndarray
    rate_hz: float           # the one interval of every run's grid, fitted on every stamp
    jitter_rms_s: float      # RMS of the stamps about the fitted grid
    runs: int
    drift: ClockDrift | None = None  # the smooth correction of a clock drifting against the host's
    sensor_time: np.ndarray | None = None  # the regular grid, the sensor's own clock (without a drift: time)

    def __post_init__(self):
        if self.sensor_time is None:
            self.sensor_time = self.time


def unrolled(t: np.ndarray, period: float | None) -> tuple[np.ndarray, int]:
    """(the stamps *t* of a counter that rolls over every *period* counted on, the rollovers): a
    step back by more than half the period is one (a clock's jitter or a late stamp is not)."""
    if period is None or len(t) < 2:
        return t, 0
    back = np.diff(t) < -period / 2
    if not back.any():
        return t, 0
    return t + period * np.concatenate([[0.0], np.cumsum(back)]), int(np.count_nonzero(back))


def stamp_resolution(t: np.ndarray, nominal: float | None = None) -> float:
    """The resolution of a clock coarser than the samples it stamps (Windows' tick, a host's
    millisecond): the median of the intervals that advance, each a tick or a few, where two stamps
    are alike or (given the *nominal* interval) where that median is shorter than the samples'
    interval by a tenth (a tick near the interval steps by one tick or two without repeating:
    50 Hz on a 15.625 ms tick); else 0."""
    d = np.diff(t)
    moved = d[d > 0]
    if not len(moved):
        return 0.0
    step = float(np.median(moved))
    if np.any(d == 0) or (nominal is not None and step < 0.9 * nominal):
        return step
    return 0.0


def gaps(t: np.ndarray, max_interval: float) -> np.ndarray:
    """(N,) bool: the sample's interval from the one before exceeds *max_interval*."""
    out = np.zeros(len(t), bool)
    out[1:] = np.diff(t) > max_interval
    return out


def index_gaps(index: np.ndarray) -> np.ndarray:
    """(N,) bool: the sample's index on the sensor's clock (a sample counter's) skips samples
    before it."""
    return np.diff(index, prepend=index[0]) > 1


def regularise(t: np.ndarray, nominal_dt: float, max_interval: float, index: np.ndarray | None = None) -> Regularised:
    """Stamps replaced by a regular grid (:func:`_regular`) and, where they bow away from it by more
    than their jitter, a smooth correction of it (components.logs.clock_drift): the grid is
    fitted again to the stamps less the correction, and the correction to what the new grid
    leaves, until no further correction beats none (at most four rounds; one grid joins the
    runs through lost samples only once the bow no longer hides their whole intervals).
    *index*: each sample's index on the sensor's clock, read from its sample counter; the grid is
    then one line through the stamps at those indices (no gap guessed from the stamps)."""
    cut = np.nonzero(gaps(t, max_interval) if index is None else index_gaps(index))[0]
    edges = np.concatenate([[0], cut, [len(t)]])
    reg, residual = _regular(t, nominal_dt, edges, index)
    u = t - float(t[0])
    drift = fit_drift(u, residual, nominal_dt)
    if drift is None:
        return reg
    first = drift
    correction = np.zeros(len(t))
    for _ in range(4):
        correction += drift.at(u)
        reg, residual = _regular(t - correction, nominal_dt, edges, index)
        drift = fit_drift(u, residual, nominal_dt)
        if drift is None:
            break
    rms = math.sqrt(float(np.mean((t - correction - reg.time) ** 2)))
    # as said to the user: the rate as the first round found it (the rounds after refine it by
    # little), and how far the samples bow away from one regular clock (the correction less its line)
    bow = float(np.max(np.abs(_off_line(u, correction))))
    said = ClockDrift(first.origin, first.spacing_s, first.coefficients, bow)
    return Regularised(reg.time + correction, reg.rate_hz, rms, reg.runs, said, reg.time)


def _regular(t: np.ndarray, nominal_dt: float, edges: np.ndarray,
             index: np.ndarray | None = None) -> tuple[Regularised, np.ndarray]:
    """(the stamps *t* replaced by a regular grid in each run between the *edges* of the gaps, the
    stamps' residual against one grid through the runs where one was tried, else against the
    result). One interval for the whole log
    (the sensor's own clock), by least squares on every stamp, and one grid for the runs whose
    starts lie a whole number of intervals apart within their stamps' scatter (samples lost
    between them; a sensor restarted out of phase starts a grid of its own).

    One interval, not one per run: a short run's own fit is mostly its stamps' jitter (3 samples
    under ±0.3 ms gave 5.161 ms for 5 ms), and the log's increments are then set against the
    motion over intervals 3 % too long (an accelerometer at rest 1.6e-3 m/s off in each such
    sample: on a count log with 0.2 % of its packets lost, χ²/dof 20.7 instead of 1.0). One grid
    through the lost samples: a run of 100 samples places itself to jitter/10 alone (17 us under
    ±0.3 ms), which a move's motion turns into misfit (χ²/dof 1.14 for 0.99 with 1 % lost). The
    grids are kept only where they fit the stamps as well as each run's own start, up to what
    fewer starts cost by chance (not so a clock that drifts against the host's)."""
    t0 = float(t[0])
    u = t - t0  # from the first stamp: the sums of k·t of epoch stamps would lose their digits
    runs = len(edges) - 1
    if index is not None:
        # the counter gives every sample's place on the sensor's clock: one line through them all
        k = np.asarray(index, float)
        d, start = _line(tuple(np.atleast_1d(np.sum(w)) for w in (np.ones(len(k)), k, k * k, u, k * u)), nominal_dt)
        out = start[0] + d * k
        return Regularised(t0 + out, 1.0 / d, math.sqrt(float(np.mean((u - out) ** 2))), runs), u - out
    run = np.repeat(np.arange(len(edges) - 1), np.diff(edges))
    k = np.arange(len(t), dtype=float) - edges[:-1][run]  # index within the run
    sums = tuple(np.bincount(run, w) for w in (None, k, k * k, u, k * u))
    d, start = _line(sums, nominal_dt)
    out = start[run] + d * k
    rms = math.sqrt(float(np.mean((u - out) ** 2)))
    if runs > 1:
        grid, offset = _grids(sums, start, d, rms)
        d1, grid_start = _line(tuple(np.bincount(grid, w) for w in _shifted(sums, offset)), nominal_dt)
        one = grid_start[grid[run]] + d1 * (k + offset[run])
        rms1 = math.sqrt(float(np.mean((u - one) ** 2)))
        # what fewer starts cost the fit by chance alone (their share of the stamps, and four σ
        # of a mean square of N): more is a clock drifting against the host's, whose runs
        # placed by their own starts follow it (5 ppm over 8 hours: 55 us RMS off on one grid,
        # 11 us on the runs' own starts)
        grids = int(grid.max()) + 1
        if rms1**2 <= rms**2 * (1 + (runs - grids) / len(t) + 4 * math.sqrt(2 / len(t))):
            return Regularised(t0 + one, 1.0 / d1, rms1, runs), u - one
        # the bow a drifting clock leaves in the stamps shows against one line through every run,
        # not against the runs' own starts, which follow it; the runs' whole intervals apart
        # counted from each one's start to the next (the grids' joins, drawn from lines through
        # the stamps before, miss by the bow's slope)
        index = k + np.concatenate([[0], np.cumsum(np.round(np.diff(start) / d))])[run]
        return Regularised(t0 + out, 1.0 / d, rms, runs), _off_line(index, u)
    return Regularised(t0 + out, 1.0 / d, rms, runs), u - out


def _off_line(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """y less its least-squares line in x."""
    xc = x - x.mean()
    yc = y - y.mean()
    return yc - xc * (float(np.dot(xc, yc)) / float(np.dot(xc, xc)))


def _shifted(sums, o):
    """The sums (n, Σk, Σk², Σt, Σkt) of a run's samples with their index k moved on by *o*."""
    n, s_k, s_kk, s_t, s_kt = sums
    return n, s_k + n * o, s_kk + 2 * o * s_k + n * o * o, s_t, s_kt + o * s_t


def _line(sums, nominal_dt: float):
    """(d, start of each group): the least-squares t ≈ start + d k, one interval d for every
    group, from the groups' sums (n, Σk, Σk², Σt, Σkt)."""
    n, s_k, s_kk, s_t, s_kt = sums
    spread = float(np.sum(s_kk - s_k * s_k / n))
    # groups of one sample carry no interval; a log of such keeps the nominal one
    d = float(np.sum(s_kt - s_k * s_t / n)) / spread if spread > 0 else nominal_dt
    return d, (s_t - d * s_k) / n


GRID_MEMORY_S = 60.0  # s: how far back the stamps predict where the next run starts


def _grids(sums, start: np.ndarray, d: float, rms: float):
    """(grid of each run, its first sample's index on that grid) from the runs' sums
    (n, Σk, Σk², Σt, Σkt) and their starts on the common interval *d*: a run joins the grid before it where its start lies a whole number of
    intervals on, within five times the scatter of the run's start and the grid's prediction
    there (the stamps' RMS over √samples). The grid is the line through every stamp on it so
    far; its slope the runs' common interval *d* until the grid's own spans more (far ahead,
    d's error was half an interval 200,000 samples on)."""
    n, s_k, s_kk, s_t, s_kt = sums
    spread_runs = float(np.sum(s_kk - s_k**2 / n))
    grid, offset = np.zeros(len(n), int), np.zeros(len(n))
    memory = GRID_MEMORY_S / d  # samples
    on = None  # the sums of the grid being built
    for r in range(len(n)):
        if on is not None:
            # the stamps long before weigh less in the prediction: a clock drifting against the
            # host's bows the stamps away from any one line by milliseconds over an hour, which a
            # line through all of them would carry to the next run's start
            fade = math.exp(-(start[r] - start[r - 1]) / d / memory)
            on = tuple(x * fade for x in on)
            sn, sx, sxx, st, sxt = on
            sxx_c = sxx - sx * sx / sn
            # the grid's own slope once it spans a good part of its memory (the local rate of a
            # drifting clock, ppm off the log's mean rate over seconds back), else the runs'
            # common interval (a short grid's own slope carried far ahead misses by intervals)
            own = sxx_c > spread_runs or sxx_c > sn * (0.1 * memory) ** 2
            b = (sxt - sx * st / sn) / sxx_c if own else d
            a = (st - b * sx) / sn
            m = (start[r] - a) / b
            # the prediction's scatter at m: the line's, from its sums
            var = rms**2 * (1 / sn + (m - sx / sn) ** 2 / (sxx_c if own else spread_runs)) / (d * d)
            if abs(m - round(m)) <= 5 * math.sqrt(var + rms**2 / n[r] / (d * d)):
                offset[r], grid[r] = round(m), grid[r - 1]
                on = tuple(p + q for p, q in zip(on, _shifted([x[r] for x in sums], offset[r])))
                continue
            grid[r] = grid[r - 1] + 1
        on = tuple(x[r] for x in sums)
    return grid, offset
