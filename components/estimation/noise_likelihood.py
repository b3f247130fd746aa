"""The slow noise terms from the whole log: restricted maximum likelihood on the block sums.

The static runs' Allan variance sees averaging times up to half a run (tens of seconds on a
multi-position schedule); bias instability and random walk act over the whole log, where the
block sums show them as the wander of the residual from position to position. For one channel,
with its blocks' rows y = H θ + e and e Gaussian with the covariance C(η) of the composite model
(η: the slow terms' magnitudes, the fast ones held), the restricted log-likelihood

    ℓ(η) = −½ [log det C + yᵀ C⁻¹ y − yᵀ C⁻¹ H (Hᵀ C⁻¹ H)⁻¹ Hᵀ C⁻¹ y + log det (Hᵀ C⁻¹ H)]

comes from the whitening filter (components.estimation.whitening: log det C = Σ log S_k) at a
cost linear in the number of blocks. It is maximised over log η; the σ of each magnitude comes
from the curvature there. The flicker floor's lower corner (the shortest time constant of its
Gauss–Markov sum) is fitted with it: a real floor does not extend to arbitrarily short times,
and a model that puts it there would take the rise below the corner for random walk. A term is present when the likelihood ratio against leaving it out
exceeds the 1 % point of its null distribution (½ χ²₀ + ½ χ²₁ on the boundary: 5.41).
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.optimize import minimize

from components.estimation.whitening import whiten_channel
from components.model.noise import ChannelNoise, block_noise

LR_CRITICAL = 5.4119  # χ²₁ 98 % point: the 1 % level of ½ χ²₀ + ½ χ²₁
SLOW = ("bias_instability", "random_walk")


def restricted_loglik(ch: ChannelNoise, y: np.ndarray, H: np.ndarray, durations: np.ndarray,
                      white_var: np.ndarray, span: float, t_lo: float) -> float:
    """ℓ of one channel's rows under *ch* (see the module docstring)."""
    bn = block_noise(ch, durations, white_var, span, t_lo)
    w, S = whiten_channel(np.column_stack([y, H]), bn)
    yw, Hw = w[:, 0], w[:, 1:]
    out = -0.5 * (np.sum(np.log(S)) + yw @ yw)
    if Hw.shape[1]:
        # columns the channel does not see are left out by the caller; a rank-deficient rest is
        # handled through the SVD (pseudo-determinant over the resolved directions)
        U, s, _ = np.linalg.svd(Hw, full_matrices=False)
        keep = s > 1e-10 * s[0] if len(s) and s[0] > 0 else np.zeros(0, bool)
        proj = U[:, keep].T @ yw
        out += 0.5 * proj @ proj - np.sum(np.log(s[keep]))
    return float(out)


def fit_slow_terms(ch: ChannelNoise, y: np.ndarray, H: np.ndarray, durations: np.ndarray,
                   white_var: np.ndarray, span: float, t_lo: float, terms=SLOW) -> tuple[ChannelNoise, dict]:
    """*ch* with the magnitudes of *terms* re-estimated by restricted maximum likelihood.
    Returns the channel and, per term: value, σ, the likelihood ratio against the term left
    out, and whether it is present."""
    terms = list(terms)
    corner = "bias_instability" in terms
    lo_min, lo_max = max(float(np.min(durations)), 1e-3), max(span / 8.0, 2 * float(np.min(durations)))

    def with_logs(x):
        kw = {t: math.exp(v) for t, v in zip(terms, x)}
        if corner:
            kw["flicker_range"] = (min(max(math.exp(x[len(terms)]), lo_min), lo_max), None)
        return replace(ch, **kw)

    def nll(x):
        return -restricted_loglik(with_logs(x), y, H, durations, white_var, span, t_lo)

    # start from the given values or from a level the data can show
    scale = math.sqrt(max(float(np.median(white_var / np.maximum(durations, 1e-12) ** 2)), 1e-300))
    x0 = [math.log(getattr(ch, t) or scale * (1.0 if t == "bias_instability" else 0.1 / math.sqrt(span)))
          for t in terms]
    if corner:
        x0.append(math.log(min(max(10.0, lo_min), lo_max)))
    x0 = np.array(x0)
    best = minimize(nll, x0, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-4, "maxiter": 400})
    x = best.x
    # curvature in log magnitude -> σ of the magnitude (delta method)
    h = 1e-2
    n = len(x)
    Hs = np.zeros((n, n))
    f0 = best.fun
    for i in range(n):
        for j in range(i, n):
            ei, ej = np.eye(n)[i] * h, np.eye(n)[j] * h
            if i == j:
                Hs[i, i] = (nll(x + ei) - 2 * f0 + nll(x - ei)) / h**2
            else:
                Hs[i, j] = Hs[j, i] = (nll(x + ei + ej) - nll(x + ei - ej) - nll(x - ei + ej) + nll(x - ei - ej)) / (4 * h**2)
    try:
        cov = np.linalg.inv(Hs) if np.all(np.linalg.eigvalsh(Hs) > 0) else np.full((n, n), np.nan)
    except np.linalg.LinAlgError:
        cov = np.full((n, n), np.nan)
    out = with_logs(x)
    report = {}
    if corner:
        report["flicker_corner_s"] = out.flicker_range[0]
    for i, t in enumerate(terms):
        without = replace(out, **{t: 0.0})
        lr = 2 * (f0 * -1 - restricted_loglik(without, y, H, durations, white_var, span, t_lo))
        value = math.exp(x[i])
        report[t] = {"value": value, "sigma": value * math.sqrt(cov[i, i]) if np.isfinite(cov[i, i]) else float("nan"),
                     "likelihood_ratio": float(lr), "present": bool(lr > LR_CRITICAL)}
    final = replace(out, **{t: (report[t]["value"] if report[t]["present"] else 0.0) for t in terms})
    return final, report
