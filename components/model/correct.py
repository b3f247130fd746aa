"""Correct a raw IMU log with a calibration result (``calbench apply``).

The sensor model of components.model.effects maps the true input x (rate or specific force) to the
output y = x + e(x) with small e. The correction inverts it per sample by fixed-point iteration
x ← y − e(x), evaluated on the sample's mean rate / specific force (three passes reduce the
residual of the inversion to (|e'|)³ ~ 1e-12 of the signal for navigation-grade errors).
Each sample's own interval is used (a logger's measured clock: the rates were logged over it),
and the drift terms count from the start of the first interval, as calibrate counts them.
Lever arms use the angular acceleration from differences of the corrected gyro rates. Table
effects are properties of the table, not of the IMU, and are not applied; a time offset is not
re-timed (stated in the output's description).
"""
from __future__ import annotations

import copy

import numpy as np

from components.model.effects import AX, OFF_DIAG, PAIRS
from components.model.motion import lever_acceleration
from components.model.result import CalibrationResult

_MIS = {ij: (AX.index(ij[0]), AX.index(ij[1])) for ij in OFF_DIAG}


def _vec(res: CalibrationResult, effect: str) -> np.ndarray:
    return np.array([res.value(f"{effect}.{c}") for c in AX])


def _matrix(res: CalibrationResult, effect: str) -> np.ndarray:
    M = np.zeros((3, 3))
    for ij, (i, j) in _MIS.items():
        M[i, j] = res.value(f"{effect}.{ij}")
    return M


def sensor_error(res: CalibrationResult, sensor: str, x: np.ndarray, f: np.ndarray,
                 dT: np.ndarray, elapsed: np.ndarray) -> np.ndarray:
    """e(x) [rate units] for mean signals x (N, 3); f is the specific force (for gyro g-terms)."""
    e = x * _vec(res, f"{sensor}.sf") + np.abs(x) * _vec(res, f"{sensor}.sf_asym")
    e += x @ _matrix(res, f"{sensor}.mis").T
    e += _vec(res, f"{sensor}.bias") + dT[:, None] * _vec(res, f"{sensor}.temp")
    e += dT[:, None] * x * _vec(res, f"{sensor}.sf_temp") + elapsed[:, None] * _vec(res, f"{sensor}.drift")
    if sensor == "gyro":
        G = np.array([[res.value(f"gyro.gsens.{i}{j}") for j in AX] for i in AX])
        e += f @ G.T
        for k, i in enumerate(AX):
            for jk in PAIRS:
                c = res.value(f"gyro.g2sens.{i}.{jk}")
                if c:
                    e[:, k] += c * f[:, AX.index(jk[0])] * f[:, AX.index(jk[1])]
    else:
        e += _vec(res, "acc.k2") * x**2 + _vec(res, "acc.k3") * x**3
        for ij, (i, j) in _MIS.items():
            c = res.value(f"acc.cross.{ij}")
            if c:
                e[:, i] += c * x[:, i] * x[:, j]
    return e


def correct_increments(res: CalibrationResult, gyro_inc: np.ndarray, acc_inc: np.ndarray,
                       dt: np.ndarray, temperature: np.ndarray | None, temperature_ref: float | None = None,
                       elapsed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Corrected increments (N, 3) gyro [rad] and acc [m/s]; *dt* (N,) each sample's interval;
    *temperature_ref* the temperature the temperature terms count from (default: the result's,
    else the first sample's); *elapsed* (N,) the time since the drift terms' origin at each
    interval's middle (default: from the intervals, the first one's start the origin)."""
    dt = np.asarray(dt, float)[:, None]
    yg, ya = gyro_inc / dt, acc_inc / dt
    T = np.zeros(len(dt)) if temperature is None else np.asarray(temperature, float)
    T0 = temperature_ref if temperature_ref is not None else (
        res.temperature_ref if res.temperature_ref is not None else (T[0] if len(T) else 0.0))
    dT = T - T0
    mid = np.cumsum(dt[:, 0]) - dt[:, 0] / 2 if elapsed is None else np.asarray(elapsed, float)
    lever = np.array([[res.value(f"acc.lever.{i}.{k}") for k in AX] for i in AX])
    xg, xa = yg.copy(), ya.copy()
    for _ in range(3):
        xg = yg - sensor_error(res, "gyro", xg, xa, dT, mid)
        fa = ya.copy()
        if lever.any():
            alpha = np.gradient(xg, mid + dt[:, 0] / 2, axis=0)
            for k in range(3):
                r = lever[k]
                fa[:, k] -= lever_acceleration(xg, alpha, r)[:, k]
        xa = fa - sensor_error(res, "acc", xa, xa, dT, mid)
    return xg * dt, xa * dt


# samples corrected at a time (a long log's work arrays are ~0.3 KB a sample), and the samples
# each piece reads beyond its ends: the lever arm's angular acceleration differences a sample's
# neighbours, and each of the three passes carries that one sample further
CORRECT_SAMPLES = 1 << 16
CORRECT_MARGIN = 8


def _assign_rows(array: np.ndarray, start: int, values: np.ndarray) -> None:
    array[start:start + len(values)] = values


def _corrected(res: CalibrationResult, log, pieces: int, out=None, after_piece=None, put_rows=_assign_rows):
    """(gyro, acc) of the whole log corrected, in its output kinds (rates and specific forces
    over each interval, else increments), *pieces* samples at a time, each with CORRECT_MARGIN
    samples either side: the same values as in one piece; into *out* (two (N, 3) arrays) if
    given, each piece's rows by ``put_rows(array, start, rows)``; ``after_piece()`` after each
    piece. Each sample's own interval (a logger's measured clock: the rates were logged over
    those), and the drift terms' time from the start of the first interval, as calibrate counts
    it; a piece's at a time (two whole-log arrays were 0.5 GB on an 8-hour log)."""
    n = log.n
    start = float(log.time[0] - log.intervals(slice(0, 1))[0]) if n else 0.0
    g_inc, a_inc = log.gyro_increment(), log.acc_increment()
    g, a = out if out is not None else (np.empty((n, 3)), np.empty((n, 3)))
    T = log.temperature
    T0 = res.temperature_ref if res.temperature_ref is not None else (float(T[0]) if T is not None and n else 0.0)
    for lo in range(0, n, pieces):
        hi = min(lo + pieces, n)
        a0, b0 = max(lo - CORRECT_MARGIN, 0), min(hi + CORRECT_MARGIN, n)
        dt = log.intervals(slice(a0, b0))
        elapsed = (log.time[a0:b0] - start) - dt / 2
        gp, ap = correct_increments(res, g_inc[a0:b0], a_inc[a0:b0], dt,
                                    None if T is None else T[a0:b0], T0, elapsed)
        gp, ap = gp[lo - a0:hi - a0], ap[lo - a0:hi - a0]
        if log.gyro_output == "rate":
            gp = gp / dt[lo - a0:hi - a0, None]
        if log.acc_output == "specific_force":
            ap = ap / dt[lo - a0:hi - a0, None]
        put_rows(g, lo, gp)
        put_rows(a, lo, ap)
        if after_piece is not None:
            after_piece()
    return g, a


def correct_log(log, res: CalibrationResult, pieces: int = CORRECT_SAMPLES, into=None, after_piece=None,
                put_rows=_assign_rows):
    """A copy of the measurement log with corrected IMU outputs (same output kinds; counts are
    written as increments, since corrected values are no longer whole counts). *into*: the
    (gyro, acc) arrays (N, 3) to write them in (a long log's on disk), a piece's rows at a time by
    ``put_rows(array, start, rows)`` (components.logs.spill.write_rows for those: through their
    file, not faulted in page by page); ``after_piece()`` after each piece of the correction."""
    # (the corrected values in the log's output kinds: rates and forces over each interval,
    # else increments)
    g, a = _corrected(res, log, pieces, into, after_piece, put_rows)
    out = copy.copy(log)
    if log.gyro_output == "rate":
        out.gyro = g
    else:
        out.gyro, out.gyro_output, out.gyro_count_rad = g, "increment", None
    if log.acc_output == "specific_force":
        out.acc = a
    else:
        out.acc, out.acc_output, out.acc_count_mps = a, "increment", None
    notes = [f"corrected with a calbench result ({', '.join(res.effects)})"]
    for name in ("imu.time_offset", "acc.time_offset"):
        if res.value(name):
            notes.append(f"{name} {res.value(name):.6g} s not re-timed")
    out.description = (log.description + "; " if log.description else "") + "; ".join(notes)
    return out
