"""Identification of a channel's composite noise from its residual Allan variance.

The Allan variance of the composite model is linear in the squared term magnitudes,

    AVAR(τ) = 3Q²/τ² + N²/τ + (2 ln 2/π) B² + K² τ/3 (+ σ² g(τ/T) per Gauss–Markov term),

so the squared magnitudes are fitted by non-negative weighted least squares to the pooled
overlapping Allan variance (components.estimation.allan), each τ weighted by the inverse variance
of its estimate, 2 AVAR² / edf, with AVAR the model's own value (iterated: weights from the data
would favour the estimates that came out low). This is the generalized method of wavelet moments
(Guerrier et al. 2013; the Haar wavelet variance is half the Allan variance) with a diagonal
weight matrix. Plain slope fitting (reading N at τ = 1 s, B at the floor) is the baseline it is
measured against (benchmarks/noise_identification.py).

Neighbouring octaves' estimates are correlated, so the weighted fit's own covariance would
understate the spread; the σ of each term is a parametric bootstrap instead: the fitted model
simulated on the same static runs, its Allan variance refitted. A term is *present* when its
magnitude exceeds three of its σ; otherwise it is reported absent with an upper bound (its value
plus three σ). A Gauss–Markov term is tried where the basic terms leave a misfit larger than the
bootstrap's 99 % quantile of the fit statistic. A term must also matter: it is present only
where it makes at least 5 % of the model's Allan variance at some observed τ (a quantization of a
thousandth of an arc-second beside navigation-grade white noise is not a finding, however well
determined).

A pulse output's quantization is i.i.d. only where the input has moved the count remainder by
a count or more between two samples of the variance. At rest the input is nearly constant, so
over short τ the remainder follows the fractional count rate of the position (it can nearly
repeat after m samples when m times that rate is close to a whole number of counts): the Allan
variance there is a property of the positions, not of a random process, and its degrees of
freedom are far fewer than the samples'. With the quantization known (a count weight), the fit
therefore uses only the τ where something other than quantization makes at least half of the
measured variance; without that, the too-low short-τ points are taken up by a spurious
sub-second Gauss–Markov term and the white level reads as absent.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import nnls
from scipy.signal import lfilter

from components.estimation.allan import ALPHA, AllanVariance, pooled_allan
from components.estimation.distributions import chi2_isf
from components.model.flicker import FLICKER_AVAR, flicker_terms, gm_avar_unit
from components.model.noise import ChannelNoise

BASIC = ("quantization", "white", "bias_instability", "random_walk")
PRESENT_SIGMAS = 3.0
PRESENT_SHARE = 0.05
QUANTIZATION_DOMINANCE = 2.0  # measured AVAR over the known quantization's below which a τ is not fitted


def basis(term: str, tau: np.ndarray) -> np.ndarray:
    """Allan variance per unit squared magnitude of a basic term."""
    tau = np.asarray(tau, float)
    return {"quantization": 3.0 / tau**2, "white": 1.0 / tau, "bias_instability": np.full_like(tau, FLICKER_AVAR),
            "random_walk": tau / 3.0}[term]


@dataclass
class ChannelFit:
    """The identified noise of one channel."""

    noise: ChannelNoise
    sigma: dict                 # term -> σ of its magnitude (bootstrap)
    present: list               # terms above three of their σ
    upper: dict                 # absent term -> upper bound (value + 3 σ)
    allan: AllanVariance
    fit_statistic: float        # Σ w (AVAR − model)²
    fit_p: float                # bootstrap p-value of that statistic under the fitted model
    gm_tau: float | None = None
    notes: list = field(default_factory=list)

    def model_avar(self, tau) -> np.ndarray:
        return self.noise.avar_realised(tau)


def _at(av: AllanVariance, keep: np.ndarray) -> AllanVariance:
    return AllanVariance(av.tau[keep], av.avar[keep], av.terms[keep], av.edf[keep])


def beyond_quantization(av: AllanVariance, quantization: float) -> np.ndarray:
    """The τ from the first whose measured Allan variance is at least
    :data:`QUANTIZATION_DOMINANCE` times that of a known *quantization* alone (all τ when fewer
    than two remain: then nothing but quantization can be read from the static runs)."""
    above = np.flatnonzero(av.avar >= QUANTIZATION_DOMINANCE * basis("quantization", av.tau) * quantization**2)
    keep = np.arange(len(av.tau)) >= (above[0] if len(above) else len(av.tau))
    return keep if np.count_nonzero(keep) >= 2 else np.ones(len(av.tau), bool)


def white_beside_quantization(av: AllanVariance, quantization: float) -> tuple[float, float]:
    """(white level N [rate/√Hz], the τ [s] it was read at) of a channel whose *quantization* Q
    is known, from the pooled Allan variance *av* of its rate on the static runs: at the shortest τ
    where the measured variance is at least :data:`QUANTIZATION_DOMINANCE` times Q's alone,
    N² = (AVAR(τ) − 3Q²/τ²) τ. Sample differences cannot give it when the counts are coarser than
    a sample's noise (most are 0; see the module docstring); the shortest such τ keeps the slow
    terms' share small. (0, nan) where no τ rises above the quantization: the white noise is
    below what the counts can show (white_ceiling bounds it from the same *av*)."""
    above = np.flatnonzero(av.avar >= QUANTIZATION_DOMINANCE * basis("quantization", av.tau) * quantization**2)
    if not len(above):
        return 0.0, float("nan")
    k = above[0]
    tau = float(av.tau[k])
    return math.sqrt(max(float(av.avar[k]) - 3.0 * quantization**2 / tau**2, 0.0) * tau), tau


def white_ceiling(av: AllanVariance, confidence: float = 0.99) -> float:
    """The largest white level N [rate/√Hz] the Allan variance *av* allows: every term's share
    is non-negative, so N²/τ ≤ AVAR(τ) at each τ, taken at the upper end of each τ's *confidence*
    interval (its degrees of freedom). Where the static runs cannot show the white level beside a
    pulse output's quantization, the whole-log likelihood reads it up to this: block scatter
    beyond it is not the sensor's white noise but something the model misses in the moves."""
    return math.sqrt(float(np.min(av.tau * av.interval(confidence)[1] ** 2)))


def _fitted_range(av: AllanVariance, known: dict) -> np.ndarray:
    return beyond_quantization(av, known["quantization"]) if known.get("quantization") \
        else np.ones(len(av.tau), bool)


def _fit_squares(av: AllanVariance, terms: list[str], fixed: dict, gm_tau: float | None,
                 iterations: int = 6) -> tuple[dict, float]:
    """Squared magnitudes of *terms* (and of one GM term at *gm_tau*) fitted by iteratively
    reweighted NNLS; *fixed*: squared magnitudes held."""
    cols = [basis(t, av.tau) for t in terms]
    if gm_tau is not None:
        cols.append(gm_avar_unit(av.tau / gm_tau))
    A = np.column_stack(cols) if cols else np.zeros((len(av.tau), 0))
    base = sum((basis(t, av.tau) * v for t, v in fixed.items()), np.zeros(len(av.tau)))
    target = av.avar - base
    model = np.maximum(av.avar, 1e-300)
    x = np.zeros(A.shape[1])
    for _ in range(iterations):
        w = np.sqrt(av.edf / 2.0) / model
        if A.shape[1]:
            x, _ = nnls(A * w[:, None], target * w, maxiter=50 * A.shape[1] + 100)
        model = np.maximum(A @ x + base, 1e-300)
    w = np.sqrt(av.edf / 2.0) / model
    stat = float(np.sum((w * (av.avar - model)) ** 2))
    out = dict(zip(terms, x[: len(terms)]))
    if gm_tau is not None:
        out["gauss_markov"] = float(x[-1])
    return out, stat


def _channel(squares: dict, gm_tau: float | None, flicker_range) -> ChannelNoise:
    kw = {t: math.sqrt(max(squares.get(t, 0.0), 0.0)) for t in BASIC}
    gm = ((math.sqrt(squares["gauss_markov"]), gm_tau),) if gm_tau and squares.get("gauss_markov", 0) > 0 else ()
    return ChannelNoise(gauss_markov=gm, flicker_range=flicker_range, **kw)


def simulate_rate(ch: ChannelNoise, n: int, dt: float, rng: np.random.Generator) -> np.ndarray:
    """A record of *n* per-sample mean rates of the composite noise *ch* (for the bootstrap and
    the tests): white, quantization as the difference of i.i.d. remainders, random walk,
    Gauss–Markov terms and the flicker floor as its GM sum over [dt, n dt]."""
    r = ch.white / math.sqrt(dt) * rng.standard_normal(n)
    if ch.quantization:
        q = ch.quantization * math.sqrt(12.0) * (rng.random(n + 1) - 0.5)
        r += np.diff(q) / dt
    if ch.random_walk:
        r += np.cumsum(ch.random_walk * math.sqrt(dt) * rng.standard_normal(n)) \
            + ch.random_walk * math.sqrt(n * dt) * rng.standard_normal()
    terms = list(ch.gauss_markov)
    if ch.bias_instability:
        lo, hi = ch.flicker_range or (None, None)
        lo = 2 * dt if lo is None else lo
        hi = max(n * dt, 2 * lo) if hi is None else hi
        terms += flicker_terms(ch.bias_instability, lo, hi)
    for s, T in terms:
        phi = math.exp(-dt / T)
        e = s * math.sqrt(1 - phi**2) * rng.standard_normal(n)
        e[0] = s * rng.standard_normal()
        r += lfilter([1.0], [1.0, -phi], e)
    return r


def identify_channel(rate: np.ndarray, runs: list[tuple[int, int]], dt: float, *,
                     terms: tuple = BASIC, known: dict | None = None, bootstrap: int = 30,
                     seed: int = 0, flicker_range=None) -> ChannelFit:
    """The composite noise of one channel from its residual *rate* (per-sample mean, e.g.
    increment / dt) on the static *runs*. ``terms``: the basic terms to fit; ``known``: term ->
    magnitude held (e.g. the quantization of a pulse output from its count weight)."""
    known = dict(known or {})
    free = [t for t in terms if t not in known]
    fixed = {t: v**2 for t, v in known.items()}
    av = pooled_allan(rate, runs, dt)
    squares, stat = _fit_squares(_at(av, _fitted_range(av, known)), free, fixed, None)
    # degrees of freedom with the noise type that dominates at each τ under the first fit
    ch0 = _channel({**squares, **fixed}, None, flicker_range)

    def alpha_of(tau):
        parts = np.array([basis(t, tau) * getattr(ch0, t) ** 2 for t in BASIC])
        return np.array([ALPHA[BASIC[i]] for i in np.argmax(parts, axis=0)])

    measured = pooled_allan(rate, runs, dt, alpha_of)
    fitted = _fitted_range(measured, known)
    av = _at(measured, fitted)
    notes = []
    if not fitted.all():
        notes.append(f"τ < {av.tau[0]:.3g} s not fitted: the known quantization makes more than half of the "
                     "variance there, and a pulse remainder at rest is not independent from sample to sample")
    squares, stat = _fit_squares(av, free, fixed, None)
    rng = np.random.default_rng(seed)
    n = max(b for _, b in runs)

    def boot(ch: ChannelNoise, gm_tau):
        vals, stats_, bavs = [], [], []
        for _ in range(bootstrap):
            sim = simulate_rate(ch, n, dt, rng)
            bavs.append(_at(pooled_allan(sim, runs, dt, alpha_of), fitted))
            sq, st = _fit_squares(bavs[-1], free, fixed, gm_tau)
            vals.append({k: math.sqrt(max(v, 0.0)) for k, v in sq.items()})
            stats_.append(st)
        return vals, np.array(stats_), bavs

    gm_tau = None
    ch = _channel({**squares, **fixed}, None, flicker_range)
    vals, stats_, bavs = boot(ch, None)
    p = float(np.mean(stats_ >= stat)) if bootstrap else float("nan")
    if bootstrap and p < 0.01 and len(av.tau) >= 5:
        # a bump the basic terms cannot follow: one Gauss–Markov term, its time constant on a grid
        best = None
        for T in np.geomspace(av.tau[0] * 2, av.tau[-1], 16):
            sq, st = _fit_squares(av, free, fixed, float(T))
            if best is None or st < best[2]:
                best = (float(T), sq, st)
        if best is not None and best[1].get("gauss_markov", 0) > 0 and best[2] < stat:
            gm_tau, squares, stat = best
            ch = _channel({**squares, **fixed}, gm_tau, flicker_range)
            vals, stats_, bavs = boot(ch, gm_tau)
            p = float(np.mean(stats_ >= stat))
            notes.append(f"a Gauss–Markov term (T = {gm_tau:.3g} s) where the basic terms left a misfit")
    sigma = {k: float(np.std([v.get(k, 0.0) for v in vals], ddof=1)) if bootstrap > 1 else float("nan")
             for k in list(free) + (["gauss_markov"] if gm_tau else [])}
    value = {k: math.sqrt(max(v, 0.0)) for k, v in squares.items()}
    full = _channel({**squares, **fixed}, gm_tau, flicker_range).avar(av.tau)

    def share(k):
        part = (gm_avar_unit(av.tau / gm_tau) if k == "gauss_markov" else basis(k, av.tau)) * value.get(k, 0.0) ** 2
        return float(np.max(part / np.maximum(full, 1e-300)))

    present = [k for k in sigma if value.get(k, 0.0) > PRESENT_SIGMAS * sigma[k] and share(k) >= PRESENT_SHARE] \
        + list(known)
    if "white" in sigma and "white" not in present and value.get("white", 0.0) > 0:
        # every sensor has white noise: below three σ it is poorly read (pulse counts leave a
        # couple of τ above their quantization), not absent; dropped, the channel was weighed by
        # its quantization alone (σ 5-22x too small, a false verdict on one log in six)
        present.append("white")
        notes.append("white noise kept though below three σ of its estimate (few τ above the quantization) or "
                     "untested (no bootstrap): no sensor is without it")
    upper = {k: value.get(k, 0.0) + PRESENT_SIGMAS * sigma[k] for k in sigma if k not in present}
    # the present terms refitted alone: an absent term's estimate is held non-negative, so on
    # average it took variance that is not its own from the terms beside it (the white level read
    # 0.5 % low on white-only records, quantization and random walk fitted above 0 by chance) —
    # unless leaving the absent ones out spoils the fit: then they are real, only below three σ
    # (a floor from 10 s beside coarse pulse counts: refitted without it, the white level took
    # it and read 9 % high), and the present terms keep the full fit's values
    gm_kept = gm_tau if "gauss_markov" in present else None
    refit = [t for t in free if t in present]
    refitted = refit + (["gauss_markov"] if gm_kept else [])
    # (nothing present — a bootstrap of 0 replicates decides nothing — leaves nothing to refit)
    kept, stat_refit = _fit_squares(av, refit, fixed, gm_kept) if refitted else ({}, stat)
    dropped = len(free) + (1 if gm_tau else 0) - len(refitted)
    if refitted and dropped and stat_refit - stat > float(chi2_isf(0.01, dropped)):
        refitted = []
        kept = {k: (v if k in present else 0.0) for k, v in squares.items()}
        notes.append(f"terms below three σ still shape the Allan variance (without them the fit statistic rises "
                     f"by {stat_refit - stat:.3g}): the present terms are the full fit's")
    final = _channel({**kept, **fixed}, gm_kept, flicker_range)
    if bootstrap > 1 and refitted:
        # their σ: the same replicates refitted the same way (fewer terms compete, so it is
        # smaller than the full fit's, which stays the absent terms' for their upper bounds)
        again = [_fit_squares(b, refit, fixed, gm_kept)[0] for b in bavs]
        for k in refitted:
            sigma[k] = float(np.std([math.sqrt(max(a.get(k, 0.0), 0.0)) for a in again], ddof=1))
    return ChannelFit(final, sigma, present, upper, measured, stat, p, gm_tau if "gauss_markov" in present else None, notes)
