"""The whitening filter against an independent computation: the dense covariance of the block
sums written from the continuous-time noise model (double integrals of each term's covariance
function), whitened by its Cholesky factor. The Kalman filter's output must be L⁻¹ y."""
import math

import numpy as np
import pytest
from scipy.linalg import cholesky, solve_triangular

from components.estimation.whitening import ChannelWhitener, whiten_channel
from components.model.block_noise import block_noise, flicker_upper
from components.model.noise import ChannelNoise


def dense_covariance(ch: ChannelNoise, edges: np.ndarray, white_var: np.ndarray, span: float, t_lo: float,
                     ends: np.ndarray | None = None):
    """Covariance of the block sums ∫ e dt over [edges[k], edges[k+1]] (or over [edges[k],
    ends[k]], gaps between) from the covariance functions: GM σ² e^(−|t−s|/T) (stationary),
    random walk P0 + K² min(s, t) (time from edges[0]), quantization r_start − r_end with
    var r = Q², one remainder shared where a block ends as the next starts; white on the diagonal."""
    if ends is None:
        a, b = edges[:-1] - edges[0], edges[1:] - edges[0]
    else:
        a, b = edges - edges[0], ends - edges[0]
    d = b - a
    n = len(d)
    C = np.diag(np.asarray(white_var, float)).copy()
    for s, T in ch.gm_terms(t_lo, flicker_upper(span, t_lo)):
        for k in range(n):
            C[k, k] += 2 * s**2 * T * (d[k] - T * (1 - math.exp(-d[k] / T)))
            for m in range(k + 1, n):
                v = s**2 * T**2 * (1 - math.exp(-d[k] / T)) * (1 - math.exp(-d[m] / T)) * math.exp(-(a[m] - b[k]) / T)
                C[k, m] += v
                C[m, k] += v
    K = ch.random_walk
    if K > 0:
        P0 = K**2 * max(span, 1.0)
        for k in range(n):
            C[k, k] += P0 * d[k] ** 2 + K**2 * (a[k] * d[k] ** 2 + d[k] ** 3 / 3)
            for m in range(k + 1, n):
                v = P0 * d[k] * d[m] + K**2 * (b[k] ** 2 - a[k] ** 2) / 2 * d[m]
                C[k, m] += v
                C[m, k] += v
    Q = ch.quantization
    if Q > 0:
        C[np.arange(n), np.arange(n)] += 2 * Q**2
        shared = np.flatnonzero(a[1:] == b[:-1])
        C[shared, shared + 1] -= Q**2
        C[shared + 1, shared] -= Q**2
    return C


CASES = {
    "gauss-markov": ChannelNoise(white=1e-3, gauss_markov=((2e-3, 30.0), (1e-3, 400.0))),
    "flicker": ChannelNoise(white=1e-3, bias_instability=1e-3),
    "random walk": ChannelNoise(white=1e-3, random_walk=1e-4),
    "quantization": ChannelNoise(white=1e-4, quantization=2e-3),
    "all": ChannelNoise(white=1e-3, quantization=1e-3, bias_instability=5e-4, random_walk=5e-5,
                        gauss_markov=((1e-3, 60.0),)),
}


@pytest.mark.parametrize("name", list(CASES))
def test_filter_equals_cholesky_whitening(name):
    ch = CASES[name]
    rng = np.random.default_rng(4)
    d = rng.choice([1.0, 1.0, 1.0, 3.7, 0.6], size=120)   # static chunks and moves of other lengths
    edges = np.concatenate([[0.0], np.cumsum(d)])
    white_var = ch.white**2 * d + rng.uniform(0, 1e-7, len(d))
    span, t_lo = float(edges[-1]), 1.0
    C = dense_covariance(ch, edges, white_var, span, t_lo)
    L = cholesky(C, lower=True)
    Y = rng.standard_normal((len(d), 3))
    expected = solve_triangular(L, Y, lower=True)
    got, S = whiten_channel(Y, block_noise(ch, d, white_var, span, t_lo))
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())
    # the innovation variances are the squared diagonal of L: the log-determinant of C
    assert np.sum(np.log(S)) == pytest.approx(2 * np.sum(np.log(np.diag(L))), rel=1e-9)


@pytest.mark.parametrize("name", list(CASES))
def test_filter_equals_cholesky_whitening_across_gaps(name):
    """Blocks with left-out stretches between some of them (a clock's gap, an exclusion, a dropped
    move): the Gauss–Markov terms decay and the random walk wanders through the gaps, and a
    remainder is shared only by blocks that meet."""
    ch = CASES[name]
    rng = np.random.default_rng(5)
    d = rng.choice([1.0, 1.0, 1.0, 3.7, 0.6], size=120)
    gaps = np.where(rng.random(120) < 0.2, rng.choice([0.01, 2.5, 40.0], size=120), 0.0)
    gaps[0] = 0.0
    starts = np.cumsum(gaps + np.concatenate([[0.0], d[:-1]]))
    white_var = ch.white**2 * d + rng.uniform(0, 1e-7, len(d))
    span, t_lo = float(starts[-1] + d[-1]), 1.0
    C = dense_covariance(ch, starts, white_var, span, t_lo, ends=starts + d)
    L = cholesky(C, lower=True)
    Y = rng.standard_normal((len(d), 3))
    expected = solve_triangular(L, Y, lower=True)
    got, S = whiten_channel(Y, block_noise(ch, d, white_var, span, t_lo, gaps=gaps))
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())
    assert np.sum(np.log(S)) == pytest.approx(2 * np.sum(np.log(np.diag(L))), rel=1e-9)


def test_white_noise_is_the_division_by_sigma_bit_for_bit():
    d = np.full(50, 1.0)
    var = np.linspace(1e-6, 2e-6, 50)
    Y = np.random.default_rng(1).standard_normal((50, 2))
    got, _ = whiten_channel(Y, block_noise(ChannelNoise(white=1e-3), d, var, 50.0, 1.0))
    assert np.array_equal(got, Y * (1.0 / np.sqrt(var))[:, None])


def test_a_variance_that_is_not_positive_is_named_by_its_block():
    """The compiled filter stops where the predicted variance S_k is not positive and the message
    gives k and S_k (here r_k of block 4 made so negative that S_4 = c P c + r_4 < 0)."""
    from dataclasses import replace as dc_replace

    from components.errors import EstimationError

    d = np.full(10, 1.0)
    bn = block_noise(CASES["gauss-markov"], d, np.full(10, 1e-6), 10.0, 1.0)
    r = bn.r.copy()
    r[3] = -1.0
    with pytest.raises(EstimationError, match=r"failed at block 4 of 10: its predicted variance is -1"):
        whiten_channel(np.ones((10, 2)), dc_replace(bn, r=r))


@pytest.mark.parametrize("name", list(CASES))
def test_filter_in_pieces_equals_cholesky_whitening(name):
    """The filter run a piece of blocks at a time, its state carried from piece to piece (how a
    long log's rows are whitened without holding them whole): still L⁻¹ y, and the same bits as
    one call."""
    ch = CASES[name]
    rng = np.random.default_rng(6)
    d = rng.choice([1.0, 1.0, 1.0, 3.7, 0.6], size=120)
    edges = np.concatenate([[0.0], np.cumsum(d)])
    white_var = ch.white**2 * d + rng.uniform(0, 1e-7, len(d))
    span, t_lo = float(edges[-1]), 1.0
    L = cholesky(dense_covariance(ch, edges, white_var, span, t_lo), lower=True)
    Y = rng.standard_normal((len(d), 3))
    expected = solve_triangular(L, Y, lower=True)
    bn = block_noise(ch, d, white_var, span, t_lo)
    whitener = ChannelWhitener(bn, 3)
    cuts = [0, 1, 2, 17, 60, 61, 119, 120]  # pieces of one block, of many, and the last alone
    got = np.vstack([whitener(Y[a:b])[0] for a, b in zip(cuts[:-1], cuts[1:])])
    np.testing.assert_allclose(got, expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())
    assert np.array_equal(got, whiten_channel(Y, bn)[0])
    with pytest.raises(ValueError, match="120 blocks"):
        whitener(Y[:1])  # past the channel's last block
