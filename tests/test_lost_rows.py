"""Lost packets written as rows (``lost_rows = true``): a logger that writes a packet lost on
its way as a row of empty cells, NaN, or a blank line. The conformance example written so by a
plain writer, imported, must calibrate as the same log with exactly those samples and the one
after each run masked (components.logs.logfile's ``mask``: another path through calbench that
leaves samples out, its samples at their own times); without the key, one error naming the row
and the key."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from components.cli import main
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS

DEG = math.pi / 180
G0 = 9.80665
SITE = '[site]\nlatitude_deg = 39.9\nheight_m = 50.0\n'
HEADER = ["t", "gx", "gy", "gz", "ax", "ay", "az", "outer", "middle", "inner"]


@pytest.fixture(scope="module")
def example(conformance):
    return read_log(conformance / "example")


def _lost_pattern(n: int, seed: int = 5) -> np.ndarray:
    """~0.3 % of the rows lost, single and in runs (one of five rows), none in the first or last
    ten rows (a log starts and ends with a sample)."""
    rng = np.random.default_rng(seed)
    lost = np.zeros(n, bool)
    starts = rng.choice(np.arange(10, n - 20), size=n // 400, replace=False)
    for s in starts:
        lost[s:s + (5 if s % 7 == 0 else 1)] = True
    lost[-10:] = False
    return lost


def _rows(log, gyro_cols: np.ndarray, acc_cols: np.ndarray) -> list[list[str]]:
    t = log.time
    angles = [np.degrees(log.gimbal[a]) for a in ("outer", "middle", "inner")]
    cols = [t, *gyro_cols.T, *acc_cols.T, *angles]
    return [["%.17g" % c[i] for c in cols] for i in range(len(t))]


def _write_with_lost(path: Path, rows: list[list[str]], lost: np.ndarray) -> None:
    """Each lost row written one of three ways, in turn: the time kept and every other cell empty;
    'nan' in one gyro cell; a blank line."""
    lines = [",".join(HEADER)]
    for k, (r, gone) in enumerate(zip(rows, lost)):
        if not gone:
            lines.append(",".join(r))
            continue
        style = k % 3
        if style == 0:
            lines.append(r[0] + "," * (len(r) - 1))
        elif style == 1:
            lines.append(",".join(r[:2] + ["nan"] + r[3:]))
        else:
            lines.append("")
    path.write_text("\n".join(lines) + "\n")


def _mapping(gyro: str, acc: str, timing: str = "nominal", lost_rows: bool = True) -> str:
    axes = "".join(f'[[table.axes]]\nname = "{n}"\naxis = {v}\ncolumn = "{n}"\nunit = "deg"\n'
                   for n, v in (("outer", [0, 0, 1]), ("middle", [1, 0, 0]), ("inner", [0, 0, 1])))
    return ('[imu]\nfile = "rec.csv"\nsample_rate_hz = 200.0\n' + ("lost_rows = true\n" if lost_rows else "")
            + f'[imu.time]\ncolumn = "t"\ntiming = "{timing}"\n{gyro}{acc}'
            + '[table]\nencoder_resolution = "exact"\n' + axes + SITE)


def _masked_reference(log, left_out: np.ndarray):
    from dataclasses import replace

    return calibrate(LogData.from_log(replace(log, mask=~left_out)), list(DEFAULT_EFFECTS))


def _after_each_run(lost: np.ndarray) -> np.ndarray:
    """The first row after each run of lost rows (its interval's start is a lost sample's end)."""
    after = np.zeros_like(lost)
    after[1:] = lost[:-1] & ~lost[1:]
    return after


def _assert_same(fit, ref, tol):
    z = {p: (v - ref.value[ref.parameters.index(p)]) / ref.sigma[ref.parameters.index(p)]
         for p, v in zip(fit.parameters, fit.value)}
    worst = max(z, key=lambda p: abs(z[p]))
    assert abs(z[worst]) < tol, (worst, z[worst])


RATES = ('[imu.gyro]\noutput = "rate"\nunit = "deg/s"\nx = "gx"\ny = "gy"\nz = "gz"\n'
         '[imu.acc]\noutput = "specific_force"\nunit = "g"\nx = "ax"\ny = "ay"\nz = "az"\n')


def test_lost_rows_of_a_nominal_clock_are_gaps_and_the_rest_calibrates_as_the_masked_log(example, tmp_path, capsys):
    log = example
    lost = _lost_pattern(log.n)
    _write_with_lost(tmp_path / "rec.csv", _rows(log, np.degrees(log.gyro / log.dt), log.acc / log.dt / G0), lost)
    (tmp_path / "map.toml").write_text(_mapping(RATES, ""))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 0
    said = capsys.readouterr().out
    assert f"{int(lost.sum())} row(s) with an empty or NaN cell" in said
    back = read_log(tmp_path / "imported")
    assert back.n == log.n - lost.sum() and back.timing == "measured"
    # the kept rows as written: at their stamps, each increment its own nominal interval's
    np.testing.assert_array_equal(back.time, log.time[~lost])
    assert back.gyro_output == back.acc_output == "increment"
    np.testing.assert_allclose(back.gyro, log.gyro[~lost], rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(back.acc, log.acc[~lost], rtol=1e-13, atol=1e-15)
    for a in ("outer", "middle", "inner"):
        np.testing.assert_allclose(back.gimbal[a], log.gimbal[a][~lost], rtol=1e-14, atol=1e-15)
    # left out by the log itself: the sample after each run of lost rows (counted here)
    left_out = lost | _after_each_run(lost)
    data = LogData.from_log(back)
    assert int((~data.usable).sum()) == int(_after_each_run(lost).sum())
    # within 0.1 σ, not exactly: the accelerometer's moving blocks are cut by sample counts, and
    # a log without the lost rows cuts them at other samples than the whole log masked (with the
    # rows lost at rest only, the two agree to 2e-11 σ)
    _assert_same(calibrate(data, list(DEFAULT_EFFECTS)), _masked_reference(log, left_out), tol=0.1)


def test_lost_rows_of_running_totals_leave_out_the_total_across_them(example, tmp_path, capsys):
    """Increments as running totals (a 32-bit register of µrad and µm/s, rolling over), measured
    timing: across a lost row the step of the totals spans two intervals; the sample after the
    run is left out, as the first sample is (nothing before it to count from)."""
    log = example
    lost = _lost_pattern(log.n, seed=8)
    g = np.round(np.cumsum(log.gyro, axis=0) / 1e-6) % 2**32
    a = np.round(np.cumsum(log.acc, axis=0) / 1e-6) % 2**32
    _write_with_lost(tmp_path / "rec.csv", _rows(log, g, a), lost)
    totals = ('[imu.gyro]\noutput = "counts"\ncount = "1e-6 rad"\naccumulated = true\nrollover = 4294967296\n'
              'x = "gx"\ny = "gy"\nz = "gz"\n'
              '[imu.acc]\noutput = "counts"\ncount = "1e-6 m/s"\naccumulated = true\nrollover = 4294967296\n'
              'x = "ax"\ny = "ay"\nz = "az"\n')
    (tmp_path / "map.toml").write_text(_mapping(totals, "", timing="measured"))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 0
    back = read_log(tmp_path / "imported")
    np.testing.assert_array_equal(back.time, log.time[~lost][1:])
    # the counts of each kept sample are the original's rounded increments: those of a sample
    # after a run are the sum over the run (left out), the others their own
    kept = np.flatnonzero(~lost)[1:]
    own = ~_after_each_run(lost)[kept]
    want = np.diff(np.round(np.cumsum(log.gyro, axis=0) / 1e-6), axis=0, prepend=0.0)[kept]
    np.testing.assert_array_equal(back.gyro[own], want[own])
    left_out = lost | _after_each_run(lost)
    left_out[0] = True
    data = LogData.from_log(back)
    assert int((~data.usable).sum()) == int(_after_each_run(lost).sum())
    # the reference: the original's increments as the same rounded counts, the same samples masked
    from dataclasses import replace

    counted = replace(log, gyro=np.diff(np.round(np.cumsum(log.gyro, axis=0) / 1e-6), axis=0, prepend=0.0),
                      acc=np.diff(np.round(np.cumsum(log.acc, axis=0) / 1e-6), axis=0, prepend=0.0),
                      gyro_output="counts", acc_output="counts", gyro_count_rad=1e-6, acc_count_mps=1e-6)
    _assert_same(calibrate(data, list(DEFAULT_EFFECTS)), _masked_reference(counted, left_out), tol=0.1)


@pytest.mark.parametrize("style, words", [
    (0, r"rec.csv: column 'gx': row {row}: empty value; expected a number \(a logger that writes a lost packet as a "
        r"row with empty or NaN cells: give imu.lost_rows = true\)"),
    (1, r"imu.gyro.y: row {row}: nan is not finite \(a logger .* give imu.lost_rows = true\)"),
    (2, r"data row {row} \(line {line}\): blank line; expected a sample on every line \(a logger that writes a lost "
        r"packet as a blank line: give imu.lost_rows = true\)"),
])
def test_without_the_key_a_lost_row_is_one_error_naming_its_row_and_the_key(example, tmp_path, capsys, style, words):
    log = example
    lost = np.zeros(log.n, bool)
    k = 300 + style - 300 % 3  # the writer's style is k % 3
    lost[k] = True
    _write_with_lost(tmp_path / "rec.csv", _rows(log, np.degrees(log.gyro / log.dt), log.acc / log.dt / G0), lost)
    (tmp_path / "map.toml").write_text(_mapping(RATES, "", lost_rows=False))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert re.search(words.format(row=k + 1, line=k + 2), err), err
    assert "Traceback" not in err


def test_lost_rows_in_table_without_its_own_file_is_refused(tmp_path, capsys):
    (tmp_path / "rec.csv").write_text("t,g\n0.005,0\n")
    (tmp_path / "map.toml").write_text(_mapping(RATES, "").replace('[table]\n', '[table]\nlost_rows = true\n'))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "key 'table.lost_rows' describes a table file, but [table] names none" in err and "imu.lost_rows" in err


def test_lost_rows_of_a_table_file_are_interpolated_across(example, tmp_path, capsys):
    """The table's angles in a file of their own (at the IMU's times, the clock offset given),
    its lost rows written as the IMU's are: the angles are interpolated across them, the IMU's
    samples all kept; the calibration within 0.1 σ of the conformance log's (a lost reading in
    a move is interpolated over two intervals instead of one)."""
    log = example
    lost = _lost_pattern(log.n, seed=11)
    t = log.time
    imu = [[f"{t[i]:.17g}"] + [f"{v:.17g}" for v in (*np.degrees(log.gyro[i] / log.dt), *(log.acc[i] / log.dt / G0))]
           for i in range(log.n)]
    (tmp_path / "rec.csv").write_text(",".join(HEADER[:7]) + "\n" + "\n".join(",".join(r) for r in imu) + "\n")
    table = [[f"{t[i]:.17g}"] + [f"{np.degrees(log.gimbal[a][i]):.17g}" for a in ("outer", "middle", "inner")]
             for i in range(log.n)]
    lines = ["tt,outer,middle,inner"]
    for k, (r, gone) in enumerate(zip(table, lost)):
        lines.append(",".join(r) if not gone else ("" if k % 2 else r[0] + ",,,"))
    (tmp_path / "table.csv").write_text("\n".join(lines) + "\n")
    mapping = _mapping(RATES, "", lost_rows=False).replace(
        '[table]\n', '[table]\nfile = "table.csv"\nlost_rows = true\nclock_offset_s = 0.0\n') + '[table.time]\ncolumn = "tt"\n'
    (tmp_path / "map.toml").write_text(mapping)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 0
    assert f"{int(lost.sum())} row(s) with an empty or NaN cell" in capsys.readouterr().out
    back = read_log(tmp_path / "imported")
    assert back.n == log.n and back.timing == "nominal"
    reference = calibrate(LogData.from_log(log), list(DEFAULT_EFFECTS))
    _assert_same(calibrate(LogData.from_log(back), list(DEFAULT_EFFECTS)), reference, tol=0.1)


@pytest.mark.parametrize("layout", ["parquet", "mat"])
def test_lost_rows_in_parquet_nulls_and_mat_nans(example, tmp_path, layout):
    """A Parquet file's lost packets as nulls (or NaN), a MATLAB file's as NaN: the kept rows
    imported as written."""
    log = example
    lost = _lost_pattern(log.n, seed=3)
    gyro, acc = np.degrees(log.gyro / log.dt), log.acc / log.dt / G0
    angles = [np.degrees(log.gimbal[a]) for a in ("outer", "middle", "inner")]
    columns = dict(zip(HEADER, [log.time, *gyro.T, *acc.T, *angles]))
    if layout == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = {k: pa.array(v, pa.float64()) for k, v in columns.items()}
        table["gy"] = pa.array(np.where(lost, np.nan, columns["gy"]), pa.float64())
        table["az"] = pa.array([None if x else v for x, v in zip(lost, columns["az"])], pa.float64())
        pq.write_table(pa.table(table), tmp_path / "rec.parquet")
    else:
        import scipy.io

        scipy.io.savemat(tmp_path / "rec.mat", {k: np.where(lost, np.nan, v) if k == "ax" else v
                                                  for k, v in columns.items()})
    name = "rec.parquet" if layout == "parquet" else "rec.mat"
    (tmp_path / "map.toml").write_text(_mapping(RATES, "").replace('file = "rec.csv"', f'file = "{name}"'))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 0
    back = read_log(tmp_path / "imported")
    np.testing.assert_array_equal(back.time, log.time[~lost])
    np.testing.assert_allclose(back.gyro, log.gyro[~lost], rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(back.acc, log.acc[~lost], rtol=1e-13, atol=1e-15)


def test_lost_rows_leave_text_columns_too(tmp_path):
    """The time as the time of day and the segment labels (text, held as runs) lose the lost
    rows with the numbers: every column of the log the same length, the labels the kept rows'."""
    n = 2000
    t = 8 * 3600 + np.arange(1, n + 1) * 0.005
    lost = np.zeros(n, bool)
    lost[[500, 501, 1200]] = True
    lines = ["time,gx,gy,gz,ax,ay,az,lab"]
    for i in range(n):
        h, rem = divmod(t[i], 3600)
        clock = f"{int(h):02d}:{int(rem // 60):02d}:{rem % 60:06.3f}"
        lab = "p1" if i < 1000 else "p2"
        lines.append(f"{clock},,,,,,,{lab}" if lost[i] else f"{clock},0.001,0.002,-0.001,0.01,0.02,1.0,{lab}")
    (tmp_path / "rec.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "map.toml").write_text(
        '[imu]\nfile = "rec.csv"\nsample_rate_hz = 200.0\nlost_rows = true\n[imu.time]\ncolumn = "time"\n'
        + RATES + '[labels]\ncolumn = "lab"\n[segments]\np1 = {kind = "static"}\np2 = {kind = "static"}\n' + SITE)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 0
    back = read_log(tmp_path / "imported")
    assert back.n == n - 3
    np.testing.assert_allclose(back.time, t[~lost], rtol=0, atol=1e-6)
    assert list(map(str, back.segment[[0, 997, 998, -1]])) == ["p1", "p1", "p2", "p2"]
