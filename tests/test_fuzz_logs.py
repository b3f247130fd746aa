"""calbench fuzzes itself: mutations of a valid log and its metadata, and property-based tests
over the reader and the least squares. Every case ends in one clear error naming the file (exit
2, one line, no traceback, no raw numerical warning) or in a result whose printed σ are finite
and positive — never a traceback, never a silent absurdity.

49 mutation kinds on the CSV/JSON pair and the Parquet file (cells, rows, header, time,
metadata, encodings), plus hypothesis: random valid logs round-trip bit-exactly, random byte
corruptions give LogFormatError only, random exclusions and effect sets give a CalbenchError
or finite estimates whose undetermined parameters are the ones determinability names."""
from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from components.cli import main
from components.errors import CalbenchError, LogFormatError
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import MeasurementLog, read_log, write_log
from components.model.effects import EFFECTS

SECONDS = 60.0


@pytest.fixture(scope="module")
def small(conformance, tmp_path_factory) -> Path:
    """The conformance example's first minute (two rests and a move), as a CSV pair."""
    log = read_log(conformance / "example")
    n = int(round(SECONDS / log.dt))
    import dataclasses

    cut = dataclasses.replace(log, time=log.time[:n], gimbal={k: v[:n] for k, v in log.gimbal.items()},
                              gyro=log.gyro[:n], acc=log.acc[:n], temperature=log.temperature[:n],
                              segment=log.segment[:n], command={})
    d = tmp_path_factory.mktemp("small")
    write_log(d / "base", cut)
    return d


def _copy(src: Path, dst: Path) -> Path:
    for suffix in (".csv", ".json"):
        shutil.copy(src / f"base{suffix}", dst / f"log{suffix}")
    return dst / "log"


def _lines(stem: Path) -> list[str]:
    return stem.with_suffix(".csv").read_text().splitlines()


def _put_lines(stem: Path, lines: list[str], end: str = "\n") -> None:
    stem.with_suffix(".csv").write_text(end.join(lines) + end)


def _cell(stem: Path, row: int, col: str, value: str) -> None:
    lines = _lines(stem)
    head = lines[0].split(",")
    fields = lines[row].split(",")
    fields[head.index(col)] = value
    lines[row] = ",".join(fields)
    _put_lines(stem, lines)


def _meta(stem: Path, edit) -> None:
    p = stem.with_suffix(".json")
    d = json.loads(p.read_text())
    edit(d)
    p.write_text(json.dumps(d))


def _header(stem: Path, edit) -> None:
    lines = _lines(stem)
    lines[0] = edit(lines[0])
    _put_lines(stem, lines)


def _rows(stem: Path, edit) -> None:
    lines = _lines(stem)
    _put_lines(stem, [lines[0]] + edit(lines[1:]))


def _deep(stem: Path) -> None:
    p = stem.with_suffix(".json")
    text = p.read_text().rstrip()[:-1] + ', "x": ' + "[" * 5000 + "]" * 5000 + "}"
    p.write_text(text)


def _parquet(stem: Path, edit) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    log = read_log(stem)
    write_log(stem, log, "parquet")
    stem.with_suffix(".csv").unlink()
    table = pq.read_table(stem.with_suffix(".parquet"))
    pq.write_table(edit(table, pa), stem.with_suffix(".parquet"))


MUTATIONS = {
    # cells
    "empty cell": lambda s: _cell(s, 5, "gyro_x", ""),
    "text cell": lambda s: _cell(s, 5, "gyro_x", "abc"),
    "nan cell": lambda s: _cell(s, 5, "acc_y", "nan"),
    "inf cell": lambda s: _cell(s, 5, "acc_y", "-inf"),
    "1e308 cell": lambda s: _cell(s, 50, "gyro_z", "1e308"),
    "negative zero": lambda s: _cell(s, 5, "gyro_x", "-0"),
    "denormal": lambda s: _cell(s, 5, "gyro_x", "1e-320"),
    "decimal comma": lambda s: _cell(s, 5, "acc_x", "0,5"),
    "unicode digit": lambda s: _cell(s, 5, "acc_x", "\u0663"),
    "huge exponent": lambda s: _cell(s, 5, "acc_x", "1e99999"),
    "angle in degrees": lambda s: _cell(s, 5, "gimbal_outer", "359.9"),
    # rows
    "missing row": lambda s: _rows(s, lambda r: r[:100] + r[101:]),
    "duplicated row": lambda s: _rows(s, lambda r: r[:100] + [r[100]] + r[100:]),
    "shuffled rows": lambda s: _rows(s, lambda r: r[:100] + [r[102], r[100], r[101]] + r[103:]),
    "short row": lambda s: _rows(s, lambda r: r[:10] + [r[10].rsplit(",", 2)[0]] + r[11:]),
    "long row": lambda s: _rows(s, lambda r: r[:10] + [r[10] + ",1"] + r[11:]),
    "blank line": lambda s: _rows(s, lambda r: r[:10] + [""] + r[10:]),
    "header repeated": lambda s: _put_lines(s, _lines(s)[:50] + [_lines(s)[0]] + _lines(s)[50:]),
    "no rows": lambda s: _rows(s, lambda r: []),
    "one row": lambda s: _rows(s, lambda r: r[:1]),
    # header
    "missing column": lambda s: _put_lines(s, [",".join(ln.split(",")[:-2] + ln.split(",")[-1:]) for ln in _lines(s)]),
    "duplicate column": lambda s: _header(s, lambda h: h.replace("acc_x", "acc_y", 1)),
    "renamed column": lambda s: _header(s, lambda h: h.replace("gyro_x", "gyro_X")),
    "extra columns": lambda s: _put_lines(s, [ln + (",extra" if i == 0 else ",1") for i, ln in enumerate(_lines(s))]),
    "bom": lambda s: s.with_suffix(".csv").write_bytes(b"\xef\xbb\xbf" + s.with_suffix(".csv").read_bytes()),
    "spaces in header": lambda s: _header(s, lambda h: h.replace(",gyro_x,", ", gyro_x ,")),
    "upper-case header": lambda s: _header(s, str.upper),
    "no header": lambda s: _put_lines(s, _lines(s)[1:]),
    # time
    "time backwards": lambda s: _cell(s, 20, "time", "0.001"),
    "time repeated": lambda s: _cell(s, 21, "time", _lines(s)[20].split(",")[0]),
    "time jump": lambda s: _rows(s, lambda r: [ln if i < 300 else ",".join([repr(float(ln.split(",")[0]) + 1.0)]
                                                                          + ln.split(",")[1:])
                                              for i, ln in enumerate(r)]),
    "time jitter": lambda s: _cell(s, 20, "time", repr(float(_lines(s)[20].split(",")[0]) + 2e-5)),
    "negative start": lambda s: _rows(s, lambda r: [",".join([repr(float(ln.split(",")[0]) - 100.0)] + ln.split(",")[1:])
                                                  for ln in r]),
    # metadata
    "latitude as text": lambda s: _meta(s, lambda d: d["site"].update(latitude_deg="39.9")),
    "missing height": lambda s: _meta(s, lambda d: d["site"].pop("height_m")),
    "extra key": lambda s: _meta(s, lambda d: d.update(operator="me")),
    "deep nesting": _deep,
    "invalid json": lambda s: s.with_suffix(".json").write_text("{"),
    "latin-1 json": lambda s: s.with_suffix(".json").write_bytes(
        s.with_suffix(".json").read_text().replace('"description": "', '"description": "\xe9').encode("latin-1")),
    "null rate": lambda s: _meta(s, lambda d: d["imu"].update(sample_rate_hz=None)),
    "format v3": lambda s: _meta(s, lambda d: d.update(format="calbench-log/3")),
    "v2 key in v1": lambda s: _meta(s, lambda d: d.update(segments={"pos01": {"kind": "static"}})),
    "axis of two numbers": lambda s: _meta(s, lambda d: d["table"]["axes"][0].update(axis=[0, 1])),
    "zero axis": lambda s: _meta(s, lambda d: d["table"]["axes"][0].update(axis=[0, 0, 0])),
    "counts without weight": lambda s: _meta(s, lambda d: d["imu"].update(gyro_output="counts")),
    "unknown output": lambda s: _meta(s, lambda d: d["imu"].update(acc_output="g")),
    # encodings
    "utf-16": lambda s: s.with_suffix(".csv").write_bytes(s.with_suffix(".csv").read_text().encode("utf-16")),
    "crlf": lambda s: _put_lines(s, _lines(s), "\r\n"),
    "parquet text column": lambda s: _parquet(s, lambda t, pa: t.set_column(
        t.column_names.index("gyro_x"), "gyro_x", pa.array([str(x) for x in t.column("gyro_x").to_pylist()]))),
}


@pytest.mark.parametrize("kind", list(MUTATIONS))
def test_a_mutated_log_gives_one_clear_error_or_an_honest_result(small, tmp_path, capsys, kind):
    stem = _copy(small, tmp_path)
    MUTATIONS[kind](stem)
    out_json = tmp_path / "r.json"
    code = main(["calibrate", str(stem), "--out", str(out_json)])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err and "calbench: warning" not in captured.err, captured.err
    assert code in (0, 2), code
    if code == 2:
        lines = [ln for ln in captured.err.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("calbench: error: "), captured.err
        assert "log." in lines[0] or str(stem.name) in lines[0], lines[0]
    else:
        res = json.loads(out_json.read_text())
        for p, e in res["parameters"].items():
            assert math.isfinite(e["value"]) and math.isfinite(e["sigma"]) and e["sigma"] > 0, (p, e)


# ------------------------------------------------------------------------------ properties
def _random_log(draw) -> MeasurementLog:
    n = draw(st.integers(2, 40))
    fs = draw(st.sampled_from([50.0, 100.0, 200.0, 1000.0]))
    t = np.arange(1, n + 1) / fs + draw(st.floats(-10.0, 10.0))
    floats = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False, width=64)
    arr = lambda k: np.array(draw(st.lists(floats, min_size=n * k, max_size=n * k))).reshape(n, k)  # noqa: E731
    # a continuous angle (steps under half a turn): readings to one turn that wrap are made
    # continuous as they are read (tests/test_angle_turns.py)
    steps = draw(st.lists(st.floats(-3.0, 3.0), min_size=n - 1, max_size=n - 1))
    angle = draw(floats) + np.concatenate([[0.0], np.cumsum(steps)])
    return MeasurementLog(time=t, gimbal={"outer": angle}, gyro=arr(3), acc=arr(3), axis_names=["outer"],
                          axis_vectors=np.array([[0.0, 0.0, 1.0]]), sample_rate_hz=fs,
                          latitude_deg=draw(st.floats(-90, 90)),
                          segment=np.array(draw(st.lists(st.sampled_from(["a", "b,c", " d", "é"]), min_size=n,
                                                         max_size=n)), dtype=object))


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_valid_logs_round_trip_bit_exactly(tmp_path, data):
    log = _random_log(data.draw)
    fmt = data.draw(st.sampled_from(["csv", "parquet"]))
    write_log(tmp_path / "r", log, fmt)
    back = read_log(tmp_path / f"r.{fmt}")
    assert np.array_equal(back.time.view(np.int64), log.time.view(np.int64))
    assert np.array_equal(back.gyro.view(np.int64), log.gyro.view(np.int64))
    assert np.array_equal(back.gimbal["outer"].view(np.int64), log.gimbal["outer"].view(np.int64))
    assert list(back.segment) == list(log.segment)


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_corruptions_are_log_format_errors(small, tmp_path, data):
    stem = _copy(small, tmp_path)
    which = data.draw(st.sampled_from([".csv", ".json"]))
    p = stem.with_suffix(which)
    raw = bytearray(p.read_bytes()[:4000] if which == ".csv" else p.read_bytes())
    if which == ".csv":
        p.write_bytes(bytes(raw) + b"\n")   # a short, valid prefix (whole lines) first
        raw = bytearray(p.read_bytes().rsplit(b"\n", 2)[0] + b"\n")
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    p.write_bytes(bytes(raw))
    try:
        read_log(stem)
    except LogFormatError as e:
        assert str(p.name) in str(e) or "log" in str(e)


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_exclusions_and_effect_sets(small, data):
    log = read_log(small / "base")
    t0 = data.draw(st.floats(0.0, SECONDS))
    t1 = t0 + data.draw(st.floats(0.01, 30.0))
    effects = data.draw(st.lists(st.sampled_from([e for e, x in EFFECTS.items() if x.target != "table"]),
                                 min_size=1, max_size=4, unique=True))
    try:
        fit = calibrate(LogData.from_log(log, exclude=[[t0, t1]]), effects)
    except CalbenchError:
        return
    assert np.all(np.isfinite(fit.value)) and np.all(np.isfinite(fit.sigma)) and np.all(fit.sigma > 0)
    asked = {p for e in effects for p in EFFECTS[e].parameters}
    assert set(fit.parameters) | set(fit.determinability.undetermined) == asked
