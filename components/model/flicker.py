"""Flicker (1/f) bias instability as a sum of first-order Gauss-Markov processes: the one
construction the IMU FMU (fmus/imu/noise.c, parameters ``*.noise.bi`` and ``*.noise.bi_tau_max``)
and the Python side share.

A bias instability B [rad/s or m/s2] (IEEE definition) has a flat Allan-deviation floor of
sqrt(2 ln 2 / pi) B = 0.664282 B. One Gauss-Markov (GM) process reaches that value at one
averaging time only; M processes with time constants spread evenly in log over the range and a
common standard deviation s stay within about ten per cent of the floor from t_lo to t_hi:

- extended range a = t_lo / 2, b = 2 t_hi, r = b / a;
- M = ceil(2 log10 r) + 1 terms, at most 16 (so t_hi / t_lo <= sqrt(1e15) / 4 = 7.9e6);
  evaluated without a logarithm as M - 1 = the smallest k >= 0 with r*r <= 10^k (r*r rounded,
  10^k exact), which the FMU evaluates the same way, so both always agree on M;
- T_j = a r^(j / (M-1)), j = 0 .. M-1 (computed as a exp(j/(M-1) ln r));
- s^2 = 0.4412712 B^2 / mean_i sum_j g(tau_i / T_j), tau_i = t_lo (t_hi/t_lo)^(i/63),
  i = 0 .. 63 (64 log-spaced points), g(u) = 2/u - (3 - 4 e^-u + e^-2u) / u^2 the Allan variance
  of a unit-variance GM process at u = tau / T (0.4412712 = 2 ln 2 / pi).

g is evaluated as written for u >= 0.5 and by its Taylor series (the same function) below, where
the written form cancels (at u = 1e-5 it is 3 % off, at 1e-7 wrong in sign and size).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from components.errors import UserError

FLICKER_FLOOR = 0.664282  # Allan-deviation floor of flicker noise per B: sqrt(2 ln 2 / pi)
FLICKER_FLOOR_SQ = 0.4412712  # its square, 2 ln 2 / pi
FLICKER_AVAR = 2.0 * math.log(2.0) / math.pi  # the same, to full precision (the estimators' model)
MAX_TERMS = 16
FIT_POINTS = 64
# below this u the series: u^(n-3) (2^n - 4) / n! after n = 20 is below 1e-17 of g
SERIES_BELOW = 0.5
_SERIES_TOP = 20


def _series_coefficients() -> tuple[float, ...]:
    """(-1)^(n+1) (2^n - 4) / n! for n = 20 down to 3 (Horner's order)."""
    fact = [1.0] * (_SERIES_TOP + 1)
    for n in range(1, _SERIES_TOP + 1):
        fact[n] = fact[n - 1] * n  # exact: every n! up to 20! is a double
    return tuple((2.0**n - 4.0) / fact[n] * (1.0 if n % 2 else -1.0) for n in range(_SERIES_TOP, 2, -1))


# once, not per call: the noise likelihood evaluates g ~2 M times a `calbench noise` (each new
# flicker corner of its fit is a new set of terms), and building them each time was half of it
_SERIES = _series_coefficients()


def _g(u: float) -> float:
    """Allan variance of a unit-variance Gauss-Markov process at u = tau / T."""
    if u < SERIES_BELOW:
        # g(u) = sum_{n>=3} (-1)^(n+1) (2^n - 4) u^(n-2) / n!, Horner from n = 20 down
        p = 0.0
        for c in _SERIES:
            p = p * u + c
        return p * u
    e1, e2 = math.exp(-u), math.exp(-2.0 * u)
    return 2.0 / u - (3.0 - 4.0 * e1 + e2) / (u * u)


def gm_avar_unit(u):
    """g(u) of a number or an array (element by element, the series below 0.5)."""
    if np.ndim(u) == 0:
        return _g(float(u))
    u = np.asarray(u, float)
    out = np.empty(u.shape)
    big = u >= SERIES_BELOW
    ub, us = u[big], u[~big]
    out[big] = 2.0 / ub - (3.0 - 4.0 * np.exp(-ub) + np.exp(-2.0 * ub)) / (ub * ub)
    p = np.zeros(us.shape)
    for c in _SERIES:
        p = p * us + c
    out[~big] = p * us
    return out


def gm_avar(sigma: float, T: float, tau):
    """Allan variance at averaging time *tau* (a number or an array) of a first-order
    Gauss-Markov process of standard deviation *sigma* and correlation time *T*:
    sigma^2 [2/u - (3 - 4 e^-u + e^-2u) / u^2], u = tau / T."""
    if isinstance(tau, (int, float)):
        return sigma * sigma * _g(tau / T)
    return sigma * sigma * gm_avar_unit(np.asarray(tau, float) / T)


def flicker_count(t_lo: float, t_hi: float) -> int:
    """Number of Gauss-Markov terms M for the range [t_lo, t_hi]: ceil(2 log10(4 t_hi / t_lo)) + 1.
    Raises UserError when the range is not 0 < t_lo < t_hi or needs more than 16 terms."""
    if not (math.isfinite(t_lo) and math.isfinite(t_hi) and 0.0 < t_lo < t_hi):
        raise UserError(f"flicker range t_lo = {t_lo!r} s, t_hi = {t_hi!r} s: expected 0 < t_lo < t_hi, finite")
    r = (2.0 * t_hi) / (0.5 * t_lo)
    rr, p = r * r, 1.0
    for k in range(MAX_TERMS):
        if rr <= p:
            return k + 1
        p *= 10.0
    raise UserError(f"flicker range t_lo = {t_lo:g} s .. t_hi = {t_hi:g} s too wide: "
                    f"ceil(2 log10(4 t_hi / t_lo)) + 1 = {math.ceil(2 * math.log10(r)) + 1} Gauss-Markov terms, "
                    f"at most {MAX_TERMS} (t_hi / t_lo <= {math.sqrt(1e15) / 4:.7g})")


def flicker_terms(B: float, t_lo: float, t_hi: float) -> list[tuple[float, float]]:
    """The Gauss-Markov terms (sigma_j, T_j) whose sum has the flicker floor 0.664282 B of the
    bias instability *B* over [t_lo, t_hi] (see the module's docstring); all sigma_j equal."""
    if not (math.isfinite(B) and B >= 0.0):
        raise UserError(f"bias instability B = {B!r}: expected a finite value >= 0")
    taus, total = _unit_sum(float(t_lo), float(t_hi))
    s = math.sqrt(FLICKER_FLOOR_SQ * B * B / (total / FIT_POINTS))
    return [(s, T) for T in taus]


@functools.lru_cache(maxsize=4096)
def _unit_sum(t_lo: float, t_hi: float) -> tuple[tuple[float, ...], float]:
    """The time constants over [t_lo, t_hi] and the sum of their unit Allan variances over the
    fit points: what the terms' common sigma depends on besides B (the noise likelihood asks for
    the same range hundreds of times with other magnitudes)."""
    M = flicker_count(t_lo, t_hi)
    a, b = 0.5 * t_lo, 2.0 * t_hi
    lr = math.log(b / a)
    taus = tuple(a * math.exp(j / (M - 1) * lr) for j in range(M))
    lt = math.log(t_hi / t_lo)
    # the 64 x M values at once: term by term in Python this was a third of `calbench noise`
    # (each flicker corner its likelihood fit tries is a new range, so the cache rarely hits)
    fit_taus = t_lo * np.exp(np.arange(FIT_POINTS) / (FIT_POINTS - 1) * lt)
    total = math.fsum(gm_avar_unit(fit_taus[:, None] / np.array(taus)[None, :]).ravel())
    return taus, total
