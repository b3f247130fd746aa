"""The table effects' columns (components.estimation.table_columns) and the fast kinematics they
use, each against an independent computation: rotation matrices multiplied stage by stage
(TableGeometry.kinematics), the cross products of lever_acceleration, and forward differences of
whole Motions summed over the blocks sample by sample."""
from __future__ import annotations

import copy
import tomllib
from types import SimpleNamespace

import numpy as np
import pytest

from components.cli.demo import SCENARIO
from components.estimation.blocks import observation_blocks
from components.estimation.log_data import LogData
from components.estimation.table_columns import TABLE_STEP, table_columns
from components.model.effects import parameters_of, regressor_of
from components.model.geometry import Stage, TableGeometry
from components.model.motion import lever_acceleration, motion_from_profile
from components.model.table_parameters import apply_table_parameter, table_parameter_value
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

TABLE_EFFECTS = ["table.base_tilt", "table.nonorth", "table.wobble", "table.encoder"]


def _imperfect(geo: TableGeometry) -> TableGeometry:
    """A table with every error the vocabulary has, so each code path runs."""
    rng = np.random.default_rng(4)
    for p in parameters_of(TABLE_EFFECTS):
        geo = apply_table_parameter(geo, p, float(rng.normal(0, 3e-5)))
    return geo


def test_rate_and_force_are_the_kinematics():
    stages = (Stage("outer", (1, 0, 0)), Stage("middle", (0, 1, 0)), Stage("inner", (0, 0, 1)))
    geo = _imperfect(TableGeometry(stages, latitude=0.7, azimuth=0.4))
    rng = np.random.default_rng(1)
    theta = rng.uniform(-7, 7, (5000, 3))
    rate = rng.normal(0, 1, (5000, 3))
    _, omega, _, force = geo.kinematics(theta, rate, rng.normal(0, 1, (5000, 3)))
    om, f = geo.rate_and_force(theta, rate)
    assert np.max(np.abs(om - omega)) <= 1e-14 * np.max(np.abs(omega))
    assert np.max(np.abs(f - force)) <= 1e-14 * geo.g
    # a stretch of the rows gives those rows' bits (the estimators' chunks are the whole log's)
    for a, b in ((0, 1), (3, 10), (17, 4099)):
        part = geo.rate_and_force(theta[a:b], rate[a:b])
        assert np.array_equal(part[0], om[a:b]) and np.array_equal(part[1], f[a:b])
    # and a table with no errors: the same plate attitude as the rotation matrices give
    plain = TableGeometry(stages, latitude=0.7)
    assert np.allclose(plain.rate_and_force(theta[:3], 0 * rate[:3])[1],
                       np.einsum("nji,j->ni", plain.kinematics(theta[:3])[0], [0, 0, plain.g]), atol=1e-14)


def test_motion_is_the_kinematics_without_the_attitude():
    """Rate, angular acceleration and force rotated as vectors stage by stage equal the rotation
    matrices multiplied (every table error, wobble included; rates and accelerations of rad/s
    and rad/s² that make the cross-product terms of alpha count); any stretch of the rows gives
    the same bits as the whole."""
    stages = (Stage("outer", (1, 0, 0)), Stage("middle", (0, 1, 0)), Stage("inner", (0, 0, 1)))
    geo = _imperfect(TableGeometry(stages, latitude=0.7, azimuth=0.4))
    rng = np.random.default_rng(2)
    theta, rate, acc = rng.uniform(-7, 7, (5000, 3)), rng.normal(0, 1, (5000, 3)), rng.normal(0, 1, (5000, 3))
    _, omega, alpha, force = geo.kinematics(theta, rate, acc)
    om, al, f = geo.motion(theta, rate, acc)
    assert np.max(np.abs(om - omega)) <= 1e-14 * np.max(np.abs(omega))
    assert np.max(np.abs(al - alpha)) <= 1e-14 * np.max(np.abs(alpha))
    assert np.max(np.abs(f - force)) <= 1e-14 * geo.g
    # a stretch of the rows gives those rows' bits (the estimators' chunks are the whole log's)
    for a, b in ((0, 1), (3, 10), (17, 4099), (1, 5000)):
        for whole, part in zip((om, al, f), geo.motion(theta[a:b], rate[a:b], acc[a:b])):
            assert np.array_equal(part, whole[a:b])
    # at rest: Earth rate alone, no angular acceleration
    om0, al0, _ = geo.motion(theta[:4])
    assert np.all(al0 == 0) and np.allclose(np.linalg.norm(om0, axis=1), geo.earth_rate, rtol=1e-12, atol=0)


def test_resuming_at_the_changed_stage_gives_the_same_bits():
    """A geometry that differs from another from stage k on, carried on from the other's
    vectors before stage k, gives what it gives from the base."""
    stages = (Stage("outer", (1, 0, 0)), Stage("middle", (0, 1, 0)), Stage("inner", (0, 0, 1)))
    first = _imperfect(TableGeometry(stages, latitude=0.7, azimuth=0.4))
    rng = np.random.default_rng(3)
    theta, rate = rng.uniform(-7, 7, (2000, 3)), rng.normal(0, 1, (2000, 3))
    states: list = []
    first.rate_and_force(theta, rate, states=states)
    for p in parameters_of(TABLE_EFFECTS):
        other = apply_table_parameter(first, p, table_parameter_value(first, p) + 1e-6)
        k = other.first_change(first)
        assert k == (0 if p.startswith("table.base_tilt") else [s.name for s in stages].index(p.split(".")[2])), p
        resumed = other.rate_and_force(theta, rate, resume=(k, *states[k]) if k else None)
        fresh = other.rate_and_force(theta, rate)
        assert all(np.array_equal(a, b) for a, b in zip(resumed, fresh)), p
    assert first.first_change(first) == 3


def test_a_lever_arm_column_is_the_lever_acceleration():
    rng = np.random.default_rng(2)
    n, q = 400, 3
    m = SimpleNamespace(omega_q=rng.normal(size=(n, q, 3)), alpha_q=rng.normal(size=(n, q, 3)),
                        dt=np.full(n, 0.005), weights=np.array([5.0, 8.0, 5.0]) / 18)
    for i, axis_i in enumerate("xyz"):
        for k, axis_k in enumerate("xyz"):
            r = np.zeros(3)
            r[k] = 1.0
            want = m.dt * (lever_acceleration(m.omega_q, m.alpha_q, r)[:, :, i] @ m.weights)
            _, got = regressor_of(m, f"acc.lever.{axis_i}.{axis_k}")
            assert np.max(np.abs(got[:, i] - want)) <= 1e-14 * np.max(np.abs(want))
            assert not np.any(np.delete(got, i, axis=1))


@pytest.fixture(scope="module")
def data():
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["scenario"]["seed"] = 32
    log = LogData.from_log(run_scenario(scenario_from_dict(d, source="test_table_columns"), progress=False).log)
    return log


def test_columns_are_the_differences_of_whole_motions(data):
    """Each table parameter's column against (block sums of the Motion at θ + h − at θ) / h built
    the slow way: every sample's quadrature integral from the rotation matrices."""
    geo = _imperfect(data.geometry)
    profile = data.angle_profile(3)
    gb, ab = observation_blocks(data.static, data.angles, 200)
    params = parameters_of(TABLE_EFFECTS)
    got = table_columns(profile, gb, ab, geo, params)
    m0 = motion_from_profile(profile, geo)
    for p in params:
        m1 = motion_from_profile(profile, apply_table_parameter(geo, p, table_parameter_value(geo, p) + TABLE_STEP))
        for blocks, (ideal0, ideal1), col in ((gb, (m0.ideal_gyro, m1.ideal_gyro), got[p][0]),
                                              (ab, (m0.ideal_acc, m1.ideal_acc), got[p][1])):
            want = (blocks.sum(ideal1) - blocks.sum(ideal0)) / TABLE_STEP
            # the slow way loses ~1e-16 of a block sum (gravity x seconds) to the difference
            slack = 1e-15 * np.max(np.abs(blocks.sum(ideal0))) / TABLE_STEP
            assert np.max(np.abs(col - want)) <= 1e-7 * np.max(np.abs(want)) + slack, p
    assert any(np.max(np.abs(c)) > 0 for pair in got.values() for c in pair)
