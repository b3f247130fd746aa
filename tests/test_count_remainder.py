"""A pulse output's count remainder turning through a rest (components.model.count_remainder,
the turning whitening filter, components.estimation.count_phase) against independent
computations:

- the covariance of the block sums' quantization error written from the remainder's Fourier
  series with a Gaussian phase wander (Cov r_j r_k = Σₙ cos(2πn mΔ) e^(−2π²n² m s²) / 2π²n², a
  few thousand terms), which the filter's L L' must reproduce to what the harmonics left
  independent can carry;
- a Monte-Carlo of real counts — floor of the accumulated input plus white noise — whose rest
  rates the generalised least squares must give with honest σ, where the plain quantization term
  (remainders independent) gives σ too small by the factor the covariance says;
- the tick rate of simulated counts, within the σ count_advance states.
"""
import math

import numpy as np
import pytest

from components.estimation.count_phase import count_advance
from components.estimation.whitening import whiten_channel
from components.model.block_noise import block_noise
from components.model.count_remainder import KEPT_DAMPING, kept_harmonics
from components.model.noise import ChannelNoise

W = 2.0  # one count (any unit)


def fourier_covariance(advance: float, spread: float, white_var: float, nb: int, terms: int = 4000) -> np.ndarray:
    n = np.arange(1, terms + 1)

    def R(m):
        m = abs(m)
        return float(np.sum(np.cos(2 * np.pi * n * m * advance) * np.exp(-2 * np.pi**2 * n**2 * m * spread)
                            / (2 * np.pi**2 * n**2)))

    r = {m: R(m) for m in range(0, nb + 2)}
    C = np.empty((nb, nb))
    for j in range(nb):
        for k in range(nb):
            m = abs(k - j)
            C[j, k] = W**2 * (2 * r[m] - r[abs(m - 1)] - r[m + 1])
    return C + np.eye(nb) * white_var


def filter_covariance(bn, nb: int) -> np.ndarray:
    Linv, _ = whiten_channel(np.eye(nb), bn)
    L = np.linalg.inv(Linv)
    return L @ L.T


def rest_noise(nb: int, advance: float, sigma: float, turning: bool = True):
    ch = ChannelNoise(quantization=W / math.sqrt(12))
    wv = np.full(nb, (sigma * W) ** 2)
    return block_noise(ch, np.ones(nb), wv, 100.0, 1.0, np.full(nb, advance * W) if turning else None)


@pytest.mark.parametrize("advance,sigma", [(3.02, 0.06), (7.37, 0.06), (0.01, 0.02), (3.5, 0.3)])
def test_the_filter_has_the_remainders_covariance(advance, sigma):
    nb = 40
    bn = rest_noise(nb, advance, sigma)
    kept = kept_harmonics(np.array([sigma**2]))
    assert bn.spin is not None and bn.states == 2 * kept + 1
    C = fourier_covariance(advance, sigma**2, (sigma * W) ** 2, nb)
    # the harmonics beyond the kept ones are taken as independent: each keeps less than
    # KEPT_DAMPING of its phase over a block, and together they carry 1/(2π² kept) of var r
    bound = 4 * W**2 * KEPT_DAMPING / (2 * math.pi**2 * kept)
    assert np.max(np.abs(filter_covariance(bn, nb) - C)) <= bound


def test_a_dithered_count_keeps_the_plain_term_bit_for_bit():
    """Noise of a count a block dithers every harmonic within the block: the same form as the
    remainders taken as independent (so fine counts are weighed as before)."""
    nb = 30
    plain, turned = rest_noise(nb, 3.3, 1.0, turning=False), rest_noise(nb, 3.3, 1.0)
    assert turned.spin is None
    for a, b in zip((plain.phi, plain.q, plain.c, plain.cross, plain.r, plain.p0),
                    (turned.phi, turned.q, turned.c, turned.cross, turned.r, turned.p0)):
        assert np.array_equal(a, b)


def simulated_rest_counts(rng, rests: int, nb: int, per_block: int, advance: float, sigma: float):
    """Per-sample counts (rests, nb * per_block) of a pulse output at a steady input of *advance*
    counts a block: each sample's count is the difference of floor(phase), the phase a uniform
    start plus the input plus white noise of *sigma* counts a block."""
    steps = advance / per_block + rng.normal(0, sigma / math.sqrt(per_block), (rests, nb * per_block))
    phase = np.concatenate([rng.random((rests, 1)), steps], axis=1).cumsum(axis=1)
    return np.diff(np.floor(phase), axis=1)


def rest_rows(nb: int, per_block: int) -> dict:
    return {"sensor": np.array(["gyro"] * nb), "axis": np.zeros(nb, int), "start": np.arange(nb) * per_block,
            "stop": np.arange(1, nb + 1) * per_block, "moving": np.zeros(nb, bool)}


@pytest.mark.parametrize("advance", [3.02, 0.013])
def test_rest_rates_by_gls_have_honest_sigma_only_with_the_turning_remainder(advance):
    """2000 rests of 30 one-second blocks at 100 samples a block, counts at an input that leaves
    a slow sawtooth (a fiftieth or less of a count per block beside a whole number, or of its
    first harmonics): the rest's rate by generalised least squares, error over σ. With the
    remainder turning — by the exact advance, and by the advance count_advance reads from the
    ticks — the RMS of those is 1 within its χ² band; taken as independent, the σ are too small
    (RMS far above)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(7)
    rests, nb, per, sigma = 2000, 30, 100, 0.06
    counts = simulated_rest_counts(rng, rests, nb, per, advance, sigma)
    sums = counts.reshape(rests, nb, per).sum(axis=2) * W
    x = np.ones((nb, 1))
    band = math.sqrt(1 + 3 * math.sqrt(2 / rests))  # RMS z of exact σ: χ²(n)/n within 3 of its SD
    ch = ChannelNoise(quantization=W / math.sqrt(12))
    wv = np.full(nb, (sigma * W) ** 2)
    rows = rest_rows(nb, per)

    def advance_by(kind, c):
        if kind == "exact":
            return np.full(nb, advance * W)
        if kind == "ticks":
            data = SimpleNamespace(count_weight=(W, None), gyro=np.column_stack([c * W, 0 * c, 0 * c]), acc=None)
            return count_advance(data, rows)["advance"]
        return None

    # read from the ticks, the advance is taken as exact though it is not: at 0.013 counts a
    # block a rest's counts tick once at most and the RMS is ~1.09 (count_phase's docstring)
    band_ticks = 1.12 if advance == 0.013 else band
    for kind in ("exact", "ticks", "independent"):
        z = []
        for y, c in zip(sums, counts):
            w, _ = whiten_channel(np.column_stack([y, x]), block_noise(ch, np.ones(nb), wv, 100.0, 1.0, advance_by(kind, c)))
            yw, hw = w[:, 0], w[:, 1]
            z.append(((hw @ yw) / (hw @ hw) - advance * W) * math.sqrt(hw @ hw))
        rms = float(np.sqrt(np.mean(np.square(z))))
        if kind == "independent":
            assert rms > 1.2 * band, rms
        else:
            assert 1 / band <= rms <= (band_ticks if kind == "ticks" else band), (kind, rms)


def test_the_tick_rate_is_known_to_a_samples_advance_at_each_end():
    """count_advance on simulated rests of a pulse gyro, slow and fast, either sign: each rest's
    rate within three σ of the truth, σ that of the tick method — the phase at the first and
    last tick known to a sample's advance beyond the whole counts (uniform: σ of the ends' sum
    √2 · that / √12) and the white noise's wander over the samples between; moves get none."""
    from types import SimpleNamespace

    rng = np.random.default_rng(3)
    per_block, nb, w, noise = 100, 20, 1e-5, 0.004  # noise: counts a sample
    rates = [0.0713, 0.51, -0.033, 97.63, -4.12]  # counts a sample
    gyro, start, stop, moving = [], [], [], []
    t = 0
    for r in rates:
        phase = np.concatenate([[rng.random()], r + rng.normal(0, noise, nb * per_block)]).cumsum()
        gyro.append(np.column_stack([np.diff(np.floor(phase)) * w, np.zeros((nb * per_block, 2))]))
        start += [t + k * per_block for k in range(nb)]
        stop += [t + (k + 1) * per_block for k in range(nb)]
        moving += [False] * nb
        t += nb * per_block
        gyro.append(np.zeros((50, 3)))  # a move: one block
        start.append(t), stop.append(t + 50), moving.append(True)
        t += 50
    data = SimpleNamespace(count_weight=(w, None), gyro=np.concatenate(gyro), acc=np.zeros((t, 3)))
    n = len(start)
    rows = {"sensor": np.array(["gyro"] * n), "axis": np.zeros(n, int), "start": np.array(start),
            "stop": np.array(stop), "moving": np.array(moving)}
    adv = count_advance(data, rows)["advance"]
    assert np.all(np.isnan(adv[rows["moving"]]))
    # a rest's first block starts it (nothing carried from before); the others meet the one before
    first = np.arange(n) % (nb + 1) == 0
    assert np.all(np.isnan(adv[first, 1])) and np.all(adv[~first & ~rows["moving"], 1] == 0)
    adv = adv[:, 0]
    span = nb * per_block
    for i, r in enumerate(rates):
        blocks = slice(i * (nb + 1), i * (nb + 1) + nb)
        frac = abs(r - round(r))
        sd_rate = math.sqrt(2 * frac**2 / 12 / span**2 + noise**2 / span)  # counts a sample
        err = adv[blocks] / (w * per_block) - r
        assert np.all(np.abs(err) <= 3 * sd_rate), (r, err[0], sd_rate)


def rest_rate_fit(rests, rate_true: float) -> tuple[float, float]:
    """(mean χ² per degree of freedom, RMS error/σ of the rate) of each rest's rate by generalised
    least squares: *rests* [(block sums y, their BlockNoise)]."""
    chi2, z = [], []
    for y, bn in rests:
        w, _ = whiten_channel(np.column_stack([y, np.ones(len(y))]), bn)
        yw, hw = w[:, 0], w[:, 1]
        rate = (hw @ yw) / (hw @ hw)
        chi2.append(float(np.sum((yw - hw * rate) ** 2)) / (len(y) - 1))
        z.append((rate - rate_true) * math.sqrt(hw @ hw))
    return float(np.mean(chi2)), float(np.sqrt(np.mean(np.square(z))))


def simulated_counts_under_a_slow_term(rng, rests, nb, per, advance, white, gm_sigma, T):
    """Per-sample counts as simulated_rest_counts, the input also carrying a Gauss–Markov rate
    of *gm_sigma* counts a block (RMS) and time constant *T* blocks."""
    from scipy.signal import lfilter

    phi = math.exp(-1.0 / (per * T))
    shocks = rng.normal(0, gm_sigma * math.sqrt(1 - phi**2), (rests, nb * per))
    shocks[:, 0] = rng.normal(0, gm_sigma, rests)  # (stationary from the start)
    rate = lfilter([1.0], [1.0, -phi], shocks, axis=1)
    steps = (advance + rate + rng.normal(0, white * math.sqrt(per), (rests, nb * per))) / per
    phase = np.concatenate([rng.random((rests, 1)), steps], axis=1).cumsum(axis=1)
    return np.diff(np.floor(phase), axis=1)


@pytest.mark.parametrize("advance,gm_sigma,T", [(3.02, 0.36, 20.0), (0.013, 0.36, 300.0), (3.02, 0.05, 2000.0)])
def test_a_slow_terms_wander_within_the_rest_dithers_the_remainder(advance, gm_sigma, T, monkeypatch):
    """600 rests of 30 one-second blocks whose rate carries a strong Gauss–Markov term (0.05–0.36
    counts a block RMS, T 20–2000 s; white noise 0.03 counts a block), the advance read from
    the ticks: the block sums whitened under the true model have χ² per row at most 1 within its
    band (the wander's spread, V(h)/h averaged over the lags, is a Markov stand-in for a smooth
    wander and is allowed to err low by up to 0.1), and the rest rates honest σ. With the
    harmonics damped by the white noise alone, the strong term's sawtooth is held too sure."""
    from types import SimpleNamespace

    import components.model.block_noise as noise_model  # (where block_noise looks the wander up)

    rng = np.random.default_rng(11)
    rests, nb, per, white = 600, 30, 100, 0.03
    counts = simulated_counts_under_a_slow_term(rng, rests, nb, per, advance, white, gm_sigma, T)
    sums = counts.reshape(rests, nb, per).sum(axis=2) * W
    ch = ChannelNoise(quantization=W / math.sqrt(12), gauss_markov=((gm_sigma * W, T),))
    rows = rest_rows(nb, per)
    advances = [count_advance(SimpleNamespace(count_weight=(W, None), gyro=np.column_stack([c * W, 0 * c, 0 * c]),
                                              acc=None), rows)["advance"] for c in counts]

    def fit():
        return rest_rate_fit([(y, block_noise(ch, np.ones(nb), np.full(nb, (white * W) ** 2), 1e4, 1.0, adv))
                              for y, adv in zip(sums, advances)], advance * W)

    top = 1 + 2 * 3 * math.sqrt(2 / (rests * (nb - 1)))  # (×2: the rows within a rest correlate)
    band = math.sqrt(1 + 3 * math.sqrt(2 / rests))
    chi2, rms = fit()
    assert 0.9 <= chi2 <= top, chi2
    assert 1 / band <= rms <= band, rms
    if T < nb:
        monkeypatch.setattr(noise_model, "slow_wander_in_rest", lambda terms, rw, d, rest: np.zeros(len(d)))
        assert fit()[0] > 1.5, "the white noise alone should hold the sawtooth too sure"


def test_the_wander_of_a_fast_term_is_white_and_of_a_random_walk_the_slow_limit():
    """slow_wander_in_rest's spread per second against closed forms: a Gauss–Markov term far
    faster than a block is white noise of density 2σ²T, whose phase over m of a rest's n blocks,
    its mean removed, has variance m q (1 − m/n) — V(h)/h averaged over the lags is 2σ²T (n−1)/2n;
    a rate random walk K is the limit T → ∞ of a term of variance K²T/2 (its own formula)."""
    from components.model.rest_wander import slow_wander_in_rest

    n, d = 30, np.ones(30)
    rest = np.full(n, float(n))
    sigma, T = 0.3, 1e-3
    got = slow_wander_in_rest([(sigma, T)], 0.0, d, rest)
    assert np.allclose(got, 2 * sigma**2 * T * (n - 1) / (2 * n), rtol=2e-3), got[0]
    K, T_long = 1e-3, 1e8
    walk = slow_wander_in_rest([], K, d, rest)
    limit = slow_wander_in_rest([(K * math.sqrt(T_long / 2), T_long)], 0.0, d, rest)
    assert np.allclose(walk, limit, rtol=1e-4), (walk[0], limit[0])
    assert np.all(slow_wander_in_rest([(sigma, T)], K, d, np.full(n, np.nan)) == 0)  # not at rest


def test_a_gap_inside_a_rest_starts_the_phase_anew():
    """1000 rests of 30 one-second blocks (2" counts at 3.02 counts a block, as above) with a
    stretch of 5-95 samples left out after the fifteenth block: the counts go on ticking through
    it, so the phase after it is the one before turned by an unknown fraction of a count.
    count_advance reads the two halves at their own rates and whitening with the gaps (the phase
    new after one) gives χ² per row within its band and honest σ for the rest's rate; carried
    across as if the blocks met, the phase is held sure and wrong, and the rate's σ too small
    (RMS error/σ 1.46 at this seed)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(13)
    rests, nb, per, sigma, advance = 1000, 30, 100, 0.06, 3.02
    half = nb // 2
    top = 1 + 2 * 3 * math.sqrt(2 / (rests * (nb - 1)))
    band = math.sqrt(1 + 3 * math.sqrt(2 / rests))
    ch = ChannelNoise(quantization=W / math.sqrt(12))
    wv = np.full(nb, (sigma * W) ** 2)
    cases = []
    for _ in range(rests):
        skip = int(rng.integers(5, 96))
        c = simulated_rest_counts(rng, 1, nb * per + skip, 1, advance / per, sigma / math.sqrt(per))[0]
        start = np.arange(nb) * per + np.where(np.arange(nb) >= half, skip, 0)
        rows = {"sensor": np.array(["gyro"] * nb), "axis": np.zeros(nb, int), "start": start,
                "stop": start + per, "moving": np.zeros(nb, bool)}
        data = SimpleNamespace(count_weight=(W, None), gyro=np.column_stack([c * W, 0 * c, 0 * c]), acc=None)
        y = np.array([c[a:a + per].sum() for a in start]) * W
        gaps = np.zeros(nb)
        gaps[half] = skip / per
        cases.append((y, count_advance(data, rows)["advance"], gaps))

    def fit(with_gaps: bool):
        return rest_rate_fit([(y, block_noise(ch, np.ones(nb), wv, 100.0, 1.0, adv, gaps if with_gaps else None))
                              for y, adv, gaps in cases], advance * W)

    chi2, rms = fit(True)
    # (the tick-read advance, taken as exact, sets part of what the sums show: χ² may run low)
    assert 0.8 <= chi2 <= top, chi2
    assert 1 / band <= rms <= band, rms
    assert fit(False)[1] > 1.2 * band, "carried across the gap, the phase should be held sure and wrong"


def test_a_lost_packet_inside_a_rest_leaves_its_rate_read_whole():
    """4000 rests of 30 one-second blocks of a pulse output at 0.37 counts a block (Earth's rate
    on a 2" gyro count: a tick every few seconds), one packet lost every three blocks — its counts
    gone with it, the sample after it left out (its interval starts at the lost one's end), as a
    logger's lost packet arrives in a log. The blocks between two losses see one or two ticks, so
    a rate read from each such piece alone is off by a large part of a count a piece; read over
    the whole rest (no move fits in a sample's gap) the block sums' χ² per row is within its band
    (each piece's own: 1.56), and with the phase turned on through each gap by the rest's rate
    over the gap's time (two samples: the lost one has no row, but its interval passed) the rest's
    rate has honest σ (the phase taken as new after each gap: RMS error/σ 0.62, σ too wide)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(17)
    rests, nb, per, sigma, advance, every = 4000, 30, 100, 0.06, 0.37, 3
    top = 1 + 2 * 3 * math.sqrt(2 / (rests * (nb - 1)))
    band = math.sqrt(1 + 3 * math.sqrt(2 / rests))
    ch = ChannelNoise(quantization=W / math.sqrt(12))
    wv = np.full(nb, (sigma * W) ** 2)
    losses = nb // every - 1
    cases = []
    for _ in range(rests):
        c = simulated_rest_counts(rng, 1, nb * per + 2 * losses, 1, advance / per, sigma / math.sqrt(per))[0]
        # every `every` blocks a lost sample (gone from the log) and then one left out (in the log)
        lost = (np.arange(1, losses + 1) * (every * per + 2)) - 2
        logged = np.delete(c, lost)
        start = np.arange(nb) * per + (np.arange(nb) // every)
        rows = {"sensor": np.array(["gyro"] * nb), "axis": np.zeros(nb, int), "start": start,
                "stop": start + per, "moving": np.zeros(nb, bool)}
        data = SimpleNamespace(count_weight=(W, None), gyro=np.column_stack([logged * W, 0 * logged, 0 * logged]),
                               acc=None, time=np.delete(np.arange(1, len(c) + 1) / per, lost))
        y = np.array([logged[a:a + per].sum() for a in start]) * W
        gaps = np.where((np.arange(nb) % every == 0) & (np.arange(nb) > 0), 2.0 / per, 0.0)
        cases.append((y, count_advance(data, rows)["advance"], gaps))
    chi2, rms = rest_rate_fit([(y, block_noise(ch, np.ones(nb), wv, 100.0, 1.0, adv, gaps)) for y, adv, gaps in cases],
                              advance * W)
    assert 0.8 <= chi2 <= top, chi2
    assert 1 / band <= rms <= band, rms


def test_the_turning_filter_in_pieces_is_the_same_filter():
    """A pulse output's remainder turns through the rests (the filter's second entry): run a
    piece of blocks at a time, its state carried over, it gives the bits of one call."""
    from components.estimation.whitening import ChannelWhitener

    bn = rest_noise(40, 3.02, 0.06)
    assert bn.spin is not None
    Y = np.random.default_rng(3).standard_normal((40, 2))
    whitener = ChannelWhitener(bn, 2)
    got = np.vstack([whitener(Y[a:b])[0] for a, b in ((0, 13), (13, 14), (14, 40))])
    assert np.array_equal(got, whiten_channel(Y, bn)[0])


def test_what_a_gap_carries_of_the_remainder_beyond_the_kept_harmonics_is_their_damped_sum():
    """remainder_carried's closed form (the sawtooth's autocovariance smoothed by the gap's phase
    spread) against the sum it stands for, Σ_{n>kept} cos(2πn x) e^(−2π²n²s²) / n² over its
    share Σ_{n>kept} 1/n², summed directly over 200,000 harmonics (the tail beyond them ~1e-5 of
    the share at kept = 16): turns either side of whole counts, spreads from none to half a count."""
    from components.model.count_remainder import remainder_carried

    rng = np.random.default_rng(1)
    x = rng.uniform(-3, 3, 200)
    s2 = rng.choice([0, 1e-6, 1e-4, 1e-3, 5e-3, 0.009, 0.0101, 0.02, 0.1, 0.5], 200)
    for kept in (0, 1, 3, 16):
        n = np.arange(kept + 1, 200_001, dtype=float)
        direct = np.array([(np.exp(-2 * math.pi**2 * s * n**2) * np.cos(2 * math.pi * t * n)) @ (1 / n**2)
                           for t, s in zip(x, s2)]) / np.sum(1 / n**2)
        assert np.max(np.abs(remainder_carried(kept, x, s2) - direct)) < 1e-4, kept
    assert np.all(remainder_carried(2, np.array([np.nan]), np.array([0.0])) == 0.0)
