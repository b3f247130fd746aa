"""The command line for scripts and CI (issue 17): --json parsed against the files and printed
numbers, the exit codes (0 ok, 1 a check failed, 2 bad input, 3 could not run), a numeric
residual CSV, a result fitted to another log refitted (said and recorded), and the checks of a
log's declared kinds and units against physics."""
from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pytest

from components.cli import main
from components.logs.logfile import read_log, write_log


@pytest.fixture(scope="module")
def logs(conformance, tmp_path_factory):
    """The conformance logs and a model fitted to each (ideal: noise-free, example: noise + effects)."""
    d = tmp_path_factory.mktemp("scripts")
    for stem in ("ideal", "example"):
        write_log(d / stem, read_log(conformance / stem))
        assert main(["calibrate", str(d / stem), "--out", str(d / f"{stem}.r.json")]) == 0
    return d


def _json_stdout(capsys, argv) -> tuple[int, dict, str]:
    code = main(argv + ["--json", "-"])
    cap = capsys.readouterr()
    return code, json.loads(cap.out), cap.err


def test_calibrate_json_is_the_result_file(logs, capsys):
    code, doc, text = _json_stdout(capsys, ["calibrate", str(logs / "example"), "--out", str(logs / "c.json")])
    res = json.loads((logs / "c.json").read_text())
    assert code == 0 and doc["command"] == "calibrate" and doc["exit_code"] == 0
    assert set(doc["parameters"]) == set(res["parameters"])
    for p, v in res["parameters"].items():
        assert doc["parameters"][p]["value"] == pytest.approx(v["value"], rel=1e-12)
    # the text went to stderr, with the same χ²/dof
    printed = float(re.search(r"chi2/dof = ([0-9.]+)", text).group(1))
    assert printed == pytest.approx(doc["fit"]["chi2_per_dof"], abs=1e-3)


def test_compare_json_fail_above_and_numeric_residuals(logs, capsys, tmp_path):
    model = str(logs / "example.r.json")
    code, doc, text = _json_stdout(capsys, ["compare", str(logs / "example"), "--model", model,
                                            "--residuals", str(tmp_path / "r.csv")])
    assert code == 0 and doc["refit"] is None
    printed = float(re.search(r"chi2/dof \(block sums[^=]*= ([0-9.]+)", text).group(1))
    assert printed == pytest.approx(doc["chi2_per_dof"], abs=1e-3)
    assert set(doc["channels"]) == {"gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z"}
    # a correct model passes a CI threshold of 1.2 and fails one below its own χ²/dof
    assert main(["compare", str(logs / "example"), "--model", model, "--fail-above", "1.2"]) == 0
    assert main(["compare", str(logs / "example"), "--model", model,
                 "--fail-above", str(doc["chi2_per_dof"] / 2)]) == 1
    # every field of the residual CSV but the label is a number any reader takes
    rows = (tmp_path / "r.csv").read_text().splitlines()
    assert rows[0].startswith("time,segment,")
    cols = [r.split(",") for r in rows[1:]]
    t = np.array([float(c[0]) for c in cols])
    assert np.allclose(t, read_log(logs / "example").time)
    assert np.isfinite(np.array([[float(x) for x in c[2:]] for c in cols[:2000]])).all()


def test_exit_codes_bad_input_and_could_not_run(logs, capsys, monkeypatch):
    code, doc, err = _json_stdout(capsys, ["diagnose", str(logs / "example"), "--model",
                                           str(logs / "example.r.json"), "--candidates", "acc.k9"])
    assert code == 2 and doc["exit_code"] == 2 and "acc.k9" in doc["error"]
    assert "acc.k2" in err and "Traceback" not in err        # the valid names, one line
    # said before the log is read (a long log takes a minute to read and check)
    code, doc, _ = _json_stdout(capsys, ["diagnose", str(logs / "nowhere"), "--model",
                                         str(logs / "example.r.json"), "--candidates", "acc.k9"])
    assert code == 2 and "acc.k9" in doc["error"]
    assert main(["compare", str(logs / "nowhere"), "--model", str(logs / "example.r.json")]) == 2
    # a run that fails underway (a unit's fault) is "could not run", not bad input
    from components.cli import cosim
    from orchestrator.errors import SimulationFault

    def fault(args):
        raise SimulationFault("unit imu failed at t = 1 s", None)

    monkeypatch.setattr(cosim, "_cmd_tumble", fault)
    code, doc, _ = _json_stdout(capsys, ["tumble"])
    assert code == 3 and doc["exit_code"] == 3 and "unit imu" in doc["error"]


def test_plan_json_bounds_grow_with_the_noise(capsys):
    code, nav, text = _json_stdout(capsys, ["plan", "six_position", "--dwell", "5", "--effects", "acc.bias"])
    assert code == 0 and set(nav["crb"]) == {"acc.bias.x", "acc.bias.y", "acc.bias.z"}
    line = next(ln for ln in text.splitlines() if ln.startswith("acc.bias.x"))
    assert float(line.split()[1]) == pytest.approx(nav["crb"]["acc.bias.x"]["display_sigma"], rel=1e-3)
    # the VRW 10 x the grade's: the bound grows (less than 10 x: the grade's bias instability
    # dominates the 5-s dwells too)
    _, loud, _ = _json_stdout(capsys, ["plan", "six_position", "--dwell", "5", "--effects", "acc.bias",
                                       "--vrw", "100"])
    assert 1.2 * nav["crb"]["acc.bias.x"]["sigma"] < loud["crb"]["acc.bias.x"]["sigma"] \
        < 10 * nav["crb"]["acc.bias.x"]["sigma"]


def test_apply_json_names_what_it_wrote(logs, capsys, tmp_path):
    code, doc, _ = _json_stdout(capsys, ["apply", str(logs / "example"), "--result", str(logs / "example.r.json"),
                                         "--out", str(tmp_path / "corr")])
    assert code == 0 and doc["samples"] == read_log(logs / "example").n
    assert all(p.startswith(str(tmp_path / "corr")) for p in doc["out"])


def test_diagnose_fail_on_verdict(logs, capsys):
    # the exit status follows the verdict in the JSON: 1 exactly when it names something missing
    code, doc, _ = _json_stdout(capsys, ["diagnose", str(logs / "example"), "--model", str(logs / "example.r.json"),
                                         "--fail-on-verdict", "--top", "3"])
    assert code == (1 if doc["verdict"] else 0)


def test_a_result_of_another_log_is_refitted_first(logs, capsys, tmp_path):
    """The ideal log's model on the example log: said, and the numbers are the example's own
    fit's (2080 vs 0.873 before), the ladder of add starts there and credits nothing to K2."""
    own = json.loads((logs / "example.r.json").read_text())
    code, doc, text = _json_stdout(capsys, ["compare", str(logs / "example"), "--model", str(logs / "ideal.r.json")])
    assert "the model was fitted to" in text and "not to this log: refitting its effects on this log first" in text
    assert doc["refit"]["fitted_to_sha256"]["csv_sha256"] != own["data"]["csv_sha256"]
    _, self_doc, _ = _json_stdout(capsys, ["compare", str(logs / "example"), "--model", str(logs / "example.r.json")])
    assert doc["chi2_per_dof"] == pytest.approx(self_doc["chi2_per_dof"], rel=1e-9)
    code, add, _ = _json_stdout(capsys, ["add", str(logs / "example"), "--model", str(logs / "ideal.r.json"),
                                         "--effect", "acc.k2", "--out", str(tmp_path / "k2.json")])
    first, second = add["ladder"][0]["chi2_per_dof"], add["ladder"][1]["chi2_per_dof"]
    assert first == pytest.approx(self_doc["chi2_per_dof"], rel=1e-9)
    dof = self_doc["dof"]
    assert abs(first - second) < 3 * (2 / dof) ** 0.5     # the example has no K2: nothing to credit
    assert json.loads((tmp_path / "k2.json").read_text())["refit_from"]["model"].endswith("ideal.r.json")


@pytest.mark.parametrize("mistake, evidence, ratio", [
    ("gyro rate", r"gyros turn ([\d.e+-]+) × .*increments declared as rates", 0.005),
    ("angles in degrees", r"gyros turn ([\d.e+-]+) × .*table angles in degrees declared as radians", math.pi / 180),
    ("acc specific force", r"([\d.e+-]+) × gravity.*increments declared as specific force", 0.005),
])
def test_declared_kinds_and_units_are_checked_against_physics(logs, tmp_path, capsys, mistake, evidence, ratio):
    log = read_log(logs / "example")
    dt = log.dt
    assert dt == pytest.approx(0.005)     # the ratios the evidence names are dt and π/180
    if mistake == "gyro rate":
        bad = dataclasses.replace(log, gyro_output="rate")
    elif mistake == "angles in degrees":
        bad = dataclasses.replace(log, gimbal={k: np.degrees(v) for k, v in log.gimbal.items()})
    else:
        bad = dataclasses.replace(log, acc_output="specific_force")
    write_log(tmp_path / "bad", bad)
    main(["calibrate", str(tmp_path / "bad"), "--out", str(tmp_path / "r.json")])
    err = capsys.readouterr().err
    found = re.search(evidence, err)
    assert found, err
    # the evidence printed is the mistake's own ratio (dt or π/180), to the 4 digits shown
    assert float(found.group(1)) == pytest.approx(ratio, rel=2e-3), err
    main(["calibrate", str(logs / "example"), "--out", str(tmp_path / "good.json")])
    assert "warning" not in capsys.readouterr().err      # the right declaration: nothing said


def test_check_fmu_run_and_noise_json(imu_fmu, tmp_path, capsys):
    code, doc, text = _json_stdout(capsys, ["check-fmu", str(imu_fmu), "--role", "imu", "--no-cost"])
    assert code == 0 and doc["accepted"] is True and doc["validation"] == [] and "verdict: ACCEPTED" in text
    examples = __import__("pathlib").Path(__file__).resolve().parents[1] / "examples"
    code, doc, _ = _json_stdout(capsys, ["run", str(examples / "tumble.toml"), "--stop", "1",
                                         "--out", str(tmp_path / "r.parquet")])
    from orchestrator.recording import Recording

    rec = Recording.load(tmp_path / "r.parquet")
    assert code == 0 and doc["rows"] == rec.rows and doc["signals"] == list(rec.signals)
    code, doc, _ = _json_stdout(capsys, ["noise", str(examples / "formats" / "log"), "--out", str(tmp_path / "n.json")])
    written = json.loads((tmp_path / "n.json").read_text())
    assert code == 0 and doc["channels"] == written["channels"]


def test_tumble_json_residuals_are_noise(capsys):
    """The two FMUs through six attitudes: IMU − truth − injected errors per attitude in the JSON;
    the largest of them over the dwell mean's noise σ is the reported figure, and noise-sized."""
    code, doc, text = _json_stdout(capsys, ["tumble", "--dwell", "2"])
    assert code == 0 and doc["verdict"] == "PASS" and len(doc["attitudes"]) == 6
    worst = max(max(max(abs(x) for x in a["acc_residual_ug"]) / doc["noise_sigma_acc_ug"],
                    max(abs(x) for x in a["gyro_residual_deg_per_h"]) / doc["noise_sigma_gyro_deg_per_h"])
                for a in doc["attitudes"].values())
    assert worst == pytest.approx(doc["largest_residual_sigma"], rel=1e-9) and worst < 5
    assert f"largest residual {worst:.2f} sigma" in text


def test_a_warning_of_another_kind_is_passed_on_once(monkeypatch, capsys):
    """A library's warning that is not numerical (Dask's "port 8787 is already in use" when two
    campaigns start at once) reaches the caller once, and main returns. It was re-emitted inside
    the block that records warnings, onto the list being walked: main never returned (found as a
    test-suite hang when two workers ran campaigns side by side)."""
    import threading
    import warnings

    from components.cli import cosim

    def warns(args):
        warnings.warn("Port 8787 is already in use", UserWarning)
        return 0

    monkeypatch.setattr(cosim, "_cmd_tumble", warns)
    outcome = {}

    def run():
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            outcome["code"] = main(["tumble"])
        outcome["seen"] = [str(w.message) for w in seen]

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(20.0)
    assert not t.is_alive(), "main did not return after a UserWarning"
    assert outcome["code"] == 0 and outcome["seen"] == ["Port 8787 is already in use"]


@pytest.mark.parametrize("name, value", [("CALBENCH_SPILL_SAMPLES", "1e6"), ("CALBENCH_SPILL_SAMPLES", "-1"),
                                         ("CALBENCH_WORKERS", "abc"), ("CALBENCH_WORKERS", "0")])
def test_a_bad_environment_variable_is_bad_input_named(logs, capsys, monkeypatch, name, value):
    # (a traceback and exit 1 before, with --json printing nothing)
    monkeypatch.setenv(name, value)
    code, doc, text = _json_stdout(capsys, ["calibrate", str(logs / "example"), "--out", str(logs / "env.json")])
    assert code == 2 and doc["exit_code"] == 2
    assert f"environment variable {name}={value!r}" in doc["error"] and "Traceback" not in text
