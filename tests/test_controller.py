"""The calibration controller driving the builtin turntable (and a two-axis one) through
schedules, the scenario runner and `calbench simulate`."""
import json
import math

import numpy as np
import pytest

from components.control.controller import CalibrationController
from components.control.schedule import COUNTS_PER_REV, DEG, loads_schedule
from components.errors import ScenarioError
from components.simulation.run import run_scenario
from components.simulation.scenario import Scenario, load_scenario
from orchestrator.errors import SimulationFault

Q = 2 * math.pi / COUNTS_PER_REV
G = 9.8          # site gravity set explicitly, so the check needs no gravity model
LAT = 39.9 * DEG
OMEGA = 7.2921151467e-5
AXES = ("outer", "middle", "inner")


def rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def C_pn(o, m, i):
    """Plate -> ENU for the default geometry (outer z, middle x, inner z), level base."""
    return rot("z", o) @ rot("x", m) @ rot("z", i)


def scenario(text: str, **kw) -> Scenario:
    sched = loads_schedule(text, "test-schedule")
    return Scenario(name="test", schedule=sched, site={"latitude_deg": 39.9, "height_m": 50.0, "gravity_mps2": G},
                    **kw)


# default settle settings (2 counts, 1e-5 rad/s, 0.5 s hold): with a 0.3 s hold the builtin
# table was once seen reading one count off for a single sample in a dwell (its true angle
# still creeping across a half-count boundary)
SIX = """
[[steps]]
kind = "tumble"
attitudes_deg = [[0, 0, 0], [0, 180, 0], [0, 90, 0], [0, -90, 0], [0, 90, 90], [0, 90, -90]]
dwell = 1.0
"""
SIX_ATT = [(0, 0, 0), (0, 180, 0), (0, 90, 0), (0, -90, 0), (0, 90, 90), (0, 90, -90)]


@pytest.fixture(scope="module")
def six():
    sc = scenario(SIX)
    return run_scenario(sc, record=[f"table.{a}.rate" for a in AXES] + ["table.plate.f"])


def test_six_position_dwells_exact(six):
    log, rec = six.log, six.recording
    tol = six.scenario.schedule.settings.settle_rate_tol
    f = np.column_stack([rec[f"table.plate.f.{c}"][1:] for c in "xyz"])
    rates = np.column_stack([rec[f"table.{a}.rate"][1:] for a in AXES])
    for k, att in enumerate(SIX_ATT, start=1):
        m = log.segment == f"pos{k:02d}"
        assert m.sum() == 200                               # 1 s at 5 ms, exactly
        for a, deg in zip(AXES, att):
            # the encoder reads exactly the command, a whole count; that is the attitude's angle
            # modulo one turn (indexing goes the shortest way: 90 -> -90 deg ends at 270 deg)
            enc = log.gimbal[a][m]
            assert np.all(enc == log.command[a][m]), (k, a)
            counts = enc / Q
            assert np.all(counts == np.round(counts))
            assert np.all(np.round(counts).astype(np.int64) % COUNTS_PER_REV
                          == round(deg * DEG / Q) % COUNTS_PER_REV), (k, a)
        # settled: no dwell sample while the table moves
        assert np.abs(rates[m]).max() < tol
        f_want = C_pn(*(np.array(att) * DEG)).T @ np.array([0.0, 0.0, G])
        assert np.abs(f[m] - f_want).max() < 5e-6          # 0.5 count of attitude is 2e-6 m/s^2


def test_six_position_labels_and_events(six):
    log, ctrl = six.log, six.controller
    want = [l for k in range(1, 7) for l in (f"move-pos{k:02d}", f"pos{k:02d}")]
    assert ctrl.labels == want
    # the labels occur in order, each as one contiguous run
    runs = [log.segment[0]] + [s for p, s in zip(log.segment[:-1], log.segment[1:]) if s != p]
    assert runs == want
    assert [e["label"] for e in ctrl.events] == want
    assert all("end" in e for e in ctrl.events)
    # the run ends with the last dwell: the last sample is its last
    assert log.segment[-1] == "pos06"
    assert log.time[-1] == pytest.approx(ctrl.events[-1]["end"])
    # moves are labelled while the table moves
    assert np.ptp(log.gimbal["middle"][log.segment == "move-pos02"]) > 3.0


def test_rotate_net_angle_and_gyro_sum():
    text = """
[settings]
settle_hold = 0.3
[[steps]]
kind = "index"
angles_deg = [0, 90, 0]
label = "start"
[[steps]]
kind = "rotate"
axis = "outer"
rate_dps = -40.0
turns = 2
label = "rot-outer"
[[steps]]
kind = "rotate"
axis = "inner"
rate_dps = 90.0
turns = 1
label = "rot-inner"
"""
    r = run_scenario(scenario(text))
    log = r.log
    h = log.dt
    incr = log.gyro_increment()
    w_ie = np.array([0.0, OMEGA * math.cos(LAT), OMEGA * math.sin(LAT)])
    ang = log.angles
    for label, k, n, axis_plate in (("rot-outer", 0, -2, None), ("rot-inner", 2, 1, np.array([0.0, 0.0, 1.0]))):
        idx = np.flatnonzero(log.segment == label)
        first, last = idx[0], idx[-1]
        start = ang[first - 1, k]                  # at rest before the first interval of the segment
        assert ang[last, k] - start == n * COUNTS_PER_REV * Q       # exactly n turns, in counts
        assert ang[last, k] == log.command[AXES[k]][last]
        # gimbal part: n 2 pi about the stage axis in plate axes (constant: one axis moves)
        o, m, i = ang[first - 1]
        if axis_plate is None:
            axis_plate = (rot("x", m) @ rot("z", i)).T @ np.array([0.0, 0.0, 1.0])
        # Earth part: C_n^p w_ie integrated over the segment (trapezoid on the encoder angles)
        mid = 0.5 * (ang[first - 1:last] + ang[first:last + 1])
        earth = sum(C_pn(*a).T @ w_ie for a in mid) * h
        got = incr[first:last + 1].sum(axis=0)
        want = n * 2 * math.pi * axis_plate + earth
        # the true angles at rest sit within a count of the encoder's (stick-slip friction
        # holds the axis where it stops): a tilt of up to one count q of the rotating axis
        # turns n full turns into an error of up to |n| 2 pi q on the cross axes
        assert np.abs(got - want).max() < abs(n) * 2 * math.pi * Q + 1e-9, (label, got - want)
        # the rate during the turn: the commanded one (rate mode), no overshoot beyond 10 %
        rate = incr[first:last + 1] @ axis_plate / h
        w = 40 * DEG if k == 0 else 90 * DEG
        assert np.abs(rate).max() < 1.1 * w


def test_two_axis_table_named_by_config():
    text = """
[settings]
settle_hold = 0.3
[[steps]]
kind = "tumble"
attitudes_deg = [[0, 0], [90, 90], [180, -90]]
dwell = 0.5
[[steps]]
kind = "rotate"
axis = "yaw"
rate_dps = 60.0
turns = 1
label = "spin"
[[steps]]
kind = "rate"
axis = "pitch"
rate_dps = 20.0
duration = 1.0
label = "sweep"
"""
    mapping = {f"{r}.{v}": f"{f}.{v}" for r, f in (("yaw", "outer"), ("pitch", "middle"))
               for v in ("mode", "angle_cmd", "rate_cmd", "angle", "rate")}
    sc = scenario(text, table_axes=["yaw", "pitch"], table_mapping=mapping)
    r = run_scenario(sc)
    assert r.info["table_parameters"]["n_axes"] == 2
    log = r.log
    assert log.axis_names == ["yaw", "pitch"]
    assert np.allclose(log.axis_vectors, [[0, 0, 1], [1, 0, 0]])
    for k, (y, p) in enumerate([(0, 0), (90, 90), (180, -90)], start=1):
        m = log.segment == f"pos{k:02d}"
        for a, deg in (("yaw", y), ("pitch", p)):
            assert np.all(log.gimbal[a][m] == log.command[a][m])
            assert np.all(np.round(log.gimbal[a][m] / Q).astype(np.int64) % COUNTS_PER_REV
                          == round(deg * DEG / Q) % COUNTS_PER_REV)
    spin = np.flatnonzero(log.segment == "spin")
    assert log.gimbal["yaw"][spin[-1]] - log.gimbal["yaw"][spin[0] - 1] == COUNTS_PER_REV * Q
    sweep = np.flatnonzero(log.segment == "sweep")
    moved = log.gimbal["pitch"][sweep[-1]] - log.gimbal["pitch"][sweep[0] - 1]
    assert 19 * DEG < moved < 22 * DEG      # 1 s at 20 deg/s plus the stop
    assert r.controller.finished


def test_controller_rejects_schedule_for_other_table():
    s = loads_schedule('[[steps]]\nkind = "index"\nangles_deg = [0, 0, 0]\n', "three.toml")
    with pytest.raises(ValueError, match=r"three.toml: step 1 \(index\): 3 angles for a table with 2 axes"):
        CalibrationController("ctrl", s, axes=["a", "b"])
    s = loads_schedule('[[steps]]\nkind = "rotate"\naxis = "inner"\nrate_dps = 1\nturns = 1\n', "r.toml")
    with pytest.raises(ValueError, match=r"r.toml: step 1 \(rotate\): key 'axis' = 'inner': expected one of"):
        CalibrationController("ctrl", s, axes=["a", "b"])


def test_timeout_names_the_step():
    text = """
[settings]
index_timeout = 0.5
[[steps]]
kind = "dwell"
duration = 0.2
[[steps]]
kind = "index"
angles_deg = [0, 90, 0]
label = "far"
"""
    with pytest.raises(SimulationFault, match=r"test-schedule: step 2 \(index, label 'far'\) at t = .*"
                                              r"did not settle within 0.5 s"):
        run_scenario(scenario(text))


def test_simulate_cli_writes_log_and_truth(tmp_path):
    from components.cli import main
    from components.logs.logfile import read_log

    src = "examples/scenarios/six_position.toml"
    assert main(["simulate", src, "--out", str(tmp_path / "a"), "--dwell", "0.5"]) == 0
    log = read_log(tmp_path / "a")
    assert set(np.unique(log.segment)) == {f"pos{k:02d}" for k in range(1, 7)} | {f"move-pos{k:02d}" for k in range(1, 7)}
    assert set(log.command) == set(AXES)
    truth = json.loads((tmp_path / "a.truth.json").read_text())
    sc = load_scenario(src)
    assert truth["effects"] == pytest.approx(sc.imu_effects)
    assert truth["effects"]["gyro.bias.x"] == pytest.approx(0.005 * DEG / 3600)
    assert truth["noise"]["acc.noise.vrw"] == pytest.approx(5e-6 * 9.80665)
    assert truth["seed"] == 1
    assert len(truth["imu"]["sha256"]) == 64 and len(truth["turntable"]["sha256"]) == 64
    assert truth["schedule"]["parameters"]["dwell"] == 0.5
    assert [a["name"] for a in truth["geometry"]["axes"]] == list(AXES)
    # the site as the log states it: normal gravity is null in both (the scenario's 0 means it)
    assert truth["site"] == {"latitude_deg": log.latitude_deg, "height_m": log.height_m,
                             "gravity_mps2": log.gravity_mps2} and log.gravity_mps2 is None
    # same seed -> bit-identical files; another seed -> other noise
    assert main(["simulate", src, "--out", str(tmp_path / "b"), "--dwell", "0.5"]) == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert (tmp_path / "a.truth.json").read_bytes() == (tmp_path / "b.truth.json").read_bytes()
    assert main(["simulate", src, "--out", str(tmp_path / "c"), "--dwell", "0.5", "--seed", "2"]) == 0
    assert (tmp_path / "a.csv").read_bytes() != (tmp_path / "c.csv").read_bytes()


def test_tilted_base_table_effect_reaches_the_fmu():
    sc = load_scenario("examples/scenarios/tilted_base_seed000.toml")
    assert sc.table_effects["table.base_tilt.x"] == pytest.approx(DEG / 60)
    from components.simulation.run import build_system

    _, _, info = build_system(sc)
    assert info["table_parameters"]["base.tilt.x"] == pytest.approx(DEG / 60)
    assert info["table_parameters"]["base.tilt.y"] == pytest.approx(DEG / 120)


@pytest.mark.parametrize("step,servo_rate,ok", [(0.00125, None, False), (0.001, None, True),
                                                 (0.0025, 800.0, True), (0.002, 800.0, False)])
def test_a_step_off_the_servo_grid_is_bad_input_before_the_run(step, servo_rate, ok):
    """The table's servo steps by whole periods of servo.rate (the FMU's default 2000 Hz, or the
    scenario's value): a step off that grid is refused by the scenario, naming the rate and the
    nearest good steps, instead of a run its first step stops (exit 3). On the grid it builds."""
    from components.simulation.run import build_system

    text = "[[steps]]\nkind = \"dwell\"\nduration = 0.1\n"
    kw = {"step": step, "controller_rate_hz": 1.0 / (4 * step)}
    if servo_rate:
        kw["table_parameters"] = {"servo.rate": servo_rate}
    sc = scenario(text, **kw)
    if ok:
        build_system(sc)
        return
    period = 1.0 / (servo_rate or 2000.0)
    with pytest.raises(ScenarioError, match=rf"step = {step:g} s: .* servo.rate = {1 / period:g} Hz, .*"
                                            rf"whole number of its periods \({period:g} s\)"):
        build_system(sc)
