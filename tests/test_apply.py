"""apply refuses a system-level result whose filter failed its own consistency checks (the
filter said "do not use these estimates"), unless told to; a consistent result corrects the log
so that a new calibration of it finds the parameters at zero."""
from __future__ import annotations

import json

from components.cli import main
from components.model.result import CalibrationResult


def test_an_inconsistent_filters_result_is_not_applied_unless_asked(conformance, tmp_path, capsys):
    log = conformance / "example"
    assert main(["calibrate", str(log), "--out", str(tmp_path / "r.json")]) == 0
    doc = json.loads((tmp_path / "r.json").read_text())
    doc["fit"]["stages"] = [{"name": "19-position", "kind": "kf", "consistency": {
        "ok": False, "problems": ["stage '19-position': the velocity innovations exceed what the filter predicts"]}}]
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["apply", str(log), "--result", str(tmp_path / "bad.json"), "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "found itself inconsistent (stage '19-position'" in err and "--accept-inconsistent" in err
    assert not (tmp_path / "c.json").exists()
    assert main(["apply", str(log), "--result", str(tmp_path / "bad.json"), "--out", str(tmp_path / "c"),
                 "--accept-inconsistent"]) == 0
    # the consistent result: the corrected log calibrates to zero within a small fraction of σ
    assert main(["apply", str(log), "--result", str(tmp_path / "r.json"), "--out", str(tmp_path / "ok")]) == 0
    assert main(["calibrate", str(tmp_path / "ok"), "--out", str(tmp_path / "r2.json")]) == 0
    again = CalibrationResult.load(tmp_path / "r2.json")
    assert all(abs(again.values[p]) < 0.05 * again.sigmas[p] for p in again.values), again.values


def test_the_corrected_log_keeps_the_raw_logs_format_unless_told(conformance, tmp_path, capsys):
    import numpy as np

    from components.logs.logfile import read_log, write_log

    raw = read_log(conformance / "example")
    write_log(tmp_path / "raw", raw, fmt="parquet")
    assert main(["calibrate", str(tmp_path / "raw"), "--out", str(tmp_path / "r.json")]) == 0
    # a Parquet log gives a Parquet log; a .csv --out or --format csv gives CSV
    assert main(["apply", str(tmp_path / "raw"), "--result", str(tmp_path / "r.json"), "--out", str(tmp_path / "p")]) == 0
    assert (tmp_path / "p.parquet").exists() and not (tmp_path / "p.csv").exists()
    assert main(["apply", str(tmp_path / "raw.parquet"), "--result", str(tmp_path / "r.json"),
                 "--out", str(tmp_path / "c.csv")]) == 0
    assert (tmp_path / "c.csv").exists() and not (tmp_path / "c.parquet").exists()
    # the same corrected numbers either way (each format round-trips doubles exactly)
    p, c = read_log(tmp_path / "p"), read_log(tmp_path / "c")
    assert np.array_equal(p.gyro, c.gyro) and np.array_equal(p.acc, c.acc)
    # and not the raw ones: the correction was applied
    assert not np.array_equal(p.acc, raw.acc)
    capsys.readouterr()
    assert main(["apply", str(tmp_path / "raw"), "--result", str(tmp_path / "r.json"), "--out", str(tmp_path / "x.csv"),
                 "--format", "parquet"]) == 2
    assert "--out" in capsys.readouterr().err and not (tmp_path / "x.json").exists()

