"""The slow noise terms from the whole log: restricted maximum likelihood on the block sums.

The static runs' Allan variance sees averaging times up to half a run (tens of seconds on a
multi-position schedule); bias instability and random walk act over the whole log, where the
block sums show them as the wander of the residual from position to position. For one channel,
with its blocks' rows y = H θ + e and e Gaussian with the covariance C(η) of the composite model
(η: the slow terms' magnitudes, the fast ones held), the restricted log-likelihood

    ℓ(η) = −½ [log det C + yᵀ C⁻¹ y − yᵀ C⁻¹ H (Hᵀ C⁻¹ H)⁻¹ Hᵀ C⁻¹ y + log det (Hᵀ C⁻¹ H)]

comes from the whitening filter (components.estimation.whitening: log det C = Σ log S_k) at a
cost linear in the number of blocks. It is maximised over log η; the σ of each magnitude comes
from the curvature there, the flicker corner and the block-variance nuisance free beside it.
The flicker floor's lower corner (the shortest time constant of its Gauss–Markov sum) is fitted
with it: a real floor does not extend to arbitrarily short times, and a model that puts it there
would take the rise below the corner for random walk. A term is present when the likelihood ratio against leaving it out
exceeds the 1 % point of its null distribution (½ χ²₀ + ½ χ²₁ on the boundary: 5.41); terms are
dropped one at a time, the one the model misses least first.

Each present term also gets its profile-likelihood interval: the magnitudes where the deviance,
maximised over everything else, reaches 9 (three σ of a one-parameter interval). On a log of a
few minutes the likelihood is far from quadratic and value ± 3σ from the curvature held the
truth in 87 % of tactical 5-minute logs; the profile interval in 83 of 84.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np

from components.estimation.whitening import whiten_channel
from components.model.block_noise import block_noise
from components.model.noise import ChannelNoise

LR_CRITICAL = 5.4119  # χ²₁ 98 % point: the 1 % level of ½ χ²₀ + ½ χ²₁
FLICKER_CORNER_TEST = 10.0  # [s] the floor's lower corner its presence is tested at
SLOW = ("bias_instability", "random_walk")
FLAT_DEVIANCE = 0.01  # dropping a term costs less than this: the likelihood does not see it
SPREAD = (-0.5, 0.5)  # log: where profile_interval also starts along a coordinate of several valleys
PROFILE_LEVEL = 9.0  # the deviance of the reported interval: three σ of a one-parameter interval (99.7 %)
MAGNITUDE_REACH = 50.0  # log: how far a slow term's magnitude may go from the white level in a fit (e^50 = 5e21)
VARIANCE_REACH = 50.0  # log: how far the blocks' independent variance may be scaled in a fit


def family_critical(tests: int, alpha: float = 0.01) -> float:
    """The likelihood ratio a term must exceed so that *tests* presence tests together name a
    term that is not there with probability at most *alpha* (Bonferroni on the boundary
    distribution ½ χ²₀ + ½ χ²₁: P(χ²₁ > c) = 2 α / tests)."""
    from components.estimation.distributions import chi2_isf

    return float(chi2_isf(2.0 * alpha / max(tests, 1), 1))


def pooled_critical(axes: int, tests: int, alpha: float = 0.01) -> float:
    """The critical value of the sum of *axes* independent presence tests' likelihood ratios (a
    term tested on every axis of a sensor at once), so that *tests* such tests together name a
    term that is not there with probability at most *alpha*: each ratio ½ χ²₀ + ½ χ²₁ under the
    null, so the sum is χ² with Binomial(axes, ½) degrees of freedom."""
    from scipy.optimize import brentq

    from components.estimation.distributions import chi2_sf

    weights = [math.comb(axes, j) / 2.0**axes for j in range(1, axes + 1)]
    target = alpha / max(tests, 1)

    def excess(c: float) -> float:
        return sum(w * float(chi2_sf(c, j)) for j, w in zip(range(1, axes + 1), weights)) - target

    hi = 1.0
    while excess(hi) > 0:  # (the tail falls with c: the root lies below the first c past it)
        hi *= 2.0
    return float(brentq(excess, 0.0, hi, xtol=1e-12, rtol=1e-15))


def restricted_loglik(ch: ChannelNoise, y: np.ndarray, H: np.ndarray, durations: np.ndarray,
                      white_var: np.ndarray, span: float, t_lo: float, restricted: bool = True,
                      advance: np.ndarray | None = None, gaps: np.ndarray | None = None) -> float:
    """ℓ of one channel's rows under *ch* (see the module docstring); ``restricted=False``: the
    ordinary log-likelihood at the GLS estimate, −½ [log det C + min_θ ‖y − H θ‖²_C] (the one that
    compares models with different columns). ``advance``: a pulse output's count phase through
    the rests, ``gaps`` [s]: what lies between the blocks (components.model.block_noise)."""
    bn = block_noise(ch, durations, white_var, span, t_lo, advance, gaps)
    w, S = whiten_channel(np.column_stack([y, H]), bn)
    yw, Hw = w[:, 0], w[:, 1:]
    out = -0.5 * (np.sum(np.log(S)) + yw @ yw)
    if Hw.shape[1]:
        # columns the channel does not see are left out by the caller; a rank-deficient rest is
        # handled through the SVD (pseudo-determinant over the resolved directions)
        U, s, _ = np.linalg.svd(Hw, full_matrices=False)
        keep = s > 1e-10 * s[0] if len(s) and s[0] > 0 else np.zeros(0, bool)
        proj = U[:, keep].T @ yw
        out += 0.5 * proj @ proj - (np.sum(np.log(s[keep])) if restricted else 0.0)
    return float(out)


def fit_slow_terms(ch: ChannelNoise, y: np.ndarray, H: np.ndarray, durations: np.ndarray,
                   white_var: np.ndarray, span: float, t_lo: float, terms=SLOW,
                   restricted: bool = True, critical: float = LR_CRITICAL,
                   variance_bound: bool = False, gaps: np.ndarray | None = None,
                   decided: dict | None = None, fits: dict | None = None) -> tuple[ChannelNoise, dict]:
    """*ch* with the magnitudes of *terms* re-estimated by (restricted) maximum likelihood, and
    the terms the data do not need dropped one at a time (backward elimination: bias instability
    and random walk can stand in for each other, so a term's likelihood ratio is taken against
    the others refitted without it). Returns the channel and, per term: value, σ, likelihood
    ratio (a dropped term's at the test that dropped it) with the ``critical`` one, present, and
    for an absent term a profile upper bound; ``loglik`` at the estimate and
    ``loglik_without`` with none of *terms*. ``critical``: the likelihood ratio a term must
    exceed (default: the 1 % level of one test; :func:`family_critical` for several).
    ``decided``: term -> present, the presence already decided by a test beyond this channel (a
    sensor's axes pooled, components.diagnosis.noise_id): the terms decided absent are dropped
    first, weakest first, those decided present kept, whatever this channel's own ratio (unless
    the likelihood is flat in one: :data:`FLAT_DEVIANCE`); the others are tested here.
    ``fits``: the maximisations of an earlier call on the same channel (same data and *ch*), read
    and added to in place: a channel refitted with its presence decided redoes none of them."""
    from scipy.optimize import minimize  # at use: ~0.1 s of every command's start otherwise

    lo_min, lo_max = max(float(np.min(durations)), 1e-3), max(span / 8.0, 2 * float(np.min(durations)))
    scale = math.sqrt(max(float(np.median(white_var / np.maximum(durations, 1e-12) ** 2)), 1e-300))
    base = replace(ch, **{t: 0.0 for t in terms})

    def variance_scale(v: float) -> float:
        return math.exp(min(max(v, -VARIANCE_REACH), VARIANCE_REACH))

    def loglik(c: ChannelNoise, v: float = 0.0) -> float:
        return restricted_loglik(c, y, H, durations, white_var * variance_scale(v), span, t_lo, restricted,
                                 gaps=gaps)

    # x = [magnitudes of the active terms (log), the floor's corner (log) if it is active, v]:
    # v (log) scales the blocks' independent variance, a nuisance refitted with every model, so
    # that excess scatter with no correlation from block to block (a white level a little low,
    # moves the motion model resolves less well than rests) is not taken for a slow term
    def nll(active: list[str], x) -> float:
        return -loglik(model(active, x), x[-1])

    def fitted_nll(active: list[str], x) -> float:
        # what the simplex minimises: the likelihood is flat beyond the clips below, where the
        # simplex wandered off and never came back (a floor's corner at e^36 s, clipped to
        # span/8, kept a fit 7.5 below the maximum, the floor 2.4x the truth), so a slope there
        # leads it back. Not in the curvatures and profiles: at a clip it would make up a σ (a
        # white level read from a variance scale at the bottom of its reach, 1e-4 of the truth)
        k = len(active)
        out = sum(max(0.0, v - mag_hi, mag_lo - v) ** 2 for v in x[:k])
        if "bias_instability" in active and len(x) > k + 1:
            out += max(0.0, x[k] - math.log(lo_max), math.log(lo_min) - x[k]) ** 2
        return nll(active, x) + out + max(0.0, abs(x[-1]) - VARIANCE_REACH) ** 2

    # magnitudes are clipped in log space to MAGNITUDE_REACH either side of the white level: the
    # simplex may wander far along a flat direction, and at e^355 a square overflows (a random
    # walk restarted from -928, where the first fit had left it, reached it on a 5-minute
    # tactical log: OverflowError out of `calbench noise`); beyond the reach a term is nothing
    # or everything, and its likelihood no different
    mag_lo, mag_hi = math.log(scale) - MAGNITUDE_REACH, math.log(scale) + MAGNITUDE_REACH

    def model(active: list[str], x) -> ChannelNoise:
        kw = {t: math.exp(min(max(v, mag_lo), mag_hi)) for t, v in zip(active, x)}
        if "bias_instability" in active:
            kw["flicker_range"] = (math.exp(min(max(x[len(active)], math.log(lo_min)), math.log(lo_max))), None)
        return replace(base, **kw)

    corner0 = math.log(min(max(FLICKER_CORNER_TEST, lo_min), lo_max))

    fits = {} if fits is None else fits

    def optimise(active: list[str], free_corner: bool = True, start=None):
        # each maximisation is a function of its arguments alone: the pooled tests' refit of a
        # channel (components.diagnosis.noise_id) starts with every one its first fit made, and
        # the elimination's last model without any term is the fit without terms asked again
        key = (tuple(active), free_corner, None if start is None else tuple(np.asarray(start, float).tolist()))
        if key not in fits:
            fits[key] = maximise(active, free_corner, start)
        x, f = fits[key]
        return x.copy(), f

    def maximise(active: list[str], free_corner: bool, start):
        x0 = [math.log(getattr(ch, t) or scale * (1.0 if t == "bias_instability" else 0.1 / math.sqrt(span)))
              for t in active]
        k = len(active)
        held = "bias_instability" in active and not free_corner
        if "bias_instability" in active and free_corner:
            x0.append(corner0)
        x0.append(0.0)
        if start is not None:
            x0 = list(start)

        def full(z):
            return np.concatenate([z[:k], [corner0], z[k:]]) if held else np.asarray(z, float)

        def run(z0):
            return minimize(lambda z: fitted_nll(active, full(z)), np.array(z0), method="Nelder-Mead",
                            options={"xatol": 1e-3, "fatol": 1e-4, "maxiter": 400 * max(1, len(z0) - 1)})

        r = run(x0)
        if start is None:
            # the likelihood can hold a second valley where the blocks' independent variance is
            # lower and a slow term takes its place: from a white level read too high (a pulse
            # channel's, at the ceiling of what its rests allow) the simplex lowered that level
            # and the floor together until the floor sat at e^-60, on a flat, and stayed there
            # (gyro_y of a 2" counts log: no floor, bias 8σ off; the floor's valley 5.5 higher)
            corners = (math.log(lo_min), corner0, math.log(lo_max)) if "bias_instability" in active and free_corner else ()
            z1 = _scan_start(lambda z: fitted_nll(active, full(z)), r.x, k, x0[:k], corners)
            if z1 is not None:  # (none better than where the simplex stopped: no second simplex)
                r1 = run(z1)
                if r1.fun < r.fun:
                    r = r1
        if "bias_instability" in active and free_corner and start is None:
            # the corner can hold two valleys, one at each end of its range: from the test
            # corner alone the simplex ran to the short end on a 5-minute log whose maximum was
            # at the long end (the floor 0.76e-3 for 0.97e-3, truth 1e-3, and both interval ends
            # measured from the wrong maximum), so it also starts at the long end, from the
            # first start and from where that fit ended
            for x1 in (list(x0), list(r.x)):
                x1[k] = math.log(lo_max)
                r1 = run(x1)
                if r1.fun < r.fun:
                    r = r1
        return full(r.x), float(r.fun)

    active = list(terms)
    x, f = optimise(active)
    # the maximum with every term in, before any is tested away: what the log says of each
    # magnitude when a term below detection is not set to 0 (noise_sensitivity's σ at estimates)
    every_term = model(active, x)
    lr, dropped_at = {}, {}  # (dropped_at: a dropped term's likelihood ratio at its test)
    # the elimination's first step: each term's test ratio against the model with every term, and
    # what dropping it costs against that fit with the floor's corner free (what ranks the terms)
    against_all, loss_against_all = None, {}
    decided = decided or {}
    while active:
        drops = {t: optimise([u for u in active if u != t]) for t in active}
        # a model with a term more fits at least as well as any without it: where the simplex
        # stopped short of that (in the floor's corner valley), it restarts from the better fit
        best = min(active, key=lambda t: drops[t][1])
        if drops[best][1] < f:
            x_try, f_try = optimise(active, start=_embed(active, best, drops[best][0], x))
            if f_try < f:
                x, f = x_try, f_try
        # the floor's presence is tested with its corner held: without the floor the corner
        # means nothing, and a likelihood ratio maximised over it too is not the 1 % test
        # LR_CRITICAL is for (it named a floor ten times the true one in 2 of 12 short logs)
        f_test = optimise(active, free_corner=False)[1] if "bias_instability" in active else f
        lr = {t: 2 * (drops[t][1] - (f_test if t == "bias_instability" else f)) for t in active}
        if against_all is None:
            against_all = dict(lr)
            loss_against_all = {t: 2 * (drops[t][1] - f) for t in active}
        # the term to drop is the one the model misses least, each loss against the same fit (the
        # corner free): the floor's test ratio is against the corner held, and ranked by those a
        # random walk the full fit put at ~0 outlived a floor it had at full size (6 of 30
        # 5-minute tactical logs named a random walk 100x the true one in the floor's place)
        # the terms decided absent go first; then a term decided present stays, unless this
        # channel's likelihood is flat in it: its maximum then sits at ~0 (1e-25 of the floor's
        # level), where the term is absent in all but name and its interval's walk finds no
        # upper end (14-18 s a channel, for (0, inf)). (Judged flat beside a random walk decided
        # absent, a 5-minute count log's acc_x floor went, then the random walk: neither, where
        # the floor alone has a ratio of 70)
        gone = [t for t in active if decided.get(t) is False] or \
            [t for t in active if decided.get(t) and 2 * (drops[t][1] - f) < FLAT_DEVIANCE]
        open_ = [t for t in active if t not in decided]
        if not gone and not open_:
            break
        weakest = min(gone or open_, key=lambda t: drops[t][1])
        if not gone and lr[weakest] > critical:
            break
        dropped_at[weakest] = max(lr[weakest], 0.0)
        active.remove(weakest)
        x, f = drops[weakest]
    out = model(active, x)
    # σ of the magnitudes from the curvature of the whole likelihood — the flicker corner and the
    # block-variance nuisance free with them, so what they trade with a magnitude counts (held at
    # their estimates, the acc floor's σ came out 1.6x too small on 36-minute logs: 33 of 36
    # within 3σ; free, 36 of 36, RMS z 0.89). Where that curvature is not positive (the corner
    # on a flat stretch of the likelihood), the corner is held.
    k = len(active)
    whole = _inverse_curvature(lambda z: nll(active, z), x, f)
    cov = whole[:k, :k]
    if not np.all(np.isfinite(np.diag(cov))):
        cov = _inverse_curvature(lambda z: nll(active, np.concatenate([z, x[k:]])), x[:k], f)
    # (the values the likelihood used: clipped as in loglik and model); the scale's σ in log: on
    # a pulse channel whose counts hide the white level it is that level's measurement
    # (components.diagnosis.noise_id), so where the whole curvature is not positive it is taken
    # with the floor's corner held, then with everything else held
    v_var = whole[-1, -1]
    if not v_var > 0 and len(x) > k + 1:
        v_var = _inverse_curvature(lambda z: nll(active, np.concatenate([z[:k], x[k:-1], z[k:]])),
                                   np.concatenate([x[:k], x[-1:]]), f)[-1, -1]
    if not v_var > 0:
        v_var = _inverse_curvature(lambda z: nll(active, np.concatenate([x[:-1], z])), x[-1:], f)[0, 0]
    report: dict = {"block_variance_scale": variance_scale(x[-1]),
                    "block_variance_log_sigma": math.sqrt(v_var) if v_var > 0 else float("nan")}
    if "bias_instability" in active:
        report["flicker_corner_s"] = out.flicker_range[0]
    if variance_bound and active:
        # the largest scale of the blocks' independent variance the log allows at one σ and at
        # three (deviance 1 and 9, everything else refitted at each step): where a slow term
        # takes the blocks' scatter the scale's maximum is at the bottom of its reach, and this
        # is what the log says of it
        spread = {len(active): (math.log(lo_min), math.log(lo_max))} if "bias_instability" in active else {}
        hi1, hi3 = profile_crossings(lambda z: nll(active, z), x, f, len(x) - 1, (1.0, PROFILE_LEVEL), 1.0, step=1.0,
                                     reach=VARIANCE_REACH + abs(x[-1]), spread=spread, refine=2)
        report["block_variance_upper"] = variance_scale(hi1) if math.isfinite(hi1) else float("nan")
        report["block_variance_upper_3sigma"] = variance_scale(hi3) if math.isfinite(hi3) else float("nan")
    f_none = optimise([])[1]
    # each term's ratio as the only one (the floor's with its corner held, as its test): with
    # against_all, the two steps of an elimination a test beyond this channel can pool
    # (components.diagnosis.noise_id.pooled_presence)
    alone = {t: 2 * (f_none - optimise([t], free_corner=t != "bias_instability")[1]) for t in terms}
    for t in terms:
        if t in active:
            i = active.index(t)
            value = getattr(out, t)
            # steps of about one σ (the curvature's): the crossing at three is a few steps out
            # (a term kept by a pooled test where this channel's likelihood is flat in it can have
            # no positive curvature: no σ from it, the interval alone)
            sd = math.sqrt(cov[i, i]) if cov[i, i] > 0 else None
            step = min(max(sd, 0.02), 0.1) if sd else 0.1
            # the floor's corner can hold two valleys of the likelihood at one magnitude
            spread = {len(active): (math.log(lo_min), math.log(lo_max))} if "bias_instability" in active else {}
            # toward 0 the profile runs to the fit without the term: where dropping it costs less
            # than the level (a term kept by a pooled test, or one present below three σ), the
            # lower end is 0 and not walked to the reach (70 minimisations per side's walk)
            sides = (-1.0, 1.0) if 2 * (drops[t][1] - f) >= PROFILE_LEVEL else (1.0,)
            ends = profile_interval(lambda z: nll(active, z), x, f, i, PROFILE_LEVEL, step, sd, spread=spread,
                                    sides=sides)
            lo, hi = ends if len(ends) == 2 else (-math.inf, ends[0])
            report[t] = {"value": value, "sigma": value * sd if sd else float("nan"),
                         "interval": (math.exp(lo), math.exp(hi)),
                         "likelihood_ratio": float(lr.get(t, 2 * (f_none - f))), "critical": critical, "present": True}
        else:
            # a profile bound: the magnitude at which adding the term costs 4.5 in likelihood
            # (three σ of a one-parameter interval), the present terms held at their estimate
            xi = math.log(scale * 1e-4)
            with_t = active + [t]
            extra = [math.log(10.0)] if t == "bias_instability" and "bias_instability" not in active else []
            f_best = f
            for _ in range(80):
                xi += math.log(1.5)
                z = list(x[: len(active)]) + [xi] + list(x[len(active):-1]) + extra + [x[-1]]
                val = nll(with_t, np.array(z))
                f_best = min(f_best, val)
                if val - f_best > 4.5:
                    break
            report[t] = {"value": 0.0, "sigma": float("nan"), "likelihood_ratio": float(dropped_at.get(t, 0.0)),
                         "critical": critical, "present": False, "upper": math.exp(xi)}
    report["every_term"] = every_term
    report["elimination"] = {"against_all": against_all or {}, "loss_against_all": loss_against_all, "alone": alone}
    report["loglik"] = -f
    report["loglik_without"] = -f_none
    return out, report


SCAN_VARIANCE = (0.0, -1.0, -2.0, -3.0)  # log: where _scan_start puts the blocks' variance scale, from the fit's
SCAN_MAGNITUDE = (-2.0, -1.0, 0.0, 1.0)  # log: and each slow term's magnitude, from its value there
DEAD = 8.0  # log: a magnitude this far below its start is one the fit set to nothing


def _scan_start(nll, x: np.ndarray, k: int, x0, corners=()) -> np.ndarray | None:
    """The best of a coarse grid around the fit *x* (coordinates: *k* log magnitudes, the floor's
    corner if free, then the variance scale v): v lowered by :data:`SCAN_VARIANCE`, each
    magnitude moved by :data:`SCAN_MAGNITUDE` from where it is (from its start *x0* where the
    fit left it more than :data:`DEAD` below that, log: at e^-54 a held floor's grid around it
    was all flat, and a floor of LR 33 went untested) and the corner at each of *corners*
    (log; empty: where it is). A start for a second simplex, not an estimate; None where no point
    of the grid is better than *x*."""
    best, f_best = None, nll(np.asarray(x, float))
    mags = [x[i] if x[i] > x0[i] - DEAD else x0[i] for i in range(k)]
    for dv, corner in itertools.product(SCAN_VARIANCE, corners or [None]):
        for dm in itertools.product(SCAN_MAGNITUDE, repeat=k):
            z = np.array(x, float)
            z[:k] = [m + d for m, d in zip(mags, dm)]
            z[-1] = x[-1] + dv
            if corner is not None:
                z[k] = corner
            f = nll(z)
            if f < f_best:
                best, f_best = z, f
    return best


def _embed(active: list[str], dropped: str, x_without: np.ndarray, x_with: np.ndarray) -> np.ndarray:
    """A start for the model with *active* terms from the fit without *dropped* (coordinates
    [log magnitudes in *active*'s order, log corner if the floor is active, v]): the dropped term
    at a twentieth of its value in *x_with*, the floor's corner from whichever fit has the floor."""
    rest = [t for t in active if t != dropped]
    mags = [x_with[active.index(t)] - math.log(20.0) if t == dropped else x_without[rest.index(t)] for t in active]
    corner = []
    if "bias_instability" in active:
        corner = [x_with[len(active)]] if dropped == "bias_instability" else [x_without[len(rest)]]
    return np.array(mags + corner + [x_without[-1]])


def profile_interval(nll, x: np.ndarray, f0: float, i: int, level: float, step: float = 0.1,
                     sd: float | None = None, reach: float = 7.0, spread: dict | None = None,
                     sides=(-1.0, 1.0)) -> tuple[float, ...]:
    """The profile-likelihood interval of x[i] (log scale): where 2 [min over the other
    coordinates of nll − f0] reaches *level* on each of *sides* (-1 lower, +1 upper, returned in
    that order; :func:`profile_crossings` says how it is walked)."""
    return tuple(profile_crossings(nll, x, f0, i, (level,), sign, step, sd, reach, spread)[0] for sign in sides)


def profile_crossings(nll, x: np.ndarray, f0: float, i: int, levels, sign: float, step: float = 0.1,
                      sd: float | None = None, reach: float = 7.0, spread: dict | None = None,
                      refine: int = 0) -> list[float]:
    """Where the profile deviance of x[i] (log scale), 2 [min over the other coordinates of
    nll − f0], reaches each of *levels* (ascending) on the side *sign* (-1 lower, +1 upper):
    walked outwards from the minimum *x* in *step*s (each minimisation started from the last
    one's), the crossing interpolated in the signed root of the deviance (near-linear in the
    coordinate, with slope 1/sd where the curvature gives a σ *sd*); one walk for all levels.
    ±inf where a level is not reached within *reach* (log) of x[i]: the log does not bound the
    magnitude that far on that side. *x* has at least one other coordinate (the likelihood's
    block-variance nuisance is always one). ``spread``: {index into *x*: values} of coordinates
    along which the likelihood may hold more than one valley at a given x[i] (the flicker floor's
    corner, with the ends of its range): each step is also minimised from the last step's point
    moved by each of :data:`SPREAD` along such a coordinate and put at each of its values, and
    the least taken. From the last point alone, one acc floor's lower end came out at 1.1e-4 or
    at 7.1e-5 of the same log as its last bits went (the simplex went up one valley or down the
    other, the truth 9.8e-5 between them); the profile is the lower valley's. ``refine``: that
    many more profile points per crossing, each where the interpolation in its bracket puts it
    (a long step over a curved root: the blocks' variance scale in steps of e, whose deviance-9
    point came out where the deviance is 7.9)."""
    from scipy.optimize import minimize

    rest = [j for j in range(len(x)) if j != i]
    jump = 1.5 * max(1.0, step / sd if sd else 1.0)  # a rise of the root that is more than a step's
    roots = [math.sqrt(v) for v in levels]
    crossings = [sign * math.inf] * len(levels)

    def least(bb, z0):
        def at(zz):
            full = np.empty(len(x))
            full[i], full[rest] = bb, zz
            return nll(full)
        r = minimize(at, z0, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-5, "maxiter": 400 * len(rest)})
        return r.x, float(r.fun), math.sqrt(max(2.0 * (float(r.fun) - f0), 0.0))

    def crossing(target, lo, hi, width):
        # lo, hi: (coordinate, root, other coordinates) on either side of the target root,
        # width = hi's coordinate - lo's (the signed step, exactly, before any refining)
        for _ in range(refine):
            b_mid = lo[0] + width * (target - lo[1]) / max(hi[1] - lo[1], 1e-12)
            mid = min((least(b_mid, lo[2]), least(b_mid, hi[2])), key=lambda r: r[1])
            point = (b_mid, mid[2], mid[0])
            lo, hi = (point, hi) if mid[2] < target else (lo, point)
            width = hi[0] - lo[0]
        return lo[0] + width * (target - lo[1]) / max(hi[1] - lo[1], 1e-12)

    z, b, root_prev, found = x[rest].copy(), x[i], 0.0, 0
    while abs(b - x[i]) < reach and found < len(levels):
        b_next = b + sign * step
        z_last = z
        z, val, root = least(b_next, z)
        for j, ends in (spread or {}).items():
            for to in [z_last[rest.index(j)] + off for off in SPREAD] + list(ends):
                z0 = z_last.copy()
                z0[rest.index(j)] = to
                z2, val2, root2 = least(b_next, z0)
                if val2 < val:
                    z, val, root = z2, val2, root2
        if root - root_prev > jump:
            # a jump of more than a step's worth: the other coordinates may have had to move
            # far (the floor's corner trades with its magnitude along a curved valley), so
            # the step is also started from the maximum's
            z2, val2, root2 = least(b_next, x[rest])
            if val2 < val:
                z, val, root = z2, val2, root2
        while found < len(levels) and root >= roots[found]:
            crossings[found] = crossing(roots[found], (b, root_prev, z_last), (b_next, root, z), sign * step)
            found += 1
        b, root_prev = b_next, root
    return crossings

def _inverse_curvature(nll, x: np.ndarray, f0: float, h: float = 1e-2) -> np.ndarray:
    """Inverse of the numerical Hessian of *nll* at its minimum *x* (NaN where not positive)."""
    n = len(x)
    if n == 0:
        return np.zeros((0, 0))
    Hs = np.zeros((n, n))
    for i in range(n):
        for j in range(i, n):
            ei, ej = np.eye(n)[i] * h, np.eye(n)[j] * h
            if i == j:
                Hs[i, i] = (nll(x + ei) - 2 * f0 + nll(x - ei)) / h**2
            else:
                Hs[i, j] = Hs[j, i] = (nll(x + ei + ej) - nll(x + ei - ej) - nll(x - ei + ej) + nll(x - ei - ej)) / (4 * h**2)
    try:
        return np.linalg.inv(Hs) if np.all(np.linalg.eigvalsh(Hs) > 0) else np.full((n, n), np.nan)
    except np.linalg.LinAlgError:
        return np.full((n, n), np.nan)


def term_level(term: str, durations: np.ndarray, white_var: np.ndarray, span: float) -> float:
    """The magnitude of a slow *term* at the level of the rows' white noise (a block's white σ as a
    rate; a random walk's over the log's *span*): the scale a term's fit searches around."""
    level = math.sqrt(max(float(np.median(white_var / np.maximum(durations, 1e-12) ** 2)), 1e-300))
    return level / math.sqrt(span) if term == "random_walk" else level


def fit_one_term(ch: ChannelNoise, term: str, y: np.ndarray, H: np.ndarray, durations: np.ndarray,
                 white_var: np.ndarray, span: float, t_lo: float, restricted: bool = False,
                 advance: np.ndarray | None = None, gaps: np.ndarray | None = None) -> tuple[float, float]:
    """(magnitude, gain in log-likelihood) of one noise term added to *ch* on these rows: a
    bounded one-dimensional maximum over the log magnitude (the flicker floor from *t_lo*). The
    ordinary likelihood by default: the gain compares with a missing effect's ½ Δχ²."""
    from scipy.optimize import minimize_scalar

    base = restricted_loglik(ch, y, H, durations, white_var, span, t_lo, restricted, advance, gaps)
    level = term_level(term, durations, white_var, span)
    lo, hi = math.log(level * 1e-3), math.log(level * 1e3)

    def nll(x):
        return -restricted_loglik(replace(ch, **{term: math.exp(x)}), y, H, durations, white_var, span, t_lo,
                                  restricted, advance, gaps)

    r = minimize_scalar(nll, bounds=(lo, hi), method="bounded", options={"xatol": 1e-2})
    gain = -r.fun - base
    if gain <= 0:
        return 0.0, 0.0
    return math.exp(r.x), float(gain)
