"""Overlapping Allan variance of a channel's residual rate over the static runs of a log
(IEEE Std 952 / 1554 conventions), pooled over the runs, with equivalent degrees of freedom and
confidence intervals.

A calibration log rests in many short runs separated by moves; the noise continues through the
moves, so each run is a contiguous record of the same process. Each run gives an overlapping
Allan variance (allantools.oadev) at the octave averaging times it is long enough for; the
runs' estimates at one τ are pooled weighted by their numbers of terms, and their equivalent
degrees of freedom (Greenhall's algorithm, allantools.edf_greenhall, for the noise type that
dominates at that τ) add, the runs being disjoint stretches of the record.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import allantools
import numpy as np
from scipy import stats

from components.model.mask_runs import runs

# allantools' noise exponent α of the rate ("frequency") data per composite term
ALPHA = {"quantization": 2, "white": 0, "bias_instability": -1, "random_walk": -2}


@dataclass
class AllanVariance:
    """Pooled overlapping Allan variance of one channel: ``tau`` [s], ``avar`` [(rate unit)²],
    ``terms`` (number of squared differences pooled), ``edf`` (equivalent degrees of freedom)."""

    tau: np.ndarray
    avar: np.ndarray
    terms: np.ndarray
    edf: np.ndarray

    @property
    def adev(self) -> np.ndarray:
        return np.sqrt(self.avar)

    def interval(self, confidence: float = 0.683) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of the Allan deviation: χ² with the equivalent degrees of freedom."""
        a = (1 - confidence) / 2
        lo = self.avar * self.edf / stats.chi2.ppf(1 - a, self.edf)
        hi = self.avar * self.edf / stats.chi2.ppf(a, self.edf)
        return np.sqrt(lo), np.sqrt(hi)


def static_runs(static: np.ndarray, min_samples: int = 8) -> list[tuple[int, int]]:
    """[a, b) index ranges of consecutive static samples, at least *min_samples* long."""
    return [(int(a), int(b)) for a, b in zip(*runs(static)) if b - a >= min_samples]


def first_runs(runs: list[tuple[int, int]], samples: int) -> list[tuple[int, int]]:
    """The leading *runs* until they hold at least *samples* samples (all when they hold fewer):
    the fast terms show at short τ, which the first rests measure well, and the Allan stage need
    not read an hours-long log to its end."""
    out, total = [], 0
    for a, b in runs:
        if total >= samples:
            break
        out.append((a, b))
        total += b - a
    return out


def octave_factors(longest: int) -> np.ndarray:
    """Averaging factors m = 1, 2, 4, ... that fit at least twice into *longest* samples."""
    m = [1]
    while 2 * m[-1] * 2 + 1 <= longest:
        m.append(2 * m[-1])
    return np.array(m)


@lru_cache(maxsize=1 << 16)
def _edf(alpha: int, m: int, n_phase: int) -> float:
    """Equivalent degrees of freedom of one run's overlapping Allan variance (Greenhall); where
    allantools has no formula (white phase noise at the longest averaging times of a run) the
    simple approximation of IEEE Std 1139 / NIST SP 1065 (allantools.edf_simple). Kept per
    (α, m, N): it depends on no data, and a multi-position log's runs share a few lengths, so the
    noise bootstrap asked the same few hundred values ~10^5 times (half of `calbench noise`)."""
    try:
        return float(allantools.edf_greenhall(alpha=alpha, d=2, m=m, N=n_phase, overlapping=True))
    except (NotImplementedError, AssertionError, ValueError, ZeroDivisionError):
        return float(max(allantools.edf_simple(n_phase, m, alpha), 1.0))


def pooled_allan(rate: np.ndarray, runs: list[tuple[int, int]], dt: float, alpha_of=None) -> AllanVariance:
    """Overlapping Allan variance of *rate* (per-sample mean rate, e.g. increment / dt) over the
    *runs*. ``alpha_of(tau)`` → allantools noise exponent dominating at each τ (array), for the
    degrees of freedom; default white noise (α = 0)."""
    if not runs:
        raise ValueError("no static run long enough for an Allan variance (at least 8 samples)")
    longest = max(b - a for a, b in runs)
    ms = octave_factors(longest)
    taus = ms * dt
    alphas = np.zeros(len(ms), int) if alpha_of is None else np.asarray(alpha_of(taus), int)
    acc = np.zeros(len(ms))
    terms = np.zeros(len(ms))
    edf = np.zeros(len(ms))
    for a, b in runs:
        x = np.asarray(rate[a:b], float)
        usable = [k for k, m in enumerate(ms) if 2 * m + 1 <= len(x)]
        if not usable:
            continue
        t, dev, _, n = allantools.oadev(x, rate=1.0 / dt, data_type="freq", taus=taus[usable])
        got = {int(round(tt / dt)): (d, nn) for tt, d, nn in zip(t, dev, n)}
        for k in usable:
            if int(ms[k]) not in got:
                continue
            d, nn = got[int(ms[k])]
            acc[k] += nn * d**2
            terms[k] += nn
            edf[k] += _edf(int(alphas[k]), int(ms[k]), len(x) + 1)
    ok = terms > 0
    return AllanVariance(taus[ok], acc[ok] / terms[ok], terms[ok], edf[ok])
