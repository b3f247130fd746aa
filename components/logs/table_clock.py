"""A table recorded on another clock: the offset and the rate between the clocks, the curve of a
rate that changes, and the table's angles at the IMU's times.

- **Two clocks.** The table's time plus an offset is the IMU's. The offset is estimated by
  matching how far the plate turns with how far the gyros say it turned (the same motion,
  whatever the axes' mapping; the gyros' errors scale it by parts per thousand at most): a coarse
  shift from the cross-correlation of the two rate magnitudes (each IMU sample's rate at its
  interval's middle), refined by Gauss–Newton on, per table interval while the table's rate
  changes (at a constant rate every shift turns the same), the gyros' turn over it (their running
  sum, a cubic through the ends of the IMU's intervals, at the readings' times shifted by δ) minus
  the plate's turn between the readings as they are — the encoder's counts are not smooth, the
  gyros' running sum is, so it is what is interpolated. The step's slope in δ is taken from the
  gyros' mean rates just outside the nodes each residual uses (an instrumental variable): the
  residual's own slope carries the counts' rounding, whose interpolated size depends on where
  between the IMU's samples δ puts the readings, and a least squares then follows that rather
  than the motion (pulses of 2″: a false curve of 8 ms on the foreign rig).
  σ from that fit's residual and slopes, and at least half the difference of the offsets
  fitted on the first and the second half (model error: both halves are reported). Two
  crystals also run at rates ppm apart: the rate between the clocks comes from a line through
  the offsets of stretches of the record, kept where it is significant against their scatter;
  a rate that changes (a crystal warming) bends the offset into a curve (components.logs.clock_curve).
- **Merging.** The table angles at the IMU's sample times by monotone cubic interpolation
  (PCHIP): between two equal readings (a rest) the angle stays exactly that reading, so rests
  keep their encoder values; during moves the interpolant follows the motion.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from components.errors import MappingError
from components.logs.clock_curve import ClockCurve, curved, legendre_tail


@dataclass
class ClockOffset:
    offset_s: float          # table time + offset = IMU time, at the table record's first sample
    sigma_s: float
    first_half_s: float      # the offset on each half of the overlap, at that half's middle, with
    second_half_s: float     # the rate below: what they differ by is what the line misses
    correlation: float       # of the gyros' and the table's turns over its moving intervals, at the offset
    rate: float = 0.0        # the IMU's clock gains rate · (table time since its first sample)
    rate_sigma: float = 0.0
    # the offsets of the record's equal stretches about the line alone (at their centres on the
    # IMU's clock, their variances), what a curve in the offset shows in (None: too few move)
    stretches: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    curve: ClockCurve | None = None  # the offset beyond its line, where the clocks' rate changes
    # what the rate and the curve add to the σ at the table's first sample beyond the σ at the
    # line's centre (where the moves are): a shift of the whole record known better leaves it
    beyond_centre_s: float = 0.0


def table_to_imu(tt: np.ndarray, offset: float, rate: float = 0.0, curve: ClockCurve | None = None) -> np.ndarray:
    """The table's times *tt* on the IMU's clock: an offset at its first sample, a clock gaining
    *rate* seconds per second of the table's (two crystals: tens of ppm apart), and where that
    rate changes the *curve* beyond the line (on the IMU's clock: taken at the line's times, ppm
    of a millisecond off)."""
    ti = tt + offset + rate * (tt - tt[0])
    return ti if curve is None else ti + curve(ti)


def rate_magnitude_from_angles(t: np.ndarray, angles: np.ndarray, axis_vectors: np.ndarray) -> np.ndarray:
    """|plate rate| [rad/s] at *t* from the gimbal angles (N, n_axes): ω = Σ_k R_1..R_{k-1} a_k θ̇_k
    in the plate frame has the norm of that sum in the base frame."""
    from components.model.geometry import rodrigues

    th = np.asarray(angles, float)
    rates = np.gradient(th, t, axis=0)
    w = np.zeros((len(t), 3))
    R = np.broadcast_to(np.eye(3), (len(t), 3, 3)).copy()
    for k, a in enumerate(np.asarray(axis_vectors, float)):
        w += np.einsum("nij,j->ni", R, a) * rates[:, k:k + 1]
        R = R @ rodrigues(a, th[:, k])
    return np.linalg.norm(w, axis=1)


def _plate(angles: np.ndarray, axis_vectors: np.ndarray) -> np.ndarray:
    """(N, 3, 3) plate attitudes in the base frame from gimbal angles (N, n_axes)."""
    from components.model.geometry import rodrigues

    R = np.broadcast_to(np.eye(3), (len(angles), 3, 3)).copy()
    for k, a in enumerate(np.asarray(axis_vectors, float)):
        R = R @ rodrigues(a, angles[:, k])
    return R


def _turn_angle(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Angle [rad] of the rotation from attitudes Ra to Rb (small: from the skew part)."""
    rel = np.einsum("nji,njk->nik", Ra, Rb)
    v = 0.5 * np.stack([rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0], rel[:, 1, 0] - rel[:, 0, 1]], 1)
    return np.arcsin(np.clip(np.linalg.norm(v, axis=1), 0.0, 1.0))


# a rate between the clocks is kept where it stands this many of its σ from none
RATE_SIGNIFICANT = 5.0


def estimate_clock_offset(t_imu: np.ndarray, dt_imu: np.ndarray, gyro_inc: np.ndarray, t_tab: np.ndarray,
                          angles: np.ndarray, axis_vectors: np.ndarray,
                          max_offset: float | None = None, use: np.ndarray | None = None) -> ClockOffset:
    """The offset δ (table time + δ = IMU time) and the rate between the clocks, from the IMU's gyro
    increments (N, 3) over the intervals (t − dt, t] and the table's angles (M, n_axes) at
    *t_tab*. *use* (N,) bool: the samples whose increment is known to cover (t − dt, t] (not the
    sample after a gap: a lost packet's counts are lost with it, or summed into the next, and the
    log leaves that sample out).

    Two crystals run tens of ppm apart: 20 ppm over 36 minutes is 43 ms, which one offset set
    against the table's motion leaves as misfit (χ²/dof 10,000 on a 26-position log). The rate
    comes from a line through the offsets of stretches of the record (:func:`_rate_from_windows`),
    refined with the offset on every moving table interval, and is kept where it stands
    RATE_SIGNIFICANT of its σ from none."""
    w_imu = np.linalg.norm(gyro_inc, axis=1) / dt_imu
    t_mid = t_imu - dt_imu / 2
    w_tab = rate_magnitude_from_angles(t_tab, angles, axis_vectors)
    dt_med = float(np.median(dt_imu))
    delta = _coarse(t_mid, w_imu, t_tab, w_tab, dt_med, max_offset)
    # The residual is taken over the table's intervals, between its readings as they are: the
    # gyros' turn there, from their running sum interpolated at the readings' times on the IMU's
    # clock, less the plate's turn between the readings. Interpolated the other way (the table's
    # angles at the IMU's interval ends), an encoder's counts put more of their noise into the
    # turn where the ends meet readings than between them: with a table read at the IMU's rate
    # the least squares then preferred the offsets half a sample off the readings (the
    # conformance log at 1.2" counts: 0.8 ms off, and a false curve of 1,400 ppm); the gyros'
    # running sum carries white noise a thousand times smaller.
    # from each reading to the k-th after it, at least an IMU interval apart (a table read faster
    # than the IMU: every reading still starts one)
    k = max(1, math.ceil(dt_med / float(np.median(np.diff(t_tab))) - 1e-6))
    plate = _plate(angles, axis_vectors)
    ends_a, ends_b = t_tab[:-k], t_tab[k:]
    turn_tab = _turn_angle(plate[:-k], plate[k:])
    # the intervals that tell the shift: turning faster than ~1 deg/s, and its rate changing (at a
    # constant rate every shift turns the same; there the turns' residual is only the counts'
    # rounding, which at a constant rate repeats in a pattern: on a ring-laser gyro's counts a
    # rotation test's four minutes pulled the offset by 1.5 ms)
    moving = (turn_tab > 0.02 * (ends_b - ends_a)) & _changing_rate(t_tab, plate, k)
    t_node = np.concatenate([[t_imu[0] - dt_imu[0]], t_imu])  # the ends of the IMU's intervals
    # the gyros' running sum is smooth (its slope the rate): a cubic through the four ends of
    # their intervals around each time asked, where a line between two misses by α dt²/8 wherever
    # the table accelerates (the offset's evidence: with a 1 kHz table the bow a drifting host
    # leaves was followed 0.68 of the way, not 1); local, so that nothing the size of the log is
    # built beside the sum (a spline's coefficients: 96 bytes an IMU sample)
    running = np.vstack([np.zeros((1, 3)), np.cumsum(gyro_inc, axis=0)])
    # the IMU's intervals up to each end that do not cover it (the sample after a gap: a lost
    # packet's counts are lost with it, or summed into the next): a table interval over one is left
    # out (a count log with 0.2 % of its packets lost: the offset 0.55 ms off, 3.7 of its σ, before)
    lost = np.concatenate([[0], np.cumsum(~use)]) if use is not None else None
    # each table interval's time on the IMU's clock at the coarse offset (the line's time factors)
    t_res = 0.5 * (ends_a + ends_b) + delta
    t_ref = float(np.mean(t_res[moving])) if moving.any() else float(t_res[0])  # IMU time, the line's centre

    scale = max(float(t_imu[-1] - t_imu[0]) / 2, 1.0)  # the curve's time axis: x = (t - t_ref) / scale
    held = ()  # the curve's coefficients, held where a stretch's or a half's offset is fitted

    def tail(t, line):
        return (legendre_tail((t - t_ref) / scale, len(line) - 2) @ np.asarray(line[2:])).reshape(np.shape(t))

    def on_imu(tau, line):
        # the table's times *tau* on the IMU's clock for the line (δ at t_ref, rate) and the curve
        # beyond it (coefficients of the Legendre polynomials P_2(x), P_3(x), ...): the IMU's time t
        # reads tau = t - δ - rate (t - t_ref) - curve(t) on the table's clock, solved for t by
        # rounds (the rate and the curve's slope are parts per million: each round gains six digits)
        t = tau + line[0]
        for _ in range(3):
            t = tau + line[0] + line[1] * (t - t_ref) + (tail(t, line) if len(line) > 2 else 0.0)
        return t

    def gyro_turn(line, sel):
        ta, tb = on_imu(ends_a[sel], line), on_imu(ends_b[sel], line)
        return np.linalg.norm(_cubic_at(t_node, running, tb) - _cubic_at(t_node, running, ta), axis=1)

    def residual(line, sel):
        return gyro_turn(line, sel) - turn_tab[sel]

    def rate_change(line, sel):
        # the residual's slope in the shift, from nodes the residual does not use (the instrument,
        # _refine): the gyros' turn direction times their mean rate over INSTRUMENT_NODES intervals
        # just after the later end's interpolation stencil less that just before the earlier's.
        # A running sum's difference holds the rounding of its two ends only, so this one shares
        # none with the residual's (a pulse count's, or white noise's summed increments)
        ta, tb = on_imu(ends_a[sel], line), on_imu(ends_b[sel], line)
        last = len(t_node) - 1
        first_a = np.clip(np.searchsorted(t_node, ta) - 2, 0, last - 3)  # _cubic_at's stencils
        first_b = np.clip(np.searchsorted(t_node, tb) - 2, 0, last - 3)
        before = np.maximum(first_a - 1 - INSTRUMENT_NODES, 0), np.maximum(first_a - 1, 0)
        after = np.minimum(first_b + 4, last), np.minimum(first_b + 4 + INSTRUMENT_NODES, last)

        def mean_rate(lo, hi):
            span = t_node[hi] - t_node[lo]
            return np.where((span > 0)[:, None], running[hi] - running[lo], 0.0) / np.where(span > 0, span, 1.0)[:, None]

        turned = running[after[1]] - running[before[0]]  # (its direction: the turn's axis)
        norm = np.linalg.norm(turned, axis=1, keepdims=True)
        axis = np.where(norm > 0, turned / np.where(norm > 0, norm, 1.0), 0.0)
        return np.sum(axis * (mean_rate(*after) - mean_rate(*before)), axis=1)

    def inside(line, sel):
        ta, tb = on_imu(ends_a, line), on_imu(ends_b, line)
        ok = sel & (ta >= t_node[0]) & (tb <= t_node[-1])
        if lost is not None:
            # IMU intervals ending after ta and starting before tb
            first = np.searchsorted(t_imu, ta, side="right")
            last = np.searchsorted(t_imu - dt_imu, tb, side="left")
            ok &= lost[np.maximum(last, first)] == lost[first]
        return ok

    def refine(sel, line, rate=None, with_rss=False):
        return _refine(residual, inside, t_res, sel, line, t_ref, rate, held=held, scale=scale, with_rss=with_rss,
                       instrument=rate_change)

    line, cov = refine(moving, np.array([delta]))
    rated, stretches = _rate_from_windows(refine, t_res, moving, float(line[0]), t_ref)
    if rated is not None:
        # the line through the windows' offsets, refined on every moving interval; its σ at least
        # what the windows' scatter about it says (the gyros' interpolation errs with each move's profile)
        line, cov, rss, _ = refine(moving, rated[0], with_rss=True)
        cov[np.diag_indices(2)] = np.maximum(np.diag(cov), rated[1])
        start = line
    else:
        # the baseline the curve's terms are tested against: the line with its rate free
        start, _, rss, _ = refine(moving, np.array([line[0], 0.0]), with_rss=True)
    # the clocks' rate changing over the record (a crystal warming): the offset a polynomial in
    # time, its terms beyond the line fitted with it on every moving interval while significant
    bent, bent_cov, curve = curved(lambda sel, x: refine(sel, x, with_rss=True), moving, start, rss, t_ref, scale,
                                   math.sqrt(cov[0, 0]), stretches)
    # the offset is said at the table's first sample, often at rest before the first move and far
    # from the line's centre: its σ there from every coefficient's, the rate's and the curve's
    # (they extrapolate from where the moves show them; a rate of 0.001 ppm known to 0.001 ppm
    # is 1 us at the start of a 36-minute record, which the centre's σ alone left out)
    since = float(t_tab[0]) + float(line[0]) - t_ref
    if curve is not None:
        line, cov, held = bent[:2], bent_cov[:2, :2], tuple(curve.coefficients)
        g = np.concatenate([[1.0, since], legendre_tail(since / scale, len(held))[0]])
        at_edge = float(g @ bent_cov @ g)
    else:
        g = np.array([1.0, since])[:len(line)]
        at_edge = float(g @ cov[:len(line), :len(line)] @ g)
    d0, rate = float(line[0]), float(line[1]) if len(line) > 1 else 0.0
    full_line = (d0, rate, *held)
    half = t_res[0] + 0.5 * (t_res[-1] - t_res[0])
    halves = [moving & (t_res <= half), moving & (t_res > half)]
    if all(h.sum() >= 10 for h in halves):
        # each half's own offset with the line's rate: what the line leaves (said at each half's middle)
        e1, e2 = (refine(h, line[:1], rate=rate)[0][0] for h in halves)
        gap = abs(e1 - e2)
        d1, d2 = (e + rate * (float(np.mean(t_res[h])) - t_ref) for e, h in zip((e1, e2), halves))
    else:
        d1 = d2 = d0
        gap = 0.0
    sel = inside(full_line, moving)
    corr = float(np.corrcoef(gyro_turn(full_line, sel), turn_tab[sel])[0, 1]) if sel.sum() > 2 else float("nan")
    # what the halves disagree by is model error the white-residual σ does not hold
    sigma = max(math.sqrt(at_edge), gap / 2)
    # on the table's clock: table time = t - δ - r (t - t_ref) for IMU time t, so the IMU's clock
    # gains r / (1 - r) per table second, and at the table's first sample t0 it reads
    # (t0 + δ - r t_ref) / (1 - r)
    t0 = float(t_tab[0])
    at_t0 = (d0 - rate * (t_ref - t0)) / (1 - rate)
    if curve is not None:
        # the offset said where the table's record starts, the curve's value there in it
        at_t0 += float(curve(t0 + at_t0))
        curve = dataclasses.replace(curve, zero_at=t0 + at_t0)
    return ClockOffset(at_t0, sigma, d1, d2, corr, rate / (1 - rate),
                       math.sqrt(cov[1, 1]) / (1 - rate) ** 2 if len(line) > 1 else 0.0, stretches, curve,
                       math.sqrt(max(at_edge - float(cov[0, 0]), 0.0)))


# the instrument's mean rates each over this many IMU intervals beside an interval's stencils
INSTRUMENT_NODES = 4
RATE_WINDOWS = 8  # the record in this many equal stretches, for the rate between the clocks and its σ


CHANGING_RATE = 0.01  # rad/s²: ~0.5 deg/s², the table's rate changing at least this fast tells a shift
CHANGING_SPAN = 0.05  # s: the plate's mean rate over this long before and after each interval


def _changing_rate(t_tab: np.ndarray, plate: np.ndarray, k: int) -> np.ndarray:
    """(len(t_tab) − k,) bool: the table intervals (from a reading to the k-th after it) whose
    plate's mean rate over CHANGING_SPAN after the interval differs from that before it by at
    least CHANGING_RATE per second between the two (from the table's readings alone: the gyros'
    counts decide nothing about which of their residuals are used)."""
    n = len(t_tab)
    m = max(1, int(round(CHANGING_SPAN / float(np.median(np.diff(t_tab))))))
    i = np.arange(n - k)
    a0, a1 = np.maximum(i - m, 0), i
    b0, b1 = i + k, np.minimum(i + k + m, n - 1)
    ok = (a1 > a0) & (b1 > b0)
    before = _turn_angle(plate[a0], plate[a1]) / np.where(ok, t_tab[a1] - t_tab[a0], 1.0)
    after = _turn_angle(plate[b0], plate[b1]) / np.where(ok, t_tab[b1] - t_tab[b0], 1.0)
    apart = 0.5 * (t_tab[b0] + t_tab[b1] - t_tab[a0] - t_tab[a1])
    return ok & (np.abs(after - before) >= CHANGING_RATE * np.where(ok, apart, 1.0))


def _cubic_at(x: np.ndarray, y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(len(t), k): *y* (n, k) at the increasing nodes *x* interpolated at *t* by the cubic through
    the four nodes around each (two before it, two after; at the ends the first or last four)."""
    i = np.clip(np.searchsorted(x, t) - 2, 0, len(x) - 4)[:, None] + np.arange(4)
    xs = x[i]
    w = np.ones(xs.shape)
    for j in range(4):
        for m in range(4):
            if m != j:
                w[:, j] *= (t - xs[:, m]) / (xs[:, j] - xs[:, m])
    return np.einsum("qj,qjk->qk", w, y[i])


def _rate_from_windows(refine, t_res, moving, delta: float, t_ref: float):
    """((δ at t_ref, rate), their variances) of the line through the offsets of the moving samples
    in RATE_WINDOWS equal stretches of the record, weighted by their σ, twice (the second with the
    first's rate inside each stretch); the variances widened by the stretches' scatter about the
    line where it exceeds their σ; None where the rate is not RATE_SIGNIFICANT of its σ from none,
    or fewer than four stretches have moves. Second: the stretches' offsets (ClockOffset.stretches),
    or None. The scatter holds what a white residual's σ does not:
    the table's interpolation errs with each move's profile (on a 200 Hz table, a rate of 0.002
    ppm between the halves of a log whose clocks share a crystal, nine times that σ); a stretch
    turning at a constant rate shows no offset at all (its σ says so). *refine* (samples, line[,
    rate]): :func:`_refine` on this record."""
    edges = np.linspace(t_res[0], t_res[-1], RATE_WINDOWS + 1)
    windows = [moving & (t_res >= a) & (t_res < b) for a, b in zip(edges[:-1], edges[1:])]
    windows = [w for w in windows if w.sum() >= 10]
    if len(windows) < 4:
        return None, None
    centre = np.array([float(np.mean(t_res[w])) for w in windows]) - t_ref
    rate = 0.0
    for _ in range(2):
        offsets, var = np.full(len(windows), np.nan), np.full(len(windows), np.nan)
        for k, (w, c) in enumerate(zip(windows, centre)):
            try:
                # δ at t_ref under the rate; the stretch's offset at its centre
                got, cov = refine(w, np.array([delta]), rate=rate)
            except MappingError:
                continue
            offsets[k], var[k] = got[0] + rate * c, cov[0, 0]
        ok = np.isfinite(offsets) & np.isfinite(var) & (var > 0)
        if ok.sum() < 4:
            return None, None
        x, y, wt = centre[ok], offsets[ok], 1.0 / var[ok]
        A = np.column_stack([np.ones_like(x), x]) * np.sqrt(wt)[:, None]
        sol, *_ = np.linalg.lstsq(A, y * np.sqrt(wt), rcond=None)
        delta, rate = float(sol[0]), float(sol[1])
    chi2 = float(np.sum(wt * (y - delta - rate * x) ** 2))
    cov = np.linalg.inv(A.T @ A) * max(1.0, chi2 / (len(x) - 2))
    stretches = (x + t_ref, y, var[ok])
    if abs(rate) <= RATE_SIGNIFICANT * math.sqrt(cov[1, 1]):
        return None, stretches
    return (np.array([delta, rate]), np.diag(cov)), stretches


def _coarse(t_mid, w_imu, t_tab, w_tab, dt, max_offset) -> float:
    """The shift maximising the cross-correlation of the two rate magnitudes, each on a grid of its
    own record: any shift at which the records overlap at all, whatever their clocks count from
    (a host's epoch seconds against a controller's seconds since power-on: one common grid over
    both was terabytes), within ±*max_offset* if given."""
    grid_dt = min(dt, float(np.median(np.diff(t_tab))))
    ga = t_mid[0] + np.arange(0.0, t_mid[-1] - t_mid[0], grid_dt)
    gb = t_tab[0] + np.arange(0.0, t_tab[-1] - t_tab[0], grid_dt)
    a = np.interp(ga, t_mid, w_imu)
    b = np.interp(gb, t_tab, w_tab)
    if not (np.any(b > 1e-3) and np.any(a > 1e-3)):
        raise MappingError("clock offset: the table never moves (or the IMU never turns) in the records: no "
                           "motion to match; give table.clock_offset_s")
    size = 1 << int(np.ceil(np.log2(len(a) + len(b))))
    xc = np.fft.irfft(np.fft.rfft(a - a.mean(), size) * np.conj(np.fft.rfft(b - b.mean(), size)), size)
    # lag k: the IMU's grid point i + k beside the table's i, a shift of ga[0] - gb[0] + k grid_dt
    lags = np.concatenate([np.arange(0, len(a)), np.arange(-len(b) + 1, 0)])
    xc = np.concatenate([xc[:len(a)], xc[size - len(b) + 1:]])
    shift = (ga[0] - gb[0]) + lags * grid_dt
    ok = np.abs(shift) <= max_offset if max_offset is not None else np.ones(len(lags), bool)
    if not ok.any():
        raise MappingError(f"clock offset: no shift within ±{max_offset:g} s lets the records overlap; give "
                           "table.clock_offset_s")
    return float(shift[ok][np.argmax(xc[ok])])


def _refine(residual, inside, t_res, moving, line, t_ref, rate: float | None = None,
            iterations: int = 15, held: tuple = (), scale: float = 1.0, with_rss: bool = False, *, instrument):
    """Gauss–Newton on the line (δ at *t_ref*[, rate[, the curve's coefficients of P_2(x), P_3(x), ...
    with x = (t − t_ref) / *scale*]]) over the *moving* table intervals that lie in the IMU's record
    under it (*inside*(line, moving)): *residual*(line, intervals), the gyros' turn less the
    table's; *t_res*, each interval's time on the IMU's clock (the rate's and the curve's time
    factors). (line, its covariance from the white residual[, the residual's sum of squares, the
    intervals in it]); a line of one number holds the rate at *rate* (0 if None) and the curve at
    *held*. *instrument*(line, intervals): a slope in the shift per interval whose noise the
    residual does not share; the step solves Sᵀ(r + J Δ) = 0 (an instrumental variable), not the
    least squares' Jᵀ(r + J Δ) = 0, whose J carries the residual's own noise: where that noise's
    size moves with the shift (a running count's rounding interpolated between samples), Jᵀr
    follows it. The covariance is the sandwich (SᵀJ)⁻¹ SᵀS (JᵀS)⁻¹ σ²."""
    line = np.asarray(line, float).copy()
    fixed = 0.0 if rate is None else rate
    cov = np.full((len(line), len(line)), np.nan)
    rss, used = float("nan"), 0
    eps = 1e-5

    def full(x):
        return tuple(x) if len(x) > 1 else (x[0], fixed, *held)

    for _ in range(iterations):
        sel = inside(full(line), moving)
        if sel.sum() < 10:
            raise MappingError("clock offset: fewer than 10 table intervals whose rate changes overlap the IMU's record at the "
                               "estimated offset; give table.clock_offset_s")
        r = residual(full(line), sel)
        # the residual depends on the line through each interval's shift δ + rate (t - t_ref)
        nudge = np.zeros(len(line))
        nudge[0] = eps
        ds = (residual(full(line + nudge), sel) - residual(full(line - nudge), sel)) / (2 * eps)
        J = _columns(ds, t_res[sel] - t_ref, len(line), scale)
        S = _columns(instrument(full(line), sel), t_res[sel] - t_ref, len(line), scale)
        ok = np.isfinite(r) & np.all(np.isfinite(J), axis=1) & np.all(np.isfinite(S), axis=1)
        r, J, S = r[ok], J[ok], S[ok]
        info = S.T @ J
        if not np.all(np.isfinite(info)) or np.linalg.cond(info) > 1e12:
            break
        stepv = -np.linalg.solve(info, S.T @ r)
        line += stepv
        rss, used = float(r @ r), len(r)  # at the line before this step (its last one: nearly the same)
        inv = np.linalg.inv(info)
        cov = inv @ (S.T @ S) @ inv.T * rss / max(len(r) - len(line), 1)
        if np.all(np.abs(stepv) < 1e-3 * np.sqrt(np.diag(cov))):
            break
    return (line, cov, rss, used) if with_rss else (line, cov)


def _columns(slope: np.ndarray, since: np.ndarray, n: int, scale: float) -> np.ndarray:
    """(len(slope), n): the residual's slope in the shift times each of the line's *n* time factors
    (1, the time *since* its centre, the curve's Legendre polynomials of since / *scale*)."""
    cols = [slope] + ([slope * since] if n > 1 else [])
    if n > 2:
        cols += list((slope[:, None] * legendre_tail(since / scale, n - 2)).T)
    return np.column_stack(cols)


def angles_at(t: np.ndarray, t_tab: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """The table angles (M, n_axes) at the times *t* (inside the table's record), by PCHIP: a
    rest's reading is held exactly."""
    from scipy.interpolate import PchipInterpolator

    out = np.empty((len(t), angles.shape[1]))
    for k in range(angles.shape[1]):
        out[:, k] = PchipInterpolator(t_tab, angles[:, k], extrapolate=False)(t)
    # hold exact readings where both neighbouring table samples are equal (no rounding at rest)
    idx = np.clip(np.searchsorted(t_tab, t), 1, len(t_tab) - 1)
    for k in range(angles.shape[1]):
        same = angles[idx - 1, k] == angles[idx, k]
        out[same, k] = angles[idx[same], k]
    return out
