"""Effect regressors evaluated on the IMU's own measured motion.

The system-level filter has no table angles: the contribution of one unit of each effect
parameter to each sample's increment (components.model.effects, the same regressors the least-squares
engine uses) is evaluated on a :class:`components.model.motion.Motion` built from the IMU data:
rate and specific force at the sample midpoints from the increments, the interval-end values
from neighbouring samples (their mean), angular acceleration from the interval-end rates (central
differences). Errors of this evaluation are products of two small quantities (the parameter
residual times the sensor error or noise), below the filter's resolution.

Where the table starts or stops (``static``: the samples the table rests through, from its
angles), the mean of the two neighbours would put half of the first moving sample's rate at the
end of the last resting one: its tangential lever-arm and time-offset terms would then act in a
sample where the table does not move, and a correction by them would put a velocity into a rest
(on the 19-position sequence's fast three-gimbal moves, exactly what made the filter attribute
it to lever arms and diverge). There the interval-end value is the resting sample's own.

The rates the motion is evaluated on are the gyro data corrected by the current estimates
(:meth:`Regressors.on_estimated_motion`), not the raw ones: the lever-arm terms α × r and
ω × (ω × r) are the table's true motion's, and a gyro misalignment turns the raw rates about
another axis. With the IMU 10 cm off the rotation centre (external table), 1e-4 rad of gyro
misalignment in the lever-arm correction left ~1e-5 m/s and m per index, which the filter read
as gyro bias (noise-free: 0.0067 deg/h) and scale factor (0.28 ppm); on the corrected rates
4e-4 deg/h and 0.05 ppm. The accelerometer data stay raw: their misalignment and scale act on
the specific force at the accelerometers, lever-arm terms included.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from components.model.effects import effect_of, regressor_of
from components.model.motion import Motion


def _interval_ends(x: np.ndarray, static: np.ndarray | None) -> np.ndarray:
    """(N+1, 3) values at the interval boundaries: the neighbours' mean, or a resting sample's
    own value where the table rests on one side."""
    xp = np.concatenate([x[:1], x, x[-1:]])
    ends = 0.5 * (xp[1:] + xp[:-1])
    if static is not None:
        sp = np.concatenate([[False], np.asarray(static, bool), [False]])
        before, after = sp[:-1], sp[1:]       # the sample ending / starting at each boundary
        ends = np.where(before[:, None], xp[:-1], np.where(after[:, None], xp[1:], ends))
    return ends


def measured_motion(gyro: np.ndarray, acc: np.ndarray, dt: float, t0: float = 0.0,
                    temperature: np.ndarray | None = None, t_ref: float | None = None,
                    static: np.ndarray | None = None) -> Motion:
    """Motion (one node per interval, at its midpoint) from increments (N, 3); ``static`` (N,):
    the samples the table rests through (None: not known)."""
    n = len(gyro)
    w = gyro / dt
    f = acc / dt
    w_b = _interval_ends(w, static)  # (N+1,) boundaries
    f_b = _interval_ends(f, static)
    alpha = (w_b[1:] - w_b[:-1]) / dt
    if temperature is not None:
        T0 = float(temperature[0]) if t_ref is None else t_ref
        dtemp = (np.asarray(temperature, float) - T0)[:, None]
    else:
        T0, dtemp = 0.0, np.zeros((n, 1))
    kw = dict(time=t0 + dt * np.arange(1, n + 1), dt=np.full(n, dt), static=np.zeros(n, bool),
              nodes=np.array([0.5]), weights=np.array([1.0]), omega_q=w[:, None, :],
              alpha_q=alpha[:, None, :], f_q=f[:, None, :], omega_start=w_b[:-1],
              omega_end=w_b[1:], f_start=f_b[:-1], f_end=f_b[1:], dtemp_q=dtemp,
              elapsed_q=(t0 + dt * (np.arange(n) + 0.5))[:, None], t0_temperature=T0,
              lever=np.zeros((3, 3)))
    names = {f.name for f in dataclasses.fields(Motion)}
    if "alpha_end" in names:
        a_b = np.concatenate([alpha[1:], alpha[-1:]])
        kw["alpha_end"] = 0.5 * (alpha + a_b)
    return Motion(**{k: v for k, v in kw.items() if k in names})


class Regressors:
    """Per-sample regressors of *parameters* on the measured data, computed by chunks (an hour
    at 200 Hz with 30 parameters would be ~1 GB at once). ``block(a, b)`` -> (G, A), each
    (b - a, 3, m): gyro and accelerometer increments per unit parameter."""

    def __init__(self, parameters: list[str], gyro: np.ndarray, acc: np.ndarray, dt: float,
                 temperature: np.ndarray | None = None, chunk: int = 8000,
                 static: np.ndarray | None = None, motion_gyro: np.ndarray | None = None):
        self.parameters = list(parameters)
        self.gyro, self.acc, self.dt = gyro, acc, dt
        # the rates the motion is evaluated on (default: the data's): the gyro increments
        # corrected by the current estimates, see on_estimated_motion()
        self.motion_gyro = gyro if motion_gyro is None else motion_gyro
        self.temperature = temperature
        self.static = None if static is None else np.asarray(static, bool)
        self.chunk = chunk
        self._cache: tuple[int, int, np.ndarray, np.ndarray] | None = None

    @classmethod
    def on_estimated_motion(cls, parameters: list[str], values: np.ndarray, gyro: np.ndarray,
                            acc: np.ndarray, dt: float, temperature: np.ndarray | None = None,
                            static: np.ndarray | None = None) -> "Regressors":
        """Regressors of *parameters* on the motion the data show once corrected by *values*
        (the gyro increments corrected to first order: regressors on the raw rates)."""
        values = np.asarray(values, float)
        # only the rates are re-evaluated: the parameters acting on the gyros (gyro effects, the
        # IMU's clock) correct them, the accelerometer-only ones would be computed for nothing
        rate_side = [k for k, p in enumerate(parameters) if effect_of(p).target in ("gyro", "imu")]
        if not any(values[k] for k in rate_side):
            return cls(parameters, gyro, acc, dt, temperature, static=static)
        rates = cls([parameters[k] for k in rate_side], gyro, acc, dt, temperature, static=static)
        return cls(parameters, gyro, acc, dt, temperature, static=static,
                   motion_gyro=rates.correct(values[rate_side])[0])

    def _compute(self, a: int, b: int):
        n = len(self.gyro)
        lo, hi = max(a - 1, 0), min(b + 1, n)
        temp = None if self.temperature is None else self.temperature[lo:hi]
        t_ref = None if self.temperature is None else float(self.temperature[0])
        st = None if self.static is None else self.static[lo:hi]
        m = measured_motion(self.motion_gyro[lo:hi], self.acc[lo:hi], self.dt, lo * self.dt, temp, t_ref, st)
        k = len(self.parameters)
        G = np.zeros((hi - lo, 3, k))
        A = np.zeros((hi - lo, 3, k))
        for j, p in enumerate(self.parameters):
            g, ac = regressor_of(m, p)
            if g is not None:
                G[:, :, j] = g
            if ac is not None:
                A[:, :, j] = ac
        return G[a - lo:b - lo], A[a - lo:b - lo]

    def block(self, a: int, b: int):
        c = self._cache
        if c is None or not (c[0] <= a and b <= c[1]):
            start = a
            stop = min(max(b, a + self.chunk), len(self.gyro))
            G, A = self._compute(start, stop)
            self._cache = c = (start, stop, G, A)
        return c[2][a - c[0]:b - c[0]], c[3][a - c[0]:b - c[0]]

    def correct(self, values: np.ndarray, chunk: int = 20000):
        """Corrected increments (raw − regressors · values) for all samples."""
        g, a = self.gyro.copy(), self.acc.copy()
        if not self.parameters or not np.any(values):
            return g, a
        for s in range(0, len(g), chunk):
            G, A = self._compute(s, min(s + chunk, len(g)))
            g[s:s + len(G)] -= G @ values
            a[s:s + len(A)] -= A @ values
        return g, a
