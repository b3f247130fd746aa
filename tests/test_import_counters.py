"""``calbench import`` of the time stamps real loggers write: a host clock coarser than the
samples (Windows' tick of 15.625 ms stamping a 200 Hz sensor: two stamps in three alike), which
``timing = "regularise"`` places on the grid fitted to all of them, and a counter that rolls
over (a 32-bit count of microseconds: every 71.6 minutes), counted on with ``rollover``. Each
imported log calibrates as the independent simulator's own (the conformance vector
``example``)."""
from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from rig_files import AXES, imported, imu_columns, mapping, table_columns, write_csv

from components.cli import main
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS

TICK = 0.015625  # s


@pytest.fixture(scope="module")
def example(conformance):
    log = read_log(conformance / "example")
    return log, calibrate(LogData.from_log(log), list(DEFAULT_EFFECTS))


def _write(tmp_path, log, stamps_ms: np.ndarray, timing: str = "regularise", time: str = 'unit = "ms"') -> None:
    write_csv(tmp_path / "imu.csv", imu_columns(log, stamps_ms))
    (tmp_path / "map.toml").write_text(mapping(log, f'{time}\ntiming = "{timing}"'))


def _same_as(back, ref, tol: float = 0.1) -> None:
    """The log *back* calibrates as the reference fit *ref*: every parameter within *tol* of its σ."""
    fit = calibrate(LogData.from_log(back), list(DEFAULT_EFFECTS))
    assert fit.parameters == ref.parameters
    z = np.abs((np.asarray(fit.value) - ref.value) / ref.sigma)
    assert z.max() < tol, (fit.parameters[int(np.argmax(z))], z.max())


def test_stamps_of_a_coarse_clock_are_regularised_and_calibrate_as_the_original(example, tmp_path, capsys):
    log, ref = example
    stamps = np.floor((log.time + 0.0371) / TICK) * TICK  # the tick the sample was read in
    assert np.mean(np.diff(stamps) == 0) > 0.6
    _write(tmp_path, log, stamps * 1e3)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    tick_ms = float(re.search(r"a clock of ([\d.]+) ms resolution", out).group(1))
    assert tick_ms == pytest.approx(TICK * 1e3, rel=1e-3)
    rate = float(re.search(r"fitted rate ([\d.]+) Hz", out).group(1))
    # a line's slope through N stamps each off by up to a tick: σ ≈ tick / (span √N); 4 σ
    assert abs(rate / log.sample_rate_hz - 1) < 4 * TICK / ((log.time[-1] - log.time[0]) * math.sqrt(log.n))
    assert "warning" not in out and "gap" not in out.split("a gap is")[-1]
    back = read_log(tmp_path / "merged")
    assert back.n == log.n
    np.testing.assert_allclose(np.diff(back.time), log.dt, rtol=1e-6)
    _same_as(back, ref)


@pytest.mark.parametrize("timing, edit, words", [
    ("regularise", lambda s: np.concatenate([s[:100], s[100:101] - 20.0, s[101:]]),
     r"imu.csv: imu.time: row 101: .* expected times that never go back"),
    ("regularise", lambda s: np.full_like(s, 5.0), r"imu.csv: imu.time: every stamp is 0.005 s; expected times that advance"),
    ("nominal", lambda s: s, r"imu.csv: imu.time: row 3: .* expected strictly increasing times"),
])
def test_stamps_that_go_back_or_stand_still_are_one_clear_error(example, tmp_path, capsys, timing, edit, words):
    """Only a regularised clock may repeat stamps; none may go back, and a clock that never
    advances is no clock."""
    log, _ = example
    stamps = np.floor((log.time + 0.0371) / TICK) * TICK * 1e3
    _write(tmp_path, log, edit(stamps), timing)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 2
    assert re.search(words, capsys.readouterr().err), words


COUNT = 2**32  # a 32-bit microsecond counter


@pytest.mark.parametrize("timing", ["nominal", "regularise"])
def test_a_counter_that_rolls_over_is_counted_on(example, tmp_path, capsys, timing):
    log, ref = example
    micros = np.mod(np.round(log.time * 1e6) + COUNT - 200_000_000, COUNT)  # rolls over 200 s in
    assert np.count_nonzero(np.diff(micros) < 0) == 1
    _write(tmp_path, log, micros, timing, time=f'unit = "us"\nrollover = {COUNT}')
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 0
    assert "the time counter rolled over 1 time(s)" in capsys.readouterr().out
    back = read_log(tmp_path / "merged")
    assert back.n == log.n
    np.testing.assert_allclose(np.diff(back.time), log.dt, rtol=1e-6)
    _same_as(back, ref)
    # without the key: one error at the row, naming the key to give
    _write(tmp_path, log, micros, timing, time='unit = "us"')
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 2
    err = capsys.readouterr().err
    assert re.search(r"imu.csv: imu.time: row \d+: .* a counter that rolls over\? give 'imu.time.rollover'", err), err


def _import_with_table(tmp_path, log, table_ms: np.ndarray, rollover: str, name: str):
    """The IMU's increments on its own times and a table file stamped *table_ms* (given half a
    sample behind the IMU's clock)."""
    write_csv(tmp_path / "imu.csv", imu_columns(log, log.time, angles=False))
    write_csv(tmp_path / "table.csv", table_columns(log, table_ms))
    (tmp_path / "map.toml").write_text(mapping(log, table=f"clock_offset_s = {0.5 * log.dt!r}",
                                               table_time=f'unit = "ms"\n{rollover}'))
    return imported(tmp_path, name)


def test_a_table_counter_that_rolls_over_is_counted_on(example, tmp_path, capsys):
    """A table controller's 16-bit millisecond counter (every 65.536 s): imported as the same
    table file stamped without the rollover."""
    log, _ = example
    ms = (log.time - 0.5 * log.dt) * 1e3
    plain = _import_with_table(tmp_path, log, ms, "", "plain")
    rolled = _import_with_table(tmp_path, log, np.mod(ms, 65536.0), "rollover = 65536", "rolled")
    assert "the table's time counter rolled over 6 time(s)" in capsys.readouterr().out
    np.testing.assert_array_equal(rolled.time, plain.time)
    for a in AXES:
        np.testing.assert_allclose(rolled.gimbal[a], plain.gimbal[a], rtol=0, atol=1e-12)


def test_a_rollover_that_is_no_period_is_one_clear_error(example, tmp_path, capsys):
    log, _ = example
    _write(tmp_path, log, log.time * 1e6, "nominal", time='unit = "us"\nrollover = -5')
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 2
    assert "map.toml: key 'imu.time.rollover' = -5" in capsys.readouterr().err


def _write_sparse_temperature(tmp_path, log, temperature: np.ndarray, every: int, sparse: bool) -> None:
    """imu.csv with the temperature (°F) in every *every*-th row, empty between."""
    cells = [f"{v:.17g}" if i % every == 0 else "" for i, v in enumerate(temperature)]
    write_csv(tmp_path / "imu.csv", {**imu_columns(log, log.time), "temp": cells})
    (tmp_path / "map.toml").write_text(mapping(log, temperature=f'unit = "degF"\nsparse = {str(sparse).lower()}'))


def test_a_temperature_read_once_a_second_is_linear_between_its_readings(example, tmp_path, capsys):
    """A warm-up, 25 -> 40 °C with a 300 s time constant, read once a second (every 200th row,
    in °F): between readings the imported temperature is within the linear interpolation's bound
    h²/8 · max|T''| of the warm-up itself."""
    log, _ = example
    tau, h = 300.0, 200 * log.dt
    warm_c = 40.0 - 15.0 * np.exp(-(log.time - log.time[0]) / tau)
    _write_sparse_temperature(tmp_path, log, warm_c * 9 / 5 + 32, 200, sparse=True)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 0
    assert f"temperature: {-(-log.n // 200)} reading(s) in {log.n} samples" in capsys.readouterr().out
    back = read_log(tmp_path / "merged")
    last = (log.n - 1) // 200 * 200  # held after the last reading
    bound = h**2 / 8 * 15.0 / tau**2 + 1e-9
    assert np.abs(back.temperature[:last] - warm_c[:last]).max() < bound
    assert np.abs(back.temperature[last:] - warm_c[last]).max() < 1e-9


def test_empty_temperature_cells_without_the_key_are_one_clear_error(example, tmp_path, capsys):
    log, _ = example
    _write_sparse_temperature(tmp_path, log, np.full(log.n, 68.0), 200, sparse=False)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 2
    assert re.search(r"imu.csv: column 'temp': row 2: empty value; expected a number .*imu.temperature.sparse = true",
                     capsys.readouterr().err)
    _write_sparse_temperature(tmp_path, log, np.full(log.n, 68.0), 10 * log.n, sparse=True)
    text = (tmp_path / "imu.csv").read_text().replace(",68\n", ",\n", 1)  # the one reading gone
    (tmp_path / "imu.csv").write_text(text)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 2
    assert "imu.temperature.column: no reading in any row" in capsys.readouterr().err


def _write_clock_text(tmp_path, log, stamps: list[str], time: str = "") -> None:
    """imu.csv with the time column as text (*stamps*), the angles beside the increments."""
    write_csv(tmp_path / "imu.csv", imu_columns(log, stamps))
    (tmp_path / "map.toml").write_text(mapping(log, time))


@pytest.mark.parametrize("clock", ["dates", "dates UTC", "time of day past midnight"])
def test_a_time_column_of_clock_readings_is_read_as_seconds(example, tmp_path, capsys, clock):
    """ISO 8601 dates and times (naive, or with a zone) and the time of day (across midnight,
    counted on with rollover = 86400): the intervals are the log's, and it calibrates as its own."""
    log, ref = example
    if clock.startswith("dates"):
        at = np.datetime64("2026-11-29T08:00:00") + np.round(log.time * 1e6).astype("timedelta64[us]")
        stamps = [str(x) + ("Z" if clock.endswith("UTC") else "") for x in at]
        time = ""
    else:
        seconds = np.round((log.time + 86400 - 200.0) * 1e6) / 1e6  # midnight 200 s in
        day = np.mod(seconds, 86400)
        stamps = [f"{int(x // 3600):02d}:{int(x % 3600 // 60):02d}:{x % 60:09.6f}" for x in day]
        time = "rollover = 86400"
    _write_clock_text(tmp_path, log, stamps, time)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    assert f"imu.time: {clock.split(' ')[0] if clock.startswith('dates') else 'time of day'} read as seconds" in out
    back = read_log(tmp_path / "merged")
    # epoch seconds keep their float's 0.24 us; a time of day its microseconds
    np.testing.assert_allclose(np.diff(back.time), np.diff(log.time), rtol=0, atol=5e-7)
    _same_as(back, ref)


@pytest.mark.parametrize("edit, time, words", [
    (lambda s: s[:5] + ["08:00:00;5"] + s[6:], "", r"imu.csv: imu.time.column: row 6: '08:00:00;5' is not a reading of "
                                                     r"the clock like row 1's '08:00:00.005000' \(time of day\)"),
    (lambda s: s, 'unit = "ms"', r"map.toml: key 'imu.time.unit': the column 't' holds time of day .* expected no unit"),
])
def test_clock_readings_that_do_not_read_are_one_clear_error(example, tmp_path, capsys, edit, time, words):
    log, _ = example
    day = np.round((log.time + 8 * 3600) * 1e6) / 1e6
    stamps = [f"{int(x // 3600):02d}:{int(x % 3600 // 60):02d}:{x % 60:09.6f}" for x in day]
    _write_clock_text(tmp_path, log, edit(stamps), time)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 2
    assert re.search(words, capsys.readouterr().err), words


def _write_totals(tmp_path, log, gyro_totals, acc_totals, gyro_keys: str, acc_keys: str, table: bool) -> None:
    """imu.csv of running totals (and the angles, or a table file half a sample behind)."""
    write_csv(tmp_path / "imu.csv", imu_columns(log, log.time, gyro_totals, acc_totals, angles=not table))
    if table:
        write_csv(tmp_path / "table.csv", table_columns(log, log.time - 0.5 * log.dt))
    (tmp_path / "map.toml").write_text(mapping(log, gyro=gyro_keys, acc=acc_keys,
                                               **({"table": f"clock_offset_s = {0.5 * log.dt!r}", "table_time": ""}
                                                  if table else {})))


@pytest.mark.parametrize("table", [False, True])
def test_running_totals_are_the_increments_again(example, tmp_path, capsys, table):
    """Running totals of the increments (a laser gyro's up/down counter of 1e-7 rad pulses
    rolling over at 2^16, an accelerometer's velocity in m/s): imported, every sample after the
    first has its own increment again (the counts to the pulse), and the log calibrates as the
    original, with the table's angles in the same file or on their own clock."""
    log, ref = example
    q = 1e-7
    pulses = np.round(np.cumsum(log.gyro, axis=0) / q)  # the counter, before it rolls over
    assert np.abs(np.diff(pulses, axis=0)).max() < 2**15
    counter = np.mod(pulses, 2**16)
    velocity = np.cumsum(log.acc, axis=0)
    _write_totals(tmp_path, log, counter, velocity,
                  f'output = "counts"\ncount = "{q!r} rad"\naccumulated = true\nrollover = 65536',
                  'output = "increment"\nunit = "m/s"\naccumulated = true', table)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 0
    assert "running totals (accumulated): the first sample's increment is not known" in capsys.readouterr().out
    back = read_log(tmp_path / "merged")
    kept = np.searchsorted(log.time, back.time)
    assert kept[0] == 1 and back.n == log.n - 1
    np.testing.assert_array_equal(back.gyro, np.diff(pulses, axis=0)[kept - 1])
    np.testing.assert_allclose(back.acc, log.acc[kept], rtol=0, atol=1e-12)
    _same_as(back, ref)


@pytest.mark.parametrize("gyro_keys, words", [
    ('output = "rate"\nunit = "rad/s"\naccumulated = true', r"key 'imu.gyro.accumulated' = true with output = 'rate'"),
    ('output = "increment"\nunit = "rad"\nrollover = 65536', r"key 'imu.gyro.rollover': .* expected 'imu.gyro.accumulated'"),
    ('output = "increment"\nunit = "rad"\naccumulated = "yes"', r"key 'imu.gyro.accumulated' = 'yes': expected true"),
])
def test_running_total_keys_that_do_not_fit_are_one_clear_error(example, tmp_path, capsys, gyro_keys, words):
    log, _ = example
    _write_totals(tmp_path, log, np.cumsum(log.gyro, axis=0), np.cumsum(log.acc, axis=0), gyro_keys,
                  'output = "increment"\nunit = "m/s"\naccumulated = true', False)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 2
    assert re.search(words, capsys.readouterr().err), words


def test_a_50_hz_sensor_on_the_coarse_clock_never_repeating_a_stamp(example, tmp_path, capsys):
    """At 50 Hz the 15.625 ms tick steps by one tick or two and never repeats a stamp: the clock
    is told by its advancing intervals being shorter than the samples' (no tick seen, every
    two-tick interval was a gap and the grid 64 Hz). The conformance log summed to 50 Hz, stamped
    so, calibrates as the same samples at their true times."""
    log, _ = example
    n = log.n // 4 * 4
    end = np.arange(3, n, 4)
    slow = dataclasses.replace(
        log, time=log.time[end], gimbal={a: v[end] for a, v in log.gimbal.items()}, command={},
        gyro=log.gyro[:n].reshape(-1, 4, 3).sum(axis=1), acc=log.acc[:n].reshape(-1, 4, 3).sum(axis=1),
        temperature=None if log.temperature is None else log.temperature[end],
        segment=None, sample_rate_hz=50.0)
    ref = calibrate(LogData.from_log(slow), list(DEFAULT_EFFECTS))
    stamps = np.floor((slow.time + 0.0371) / TICK) * TICK
    assert not np.any(np.diff(stamps) == 0)
    _write(tmp_path, slow, stamps * 1e3)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    assert "a clock of 15.62 ms resolution (0% of the intervals zero)" in out, out
    assert "1 run(s), fitted rate 50.0000" in out, out
    back = read_log(tmp_path / "merged")
    assert back.n == slow.n
    _same_as(back, ref, tol=0.05)
