"""The cubic spline through a moving run's measured angles.

Twice continuously differentiable, cubic between knots, with each end either *clamped* (slope 0:
the table at rest before or after the run) or *not-a-knot* (the third derivative continuous at
the second knot: the run cut by the log's edge, where nothing is known of the slope). These are
the conditions ``scipy.interpolate.CubicSpline`` calls ``(1, 0)`` and ``"not-a-knot"`` and the
tests check against it; calbench solves them itself because importing scipy.interpolate took
~0.15 s of every command (a tenth of a diagnose on a 40-minute log) for this one curve.

The slopes s_i at the knots follow from the second derivative being continuous at every inner
knot (h_i = x_{i+1} − x_i, m_i the chord slope of interval i):

    h_i s_{i−1} + 2 (h_{i−1} + h_i) s_i + h_{i−1} s_{i+1} = 3 (h_i m_{i−1} + h_{i−1} m_i),

a tridiagonal system closed by the two end conditions; each interval is then the cubic Hermite
polynomial of its two knots' values and slopes.
"""
from __future__ import annotations

import numpy as np


def knot_slopes(x: np.ndarray, y: np.ndarray, clamp_start: bool, clamp_end: bool) -> np.ndarray:
    """dy/dx at the knots *x* (n,) of the values *y* (n, k). Not-a-knot needs four knots or
    more; with fewer both ends must be clamped."""
    # imported here: the CLI's parser imports this module, and scipy.linalg costs 0.15 s of
    # every command's start
    from scipy.linalg import solve_banded

    x = np.asarray(x, float)
    y = np.asarray(y, float).reshape(len(x), -1)
    n = len(x)
    h = np.diff(x)
    if n < 2 or not np.all(h > 0):
        raise ValueError(f"spline knots must be at least two and strictly increasing (got {n})")
    if n < 4 and not (clamp_start and clamp_end):
        raise ValueError(f"a not-a-knot end needs at least four knots (got {n})")
    chord = np.diff(y, axis=0) / h[:, None]
    band = np.zeros((3, n))  # rows: upper diagonal, diagonal, lower diagonal (solve_banded's layout)
    rhs = np.empty_like(y)
    band[0, 2:] = h[:-1]
    band[1, 1:-1] = 2 * (h[:-1] + h[1:])
    band[2, :-2] = h[1:]
    rhs[1:-1] = 3 * (h[1:, None] * chord[:-1] + h[:-1, None] * chord[1:])
    if clamp_start:
        band[1, 0], band[0, 1], rhs[0] = 1.0, 0.0, 0.0
    else:
        d = x[2] - x[0]
        band[1, 0], band[0, 1] = h[1], d
        rhs[0] = ((h[0] + 2 * d) * h[1] * chord[0] + h[0] ** 2 * chord[1]) / d
    if clamp_end:
        band[1, -1], band[2, -2], rhs[-1] = 1.0, 0.0, 0.0
    else:
        d = x[-1] - x[-3]
        band[1, -1], band[2, -2] = h[-2], d
        rhs[-1] = (h[-1] ** 2 * chord[-2] + (2 * d + h[-1]) * h[-2] * chord[-1]) / d
    return solve_banded((1, 1), band, rhs, overwrite_ab=True, overwrite_b=True, check_finite=False)


class RunSpline:
    """The spline of one run, evaluated by interval and offset into it (the caller knows which
    interval a point lies in: a sample's quadrature nodes lie in the sample's own interval)."""

    def __init__(self, x: np.ndarray, y: np.ndarray, clamp_start: bool, clamp_end: bool):
        x = np.asarray(x, float)
        y = np.asarray(y, float).reshape(len(x), -1)
        s = knot_slopes(x, y, clamp_start, clamp_end)
        self.h = np.diff(x)
        h = self.h[:, None]
        chord = np.diff(y, axis=0) / h
        t = (s[:-1] + s[1:] - 2 * chord) / h
        # p(u) = ((c3 u + c2) u + c1) u + c0 on interval i, u = x − x_i in [0, h_i]
        self.c0, self.c1 = y[:-1], s[:-1]
        self.c2 = (chord - s[:-1]) / h - t
        self.c3 = t / h
        self.intervals = len(h)

    def __call__(self, interval: np.ndarray, u: np.ndarray, derivative: int = 0) -> np.ndarray:
        """Value (or its first or second derivative) at offset *u* into *interval*, both of the
        same shape S; result S + (k,)."""
        if derivative not in (0, 1, 2):
            raise ValueError(f"derivative {derivative}: 0, 1 or 2")
        return self.with_derivatives(interval, u)[derivative]

    def with_derivatives(self, interval: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Value, first and second derivative at offset *u* into *interval* (the coefficients
        gathered once)."""
        i = np.asarray(interval)
        u = np.asarray(u, float)[..., None]
        c0, c1, c2, c3 = self.c0[i], self.c1[i], self.c2[i], self.c3[i]
        return ((c3 * u + c2) * u + c1) * u + c0, (3 * c3 * u + 2 * c2) * u + c1, 6 * c3 * u + 2 * c2

    def at_knots(self, knots: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Value, first and second derivative at knot indices *knots* (0 … intervals): from the
        interval that starts there, the last knot from the interval that ends there."""
        k = np.asarray(knots)
        i = np.minimum(k, self.intervals - 1)
        return self.with_derivatives(i, np.where(k == self.intervals, self.h[i], 0.0))
