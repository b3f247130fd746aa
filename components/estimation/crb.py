"""Cramér–Rao bound of a calibration schedule for a noise model.

The observations are the least-squares engine's block sums (components.estimation.lsq), so the bound is the
one the estimator can reach. Noise model per sensor axis: white noise (σ per sample, i.e.
ARW/VRW) plus bias instability as a nuisance: a first-order Gauss–Markov bias with standard
deviation σ_GM and correlation time τ, discretised into windows of length w (≤ τ) whose offsets
form an AR(1) sequence with φ = exp(-w/τ) and prior precision from its exact stationary
covariance. The information of the parameters of interest is the Schur complement

    J = F_θθ − F_θn (F_nn + P_n)^{-1} F_nθ,   CRB = J^{-1}

with F = Hᵀ R⁻¹ H over [θ, nuisance] and P_n the prior precision of the nuisance offsets.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from components.estimation.blocks import observation_blocks
from components.estimation.design import design
from components.estimation.log_data import LogData
from components.estimation.rest_angles import rest_sigma
from components.model.effects import effect_of, parameters_of

# sigma of the Gauss–Markov process whose Allan-deviation peak equals the IEEE bias-instability
# floor 0.664 B (the same constants as the IMU FMU, fmus/imu/noise.c)
FLICKER_FLOOR = 0.664282
GM_PEAK = 0.617364


@dataclass(frozen=True)
class NoiseModel:
    gyro_arw: float = 0.0       # rad/sqrt(s)
    acc_vrw: float = 0.0        # m/s/sqrt(s)
    gyro_bi: float = 0.0        # rad/s (IEEE bias instability B)
    acc_bi: float = 0.0         # m/s2
    bi_tau: float = 100.0       # s, correlation time of the bias-instability process

    @classmethod
    def navigation_grade(cls) -> "NoiseModel":
        from components.model.effects import DEG, UG

        return cls(gyro_arw=0.002 * DEG / 60, acc_vrw=10 * UG, gyro_bi=0.003 * DEG / 3600,
                   acc_bi=5 * UG)


def _ar1_precision(n: int, sigma: float, phi: float) -> np.ndarray:
    """Precision of a stationary AR(1) sequence of n values with marginal σ and coefficient φ."""
    if n == 0:
        return np.zeros((0, 0))
    q = sigma**2 * (1 - phi**2)
    P = np.zeros((n, n))
    idx = np.arange(n)
    P[idx, idx] = (1 + phi**2) / q
    P[0, 0] = P[-1, -1] = 1 / q
    if n == 1:
        P[0, 0] = 1 / sigma**2
    P[idx[:-1], idx[1:]] = P[idx[1:], idx[:-1]] = -phi / q
    return P


def cramer_rao(data: LogData, effects: list[str], noise: NoiseModel, chunk_s: float = 1.0,
               window_s: float | None = None, rest_angle_sigma=None) -> dict[str, float]:
    """σ bound per parameter of *effects* on the motion of *data* (its IMU values are unused).
    ``rest_angle_sigma``: as for components.estimation.lsq.calibrate."""
    params = parameters_of(effects)
    table_params = [p for p in params if effect_of(p).target == "table"]
    geo = data.geometry
    dt = float(np.median(np.diff(data.time)))
    motion = data.motion(geo)
    n_chunk = max(1, int(round(chunk_s / dt)))
    gb, ab = observation_blocks(motion.static, data.angles, n_chunk)
    sg = np.full(3, max(noise.gyro_arw * np.sqrt(dt), 1e-30))
    sa = np.full(3, max(noise.acc_vrw * np.sqrt(dt), 1e-30))
    q = rest_sigma(data.angles, rest_angle_sigma)
    # the design needs a measurement only for its residual: use the ideal one
    ideal = LogData(data.time, data.angles, motion.ideal_gyro, motion.ideal_acc, geo,
                    data.temperature, data.segment, data.dt0)
    ideal._profiles = data._profiles

    def motion_for(g):
        return data.motion(g)

    _, H, w, rows = design(ideal, motion, params, gb, ab, sg, sa, q, geo, table_params, motion_for)
    Hw = H * w[:, None]

    # bias-instability nuisance: per sensor axis, AR(1) offsets over windows
    t_mid = (data.time[rows["start"]] + data.time[np.maximum(rows["stop"] - 1, 0)]) / 2
    n_cols, prior_blocks = [], []
    span = data.time[-1] - data.time[0] + dt
    for sensor, bi in (("gyro", noise.gyro_bi), ("acc", noise.acc_bi)):
        if bi <= 0:
            continue
        sigma = bi * FLICKER_FLOOR / GM_PEAK
        win = window_s or min(noise.bi_tau, span)
        n_win = max(1, int(np.ceil(span / win)))
        k = np.minimum(((t_mid - data.time[0]) / win).astype(int), n_win - 1)
        duration = (rows["stop"] - rows["start"]) * dt
        for axis in range(3):
            sel = (rows["sensor"] == sensor) & (rows["axis"] == axis)
            cols = np.zeros((len(w), n_win))
            cols[np.nonzero(sel)[0], k[sel]] = duration[sel]
            n_cols.append(cols * w[:, None])
            prior_blocks.append(_ar1_precision(n_win, sigma, np.exp(-win / noise.bi_tau)))
    F = Hw.T @ Hw
    if n_cols:
        N = np.hstack(n_cols)
        P = np.zeros((N.shape[1], N.shape[1]))
        o = 0
        for b in prior_blocks:
            P[o:o + len(b), o:o + len(b)] = b
            o += len(b)
        Fnn = N.T @ N + P
        Ftn = Hw.T @ N
        F = F - Ftn @ np.linalg.solve(Fnn, Ftn.T)
    scale = np.sqrt(np.clip(np.diag(F), 1e-300, None))
    cov = np.linalg.pinv(F / np.outer(scale, scale), rcond=1e-12) / np.outer(scale, scale)
    return dict(zip(params, np.sqrt(np.clip(np.diag(cov), 0, None))))
