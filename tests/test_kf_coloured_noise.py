"""The system-level filter's slow-noise states (components.navigation.kf.noise_states) against an
independent computation: on a level IMU at rest the vertical velocity is the integral of the
vertical accelerometer's error, so the filter's σ of acc.bias.z is the generalised least
squares' σ with the exact covariance of the integrated Gauss–Markov, white and initial velocity
errors (a dense K × K matrix, closed form). With the Gauss–Markov term as a state the two agree;
without it the filter claims a σ several times too small, and a Monte-Carlo of its errors shows it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from components.model.noise import ChannelNoise, NoiseModel
from components.navigation.earth import Site
from components.navigation.kf import FilterSettings, noise_states, run_filter

DT, SECONDS = 0.01, 60.0
SIGMA_A = 2e-5          # per-sample white velocity increment [m/s]
GM_SIGMA, GM_T = 2e-4, 15.0   # the accelerometer z's Gauss–Markov bias [m/s²], [s]
RW_K = 4e-5             # or its random walk [m/s²/√s]
PRIOR = 1e-3            # σ of the prior on acc.bias.z [m/s²]
SITE = Site(math.radians(40.0))


class BiasZ:
    """Regressors of acc.bias.z alone: a bias of 1 m/s² adds dt to each z increment."""

    def block(self, a, b):
        G = np.zeros((b - a, 3, 1))
        A = np.zeros((b - a, 3, 1))
        A[:, 2, 0] = DT
        return G, A


def _data(rng, bias):
    n = int(SECONDS / DT)
    phi = math.exp(-DT / GM_T)
    x = np.empty(n)
    x[0] = rng.normal() * GM_SIGMA
    e = rng.normal(size=n) * GM_SIGMA * math.sqrt(1 - phi * phi)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + e[k]
    gyro = np.tile(SITE.w_ie * DT, (n, 1))   # body axes along east, north, up
    acc = np.tile(np.array([0.0, 0.0, SITE.g]) * DT, (n, 1))
    acc += rng.normal(size=(n, 3)) * SIGMA_A
    acc[:, 2] += (bias + x) * DT
    return gyro, acc


def _settings(with_states: bool, slow: str = "gm") -> FilterSettings:
    s = FilterSettings(parameters=["acc.bias.z"], prior_sigma={"acc.bias.z": PRIOR}, passes=1,
                       sigma_gyro=1e-9, sigma_acc=SIGMA_A, phi0=(1e-5, 1e-5, 1e-4))
    if with_states:
        z = ChannelNoise(gauss_markov=((GM_SIGMA, GM_T),)) if slow == "gm" else ChannelNoise(random_walk=RW_K)
        noise = NoiseModel((ChannelNoise(),) * 5 + (z,))
        states, fast = noise_states(noise, s.kf_interval, SECONDS)
        assert len(states) == 1 and not fast.any()
        s.noise_states = tuple(states)
    return s


def _filter(gyro, acc, with_states: bool, slow: str = "gm"):
    n = len(gyro)
    return run_filter(gyro, acc, DT, SITE, np.eye(3), np.ones(n, bool), _settings(with_states, slow), BiasZ(),
                      np.zeros(1), prior_mean=np.zeros(1))


def _gls_sigma(settings: FilterSettings, slow: str = "gm") -> float:
    """σ of the bias from the vertical velocities at the filter's update times, by generalised
    least squares with their exact covariance (integrated stationary Gauss–Markov, integrated
    white increments, the initial velocity's and the observation's σ)."""
    t = np.arange(1, int(SECONDS / settings.kf_interval) + 1) * settings.kf_interval
    a, b = np.minimum.outer(t, t), np.maximum.outer(t, t)
    T = GM_T
    if slow == "gm":   # ∫0^a ∫0^b σ² e^(−|s−u|/T) du ds
        coloured = GM_SIGMA**2 * (2 * T * a - 2 * T**2 * (1 - np.exp(-a / T))
                                  + T**2 * (1 - np.exp(-(b - a) / T) - np.exp(-a / T) + np.exp(-b / T)))
    else:              # ∫0^a ∫0^b K² min(s, u) du ds, the walk from 0
        coloured = RW_K**2 * (a**2 * b / 2 - a**3 / 6)
    r = max(3 * SIGMA_A, 1e-6)
    cov = coloured + SIGMA_A**2 * a / DT + settings.v0**2 + r**2 * np.eye(len(t))
    h = t  # the velocity a bias of 1 m/s² has built up
    info = h @ np.linalg.solve(cov, h) + 1 / PRIOR**2
    return 1 / math.sqrt(info)


@pytest.mark.parametrize("slow", ["gm", "rw"])
def test_the_slow_noise_state_gives_the_least_squares_sigma(slow):
    gyro, acc = _data(np.random.default_rng(1), 0.0)
    exact = _gls_sigma(_settings(True, slow), slow)
    with_state = float(_filter(gyro, acc, True, slow).sigma[0])
    without = float(_filter(gyro, acc, False).sigma[0])
    assert with_state == pytest.approx(exact, rel=0.01)   # the state held over an interval: ~Δ/T
    assert without < exact / 3   # the white-noise filter's claim


def test_monte_carlo_errors_match_the_sigma_only_with_the_state():
    """z = error / σ over 24 seeds: Σ z² is χ²(24) when σ is right (99.9 % interval 7.5-51.2);
    the filter without the state claims a σ ~4x too small, so Σ z² is ~16x too big."""
    rng = np.random.default_rng(2)
    z_with, z_without = [], []
    for _ in range(24):
        bias = rng.normal() * PRIOR
        gyro, acc = _data(rng, bias)
        for states, out in ((True, z_with), (False, z_without)):
            f = _filter(gyro, acc, states)
            out.append((f.values[0] - bias) / f.sigma[0])
    s_with, s_without = float(np.sum(np.square(z_with))), float(np.sum(np.square(z_without)))
    assert 7.5 < s_with < 51.2, z_with
    assert s_without > 51.2, z_without
