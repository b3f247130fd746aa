"""calbench-log/1: the shared conformance vectors load and agree with an independent forward
model; write -> read is bit-exact; a simulated run becomes a log; every rule of the spec is
enforced with an error naming the file and the row or key."""
from __future__ import annotations

import json
import math
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from components.errors import LogFormatError
from components.logs.logfile import MeasurementLog, read_log, write_log

EARTH_RATE = 7.2921151467e-5  # domain.md §2


def bits(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


# ------------------------------------------------------------------ shared examples
@pytest.fixture(scope="module")
def ideal(conformance: Path) -> MeasurementLog:
    return read_log(conformance / "ideal")


@pytest.mark.parametrize("name", ["ideal", "example"])
def test_shared_examples_load(name, conformance):
    log = read_log(conformance / f"{name}.csv")
    meta = json.loads((conformance / f"{name}.json").read_text())
    assert log.n == 83300 == 416.5 * 200
    assert log.axis_names == ["outer", "middle", "inner"]
    assert np.array_equal(log.axis_vectors, [[0, 0, 1], [1, 0, 0], [0, 0, 1]])
    assert log.latitude_deg == 39.9 and log.latitude == math.radians(39.9)
    assert log.height_m == 50.0 and log.gravity_mps2 == meta["site"]["gravity_mps2"] == log.gravity
    assert log.sample_rate_hz == 200.0 and log.dt == 0.005
    assert log.gyro_output == log.acc_output == "increment"
    assert log.description == meta["description"]
    assert log.time[0] == 0.005 and log.time[-1] == 416.5
    assert log.segment[0] == "pos01" and log.segment[-1] == "restZh4"
    assert log.temperature is not None and log.command == {} and log.extra == {}
    assert log.gyro_increment() is log.gyro  # increments are taken as they are
    # the first data line, parsed independently
    with open(conformance / f"{name}.csv") as f:
        head = f.readline().strip().split(",")
        first = dict(zip(head, f.readline().strip().split(",")))
    assert log.acc[0, 2] == float(first["acc_z"]) and log.gyro[0, 1] == float(first["gyro_y"])


def _rodrigues(a: np.ndarray, th: np.ndarray) -> np.ndarray:
    """(N, 3, 3) active rotations by th about unit axis a."""
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def test_ideal_vector_static_samples_match_forward_model(ideal):
    """domain.md §1-§3 with numpy only: C_p^b0 = R(a1,θ1) R(a2,θ2) R(a3,θ3), base = ENU,
    ω = C_n^p [0, Ω cos L, Ω sin L], f = C_n^p [0, 0, g]; at rest the increments are ω·dt, f·dt."""
    ang = ideal.angles
    static = np.zeros(ideal.n, bool)
    static[1:-1] = (ang[1:-1] == ang[:-2]).all(1) & (ang[1:-1] == ang[2:]).all(1)
    idx = np.nonzero(static)[0]
    assert len(idx) > 50000  # 6 x 40 s + rests at 200 Hz
    C = np.broadcast_to(np.eye(3), (len(idx), 3, 3))
    for k, a in enumerate(ideal.axis_vectors):
        C = C @ _rodrigues(a, ang[idx, k])
    L, g, dt = ideal.latitude, ideal.gravity_mps2, 1.0 / ideal.sample_rate_hz
    w_n = np.array([0.0, EARTH_RATE * math.cos(L), EARTH_RATE * math.sin(L)])
    f_n = np.array([0.0, 0.0, g])
    w_p = np.einsum("nji,j->ni", C, w_n) * dt  # C^T
    f_p = np.einsum("nji,j->ni", C, f_n) * dt
    eg = np.linalg.norm(ideal.gyro_increment()[idx] - w_p, axis=1) / np.linalg.norm(w_p, axis=1)
    ea = np.linalg.norm(ideal.acc_increment()[idx] - f_p, axis=1) / np.linalg.norm(f_p, axis=1)
    print(f"ideal vector, {len(idx)} static samples: max relative deviation gyro {eg.max():.3g}, "
          f"acc {ea.max():.3g}")
    assert eg.max() < 1e-12 and ea.max() < 1e-12
    # the six attitudes are all visited: each body axis up and down
    up = np.sign(np.round(f_p / np.linalg.norm(f_p, axis=1)[:, None], 6))
    assert len({tuple(r) for r in up}) == 6


# ------------------------------------------------------------------ writing
@pytest.mark.parametrize("write_rows", [None, 997])
def test_roundtrip_bit_identical(ideal, tmp_path, write_rows, monkeypatch):
    """Also written 997 rows at a time (a long log is): the same values, the same CSV text."""
    from components.logs import logfile

    ideal.extra["extra_note"] = np.arange(ideal.n, dtype=float) * 0.1  # extra columns survive too
    try:
        write_log(tmp_path / "one", ideal, fmt="csv")
        if write_rows:
            monkeypatch.setattr(logfile, "WRITE_ROWS", write_rows)
        write_log(tmp_path / "rt", ideal, fmt="both")
    finally:
        del ideal.extra["extra_note"]
    assert (tmp_path / "rt.csv").read_bytes() == (tmp_path / "one.csv").read_bytes()
    for f in ("rt.csv", "rt.parquet"):
        back = read_log(tmp_path / f)
        assert bits(back.time).tolist() == bits(ideal.time).tolist()
        for a in ideal.axis_names:
            assert np.array_equal(bits(back.gimbal[a]), bits(ideal.gimbal[a]))
        assert np.array_equal(bits(back.gyro), bits(ideal.gyro))
        assert np.array_equal(bits(back.acc), bits(ideal.acc))
        assert np.array_equal(bits(back.temperature), bits(ideal.temperature))
        assert back.segment.tolist() == ideal.segment.tolist()
        assert np.array_equal(back.extra["extra_note"], np.arange(ideal.n) * 0.1)
        assert back.metadata() == ideal.metadata()


def test_writer_refuses_a_broken_log(ideal, tmp_path):
    t = ideal.time.copy()
    t[100] = t[99]
    bad = MeasurementLog(**{**ideal.__dict__, "time": t})
    with pytest.raises(LogFormatError, match=r"sample 101, column 'time'.*strictly increasing"):
        write_log(tmp_path / "x", bad)
    assert not (tmp_path / "x.csv").exists()


def test_output_kinds_convert_to_increments():
    n, fs = 4, 100.0
    base = dict(time=np.arange(1, n + 1) / fs, gimbal={"a": np.zeros(n)}, axis_names=["a"],
                axis_vectors=np.array([[0.0, 0.0, 1.0]]), sample_rate_hz=fs)
    x = np.arange(12.0).reshape(n, 3)
    log = MeasurementLog(gyro=x, acc=x, gyro_output="rate", acc_output="specific_force", **base)
    assert np.array_equal(log.gyro_increment(), x * 0.01) and np.array_equal(log.acc_increment(), x * 0.01)
    log = MeasurementLog(gyro=x, acc=x, gyro_output="counts", acc_output="counts", gyro_count_rad=1e-6,
                         acc_count_mps=2e-5, **base)
    assert np.array_equal(log.gyro_increment(), x * 1e-6) and np.array_equal(log.acc_increment(), x * 2e-5)
    log.validate()


def test_large_log_loads_fast(tmp_path):
    """6 min at 1 kHz (360 000 rows, full-precision doubles); 1 h at 1 kHz scales linearly."""
    n, fs = 360_000, 1000.0
    rng = np.random.default_rng(3)
    log = MeasurementLog(time=np.arange(1, n + 1) / fs,
                         gimbal={a: rng.standard_normal(n) for a in ("outer", "middle", "inner")},
                         gyro=rng.standard_normal((n, 3)) * 1e-6, acc=rng.standard_normal((n, 3)) * 1e-2,
                         axis_names=["outer", "middle", "inner"],
                         axis_vectors=np.array([[0.0, 0, 1], [1, 0, 0], [0, 0, 1]]), sample_rate_hz=fs,
                         segment=np.array(["seg%d" % (i // 60000) for i in range(n)], dtype=object))
    write_log(tmp_path / "big", log)
    t0 = time.perf_counter()
    back = read_log(tmp_path / "big")
    took = time.perf_counter() - t0
    print(f"read {n} rows in {took:.2f} s")
    assert np.array_equal(back.gyro, log.gyro) and back.n == n
    assert took < 5.0


# ------------------------------------------------------------------ from an orchestrator run
def test_log_from_orchestrator_run(tmp_path):
    import components  # noqa: F401
    from components.logs.recording import log_from_recording
    from orchestrator.master import simulate
    from orchestrator.system import system_from_dict

    lat = 0.61
    sysd = {
        "system": {"name": "short", "step": 0.005, "stop": 1.0},
        "units": {
            "ctrl": {"component": "components.control.sequencer:AttitudeSequence",
                     "config": {"sequence": [[0.0, 0.0, 0.0, 0.0], [0.3, 0.0, 0.2, 0.0]]}},
            "table": {"fmu": "builtin:turntable", "role": "turntable",
                      "parameters": {"site.latitude": lat, "site.height": 120.0}},
            "imu": {"fmu": "builtin:imu", "role": "imu", "role_options": {"gyro_output": "rate"}},
        },
        "connections": [{"from": f"ctrl.{a}.{v}", "to": f"table.{a}.{v}"}
                        for a in ("outer", "middle", "inner") for v in ("angle_cmd", "mode", "rate_cmd")]
        + [{"from": f"table.plate.{v}", "to": f"imu.{v}"} for v in ("omega", "f", "alpha")],
        "record": {"signals": ["table.outer.angle", "table.middle.angle", "table.inner.angle",
                               "table.middle.angle_cmd", "imu.gyro", "imu.acc", "imu.temperature"]},
    }
    rec = simulate(system_from_dict(sysd))
    log = log_from_recording(rec, segment_signal="table.middle.angle_cmd",
                             segment_labels=lambda v: "level" if v == 0 else "tilted")
    write_log(tmp_path / "run", log)
    back = read_log(tmp_path / "run")
    assert back.latitude_deg == math.degrees(lat) and back.height_m == 120.0 and back.gravity_mps2 is None
    assert back.axis_names == ["outer", "middle", "inner"]
    assert np.array_equal(back.axis_vectors, [[0, 0, 1], [1, 0, 0], [0, 0, 1]])  # builtin defaults
    assert back.sample_rate_hz == 200.0 and back.gyro_output == "rate" and back.acc_output == "increment"
    assert back.n == 200 and back.time[0] == 0.005 and back.time[-1] == 1.0
    assert np.array_equal(back.gimbal["middle"], rec["table.middle.angle"][1:])
    assert np.array_equal(back.gyro[:, 2], rec["imu.gyro.z"][1:])
    assert list(back.command) == ["middle"] and back.command["middle"][-1] == 0.2
    assert back.segment[0] == "level" and back.segment[-1] == "tilted"
    # the table tilts 0.2 rad about x: at the end gravity is along +z and +y of the plate
    f = back.specific_force()[-1]
    assert abs(math.atan2(f[1], f[2]) - 0.2) < 1e-4


# ------------------------------------------------------------------ every rule of the spec
ROWS = 400  # a copy of the first 400 samples of ideal (pos01, static)


@pytest.fixture(scope="module")
def ideal_head(conformance: Path) -> tuple[list[str], dict]:
    with open(conformance / "ideal.csv") as f:
        lines = [next(f) for _ in range(ROWS + 1)]
    return lines, json.loads((conformance / "ideal.json").read_text())


def _edit_col(lines, col, row, value):
    head = lines[0].strip().split(",")
    j = head.index(col)
    cells = lines[row].rstrip("\n").split(",")
    cells[j] = value
    lines[row] = ",".join(cells) + "\n"


def _drop_col(lines, col):
    j = lines[0].strip().split(",").index(col)
    return [",".join(c for k, c in enumerate(ln.rstrip("\n").split(",")) if k != j) + "\n" for ln in lines]


def _add_col(lines, name, value="0"):
    return [lines[0].rstrip("\n") + f",{name}\n"] + [ln.rstrip("\n") + f",{value}\n" for ln in lines[1:]]


def _csv_case(fn):
    def edit(lines, meta):
        return fn(lines) or lines, meta
    return edit


def _json_case(fn):
    def edit(lines, meta):
        fn(meta)
        return lines, meta
    return edit


def _swap_time(lines):
    _edit_col(lines, "time", 50, "0.245")


def _gap(lines):
    del lines[120]


def _jitter_ok(lines):
    _edit_col(lines, "time", 30, "0.15004")  # 0.8 % of the interval: within the tolerance


CASES = {
    # columns
    "missing column": (_csv_case(lambda ls: _drop_col(ls, "gyro_y")), "csv", r"missing column 'gyro_y'"),
    "metadata axis not in data": (_csv_case(lambda ls: _drop_col(ls, "gimbal_inner")), "csv",
                                  r"missing column 'gimbal_inner' \(table.axes names axis 'inner'\)"),
    "data axis not in metadata": (_csv_case(lambda ls: _add_col(ls, "gimbal_tilt")), "csv",
                                  r"column 'gimbal_tilt' is for axis 'tilt'.*does not name"),
    "command axis not in metadata": (_csv_case(lambda ls: _add_col(ls, "command_tilt")), "csv",
                                     r"column 'command_tilt' is for axis 'tilt'"),
    "metadata axis added": (_json_case(lambda m: m["table"]["axes"].append({"name": "fourth", "axis": [0, 1, 0]})),
                            "csv", r"missing column 'gimbal_fourth'"),
    "duplicate column": (_csv_case(lambda ls: _add_col(ls, "acc_x")), "csv", r"column 'acc_x' appears twice"),
    # values
    "NaN": (_csv_case(lambda ls: _edit_col(ls, "acc_x", 10, "nan")), "csv",
            r"data row 10 \(line 11\), column 'acc_x'.*not finite"),
    "Inf": (_csv_case(lambda ls: _edit_col(ls, "gimbal_middle", 7, "-inf")), "csv",
            r"data row 7 \(line 8\), column 'gimbal_middle'.*not finite"),
    "overflow": (_csv_case(lambda ls: _edit_col(ls, "gyro_z", 3, "1e400")), "csv",
                 r"data row 3 \(line 4\), column 'gyro_z'.*not finite"),
    "non-numeric": (_csv_case(lambda ls: _edit_col(ls, "gyro_x", 25, "0.1a")), "csv",
                    r"data row 25 \(line 26\), column 'gyro_x': '0.1a' is not a number"),
    "decimal comma": (_csv_case(lambda ls: _edit_col(ls, "temperature", 12, "20,001")), "csv",
                      r"data row 12 \(line 13\): 13 field\(s\); expected 12"),
    "empty value": (_csv_case(lambda ls: _edit_col(ls, "acc_y", 44, "")), "csv",
                    r"data row 44 \(line 45\), column 'acc_y': empty value"),
    "blank line": (_csv_case(lambda ls: ls.insert(5, "\n")), "csv", r"data row 5 \(line 6\): blank line"),
    # (an empty label was read as a label of its own, a segment of one sample)
    "empty label": (_csv_case(lambda ls: _edit_col(ls, "segment", 60, "")), "csv",
                    r"data row 60 \(line 61\), column 'segment': empty value; expected text"),
    "no samples": (_csv_case(lambda ls: ls[1:].clear() or ls[:1]), "csv", r"no samples"),
    "time not increasing": (_csv_case(_swap_time), "csv",
                            r"data row 50 \(line 51\), column 'time'.*strictly increasing"),
    "gap": (_csv_case(_gap), "csv", r"data row 120 \(line 121\), column 'time': interval 0.01.*expected "
                                    r"1/sample_rate_hz = 0.005"),
    "counts not whole": (_json_case(lambda m: m["imu"].update(gyro_output="counts", gyro_count_rad=1e-7)), "csv",
                         r"data row 1 \(line 2\), column 'gyro_y'.*not a whole number"),
    # metadata
    "format v3": (_json_case(lambda m: m.update(format="calbench-log/3")), "json",
                  r"key 'format' = 'calbench-log/3': expected 'calbench-log/1' or 'calbench-log/2' \(a newer"),
    "v2 key in v1": (_json_case(lambda m: m.update(exclude=[[0, 1]])), "json",
                     r"key 'exclude' \(what to leave out\) belongs to 'calbench-log/2'"),
    "format missing": (_json_case(lambda m: m.pop("format")), "json", r"missing key 'format'"),
    "latitude missing": (_json_case(lambda m: m["site"].pop("latitude_deg")), "json",
                         r"missing key 'site.latitude_deg'"),
    "gravity key missing": (_json_case(lambda m: m["site"].pop("gravity_mps2")), "json",
                            r"missing key 'site.gravity_mps2'"),
    "sample rate missing": (_json_case(lambda m: m["imu"].pop("sample_rate_hz")), "json",
                            r"missing key 'imu.sample_rate_hz'"),
    "sample rate negative": (_json_case(lambda m: m["imu"].update(sample_rate_hz=-200)), "json",
                             r"key 'imu.sample_rate_hz' = -200.0: expected a positive"),
    "axes missing": (_json_case(lambda m: m["table"].pop("axes")), "json", r"missing key 'table.axes'"),
    "axis vector missing": (_json_case(lambda m: m["table"]["axes"][1].pop("axis")), "json",
                            r"missing key 'table.axes\[1\].axis'"),
    "unknown gyro kind": (_json_case(lambda m: m["imu"].update(gyro_output="deg/h")), "json",
                          r"key 'imu.gyro_output' = 'deg/h': unknown output kind"),
    "unknown acc kind": (_json_case(lambda m: m["imu"].update(acc_output="g")), "json",
                         r"key 'imu.acc_output' = 'g': unknown output kind"),
    "counts with null weight": (_json_case(lambda m: m["imu"].update(acc_output="counts")), "json",
                                r"key 'imu.acc_count_mps' is null but imu.acc_output is 'counts'"),
    "axis not unit": (_json_case(lambda m: m["table"]["axes"][2].update(axis=[0, 0, 1 + 1e-8])), "json",
                      r"key 'table.axes\[2\].axis'.*expected a unit vector"),
    "axis zero": (_json_case(lambda m: m["table"]["axes"][0].update(axis=[0, 0, 0])), "json",
                  r"key 'table.axes\[0\].axis'.*zero vector"),
    "latitude out of range": (_json_case(lambda m: m["site"].update(latitude_deg=95.0)), "json",
                              r"key 'site.latitude_deg' = 95.0: expected a latitude in \[-90, 90\]"),
    "latitude not a number": (_json_case(lambda m: m["site"].update(latitude_deg="39.9N")), "json",
                              r"key 'site.latitude_deg' = '39.9N'"),
}


def _write_case(tmp_path, ideal_head, edit) -> Path:
    lines, meta = list(ideal_head[0]), json.loads(json.dumps(ideal_head[1]))
    lines, meta = edit(lines, meta)
    (tmp_path / "bad.csv").write_text("".join(lines))
    (tmp_path / "bad.json").write_text(json.dumps(meta))
    return tmp_path / "bad"


@pytest.mark.parametrize("case", list(CASES))
def test_rule_violation_is_refused(case, tmp_path, ideal_head):
    edit, where, msg = CASES[case]
    stem = _write_case(tmp_path, ideal_head, edit)
    with pytest.raises(LogFormatError) as e:
        read_log(stem)
    text = str(e.value)
    assert str(tmp_path / f"bad.{where}") in text, text
    import re
    assert re.search(msg, text), text


def test_unedited_copy_and_tolerated_edits_load(tmp_path, ideal_head):
    stem = _write_case(tmp_path, ideal_head, lambda ls, m: (ls, m))
    assert read_log(stem).n == ROWS
    stem = _write_case(tmp_path, ideal_head, _csv_case(_jitter_ok))
    assert read_log(stem).time[29] == 0.15004
    stem = _write_case(tmp_path, ideal_head, _json_case(
        lambda m: m["table"]["axes"][2].update(axis=[0, 0, 1 + 1e-12])))
    assert read_log(stem).n == ROWS
    # unknown extra columns and keys are kept
    stem = _write_case(tmp_path, ideal_head, lambda ls, m: (_add_col(ls, "humidity", "41.5"),
                                                             {**m, "operator": "A. N. Other"}))
    log = read_log(stem)
    assert np.all(log.extra["humidity"] == 41.5) and log.metadata()["operator"] == "A. N. Other"


def test_missing_files(tmp_path, conformance):
    shutil.copy(conformance / "ideal.json", tmp_path / "only.json")
    with pytest.raises(LogFormatError, match=r"only\.csv: sample file does not exist"):
        read_log(tmp_path / "only")
    (tmp_path / "nometa.csv").write_text("time\n")
    with pytest.raises(LogFormatError, match=r"nometa\.json: metadata file does not exist"):
        read_log(tmp_path / "nometa.csv")


def test_invalid_json(tmp_path, ideal_head):
    stem = _write_case(tmp_path, ideal_head, lambda ls, m: (ls, m))
    (tmp_path / "bad.json").write_text('{"format": "calbench-log/1",\n "site": }')
    with pytest.raises(LogFormatError, match=r"bad\.json: not valid JSON \(line 2"):
        read_log(stem)


def test_parquet_rules(tmp_path, ideal_head):
    import pyarrow as pa
    import pyarrow.parquet as pq

    stem = _write_case(tmp_path, ideal_head, lambda ls, m: (ls, m))
    log = read_log(stem)
    cols = log.columns()
    cols["acc_z"] = cols["acc_z"].copy()
    cols["acc_z"][41] = np.nan
    (tmp_path / "bad.csv").unlink()
    pq.write_table(pa.table({k: (pa.array(list(v)) if v.dtype == object else v) for k, v in cols.items()}),
                   tmp_path / "bad.parquet")
    with pytest.raises(LogFormatError, match=r"bad\.parquet: row 42, column 'acc_z'.*not finite"):
        read_log(stem)
    del cols["gyro_x"]
    pq.write_table(pa.table({k: (pa.array(list(v)) if v.dtype == object else v) for k, v in cols.items()}),
                   tmp_path / "bad.parquet")
    with pytest.raises(LogFormatError, match=r"bad\.parquet: missing column 'gyro_x'"):
        read_log(stem)


def test_parquet_without_a_segment_column(tmp_path, ideal):
    """segment is optional: a Parquet log without it (what `calbench import` writes from a
    logger file without labels) reads, bit-identical in its numbers."""
    import pyarrow.parquet as pq

    write_log(tmp_path / "nolabel", ideal, fmt="parquet")
    table = pq.read_table(tmp_path / "nolabel.parquet")
    pq.write_table(table.drop_columns(["segment"]), tmp_path / "nolabel.parquet")
    meta = json.loads((tmp_path / "nolabel.json").read_text())
    meta.pop("segments", None)
    meta.pop("exclude", None)
    (tmp_path / "nolabel.json").write_text(json.dumps(meta))
    back = read_log(tmp_path / "nolabel.parquet")
    assert back.segment is None
    assert np.array_equal(bits(back.gyro), bits(ideal.gyro))


def test_a_lean_read_holds_what_the_estimators_use_bit_identical(tmp_path, ideal):
    """read_log(lean=True), as calibrate, compare, diagnose and noise read: the commands and
    extra columns are not read; every column the estimators use is bit-identical to the file's,
    and the gimbal angles are one array (not stacked a second time)."""
    ideal.extra["extra_note"] = np.arange(ideal.n, dtype=float)
    ideal.command.update({a: ideal.gimbal[a] + 1e-6 for a in ideal.axis_names})
    try:
        write_log(tmp_path / "lean", ideal, fmt="both")
    finally:
        del ideal.extra["extra_note"]
        ideal.command.clear()
    for f in ("lean.csv", "lean.parquet"):
        full = read_log(tmp_path / f)
        assert set(full.command) == set(ideal.axis_names) and "extra_note" in full.extra
        back = read_log(tmp_path / f, lean=True)
        assert back.command == {} and back.extra == {}
        assert np.array_equal(bits(back.time), bits(ideal.time))
        assert np.array_equal(bits(back.angles), bits(ideal.angles))
        assert np.array_equal(bits(back.gyro), bits(ideal.gyro))
        assert np.array_equal(bits(back.acc), bits(ideal.acc))
        assert np.array_equal(bits(back.temperature), bits(ideal.temperature))
        assert back.segment.tolist() == ideal.segment.tolist()
        if f.endswith(".parquet"):
            assert np.shares_memory(back.angles, back.gimbal[ideal.axis_names[0]])


def test_a_bad_value_beyond_the_first_piece_is_named_at_its_row(tmp_path, ideal_head, monkeypatch):
    """The values are checked a piece of rows at a time (components.logs.spill.PIECE): the row
    named is the file's, not the piece's."""
    from components.logs import spill

    monkeypatch.setattr(spill, "PIECE", 64)
    stem = _write_case(tmp_path, ideal_head, _csv_case(lambda lines: _edit_col(lines, "gyro_y", 150, "inf")))
    with pytest.raises(LogFormatError, match=r"data row 150 \(line 151\), column 'gyro_y'.*not finite"):
        read_log(stem)


def test_a_count_that_is_not_whole_beyond_the_first_piece_is_named_at_its_row(ideal, tmp_path, monkeypatch):
    """Pulse counts are checked for whole numbers a piece at a time: the row named is the log's
    first offending one in the first offending column, wherever the pieces fall."""
    from components.logs import spill

    monkeypatch.setattr(spill, "PIECE", 64)
    counts = np.round(ideal.gyro / 1e-7)
    counts[149, 1] += 0.5   # sample 150, in the third piece
    counts[9, 2] += 0.25    # an earlier sample of a later column: named after gyro_y
    bad = MeasurementLog(**{**ideal.__dict__, "gyro": counts, "gyro_output": "counts", "gyro_count_rad": 1e-7})
    with pytest.raises(LogFormatError, match=r"sample 150, column 'gyro_y': .* is not a whole number"):
        write_log(tmp_path / "x", bad)


@pytest.mark.parametrize("broken", ["repeat", "gap", "gap then repeat", "repeat on a piece boundary"])
def test_the_time_checks_name_the_first_offending_row_across_pieces(ideal, tmp_path, monkeypatch, broken):
    """The time column is checked a piece at a time (components.logs.spill.PIECE samples): the row
    named is the first offending one wherever the piece boundaries fall, and a time that does not
    increase is named before any gap, as in one pass over the whole column."""
    from components.logs import spill

    monkeypatch.setattr(spill, "PIECE", 97)
    t = ideal.time.copy()
    if "gap" in broken:
        t[5000:] += 0.5   # a gap between rows 5000 and 5001 (1-based)
    if broken == "repeat on a piece boundary":
        t[97 * 60] = t[97 * 60 - 1]   # the interval between the last sample of a piece and the next
    elif "repeat" in broken:
        t[7001] = t[7000]
    bad = MeasurementLog(**{**ideal.__dict__, "time": t})
    expected = (rf"sample {97 * 60 + 1}, column 'time'.*strictly increasing" if "boundary" in broken else
                r"sample 7002, column 'time'.*strictly increasing" if "repeat" in broken else
                r"sample 5001, column 'time': interval 0\.50[45]\d* s .*expected 1/sample_rate_hz")
    with pytest.raises(LogFormatError, match=expected):
        write_log(tmp_path / "x", bad)


def test_a_files_hash_is_read_again_only_when_the_file_changed(tmp_path):
    """The hash is memoised by size and modification time: the same bytes give the digest
    hashlib gives, and a rewritten file its new digest."""
    import hashlib
    import os

    from orchestrator.units import sha256_file

    f = tmp_path / "x.bin"
    f.write_bytes(b"a" * 1000)
    assert sha256_file(f) == hashlib.sha256(b"a" * 1000).hexdigest() == sha256_file(f)
    f.write_bytes(b"b" * 1001)
    st = os.stat(f)
    os.utime(f, ns=(st.st_atime_ns, st.st_mtime_ns + 1))
    assert sha256_file(f) == hashlib.sha256(b"b" * 1001).hexdigest()


@pytest.mark.parametrize("spill", [False, True])
def test_parquet_columns_of_other_types_read_as_their_float64_values(tmp_path, ideal, monkeypatch, spill):
    """A Parquet log from other software: pulse counts as int32, the temperature as float32,
    the labels as plain (not dictionary-encoded) strings. Each reads as exactly the float64
    value of what is stored (an int32 count is exact in float64, a float32 widens exactly),
    whole and, spilled, a row group at a time."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    if spill:
        monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
    write_log(tmp_path / "other", ideal, fmt="parquet")
    table = pq.read_table(tmp_path / "other.parquet")
    counts = {c: np.round(ideal.gyro[:, j] / 1e-7).astype(np.int32) for j, c in enumerate(("gyro_x", "gyro_y", "gyro_z"))}
    temperature = (ideal.temperature + 0.3).astype(np.float32)
    for name, values in [*counts.items(), ("temperature", temperature),
                         ("segment", pa.array(ideal.segment.tolist(), pa.string()))]:
        table = table.set_column(table.schema.get_field_index(name), name, pa.array(values))
    pq.write_table(table, tmp_path / "other.parquet", row_group_size=97)
    meta = json.loads((tmp_path / "other.json").read_text())
    meta["imu"].update(gyro_output="counts", gyro_count_rad=1e-7)
    (tmp_path / "other.json").write_text(json.dumps(meta))

    back = read_log(tmp_path / "other.parquet", lean=spill)
    for j, c in enumerate(counts):
        assert np.array_equal(bits(back.gyro[:, j]), bits(counts[c].astype(np.float64)))
    assert back.temperature.dtype == np.float64 and back.gyro.dtype == np.float64
    assert np.array_equal(bits(back.temperature), bits(temperature.astype(np.float64)))
    assert np.array_equal(bits(back.acc), bits(ideal.acc))
    assert back.segment.tolist() == ideal.segment.tolist()
