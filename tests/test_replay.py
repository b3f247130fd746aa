"""Replaying a log through FMUs: the IMU FMU on the log's motion agrees with the Python forward
model (two independent implementations of the same sensor physics), and the servo replay of the
logged commands reproduces the logged angles with the same table and departs from them, where
the table moves, with a different one."""
import numpy as np
import pytest

from components.diagnosis.compare import assess
from components.estimation.chunks import PlateAtSamples
from components.estimation.design import predict
from components.estimation.log_data import LogData
from components.model.effects import effect_of
from components.simulation.replay import replay_imu, replay_servo
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

EFFECTS = {"gyro.bias.x": "0.02 deg/h", "gyro.sf.z": "30 ppm", "gyro.mis.xy": "20 arcsec",
           "acc.bias.z": "80 ug", "acc.sf.x": "40 ppm", "acc.k2.z": "40 ug/g2"}


@pytest.fixture(scope="module")
def run():
    sc = scenario_from_dict({
        "scenario": {"name": "replay", "step": 0.005, "seed": 5},
        "schedule": {"name": "six_position", "overrides": {"dwell": 2.0}},
        "site": {"latitude_deg": 39.9, "height_m": 50.0},
        "turntable": {"fmu": "builtin:turntable"},
        "imu": {"fmu": "builtin:imu", "effects": EFFECTS},
    }, source="test")
    return run_scenario(sc, progress=False)


def _system(tmp_path, params: dict) -> str:
    lines = ["[system]", 'name = "model"', "step = 0.005", "stop = 1.0", "[units.imu]",
             'fmu = "builtin:imu"', 'role = "imu"', "[units.imu.parameters]"]
    lines += [f'"{k}" = {v!r}' for k, v in params.items()]
    p = tmp_path / "model.toml"
    p.write_text("\n".join(lines) + "\n")
    return str(p)


def test_imu_fmu_replay_equals_the_forward_model(run, tmp_path):
    truth = run.truth["effects"]
    data = LogData.from_log(run.log)
    motion = data.motion(data.geometry)
    pred = replay_imu(data, _system(tmp_path, truth), motion)
    params = [p for p in truth if effect_of(p).target != "table"]
    g, a = predict(motion, params, np.array([truth[p] for p in params]))
    ref = np.hstack([g, a])
    st = motion.static
    # static samples: the C sensor model and the Python regressors agree to rounding
    scale = np.abs(ref[st]).max(axis=0)
    # (1e-8: the K2 term right after a move, where the FMU's interpolant still carries the
    # move's last acceleration, is integrated slightly differently)
    assert np.max(np.abs(pred[st] - ref[st]) / scale) < 1e-8
    # and the replayed FMU explains the measurement: noise-free data, so what is left is far
    # below a navigation-grade accelerometer's noise (7e-6 m/s per 5 ms sample)
    comp = assess(data, data.geometry, PlateAtSamples.of(motion), pred)
    for ch in ("acc_x", "acc_y", "acc_z"):
        assert comp.channels[ch]["rms"] < 1e-8


def test_imu_fmu_replay_without_the_effects_fails_visibly(run, tmp_path):
    data = LogData.from_log(run.log)
    motion = data.motion(data.geometry)
    comp = assess(data, data.geometry, PlateAtSamples.of(motion), replay_imu(data, _system(tmp_path, {}), motion))
    # the missing 80 ug bias on z over 2 s blocks: far above any noise level
    assert comp.channels["acc_z"]["rms"] > 0.5 * 80e-6 * 9.80665 * 0.005


def test_servo_replay_reproduces_the_same_table(run):
    res = replay_servo(run.log)
    for a, v in res.items():
        assert v["max"] == 0.0, (a, v["max"])


def test_servo_replay_with_a_slower_table_differs_while_moving(run):
    # a table with half the acceleration limit on the middle axis: its moves lag the logged
    # ones by many counts, while at rest both sit on the commanded count
    q = 2 * np.pi / 2**24
    res = replay_servo(run.log, parameters={"middle.acc_max": np.radians(100.0)})
    assert res["middle"]["rms_moving"] > 1000 * q
    # once both have come to rest they sit on the same commanded count
    assert abs(res["middle"]["difference"][-1]) <= q
    assert res["outer"]["max"] == 0.0  # the outer axis never moves in this schedule
