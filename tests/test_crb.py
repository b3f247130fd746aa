"""The Cramér–Rao bound against Monte-Carlo: noise of the stated model added to the shared ideal
run (an independent simulator's noise-free data), calibrated again and again; the empirical
spread of the estimates must match the bound."""
import math
from pathlib import Path

import numpy as np
import pytest

from components.estimation.crb import FLICKER_FLOOR, GM_PEAK, NoiseModel, cramer_rao
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS, DEG, UG


@pytest.fixture(scope="module")
def ideal(conformance: Path):
    return LogData.from_log(read_log(conformance / "ideal"))


def _noisy(data: LogData, noise: NoiseModel, rng: np.random.Generator) -> LogData:
    n, dt = len(data.time), float(np.median(np.diff(data.time)))
    g = data.gyro + noise.gyro_arw * math.sqrt(dt) * rng.standard_normal((n, 3))
    a = data.acc + noise.acc_vrw * math.sqrt(dt) * rng.standard_normal((n, 3))
    if noise.acc_bi:
        # exact AR(1) discretisation of the Gauss–Markov bias, added as bias * dt
        sigma = noise.acc_bi * FLICKER_FLOOR / GM_PEAK
        phi = math.exp(-dt / noise.bi_tau)
        x = np.empty((n, 3))
        x[0] = sigma * rng.standard_normal(3)
        e = sigma * math.sqrt(1 - phi**2) * rng.standard_normal((n, 3))
        for k in range(1, n):
            x[k] = phi * x[k - 1] + e[k]
        a = a + x * dt
    return LogData(data.time, data.angles, g, a, data.geometry, data.temperature, data.segment, data.dt0)


def test_white_noise_monte_carlo_matches_crb(ideal):
    noise = NoiseModel(gyro_arw=0.002 * DEG / 60, acc_vrw=10 * UG)
    # the independent simulator's rest angles are exact counts
    crb = cramer_rao(ideal, list(DEFAULT_EFFECTS), noise, rest_angle_sigma=0.0)
    rng = np.random.default_rng(20261122)
    z = []
    for _ in range(10):
        fit = calibrate(_noisy(ideal, noise, rng), list(DEFAULT_EFFECTS), rest_angle_sigma=0.0)
        z.append([v / crb[p] for p, v in zip(fit.parameters, fit.value)])  # truth is zero
    z = np.array(z)
    # 240 normalised errors: RMS 1 within sampling error (±3 σ of the RMS estimate ≈ 0.14)
    assert abs(np.sqrt(np.mean(z**2)) - 1) < 0.14, np.sqrt(np.mean(z**2))
    assert abs(np.mean(z)) < 0.25


def test_bias_instability_nuisance_bound_covers_monte_carlo(ideal):
    # accelerometer bias instability dominates the accelerometer bias estimate: the white-only
    # bound is far too optimistic, the bound with the nuisance matches the spread
    noise = NoiseModel(gyro_arw=0.002 * DEG / 60, acc_vrw=10 * UG, acc_bi=20 * UG, bi_tau=100.0)
    white = cramer_rao(ideal, ["acc.bias"], NoiseModel(gyro_arw=noise.gyro_arw, acc_vrw=noise.acc_vrw))
    full = cramer_rao(ideal, ["acc.bias"], noise)
    rng = np.random.default_rng(7)
    est = np.array([calibrate(_noisy(ideal, noise, rng), ["acc.bias"]).value for _ in range(12)])
    rms = np.sqrt(np.mean(est**2))
    assert rms > 3 * white["acc.bias.x"]
    # 36 values: the RMS estimate is within ±40 % of the true σ at 3 sigma
    assert 0.6 < rms / full["acc.bias.x"] < 1.4, rms / full["acc.bias.x"]
