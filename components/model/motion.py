"""The plate's motion over every sample interval of a log, reconstructed from the measured gimbal
angles through the table geometry: angular rate, angular acceleration and specific force at
Gauss–Legendre nodes inside each interval, from which the forward model integrates the ideal
increments and every effect's regressor.

Angles are interpolated per moving run (a maximal run of intervals in which some angle changes)
by a cubic spline through the logged angles, clamped to zero rate at rest ends. Encoder
quantisation makes per-sample rates of this interpolant noisy (domain.md §3); what stays exact
is the integral of the gimbal rate between two rest samples, so estimators compare gyro output
with the table over whole rest-to-rest moves (see components.estimation.blocks).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from components.model.approach import approach_sides, moving_runs
from components.model.geometry import TableGeometry, cross
from components.model.spline import RunSpline

_GL = {
    2: (np.array([-1, 1]) / np.sqrt(3), np.array([1.0, 1.0])),
    3: (np.array([-np.sqrt(3 / 5), 0.0, np.sqrt(3 / 5)]), np.array([5, 8, 5]) / 9),
    4: (np.array([-0.8611363115940526, -0.3399810435848563, 0.3399810435848563, 0.8611363115940526]),
        np.array([0.3478548451374538, 0.6521451548625461, 0.6521451548625461, 0.3478548451374538])),
}


def gauss_legendre(q: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes on [0, 1] and weights summing to 1."""
    x, w = _GL[q]
    return (x + 1) / 2, w / 2


def lever_acceleration(omega: np.ndarray, alpha: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Specific force at offset *r* [m] minus that at the reference point of a rigid body turning
    at *omega* [rad/s] with *alpha* [rad/s²] (all in body axes, (..., 3)): α × r + ω × (ω × r)."""
    return cross(alpha, r) + cross(omega, cross(omega, r))


@dataclass
class Motion:
    time: np.ndarray       # (N,) end of each sample interval
    dt: np.ndarray         # (N,) interval lengths
    static: np.ndarray     # (N,) bool: no gimbal angle changed over the interval
    nodes: np.ndarray      # (Q,) node positions in [0, 1]
    weights: np.ndarray    # (Q,) weights, sum 1
    omega_q: np.ndarray    # (N, Q, 3) inertial rate of the plate, plate axes
    alpha_q: np.ndarray    # (N, Q, 3)
    f_q: np.ndarray        # (N, Q, 3) specific force at the plate reference point
    omega_start: np.ndarray  # (N, 3) at the start / end of each interval
    omega_end: np.ndarray
    f_start: np.ndarray
    f_end: np.ndarray
    alpha_end: np.ndarray  # (N, 3) angular acceleration at the sample times
    dtemp_q: np.ndarray    # (N, Q) temperature - T0
    elapsed_q: np.ndarray  # (N, Q) time since the start of the log
    t0_temperature: float
    lever: np.ndarray      # (3, 3) row i: offset of accelerometer i used by f_at
    # (N, 3) at the start of each interval (the previous sample's alpha_end); None: shift
    # alpha_end by one row (a motion whose rows are consecutive samples)
    alpha_start: np.ndarray | None = None

    def alpha_at_start(self) -> np.ndarray:
        if self.alpha_start is not None:
            return self.alpha_start
        return np.vstack([self.alpha_end[:1], self.alpha_end[:-1]])

    def f_at(self, i: str) -> np.ndarray:
        """Specific force (N, Q, 3) at accelerometer i's location (size effect)."""
        r = self.lever["xyz".index(i)]
        if not r.any():
            return self.f_q
        return self.f_q + lever_acceleration(self.omega_q, self.alpha_q, r)

    def integral(self, values_q: np.ndarray) -> np.ndarray:
        """∫ over each interval of node values (N, Q, ...) -> (N, ...)."""
        return self.dt.reshape((-1,) + (1,) * (values_q.ndim - 2)) * np.tensordot(
            values_q, self.weights, axes=([1], [0]))

    @property
    def ideal_gyro(self) -> np.ndarray:
        return self.integral(self.omega_q)

    @property
    def ideal_acc(self) -> np.ndarray:
        """Ideal accelerometer increments, each axis at its own location (lever arms)."""
        out = np.empty((len(self.dt), 3))
        for k, i in enumerate("xyz"):
            out[:, k] = self.integral(self.f_at(i)[:, :, k])
        return out


@dataclass
class AngleProfile:
    """The measured gimbal angles interpolated inside every sample interval; independent of the
    geometry, so one profile serves every geometry a fit tries."""

    time: np.ndarray
    t_prev: np.ndarray
    dt: np.ndarray
    static: np.ndarray
    nodes: np.ndarray
    weights: np.ndarray
    # the moving samples' node values: a rest's angle is its sample's, its rates zero (a log is
    # mostly rests: rows for them were 216 bytes a sample of copies)
    moving_index: np.ndarray  # (M,) the samples of the rows below
    th_q: np.ndarray    # (M, Q, n_axes) measured angle at the nodes
    rate_q: np.ndarray
    acc_q: np.ndarray
    th_end: np.ndarray  # (N, n_axes) at the sample times (every sample: the measured angles)
    rate_end: np.ndarray  # (M, n_axes) at the moving samples' times
    acc_end: np.ndarray
    attitudes: np.ndarray | None = None  # distinct angles of the static intervals
    attitude_of: np.ndarray | None = None  # per static interval, its row in `attitudes`
    # the side each stage last moved to (+1, -1; 0 before any move): a rest is an attitude and
    # the sides it was reached from (a table's reversal error puts it apart by them), and a moving
    # interval goes from its start's sides to its end's (components.model.geometry, Stage.reversal)
    attitude_sides: np.ndarray | None = None  # (A, n_axes) int8
    move_side0: np.ndarray | None = None     # (M, n_axes) the sides at each moving interval's start
    move_side_rate: np.ndarray | None = None  # (M, n_axes) (its end's sides - those) / its length [1/s]
    move_t0: np.ndarray | None = None        # (M,) its start [s]
    side0: np.ndarray | None = None          # (n_axes,) the sides before the first sample
    side_band: np.ndarray | None = None      # (n_axes,) [rad] the travel a side needs (approach.run_sides)
    _key: str | None = field(default=None, repr=False, compare=False)
    _static_samples: np.ndarray | None = field(default=None, repr=False, compare=False)
    # geometry -> rest_values, the last few (a chunk's design asks for the same geometry's four
    # times; the table columns' steps each once)
    _rest: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def key(self) -> str:
        """Digest of time, angles and quadrature: equal profiles give equal motions (computed when
        first asked: only the table columns' cache needs it, and it reads the whole log)."""
        if self._key is None:
            h = hashlib.sha256(np.ascontiguousarray(self.time))
            h.update(np.ascontiguousarray(self.th_end))
            # the sides are the angles' with these two (the table columns' cache keys on this)
            for a, t in ((self.side0, np.int8), (self.side_band, float)):
                if a is not None:
                    h.update(np.ascontiguousarray(a, t))
            h.update(bytes([len(self.nodes), self.th_end.shape[1]]))
            self._key = h.hexdigest()
        return self._key

    def attitude_at(self, samples: np.ndarray) -> np.ndarray:
        """The row in `attitudes` of each of the static *samples* (sample indices)."""
        if self._static_samples is None:
            self._static_samples = np.flatnonzero(self.static)
        return self.attitude_of[np.searchsorted(self._static_samples, samples)]


def same_as_before(rows: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(N - 1,) bool: row k + 1 of *rows* (N, k) equals row k in every column; into *out* if
    given. Column by column: np.all over rows of three is 5x slower (a reduction per row)."""
    rows = np.asarray(rows)
    out = np.empty(max(len(rows) - 1, 0), bool) if out is None else out
    if rows.shape[1] == 0:
        out[:] = True
        return out
    np.equal(rows[1:, 0], rows[:-1, 0], out=out)
    for k in range(1, rows.shape[1]):
        out &= rows[1:, k] == rows[:-1, k]
    return out


def interpolate_angles(time: np.ndarray, angles: np.ndarray, quadrature: int = 3,
                       dt0: float | None = None, side0: np.ndarray | None = None,
                       band: np.ndarray | None = None) -> AngleProfile:
    """Interpolate measured angles (N, n_axes) at t_k over each interval (t_{k-1}, t_k].

    The interval before the first sample is taken as static at the first angles; its length is
    ``dt0`` (default: the first sample spacing). ``side0``: the side each stage last moved to
    before the first sample (+1, -1, 0: none; a stretch of a longer log has the log's); ``band``
    (per stage [rad], default 0): what a stage must travel for a side to count (:func:`run_sides`)."""
    time = np.asarray(time, float)
    n = len(time)
    measured = np.atleast_2d(np.asarray(angles, float))
    if dt0 is None:
        dt0 = time[1] - time[0] if n > 1 else 0.0
    t_prev = np.concatenate([[time[0] - dt0], time[:-1]])
    dt = time - t_prev
    static = np.empty(n, bool)  # the interval before the first sample at rest (unless its angles are NaN)
    np.all(measured[:1] == measured[:1], axis=1, out=static[:1])
    same_as_before(measured, out=static[1:])
    x, w = gauss_legendre(quadrature)
    q = len(x)
    n_ax = measured.shape[1]
    moving = np.flatnonzero(~static)
    m = len(moving)
    th_q, rate_q, acc_q = (np.empty((m, q, n_ax)) for _ in range(3))
    rate_end, acc_end = np.empty((m, n_ax)), np.empty((m, n_ax))
    side0 = np.zeros(n_ax, np.int8) if side0 is None else np.asarray(side0, np.int8)
    band = np.zeros(n_ax) if band is None else np.broadcast_to(np.asarray(band, float), (n_ax,))
    sides = approach_sides(measured, static, side0, band)
    move_side0, move_side_rate, move_t0 = np.zeros((0, n_ax)), np.zeros((0, n_ax)), np.zeros(0)
    row = 0  # the run's first row
    for a, b in moving_runs(static):
        # knots: the rest sample before the run (index a-1, or the virtual one) to sample b-1,
        # whose reading is the rest's when one follows: the plate is at rest from there, as it was
        # up to the rest sample before the run (a knot at the next rest sample instead let the
        # spline overshoot and come back inside that sample's rest interval, with a rate at its
        # start the rest's sums do not have: a spurious time-offset column on every rest after a move)
        lo = a - 1
        hi = b - 1
        kt = np.concatenate([[t_prev[a]], time[a:hi + 1]])
        kth = np.vstack([measured[lo] if lo >= 0 else measured[0], measured[a:hi + 1]])
        rest_lo = lo < 0 or static[lo]
        rest_hi = b < n and static[b]
        # at rest before (after) the run: slope 0 there; else not-a-knot, which needs four knots
        short = len(kt) < 4
        spl = RunSpline(kt, kth, rest_lo or short, rest_hi or short)
        # sample i's interval is the run's knot interval i − a; its end, knot i − a + 1
        k = np.arange(b - a)
        kq = np.broadcast_to(k[:, None], (b - a, q))
        u = dt[a:b, None] * x[None, :]
        rows = slice(row, row + b - a)
        th_q[rows], rate_q[rows], acc_q[rows] = spl.with_derivatives(kq, u)
        _, rate_end[rows], acc_end[rows] = spl.at_knots(k + 1)
        row += b - a
    # a stage's side changes over the interval of its first sample that moves the other way (the
    # reading moves once the play is taken up: a backlash of arcseconds takes milliseconds)
    if m:
        before = np.vstack([side0[None, :], sides[:-1]])
        move_side0 = before[moving].astype(float)
        move_side_rate = (sides[moving] - before[moving]) / dt[moving, None]
        move_t0 = t_prev[moving]
    att, att_sides, inv = _attitudes(measured, static, sides)
    return AngleProfile(time, t_prev, dt, static, x, w, moving, th_q, rate_q, acc_q, measured,
                        rate_end, acc_end, att, inv.ravel(), att_sides, move_side0, move_side_rate,
                        move_t0, side0, np.array(band, float))


def _attitudes(measured: np.ndarray, static: np.ndarray, sides: np.ndarray):
    """The distinct (angles, sides) rows of the static samples (sorted, as np.unique gives them;
    a static sample is one whose angles are those of the sample before, the first at rest):
    the angles (A, n_axes), the sides (A, n_axes) and, per static sample, its row. Consecutive
    static samples mostly share them, so the rows are made unique over the changes only
    (np.unique over every sample sorted millions of rows: a third of calibrate's time on a 1 kHz
    log)."""
    n_ax = measured.shape[1]
    idx = np.flatnonzero(static)
    if len(idx) == 0:
        return np.zeros((0, n_ax)), np.zeros((0, n_ax), np.int8), np.zeros(0, int)
    # a static sample right after another has its angles (that is what static means): only
    # its side can be new; after a move, anything can (taken as new: np.unique merges repeats)
    sd = sides[idx]
    new = np.ones(len(idx), bool)
    new[1:] = ~same_as_before(sd) | (np.diff(idx) != 1)
    first = idx[new]
    att, inv_new = np.unique(np.hstack([measured[first], sd[new]]), axis=0, return_inverse=True)
    return att[:, :n_ax].copy(), att[:, n_ax:].astype(np.int8), inv_new.ravel()[np.cumsum(new) - 1]


def _true_motion(geometry: TableGeometry, th: np.ndarray, rate: np.ndarray, acc: np.ndarray, sides=None):
    """Measured angle derivatives -> true ones through the encoder error e(θ):
    θ_m = θ + e(θ) gives θ̇ = θ̇_m / (1 + e'), θ̈ = (θ̈_m - e'' θ̇²) / (1 + e'); then the reversal
    error r of each stage: the plate r/2 past the reading on the side the stage last moved to.
    *sides*: a callable giving (side (K, n_axes), d side/dt (K, n_axes)) at these K points: a side
    changes across the interval where the reading first moves the other way."""
    t, r, a = _encoder_motion(geometry, th, rate, acc)
    if sides is None or not geometry.has_reversal:
        return t, r, a
    side, side_rate = sides()
    t, r = np.array(t, float, copy=True), np.array(r, float, copy=True)
    for k, s in enumerate(geometry.stages):
        if s.reversal:
            t[:, k] += 0.5 * s.reversal * side[:, k]
            r[:, k] += 0.5 * s.reversal * side_rate[:, k]
    return t, r, a


def _encoder_motion(geometry: TableGeometry, th: np.ndarray, rate: np.ndarray, acc: np.ndarray):
    """The encoder-error part of :func:`_true_motion`."""
    if not any(s.has_encoder_error for s in geometry.stages):
        return th, rate, acc
    t = geometry.true_angles(th)
    r, a = rate.copy(), acc.copy()
    for k, s in enumerate(geometry.stages):
        if not s.has_encoder_error:
            continue
        u = t[:, k]
        e1 = s.enc_s1 * np.cos(u) - s.enc_c1 * np.sin(u) + 2 * (s.enc_s2 * np.cos(2 * u) - s.enc_c2 * np.sin(2 * u))
        e2 = -s.enc_s1 * np.sin(u) - s.enc_c1 * np.cos(u) - 4 * (s.enc_s2 * np.sin(2 * u) + s.enc_c2 * np.cos(2 * u))
        r[:, k] = rate[:, k] / (1 + e1)
        a[:, k] = (acc[:, k] - e2 * r[:, k] ** 2) / (1 + e1)
    return t, r, a


def motion_from_profile(profile: AngleProfile, geometry: TableGeometry,
                        temperature: np.ndarray | None = None, t0_temperature: float | None = None,
                        lever: np.ndarray | None = None, time_origin: float | None = None,
                        samples: np.ndarray | None = None) -> Motion:
    """Plate motion at the profile's nodes for one geometry. ``time_origin``: the time drift
    terms count from (default: the start of the profile's first interval; a stretch of a longer
    log gives the log's). ``samples``: sorted sample indices, the motion of those samples alone
    (a row each, the same values as the whole profile's rows; the estimators' block sums need
    the moving samples one by one but a rest only once, components.estimation.block_motion)."""
    p = profile
    n_all, q = len(p.time), len(p.nodes)
    whole = samples is None
    idx = np.arange(n_all) if whole else np.asarray(samples, int)

    def take(a):
        return a if whole else a[idx]

    n = len(idx)
    om = np.empty((n, q, 3))
    al = np.zeros((n, q, 3))
    f = np.empty((n, q, 3))
    # static intervals: one kinematics evaluation per distinct attitude (a schedule has few)
    st = take(p.static)
    # (the ends below may need them where these samples are all moving: cached per geometry)
    om_u, f_u = rest_values(p, geometry) if p.static.any() else (None, None)
    if st.any():
        att = p.attitude_of if whole else p.attitude_at(idx[st])
        om[st] = om_u[att][:, None, :]
        f[st] = f_u[att][:, None, :]
    mv = ~st
    if mv.any():
        om[mv], al[mv], f[mv] = _moving_nodes(p, geometry, None if whole else idx[mv])
    # values at the sample times, of these samples and of the ones before them (their starts):
    # static ends share the attitudes above; moving ends computed
    prev = np.maximum(idx - 1, 0)
    ends = idx if whole else np.union1d(idx, prev)
    om_e, al_e, f_e = _ends(p, geometry, ends, om_u, f_u, whole)
    if whole:
        at, before = slice(None), np.concatenate([[0], idx[:-1]])
    else:
        at, before = np.searchsorted(ends, idx), np.searchsorted(ends, prev)
    tq_all = take(p.t_prev)[:, None] + take(p.dt)[:, None] * p.nodes[None, :]
    if temperature is not None:
        T = np.asarray(temperature, float)
        T_prev, T_end = T[prev], T[idx]
        T_q = T_prev[:, None] + (T_end - T_prev)[:, None] * p.nodes[None, :]
        T0 = float(T[0]) if t0_temperature is None else float(t0_temperature)
        dtemp_q = T_q - T0
    else:
        T0 = float(t0_temperature or 0.0)
        dtemp_q = np.zeros((n, q))
    return Motion(
        time=take(p.time), dt=take(p.dt), static=st, nodes=p.nodes, weights=p.weights,
        omega_q=om, alpha_q=al, f_q=f,
        omega_start=om_e[before], omega_end=om_e[at], f_start=f_e[before], f_end=f_e[at],
        alpha_end=al_e[at], alpha_start=al_e[before],
        dtemp_q=dtemp_q, elapsed_q=tq_all - (p.t_prev[0] if time_origin is None else time_origin),
        t0_temperature=T0,
        lever=np.zeros((3, 3)) if lever is None else np.asarray(lever, float),
    )


def _ends(p: AngleProfile, geometry: TableGeometry, samples: np.ndarray, om_u, f_u, whole: bool):
    """Inertial rate, angular acceleration and specific force (len(samples), 3) at the ends of
    the intervals of *samples* (sorted indices; *whole*: every sample of the profile)."""
    om_e = np.empty((len(samples), 3))
    f_e = np.empty((len(samples), 3))
    al_e = np.zeros((len(samples), 3))
    st = p.static[samples]
    if st.any():
        att = p.attitude_of if whole else p.attitude_at(samples[st])
        om_e[st], f_e[st] = om_u[att], f_u[att]
    mv = ~st
    if mv.any():
        k = samples[mv]
        r = np.searchsorted(p.moving_index, k)
        the, re, ae = _true_motion(geometry, p.th_end[k], p.rate_end[r], p.acc_end[r],
                                   lambda: _move_sides(p, r, p.time[k][:, None]))
        om_e[mv], al_e[mv], f_e[mv] = geometry.motion(the, re, ae)
    return om_e, al_e, f_e


class IdealIncrements:
    """The ideal gyro and accelerometer increments of one angle profile (no lever arms), for any
    table geometry, as rest values per attitude (a rest's increment is its attitude's rate and
    force times the interval) and per moving sample (node by node, by
    TableGeometry.rate_and_force) — what the table effects' finite-difference columns need, one
    geometry per parameter."""

    def __init__(self, profile: AngleProfile):
        self.profile = profile
        self.moving_index = profile.moving_index
        _, q, n_ax = profile.th_q.shape
        self._nodes = (profile.th_q.reshape(-1, n_ax), profile.rate_q.reshape(-1, n_ax),
                       profile.acc_q.reshape(-1, n_ax))
        self._q = q
        self._dt_m = profile.dt[self.moving_index, None]
        self._first: tuple | None = None  # (geometry, its states) of the first call: later ones resume there

    def of(self, geometry: TableGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(rest rate (A, 3), rest force (A, 3), moving gyro (M, 3), moving acc (M, 3)) increments
        per unit time at rest, per sample when moving."""
        p = self.profile
        if p.attitudes is not None and len(p.attitudes):
            om_u, f_u = rest_values(p, geometry)
            wsum = float(np.sum(p.weights))
            rest_g, rest_a = om_u * wsum, f_u * wsum
        else:
            rest_g = rest_a = np.zeros((0, 3))
        if len(self.moving_index) == 0:
            return rest_g, rest_a, np.zeros((0, 3)), np.zeros((0, 3))
        th, rate, _ = _true_motion(geometry, *self._nodes, lambda: _node_sides(p, slice(None)))
        # a finite-difference step changes one stage (or the base): the stages before it are the
        # first geometry's, so the vectors are carried on from there
        if self._first is None:
            states: list = []
            om, f = geometry.rate_and_force(th, rate, states=states)
            self._first = (geometry, states)
        else:
            k = geometry.first_change(self._first[0])
            om, f = geometry.rate_and_force(th, rate, resume=(k, *self._first[1][k]) if k else None)
        w = p.weights
        mov_g = self._dt_m * np.tensordot(om.reshape(-1, self._q, 3), w, axes=([1], [0]))
        mov_a = self._dt_m * np.tensordot(f.reshape(-1, self._q, 3), w, axes=([1], [0]))
        return rest_g, rest_a, mov_g, mov_a


def ideal_increments(profile: AngleProfile, geometry: TableGeometry) -> tuple[np.ndarray, np.ndarray]:
    """The ideal gyro and accelerometer increments (N, 3) of motion_from_profile(profile,
    geometry) (no lever arms), without building the Motion (:class:`IdealIncrements` per sample)."""
    p = profile
    rest_g, rest_a, mov_g, mov_a = IdealIncrements(p).of(geometry)
    gyro = np.empty((len(p.dt), 3))
    acc = np.empty((len(p.dt), 3))
    st = p.static
    if st.any():
        gyro[st] = p.dt[st, None] * rest_g[p.attitude_of]
        acc[st] = p.dt[st, None] * rest_a[p.attitude_of]
    gyro[~st], acc[~st] = mov_g, mov_a
    return gyro, acc


def rest_values(p: AngleProfile, geometry: TableGeometry) -> tuple[np.ndarray, np.ndarray]:
    """Inertial rate and specific force (A, 3) at each distinct rest attitude of the profile
    (one kinematics evaluation per attitude: a schedule has few), kept for the last few
    geometries (read-only: shared by every caller)."""
    got = p._rest.get(geometry)
    if got is None:
        att = p.attitudes
        th, r0, a0 = _true_motion(geometry, att, np.zeros_like(att), np.zeros_like(att),
                                  lambda: (p.attitude_sides, np.zeros_like(att)))
        om_u, _, f_u = geometry.motion(th, r0, a0)
        for a in (om_u, f_u):
            a.setflags(write=False)
        got = p._rest[geometry] = (om_u, f_u)
        while len(p._rest) > REST_VALUES_KEPT:
            p._rest.pop(next(iter(p._rest)))
    return got


REST_VALUES_KEPT = 4


def _moving_nodes(p: AngleProfile, geometry: TableGeometry, samples: np.ndarray | None = None):
    """Inertial rate, angular acceleration and specific force (M, Q, 3) at the quadrature nodes
    of the moving intervals (or of the moving *samples*, indices)."""
    rows = slice(None) if samples is None else np.searchsorted(p.moving_index, samples)
    _, q, n_ax = p.th_q.shape
    th, rate, acc = _true_motion(geometry, p.th_q[rows].reshape(-1, n_ax), p.rate_q[rows].reshape(-1, n_ax),
                                 p.acc_q[rows].reshape(-1, n_ax), lambda: _node_sides(p, rows))
    om_m, al_m, f_m = geometry.motion(th, rate, acc)
    return tuple(x.reshape(-1, q, 3) for x in (om_m, al_m, f_m))


def _move_sides(p: AngleProfile, rows, t: np.ndarray):
    """(side, d side/dt) (K, n_axes) of the moving samples' *rows* at times *t* (K, 1) or (K, Q)
    (flattened row-major with the rows)."""
    side0, rate = p.move_side0[rows], p.move_side_rate[rows]
    elapsed = t - p.move_t0[rows][:, None]  # (K, Q)
    q = elapsed.shape[1]
    side = side0[:, None, :] + rate[:, None, :] * elapsed[:, :, None]
    return side.reshape(-1, side0.shape[1]), np.repeat(rate, q, axis=0)


def _node_sides(p: AngleProfile, rows):
    """(side, d side/dt) at the quadrature nodes of the moving samples' *rows* (a slice or
    indices into the moving samples), node by node as th_q holds them."""
    mi = p.moving_index[rows]
    return _move_sides(p, rows, p.t_prev[mi][:, None] + p.dt[mi][:, None] * p.nodes[None, :])


def reconstruct(time: np.ndarray, angles: np.ndarray, geometry: TableGeometry,
                temperature: np.ndarray | None = None, t0_temperature: float | None = None,
                quadrature: int = 3, lever: np.ndarray | None = None, dt0: float | None = None) -> Motion:
    """Motion over each interval (t_{k-1}, t_k] from measured angles (N, n_axes) at t_k."""
    return motion_from_profile(interpolate_angles(time, angles, quadrature, dt0), geometry,
                               temperature, t0_temperature, lever)
