"""The slow noise terms' wander about a rest's mean rate: what, beside the white noise, dithers a
pulse count's remainder as it turns through a rest (components.model.count_remainder), whose
advance, read from the rest's ticks (components.estimation.count_phase), already holds the slow
terms' mean over the rest."""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np


def rest_spans(durations: np.ndarray, advance: np.ndarray, joined: np.ndarray | None = None) -> np.ndarray:
    """Each block's rest length [s] (NaN where the advance is not known): a rest is a run of
    blocks with a known advance, each starting where the one before it ended (``joined`` (B,)
    bool: the block ends where the next one starts; None: all do) — count_phase's rests, each
    read at its own rate."""
    d = np.asarray(durations, float)
    known = np.isfinite(np.asarray(advance, float))
    joined = np.ones(len(d), bool) if joined is None else np.asarray(joined, bool)
    same = np.zeros(len(d), bool)  # the block continues the rest before it
    same[1:] = known[1:] & known[:-1] & joined[:-1]
    rest_id = np.cumsum(~same)
    span = np.bincount(rest_id, weights=d)[rest_id]
    return np.where(known, span, np.nan)


# the cells a rest is cut into to measure the slow terms' wander in it (its blocks, up to this)
WANDER_CELLS = 64


def slow_wander_in_rest(terms, random_walk: float, d: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """The variance [unit² s²] by which the slow terms spread a block's phase beyond the mean rate
    over its rest: blocks of durations *d* in rests of *rest* seconds (NaN: not at rest; 0 there),
    under Gauss–Markov *terms* ((σ, T) pairs, a flicker floor's realisation among them) and a rate
    random walk *random_walk* (components.model.noise.ChannelNoise).

    What turns a pulse count's remainder through a rest is the advance read from the rest's
    ticks (components.estimation.count_phase), which holds the slow terms' mean over the rest;
    only their wander about that mean dithers the phase. That wander is smooth: its phase
    variance V(h) over a lag h grows faster than h, which the harmonics' damping block by block
    (a spread proportional to the lag) cannot follow. The spread per second is taken as V(h)/h
    averaged over the lags in the rest — on simulated rests under strong Gauss–Markov terms
    (T of 10 s to 2000 s on 30 s rests) the block sums' χ² per row came out at 0.91–0.98; with
    the spread of one block's lag alone 0.98–1.14, and with the white noise's alone up to 2.2.
    V is computed from the terms' covariance on up to :data:`WANDER_CELLS` equal cells of the
    rest with the rest's mean removed (a random walk's, non-stationary, the same way)."""
    d = np.asarray(d, float)
    rest = np.asarray(rest, float)
    out = np.zeros(len(d))
    if not terms and random_walk <= 0:
        return out
    for W in np.unique(rest[np.isfinite(rest)]):
        at = rest == W
        n = int(min(max(round(W / float(np.mean(d[at]))), 1), WANDER_CELLS))  # (the rest's blocks)
        # (to four digits of the rest's length: a jittered clock makes every rest's a little
        # different, and the rate is smooth in it)
        out[at] = _wander_rate(tuple(terms), float(random_walk), float(f"{W:.4g}"), n) * d[at]
    return out


@lru_cache(maxsize=4096)
def _wander_rate(terms: tuple, random_walk: float, W: float, n: int) -> float:
    """The mean over lags h = kc (c = W/n, k = 1..n) of V(h)/h [unit² s], V the variance of the
    slow terms' integral over h less the rest's mean rate times h, averaged over where h starts."""
    c = W / n
    k = np.arange(n)
    lag = np.abs(k[:, None] - k[None, :])
    C = np.zeros((n, n))  # the cells' mean rates
    for s, T in terms:
        x = c / T
        a, one_less = math.exp(-x), -math.expm1(-x)  # (1 − a without its cancellation: T ≫ c)
        C += np.where(lag == 0, s**2 * _mean_variance(x),
                      s**2 * (one_less / x) ** 2 * a ** (np.maximum(lag, 1) - 1))
    if random_walk > 0:
        lo = np.minimum(k[:, None], k[None, :])
        C += random_walk**2 * c * (lo + np.where(lag == 0, 1 / 3, 1 / 2))
    P = np.eye(n) - 1.0 / n
    S = c**2 * (P @ C @ P)  # the cells' phase beyond the mean rate
    Z = np.zeros((n + 1, n + 1))
    Z[1:, 1:] = S.cumsum(0).cumsum(1)
    rates = []
    for m in range(1, n + 1):
        j = np.arange(n - m + 1)
        V = Z[j + m, j + m] - Z[j, j + m] - Z[j + m, j] + Z[j, j]
        rates.append(float(V.mean()) / (m * c))
    return max(float(np.mean(rates)), 0.0)


def _mean_variance(x: float) -> float:
    """A Gauss–Markov term's variance over a window x time constants long, as a fraction of its
    own: 2 (x − 1 + e^(−x)) / x², by its series where x is small (there the closed form loses
    what the rest's mean removes: a term of T = 1e8 s on 30 s rests was 2 % off)."""
    if x < 1e-3:
        return 1 - x / 3 + x**2 / 12 - x**3 / 60 + x**4 / 360
    return 2 * (x + math.expm1(-x)) / x**2
