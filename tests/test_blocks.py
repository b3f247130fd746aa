"""Observation blocks (components.estimation.blocks) on table motions with known shape."""
from __future__ import annotations

import numpy as np

from components.estimation.blocks import observation_blocks
from components.navigation.system import static_mask

DT = 0.005


def _triangle_index(rest: int, half: int, accel: float) -> np.ndarray:
    """Angles (N, 1) of a rest, a bang-bang index (accelerate for *half* samples, brake for
    *half*: the angular acceleration jumps from +accel to -accel at the peak), a rest."""
    t = np.arange(1, 2 * half + 1) * DT
    T = half * DT
    up = 0.5 * accel * t ** 2
    down = accel * T ** 2 - 0.5 * accel * (2 * T - t) ** 2
    move = np.where(t <= T, up, down)
    return np.concatenate([np.zeros(rest), move, np.full(rest, move[-1])])[:, None]


def test_moving_accelerometer_blocks_are_cut_away_from_the_acceleration_jump():
    """A 1.35 s index in 1 s chunks: an even split cuts at the peak, where the servo switches
    from accelerating to braking and an interpolated rate is worst; the cut moves at least
    three samples away from it (and stays inside the move), the gyro block stays whole."""
    half = 135
    angles = _triangle_index(200, half, accel=4.0)
    static = static_mask(angles)
    gyro, acc = observation_blocks(static, angles, 200)
    move = np.nonzero(~static)[0]
    a, b = move[0], move[-1] + 1
    peak = a + half                    # boundary at the acceleration jump
    cuts = [s for s, m in zip(acc.start, acc.moving) if m and a < s < b]
    assert len(cuts) == 1 and abs(cuts[0] - peak) > 3, (cuts, peak)
    assert any(m and s == a and e == b for s, e, m in zip(gyro.start, gyro.stop, gyro.moving))
    # blocks tile the log without gaps or overlaps
    assert np.array_equal(acc.start[1:], acc.stop[:-1]) and acc.stop[-1] == len(angles)


def test_a_log_that_starts_moving_leaves_out_its_first_move():
    """A window cut out of a schedule during a move: the rate at its first angle is unknown (the
    interpolation would take the table at rest), so no block covers that move."""
    angles = _triangle_index(200, 135, accel=4.0)[300:]    # starts inside the move
    static = static_mask(angles)
    first_rest = int(np.argmax(static[1:])) + 1
    gyro, acc = observation_blocks(static, angles, 200)
    assert gyro.start[0] == acc.start[0] == first_rest
    assert not acc.moving[0] and not gyro.moving[0]


def test_jerk_near_is_the_largest_third_difference_within_its_window():
    """_JerkNear from its definition, written as loops here: per block boundary k (the time of
    sample k-1), the largest over samples j = k-4 ... k+2 (clipped to the log) of Σ_axes
    |a[j+1] − 3 a[j] + 3 a[j-1] − a[j-2]| (0 where the difference does not exist). Asked for at
    every boundary at once, one at a time and in windows of 5 (each computed from the angles
    around them only: the margins)."""
    from components.estimation.blocks import _JerkNear

    rng = np.random.default_rng(3)
    for n, axes in ((1, 1), (3, 2), (4, 3), (9, 1), (60, 3)):
        a = np.cumsum(np.cumsum(rng.standard_normal((n, axes)), axis=0), axis=0)
        d3 = [sum(abs(a[j + 1, i] - 3 * a[j, i] + 3 * a[j - 1, i] - a[j - 2, i]) for i in range(axes))
              if 2 <= j <= n - 2 else 0.0 for j in range(n)]
        expected = np.array([max(d3[min(max(j, 0), n - 1)] for j in range(k - 4, k + 3)) for k in range(n + 1)])
        near = _JerkNear(a)
        assert len(near) == n + 1
        np.testing.assert_allclose(near[np.arange(n + 1)], expected, rtol=1e-12, atol=1e-12)
        for k in range(n + 1):
            np.testing.assert_allclose(near[k], expected[k], rtol=1e-12, atol=1e-12)
            w = np.arange(k, min(k + 5, n + 1))
            np.testing.assert_allclose(near[w], expected[w], rtol=1e-12, atol=1e-12)


def test_a_settling_that_pauses_and_creeps_on_is_left_out():
    """The log starts with the table settling: moving, still for a quarter of a block (within a
    count), moving again, then at rest. No block may start before that rest: the interpolation
    takes the first move's start at rest and the pause as a rest, neither of which it is (a
    compare misfit of 4.2x noise on the first move, chi2/dof 1.087 with the right model)."""
    import numpy as np

    from components.estimation.blocks import observation_blocks

    n, per = 1000, 200
    angles = np.zeros((n, 1))
    angles[:10, 0] = np.linspace(2e-5, 1e-5, 10)     # moving from the first sample
    angles[10:60, 0] = 1e-5                           # a pause of 50 samples
    angles[60:70, 0] = np.linspace(9e-6, 0.0, 10)     # creeps on
    static = np.concatenate([[False], np.all(angles[1:] == angles[:-1], axis=1)])
    gb, ab = observation_blocks(static, angles, per)
    assert gb.start.min() >= 70 and ab.start.min() >= 70, (gb.start.min(), ab.start.min())
    # a pause as long as a block is a rest: the log is known from there
    angles[10:260, 0] = 1e-5
    angles[260:270, 0] = np.linspace(9e-6, 0.0, 10)
    angles[270:, 0] = 0.0
    static = np.concatenate([[False], np.all(angles[1:] == angles[:-1], axis=1)])
    gb, _ = observation_blocks(static, angles, per)
    assert gb.start.min() == 10


def test_the_datas_white_level_at_rest_is_the_scatter_of_its_rests_and_follows_its_mask():
    """LogData.white_sigma_at_rest: white increments of known σ at two rests (a move between
    them, with increments a thousand times larger, is not a rest) give σ within a Monte-Carlo
    bound of the MAD scale (its standard error ~1.2 σ/√pairs; 6 of them); computed once, and a
    copy of the data with another mask has its own (half the rests left out: the level of the
    samples kept, which the test makes twice as noisy)."""
    import dataclasses

    from components.estimation.log_data import LogData

    rng = np.random.default_rng(11)
    n_rest, n_move = 20000, 400
    angles = np.concatenate([np.zeros(n_rest), np.linspace(0, 1, n_move), np.ones(n_rest)])[:, None]
    n = len(angles)
    sigma = np.array([1e-6, 2e-6, 3e-6])
    scale = np.ones(n)
    scale[n_rest + n_move:] = 2.0  # the second rest twice as noisy
    scale[n_rest:n_rest + n_move] = 1e3
    gyro = 5e-7 + rng.standard_normal((n, 3)) * sigma * scale[:, None]
    data = LogData(time=np.arange(n) * DT, angles=angles, gyro=gyro, acc=gyro[:, ::-1].copy(), geometry=None)
    got = data.white_sigma_at_rest("gyro")
    second = slice(n_rest + n_move + 1, n)
    # the MAD scale of the rests' pooled differences: that of a sample half N(0, 1), half N(0, 4)
    mix = np.concatenate([rng.standard_normal(10 ** 6), 2 * rng.standard_normal(10 ** 6)])
    pooled = 1.4826 * np.median(np.abs(mix - np.median(mix)))
    bound = 6 * 1.2 / np.sqrt(2 * n_rest)
    assert np.all(np.abs(got / (sigma * pooled) - 1) < bound), got / (sigma * pooled)
    assert data.white_sigma_at_rest("gyro") is got  # once
    assert np.allclose(data.white_sigma_at_rest("acc"), got[::-1], rtol=0, atol=0)
    second_only = np.zeros(n, bool)
    second_only[second] = True
    masked = dataclasses.replace(data, valid=second_only)
    kept = masked.white_sigma_at_rest("gyro")
    assert np.all(np.abs(kept / (2 * sigma) - 1) < bound), kept / (2 * sigma)
