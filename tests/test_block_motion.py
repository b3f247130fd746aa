"""The design's motion by blocks (components.estimation.block_motion): the moving samples one by
one and each rest block as one row. Checked against the definition — the per-sample motion of
the whole log, every regressor per sample, summed over the blocks — for every sensor effect of
the vocabulary, on a log with moves, a varying temperature and left-out samples; so a future
effect that is not linear in temperature or time at rest fails here."""
from __future__ import annotations

import copy
import tomllib
from dataclasses import fields, replace

import numpy as np
import pytest

from components.cli.demo import SCENARIO
from components.estimation.block_motion import BlockMotion
from components.estimation.blocks import observation_blocks
from components.estimation.log_data import LogData
from components.model.effects import EFFECTS, regressor_of, time_offset_of_lever
from components.model.motion import motion_from_profile
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict


@pytest.fixture(scope="module")
def data():
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["scenario"]["seed"] = 7
    log = LogData.from_log(run_scenario(scenario_from_dict(d, source="test_block_motion"), progress=False).log)
    t = log.time
    # a temperature that is neither constant nor linear, so the rests' means are tested
    return replace(log, temperature=21.0 + 2e-3 * t + 0.4 * np.sin(t / 37.0), _profiles={})


@pytest.fixture(scope="module")
def blocks(data):
    valid = np.ones(len(data.time), bool)
    valid[7000:7300] = False  # inside rests and moves alike: restricted blocks start mid-rest
    valid[np.flatnonzero(~data.static)[500]] = False
    return observation_blocks(data.static, data.angles, 200, valid)


def _close(a, b, scale, what):
    err = np.max(np.abs(np.asarray(a) - np.asarray(b))) if np.size(a) else 0.0
    assert err <= 1e-12 * scale, (what, err, scale)


def test_a_motion_of_some_samples_has_their_rows_of_the_whole(data):
    p = data.angle_profile(3)
    whole = motion_from_profile(p, data.geometry, data.temperature, 20.0)
    rng = np.random.default_rng(3)
    some = np.unique(np.concatenate([rng.choice(len(p.time), 400, replace=False),
                                     np.flatnonzero(~p.static)[:50], np.flatnonzero(~p.static)[:50] + 1, [0]]))
    part = motion_from_profile(p, data.geometry, data.temperature, 20.0, samples=some)
    assert not p.static[some].all() and p.static[some].any()
    for f in fields(whole):
        a, b = getattr(whole, f.name), getattr(part, f.name)
        if f.name == "alpha_start":
            a = whole.alpha_at_start()
        if isinstance(a, np.ndarray) and a.shape[:1] == (len(p.time),):
            np.testing.assert_array_equal(a[some], b, err_msg=f.name)


def test_block_sums_of_every_regressor_equal_the_per_sample_sums(data, blocks):
    gb, ab = blocks
    assert (~gb.moving).any() and gb.moving.any() and ab.moving.any()
    geo, T0 = data.geometry, 20.5
    p = data.angle_profile(3)
    full = motion_from_profile(p, geo, data.temperature, T0)
    bm = BlockMotion(p, geo, data.temperature, T0, None)
    rg, ra = bm.rests(gb), bm.rests(ab)
    params = [q for e in EFFECTS.values() if e.regressor is not None for q in e.parameters]
    assert len(params) > 90  # every sensor parameter, 98 today
    for q in params:
        g, a = regressor_of(full, q)
        gm, am = regressor_of(bm.moving, q)
        if g is not None:
            want = gb.sum(g)
            _close(bm.sums(gb, gm, regressor_of(rg, q)[0]), want, np.abs(want).max() + 1e-300, q)
        if a is not None:
            want = ab.sum(a)
            _close(bm.sums(ab, am, regressor_of(ra, q)[1]), want, np.abs(want).max() + 1e-300, q)
    for q in EFFECTS["acc.lever"].parameters:
        idx = q.split(".", 2)[2]
        want = ab.sum(time_offset_of_lever(full, idx))
        got = bm.sums(ab, time_offset_of_lever(bm.moving, idx), time_offset_of_lever(ra, idx))
        assert np.abs(want).max() > 0
        _close(got, want, np.abs(want).max(), f"time offset x {q}")
    # the ideal increments the measured are differenced against
    for blocks, rows, sensor in ((gb, rg, "gyro"), (ab, ra, "acc")):
        want = blocks.sum(getattr(full, f"ideal_{sensor}"))
        got = bm.sums(blocks, getattr(bm.moving, f"ideal_{sensor}"), getattr(rows, f"ideal_{sensor}"))
        _close(got, want, np.abs(want).max(), f"ideal {sensor}")


def test_temperature_and_time_at_rest_are_the_blocks_interval_means(data, blocks):
    # the rows' temperature and time, checked against a direct trapezoid of the log's samples
    gb, _ = blocks
    bm = BlockMotion(data.angle_profile(3), data.geometry, data.temperature, 20.0, None)
    rows = bm.rests(gb)
    rest = ~gb.moving
    t, T = data.time, data.temperature
    t_prev = np.concatenate([[t[0] - (t[1] - t[0])], t[:-1]])
    T_prev = np.concatenate([[T[0]], T[:-1]])
    for k, (a, b) in enumerate(zip(gb.start[rest][:40], gb.stop[rest][:40])):
        dt = t[a:b] - t_prev[a:b]
        assert rows.dt[k] == pytest.approx(dt.sum(), rel=1e-13)
        assert rows.dtemp_q[k, 0] == pytest.approx(np.sum(dt * ((T[a:b] + T_prev[a:b]) / 2 - 20.0)) / dt.sum(), rel=1e-11)
        assert rows.elapsed_q[k, 0] == pytest.approx(np.sum(dt * (t_prev[a:b] + dt / 2 - t_prev[0])) / dt.sum(), rel=1e-12)


def test_a_moving_block_with_a_rest_sample_is_refused(data, blocks):
    gb, _ = blocks
    bm = BlockMotion(data.angle_profile(3), data.geometry, data.temperature, 20.0, None)
    k = int(np.flatnonzero(gb.moving)[0])
    bad = replace(gb, start=gb.start.copy())
    bad.start[k] -= 1  # now takes in the rest sample before the move
    with pytest.raises(ValueError, match="rest sample"):
        bm.moving_rows(bad)
