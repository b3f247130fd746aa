"""The rows of a log without table angles for any sensor effect of the vocabulary.

:mod:`.positions` fits bias, scale factor and misalignment with a model written for them. What
compare, diagnose and add need on such a log is the same rows for *any* effect: the motion each
sample saw, rebuilt from the rests' attitudes and the turns' profiles, and every effect's
regressor (components.model.effects) summed over the rows — the same regressors the least
squares with table angles uses, so one vocabulary serves both.

The motion (body frame B, attitudes C_p body → ENU, Ω_n the Earth rate in ENU, g gravity):

- in rest p: ω = C_pᵀ Ω_n, f = g C_pᵀ e_up, α = 0;
- in turn r from rest q about the body axis a: θ_k the angle turned by sample k (from the gyro
  along a, scaled to the stated angle, as :mod:`.positions_observations` does), ω_k = a θ̇_k +
  R(a, θ_k)ᵀ C_qᵀ Ω_n, f_k = g R(a, θ_k)ᵀ C_qᵀ e_up (the turn's own translation is unknown: the
  accelerometers' rows of a turn are not used), α_k = a θ̈_k;
- elsewhere (hand moves, excluded samples) nothing: no row uses them.

Rows: per rest chunk Σ Δθ and Σ Δv (3 + 3), per turn Σ Δθ from rest to rest (3); each row's
white-noise variance density² × its duration, whitened by the composite noise model when it is
coloured (components.estimation.whitening; the rows are in time order per channel). The
prediction is ideal(C) + H(C) θ, linear in the effects' parameters θ; the attitudes enter
through the motion, their columns by central differences of the whole prediction (a rest's
attitude moves its own rows and the turns that start from it).

Work is done on *units*: a rest chunk is one unit (its motion is constant, and every regressor
is a function of the motion times at most a linear function of time and of the sample-held
temperature, so the chunk's time-weighted mean time and temperature give its sum exactly), a
turn's samples are a unit each. ``per_sample=True`` makes every sample a unit instead, for the
per-sample prediction a comparison shows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from components.errors import EstimationError
from components.estimation.log_data import LogData
from components.estimation.positions_input import split_segments
from components.estimation.positions_observations import reduce_turns, white_sigmas
from components.estimation.whitening import whiten
from components.model.effects import regressor_of
from components.model.geometry import EARTH_RATE, rodrigues, rotvec
from components.model.motion import Motion

ATTITUDE_STEP = 1e-5  # rad, central-difference step of the attitude angles (error ~ step²)


@dataclass
class Rows:
    """The design at one set of attitudes: observed minus ideal (y), the effects' columns (H),
    the attitudes' columns (A), all whitened, and what each row is."""

    y: np.ndarray
    H: np.ndarray
    A: np.ndarray
    info: dict          # sensor, axis, start, stop (samples), moving, piece, variance (white) per row


class PositionsDesign:
    """A log without table angles as rows for any sensor effect (see the module docstring)."""

    def __init__(self, data: LogData, *, chunk_s: float = 1.0, noise=None, temperature_ref: float | None = None,
                 per_sample: bool = False):
        if data.segment is None or not data.segment_kinds:
            raise EstimationError("a log without table angles needs segment labels and their descriptions "
                                  "('segments' in calbench-log/2)")
        self.notes: list[str] = []
        self.data = data
        t = np.asarray(data.time, float)
        n = len(t)
        self.dt_med = float(np.median(np.diff(t))) if n > 1 else 1.0
        dt = np.concatenate([[self.dt_med], np.diff(t)])
        self.dt_samples = dt
        self.segs = split_segments(data.segment, data.usable, data.segment_kinds, t, self.dt_med, chunk_s, self.notes)
        self.turns = reduce_turns(self.segs, data.gyro, dt)
        self.sg, self.sa, self.noise_source = white_sigmas(noise, data.gyro, data.acc, self.segs.use, self.dt_med,
                                                           self.notes)
        self.noise = noise if noise is not None and noise.coloured else None
        lat = data.geometry.latitude
        self.g = float(data.geometry.gravity)
        self.Om = EARTH_RATE * np.array([0.0, math.cos(lat), math.sin(lat)])
        self.P = len(self.segs.names)
        self.na = 3 if abs(math.cos(lat)) > 1e-6 else 2
        if data.temperature is not None:
            T = np.asarray(data.temperature, float)
            self.T0 = float(T[0]) if temperature_ref is None else float(temperature_ref)
            dtemp = T - self.T0
        else:
            self.T0, dtemp = float(temperature_ref or 0.0), np.zeros(n)
        elapsed = t - dt / 2 - (t[0] - dt[0])
        self._units(dt, dtemp, elapsed, per_sample)
        self._rows()

    # ------------------------------------------------------------------ layout
    def _units(self, dt, dtemp, elapsed, per_sample: bool) -> None:
        """The units in time order with their duration, mean temperature offset and elapsed time,
        the piece that defines their motion (rest p, or turn P + k), and each turn's profile."""
        data = self.data
        n = len(dt)
        if per_sample:
            own = np.full(n, -1)
            for p, (a, b) in enumerate(self.segs.ranges):
                own[a:b] = p
            for k, r in enumerate(self.turns):
                own[r.lo:r.hi] = self.P + k
            first = np.arange(n)
            self.u_start, self.u_stop = first, first + 1
            self.u_dt, self.u_dtemp, self.u_elapsed, self.u_owner = dt, dtemp, elapsed, own
            self.u_gyro, self.u_acc = data.gyro, data.acc
            self.u_time = data.time
            self.chunk_units = [(p, a, b) for p, a, b in self.segs.chunks]
            self.turn_units = [(r.lo, r.hi) for r in self.turns]
        else:
            pieces = [(a, b, p) for p, a, b in self.segs.chunks] + \
                     [(k, k + 1, self.P + i) for i, r in enumerate(self.turns) for k in range(r.lo, r.hi)]
            pieces.sort(key=lambda x: x[0])
            st = np.array([x[0] for x in pieces], int)
            sp = np.array([x[1] for x in pieces], int)
            own = np.array([x[2] for x in pieces], int)
            cdt = np.concatenate([[0.0], np.cumsum(dt)])
            cw = lambda v: np.concatenate([[0.0], np.cumsum(v * dt)])  # noqa: E731
            ct, ce = cw(dtemp), cw(elapsed)
            T = cdt[sp] - cdt[st]
            self.u_start, self.u_stop, self.u_owner, self.u_dt = st, sp, own, T
            self.u_dtemp = (ct[sp] - ct[st]) / T
            self.u_elapsed = (ce[sp] - ce[st]) / T
            cg = np.vstack([np.zeros((1, 3)), np.cumsum(data.gyro, axis=0)])
            ca = np.vstack([np.zeros((1, 3)), np.cumsum(data.acc, axis=0)])
            self.u_gyro, self.u_acc = cg[sp] - cg[st], ca[sp] - ca[st]
            self.u_time = data.time[sp - 1]
            index = {int(s): u for u, s in enumerate(st)}
            self.chunk_units = [(p, index[a], index[a] + 1) for p, a, _ in self.segs.chunks]
            self.turn_units = [(index[r.lo], index[r.lo] + (r.hi - r.lo)) for r in self.turns]
        self.turn_profile = []
        for k, r in enumerate(self.turns):
            s = data.gyro[r.lo:r.hi] @ r.axis
            ds = s * (r.angle / float(s.sum()))
            t_mid = data.time[r.lo:r.hi] - dt[r.lo:r.hi] / 2
            rate = ds / dt[r.lo:r.hi]
            acc_rate = np.gradient(rate, t_mid) if len(rate) > 1 else np.zeros_like(rate)
            self.turn_profile.append((np.cumsum(ds) - ds / 2, rate, acc_rate))

    def _rows(self) -> None:
        """The blocks in time order (rest chunks: gyro and accelerometer rows; turns: gyro), as
        unit ranges, and per row what it is."""
        blocks = [(a, b, p, False) for p, a, b in self.chunk_units] + \
                 [(a, b, self.P + k, True) for k, (a, b) in enumerate(self.turn_units)]
        blocks.sort(key=lambda x: x[0])
        arr = np.array(blocks, dtype=object).reshape(-1, 4)
        g = tuple(arr[:, i].astype(t) for i, t in enumerate((int, int, int, bool)))
        still = ~g[3]
        a = tuple(x[still] for x in g)
        self.gyro_blocks, self.acc_blocks = g, a
        cdt = np.concatenate([[0.0], np.cumsum(self.u_dt)])
        parts = {}
        for name, (st, sp, pc, mv), dens in (("gyro", g, self.sg), ("acc", a, self.sa)):
            T = cdt[sp] - cdt[st]
            parts[name] = dict(sensor=np.array([name] * (3 * len(st))), axis=np.tile([0, 1, 2], len(st)),
                               start=np.repeat(self.u_start[st], 3), stop=np.repeat(self.u_stop[sp - 1], 3),
                               unit_start=np.repeat(st, 3), unit_stop=np.repeat(sp, 3),
                               moving=np.repeat(mv, 3), piece=np.repeat(pc, 3), duration=np.repeat(T, 3),
                               variance=((dens / math.sqrt(self.dt_med))[None, :] ** 2 * T[:, None]).reshape(-1))
        self.info = {k: np.concatenate([parts["gyro"][k], parts["acc"][k]]) for k in parts["gyro"]}
        self.n_rows = len(self.info["start"])
        self.observed = np.concatenate([self._sums(self.u_gyro, g), self._sums(self.u_acc, a)])

    @staticmethod
    def _sums(x: np.ndarray, blocks, lo: int = 0) -> np.ndarray:
        c = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, axis=0)])
        return (c[blocks[1] - lo] - c[blocks[0] - lo]).reshape(-1)

    @property
    def attitude_names(self) -> list[str]:
        """The nuisance parameters: per rest its tilt about east and north (and its heading)."""
        ax = ("tilt_e", "tilt_n", "heading")[:self.na]
        return [f"attitude[{name}].{a}" for name in self.segs.names for a in ax]

    # ------------------------------------------------------------------ motion
    def motion(self, C: np.ndarray, lo: int = 0, hi: int | None = None, earth: bool = True) -> Motion:
        """The motion of units [lo, hi) for attitudes C (P, 3, 3); ``earth`` False: without the
        Earth rate (which parameters the turns determine)."""
        hi = len(self.u_owner) if hi is None else hi
        n = hi - lo
        own = self.u_owner[lo:hi]
        Om = self.Om if earth else np.zeros(3)
        om = np.zeros((n, 3))
        f = np.zeros((n, 3))
        al = np.zeros((n, 3))
        rest = (own >= 0) & (own < self.P)
        if rest.any():
            om[rest] = np.einsum("pij,i->pj", C, Om)[own[rest]]
            f[rest] = self.g * C[own[rest], 2, :]
        for k in np.unique(own[own >= self.P]) - self.P:
            r = self.turns[k]
            sel = np.nonzero(own == self.P + k)[0]
            pos = self.u_start[lo + sel] - r.lo          # sample within the turn
            th, rate, acc_rate = (x[pos] for x in self.turn_profile[k])
            RT = np.transpose(rodrigues(r.axis, th), (0, 2, 1))
            om[sel] = r.axis * rate[:, None] + RT @ (C[r.q].T @ Om)
            f[sel] = self.g * (RT @ C[r.q, 2, :])
            al[sel] = r.axis * acc_rate[:, None]
        ends_w = np.vstack([om[:1], 0.5 * (om[1:] + om[:-1]), om[-1:]])
        ends_f = np.vstack([f[:1], 0.5 * (f[1:] + f[:-1]), f[-1:]])
        # a rest unit's interval ends are its own values (the motion is constant through it)
        ends_w[:-1][rest], ends_w[1:][rest] = om[rest], om[rest]
        ends_f[:-1][rest], ends_f[1:][rest] = f[rest], f[rest]
        return Motion(time=self.u_time[lo:hi], dt=self.u_dt[lo:hi], static=rest, nodes=np.array([0.5]),
                      weights=np.array([1.0]), omega_q=om[:, None, :], alpha_q=al[:, None, :], f_q=f[:, None, :],
                      omega_start=ends_w[:-1], omega_end=ends_w[1:], f_start=ends_f[:-1], f_end=ends_f[1:],
                      alpha_end=al, dtemp_q=self.u_dtemp[lo:hi, None], elapsed_q=self.u_elapsed[lo:hi, None],
                      t0_temperature=self.T0, lever=np.zeros((3, 3)))

    def predict_units(self, C: np.ndarray, params: list[str], theta: np.ndarray, earth: bool = True):
        """(gyro, acc) prediction (U, 3) of every unit: ideal + Σ θ × regressor."""
        m = self.motion(C, earth=earth)
        g, a = m.ideal_gyro.copy(), m.ideal_acc.copy()
        for p, v in zip(params, theta):
            gc, ac = regressor_of(m, p)
            if gc is not None:
                g += v * gc
            if ac is not None:
                a += v * ac
        return g, a

    def _predict(self, C, params, lo=0, hi=None, earth=True):
        """(ideal sums, H) of the rows inside units [lo, hi)."""
        m = self.motion(C, lo, hi, earth)
        gsel, asel = self._block_subset(lo, hi if hi is not None else len(self.u_owner))
        ideal = np.concatenate([self._sums(m.ideal_gyro, gsel, lo), self._sums(m.ideal_acc, asel, lo)])
        H = np.zeros((len(ideal), len(params)))
        ng = 3 * len(gsel[0])
        for k, p in enumerate(params):
            gcol, acol = regressor_of(m, p)
            if gcol is not None:
                H[:ng, k] = self._sums(gcol, gsel, lo)
            if acol is not None:
                H[ng:, k] = self._sums(acol, asel, lo)
        return ideal, H

    def _block_subset(self, lo: int, hi: int):
        def pick(blocks):
            sel = (blocks[0] >= lo) & (blocks[1] <= hi)
            return tuple(x[sel] for x in blocks)
        return pick(self.gyro_blocks), pick(self.acc_blocks)

    def _row_index(self, lo: int, hi: int) -> np.ndarray:
        i = self.info
        return np.nonzero((i["unit_start"] >= lo) & (i["unit_stop"] <= hi))[0]

    # ------------------------------------------------------------------ rows
    def rows(self, C: np.ndarray, params: list[str], theta: np.ndarray | None = None,
             attitudes: bool = True, earth: bool = True) -> Rows:
        """Whitened rows at attitudes C: y = observed − ideal, H the columns of *params*, A the
        attitudes' columns of the whole prediction ideal + H θ (θ = *theta*, default 0)."""
        theta = np.zeros(len(params)) if theta is None else np.asarray(theta, float)
        ideal, H = self._predict(C, params, earth=earth)
        y = self.observed - ideal
        A = np.zeros((self.n_rows, self.na * self.P))
        if attitudes:
            # only the parameters with a value move the prediction when an attitude turns
            active = [k for k in range(len(params)) if theta[k] != 0]
            act_params, act_theta = [params[k] for k in active], theta[active]
            for p in range(self.P):
                lo, hi = self._span_of(p)
                idx = self._row_index(lo, hi)
                for j in range(self.na):
                    side = []
                    for sign in (1.0, -1.0):
                        phi = np.zeros(3)
                        phi[j] = sign * ATTITUDE_STEP
                        C2 = C.copy()
                        C2[p] = rotvec(phi) @ C[p]
                        i2, H2 = self._predict(C2, act_params, lo, hi, earth=earth)
                        side.append(i2 + H2 @ act_theta)
                    A[idx, self.na * p + j] = (side[0] - side[1]) / (2 * ATTITUDE_STEP)
        var = self.info["variance"]
        info = dict(self.info)
        if self.noise is None:
            w = 1.0 / np.sqrt(var)
            return Rows(y * w, H * w[:, None], A * w[:, None], info)
        span = float(self.data.time[-1] - self.data.time[0] + self.dt_med)
        yw, bw, _ = whiten(y, np.hstack([H, A]), info, var, self.noise, self.dt_med, span)
        return Rows(yw, bw[:, :H.shape[1]], bw[:, H.shape[1]:], info)

    def _span_of(self, p: int) -> tuple[int, int]:
        """The units whose rows move with rest p's attitude: its chunks and the turns from it."""
        units = [(a, b) for q, a, b in self.chunk_units if q == p]
        units += [self.turn_units[k] for k, r in enumerate(self.turns) if r.q == p]
        return min(a for a, _ in units), max(b for _, b in units)

    def turn_rest(self, C: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """The attitudes turned by *delta* (na angles per rest, in ENU)."""
        phi = delta.reshape(self.P, self.na)
        if self.na == 2:
            phi = np.hstack([phi, np.zeros((self.P, 1))])
        return np.einsum("pij,pjk->pik", rotvec(phi), C)
