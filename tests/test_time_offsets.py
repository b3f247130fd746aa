"""The gyro–accelerometer time offset (acc.time_offset, PSINS's tGA) through the loop: a table
log whose accelerometers sample 1 ms late against their gyros (the IMU FMU's parameter), at
navigation-grade white noise on the diagnosis schedule.

What physics allows: the least squares' gyro rows are rest-to-rest sums, which no time shift
changes, so on a table log the accelerometers' offset against the gyros and the whole IMU's
against the table move the same rows; the diagnosis must name the offset and say that the two
cannot be told apart there (and that the system-level filter separates them). Adding it brings
χ²/dof back into its band and recovers the 1 ms within its σ."""
from __future__ import annotations

import copy
import json
import math
import tomllib

import pytest
from scipy.stats import chi2

from components.cli import main
from components.cli.demo import SCENARIO
from components.logs.logfile import write_log
from components.model.result import CalibrationResult
from components.simulation.multi_imu import Variant, run_variants
from components.simulation.scenario import scenario_from_dict

TGA = 1e-3


@pytest.fixture(scope="module")
def late_accelerometers(tmp_path_factory):
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["imu"]["effects"].pop("acc.k2.z")      # the demo's hidden effect: only the baseline errors
    d["schedule"]["overrides"]["dwell"] = 2.0
    sc = scenario_from_dict(d, source="test_time_offsets")
    log, _ = run_variants(sc, [Variant("tga", effects={"acc.time_offset": TGA}, seed=77)])["tga"]
    out = tmp_path_factory.mktemp("tga")
    write_log(out / "tga", log)
    return out


def test_a_late_accelerometer_is_named_and_added(late_accelerometers, capsys):
    d = late_accelerometers
    assert main(["calibrate", str(d / "tga"), "--out", str(d / "r0.json")]) == 0
    assert main(["diagnose", str(d / "tga"), "--model", str(d / "r0.json"), "--json", str(d / "d0.json")]) == 0
    out = capsys.readouterr().out
    d0 = json.loads((d / "d0.json").read_text())
    assert d0["verdict"] in ("acc.time_offset", "imu.time_offset"), d0["verdict"]
    first = next(c for c in d0["ranking"] if c["effect"] == d0["verdict"])
    other = ({"acc.time_offset", "imu.time_offset"} - {d0["verdict"]}).pop()
    assert other in [x["effect"] for x in first["indistinguishable"]]
    assert "system-level filter" in out
    assert main(["add", str(d / "tga"), "--model", str(d / "r0.json"), "--effect", "acc.time_offset",
                 "--out", str(d / "r1.json")]) == 0
    r1 = CalibrationResult.load(d / "r1.json")
    dof = r1.fit["dof"]
    lo, hi = chi2.ppf([0.0005, 0.9995], dof) / dof
    assert lo < r1.fit["chi2_per_dof"] < hi, r1.fit["chi2_per_dof"]
    got, sig = r1.values["acc.time_offset"], r1.sigmas["acc.time_offset"]
    assert abs(got - TGA) < 4 * sig and sig < 0.01 * TGA, (got, sig)
    assert main(["diagnose", str(d / "tga"), "--model", str(d / "r1.json"), "--json", str(d / "d1.json")]) == 0
    assert json.loads((d / "d1.json").read_text())["verdict"] is None
    ladder = r1.extra["ladder"]
    assert ladder[-1]["chi2_per_dof"] < ladder[0]["chi2_per_dof"] and not math.isnan(ladder[0]["chi2_per_dof"])


def test_a_whole_imu_offset_leaves_no_accelerometer_offset_behind(tmp_path, capsys):
    """The IMU 0.5 ms late against the table, its offset in the model: the gyro rows are
    rest-to-rest sums no time shift changes, so nothing is left for acc.time_offset. The spline
    of a move ended one sample late (at the next rest sample, clamped there), which gave the
    rest after every move a rate at its start the rest's own sums do not have: acc.time_offset
    was named (F 7.7 here, 84-100 on the diagnosis schedule) and, added, pulled imu.time_offset
    10 σ off."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "examples" / "scenarios" / "six_position.toml").read_text()
    text = text.replace("[imu.effects]", '[imu.effects]\n"imu.time_offset" = "0.5 ms"', 1)
    scn = tmp_path / "late.toml"
    scn.write_text(text)
    assert main(["simulate", str(scn), "--out", str(tmp_path / "late"), "--dwell", "10"]) == 0
    effects = "gyro.bias,gyro.sf,gyro.mis,acc.bias,acc.sf,acc.mis,imu.time_offset"
    assert main(["calibrate", str(tmp_path / "late"), "--effects", effects, "--out", str(tmp_path / "r.json")]) == 0
    res = CalibrationResult.load(tmp_path / "r.json")
    off, s = res.values["imu.time_offset"], res.sigmas["imu.time_offset"]
    assert abs(off - 0.5e-3) < 3.5 * s, (off, s)
    capsys.readouterr()
    assert main(["diagnose", str(tmp_path / "late"), "--model", str(tmp_path / "r.json"), "--candidates",
                 "acc.time_offset", "--json", str(tmp_path / "d.json")]) == 0
    d = json.loads((tmp_path / "d.json").read_text())
    assert d["found"] == [] and "acc.time_offset is missing" not in capsys.readouterr().out
    cand = next(c for c in d["ranking"] if c["effect"] == "acc.time_offset")
    assert cand["p_adjusted"] > 0.01, cand
