"""A supplier's pulse-output IMU (tests/fmus/supplier_pulse_imu: Integer pulse counts per interval,
its own names, deg/s and g inputs, no angular-acceleration input, no noise parameter, no seed),
as ring-laser and many navigation IMUs deliver data. The weight of a count comes from the unit
description (count_weight) - the FMU cannot say it in a way the role understands - and reaches
the log; the calibration finds the injected biases back through the counts; a pulse IMU whose
weight is not known is refused before the run (scenario) or before the first case (campaign);
the noise and seed it cannot take are said, and the criteria that need them are not applicable."""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from components.diagnosis.noise_choice import choose_noise
from components.errors import CampaignError, ScenarioError
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.model.effects import ARCSEC, DEG_H, UG
from components.simulation.run import build_system, run_scenario
from components.simulation.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
PULSE = Path(__file__).parent / "fmus" / "supplier_pulse_imu"
AX = "XYZ"
MAPPING = {**{f"omega.{c.lower()}": f"AngularRate_{c}" for c in AX}, **{f"f.{c.lower()}": f"Accel_{c}" for c in AX},
           **{f"gyro.{c.lower()}": f"GyroPulses_{c}" for c in AX}, **{f"acc.{c.lower()}": f"AccPulses_{c}" for c in AX}}
EFFECT_MAP = {**{f"gyro.bias.{c.lower()}": f"GyroBias_{c}" for c in AX},
              **{f"acc.bias.{c.lower()}": f"AccBias_{c}" for c in AX}}
G0 = 9.80665


def _unit(**changes) -> dict:
    from fmus.build import fmu_path

    d = {"fmu": str(fmu_path(PULSE, 2)), "mapping": MAPPING,
         "role_options": {"gyro_output": "counts", "acc_output": "counts"},
         "count_weight": {"gyro": "0.05 arcsec", "acc": "0.1 mm/s"},
         "effect_map": dict(EFFECT_MAP), "parameters": {"GyroPulseWeight": 0.05, "AccPulseWeight": 0.1},
         "effects": {"gyro.bias.x": "2 deg/h", "gyro.bias.z": "-3 deg/h", "acc.bias.y": "500 ug",
                     "acc.bias.z": "-200 ug"},
         "noise": {"gyro.noise.arw": "0.01 deg/sqrt(h)"}}
    d.update(changes)
    return {k: v for k, v in d.items() if v is not None}


def _scenario(**imu_changes) -> dict:
    d = tomllib.loads((ROOT / "examples" / "scenarios" / "six_position.toml").read_text())
    d["scenario"]["seed"] = 5
    d["scenario"]["step"] = 0.01
    d["schedule"]["overrides"] = {"dwell": 20.0}
    d["imu"] = _unit(**imu_changes)
    return d


@pytest.fixture(scope="module")
def pulse_run():
    return run_scenario(scenario_from_dict(_scenario(), source="test_supplier_pulse"), progress=False)


FITTED = ["gyro.bias", "acc.bias", "acc.sf"]


@pytest.fixture(scope="module")
def chosen_noise(pulse_run):
    """The log's data and the noise calibrate chooses for it (identified around the counts' floor:
    the slow part of two tests, computed once)."""
    data = LogData.from_log(pulse_run.log)
    return data, choose_noise(None, data, effects=FITTED)


def test_the_counts_and_their_weight_reach_the_log(pulse_run):
    log = pulse_run.log
    assert log.gyro_output == log.acc_output == "counts"
    assert log.gyro_count_rad == pytest.approx(0.05 * ARCSEC, rel=1e-15)
    assert log.acc_count_mps == pytest.approx(1e-4, rel=1e-15)
    # whole pulses, and at rest the accelerometer counts per second are gravity's (|f| = g)
    assert np.array_equal(log.gyro, np.round(log.gyro)) and np.array_equal(log.acc, np.round(log.acc))
    # (the first 10 s are a rest; the biases injected move |f| by at most 5.4e-3 m/s2)
    per_s = np.linalg.norm(log.acc[:1000].sum(axis=0)) * 1e-4 / (1000 * 0.01)
    assert per_s == pytest.approx(log.gravity, abs=6e-3)


def test_the_calibration_finds_the_injected_biases_through_the_counts(pulse_run, chosen_noise):
    truth = pulse_run.truth
    assert truth["not_injected"] == {"effects": [], "noise": ["gyro.noise.arw"], "seed": True}
    # as calibrate on the command line does: pulse counts bring their quantization as noise
    (data, (noise, said, _)), effects = chosen_noise, FITTED
    assert said.startswith("pulse counts: quantization from the count weights")
    fit = calibrate(data, effects, noise=noise)
    v, s = fit.values(), dict(zip(fit.parameters, fit.sigma))
    # no σ below what quantization alone leaves over the run (a count over its ~100 s):
    # pulses whose differences are mostly 0 must not read as a noise-free sensor
    assert min(s[f"gyro.bias.{c}"] for c in "xyz") > 0.05 * ARCSEC / 1000 / 4
    assert min(s[f"acc.bias.{c}"] for c in "xyz") > 1e-4 / 1000 / 4
    for name, si in (("gyro.bias.x", 2 * DEG_H), ("gyro.bias.z", -3 * DEG_H), ("gyro.bias.y", 0.0),
                     ("acc.bias.y", 500 * UG), ("acc.bias.z", -200 * UG), ("acc.bias.x", 0.0)):
        # the quantisation over a 20 s rest is 0.05 arcsec / 20 s = 0.0007 deg/h and
        # 1e-4 m/s / 20 s = 0.5 ug: far below the biases, so a wrong weight would show
        tol = max(4 * s[name], 0.02 * DEG_H if name.startswith("gyro") else 3 * UG)
        assert abs(v[name] - si) < tol, (name, v[name], si, s[name])


def test_white_noise_least_squares_on_counts_keeps_the_quantization(pulse_run):
    """Without a noise model the per-sample σ comes from the scatter at rest, which pulse counts
    whose differences are mostly 0 collapse (found: σ 1e-14 deg/h, errors 1e10 σ): one count
    (w/√12) is the least noise a sample has, so no error is many σ off."""
    fit = calibrate(LogData.from_log(pulse_run.log), ["gyro.bias", "acc.bias"])
    assert np.all(fit.sigma_gyro >= 0.05 * ARCSEC / np.sqrt(12) * (1 - 1e-12))
    assert np.all(fit.sigma_acc >= 1e-4 / np.sqrt(12) * (1 - 1e-12))
    v, s = fit.values(), dict(zip(fit.parameters, fit.sigma))
    for name, si in (("gyro.bias.y", 0.0), ("gyro.bias.z", -3 * DEG_H), ("acc.bias.x", 0.0), ("acc.bias.z", -200 * UG)):
        assert abs(v[name] - si) < 4 * s[name], (name, v[name], si, s[name])


def test_a_pulse_imu_of_unknown_weight_is_refused_before_the_run():
    sc = scenario_from_dict(_scenario(count_weight=None), source="t")
    with pytest.raises(ScenarioError, match=r"gyro_output = 'counts', but the weight of one count is not known "
                                            r"\(the FMU \S+ has no gyro.count_weight parameter\): state it"):
        build_system(sc)


@pytest.mark.parametrize("change, match", [
    ({"count_weight": {"gyro": "0.05 deg/h"}}, r"count_weight.gyro = '0.05 deg/h': expected a number \[rad\]"),
    ({"count_weight": {"gyro": "-1 arcsec"}}, r"count_weight.gyro = '-1 arcsec': expected a positive weight"),
    ({"count_weight": {"gyro": "1 arcsec", "mag": 1}}, r"count_weight = .*: expected a table \{gyro"),
    ({"role_options": {"gyro_output": "counts", "acc_output": "specific_force"}},
     r"count_weight.acc is given, but acc_output = 'specific_force'"),
])
def test_count_weight_mistakes_are_one_line_errors(change, match):
    with pytest.raises(ScenarioError, match=match):
        scenario_from_dict(_scenario(**change), source="t")


def test_our_imu_takes_the_stated_weight():
    """On our IMU a stated weight sets its gyro.count_weight; without one its own value is used."""
    d = _scenario(fmu="builtin:imu", mapping={}, effect_map=None, parameters={}, noise={}, effects={},
                  count_weight={"gyro": "0.2 arcsec"})
    d["imu"]["role_options"] = {"gyro_output": "counts", "acc_output": "increment"}
    _, _, info = build_system(scenario_from_dict(d, source="t"))
    assert info["count_weights"] == {"gyro": pytest.approx(0.2 * ARCSEC)}
    assert info["imu_parameters"]["gyro.count_weight"] == pytest.approx(0.2 * ARCSEC)
    del d["imu"]["count_weight"]
    _, _, info = build_system(scenario_from_dict(d, source="t"))
    from fmpy import read_model_description

    own = next(v for v in read_model_description(str(info["imu_path"])).modelVariables
               if v.name == "gyro.count_weight")
    assert info["count_weights"] == {"gyro": float(own.start)}


def _campaign(tmp_path, weight: str) -> Path:
    mapping = "\n".join(f'"{k}" = "{v}"' for k, v in MAPPING.items())
    emap = "\n".join(f'"{k}" = "{v}"' for k, v in EFFECT_MAP.items())
    text = f'''
[campaign]
name = "pulse"
seed = 1
replicates = 1
[scenario]
file = "{(ROOT / 'examples' / 'scenarios' / 'six_position.toml').as_posix()}"
step = 0.01
schedule_overrides = {{dwell = 10.0}}
[systems.pulse]
imu = "build:{PULSE.as_posix()}"
gyro_output = "counts"
acc_output = "counts"
{weight}
[systems.pulse.mapping]
{mapping}
[systems.pulse.effect_map]
{emap}
[procedures.lsq]
method = "lsq"
effects = ["gyro.bias", "acc.bias", "acc.sf"]
[variations]
"acc.bias.y" = {{values = ["300 ug"]}}
"gyro.noise.arw" = {{values = ["0.01 deg/sqrt(h)"]}}
[[criteria]]
id = "TOL"
requirement = "R1"
kind = "estimate"
parameters = ["acc.bias.*"]
tolerance = "30 ug"
[[criteria]]
id = "CRB"
requirement = "R2"
kind = "estimate"
parameters = ["gyro.bias.*"]
crb_sigmas = 5
'''
    p = tmp_path / "pulse.toml"
    p.write_text(text)
    return p


def test_a_campaign_refuses_a_pulse_imu_of_unknown_weight_before_its_first_case(tmp_path):
    from components.campaign.reader import load_campaign

    with pytest.raises(CampaignError, match=r"\[systems.pulse\]: gyro_output = 'counts', but the weight of one "
                                            r"count is not known"):
        load_campaign(_campaign(tmp_path, ""))


def test_a_pulse_imu_campaign_case_is_judged_where_it_can_be(tmp_path):
    """One case in this process, as a worker runs it: the tolerance on the accelerometer biases is
    judged (and met: quantization leaves ~1 ug), the Cramér-Rao criterion is not applicable
    because the IMU took none of the noise asked for, and the record says what it could not take."""
    import json

    from components.campaign.case import run_case
    from components.campaign.reader import load_campaign
    from components.campaign.spec import task_for

    camp = load_campaign(_campaign(tmp_path, 'count_weight = {gyro = "0.05 arcsec", acc = "0.1 mm/s"}'))
    assert camp.systems["pulse"].count_weight == {"gyro": pytest.approx(0.05 * ARCSEC), "acc": pytest.approx(1e-4)}
    task = json.loads(json.dumps(task_for(camp, camp.cases[0])))
    assert "gyro.noise.arw" in task["not_injected"]["noise"] and task["not_injected"]["seed"] is True
    rec = run_case(task)
    by = {c["id"]: c for c in rec["criteria"]}
    assert by["TOL"].get("applicable", True) and by["TOL"]["passed"] is True, by["TOL"]
    assert by["CRB"]["passed"] is None and by["CRB"]["applicable"] is False
    assert "takes none of the noise asked for (" in by["CRB"]["message"] and "gyro.noise.arw" in by["CRB"]["message"]
    est = rec["estimates"]
    assert abs(est["acc.bias.y"]["value"] - 300 * UG) < 5 * UG


def test_compare_on_counts_without_a_noise_model_keeps_the_quantization(pulse_run):
    """compare's white level comes from the residual's scatter at rest, which pulse counts
    collapse (a laser-gyro log printed chi2/dof = 2.4e21): one count, w/√12, is its floor, under
    which the model fitted to the log has a finite chi2/dof of order 1 (at most that: the block
    sums' quantization error is a difference of two remainders, not √n of them)."""
    from components.diagnosis.compare import compare
    from components.model.result import result_from_fit

    data = LogData.from_log(pulse_run.log)
    effects = ["gyro.bias", "acc.bias", "acc.sf"]
    model = result_from_fit(calibrate(data, effects), effects, data)
    c = compare(data, model, fitted_parameters=len(model.values), noise=None)
    assert 0 < c.chi2_per_dof < 2.0, c.chi2_per_dof


def test_a_noise_free_pulse_outputs_noise_floor_is_its_counts(chosen_noise):
    """This FMU takes no noise: its samples carry only the remainders of their counts, so a
    sample's residual at rest is of the order of w/√6 (two uniform remainders), and the
    per-sample noise floor compare reports must be that, not the white level the log lacks
    (found: 7e-20 rad, rms/noise 1e12 on a supplier's noise-free pulse log)."""
    from components.diagnosis.compare import compare
    from components.model.result import result_from_fit

    (data, chosen), effects = chosen_noise, FITTED
    for spec in (None, ["white"]):
        noise, said, _ = chosen if spec is None else choose_noise(spec, data, effects=effects)
        model = result_from_fit(calibrate(data, effects, noise=noise), effects, data)
        c = compare(data, model, fitted_parameters=len(model.values), noise=noise)
        for ch, v in c.channels.items():
            w = data.count_weight[0 if ch.startswith("gyro") else 1]
            assert 0.2 < v["rms"] / v["noise_floor"] < 2.0, (spec, ch, v["rms"], v["noise_floor"])
            assert v["noise_floor"] >= w / np.sqrt(6) * (1 - 1e-12), (spec, ch, v["noise_floor"])
