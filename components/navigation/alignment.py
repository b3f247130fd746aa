"""Initial alignment on a stationary base from the initial static period.

- **coarse**: analytic (TRIAD-like double-vector) from the mean specific force and mean rate:
  ``C_b^n = [f^n, ω^n, f^n × ω^n] [f^b, ω^b, f^b × ω^b]⁻¹`` with f^n = (0, 0, g) and
  ω^n = ω_ie^n, orthonormalised. Its heading error is the gyro's East error over Ω cos L.
- **fine**: a short Kalman filter on the same static period, the 9 navigation error states only,
  zero velocity observed (the calibration filter's machinery with no effect states): levelling
  converges in seconds, heading by gyrocompassing (its σ is reported, and seeds the φ block of
  the calibration filter's initial covariance).
"""
from __future__ import annotations

import numpy as np

from components.navigation.earth import Site
from components.navigation.strapdown import orthonormalize


def static_run(static: np.ndarray, start: int = 0) -> tuple[int, int]:
    """The first run [a, b) of static samples at or after *start*."""
    idx = np.nonzero(static[start:])[0]
    if len(idx) == 0:
        raise ValueError("no static sample to align on")
    a = start + int(idx[0])
    moving = np.nonzero(~static[a:])[0]
    b = a + int(moving[0]) if len(moving) else len(static)
    return a, b


def alignment_run(static: np.ndarray, min_len: int) -> tuple[int, int]:
    """The first static run [a, b) of at least ``min_len`` samples (else the longest one).

    The alignment needs the body truly at rest: a table settling after a move creeps at up to
    1e-6 rad/s for seconds (stick-slip), which is 2 % of the horizontal Earth rate, so a
    gyrocompass on the short rest after an index (seed 003's 0.5 s "S204-start") is off by
    ~0.02 rad in heading and the filter starting there never recovers (a systematic 0.01–0.02
    °/h in the S204 gyro biases, noise-free)."""
    runs = []
    a = 0
    while True:
        try:
            a, b = static_run(static, a)
        except ValueError:
            break
        if b - a >= min_len:
            return a, b
        runs.append((b - a, -a, a, b))
        a = b
    if not runs:
        raise ValueError("no static sample to align on")
    _, _, a, b = max(runs)
    return a, b


def coarse_align(gyro: np.ndarray, acc: np.ndarray, site: Site) -> np.ndarray:
    """C_b^n from static increments (N, 3) (sums: any dt)."""
    fb = np.sum(acc, axis=0)
    wb = np.sum(gyro, axis=0)
    fb, wb = fb / np.linalg.norm(fb), wb / np.linalg.norm(wb)
    fn = np.array([0.0, 0.0, 1.0])
    wn = site.w_ie / np.linalg.norm(site.w_ie)
    Mn = np.column_stack([fn, wn, np.cross(fn, wn)])
    Mb = np.column_stack([fb, wb, np.cross(fb, wb)])
    return orthonormalize(Mn @ np.linalg.inv(Mb))


def fine_align(gyro: np.ndarray, acc: np.ndarray, dt: float, site: Site, C0: np.ndarray,
               sigma_gyro=None, sigma_acc=None, kf_interval: float = 0.1):
    """Zero-velocity KF over static increments starting from C0. Returns (C_b^n at the start of
    the period (the base is static, so the body attitude does not change), φ σ (3,))."""
    from components.navigation.kf import FilterSettings, run_filter

    settings = FilterSettings(parameters=[], kf_interval=kf_interval, passes=1,
                              phi0=(1e-3, 1e-3, 2e-2), sigma_gyro=sigma_gyro, sigma_acc=sigma_acc)
    static = np.ones(len(gyro), bool)
    out = run_filter(gyro, acc, dt, site, C0, static, settings, regressors=None)
    # attitude at the end of the period in the Earth-fixed n, which is the start attitude
    return out.C_final, out.sigma_nav[:3]
