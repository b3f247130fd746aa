"""The diagnosis judges a candidate's magnitude against the log's grade: on a tactical-grade log
(white noise 100 times a navigation grade's) a gyro drift of 300 deg/h per hour - three times
what the old fixed cap of 1e5 x the navigation-grade typical value let through, far below what
any real IMU can have - is named, and found at its value."""
from __future__ import annotations

import copy
import tomllib

import pytest

from components.cli.demo import SCENARIO
from components.diagnosis.diagnose import diagnose
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.model.effects import DEFAULT_EFFECTS, DEG_H, EFFECTS
from components.model.plausibility import plausible_limit
from components.model.result import result_from_fit
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

DRIFT = 300 * DEG_H / 3600  # rad/s per s


def test_a_tactical_drift_beyond_navigation_typical_is_named():
    assert 1e5 * EFFECTS["gyro.drift"].typical < DRIFT < plausible_limit("gyro.drift.z")
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["imu"]["effects"].pop("acc.k2.z")
    d["imu"]["effects"]["gyro.drift.z"] = DRIFT
    d["imu"]["noise"] = {"gyro.noise.arw": "0.2 deg/sqrt(h)", "acc.noise.vrw": "1000 ug/sqrt(Hz)"}
    d["scenario"]["seed"] = 7
    run = run_scenario(scenario_from_dict(d, source="tactical drift"), progress=False)
    data = LogData.from_log(run.log)
    effects = list(DEFAULT_EFFECTS)
    model = result_from_fit(calibrate(data, effects), effects, data)
    dg = diagnose(data, model, forward=False)
    assert dg.verdict == "gyro.drift", [(c.effect, c.status, c.p_adjusted) for c in dg.ranking[:4]]
    cand = next(c for c in dg.ranking if c.effect == "gyro.drift")
    value, sigma = cand.parameters["gyro.drift.z"]
    assert value == pytest.approx(DRIFT, abs=4 * sigma)
