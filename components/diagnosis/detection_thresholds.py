"""The theoretical thresholds diagnose reports per candidate parameter: the magnitude its F
test detects with 95 % power at the first Holm level α/m (non-central F), and the magnitude from
which it is named first rather than its closest look-alike — the candidate whose columns take the
largest share of its own — in 95 % of logs (:func:`naming_snr`). A look-alike pair such as acc.k2
and acc.sf_asym on rests at ±1 g and 0 is detected long before the log can tell which of the two
it is."""
from __future__ import annotations

import math

import numpy as np

from components.estimation.distributions import f_isf, ncf_sf

# a parameter whose column lies closer than this to another candidate's is never named first:
# its naming threshold would be > 16 x its detection threshold, where the linearised model's own
# error is as large as what separates the two (measured, benchmarks/coloured_noise.py on the
# diagnosis schedule: acc.sf_asym at cosine 0.9805 to acc.k2 named first 20/20 at 1.3 x its
# naming threshold; imu.time_offset at 0.9997 to acc.time_offset 0/20, with a residual left)
NAMING_LIMIT = 0.999


def theoretical_thresholds(ranked: list, design, base: list[str], available: dict, alpha: float) -> None:
    """Fill each candidate's ``threshold`` (parameter -> magnitude) and ``naming`` (parameter ->
    (magnitude, look-alike, cosine)) from its information beyond the *base* model's columns in
    *design* (the candidates' ``_basis``: their new columns, orthonormal)."""
    for c in ranked:
        k = c.added_rank
        dof_c = max(design.n - len(base) - k, 1)
        lam = noncentrality(k, dof_c, alpha / max(len(ranked), 1), 0.95)
        for p in available[c.effect]:
            h = design.projected_column(base, p)
            info = float(h @ h)
            if info > 0:
                c.threshold[p] = math.sqrt(lam / info)
                rivals = [(float(np.linalg.norm(d._basis.T @ h)) / math.sqrt(info), d.effect)  # type: ignore[attr-defined]
                          for d in ranked if d is not c]
                if rivals:
                    rho, rival = max(rivals)
                    snr = naming_snr(min(rho, 1.0)) if rho <= NAMING_LIMIT else math.inf
                    c.naming[p] = (max(c.threshold[p], snr / math.sqrt(info)), rival, rho)


def naming_snr(rho: float, power: float = 0.95) -> float:
    """The signal-to-noise m (magnitude × √information) at which a one-parameter effect beats a
    look-alike whose columns take the fraction *rho* (the cosine) of it: with the effect's
    projection A ~ N(m, 1) and the rival's B ~ N(ρ m, 1), corr ρ, it is named when |A| > |B|,
    and A − B and A + B are independent, so P = Φ(x) Φ(y) + Φ(−x) Φ(−y) with
    x = m √((1 − ρ)/2), y = m √((1 + ρ)/2); infinite for ρ → 1 (never told apart)."""
    from scipy.special import ndtr

    if rho >= 1.0 - 1e-12:
        return math.inf
    a, b = math.sqrt((1 - rho) / 2), math.sqrt((1 + rho) / 2)

    def shortfall(m: float) -> float:
        return ndtr(m * a) * ndtr(m * b) + ndtr(-m * a) * ndtr(-m * b) - power

    hi = 1.0
    while shortfall(hi) < 0:
        hi *= 2
    return _root(shortfall, 0.0, hi)


def noncentrality(k: int, dof: int, level: float, power: float) -> float:
    """λ with P(F'(k, dof, λ) > F_(1-level)(k, dof)) = power (non-central F)."""
    crit = f_isf(level, k, dof)
    f = lambda lam: ncf_sf(crit, k, dof, lam) - power  # noqa: E731
    hi = 10.0
    while f(hi) < 0:
        hi *= 2
    return _root(f, 1e-9, hi)


def _root(f, lo: float, hi: float, xtol: float = 1e-12) -> float:
    """The root of *f* between *lo* and *hi*, where f changes sign: false position with the
    Illinois halving (superlinear, never leaves the bracket). scipy.optimize.brentq did this, at
    the price of importing scipy.optimize: ~0.15 s of every diagnose."""
    flo, fhi = f(lo), f(hi)
    if flo == 0:
        return float(lo)
    if fhi == 0:
        return float(hi)
    if (flo < 0) == (fhi < 0):
        raise ValueError(f"no sign change of the function between {lo} and {hi}")
    kept = 0  # which end stayed last time: -1 lo, +1 hi (the Illinois rule halves it if it stays again)
    for _ in range(200):
        x = hi - fhi * (hi - lo) / (fhi - flo)
        fx = f(x)
        if fx == 0:
            return float(x)
        if (fx < 0) == (flo < 0):
            lo, flo = x, fx
            if kept == 1:
                fhi /= 2
            kept = 1
        else:
            hi, fhi = x, fx
            if kept == -1:
                flo /= 2
            kept = -1
        if hi - lo <= xtol + 4 * np.finfo(float).eps * abs(x):
            return float(x)
    raise ArithmeticError(f"no root to {xtol} in 200 steps between {lo} and {hi}")
