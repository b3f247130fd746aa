"""Noise identification against independent computations: closed-form Allan variances of white
noise, noise records generated in the test (not by the code under test), and the statistics of
the estimates over seeds."""
import math

import numpy as np
import pytest
from scipy import stats
from scipy.signal import lfilter

from components.estimation.allan import pooled_allan, static_runs
from components.estimation.noise_fit import identify_channel
from components.estimation.noise_likelihood import FLAT_DEVIANCE, LR_CRITICAL, fit_slow_terms
from components.model.effects import UG
from components.model.flicker import FLICKER_AVAR
from components.model.noise import ChannelNoise

DT = 0.01


def record(n, rng, white=0.0, rw=0.0, gm=(), quant=0.0):
    """Per-sample mean rates written from the definitions: white N/√dt, random walk K √dt per
    step, first-order Gauss–Markov (σ, T) as exact AR(1), quantization as the difference of
    uniform remainders of a pulse count of weight √12 Q."""
    r = white / math.sqrt(DT) * rng.standard_normal(n)
    if rw:
        r += np.cumsum(rw * math.sqrt(DT) * rng.standard_normal(n))
    for s, T in gm:
        phi = math.exp(-DT / T)
        e = s * math.sqrt(1 - phi**2) * rng.standard_normal(n)
        e[0] = s * rng.standard_normal()
        r += lfilter([1.0], [1.0, -phi], e)
    if quant:
        q = quant * math.sqrt(12) * (rng.random(n + 1) - 0.5)
        r += np.diff(q) / DT
    return r


def pulse_counts_at_rest(rng, n, position, w, noise):
    """A pulse output written from its definition over positions of *position* samples, each at a
    random constant input within ±1 g: the counts are the floor of the running integral of input
    + *noise()* (a per-sample rate record) over the count weight *w*, the remainder carried from
    sample to sample. Returns the counts' rate minus the input, the counts and the input."""
    true_rate = np.repeat(9.80665 * rng.uniform(-1, 1, n // position + 1), position)[:n]
    inc = (true_rate + noise()) * DT
    counts = np.floor((np.cumsum(inc) + w * rng.random()) / w)
    return np.diff(counts, prepend=counts[0] - np.round(inc[0] / w)) * w / DT - true_rate, counts, true_rate


def runs_of(n, length, gap):
    static = np.zeros(n, bool)
    for a in range(0, n, length + gap):
        static[a:a + length] = True
    return static_runs(static)


def test_pooled_allan_of_white_noise_is_its_closed_form_within_the_edf_interval():
    rng = np.random.default_rng(1)
    n = 200_000
    r = record(n, rng, white=1e-3)
    av = pooled_allan(r, runs_of(n, 6000, 500), DT)
    expected = 1e-3**2 / av.tau
    # each τ's estimate within its 99.9 % χ² interval from the equivalent degrees of freedom
    lo = expected * stats.chi2.ppf(0.0005, av.edf) / av.edf
    hi = expected * stats.chi2.ppf(0.9995, av.edf) / av.edf
    assert np.all((av.avar > lo) & (av.avar < hi)), np.c_[av.tau, av.avar / expected, av.edf]


def test_fast_terms_recovered_within_three_sigma_and_absent_ones_not_claimed():
    # white noise and quantization, as a navigation-grade pulse-output gyro shows them
    rng = np.random.default_rng(2)
    n = 120_000
    N, Q = 2e-5, 3e-6
    r = record(n, rng, white=N, quant=Q)
    fit = identify_channel(r, runs_of(n, 3000, 300), DT, bootstrap=20, seed=3)
    assert set(fit.present) == {"white", "quantization"}
    assert abs(fit.noise.white - N) < 3 * fit.sigma["white"]
    assert abs(fit.noise.quantization - Q) < 3 * fit.sigma["quantization"]


def test_the_white_level_is_not_taken_by_terms_the_record_lacks():
    """On white-noise records the fit's other terms (quantization, bias instability, random walk;
    held non-negative) come out above 0 by chance and take variance from the white level beside
    them: read from that fit, the level was 0.5 % low on average (six standard errors of this
    ensemble's mean). Refitted with the present terms alone it is unbiased: the ensemble's mean
    relative error within three of its standard errors."""
    rng = np.random.default_rng(21)
    N, n = 1e-2, 30_000
    runs = runs_of(n, 1000, 500)
    err = np.array([identify_channel(record(n, rng, white=N), runs, DT, bootstrap=5, seed=k).noise.white / N - 1
                    for k in range(60)])
    assert abs(err.mean()) < 3 * err.std(ddof=1) / math.sqrt(len(err)), (err.mean(), err.std(ddof=1))


def test_a_pulse_output_at_rest_keeps_its_white_level_beside_coarser_quantization():
    """A pulse output written from its definition: the counts are the floor of the running
    integral of the input over a count weight w, so the remainder is carried from sample to
    sample. At rest (a constant input per position) the remainder follows the position's
    fractional count rate, not i.i.d. draws, and shows a short-τ Allan variance below 3 Q²/τ².
    With counts coarser than the white noise of a sample (w/√12 three times its σ here), the
    white level is still found within three of its σ, and no Gauss–Markov term is invented."""
    rng = np.random.default_rng(11)
    n, length, gap = 150_000, 3000, 300
    N, w = 1e-4, 1e-4                     # 10 µg/√Hz at 100 Hz: 1e-5 m/s a sample; w/√12 = 2.9e-5
    runs = runs_of(n, length, gap)
    rate, counts, true_rate = pulse_counts_at_rest(rng, n, length + gap, w, lambda: record(n, rng, white=N))
    assert np.mean(np.diff(counts) == np.round(true_rate[1:] * DT / w)) > 0.2  # coarse: mostly the same count
    fit = identify_channel(rate, runs, DT, known={"quantization": w / math.sqrt(12)}, bootstrap=20, seed=4)
    assert "white" in fit.present and fit.gm_tau is None, (fit.present, fit.gm_tau, fit.notes)
    assert abs(fit.noise.white - N) < 3 * fit.sigma["white"], (fit.noise.white, fit.sigma)


def test_a_floor_below_three_sigma_beside_coarse_counts_does_not_go_into_the_white_level():
    """Coarse pulse counts leave only τ ≥ ~0.3 s to fit, where a flicker floor from 10 s already
    shows; on a record of 26 thirty-second rests (a logger file's schedule) it can stay below
    three of its σ — on this one it does. Refitted without it, the white level took the floor's
    variance and read 10 % high (6 of its σ); the present terms keep the full fit's values
    instead, said in the notes, and the white level is within the bound of its bootstrap σ
    (Student's t, 19 degrees of freedom, 1 %)."""
    from components.model.flicker import flicker_terms

    rng = np.random.default_rng(13)
    n, length, gap = 26 * 3300, 3000, 300
    N, B, w = 1e-4, 1e-4, 1e-4
    runs = runs_of(n, length, gap)
    rate, _, _ = pulse_counts_at_rest(rng, n, length + gap, w,
                                      lambda: record(n, rng, white=N, gm=flicker_terms(B, 10.0, 3600.0)))
    fit = identify_channel(rate, runs, DT, known={"quantization": w / math.sqrt(12)}, bootstrap=20, seed=4)
    assert "bias_instability" not in fit.present and any("below three σ" in x for x in fit.notes), fit.notes
    assert abs(fit.noise.white - N) < stats.t.isf(0.005, 19) * fit.sigma["white"], (fit.noise.white, fit.sigma)


def test_without_a_bootstrap_only_the_white_noise_is_kept_and_nothing_overflows():
    """The report draws the Allan deviations with no bootstrap: with no σ no term is tested, so none
    is claimed but the white noise no sensor is without (dropped, the page's model was all
    zeros and its likelihood stage did not run), and nothing overflows (the fit of no terms
    overflowed the fit statistic, a warning at the end of every demo)."""
    import warnings

    rng = np.random.default_rng(3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = identify_channel(record(20_000, rng, white=1e-3), runs_of(20_000, 2000, 200), DT, bootstrap=0)
    assert fit.present == ["white"], fit
    assert abs(fit.noise.white / 1e-3 - 1) < 0.05 and not fit.noise.bias_instability and not fit.noise.random_walk


def _floor_blocks(rng, blk, nb, N, B):
    """Block sums (y, design H, durations, span) of *nb* rests of *blk* seconds: white noise N and
    a flicker floor B from 10 s to an hour (its Gauss–Markov sum), a bias and a scale factor
    over four attitudes as the design."""
    from components.model.flicker import flicker_terms

    per = int(blk / DT)
    r = record(nb * per, rng, white=N, gm=flicker_terms(B, 10.0, 3600.0))
    y = (r * DT).reshape(nb, per).sum(axis=1)
    H = blk * np.column_stack([np.ones(nb), np.tile(np.repeat([1.0, -1.0, 0.0, 0.5], 3), nb)[:nb]])
    return y, H, np.full(nb, blk), nb * blk


def _blocks(r, nb, per):
    """1 s block sums of the increments, a bias and a ±1 g scale factor as the design."""
    y = (r[: nb * per] * DT).reshape(nb, per).sum(axis=1)
    f = np.tile(np.repeat([1.0, -1.0, 0.0, 0.5], 60), nb // 240 + 1)[:nb]
    H = np.column_stack([np.ones(nb), f])
    return y + H @ np.array([50 * UG, 20e-6 * 9.8]), H


@pytest.mark.parametrize("present", [("bias_instability",), ("random_walk",)])
def test_slow_terms_by_likelihood_recover_the_one_present(present):
    # bias instability as a flat floor over [1 s, 3 h] from GM terms written here (equal σ, two
    # per decade; its level B is what its Allan variance averages to over that range)
    rng = np.random.default_rng(5 if present[0] == "random_walk" else 6)
    nb, per = 2400, int(1 / DT)
    N = 10 * UG
    if present == ("bias_instability",):
        T = np.geomspace(0.5, 20000, 10)
        taus = np.geomspace(1, 10000, 64)
        g = lambda u: 2 / u - (3 - 4 * np.exp(-u) + np.exp(-2 * u)) / u**2  # noqa: E731
        s = math.sqrt(FLICKER_AVAR * (8 * UG) ** 2 / np.mean([g(t / T).sum() for t in taus]))
        r = record(nb * per, rng, white=N, gm=[(s, t) for t in T])
        truth = {"bias_instability": 8 * UG}
    else:
        r = record(nb * per, rng, white=N, rw=0.5 * UG)
        truth = {"random_walk": 0.5 * UG}
    y, H = _blocks(r, nb, per)
    d = np.ones(nb)
    ch, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, float(nb), 1.0)
    for t in ("bias_instability", "random_walk"):
        assert rep[t]["present"] == (t in truth), rep
    t = present[0]
    # the flat floor the GM sum was scaled to is approximate (±12 %): the σ and that margin
    assert abs(rep[t]["value"] - truth[t]) < 3 * rep[t]["sigma"] + 0.12 * truth[t], rep


def test_the_family_level_of_the_presence_tests():
    """½ χ²₀ + ½ χ²₁ exceeds c with probability 1 − Φ(√c): the family's critical value puts
    α / m there (the normal quantile, independent of the χ² routine), and one test's is the
    documented 5.41."""
    from scipy.stats import norm

    from components.estimation.noise_likelihood import LR_CRITICAL, family_critical

    assert family_critical(1) == pytest.approx(LR_CRITICAL, abs=1e-4)
    for m in (2, 6, 12):
        assert math.sqrt(family_critical(m)) == pytest.approx(norm.isf(0.01 / m), rel=1e-9)


def test_the_floors_sigma_counts_what_its_corner_trades_with_it():
    """The σ of the bias instability is the profile likelihood's: the curvature of ℓ maximised
    over the floor's lower corner and the block-variance nuisance at each magnitude, computed
    here by a grid of fixed magnitudes and an optimiser of its own over those two. Held at their
    estimates instead, the corner's trade with the magnitude was left out and the accelerometer
    floor's σ came out 1.6× too small on 36-minute logs (benchmarks/coloured_noise*.txt:
    within 3σ in 90 % of logs). 10 s blocks over 40 minutes (a multi-position log's rests), the
    floor from 10 s to an hour."""
    from scipy.optimize import minimize

    from components.estimation.noise_likelihood import restricted_loglik

    N, B = 10 * UG, 10 * UG
    y, H, d, span = _floor_blocks(np.random.default_rng(204), 10.0, 240, N, B)
    ch, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, span, 1.0, terms=("bias_instability",))
    b = rep["bias_instability"]
    assert b["present"], rep

    def profile(log_b):
        def nll(z):
            c = ChannelNoise(white=N, bias_instability=math.exp(log_b), flicker_range=(math.exp(z[0]), None))
            return -restricted_loglik(c, y, H, d, N**2 * d * math.exp(z[1]), span, 1.0)
        return min(minimize(nll, z0, method="Nelder-Mead", options={"xatol": 1e-6, "fatol": 1e-9}).fun
                   for z0 in ([math.log(rep["flicker_corner_s"]), math.log(rep["block_variance_scale"])], [math.log(10.0), 0.0]))

    x0 = math.log(b["value"])
    steps = np.linspace(-0.1, 0.1, 5)
    curvature = np.polyfit(steps, [profile(x0 + s) for s in steps], 2)[0] * 2
    sigma_profile = b["value"] / math.sqrt(curvature)
    assert b["sigma"] == pytest.approx(sigma_profile, rel=0.15), (b["sigma"], sigma_profile)


def test_the_slow_terms_interval_is_where_the_profile_likelihood_reaches_three_sigma():
    """On a 5-minute log the floor's likelihood is far from quadratic (the corner trades with the
    magnitude along a curved valley): value ± 3σ from the curvature held the truth in 87 % of
    tactical 5-minute logs. The reported interval is the profile likelihood's: at each end the
    deviance, maximised here over the corner and the block-variance nuisance by an optimiser of
    its own, is 9 (three σ of a one-parameter interval)."""
    from scipy.optimize import minimize

    from components.estimation.noise_likelihood import restricted_loglik

    N, B, blk = 1e-3, 1e-3, 5.0
    y, H, d, span = _floor_blocks(np.random.default_rng(305), blk, 60, N, B)
    _, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, span, 1.0, terms=("bias_instability",))
    b = rep["bias_instability"]
    assert b["present"], rep
    lo, hi = b["interval"]

    def nll(log_b, z):
        c = ChannelNoise(white=N, bias_instability=math.exp(log_b), flicker_range=(math.exp(z[0]), None))
        return -restricted_loglik(c, y, H, d, N**2 * d * math.exp(z[1]), span, 1.0)

    # the corner within the range the model gives it (the shortest block .. an eighth of the log),
    # here as bounds of Powell's method
    corner = (math.log(blk), math.log(span / 8))
    starts = ([math.log(rep["flicker_corner_s"]), math.log(rep["block_variance_scale"])], [math.log(10.0), 0.0],
              [math.log(blk) + 0.01, 0.0])

    def profile(log_b):
        return min(minimize(lambda z: nll(log_b, z), z0, method="Powell", bounds=[corner, (-5, 5)],
                            options={"xtol": 1e-6, "ftol": 1e-10, "maxiter": 4000}).fun for z0 in starts)

    best = min(minimize(lambda x: nll(x[0], x[1:]), [math.log(b["value"]), *z0], method="Powell",
                        bounds=[(-15, 0), corner, (-5, 5)],
                        options={"xtol": 1e-6, "ftol": 1e-10, "maxiter": 6000}).fun for z0 in starts)
    for end in (lo, hi):
        assert 2 * (profile(math.log(end)) - best) == pytest.approx(9.0, abs=0.6), (lo, b["value"], hi)
    # and it is not the symmetric one: the upper side reaches further (log-likelihood flatter there)
    assert hi / b["value"] > b["value"] / lo, (lo, b["value"], hi)


@pytest.mark.parametrize("seed", [302, 303, 307, 308, 331])
def test_the_interval_walk_does_not_stop_in_the_higher_of_two_valleys(seed):
    """At a given floor magnitude the likelihood can hold two valleys along the flicker corner;
    walked from the last step's point alone, the interval ended where the higher one crossed
    three σ (deviance 3.1-5.6 at that end on 307, 308, 331: too narrow). On 302 and 303 the fit
    itself stopped in the wrong valley (the corner at the short end of its range, the maximum at
    the long end), and the upper end, measured from it, had a deviance of 2.2-2.9. Each end is
    checked here against the profile over a grid of starts by Powell's method."""
    from scipy.optimize import minimize

    from components.estimation.noise_likelihood import restricted_loglik

    N, blk = 1e-3, 5.0
    y, H, d, span = _floor_blocks(np.random.default_rng(seed), blk, 60, N, 1e-3)
    _, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, span, 1.0, terms=("bias_instability",))
    b = rep["bias_instability"]
    assert b["present"], rep

    def nll(log_b, z):
        c = ChannelNoise(white=N, bias_instability=math.exp(log_b), flicker_range=(math.exp(z[0]), None))
        return -restricted_loglik(c, y, H, d, N**2 * d * math.exp(z[1]), span, 1.0)

    corner = (math.log(blk), math.log(span / 8))
    starts = [[c, v] for c in np.linspace(corner[0] + 0.01, corner[1] - 0.01, 6) for v in (-0.5, 0.0, 0.5)]
    opts = {"xtol": 1e-6, "ftol": 1e-10, "maxiter": 4000}

    def profile(log_b):
        return min(minimize(lambda z: nll(log_b, z), z0, method="Powell", bounds=[corner, (-5, 5)],
                            options=opts).fun for z0 in starts)

    best = min(minimize(lambda x: nll(x[0], x[1:]), [math.log(b["value"]), *z0], method="Powell",
                        bounds=[(-15, 0), corner, (-5, 5)], options=opts).fun for z0 in starts)
    for end in b["interval"]:
        assert 2 * (profile(math.log(end)) - best) == pytest.approx(9.0, abs=0.6), (b["interval"], b["value"])


def test_a_floor_on_a_short_log_is_not_taken_for_a_random_walk():
    """Over five minutes a flicker floor and a random walk both explain the wander; with both
    in, the fit keeps the floor. Backward elimination must then drop the term the model misses
    least, each loss against the same fit: ranked by test ratios against different fits (the
    floor's with its corner held), a random walk the full fit put near 0 outlived the floor, and
    one was named in its place — 100x any true one — on 6 of 30 tactical 5-minute logs' channels.
    Floor-only records: a random walk named on at most 2 of 24 (with each record's test at its
    1 % level, 3 or more has probability 0.2 %; the old ranking named 4)."""

    rng = np.random.default_rng(77)
    N = 1e-3
    named = 0
    for _ in range(24):
        y, H, d, span = _floor_blocks(rng, 5.0, 60, N, 1e-3)
        _, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, span, 1.0)
        named += rep["random_walk"]["present"]
    assert named <= 2, named


def test_a_magnitude_far_along_a_flat_direction_does_not_overflow_the_fit():
    """The simplex may wander far along a direction the rows do not see (a random walk on a
    5-minute log was restarted from e^-928 and reached e^355, where its square overflowed:
    OverflowError out of `calbench noise`). A start at an absurd magnitude is the same path in
    one step: the fit ends, and on white rows finds neither slow term."""
    rng = np.random.default_rng(8)
    nb, per = 300, int(1 / DT)
    N = 10 * UG
    y, H = _blocks(record(nb * per, rng, white=N), nb, per)
    d = np.ones(nb)
    ch, rep = fit_slow_terms(ChannelNoise(white=N, random_walk=1e200, bias_instability=1e-300), y, H, d,
                             N**2 * d, float(nb), 1.0)
    assert not rep["random_walk"]["present"] and not rep["bias_instability"]["present"], rep
    assert ch.random_walk == 0.0 and ch.bias_instability == 0.0
    assert np.isfinite(rep["loglik"]) and rep["loglik"] >= rep["loglik_without"] - 1e-9


@pytest.mark.parametrize("seed", [3, 5, 6])
def test_a_floor_beside_a_white_level_given_too_high_is_the_likelihoods_maximum(seed):
    """A pulse channel whose counts hide its white level starts the block variance at the most
    its rests allow (here twice the truth); the likelihood then has its maximum where that
    variance is lower and the floor takes its place. From that start the simplex stopped short:
    on 5 and 6 it ran the floor's corner out to e^36 s, past the clip where the likelihood is
    flat, and on 3 it stayed in the far valley of the corner, 13 below the maximum with the
    floor at 2.1x the truth. (On a 2" counts log, gyro_y's 0.1 °/h floor was lost the same way
    and its bias came out 8σ off.) The fit must reach the maximum that a grid of starts and an
    optimiser of the test's own find over magnitude, corner and variance scale, and the floor
    must lie within 3σ of the truth (with the ±12 % of the flat floor the GM sum approximates)."""
    from scipy.optimize import minimize

    from components.estimation.noise_likelihood import restricted_loglik

    N, B = 10 * UG, 10 * UG
    y, H, d, span = _floor_blocks(np.random.default_rng(seed), 1.0, 800, N, B)
    ceiling = 2.0 * N
    _, rep = fit_slow_terms(ChannelNoise(white=0.0), y, H, d, ceiling**2 * d, span, 1.0)
    b = rep["bias_instability"]
    corner = (math.log(1.0), math.log(span / 8))

    def nll(z):
        c = ChannelNoise(white=0.0, bias_instability=math.exp(z[0]), flicker_range=(math.exp(z[1]), None))
        return -restricted_loglik(c, y, H, d, ceiling**2 * d * math.exp(z[2]), span, 1.0)

    starts = [[lb, c, v] for lb in math.log(B) + np.arange(-3.0, 3.1) for c in np.linspace(*corner, 4)
              for v in np.arange(-3.0, 0.6, 0.5)]
    z0 = min(starts, key=nll)
    best = minimize(nll, z0, method="Powell", bounds=[(-20, 0), corner, (-5, 5)],
                    options={"xtol": 1e-6, "ftol": 1e-10, "maxiter": 4000})
    assert rep["loglik"] >= -best.fun - 0.05, (rep["loglik"], -best.fun, best.x)
    assert b["present"] and abs(b["value"] - B) < 3 * b["sigma"] + 0.12 * B, b


@pytest.mark.parametrize("name", ["coarse_counts_gyro_y", "coarse_counts_acc_z"])
def test_a_floor_the_blocks_show_is_found_beside_coarse_counts(name):
    """Two channels' block rows (tests/data/block_rows: y, H, durations, the white variance at
    the ceiling of what the rests allow, and the counts' quantization) where the likelihood's
    maximum has a flicker floor and a lower block variance. The first is gyro_y of a 13-minute
    log of 2" counts: the fit lost its floor (from the ceiling the simplex ran the floor to
    nothing) and the gyro bias came out 8σ off. The second is acc_z of a 5-minute log of 1 mm/s
    counts: the fit with every term found it, but the fit of the floor alone with its corner held
    (the presence test's) started from where the fit had set the floor to e^-54, searched a flat
    around it, and the floor was tested away; diagnose then named acc.temp. Against a maximum
    the test finds itself (a grid of starts and Powell over the floor, its corner and the
    variance scale; and the variance scale alone without the floor): the floor's likelihood
    ratio exceeds the family's critical value, so the fit must name it and reach that maximum."""
    from pathlib import Path

    from scipy.optimize import minimize, minimize_scalar

    from components.estimation.noise_likelihood import family_critical, restricted_loglik

    r = np.load(Path(__file__).parent / "data" / "block_rows" / f"{name}.npz")
    y, H, d, wv, span, q = r["y"], r["H"], r["durations"], r["white_var"], float(r["span"]), float(r["quantization"])
    critical = family_critical(12)  # six channels, two slow terms each, as identify_noise tests them
    ch, rep = fit_slow_terms(ChannelNoise(quantization=q), y, H, d, wv, span, 1.0, critical=critical)
    corner = (math.log(max(float(d.min()), 1e-3)), math.log(max(span / 8, 2 * float(d.min()))))

    def nll(z):
        c = ChannelNoise(quantization=q, bias_instability=math.exp(z[0]), flicker_range=(math.exp(z[1]), None))
        return -restricted_loglik(c, y, H, d, wv * math.exp(z[2]), span, 1.0)

    level = math.log(math.sqrt(float(np.median(wv / d**2))))
    starts = [[b, c, v] for b in level + np.arange(-6.0, 2.1) for c in np.linspace(*corner, 5)
              for v in np.arange(-6.0, 1.1, 0.5)]
    floor = minimize(nll, min(starts, key=nll), method="Powell", bounds=[(level - 20, level + 5), corner, (-12, 5)],
                     options={"xtol": 1e-6, "ftol": 1e-10, "maxiter": 4000})
    none = minimize_scalar(lambda v: -restricted_loglik(ChannelNoise(quantization=q), y, H, d, wv * math.exp(v), span,
                                                        1.0), bounds=(-12, 5), method="bounded")
    assert 2 * (none.fun - floor.fun) > critical  # the premise: the floor is there to be found (gyro_y: 10.2)
    assert rep["bias_instability"]["present"], rep
    assert rep["loglik"] >= -floor.fun - 0.05, (rep["loglik"], -floor.fun, floor.x)


def test_a_white_level_the_blocks_do_not_bound_below_has_its_one_and_three_sigma_limits():
    """acc_z of coarse-count seed 8 (tests/data/block_rows): the floor takes the blocks' scatter
    and the maximum of the blocks' independent variance is at the bottom of its reach. What the
    log says of it are upper limits: the scales at which the deviance, maximised over the floor,
    its corner and nothing else, reaches 1 and 9 (one walk finds both). Checked against the
    profile the test computes itself (a grid of starts and Powell over floor and corner at
    each scale)."""
    from pathlib import Path

    from scipy.optimize import minimize

    from components.estimation.noise_likelihood import family_critical, restricted_loglik

    r = np.load(Path(__file__).parent / "data" / "block_rows" / "coarse_counts_acc_z.npz")
    y, H, d, wv, span, q = r["y"], r["H"], r["durations"], r["white_var"], float(r["span"]), float(r["quantization"])
    _, rep = fit_slow_terms(ChannelNoise(quantization=q), y, H, d, wv, span, 1.0, critical=family_critical(12),
                            variance_bound=True)
    assert rep["bias_instability"]["present"] and rep["block_variance_scale"] < 1e-6, rep
    upper = rep["block_variance_upper"]
    corner = (math.log(max(float(d.min()), 1e-3)), math.log(max(span / 8, 2 * float(d.min()))))
    level = math.log(math.sqrt(float(np.median(wv / d**2))))

    def profile(scale):
        def nll(z):
            c = ChannelNoise(quantization=q, bias_instability=math.exp(z[0]), flicker_range=(math.exp(z[1]), None))
            return -restricted_loglik(c, y, H, d, wv * scale, span, 1.0)
        starts = [[b, c] for b in level + np.arange(-6.0, 2.1) for c in np.linspace(*corner, 5)]
        return minimize(nll, min(starts, key=nll), method="Powell", bounds=[(level - 20, level + 5), corner],
                        options={"xtol": 1e-6, "ftol": 1e-10, "maxiter": 4000}).fun

    at_max = profile(rep["block_variance_scale"])
    deviance = 2 * (profile(upper) - at_max)
    assert deviance == pytest.approx(1.0, abs=0.1), (upper, deviance)
    upper3 = rep["block_variance_upper_3sigma"]
    assert upper3 > upper
    deviance3 = 2 * (profile(upper3) - at_max)
    assert deviance3 == pytest.approx(9.0, abs=0.3), (upper3, deviance3)


@pytest.mark.parametrize("rw,present", [(0.1, False), (0.2, True)])
def test_a_terms_likelihood_ratio_is_its_tests_whether_kept_or_dropped(rw, present):
    """The likelihood ratio reported for a slow term — kept, or dropped by its presence test —
    is 2 (max ℓ with it − max ℓ without), both maxima found here by a separate search over the
    term's magnitude and the blocks' variance scale: 20 minutes of 1 s blocks, white noise 10 µg
    and a random walk weak enough that the test drops it (LR ~1.3 against 5.41) or keeps it."""
    from scipy.optimize import minimize

    from components.estimation.noise_likelihood import restricted_loglik

    rng = np.random.default_rng(0)
    nb, per, N = 1200, int(1 / DT), 10 * UG
    y, H = _blocks(record(nb * per, rng, white=N, rw=rw * UG), nb, per)
    d = np.ones(nb)
    wv = N**2 * d
    _, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, wv, float(nb), 1.0, terms=("random_walk",))
    r = rep["random_walk"]
    assert r["present"] == present

    def nll(K: float, v: float) -> float:
        return -restricted_loglik(ChannelNoise(white=N, random_walk=K), y, H, d, wv * math.exp(v), float(nb), 1.0)

    opts = {"xatol": 1e-6, "fatol": 1e-8}
    with_term = min((minimize(lambda z: nll(math.exp(z[0]), z[1]), [math.log(s * UG), 0.0], method="Nelder-Mead",
                              options=opts) for s in (0.03, 0.1, 0.3, 1.0)), key=lambda o: o.fun)
    without = minimize(lambda z: nll(0.0, z[0]), [0.0], method="Nelder-Mead", options=opts)
    lr = 2 * (without.fun - with_term.fun)
    assert (lr > r["critical"]) == present
    assert r["likelihood_ratio"] == pytest.approx(lr, abs=0.01)
    assert lr > 0.5  # (a dropped term's ratio is not simply 0)


@pytest.mark.parametrize("axes,tests", [(3, 4), (3, 1), (2, 6), (1, 12)])
def test_the_pooled_critical_value_of_a_sensors_axes(axes, tests):
    """Under the null each axis's ratio is ½ χ²₀ + ½ χ²₁, so their sum is χ² with Binomial(axes, ½)
    degrees of freedom: the pooled critical value leaves α / tests above it (written here from
    scipy.stats), and one axis's is the family's own."""
    from components.estimation.noise_likelihood import family_critical, pooled_critical

    c = pooled_critical(axes, tests)
    tail = sum(stats.binom.pmf(j, axes, 0.5) * stats.chi2.sf(c, j) for j in range(1, axes + 1))
    assert tail == pytest.approx(0.01 / tests, rel=1e-9)
    if axes == 1:
        assert c == pytest.approx(family_critical(tests), rel=1e-9)


def test_a_presence_decided_by_the_pooled_test_overrides_the_channels_own():
    """fit_slow_terms with the presence decided beyond the channel (its sensor's axes pooled):
    a random walk this channel alone drops (LR ~1.3) is kept at its likelihood maximum, one it
    alone keeps (LR ~18) is dropped with its upper bound, and either way the ratio reported is
    the channel's own."""
    nb, per, N = 1200, int(1 / DT), 10 * UG
    d = np.ones(nb)
    for rw, own in ((0.1, False), (0.2, True)):
        y, H = _blocks(record(nb * per, np.random.default_rng(0), white=N, rw=rw * UG), nb, per)
        _, alone = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, float(nb), 1.0, terms=("random_walk",))
        ch, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, float(nb), 1.0, terms=("random_walk",),
                                 decided={"random_walk": not own})
        assert alone["random_walk"]["present"] == own
        assert rep["random_walk"]["present"] == (not own)
        assert rep["random_walk"]["likelihood_ratio"] == pytest.approx(alone["random_walk"]["likelihood_ratio"],
                                                                       abs=0.01)
        if own:
            assert ch.random_walk == 0.0 and rep["random_walk"]["upper"] > 0
        else:
            # kept: its maximum, where the likelihood ratio says it is (~ the truth, within its interval)
            lo, hi = rep["random_walk"]["interval"]
            assert ch.random_walk > 0 and lo <= 0.1 * UG <= hi
    # white noise alone: the likelihood is flat in the random walk (its maximum at ~0), so a
    # pooled 'present' cannot keep it there; it stays absent with its upper bound
    y, H = _blocks(record(nb * per, np.random.default_rng(2), white=N), nb, per)
    ch, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, float(nb), 1.0, terms=("random_walk",),
                             decided={"random_walk": True})
    assert rep["random_walk"]["likelihood_ratio"] < 0.01
    assert not rep["random_walk"]["present"] and ch.random_walk == 0.0 and 0 < rep["random_walk"]["upper"] < 0.3 * UG


def test_a_refit_with_the_first_fits_maximisations_gives_the_same_bits_and_redoes_none(monkeypatch):
    """The pooled tests' refit of a channel is handed the maximisations of its first fit: its
    result is that of a refit from scratch, bit for bit, and it runs only the minimisations the
    first fit did not (the interval of the term it now keeps), none of the elimination's."""
    import scipy.optimize

    nb, per, N = 1200, int(1 / DT), 10 * UG
    d = np.ones(nb)
    y, H = _blocks(record(nb * per, np.random.default_rng(0), white=N, rw=0.1 * UG), nb, per)
    args = (ChannelNoise(white=N), y, H, d, N**2 * d, float(nb), 1.0)
    runs = []
    minimize = scipy.optimize.minimize
    monkeypatch.setattr(scipy.optimize, "minimize", lambda *a, **k: runs.append(1) or minimize(*a, **k))
    fits: dict = {}
    fit_slow_terms(*args, terms=("random_walk",), fits=fits)
    assert fits  # (the elimination's maximisations, kept)
    runs.clear()
    ch0, rep0 = fit_slow_terms(*args, terms=("random_walk",), decided={"random_walk": True})
    scratch = len(runs)
    runs.clear()
    ch1, rep1 = fit_slow_terms(*args, terms=("random_walk",), decided={"random_walk": True}, fits=fits)
    assert ch1 == ch0 and rep1["random_walk"] == rep0["random_walk"]
    assert rep1["loglik"] == rep0["loglik"] and rep1["loglik_without"] == rep0["loglik_without"]
    # the maximisations with and without the term (each a first simplex and its restarts) are not rerun
    print(f"minimisations: {scratch} from scratch, {len(runs)} with the first fit's")
    assert len(runs) < scratch - 2


def _report(against_all: dict, alone: dict, own: dict, loss: dict | None = None) -> dict:
    """A channel's likelihood report as pooled_presence reads it: each term's ratio at its own
    test (``own``) and the elimination's two steps (``loss``: what dropping each term costs
    against the fit with every term, the floor's corner free; by default its test ratio)."""
    return {**{t: {"likelihood_ratio": v} for t, v in own.items()},
            "elimination": {"against_all": against_all, "loss_against_all": loss or against_all, "alone": alone}}


def test_the_pooled_tests_eliminate_on_the_axes_sums_step_by_step():
    """A triad whose x axis's random walk stands in for its floor (each alone ~40, against the
    other ~1) and whose y and z axes have a floor and no random walk: the sums against the model
    with both are 62 for the floor and 2.2 for the random walk, so the random walk goes from
    every axis (2.2 < 11.6) and the floor, tested alone (40 + 35 + 35), stays on every axis.
    The axes' ratios at their own tests (x kept its random walk at 45 against no term) summed
    to 45.2 for the random walk: present on all three axes beside the floor."""
    from components.diagnosis.noise_id import pooled_presence

    bi, rw = "bias_instability", "random_walk"
    x = _report({bi: 0.5, rw: 2.0}, {bi: 40.0, rw: 45.0}, {bi: 0.5, rw: 45.0})
    yz = _report({bi: 30.0, rw: 0.1}, {bi: 35.0, rw: 20.0}, {bi: 35.0, rw: 0.1})
    pooled = [((0, 1, 2), bi), ((0, 1, 2), rw)]
    decided, tested = pooled_presence([x, yz, yz], pooled, 11.6)
    assert decided == [{bi: True, rw: False}] * 3
    assert tested[0][rw]["pooled_likelihood_ratio"] == pytest.approx(2.2)
    assert tested[0][bi]["pooled_likelihood_ratio"] == pytest.approx(110.0)
    # both strong against the model with both: both stay
    both = _report({bi: 9.0, rw: 8.0}, {bi: 50.0, rw: 50.0}, {bi: 9.0, rw: 8.0})
    assert pooled_presence([both] * 3, pooled, 11.6)[0] == [{bi: True, rw: True}] * 3
    # the weaker absent and the other, alone, too
    weak = _report({bi: 1.0, rw: 0.5}, {bi: 3.0, rw: 2.0}, {bi: 1.0, rw: 0.5})
    assert pooled_presence([weak] * 3, pooled, 11.6)[0] == [{bi: False, rw: False}] * 3
    # one term pooled: the axes' own ratios
    assert pooled_presence([x, yz, yz], [((0, 1, 2), rw)], 11.6)[0] == [{rw: True}] * 3


def test_the_pooled_elimination_ranks_the_terms_as_each_channel_does():
    """Each channel's elimination drops first the term whose loss, against the fit with the
    floor's corner free, is least; the floor's test ratio holds its corner and can be the smaller
    where the corner moves to take the wander. A triad whose floors each cost 8 to drop but test
    at 1, beside random walks that cost and test 2: the random walk goes (its sum 6 < 11.6) and
    the floor, alone (20 + 20 + 20), stays. Ranked by the test ratios, the floor went (3) and the
    random walk, alone (30 + 30 + 30), stood in for it."""
    from components.diagnosis.noise_id import pooled_presence

    bi, rw = "bias_instability", "random_walk"
    axis = _report({bi: 1.0, rw: 2.0}, {bi: 20.0, rw: 30.0}, {bi: 1.0, rw: 2.0}, loss={bi: 8.0, rw: 2.0})
    decided, tested = pooled_presence([axis] * 3, [((0, 1, 2), bi), ((0, 1, 2), rw)], 11.6)
    assert decided == [{bi: True, rw: False}] * 3
    assert tested[0][rw]["pooled_likelihood_ratio"] == pytest.approx(6.0)
    assert tested[0][bi]["pooled_likelihood_ratio"] == pytest.approx(60.0)


def test_a_channel_reports_what_dropping_each_term_costs_against_the_full_fit():
    """The elimination's ranking is in the report: each term's loss is twice the log-likelihood
    the fit with every term (the floor's corner free) has over the fit with the other term
    alone, each maximised by a call of its own (the terms kept by *decided*); and the floor's
    loss is at least its test ratio (the test holds the corner, which can only lower the full
    fit's maximum)."""
    from components.model.flicker import flicker_terms

    nb, per, N = 600, int(1 / DT), 10 * UG
    d = np.ones(nb)
    y, H = _blocks(record(nb * per, np.random.default_rng(3), white=N, rw=2 * UG,
                          gm=flicker_terms(3 * UG, 10.0, 3600.0)), nb, per)
    args = (ChannelNoise(white=N), y, H, d, N**2 * d, float(nb), 1.0)
    _, rep = fit_slow_terms(*args)
    el = rep["elimination"]
    assert set(el["loss_against_all"]) == set(el["against_all"]) == {"bias_instability", "random_walk"}
    bi, rw = "bias_instability", "random_walk"
    both = fit_slow_terms(*args, decided={bi: True, rw: True})[1]["loglik"]
    for t, other in ((bi, rw), (rw, bi)):
        alone = fit_slow_terms(*args, terms=(other,), decided={other: True})[1]["loglik"]
        print(f"{t}: reported loss {el['loss_against_all'][t]:.4f} (test ratio {el['against_all'][t]:.4f}), "
              f"from two fits {2 * (both - alone):.4f}")
        assert el["loss_against_all"][t] == pytest.approx(2 * (both - alone), abs=0.02)
    assert el["loss_against_all"][bi] >= el["against_all"][bi] - 1e-9


def test_a_term_decided_absent_goes_before_one_decided_present_is_judged_flat():
    """A random walk the sensor's pooled tests decided absent and a floor they decided present,
    on a channel whose wander is a random walk: beside the random walk the floor adds nothing
    (its likelihood flat), but the random walk goes first, and alone the floor takes the wander
    (its ratio far above the critical one): kept, not dropped with the random walk after it."""
    nb, per, N = 1200, int(1 / DT), 10 * UG
    d = np.ones(nb)
    y, H = _blocks(record(nb * per, np.random.default_rng(1), white=N, rw=5 * UG), nb, per)
    ch, rep = fit_slow_terms(ChannelNoise(white=N), y, H, d, N**2 * d, float(nb), 1.0,
                             decided={"bias_instability": True, "random_walk": False})
    assert rep["elimination"]["against_all"]["bias_instability"] < FLAT_DEVIANCE  # (the case: flat beside it)
    assert not rep["random_walk"]["present"] and ch.random_walk == 0.0
    assert rep["bias_instability"]["present"] and ch.bias_instability > 0
    assert rep["elimination"]["alone"]["bias_instability"] > 2 * LR_CRITICAL


def test_static_runs_are_the_masks_runs():
    """static_runs against a loop over the mask: every run of True at least min_samples long,
    at the ends too, none on an empty or all-False mask."""
    rng = np.random.default_rng(12)
    for mask in [np.zeros(0, bool), np.zeros(7, bool), np.ones(9, bool)] + [rng.random(n) < 0.8 for n in (1, 50, 997)]:
        want, a = [], None
        for i, m in enumerate(list(mask) + [False]):
            if m and a is None:
                a = i
            elif not m and a is not None:
                if i - a >= 3:
                    want.append((a, i))
                a = None
        assert static_runs(mask, 3) == want
