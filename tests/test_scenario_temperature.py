"""A scenario's [temperature] profile: the IMU follows it (its logged temperature is the
piecewise-linear profile at each sample time, computed here with numpy), a temperature
coefficient injected under it is recovered by calibrate, and a wrong profile is one error naming
the knot."""
import copy

import numpy as np
import pytest

from components.errors import ScenarioError
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.model.effects import UG
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

KNOTS = [[0, 25], [20, 45], [40, 45], [80, 25]]  # heat, soak, cool [s, degC]
BASE = {
    "scenario": {"name": "temperature", "step": 0.01, "seed": 3},
    "schedule": {"name": "six_position", "overrides": {"dwell": 5.0}},
    "site": {"latitude_deg": 45.0},
    "turntable": {"fmu": "builtin:turntable"},
    "imu": {"fmu": "builtin:imu", "effects": {"acc.temp.z": "20 ug/K"}},
    "temperature": {"profile": KNOTS},
}


@pytest.fixture(scope="module")
def run():
    return run_scenario(scenario_from_dict(copy.deepcopy(BASE), source="test"), progress=False)


def test_the_imu_follows_the_profile_and_its_coefficient_is_recovered(run):
    log = run.log
    t = np.asarray(log.time)
    want = np.interp(t, [k[0] for k in KNOTS], [k[1] for k in KNOTS])
    assert np.max(np.abs(np.asarray(log.temperature) - want)) < 1e-9
    assert run.truth["temperature_profile"] == KNOTS
    effects = ["gyro.bias", "gyro.sf", "gyro.mis", "acc.bias", "acc.sf", "acc.mis", "acc.temp"]
    fit = calibrate(LogData.from_log(log), effects)
    got = dict(zip(fit.parameters, fit.value))
    # a noise-free IMU: what is left is the model's discretisation, well below a part in a thousand
    assert got["acc.temp.z"] == pytest.approx(20 * UG, rel=1e-3)
    assert abs(got["acc.temp.x"]) < 0.01 * UG and abs(got["acc.temp.y"]) < 0.01 * UG


@pytest.mark.parametrize("profile, words", [
    ([[0, 25]], "at least two"),
    ([[5, 25], [20, 45]], "start at 0 s"),
    ([[0, 25], [20, 45], [20, 30]], "knot 3: time 20 s is not after"),
    ([[0, 298.15], [60, 318.15]], "knot 1: 298.15 degC is outside"),
    ([[0, 25], ["60", 45]], "knot 2"),
])
def test_a_wrong_profile_is_one_error_naming_the_knot(profile, words):
    d = copy.deepcopy(BASE)
    d["temperature"]["profile"] = profile
    with pytest.raises(ScenarioError, match="temperature") as e:
        scenario_from_dict(d, source="s.toml")
    assert words in str(e.value) and "s.toml: [temperature]" in str(e.value)


def test_a_profile_beside_another_temperature_mode_is_refused():
    d = copy.deepcopy(BASE)
    d["imu"]["parameters"] = {"temperature.mode": 1}
    with pytest.raises(ScenarioError, match="temperature.mode"):
        scenario_from_dict(d, source="s.toml")
