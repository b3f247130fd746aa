"""The report and files of another run: a result or baseline fitted to another log is refitted on
this one first (said, and recorded with its file and SHA-256), as compare and diagnose do; a
truth file of another run of the same schedule is refused by the samples' SHA-256 the truth now
records. Before, the page showed another log's values on this log's residuals (a ladder from
1.402 to 1.017 beside sections saying 1.636 and 3.056) and judged against the wrong truth
(-24.6 σ) with exit 0. And the page's noise model keeps the white noise (it was all zeros)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from components.cli import main
from components.model.result import CalibrationResult

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "examples" / "scenarios" / "six_position.toml"


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("two")
    for name, seed in (("a", 1), ("b", 2)):
        assert main(["simulate", str(SCENARIO), "--out", str(d / name), "--dwell", "10", "--seed", str(seed)]) == 0
        assert main(["calibrate", str(d / name), "--out", str(d / f"{name}_res.json")]) == 0
    return d


def test_a_model_of_another_log_is_refitted_before_the_page(two_runs, capsys):
    d = two_runs
    capsys.readouterr()
    assert main(["report", str(d / "b"), "--model", str(d / "a_res.json"), "--baseline", str(d / "a_res.json"),
                 "--out", str(d / "page.html")]) == 0
    out = capsys.readouterr().out
    assert "not to this log: refitting its effects on this log first" in out
    page = json.loads((d / "page.json").read_text())
    own = CalibrationResult.load(d / "b_res.json")   # b calibrated on itself: what the refit must give
    after = page["views"][-1]["comparison"]
    assert after["chi2_per_dof"] == pytest.approx(own.fit["chi2_per_dof"], rel=1e-6)   # (its iterations: 2e-9)
    base = next(m for m in page["provenance"]["models"].values() if m.get("refitted_on_this_log"))
    assert base["file"] == str(d / "a_res.json") and len(base["sha256"]) == 64


def test_a_truth_of_another_run_of_the_same_schedule_is_refused(two_runs, capsys):
    d = two_runs
    truth = json.loads((d / "b.truth.json").read_text())
    assert list(truth["samples_sha256"]) == ["csv"]
    err_code = main(["report", str(d / "b"), "--model", str(d / "b_res.json"), "--truth", str(d / "a.truth.json"),
                     "--out", str(d / "t.html")])
    assert err_code == 2
    assert "the truth of another run's samples (csv " in capsys.readouterr().err
    assert main(["report", str(d / "b"), "--model", str(d / "b_res.json"), "--truth", str(d / "b.truth.json"),
                 "--out", str(d / "ok.html")]) == 0
    twin = json.loads((d / "ok.json").read_text())
    # every fitted parameter against the truth, 0 where the scenario injected nothing
    rows = {r["parameter"]: r for r in twin["truth_values"]}
    res = CalibrationResult.load(d / "b_res.json")
    assert set(res.values) <= set(rows)
    for p in set(res.values) - set(truth["effects"]):
        assert rows[p]["truth"] == 0.0
    assert twin["provenance"]["truth"]["seed"] == 2 and len(twin["provenance"]["truth"]["sha256"]) == 64


def test_the_pages_noise_model_has_the_white_noise(two_runs):
    d = two_runs
    assert main(["report", str(d / "b"), "--model", str(d / "b_res.json"), "--out", str(d / "n.html")]) == 0
    noise = json.loads((d / "n.json").read_text())["noise"]["channels"]
    # the scenario's 0.001 deg/sqrt(h) and 5 ug/sqrt(Hz), within 10 %
    arw = noise["gyro_x"]["white"]["display"][0]
    vrw = noise["acc_z"]["white"]["display"][0]
    assert arw == pytest.approx(0.001, rel=0.1) and vrw == pytest.approx(5.0, rel=0.1)


def test_add_refuses_an_effect_the_model_has(two_runs, capsys):
    """add of an effect already in the model refitted the same model and put a rung "+ gyro.bias"
    on the ladder that changed nothing."""
    d = two_runs
    capsys.readouterr()
    assert main(["add", str(d / "b"), "--model", str(d / "b_res.json"), "--effect", "gyro.bias",
                 "--out", str(d / "dup.json")]) == 2
    assert "--effect gyro.bias: already in the model" in capsys.readouterr().err
    assert not (d / "dup.json").exists()
