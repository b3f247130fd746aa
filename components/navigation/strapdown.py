"""Strapdown navigation in ENU from increments on a stationary base.

Two IMU samples form one navigation step (the standard two-sample forms; Savage, *Strapdown
Analytics* §7, Titterton & Weston §11):

- attitude: rotation vector ``φ = Δθ1 + Δθ2 + (2/3) Δθ1 × Δθ2`` (coning correction);
  ``C_b^n ← Rot(−ω_in^n T) C_b^n Rot(φ)`` (n rotates with the Earth, ω_in = ω_ie: the base is
  stationary, the transport rate of a velocity of mm/s is below 1e-9 of ω_ie);
- velocity: ``Δv_b = Δv + ½ Δθ × Δv + (2/3)(Δθ1 × Δv2 + Δv1 × Δθ2)`` (rotation compensation and
  sculling correction, Δθ, Δv the sums over the step; the rotation compensation in Savage's
  closed form, whose second-order term (1/6) Δθ × (Δθ × Δv) matters at table rates: without it
  a constant 30 °/s rotation leaves a 5e-6 g bias), ``Δv^n = (I − ½ [ω_in T ×]) C_b^n Δv_b``,
  ``v ← v + Δv^n + (g^n − 2 ω_ie × v) T``;
- position: latitude, longitude and height integrate the velocity (their errors are kept as
  states), while gravity and Earth rate use the fixed site (the base does not move).

An odd number of samples leaves the last one for a single-sample step (no correction terms).
"""
from __future__ import annotations

import math

import numpy as np

from components.navigation.earth import Site


def rot(v) -> np.ndarray:
    """Rodrigues matrix of a rotation vector (3,) -> (3, 3)."""
    x, y, z = float(v[0]), float(v[1]), float(v[2])
    t2 = x * x + y * y + z * z
    if t2 < 1e-24:
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        t = math.sqrt(t2)
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    return np.array([[1 - b * (y * y + z * z), -a * z + b * x * y, a * y + b * x * z],
                     [a * z + b * x * y, 1 - b * (x * x + z * z), -a * x + b * y * z],
                     [-a * y + b * x * z, a * x + b * y * z, 1 - b * (x * x + y * y)]])


def cross(a, b) -> np.ndarray:
    """a × b for (3,) vectors (np.cross is ~10x slower on small arrays)."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def orthonormalize(C: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(C)
    return u @ vt


def coning(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    return d1 + d2 + (2.0 / 3.0) * cross(d1, d2)


def rotation_compensation(dth, dv) -> np.ndarray:
    """Savage's closed form ((1 − cos α)/α²) α × Δv + (1/α²)(1 − sin α/α) α × (α × Δv): the
    first-order ½ α × Δv alone leaves −(α²/6) Δv, a 5e-6 g bias at 30 °/s and 100 Hz."""
    a2 = float(dth @ dth)
    if a2 < 1e-8:
        c1, c2 = 0.5 - a2 / 24.0, 1.0 / 6.0 - a2 / 120.0
    else:
        a = math.sqrt(a2)
        c1, c2 = (1 - math.cos(a)) / a2, (1 - math.sin(a) / a) / a2
    ax = cross(dth, dv)
    return c1 * ax + c2 * cross(dth, ax)


def sculling(d1, d2, v1, v2) -> np.ndarray:
    dth, dv = d1 + d2, v1 + v2
    return dv + rotation_compensation(dth, dv) + (2.0 / 3.0) * (cross(d1, v2) + cross(v1, d2))


class Strapdown:
    """State: C_b^n (3, 3), v^n (3,), position [L, λ, h]; step() consumes one or two samples."""

    def __init__(self, site: Site, C_bn: np.ndarray, dt: float, v=None, pos=None):
        self.site = site
        self.C = np.array(C_bn, float)
        self.v = np.zeros(3) if v is None else np.array(v, float)
        self.pos = np.array([site.latitude, 0.0, site.height]) if pos is None else np.array(pos, float)
        self.dt = dt
        self._w_ie = site.w_ie
        self._g = site.g_n
        self._rm, self._rn = site.rm, site.rn
        self._cosl = math.cos(site.latitude)
        self._earth_rot = {}

    def _nav_rot(self, T: float) -> np.ndarray:
        m = self._earth_rot.get(T)
        if m is None:
            m = self._earth_rot[T] = rot(-self._w_ie * T)
        return m

    def step(self, dth: np.ndarray, dv: np.ndarray) -> None:
        """One step over the samples dth, dv (1 or 2, 3)."""
        if len(dth) == 2:
            phi = coning(dth[0], dth[1])
            dvb = sculling(dth[0], dth[1], dv[0], dv[1])
        else:
            phi = dth[0]
            dvb = dv[0] + rotation_compensation(dth[0], dv[0])
        T = self.dt * len(dth)
        wT = self._w_ie * T
        dvn = self.C @ dvb
        dvn = dvn - 0.5 * cross(wT, dvn)
        v0 = self.v
        self.v = v0 + dvn + (self._g - 2.0 * cross(self._w_ie, v0)) * T
        vm = 0.5 * (v0 + self.v)
        self.pos = self.pos + T * np.array([vm[1] / self._rm, vm[0] / (self._rn * self._cosl), vm[2]])
        self.C = self._nav_rot(T) @ self.C @ rot(phi)

    def correct(self, phi: np.ndarray, dv: np.ndarray, dpos: np.ndarray) -> None:
        """Feedback of estimated errors: C_true = (I + [φ×]) C (φ the computed-frame error, as
        C_computed = (I − [φ×]) C_true), v_true = v − δv, pos_true = pos − δpos."""
        self.C = orthonormalize(rot(phi) @ self.C)
        self.v = self.v - dv
        self.pos = self.pos - dpos


def navigate(gyro: np.ndarray, acc: np.ndarray, dt: float, site: Site, C_bn0: np.ndarray,
             record_every: int = 1):
    """Open-loop navigation over all samples (pairs). Returns sample indices (end of each
    recorded step), C_b^n (K, 3, 3), v (K, 3), pos (K, 3)."""
    nav = Strapdown(site, C_bn0, dt)
    n = len(gyro)
    idx, Cs, vs, ps = [], [], [], []
    k, s = 0, 0
    while k < n:
        m = 2 if k + 1 < n else 1
        nav.step(gyro[k:k + m], acc[k:k + m])
        k += m
        s += 1
        if s % record_every == 0 or k >= n:
            idx.append(k - 1)
            Cs.append(nav.C.copy())
            vs.append(nav.v.copy())
            ps.append(nav.pos.copy())
    return np.array(idx), np.array(Cs), np.array(vs), np.array(ps)
