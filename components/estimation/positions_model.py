"""The model of a multi-position calibration, as :mod:`.positions` states it: the parameter
layout, the rows predicted for given calibration parameters and attitudes, their whitened
Jacobian, the heading curvature Newton needs, and the attitudes' starting values and update."""
from __future__ import annotations

import math

import numpy as np

from components.estimation.positions_observations import Rests, Turn
from components.model.effects import AX
from components.model.geometry import rotvec, skew

# parameter layout: gyro bias (3), G (9, row-major), acc bias (3), A (9), then na angles per rest
_GB, _G, _AB, _A, _NCAL = 0, 3, 12, 15, 24


def _cal_names() -> list[str]:
    names = [f"gyro.bias.{c}" for c in AX]
    names += [f"gyro.sf.{AX[i]}" if i == j else f"gyro.mis.{AX[i]}{AX[j]}" for i in range(3) for j in range(3)]
    names += [f"acc.bias.{c}" for c in AX]
    names += [f"acc.sf.{AX[i]}" if i == j else f"acc.mis.{AX[i]}{AX[j]}" for i in range(3) for j in range(3)]
    return names


CAL_NAMES = _cal_names()


def unpack(th: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(gyro bias, G, acc bias, A) of a parameter vector."""
    return th[_GB:_GB + 3], th[_G:_G + 9].reshape(3, 3), th[_AB:_AB + 3], th[_A:_A + 9].reshape(3, 3)


def frame(up: np.ndarray, north: np.ndarray | None) -> np.ndarray:
    """C (body -> ENU) whose rows are east, north and up in the body frame."""
    u = up / np.linalg.norm(up)
    if north is None or np.linalg.norm(north - (north @ u) * u) < 1e-9:
        e = np.zeros(3)
        e[int(np.argmin(np.abs(u)))] = 1.0
        north = e
    n = north - (north @ u) * u
    n /= np.linalg.norm(n)
    return np.vstack([np.cross(n, u), n, u])


def starting_frames(U0: np.ndarray, rests: Rests, Om: np.ndarray, use_heading: bool) -> np.ndarray:
    """Starting attitudes (P, 3, 3): up from the accelerometers' mean, north (latitude given)
    from the gyros' horizontal rate, else any."""
    P = len(U0)
    north0 = [None] * P
    if use_heading:
        # the horizontal rate at rest is the Earth's once the gyro bias is out, and the bias is
        # what the rests' rates share once the Earth's is out: alternate the two
        S_g, T_p = rests.S_g, rests.T
        rate = S_g / T_p[:, None]
        vert = Om[2] * U0
        bg = np.average(rate - vert, axis=0, weights=T_p)
        for _ in range(30):
            hor = rate - bg - vert
            hor -= np.sum(hor * U0, axis=1)[:, None] * U0
            nb = np.linalg.norm(hor, axis=1)
            nvec = np.where(nb[:, None] > 0, hor / np.where(nb > 0, nb, 1.0)[:, None], 0.0)
            bg = np.average(rate - vert - Om[1] * nvec, axis=0, weights=T_p)
        north0 = [v if np.linalg.norm(v) > 0 else None for v in nvec]
    return np.array([frame(U0[p], north0[p]) for p in range(P)])


class Model:
    """The rows — per rest Σ Δv (3), then per rest Σ Δθ (3), then per turn Σ Δθ (3) — for
    calibration parameters ``th`` (the layout above) and attitudes ``C`` (P, 3, 3) body -> ENU;
    ``na`` angles per rest are estimated (2 tilts, + the heading with the latitude). ``Om`` the
    Earth rate in ENU, ``g`` gravity, ``dens_*`` the white noise per √s."""

    def __init__(self, rests: Rests, turns: list[Turn], g: float, Om: np.ndarray, na: int,
                 dens_g: np.ndarray, dens_a: np.ndarray):
        self.rests, self.turns, self.g, self.Om, self.na = rests, turns, g, Om, na
        self.dens_g, self.dens_a = dens_g, dens_a
        P = self.P = len(rests.T)
        self.nrow = 6 * P + 3 * len(turns)
        self.ncol = _NCAL + na * P
        T_p = rests.T
        self.sig_row = np.concatenate([(dens_a[None, :] * np.sqrt(T_p)[:, None]).ravel(),
                                       (dens_g[None, :] * np.sqrt(T_p)[:, None]).ravel(),
                                       np.concatenate([dens_g * math.sqrt(r.T) for r in turns]) if turns else []])
        self.y_obs = np.concatenate([rests.S_a.ravel(), rests.S_g.ravel()] + [r.sum for r in turns])

    @property
    def attitude_columns(self) -> list[int]:
        return list(range(_NCAL, self.ncol))

    def predict(self, th: np.ndarray, C: np.ndarray) -> np.ndarray:
        T_p, g = self.rests.T, self.g
        bg, G, ba, A = unpack(th)
        Kg, Ka = np.eye(3) + G, np.eye(3) + A
        U = C[:, 2, :]
        Ob = np.einsum("pij,i->pj", C, self.Om)
        f = g * U
        pa = T_p[:, None] * (f @ Ka.T + ba)
        pg = T_p[:, None] * (Ob @ Kg.T + bg)
        v = [r.angle * r.axis + r.M @ Ob[r.q] for r in self.turns]
        pr = [Kg @ vr + bg * r.T for vr, r in zip(v, self.turns)]
        return np.concatenate([pa.ravel(), pg.ravel()] + pr)

    def jacobian(self, th: np.ndarray, C: np.ndarray, determinability: bool = False) -> np.ndarray:
        """∂(rows)/∂(parameters, attitude angles), each row divided by its σ. ``determinability``:
        without the Earth rate's part in the gyro scale-factor and misalignment columns, so that
        those count as determined only where a turn excites them — scaled to unit length, the
        columns of a rate of 15 deg/h at rest would otherwise look as good as a turn's."""
        T_p, g, P, na = self.rests.T, self.g, self.P, self.na
        _, G, _, A = unpack(th)
        Kg, Ka = np.eye(3) + G, np.eye(3) + A
        U = C[:, 2, :]
        Ob = np.einsum("pij,i->pj", C, self.Om)
        f = g * U
        ez_x = skew(np.array([0.0, 0.0, 1.0]))
        om_x = skew(self.Om)
        J = np.zeros((self.nrow, self.ncol))
        for p in range(P):
            att = slice(_NCAL + na * p, _NCAL + na * (p + 1))
            Da = Ka @ (g * C[p].T @ ez_x)
            Dg = Kg @ (C[p].T @ om_x)
            for i in range(3):
                ra, rg = 3 * p + i, 3 * P + 3 * p + i
                J[ra, _AB + i] = T_p[p]
                J[ra, _A + 3 * i:_A + 3 * i + 3] = T_p[p] * f[p]
                J[ra, att] = T_p[p] * Da[i, :na]
                J[rg, _GB + i] = T_p[p]
                if not determinability:
                    J[rg, _G + 3 * i:_G + 3 * i + 3] = T_p[p] * Ob[p]
                J[rg, att] = T_p[p] * Dg[i, :na]
        for k, r in enumerate(self.turns):
            q = r.q
            att = slice(_NCAL + na * q, _NCAL + na * (q + 1))
            Dr = Kg @ (r.M @ C[q].T @ om_x)
            vr = r.angle * r.axis if determinability else r.angle * r.axis + r.M @ Ob[q]
            for i in range(3):
                row = 6 * P + 3 * k + i
                J[row, _GB + i] = r.T
                J[row, _G + 3 * i:_G + 3 * i + 3] = vr
                J[row, att] = Dr[i, :na]
        return J / self.sig_row[:, None]

    def chi2(self, th: np.ndarray, C: np.ndarray) -> float:
        r = (self.y_obs - self.predict(th, C)) / self.sig_row
        return float(r @ r)

    def heading_curvature(self, th: np.ndarray, C: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Σ_i r_i ∂²(pred_i/σ_i)/∂ψ_p² per position's heading ψ_p with the sign of the cost's
        Hessian: a heading turns the horizontal Earth rate, ∂²(C_pᵀ Ω_n)/∂ψ² = −C_pᵀ Ω_h."""
        P, T_p, sig_row = self.P, self.rests.T, self.sig_row
        Om_h = np.array([self.Om[0], self.Om[1], 0.0])
        _, G, _, _ = unpack(th)
        Kg = np.eye(3) + G
        out = np.zeros(P)
        for p in range(P):
            rows = slice(3 * P + 3 * p, 3 * P + 3 * p + 3)
            out[p] += r[rows] @ (T_p[p] * Kg @ C[p].T @ Om_h / sig_row[rows])
        for k, rt in enumerate(self.turns):
            rows = slice(6 * P + 3 * k, 6 * P + 3 * k + 3)
            out[rt.q] += r[rows] @ (Kg @ rt.M @ C[rt.q].T @ Om_h / sig_row[rows])
        return out

    def step(self, th: np.ndarray, C: np.ndarray, d: np.ndarray, free: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """The parameters ``free`` moved by the first entries of ``d``, each attitude turned (in
        ENU) by the rest, na angles per rest."""
        P, na = self.P, self.na
        th2 = th.copy()
        th2[free] += d[:len(free)]
        phi = d[len(free):].reshape(P, na)
        if na == 2:
            phi = np.hstack([phi, np.zeros((P, 1))])
        C2 = np.einsum("pij,pjk->pik", rotvec(phi), C)
        return th2, C2
