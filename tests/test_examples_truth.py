"""Shipped examples against their truth (issue 17, item 6), the frame a system-level
configuration's misalignments are in, and unitless effect values refused in scenarios.

Examples and where they are run against their truth:
- examples/scenarios/seed001.toml: here (kf seed_001 --simulate, every estimate within 3.5 σ)
- examples/scenarios/six_position.toml: here (simulate with 10-s dwells, calibrate, within 4 σ)
- examples/scenarios/seed003.toml: tests/test_kf.py; mems_psins19.toml: tests/test_kf_mems.py
- examples/scenarios/seed002_latitude.toml, tilted_base_seed000.toml: tests/test_procedures.py
- examples/libcosim_pair.toml: tests/test_verify.py
- not yet run against a truth by a test (loaded only, tests/test_formats_doc.py):
  examples/tumble.toml, examples/campaigns/smoke.toml; components/simulation/scenarios/
  demo_hidden_k2.toml runs only through the demo
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from components.cli import main
from components.errors import ScenarioError
from components.model.effects import ARCSEC
from components.navigation.truth_frame import estimation_frame, not_estimated, truth_in_frame

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenarios"


def _run_json(capsys, argv) -> tuple[int, dict]:
    code = main(argv + ["--json", "-"])
    return code, json.loads(capsys.readouterr().out)


def test_seed001_example_kf_is_within_its_sigmas_of_the_truth(capsys, tmp_path):
    """The example injects acc.mis.xy, which the former 3-misalignment configuration could not
    hold (acc.mis.yx 66 σ, acc.bias.x 22 σ off); with all six in the table frame none is off."""
    code, doc = _run_json(capsys, ["kf", "seed_001", "--simulate", str(EXAMPLES / "seed001.toml"),
                                   "--out", str(tmp_path / "r.json"), "--quiet"])
    assert code == 0, doc.get("problems")
    assert doc["truth_frame"] == "table" and doc["not_estimated"] == []
    z = {r["parameter"]: r["error"] / r["sigma"] for r in doc["errors_against_truth"]}
    assert len(z) == 21 + 3 and "acc.mis.xy" in z
    assert max(abs(v) for v in z.values()) < 3.5, z


def test_six_position_example_calibrates_to_its_truth(capsys, tmp_path):
    code, sim = _run_json(capsys, ["simulate", str(EXAMPLES / "six_position.toml"), "--dwell", "10",
                                   "--out", str(tmp_path / "six"), "--check"])
    assert code == 0 and sim["samples"] == 14400
    checked = {r["parameter"]: r["error"] / r["sigma"] for r in sim["errors_against_truth"]}
    assert len(checked) == 24 and max(abs(v) for v in checked.values()) < 4.0, checked
    truth = json.loads((tmp_path / "six.truth.json").read_text())["effects"]
    code, res = _run_json(capsys, ["calibrate", str(tmp_path / "six"), "--out", str(tmp_path / "r.json")])
    assert code == 0
    z = {p: (v["value"] - truth.get(p, 0.0)) / v["sigma"] for p, v in res["parameters"].items()}
    assert len(z) == 24 and max(abs(v) for v in z.values()) < 4.0, z


def _lq(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m = L Q with L lower triangular (positive diagonal), Q orthogonal."""
    q, r = np.linalg.qr(m.T)
    s = np.sign(np.diag(r))
    return (r.T * s), (q * s).T


def test_accelerometer_frame_truth_matches_the_exact_rotation():
    """Independent: the exact rotation that makes the accelerometers' matrix lower triangular (an
    LQ decomposition) applied to both sensors; first order in arcsec-sized angles."""
    inj = {"acc.mis.xy": 15 * ARCSEC, "acc.mis.xz": -8 * ARCSEC, "acc.mis.yz": 5 * ARCSEC,
           "acc.mis.zy": -20 * ARCSEC, "gyro.mis.yz": 20 * ARCSEC, "gyro.mis.zx": 10 * ARCSEC,
           "acc.sf.x": 40e-6}
    idx = {"x": 0, "y": 1, "z": 2}

    def matrix(sensor):
        m = np.eye(3)
        for i in "xyz":
            m[idx[i], idx[i]] += inj.get(f"{sensor}.sf.{i}", 0.0)
            for j in "xyz":
                if i != j:
                    m[idx[i], idx[j]] = inj.get(f"{sensor}.mis.{i}{j}", 0.0)
        return m

    a, g = matrix("acc"), matrix("gyro")
    la, q = _lq(a)
    g2 = g @ q.T
    params = [f"gyro.mis.{ij}" for ij in ("xy", "xz", "yx", "yz", "zx", "zy")] + ["acc.mis.yx", "acc.mis.zx",
                                                                                   "acc.mis.zy"]
    assert estimation_frame(params) == "accelerometer"
    seen = truth_in_frame(inj, "accelerometer")
    for i, j in (("y", "x"), ("z", "x"), ("z", "y")):
        assert seen[f"acc.mis.{i}{j}"] == pytest.approx(la[idx[i], idx[j]], abs=0.01 * ARCSEC)  # second order: (1e-4 rad)² ~ 0.002"
    for i in "xyz":
        for j in "xyz":
            if i != j:
                assert seen[f"gyro.mis.{i}{j}"] == pytest.approx(g2[idx[i], idx[j]], abs=0.01 * ARCSEC)  # second order: (1e-4 rad)² ~ 0.002"
    assert not_estimated(inj, params, "accelerometer") == ["acc.sf.x"]
    assert estimation_frame(params + ["acc.mis.xy", "acc.mis.xz", "acc.mis.yz"]) == "table"


@pytest.mark.parametrize("given, line, message", [
    ('"acc.sf.z" = "35 ppm"', '"acc.sf.z" = 35', r"acc.sf.z = 35 is 3500 % .*\"35 ppm\""),
    ('"acc.bias.x" = "50 ug"', '"acc.bias.x" = 0.0006', r"a bare number for an effect in m/s2.*\"0.0006 ug\""),
])
def test_a_bare_effect_value_in_a_scenario_is_refused(tmp_path, given, line, message):
    from components.simulation.scenario import load_scenario

    text = (EXAMPLES / "six_position.toml").read_text()
    (tmp_path / "s.toml").write_text(text.replace(given, line))
    with pytest.raises(ScenarioError, match=message):
        load_scenario(tmp_path / "s.toml")
    # a ratio within what an IMU has stays a number (SI), as before
    (tmp_path / "ok.toml").write_text(text.replace('"acc.sf.z" = "35 ppm"', '"acc.sf.z" = 3e-5'))
    assert load_scenario(tmp_path / "ok.toml").imu_effects["acc.sf.z"] == pytest.approx(3e-5)
