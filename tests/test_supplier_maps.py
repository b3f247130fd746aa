"""A supplier's IMU all the way (docs/supplier.md): its own parameter names and units (deg/h, mg,
urad, deg/sqrt(h)), a noise parameter and an integer seed (tests/fmus/supplier_noisy_imu). A
scenario injects vocabulary effects and noise through the unit's maps: the calibration finds
them at their injected values (so every unit was converted right), the truth records what was
injected and what could not be, the seed reaches the FMU; a unit given against another declared
one is refused before anything runs; a noise-free IMU's criteria that need noise are not
applicable, never passed."""
from __future__ import annotations

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from components.errors import ScenarioError
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.model.effects import ARCSEC, DEG_H, UG
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
NOISY = Path(__file__).parent / "fmus" / "supplier_noisy_imu"
AX = "XYZ"
MAPPING = {**{f"omega.{c.lower()}": f"AngularRate_{c}" for c in AX}, **{f"f.{c.lower()}": f"Accel_{c}" for c in AX},
           **{f"gyro.{c.lower()}": f"GyroRate_{c}" for c in AX}, **{f"acc.{c.lower()}": f"Accel_Out_{c}" for c in AX}}
EFFECT_MAP = {**{f"gyro.bias.{c.lower()}": f"GyroBias_{c}" for c in AX},
              **{f"acc.bias.{c.lower()}": f"AccBias_{c}" for c in AX}, "gyro.mis.xy": "GyroMis_XY"}


def _scenario(seed: int = 3, **imu_changes) -> dict:
    from fmus.build import fmu_path

    d = tomllib.loads((ROOT / "examples" / "scenarios" / "six_position.toml").read_text())
    d["scenario"]["seed"] = seed
    d["scenario"]["step"] = 0.01
    d["schedule"]["overrides"] = {"dwell": 10.0}
    d["imu"] = {"fmu": str(fmu_path(NOISY, 2)), "mapping": MAPPING, "role_options": {"gyro_output": "rate",
                                                                                     "acc_output": "specific_force"},
                "effect_map": dict(EFFECT_MAP), "noise_map": {"gyro.noise.arw": "GyroARW"},
                "seed_parameter": "RandomSeed",
                "effects": {"gyro.bias.x": "2 deg/h", "acc.bias.y": "500 ug", "gyro.mis.xy": "50 arcsec",
                            "gyro.sf.z": "100 ppm"},
                "noise": {"gyro.noise.arw": "0.05 deg/sqrt(h)", "acc.noise.vrw": "5 ug/sqrt(Hz)"}}
    d["imu"].update(imu_changes)
    return d


@pytest.fixture(scope="module")
def supplier_run():
    return run_scenario(scenario_from_dict(_scenario(), source="test_supplier_maps"), progress=False)


def test_effects_and_noise_reach_the_supplier_through_its_maps(supplier_run):
    truth = supplier_run.truth
    assert truth["effects"]["gyro.bias.x"] == pytest.approx(2 * DEG_H)
    assert truth["not_injected"] == {"effects": ["gyro.sf.z"], "noise": ["acc.noise.vrw"], "seed": False}
    assert "gyro.sf.z" not in truth["effects"] and truth["noise"] == {"gyro.noise.arw": pytest.approx(0.05 * math.pi / 180 / 60)}
    # the FMU got its own units: deg/h, mg, urad, deg/sqrt(h)
    p = truth["imu"]["parameters"]
    assert p["GyroBias_X"] == pytest.approx(2.0) and p["AccBias_Y"] == pytest.approx(0.5 * 0.980665 / 0.980665)
    assert p["GyroMis_XY"] == pytest.approx(50 * ARCSEC * 1e6) and p["GyroARW"] == pytest.approx(0.05)
    assert p["RandomSeed"] == 3
    # the physics: calibration finds what was injected, in SI, within its σ
    fit = calibrate(LogData.from_log(supplier_run.log), ["gyro.bias", "gyro.mis", "acc.bias", "acc.sf"])
    v, s = fit.values(), dict(zip(fit.parameters, fit.sigma))
    # (the accelerometers are noise-free here - their VRW has no parameter - so their σ is the
    # floor: 1e-4 of the value is the supplier's linear-interpolation mean against the table's motion)
    for name, si in (("gyro.bias.x", 2 * DEG_H), ("acc.bias.y", 500 * UG), ("gyro.mis.xy", 50 * ARCSEC)):
        assert abs(v[name] - si) < max(4 * s[name], 1e-4 * abs(si)), (name, v[name], si, s[name])
    # and the gyro noise is the density asked for (white: σ per sample = N / sqrt(h) × h)
    assert fit.sigma_gyro[0] == pytest.approx(0.05 * math.pi / 180 / 60 * math.sqrt(0.01), rel=0.1)


def test_the_seed_reaches_the_supplier(supplier_run):
    again = run_scenario(scenario_from_dict(_scenario(seed=3), source="t"), progress=False)
    other = run_scenario(scenario_from_dict(_scenario(seed=4), source="t"), progress=False)
    assert np.array_equal(again.log.gyro, supplier_run.log.gyro)
    assert not np.array_equal(other.log.gyro, supplier_run.log.gyro)


@pytest.mark.parametrize("change, match", [
    ({"effect_map": {**EFFECT_MAP, "gyro.bias.x": ["GyroBias_X", "deg/s"]}},
     r"'gyro.bias.x': the map says 'deg/s', the FMU declares GyroBias_X in 'deg/h': the values would be off by"),
    ({"effect_map": {**EFFECT_MAP, "acc.bias.x": "AccBias_X_"}}, r"has no parameter 'AccBias_X_' \(did you mean AccBias_X"),
    ({"effect_map": {**EFFECT_MAP, "acc.bias.x": "GyroBias_X"}},
     r"declares GyroBias_X in 'deg/h', which is not a unit of m/s2"),
    ({"noise_map": {"gyro.noise.arw": ["GyroARW", "ug/sqrt(Hz)"]}}, r"unit 'ug/sqrt\(Hz\)': expected one of"),
    ({"seed_parameter": "Seed"}, r"seed_parameter = 'Seed': the FMU \S+ has no such parameter"),
    # the seed into a Real parameter: a scale factor of +300 % with seed 3
    ({"seed_parameter": "GyroBias_Y"}, r"GyroBias_Y is a Real; the noise seed is an Integer parameter"),
    # a parameter set by hand and by an injected effect: the run used one, the truth the other
    ({"parameters": {"GyroBias_X": 1.0}}, r"\[imu.parameters\] sets 'GyroBias_X', which \[imu.effects\]"),
])
def test_map_mistakes_are_refused_before_the_run(change, match):
    sc = scenario_from_dict(_scenario(**change), source="test")
    from components.simulation.run import build_system

    with pytest.raises(ScenarioError, match=match):
        build_system(sc)


def test_a_campaign_refuses_a_unit_mistake_before_its_first_case(tmp_path):
    from components.campaign.reader import load_campaign
    from components.errors import CampaignError

    text = f'''
[campaign]
name = "units"
seed = 1
replicates = 1
[scenario]
file = "{ROOT / 'examples' / 'scenarios' / 'six_position.toml'}"
[systems.noisy]
imu = "build:{NOISY}"
gyro_output = "rate"
acc_output = "specific_force"
[systems.noisy.mapping]
{chr(10).join(f'"{k}" = "{v}"' for k, v in MAPPING.items())}
[systems.noisy.effect_map]
"gyro.bias.x" = ["GyroBias_X", "deg/s"]
[procedures.lsq]
method = "lsq"
[[criteria]]
id = "B"
requirement = "R"
kind = "estimate"
parameters = ["acc.bias.*"]
tolerance = "30 ug"
'''
    p = tmp_path / "c.toml"
    p.write_text(text)
    with pytest.raises(CampaignError, match=r"the map says 'deg/s', the FMU declares GyroBias_X in 'deg/h'"):
        load_campaign(p)


def test_criteria_that_need_noise_are_not_applicable_on_a_noise_free_imu():
    """The record of a case whose IMU took none of the noise: a σ, CRB, χ² or diagnosis criterion
    is 'not applicable' with the reason (not a pass on meaningless numbers); a tolerance still
    judges; the case's verdict comes from what could be judged."""
    from components.campaign.case import record

    crits = [{"id": "TOL", "requirement": "R1", "kind": "estimate", "parameters": ["acc.bias.*"], "tolerance": "30 ug"},
             {"id": "CRB", "requirement": "R2", "kind": "estimate", "parameters": ["gyro.bias.*"], "crb_sigmas": 5},
             {"id": "FIT", "requirement": "R3", "kind": "chi2", "max": 1.2}]
    numbers = {"estimates": {"acc.bias.x": {"value": 1e-4, "sigma": 1e-12, "truth": 1e-4, "error": 1e-7, "crb": 1e-12},
                             "gyro.bias.x": {"value": 0.0, "sigma": 1e-15, "truth": 0.0, "error": 1e-16, "crb": 1e-15}},
               "chi2_per_dof": 5.1e17, "diagnosis": None}
    task = {"case": {"id": "lsq-acme-g0-r0"}, "truth": {}, "criteria": crits,
            "not_injected": {"effects": [], "noise": ["gyro.noise.arw"], "seed": True, "noise_free": True}}
    rec = record(task, copy.deepcopy(numbers))
    by = {r["id"]: r for r in rec["criteria"]}
    assert by["TOL"]["passed"] is True
    for cid in ("CRB", "FIT"):
        assert by[cid]["passed"] is None and by[cid]["applicable"] is False
        assert "not applicable: the IMU FMU takes none of the noise asked for (gyro.noise.arw" in by[cid]["message"]
    assert rec["verdict"] == "pass"
    # with noise, the same numbers are judged (and the absurd chi2 fails)
    task["not_injected"] = {"effects": [], "noise": [], "seed": False, "noise_free": False}
    rec = record(task, copy.deepcopy(numbers))
    assert {r["id"]: r["passed"] for r in rec["criteria"]}["FIT"] is False and rec["verdict"] == "fail"


@pytest.mark.parametrize("change, match", [
    # rates without role_options: the role's default kind and the option that takes rates are said
    ({"role_options": {}}, r"GyroRate_X: unit 'deg/s' cannot be converted to rad \(the role takes gyro_output = "
                           r"'increment' \[rad\] here; for an output of another kind set gyro_output in the unit's "
                           r"role_options: 'rate' \[rad/s\]"),
    # a mapped name in another case: the unit's own spelling is proposed
    ({"mapping": {**MAPPING, "omega.x": "AngularRate_x"}},
     r"missing input omega.x \(mapped to 'AngularRate_x'\) .*; did you mean 'AngularRate_X'\?"),
])
def test_role_mistakes_say_how_to_mend_them(change, match):
    from orchestrator.errors import RoleError

    with pytest.raises(RoleError, match=match):
        run_scenario(scenario_from_dict(_scenario(**change), source="test"), progress=False)


def test_a_case_with_no_applicable_criterion_is_skipped_in_junit():
    """JUnit: a case whose every criterion is not applicable (a noise-free IMU against criteria on
    σ and χ²) is <skipped>, not a pass a CI would count; one with a criterion judged is a testcase
    as before."""
    import xml.etree.ElementTree as ET
    from types import SimpleNamespace

    from components.campaign.case import record
    from components.campaign.junit import junit_xml

    crits = [{"id": "CRB", "requirement": "R2", "kind": "estimate", "parameters": ["gyro.bias.*"], "crb_sigmas": 5},
             {"id": "FIT", "requirement": "R3", "kind": "chi2", "max": 1.2}]
    numbers = {"estimates": {"gyro.bias.x": {"value": 0.0, "sigma": 1e-15, "truth": 0.0, "error": 1e-16, "crb": 1e-15}},
               "chi2_per_dof": 5.1e17, "diagnosis": None}
    lost = {"effects": [], "noise": ["gyro.noise.arw"], "seed": True, "noise_free": True}
    recs = {}
    for cid, cs in (("free", crits), ("judged", crits + [{"id": "TOL", "requirement": "R1", "kind": "estimate",
                                                          "parameters": ["gyro.bias.*"], "tolerance": "1 deg/h"}])):
        recs[cid] = record({"case": {"id": cid}, "truth": {}, "criteria": cs, "not_injected": lost},
                           copy.deepcopy(numbers))
    cases = [SimpleNamespace(id=c, procedure="lsq", system="acme", seed=0, variation={}) for c in recs]
    root = ET.fromstring(junit_xml(SimpleNamespace(name="c", cases=cases), recs).split("\n", 1)[1])
    tcs = {tc.get("name"): tc for tc in root.iter("testcase")}
    assert tcs["free"].find("skipped") is not None and "not applicable" in tcs["free"].find("skipped").get("message")
    assert tcs["judged"].find("skipped") is None and tcs["judged"].find("failure") is None
    assert root.get("skipped") == "1"
