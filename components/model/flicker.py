"""Flicker (bias-instability) noise as a sum of first-order Gauss–Markov processes.

Bias instability B (IEEE Std 952 / 1554) is a flat Allan-deviation floor of 0.664 B over decades
of averaging time (flicker, 1/f noise), which no finite state-space model has. A sum of GM terms
whose time constants are spread evenly on a log scale has a nearly flat Allan variance between
the shortest and the longest of them. The construction below is the one the IMU FMU simulates
(``gyro.noise.bi_tau`` … ``bi_tau_max``, fmus/imu/noise.c) and the one the estimators whiten with:

- extended range a = T_lo / 2, b = 2 T_hi; M = ceil(2 log10(b / a)) + 1 terms (at most 16);
- T_j = a (b / a)^(j / (M − 1));
- one standard deviation s for all terms, s² = (2 ln 2 / π) B² / mean_i Σ_j g(τ_i / T_j) over 64
  log-spaced τ_i in [T_lo, T_hi], g(u) = 2/u − (3 − 4 e^(−u) + e^(−2u)) / u² the Allan variance of
  a unit-variance GM process at u = τ / T.
"""
from __future__ import annotations

import math

import numpy as np

FLICKER_AVAR = 2.0 * math.log(2.0) / math.pi   # Allan variance of flicker noise per B² (0.664² B²)
MAX_TERMS = 16


def gm_avar_unit(u):
    """Allan variance of a unit-variance first-order Gauss–Markov process at u = τ / T."""
    u = np.asarray(u, float)
    return 2.0 / u - (3.0 - 4.0 * np.exp(-u) + np.exp(-2.0 * u)) / u**2


def gm_avar(sigma: float, T: float, tau):
    """Allan variance of a GM process of standard deviation *sigma* and correlation time *T*."""
    return sigma**2 * gm_avar_unit(np.asarray(tau, float) / T)


def flicker_terms(B: float, t_lo: float, t_hi: float) -> list[tuple[float, float]]:
    """(σ_j, T_j) of the GM terms that approximate bias instability *B* between *t_lo* and
    *t_hi* [s]. Raises ValueError when the range needs more than 16 terms or is empty."""
    if not (t_lo > 0 and t_hi > t_lo):
        raise ValueError(f"flicker range [{t_lo!r}, {t_hi!r}] s: expected 0 < t_lo < t_hi")
    a, b = t_lo / 2.0, 2.0 * t_hi
    m = math.ceil(2.0 * math.log10(b / a)) + 1
    if m > MAX_TERMS:
        raise ValueError(f"flicker range [{t_lo:g}, {t_hi:g}] s needs {m} Gauss–Markov terms; at most "
                         f"{MAX_TERMS} (a ratio t_hi/t_lo up to about {10 ** ((MAX_TERMS - 1) / 2) / 4:.3g})")
    T = a * (b / a) ** (np.arange(m) / (m - 1))
    taus = t_lo * (t_hi / t_lo) ** (np.arange(64) / 63.0)
    mean = float(np.mean([gm_avar_unit(t / T).sum() for t in taus]))
    s = math.sqrt(FLICKER_AVAR * B**2 / mean) if B > 0 else 0.0
    return [(s, float(t)) for t in T]
