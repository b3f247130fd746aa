"""The Cramér–Rao bound against Monte-Carlo: noise of the stated model added to the shared ideal
run (an independent simulator's noise-free data), calibrated again and again; the empirical
spread of the estimates must match the bound."""
import math
from pathlib import Path

import numpy as np
import pytest

from components.estimation.crb import cramer_rao
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS, DEG, UG
from components.model.noise import NoiseModel

GM_SIGMA = 20 * UG * 0.664282 / 0.617364  # a Gauss–Markov bias whose ADEV peak is a 20 ug floor


@pytest.fixture(scope="module")
def ideal(conformance: Path):
    return LogData.from_log(read_log(conformance / "ideal"))


def _noisy(data: LogData, noise: NoiseModel, rng: np.random.Generator) -> LogData:
    """Sample-level noise of the model (white + Gauss–Markov terms), written independently of
    the block-level discrete form the estimators use."""
    n, dt = len(data.time), float(np.median(np.diff(data.time)))
    g = data.gyro + noise.channels[0].white * math.sqrt(dt) * rng.standard_normal((n, 3))
    a = data.acc + noise.channels[3].white * math.sqrt(dt) * rng.standard_normal((n, 3))
    for sigma, tau in noise.channels[3].gauss_markov:
        # exact AR(1) discretisation of the Gauss–Markov bias, added as bias * dt
        phi = math.exp(-dt / tau)
        x = np.empty((n, 3))
        x[0] = sigma * rng.standard_normal(3)
        e = sigma * math.sqrt(1 - phi**2) * rng.standard_normal((n, 3))
        for k in range(1, n):
            x[k] = phi * x[k - 1] + e[k]
        a = a + x * dt
    return LogData(data.time, data.angles, g, a, data.geometry, data.temperature, data.segment, data.dt0)


def test_white_noise_monte_carlo_matches_crb(ideal):
    noise = NoiseModel.per_sensor({"white": 0.002 * DEG / 60}, {"white": 10 * UG})
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


def test_coloured_noise_bound_and_whitened_estimates_match_monte_carlo(ideal):
    # an accelerometer Gauss–Markov bias dominates the accelerometer bias estimate: the white-only
    # bound is far too optimistic; the bound under the coloured model matches the spread, and the
    # least squares whitened with that model reports σ that match it too
    white = NoiseModel.per_sensor({"white": 0.002 * DEG / 60}, {"white": 10 * UG})
    noise = NoiseModel.per_sensor({"white": 0.002 * DEG / 60},
                                  {"white": 10 * UG, "gauss_markov": ((GM_SIGMA, 100.0),)})
    crb_white = cramer_rao(ideal, ["acc.bias"], white)
    full = cramer_rao(ideal, ["acc.bias"], noise)
    rng = np.random.default_rng(7)
    fits = [calibrate(_noisy(ideal, noise, rng), ["acc.bias"], noise=noise) for _ in range(12)]
    est = np.array([f.value for f in fits])
    rms = np.sqrt(np.mean(est**2))
    assert rms > 3 * crb_white["acc.bias.x"]
    # 36 values: the RMS estimate is within ±40 % of the true σ at 3 sigma
    assert 0.6 < rms / full["acc.bias.x"] < 1.4, rms / full["acc.bias.x"]
    # the fit's σ is the bound (same design, same model)
    assert fits[0].sigma[0] == pytest.approx(full["acc.bias.x"], rel=1e-6)
