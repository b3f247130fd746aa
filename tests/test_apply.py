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



def _zero_result(tmp_path, conformance):
    import dataclasses

    assert main(["calibrate", str(conformance / "example"), "--out", str(tmp_path / "r.json")]) == 0
    res = CalibrationResult.load(tmp_path / "r.json")
    return res, dataclasses.replace(res, values={k: 0.0 for k in res.values})


def test_a_zero_model_leaves_a_jittered_clocks_rates_as_they_are(conformance, tmp_path):
    """Rates logged over a measured, jittered clock (imu.timing 'measured', ±20 % intervals):
    correcting with a model whose every parameter is 0 returns them unchanged. The correction took
    every interval as the nominal one, and a zero model changed the rates by up to 40 %."""
    import dataclasses

    import numpy as np

    from components.logs.logfile import read_log
    from components.model.correct import correct_log

    log = read_log(conformance / "example")
    rng = np.random.default_rng(1)
    t = np.sort(log.time + rng.uniform(-0.2, 0.2, log.n) * log.dt)
    jittered = dataclasses.replace(log, timing="measured", time=t, gyro=log.gyro_increment() / log.dt,
                                   gyro_output="rate", acc=log.acc_increment() / log.dt, acc_output="specific_force")
    _, zero = _zero_result(tmp_path, conformance)
    out = correct_log(jittered, zero)
    assert np.allclose(out.gyro, jittered.gyro, rtol=1e-12, atol=1e-15)
    assert np.allclose(out.acc, jittered.acc, rtol=1e-12, atol=1e-12)


def test_the_correction_in_pieces_is_the_correction_in_one(conformance, tmp_path):
    """A long log is corrected a piece at a time, each with a margin for the lever arm's
    differences (over three passes, coupled through the g-sensitivity): with a lever arm, a
    g-sensitivity and a drift in the model, pieces of 997 samples give the bits of one piece."""
    import dataclasses

    import numpy as np

    from components.logs.logfile import read_log
    from components.model.correct import correct_log

    log = read_log(conformance / "example")
    res, _ = _zero_result(tmp_path, conformance)
    values = {**res.values, "acc.lever.x.y": 0.05, "acc.lever.z.x": -0.03, "gyro.gsens.xz": 2e-6,
              "acc.drift.y": 1e-7, "acc.k2.z": 4e-5}
    model = dataclasses.replace(res, values=values, effects=list(dict.fromkeys(
        list(res.effects) + ["acc.lever", "gyro.gsens", "acc.drift", "acc.k2"])))
    whole = correct_log(log, model, pieces=10**9)
    cut = correct_log(log, model, pieces=997)
    assert np.array_equal(whole.gyro, cut.gyro) and np.array_equal(whole.acc, cut.acc)
    assert not np.array_equal(whole.acc, log.acc)
    # rates over a measured, jittered clock: each piece takes its samples' own intervals
    rng = np.random.default_rng(2)
    t = np.sort(log.time + rng.uniform(-0.2, 0.2, log.n) * log.dt)
    jittered = dataclasses.replace(log, timing="measured", time=t, gyro=log.gyro_increment() / log.dt,
                                   gyro_output="rate", acc=log.acc_increment() / log.dt, acc_output="specific_force")
    whole = correct_log(jittered, model, pieces=10**9)
    cut = correct_log(jittered, model, pieces=997)
    assert np.array_equal(whole.gyro, cut.gyro) and np.array_equal(whole.acc, cut.acc)
    assert not np.array_equal(whole.acc, jittered.acc)


def test_a_parquet_log_rewritten_a_row_group_at_a_time_is_the_log_corrected_whole(conformance, tmp_path, monkeypatch):
    """Parquet to Parquet, apply reads only what the correction needs (on disk, as a long log's)
    and rewrites the file a row group at a time; its samples, every other column (an extra one
    included) and its metadata are those of the correction of the whole log written as CSV."""
    import numpy as np
    import pyarrow.parquet as pq

    from components.logs.logfile import read_log, write_log

    raw = read_log(conformance / "example")
    raw.extra["humidity"] = np.linspace(30.0, 40.0, raw.n)
    write_log(tmp_path / "raw", raw, fmt="parquet")
    pq.write_table(pq.read_table(tmp_path / "raw.parquet"), tmp_path / "raw.parquet", row_group_size=7000)
    assert main(["calibrate", str(tmp_path / "raw"), "--out", str(tmp_path / "r.json")]) == 0
    assert main(["apply", str(tmp_path / "raw.parquet"), "--result", str(tmp_path / "r.json"),
                 "--out", str(tmp_path / "whole.csv")]) == 0
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
    assert main(["apply", str(tmp_path / "raw.parquet"), "--result", str(tmp_path / "r.json"),
                 "--out", str(tmp_path / "rows")]) == 0
    monkeypatch.delenv("CALBENCH_SPILL_SAMPLES")
    whole, rows = read_log(tmp_path / "whole.csv"), read_log(tmp_path / "rows.parquet")
    assert pq.ParquetFile(tmp_path / "rows.parquet").num_row_groups > 1
    for k in ("time", "gyro", "acc", "temperature"):
        assert np.array_equal(getattr(whole, k), getattr(rows, k)), k
    assert rows.segment.tolist() == whole.segment.tolist()
    assert np.array_equal(rows.extra["humidity"], raw.extra["humidity"])
    assert all(np.array_equal(rows.gimbal[a], whole.gimbal[a]) for a in whole.axis_names)
    assert rows.metadata() == whole.metadata()
    assert not np.array_equal(rows.acc, raw.acc)
