"""PWCS observability of the system-level filter (components.navigation.observability), checked
against facts that do not come from the analysis itself:

- a schedule with z always up cannot excite the x and y accelerometer scale factors (f_x = f_y =
  0): exactly zero singular values; the z bias and scale factor enter only as b + g·sf (one
  combination); the filter run on the same data keeps its prior σ along those directions;
- the TOM's transitions predict the velocity error of the nonlinear strapdown navigation of
  data corrupted by small effects (at the start of every static run);
- the IMU/table time offset: a shifted IMU record on a stationary base is a shifted but equally
  valid trajectory, so its velocity signature is a tiny residual of two large, cancelling
  parts (gyro and accelerometer) -- far below the gyro part alone.
"""
import numpy as np
import pytest

from components.estimation.log_data import LogData
from components.model.effects import DEG, UG, parameters_of
from components.navigation.earth import Site
from components.navigation.observability import analyse, pwcs, static_runs, total_observability
from components.navigation.sensor import Regressors
from components.navigation.strapdown import navigate
from components.navigation.system import static_mask
from components.simulation.run import schedule_motion_log

ZUP = """
[schedule]
name = "z-up"
description = "z up, two headings"
[parameters]
dwell = 10.0
[[steps]]
kind = "tumble"
attitudes_deg = [[0, 0, 0], [90, 0, 0], [0, 0, 0]]
dwell = "$dwell"
"""


@pytest.fixture(scope="module")
def zup(tmp_path_factory):
    p = tmp_path_factory.mktemp("obs") / "zup.toml"
    p.write_text(ZUP)
    return LogData.from_log(schedule_motion_log(str(p)))


@pytest.fixture(scope="module")
def six():
    return LogData.from_log(schedule_motion_log("six_position", dwell=10.0))


def test_z_up_schedule_leaves_the_unexcited_states_unobservable(zup):
    params = parameters_of(["gyro.bias", "acc.bias", "acc.sf"])
    dt = 0.005
    ob = analyse(zup, params, 0.002 * DEG / 60 * np.sqrt(dt), 10 * UG * np.sqrt(dt))
    n = len(ob.states)
    s = ob.singular_values / ob.singular_values[0]
    # acc.sf.x, acc.sf.y (zero columns) and b_z / sf_z: at least three exact null directions
    assert np.all(s[-3:] < 1e-12), s
    null = ob.vt[-3:] * ob.ref_sigma  # physical units
    ix, iy = ob.states.index("acc.sf.x"), ob.states.index("acc.sf.y")
    ib, iz = ob.states.index("acc.bias.z"), ob.states.index("acc.sf.z")
    # the null space contains acc.sf.x and acc.sf.y (unit vectors) ...
    basis = ob.vt[-3:]
    for j in (ix, iy):
        e = np.zeros(n)
        e[j] = 1.0
        assert np.linalg.norm(basis.T @ (basis @ e)) > 0.999
    # ... and the third direction is δb_z = −g δsf_z (the accelerometer reads b + sf·g)
    g = Site.of_geometry(zup.geometry).g
    third = [v for v in null if abs(v[ib]) > 1e-3 * np.abs(v).max()]
    assert third
    v = third[0]
    assert abs(v[ib] + g * v[iz]) < 1e-6 * abs(v[ib])
    # the filter on the same data learns nothing along these directions
    for i, r in enumerate(ob.null_filter_ratio[-3:]):
        assert r is not None and abs(r - 1.0) < 1e-3, (i, r)
    # while the level biases are learnt
    assert ob.filter_ratio["acc.bias.x"] < 0.05 and ob.filter_ratio["acc.bias.y"] < 0.05
    assert ob.rank <= n - 3


def test_six_position_resolves_bias_and_scale_factor(six):
    ob = pwcs(six, parameters_of(["acc.bias", "acc.sf"]))
    assert ob.rank == len(ob.states)


@pytest.mark.parametrize("param,value", [("gyro.sf.x", 2e-4), ("acc.lever.y.x", 0.05),
                                         ("gyro.mis.zy", 1e-4), ("acc.bias.y", 5e-4)])
def test_transitions_predict_the_strapdown_velocity_error(six, param, value):
    dt = 0.005
    tom, ref, _, _ = total_observability(six, [param], krylov=0)
    col = tom[:, 6] / ref[6] * value  # H Ψ_j at the start of each static run (krylov=0: H only)
    pred = col.reshape(-1, 3)
    site = Site.of_geometry(six.geometry)
    C0 = six.geometry.kinematics(six.angles[:1])[0][0]
    idx, _, v0, _ = navigate(six.gyro, six.acc, dt, site, C0)
    g, a = Regressors([param], six.gyro, six.acc, dt).correct(np.array([-value]))
    _, _, v1, _ = navigate(g, a, dt, site, C0)
    runs = [r for r in static_runs(static_mask(six.angles), 200) if r[2]]
    assert len(runs) == len(pred)
    got = []
    for a_, _, _ in runs:
        k = np.searchsorted(idx, a_ - 1)  # the step ending at the run's first sample
        got.append(v1[k] - v0[k] if a_ > 0 else np.zeros(3))
    got = np.array(got)
    scale = np.abs(got).max()
    assert scale > 1e-5  # the effect does show
    # the step boundary may be one sample off the run start: the static drift over 1 sample
    assert np.abs(pred - got).max() < 0.03 * scale, (pred, got)


def test_time_offset_signature_is_a_cancelling_residual(six):
    dt = 0.005
    site = Site.of_geometry(six.geometry)
    C0 = six.geometry.kinematics(six.angles[:1])[0][0]
    _, _, v0, _ = navigate(six.gyro, six.acc, dt, site, C0, record_every=20)
    g, a = Regressors(["imu.time_offset"], six.gyro, six.acc, dt).correct(np.array([-1e-3]))
    _, _, v_both, _ = navigate(g, a, dt, site, C0, record_every=20)
    _, _, v_gyro, _ = navigate(g, six.acc, dt, site, C0, record_every=20)
    both, gyro = np.abs(v_both - v0).max(), np.abs(v_gyro - v0).max()
    assert both < 0.02 * gyro, (both, gyro)
    # the PWCS transitions show the same: 1 ms moves the velocity at the static runs' starts by
    # far less than the gyro part alone does (the linear model's residual is itself only good to
    # ~0.5 % of the gyro part: its value, unlike its smallness, is not checked)
    tom, ref, _, _ = total_observability(six, ["imu.time_offset"], krylov=0)
    assert np.abs(tom[:, 6] / ref[6] * 1e-3).max() < 0.02 * gyro
