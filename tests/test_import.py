"""``calbench import``: the conformance vector ``example`` (a 416 s navigation-grade table log with
its truth) written out the way other software writes logs — separate IMU and table files on
different clocks and rates, deg/s and g, ADC counts with a scale and an offset, pulse counts,
jittered host time stamps in ms, angles in degrees, a decimal comma, TSV, Parquet, MAT, HDF5 —
and imported back: it calibrates to the original log's values within 0.1 σ, and the table's
clock offset is found within its reported σ. Every mistake in a mapping is one error naming the
mapping file and the key, or the input file and the column or row."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from components.cli import main
from components.errors import MappingError
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.importer import import_log
from components.logs.logfile import read_log
from components.logs.mapping import load_mapping
from components.model.effects import DEFAULT_EFFECTS

G0 = 9.80665
DEG = math.pi / 180
CLOCK = 0.0123          # s: table time + CLOCK = IMU time
RNG = np.random.default_rng(21)


@pytest.fixture(scope="module")
def original(conformance):
    log = read_log(conformance / "example")
    fit = calibrate(LogData.from_log(log), list(DEFAULT_EFFECTS))
    return log, fit


def _write_delimited(path: Path, header: list[str], cols: list[np.ndarray], delimiter: str = ",",
                     decimal: str = ".", preamble: str = "", fmt: str = "%.17g") -> None:
    """A plain text table the way a logger writes one (independent of calbench's writer)."""
    rows = np.column_stack(cols)
    lines = [preamble] if preamble else []
    lines.append(delimiter.join(header))
    for r in rows:
        cells = [fmt % x for x in r]
        if decimal != ".":
            cells = [c.replace(".", decimal) for c in cells]
        lines.append(delimiter.join(cells))
    path.write_text("\n".join(lines) + "\n")


def _mapping(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


SITE = '[site]\nlatitude_deg = 39.9\nheight_m = 50.0\n'


def _axes_toml(columns: list[str], unit: str = "deg") -> str:
    vecs = {"outer": [0, 0, 1], "middle": [1, 0, 0], "inner": [0, 0, 1]}
    return "".join(f'[[table.axes]]\nname = "{n}"\naxis = {vecs[n]}\ncolumn = "{c}"\nunit = "{unit}"\n'
                   for n, c in zip(("outer", "middle", "inner"), columns))


def _sensor_toml(sensor: str, output: str, unit: str, columns: list[str]) -> str:
    """An [imu.gyro] or [imu.acc] table: its output kind, unit and the x, y, z columns."""
    return f'[imu.{sensor}]\noutput = "{output}"\nunit = "{unit}"\n' + "".join(
        f'{a} = "{c}"\n' for a, c in zip("xyz", columns))


def _rec_csv_imu(rate_hz) -> str:
    """The [imu] of rec.csv: t [s], gx gy gz [deg/s], ax ay az [g]."""
    return f'''[imu]
file = "rec.csv"
sample_rate_hz = {rate_hz}
[imu.time]
column = "t"
[imu.gyro]
output = "rate"
unit = "deg/s"
x = "gx"
y = "gy"
z = "gz"
[imu.acc]
output = "specific_force"
unit = "g"
x = "ax"
y = "ay"
z = "az"
'''


def _fit(log) -> object:
    return calibrate(LogData.from_log(log), list(DEFAULT_EFFECTS))


def _same(fit, ref, tol=0.1):
    z = {p: (v - ref.value[ref.parameters.index(p)]) / ref.sigma[ref.parameters.index(p)]
         for p, v in zip(fit.parameters, fit.value)}
    assert sorted(fit.parameters) == sorted(ref.parameters)
    worst = max(z, key=lambda p: abs(z[p]))
    assert abs(z[worst]) < tol, (worst, z[worst])


@pytest.fixture(scope="module")
def kilohertz_run():
    """The six-position schedule simulated at 1 kHz: the table's angles at 1 kHz, the IMU summed to
    200 Hz (exact increments), and the reference log at 200 Hz with the angles of its own times."""
    import dataclasses
    import tomllib

    from components.simulation.run import run_scenario
    from components.simulation.scenario import scenario_from_dict

    root = Path(__file__).resolve().parents[1]
    d = tomllib.loads((root / "examples" / "scenarios" / "six_position.toml").read_text())
    d["scenario"]["step"] = 0.001
    d["schedule"]["overrides"]["dwell"] = 8.0
    fast = run_scenario(scenario_from_dict(d, source="test_import"), progress=False).log
    n = fast.n // 5 * 5
    # the IMU record inside the table's, by 50 ms at each end: the clock offset and the stamps'
    # jitter must not push a sample out of the table record, which would change the calibration
    end = np.arange(4, n, 5)[10:-10]
    ref = dataclasses.replace(
        fast, time=fast.time[end], gimbal={a: v[end] for a, v in fast.gimbal.items()}, command={},
        gyro=fast.gyro[:n].reshape(-1, 5, 3).sum(axis=1)[10:-10], acc=fast.acc[:n].reshape(-1, 5, 3).sum(axis=1)[10:-10],
        temperature=None if fast.temperature is None else fast.temperature[end],
        segment=fast.segment[end], sample_rate_hz=200.0, encoder_resolution="exact")
    return fast, ref, _fit(ref)


def test_separate_table_file_on_its_own_clock_deg_s_g_jitter_decimal_comma(kilohertz_run, tmp_path, capsys):
    fast, log, ref = kilohertz_run
    dt = log.dt
    # IMU at 200 Hz: host stamps in ms with ±0.2 ms jitter, rates in deg/s with y flipped and the
    # columns renamed and reordered, specific force in g, labels; TSV
    t_ms = (log.time + RNG.uniform(-2e-4, 2e-4, log.n)) * 1e3
    rate = np.degrees(log.gyro / dt)
    force = log.acc / dt / G0
    _write_delimited(tmp_path / "imu.tsv", ["stamp_ms", "wz", "wy", "wx", "ax", "ay", "az"],
                     [t_ms, rate[:, 2], -rate[:, 1], rate[:, 0], force[:, 0], force[:, 1], force[:, 2]],
                     delimiter="\t")
    # table at 1 kHz on its own clock (CLOCK behind: not a whole number of its samples), degrees,
    # ';' with a decimal comma, two lines before the header
    _write_delimited(tmp_path / "table.csv", ["t", "A", "B", "C"],
                     [fast.time - CLOCK] + [np.degrees(fast.gimbal[a]) for a in ("outer", "middle", "inner")],
                     delimiter=";", decimal=",", preamble="# turntable controller export\n# v1.2")
    m = _mapping(tmp_path / "map.toml", f'''
description = "round trip: separate files"
[imu]
file = "imu.tsv"
sample_rate_hz = 200.0
[imu.time]
column = "stamp_ms"
unit = "ms"
timing = "regularise"
[imu.gyro]
output = "rate"
unit = "deg/s"
x = "wx"
y = "-wy"
z = "wz"
[imu.acc]
output = "specific_force"
unit = "g"
x = "ax"
y = "ay"
z = "az"
[table]
file = "table.csv"
delimiter = ";"
decimal = ","
skip_rows = 2
clock_offset_s = "estimate"
encoder_resolution = "exact"
[table.time]
column = "t"
unit = "s"
{_axes_toml(["A", "B", "C"])}
{SITE}''')
    assert main(["import", str(m), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    line = [ln for ln in out.splitlines() if "combined" in ln and "clock offset" in ln][0]
    got = float(line.split("IMU")[1].split("±")[0]) * 1e-3
    sig = float(line.split("±")[1].split("ms")[0]) * 1e-3
    assert abs(got - CLOCK) < 4 * sig and sig < 1e-5, line
    assert "regularised" in out
    # every conversion said: the units and the reversed axis
    assert "gyro: rate in deg/s" in out and "y = -wy" in out and "(sign reversed: y)" in out, out
    assert "accelerometer: specific_force in g (x 9.80665 to SI)" in out
    back = read_log(tmp_path / "merged")
    assert back.version == "calbench-log/2" and back.encoder_resolution == "exact"
    # the same files imported with the true offset given calibrate 0.21 σ from the reference (the
    # 1 kHz angles interpolated at the regularised times), and ±1 µs of offset (2 of its σ) moves
    # that by 0.1 σ: 0.1 σ held only where the offset's error happened to offset the merge's
    _same(_fit(back), ref, tol=0.35)


def _regularised_rig(tmp_path: Path, table_time: np.ndarray, fast, time_column: str, time_unit: str, gyro: str,
                     acc: str, clock_offset: str) -> Path:
    """The table's angles of *fast* at *table_time* in table.csv and the mapping of an imu.csv
    stamped by a host (timing = "regularise") beside it."""
    _write_delimited(tmp_path / "table.csv", ["t", "A", "B", "C"],
                     [table_time] + [np.degrees(fast.gimbal[a]) for a in ("outer", "middle", "inner")])
    return _mapping(tmp_path / "map.toml", f'''
[imu]
file = "imu.csv"
sample_rate_hz = 200.0
[imu.time]
column = "{time_column}"
unit = "{time_unit}"
timing = "regularise"
{gyro}{acc}[table]
file = "table.csv"
clock_offset_s = {clock_offset}
encoder_resolution = "exact"
[table.time]
column = "t"
{_axes_toml(["A", "B", "C"])}
{SITE}''')


@pytest.mark.parametrize("epoch", [0.0, 1.7e9])
def test_a_table_clock_running_at_another_rate_is_estimated(kilohertz_run, tmp_path, capsys, epoch):
    """The table's controller on a crystal of its own, 300 ppm fast against the IMU's (exaggerated so
    that it shows on two minutes: two crystals are tens of ppm apart, 43 ms over 36 minutes at 20
    ppm, and one offset left a 26-position log at χ²/dof 10,000), its clock's origin 30 s off; the
    IMU's host stamps also in Unix epoch seconds (the search for the offset spanned both records
    on one grid: 5 TB for a controller counting from its power-on). The offset and the rate from
    the rates' match: each within 4 of its σ of the truth; the log calibrates within
    1 + 4√(2/dof)."""
    fast, log, _ = kilohertz_run
    rng = np.random.default_rng(9)
    gain = 300e-6
    t_tab = (fast.time - CLOCK) * (1 + gain) + 30.0  # the controller's clock, started 30 s before
    t_ms = (epoch + log.time + rng.uniform(-2e-4, 2e-4, log.n)) * 1e3
    inc, vel = np.degrees(log.gyro), log.acc * 1e3
    _write_delimited(tmp_path / "imu.csv", ["t_ms", "dx", "dy", "dz", "vx", "vy", "vz"],
                     [t_ms, inc[:, 0], inc[:, 1], inc[:, 2], vel[:, 0], vel[:, 1], vel[:, 2]])
    m = _regularised_rig(tmp_path, t_tab, fast, "t_ms", "ms", _sensor_toml("gyro", "increment", "deg", ["dx", "dy", "dz"]),
                         _sensor_toml("acc", "increment", "mm/s", ["vx", "vy", "vz"]), '"estimate"')
    assert main(["import", str(m), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    said = re.search(r"clock offset table -> IMU ([+-][\d.]+) ± ([\d.e-]+) ms at the table's first sample, the IMU's "
                     r"clock ([+-][\d.e+-]+) ± ([\d.e-]+) ppm against the table's", out)
    assert said, out
    offset, s_offset, rate, s_rate = (float(v) for v in said.groups())
    truth_offset = epoch + fast.time[0] - t_tab[0]  # IMU time - table time at the table's first sample
    truth_rate = 1 / (1 + gain) - 1         # the IMU's seconds per table second, less one
    print(f"offset {offset:+.6f} ± {s_offset:.2g} ms (truth {truth_offset * 1e3:+.6f}); "
          f"rate {rate:+.6g} ± {s_rate:.2g} ppm (truth {truth_rate * 1e6:+.6g})")
    assert abs(offset * 1e-3 - truth_offset) < 4 * s_offset * 1e-3
    assert abs(rate - truth_rate * 1e6) < 4 * s_rate
    assert "followed: degree" not in out, out  # a rate that does not change: the line, no curve
    fit = _fit(read_log(tmp_path / "merged"))
    print(f"chi2/dof {fit.chi2 / fit.dof:.4f} over {fit.dof}")
    assert fit.chi2 / fit.dof < 1 + 4 * math.sqrt(2 / fit.dof), (fit.chi2 / fit.dof, fit.dof)
    # the two given, as a user who knows them writes them: the same log
    m.write_text(m.read_text().replace('clock_offset_s = "estimate"', f"clock_offset_s = {float(truth_offset)!r}\n"
                                       f"clock_rate_ppm = {float(truth_rate) * 1e6!r}"))
    assert main(["import", str(m), "--out", str(tmp_path / "given")]) == 0
    assert "ppm against the table's (given)" in capsys.readouterr().out
    fit = _fit(read_log(tmp_path / "given"))
    assert fit.chi2 / fit.dof < 1 + 4 * math.sqrt(2 / fit.dof), (fit.chi2 / fit.dof, fit.dof)
    with pytest.raises(MappingError, match="'table.clock_rate_ppm': with table.clock_offset_s = 'estimate'"):
        load_mapping(_mapping(tmp_path / "map.toml", m.read_text().replace(f"clock_offset_s = {float(truth_offset)!r}",
                                                                           'clock_offset_s = "estimate"')))


def test_lost_packets_of_an_increment_output_do_not_shift_the_clock_offset(kilohertz_run, tmp_path, capsys):
    """Packets lost from an increment output (1 % of the rows, at random) take their increments
    with them: the sample after each covers its own interval, not the gap. Matched against the
    table's turn over the gap, 0.5-1 % of the moving samples pulled the offset from the rates off
    by many of its σ; left out (as the log leaves them out), it is found within 4 σ."""
    fast, log, _ = kilohertz_run
    rng = np.random.default_rng(4)
    kept = rng.random(log.n) > 0.01
    kept[[0, -1]] = True
    t_ms = (log.time + rng.uniform(-2e-4, 2e-4, log.n)) * 1e3
    inc, vel = np.degrees(log.gyro), log.acc * 1e3
    _write_delimited(tmp_path / "imu.csv", ["t_ms", "dx", "dy", "dz", "vx", "vy", "vz"],
                     [c[kept] for c in (t_ms, inc[:, 0], inc[:, 1], inc[:, 2], vel[:, 0], vel[:, 1], vel[:, 2])])
    m = _regularised_rig(tmp_path, fast.time - CLOCK, fast, "t_ms", "ms",
                         _sensor_toml("gyro", "increment", "deg", ["dx", "dy", "dz"]),
                         _sensor_toml("acc", "increment", "mm/s", ["vx", "vy", "vz"]), '"estimate"')
    assert main(["import", str(m), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    assert "gap(s) longer than" in out
    got, sig = (float(v) * 1e-3 for v in re.search(r"matched on the rates ([+-][\d.]+) ± ([\d.e-]+) ms", out).groups())
    print(f"matched on the rates: {got * 1e3:.4f} ± {sig * 1e3:.2g} ms (truth {CLOCK * 1e3} ms)")
    assert abs(got - CLOCK) < 4 * sig and sig < 1e-4, (got, sig)
    # the runs between the gaps on one grid interval: each sample's increment set against the
    # motion over the sensor's own interval, so the fit is as good as the log's noise allows
    fit = _fit(read_log(tmp_path / "merged"))
    print(f"the exact log: chi2/dof {kilohertz_run[2].chi2 / kilohertz_run[2].dof:.4f}")
    print(f"chi2/dof {fit.chi2 / fit.dof:.4f} over {fit.dof}")
    assert fit.chi2 / fit.dof < 1 + 4 * math.sqrt(2 / fit.dof), (fit.chi2 / fit.dof, fit.dof)


def test_a_table_clock_whose_rate_changes_is_followed(kilohertz_run, tmp_path, capsys):
    """The table controller's crystal warming: its rate soaks by 200 ppm against the IMU's (towards
    it over a quarter of the record; exaggerated so that it shows on two minutes: an uncompensated
    crystal moves ppm over its first hour, and 1 ppm over 36 minutes left a 26-position log at
    χ²/dof 1.10 on the best line). The offset then bows away from any line; followed as a
    polynomial in time, the import says the bow (the truth's within 25 %), the offset at the
    table's first sample is the truth's within 4 of its σ, and the log calibrates as the exact
    log does (χ²/dof within 1 + 4√(2/dof), the estimates within a σ of the exact log's)."""
    fast, log, _ = kilohertz_run
    rng = np.random.default_rng(10)
    u = fast.time - fast.time[0]
    soak = 200e-6 * (1 - np.exp(-u / (u[-1] / 4)))
    extra = np.concatenate([[0.0], np.cumsum(np.diff(u) * 0.5 * (soak[1:] + soak[:-1]))])
    t_tab = fast.time - CLOCK + extra
    t_s = log.time + rng.uniform(-2e-4, 2e-4, log.n)
    _write_delimited(tmp_path / "imu.csv", ["t", "dx", "dy", "dz", "vx", "vy", "vz"], [t_s, *log.gyro.T, *log.acc.T])
    m = _regularised_rig(tmp_path, t_tab, fast, "t", "s", _sensor_toml("gyro", "increment", "rad", ["dx", "dy", "dz"]),
                         _sensor_toml("acc", "increment", "m/s", ["vx", "vy", "vz"]), '"estimate"')
    assert main(["import", str(m), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    said = re.search(r"clock offset table -> IMU ([+-][\d.]+) ± ([\d.e-]+) ms at the table's first sample", out)
    bow = re.search(r"the offset bowing up to ([\d.e-]+) ms off its line \(followed", out)
    assert said and bow, out
    offset, s_offset = (float(v) for v in said.groups())
    truth_offset = fast.time[0] - t_tab[0]
    # the truth's bow: the table's time less its best line, over the IMU's record
    inside = (fast.time >= log.time[0]) & (fast.time <= log.time[-1])
    x, e = fast.time[inside], extra[inside]
    truth_bow = float(np.max(np.abs(e - np.polyval(np.polyfit(x - x.mean(), e, 1), x - x.mean()))))
    print(f"offset {offset:+.6f} ± {s_offset:.2g} ms (truth {truth_offset * 1e3:+.6f}); bow {bow.group(1)} ms "
          f"(truth {truth_bow * 1e3:.4g})")
    assert abs(offset * 1e-3 - truth_offset) < 4 * s_offset * 1e-3
    assert float(bow.group(1)) * 1e-3 == pytest.approx(truth_bow, rel=0.25)
    fit = _fit(read_log(tmp_path / "merged"))
    print(f"chi2/dof {fit.chi2 / fit.dof:.4f} over {fit.dof}")
    assert fit.chi2 / fit.dof < 1 + 4 * math.sqrt(2 / fit.dof), (fit.chi2 / fit.dof, fit.dof)
    _same(fit, kilohertz_run[2], tol=1.0)


def _drifting_rig(kilohertz_run, tmp_path: Path, drifts: str, table: str, keeps: str = "host",
                  table_clock: str | None = None) -> Path:
    """The mapping of a rig whose *drifts* clock ("sensor" or "host") drifts against the other: its
    rate moving by 100 ppm over the two-minute log (exaggerated so that it shows here; a crystal in
    a thermal chamber moves tens of ppm over half an hour). The host stamps the IMU's samples
    (±0.2 ms jitter); the *table* file's angles are stamped by the "host" too (offset 0), or by a
    "controller" on a clock that keeps true time, 5 ms behind (the offset estimated). The mapping
    says *keeps* and *table_clock* (None: not said).
    Emulated from the simulated log: host time = its time warped by the rate change; where the
    sensor's clock is the one that drifts, true time is the host's and each interval's increment
    of gravity is longer by it (the gyros' turn is the table's, whatever the clock)."""
    fast, log, _ = kilohertz_run
    rng = np.random.default_rng(6)
    span = float(fast.time[-1] - fast.time[0])
    beta = 100e-6 / span  # the rate's change per second

    def host(t):
        return t + 0.5 * beta * (t - fast.time[0]) ** 2

    stretch = 1 + beta * (log.time - fast.time[0]) if drifts == "sensor" else np.ones(log.n)
    t_s = host(log.time) + rng.uniform(-2e-4, 2e-4, log.n)
    rate, force = log.gyro / log.dt, log.acc / log.dt * stretch[:, None]
    _write_delimited(tmp_path / "imu.csv", ["t", "wx", "wy", "wz", "fx", "fy", "fz"],
                     [t_s, *rate.T, *force.T])
    true = host(fast.time) if drifts == "sensor" else fast.time
    m = _regularised_rig(tmp_path, true - 5e-3 if table == "controller" else host(fast.time), fast, "t", "s",
                         _sensor_toml("gyro", "rate", "rad/s", ["wx", "wy", "wz"]),
                         _sensor_toml("acc", "specific_force", "m/s2", ["fx", "fy", "fz"]),
                         '"estimate"' if table == "controller" else "0.0")
    text = m.read_text().replace('timing = "regularise"', f'timing = "regularise"\nkeeps_time = "{keeps}"')
    if table_clock:
        text = text.replace('[table.time]\ncolumn = "t"', f'[table.time]\ncolumn = "t"\nclock = "{table_clock}"')
    m.write_text(text)
    return m


@pytest.mark.parametrize("drifts, table, keeps", [("sensor", "host", "host"), ("host", "host", "sensor"),
                                                  ("host", "controller", "sensor")])
def test_a_sensor_clock_drifting_against_the_host_is_followed(kilohertz_run, tmp_path, capsys, drifts, table, keeps):
    """One clock drifts against the other (_drifting_rig). The sensor's samples then bow ~1 ms away
    from any one regular grid on the host's clock, and the samples set against the table's motion
    there misfit; followed on a smooth clock, the calibration fits as the exact log does: χ²/dof
    within 1 + 4√(2/dof), its estimates within a σ of the exact log's.
    - the sensor's clock drifts (the host keeps time, the default): the log follows the host;
    - the host's clock drifts (``keeps_time = "sensor"``): the log's time is the sensor's clock (its
      nominal intervals), the table's angles taken at the host's stamps (``table.time.clock =
      "host"``);
    - the host's clock drifts, and the table's angles come from a controller that stamps them on
      its own clock (``table.time.clock = "controller"``): matched at the host's stamps, the angles
      stood up to the bow (1 ms) off. The import finds nothing to say about the clocks."""
    fast = kilohertz_run[0]
    span = float(fast.time[-1] - fast.time[0])
    m = _drifting_rig(kilohertz_run, tmp_path, drifts, table, keeps, table if keeps == "sensor" else None)
    assert main(["import", str(m), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    said = re.search(r"clock drifts against the host's: its stamps bow up to ([\d.]+) ms .* rate moving over ([\d.]+) ppm",
                     out)
    assert said, out
    assert "warning: the table's clock" not in out, out
    bow, moving = (float(v) for v in said.groups())
    # t² on [0, T] lies within T²/6 of its best line: the bow is Δ·T/12
    assert bow * 1e-3 == pytest.approx(100e-6 * span / 12, rel=0.1), said.group(0)
    assert moving == pytest.approx(100, rel=0.1), said.group(0)
    merged = read_log(tmp_path / "merged")
    if keeps == "sensor":
        # the log's time the sensor's regular clock: its intervals equal to the float's last digits
        assert np.ptp(np.diff(merged.time)) < 1e-12
    fit = _fit(merged)
    print(f"chi2/dof {fit.chi2 / fit.dof:.4f} over {fit.dof}; the exact log "
          f"{kilohertz_run[2].chi2 / kilohertz_run[2].dof:.4f}")
    assert fit.chi2 / fit.dof < 1 + 4 * math.sqrt(2 / fit.dof), (fit.chi2 / fit.dof, fit.dof)
    # and the estimates are the exact log's, within a σ of theirs: where the host's clock drifts,
    # the log's intervals on the grid the host's stamps show were 50 ppm long, and every
    # accelerometer scale factor 44 σ off with a χ² as good as the exact log's
    _same(fit, kilohertz_run[2], tol=1.0)


@pytest.mark.parametrize("drifts, keeps, other, tell", [
    ("host", "host", +1, "keeps the sensor's time, not the host's: .* give imu.time.keeps_time = 'sensor' and "
                         "table.time.clock = 'controller'"),
    ("sensor", "sensor", -1, r"keeps the host's time, not the sensor's: .*\(imu.time.keeps_time = 'host'\), or .*"
                             r"\(table.time.clock = 'host'\)")])
def test_a_table_controller_tells_which_clock_drifts(kilohertz_run, tmp_path, capsys, drifts, keeps, other, tell):
    """The stamps cannot tell whether the sensor's clock or the host's drifts; a table controller on
    a third clock that keeps time can: matched against the log's time, its offsets bow with the
    host's stamps where the mapping names the wrong clock (all of the bow, ±1 by the frame), and
    the import says so and what to write. Found: a 26-position log whose host drifted, imported
    with the default keeps_time, calibrated to χ²/dof 25.8 with nothing said but a rate σ 100
    times its usual."""
    m = _drifting_rig(kilohertz_run, tmp_path, drifts, "controller", keeps, "controller" if keeps == "sensor" else None)
    assert main(["import", str(m), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    said = re.search(r"warning: the table's clock " + tell, out)
    assert said, out
    a, sa = (float(v) for v in re.search(r"follow ([+-][\d.]+) ± ([\d.e-]+) of the host stamps' bow", out).groups())
    assert abs(a - other) <= 5 * sa, (a, sa)


@pytest.mark.parametrize("origin", [123.4, 1.7e9])
def test_regularised_runs_share_the_sensors_interval(origin):
    """Stamps of a regular clock (5.0001 ms) with ±0.3 ms uniform jitter and 1 % of the samples
    lost, in runs between the gaps: one grid through every run (the gaps whole intervals), its
    interval within 4 of the line fit's σ (jitter / √Σ(k − k̄)² over all samples) and every time
    within 5 of the fit's largest σ (2 jitter / √N at the ends) of the truth: 4 us here, where
    each run placed by its own stamps is off by jitter / √(run length), 17 us for 100 samples.
    A sensor restarted out of phase (0.4 of an interval) keeps each part on its own grid. The
    same from an epoch origin (1.7e9 s; float64 resolves 0.24 us there): summed from it, the
    grid's k·t sums lost 14 us."""
    from components.logs.timebase import regularise

    rng = np.random.default_rng(8)
    d, n = 5.0001e-3, 200_000
    kept = rng.random(n) > 0.01
    true = (origin + d * np.arange(n))[kept]
    jitter = 3e-4 / math.sqrt(3)  # σ of a uniform ±0.3 ms
    reg = regularise(true + rng.uniform(-3e-4, 3e-4, len(true)), 5e-3, 7.5e-3)
    assert reg.runs > 1000
    index = np.flatnonzero(kept).astype(float)
    sigma_d = jitter / math.sqrt(float(np.sum((index - index.mean()) ** 2)))
    assert abs(1 / reg.rate_hz - d) < 4 * sigma_d
    assert np.max(np.abs(reg.time - true)) < 5 * 2 * jitter / math.sqrt(len(true))
    assert reg.drift is None  # a regular clock: no correction beats none
    # restarted half a log later, 0.4 of an interval out of the first part's phase
    second = true[-1] + 3.4 * d + d * np.arange(50_000)
    both = np.concatenate([true, second])
    reg = regularise(both + rng.uniform(-3e-4, 3e-4, len(both)), 5e-3, 7.5e-3)
    cut = len(true)
    for part in (slice(0, cut), slice(cut, None)):
        err = reg.time[part] - both[part]
        assert np.max(np.abs(err)) < 5 * 2 * jitter / math.sqrt(len(err)) + 20 * d * sigma_d / d, np.max(np.abs(err))


@pytest.mark.parametrize("layout", ["parquet", "mat", "hdf5"])
def test_single_file_layouts_with_adc_counts_and_pulse_counts(original, tmp_path, layout):
    """Gyro rates as 24-bit ADC counts with a scale and an offset (a Xsens-like raw record), the
    accelerometers as pulse counts (increments in units of 1e-9 m/s, remainder carried), angles
    in degrees in the same file."""
    log, ref = original
    dt = log.dt
    scale, offset = 1e-7, 1000.0              # deg/s per count, counts at zero rate
    adc = np.round(np.degrees(log.gyro / dt) / scale + offset)
    w = 1e-9
    pulses = np.diff(np.round(np.cumsum(log.acc, axis=0) / w), axis=0, prepend=0.0)
    cols = {"time_s": log.time, "gx": adc[:, 0], "gy": adc[:, 1], "gz": adc[:, 2],
            "px": pulses[:, 0], "py": pulses[:, 1], "pz": pulses[:, 2],
            **{f"ang_{a}": np.degrees(log.gimbal[a]) for a in ("outer", "middle", "inner")}}
    if layout == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        pq.write_table(pa.table(cols), tmp_path / "rec.parquet")
        fname = "rec.parquet"
    elif layout == "mat":
        import scipy.io

        scipy.io.savemat(tmp_path / "rec.mat", {"t": log.time[:, None], "gyro_adc": adc, "acc_pulses": pulses,
                                                "angles_deg": np.column_stack([cols["ang_outer"], cols["ang_middle"],
                                                                               cols["ang_inner"]])})
        fname = "rec.mat"
    else:
        h5py = pytest.importorskip("h5py")
        with h5py.File(tmp_path / "rec.h5", "w") as f:
            f["imu/time"] = log.time
            f["imu/gyro"] = adc
            f["imu/acc"] = pulses
            f["table/angles"] = np.column_stack([cols["ang_outer"], cols["ang_middle"], cols["ang_inner"]])
        fname = "rec.h5"
    names = {"parquet": ("time_s", "gx", "gy", "gz", "px", "py", "pz", "ang_outer", "ang_middle", "ang_inner"),
             "mat": ("t", "gyro_adc:0", "gyro_adc:1", "gyro_adc:2", "acc_pulses:0", "acc_pulses:1", "acc_pulses:2",
                     "angles_deg:0", "angles_deg:1", "angles_deg:2"),
             "hdf5": ("imu/time", "imu/gyro:0", "imu/gyro:1", "imu/gyro:2", "imu/acc:0", "imu/acc:1", "imu/acc:2",
                      "table/angles:0", "table/angles:1", "table/angles:2")}[layout]
    m = _mapping(tmp_path / "map.toml", f'''
[imu]
file = "{fname}"
sample_rate_hz = 200.0
[imu.time]
column = "{names[0]}"
[imu.gyro]
output = "rate"
unit = "deg/s"
scale = {scale}
offset = {offset}
x = "{names[1]}"
y = "{names[2]}"
z = "{names[3]}"
[imu.acc]
output = "counts"
count = "1e-9 m/s"
x = "{names[4]}"
y = "{names[5]}"
z = "{names[6]}"
[table]
encoder_resolution = "exact"
{_axes_toml(names[7:])}
{SITE}''')
    assert main(["import", str(m), "--out", str(tmp_path / "imported")]) == 0
    back = read_log(tmp_path / "imported")
    assert back.acc_output == "counts" and back.acc_count_mps == pytest.approx(1e-9)
    _same(_fit(back), ref)


def test_noisy_angles_rounded_to_the_encoders_count(original, tmp_path):
    """An interpolating encoder's angles: the counts plus reading noise (0.1 count RMS), so no two
    samples repeat and no rest survives. Imported with round_to_count they are the counts again
    (a sample's noise beyond half a count is a 5-sigma event) and calibrate as the original;
    without it calibrate names the angles and the mapping key, not the noise."""
    from components.errors import EstimationError

    log, ref = original
    q = 1e-7  # rad: the independent simulator writes its angles in whole 1e-7 rad
    assert np.abs(np.round(log.angles / q) * q - log.angles).max() < 1e-14
    noisy = {a: log.gimbal[a] + RNG.normal(0.0, 0.1 * q, log.n) for a in ("outer", "middle", "inner")}
    cols = [log.time, *(np.degrees(log.gyro[:, k] / log.dt) for k in range(3)),
            *(log.acc[:, k] / log.dt / G0 for k in range(3)), *(np.degrees(noisy[a]) for a in noisy)]
    _write_delimited(tmp_path / "rec.csv", ["t", "gx", "gy", "gz", "ax", "ay", "az", "A1", "A2", "A3"], cols)
    text = _rec_csv_imu(1 / log.dt) + f'''[table]
encoder_resolution = "{q!r} rad"
ROUND
{_axes_toml(["A1", "A2", "A3"])}
{SITE}'''
    m = _mapping(tmp_path / "map.toml", text.replace("ROUND", "round_to_count = true"))
    assert main(["import", str(m), "--out", str(tmp_path / "rounded")]) == 0
    _same(_fit(read_log(tmp_path / "rounded")), ref)
    m = _mapping(tmp_path / "map.toml", text.replace("ROUND", ""))
    assert main(["import", str(m), "--out", str(tmp_path / "raw")]) == 0
    with pytest.raises(EstimationError, match="change at every sample.*round_to_count"):
        _fit(read_log(tmp_path / "raw"))
    m = _mapping(tmp_path / "map.toml", text.replace("ROUND", "round_to_count = true").replace(
        f'encoder_resolution = "{q!r} rad"', 'encoder_resolution = "exact"'))
    with pytest.raises(MappingError, match="'table.round_to_count' = true needs 'table.encoder_resolution'"):
        import_log(load_mapping(m))


LABELS = '\n[labels]\n[[labels.ranges]]\nfrom = 0\nto = 1\nlabel = "a"\n'
# a table file beside the IMU's (the recording itself: the mapping's load looks at no column)
TABLE_FILE = ('\n[table]\nfile = "rec.csv"\n[table.time]\ncolumn = "t"\n'
              '[[table.axes]]\nname = "outer"\naxis = [0, 0, 1]\ncolumn = "gx"\n')


@pytest.mark.parametrize("edit, match", [
    (lambda s: s.replace('sample_rate_hz = 200.0', 'sample_rate_hz = -1'), r"map.toml: key 'imu.sample_rate_hz'"),
    (lambda s: s.replace('unit = "deg/s"', 'unit = "deg/min"'), r"key 'imu.gyro.unit' = 'deg/min': expected one of"),
    (lambda s: s.replace('x = "gx"', 'x = "gq"'), r"rec.csv: imu.gyro.x: no column 'gq'; the file has: t, gx"),
    (lambda s: s.replace('output = "specific_force"', 'output = "force"'), r"key 'imu.acc.output' = 'force'"),
    (lambda s: s.replace('[imu.time]\ncolumn = "t"', '[imu.time]\ncolumn = "t"\ntiming = "jittery"'),
     r"key 'imu.time.timing' = 'jittery'"),
    (lambda s: s.replace('[imu.time]\ncolumn = "t"', '[imu.time]\ncolumn = "t"\nkeeps_time = "table"'),
     r"key 'imu.time.keeps_time' = 'table': expected one of host, sensor"),
    (lambda s: s.replace('[imu.time]\ncolumn = "t"', '[imu.time]\ncolumn = "t"\nkeeps_time = "sensor"'),
     r"key 'imu.time.keeps_time' = 'sensor': .* only timing = 'regularise' follows \(timing is 'nominal'\)"),
    (lambda s: s.replace('file = "rec.csv"', 'file = "nope.csv"'), r"nope.csv: the input file does not exist"),
    (lambda s: s.replace('[imu.time]\ncolumn = "t"', '[imu.time]\ncolumn = "t"\ntiming = "regularise"\n'
                         'keeps_time = "sensor"') + TABLE_FILE,
     r"map.toml: key 'table.time.clock' is needed with imu.time.keeps_time = 'sensor' .* 'host' .* 'controller'"),
    (lambda s: s + TABLE_FILE.replace('column = "t"', 'column = "t"\nclock = "ntp"'),
     r"key 'table.time.clock' = 'ntp': expected one of host, controller"),
    (lambda s: s.replace('[site]\nlatitude_deg = 39.9', '[site]\nlatitude_deg = 99'), r"key 'site.latitude_deg' = 99"),
    (lambda s: s + '\n[labels]\ncolumn = "t"\n[[labels.ranges]]\nfrom = 0\nto = 1\nlabel = "a"\n',
     r"give a column or ranges, not both"),
    # found later, by what they break, before these were checked at the import
    (lambda s: s.replace('[imu.time]\ncolumn = "t"', '[imu.time]\ncolumn = "t"\nunit = "ms"'),
     r"map.toml: the imu file's time stamps' median interval is 5e-06 s .* 0.001 x 1/imu.sample_rate_hz .*imu.time.unit"),
    (lambda s: s.replace('sample_rate_hz = 200.0', 'sample_rate_hz = 100.0'), r"0.5 x 1/imu.sample_rate_hz"),
    (lambda s: s + LABELS + '[segments]\na = { kind = "static" }\nb = { kind = "static" }\n',
     r"map.toml: key 'segments' names label\(s\) 'b' that no sample carries; expected labels of the data \(a\)"),
    (lambda s: 'exclude = ["b"]\n' + s + LABELS, r"map.toml: key 'exclude' names label\(s\) 'b' that no sample"),
])
def test_mapping_mistakes_are_one_clear_error(tmp_path, edit, match):
    t = np.arange(1, 101) * 0.005
    _write_delimited(tmp_path / "rec.csv", ["t", "gx", "gy", "gz", "ax", "ay", "az"],
                     [t] + [np.zeros(100)] * 5 + [np.ones(100)])
    text = _rec_csv_imu(200.0) + SITE
    m = _mapping(tmp_path / "map.toml", edit(text))
    with pytest.raises(MappingError, match=match):
        import_log(load_mapping(m))


# a recording of one gyro and one accelerometer column, in SI, for the bad-cell cases
_PLAIN_MAPPING = '''[imu]
file = "rec.csv"
sample_rate_hz = 200.0
[imu.time]
column = "t"
[imu.gyro]
output = "rate"
unit = "rad/s"
x = "g"
y = "g"
z = "g"
[imu.acc]
output = "specific_force"
unit = "m/s2"
x = "a"
y = "a"
z = "a"
'''


def test_a_non_number_and_backwards_time_name_their_row(tmp_path, capsys):
    t = np.arange(1, 11) * 0.005
    _write_delimited(tmp_path / "rec.csv", ["t", "g", "a"], [t, np.zeros(10), np.ones(10)])
    lines = (tmp_path / "rec.csv").read_text().splitlines()
    lines[4] = lines[4].replace("0,1", "x,1")
    (tmp_path / "rec.csv").write_text("\n".join(lines) + "\n")
    m = _mapping(tmp_path / "map.toml", _PLAIN_MAPPING + SITE)
    assert main(["import", str(m), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "rec.csv" in err and "Traceback" not in err


def test_a_parquet_file_is_read_only_for_the_columns_the_mapping_names(original, tmp_path, monkeypatch, capsys):
    """A long recording's Parquet file is read a named column at a time (never whole, nor the
    columns no key names); its text column becomes labels sharing one string per distinct value
    (one per row was ~50 bytes a sample); the imported log is the original, labels included."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    log, _ = original
    cols = {"time_s": log.time, **{f"g{c}": log.gyro[:, k] for k, c in enumerate("xyz")},
            **{f"a{c}": log.acc[:, k] for k, c in enumerate("xyz")},
            **{f"ang_{a}": log.gimbal[a] for a in ("outer", "middle", "inner")},
            "label": pa.array([str(s) for s in log.segment]), "unused": np.arange(log.n, dtype=float)}
    pq.write_table(pa.table(cols), tmp_path / "rec.parquet")
    read = []
    real = pq.ParquetFile.read
    monkeypatch.setattr(pq.ParquetFile, "read", lambda self, columns=None, **kw: read.append(columns) or
                        real(self, columns=columns, **kw))
    m = _mapping(tmp_path / "map.toml", f'''
[imu]
file = "rec.parquet"
sample_rate_hz = {1.0 / log.dt}
[imu.time]
column = "time_s"
[imu.gyro]
output = "increment"
unit = "rad"
x = "gx"
y = "gy"
z = "gz"
[imu.acc]
output = "increment"
unit = "m/s"
x = "ax"
y = "ay"
z = "az"
[labels]
column = "label"
[table]
encoder_resolution = "exact"
{_axes_toml(["ang_outer", "ang_middle", "ang_inner"], unit="rad")}
{SITE}''')
    assert main(["import", str(m), "--out", str(tmp_path / "imported"), "--format", "parquet"]) == 0
    assert all(c is not None and len(c) == 1 for c in read) and ["unused"] not in read
    back = read_log(tmp_path / "imported")
    assert back.segment.tolist() == [str(s) for s in log.segment]
    assert np.array_equal(back.gyro, log.gyro) and np.array_equal(back.time, log.time)

    from components.logs.mapping import load_mapping
    from components.logs.sources import Columns

    mapping = load_mapping(m)
    labels = Columns(mapping.imu).text(mapping.labels, "labels")
    assert len({id(x) for x in labels}) == len(set(labels.tolist()))
    # an empty label (a null in the file) is refused as it is in a CSV source; it became the label 'None'
    holed = [str(s) for s in log.segment]
    holed[7] = None
    pq.write_table(pa.table({**cols, "label": pa.array(holed, pa.string())}), tmp_path / "rec.parquet")
    assert main(["import", str(m), "--out", str(tmp_path / "holed")]) == 2
    assert "labels.column: row 8: empty label" in capsys.readouterr().err


def _one_rest_mapping(gyro: tuple[str, str, str], more: str = "") -> str:
    """The mapping of imu.csv (columns t, the gyro's three, 'one' and 'zero'): rates in deg/s from
    the columns *gyro*, the accelerometers reading 1 g on z, the first 10 s one rest, no table;
    *more* (TOML) besides."""
    x, y, z = gyro
    return f'''
[imu]
file = "imu.csv"
sample_rate_hz = 200.0
[imu.time]
column = "t"
[imu.gyro]
output = "rate"
unit = "deg/s"
x = "{x}"
y = "{y}"
z = "{z}"
[imu.acc]
output = "specific_force"
unit = "g"
x = "zero"
y = "zero"
z = "one"
{more}
[labels]
[[labels.ranges]]
from = 0.0
to = 10.0
label = "pos01"
[segments]
pos01 = {{ kind = "static" }}
{SITE}'''


def test_a_csv_column_used_twice_is_the_same_both_times(tmp_path):
    """A CSV column is dropped from the parsed file once converted; a mapping that names it twice
    (here one gyro column for two axes, one flipped) gets it again, the same values."""
    n = 400
    t = np.arange(n) * 0.005
    w = np.sin(np.arange(n) * 0.01) * 10.0       # deg/s
    _write_delimited(tmp_path / "imu.csv", ["t", "w", "one", "zero"], [t, w, np.ones(n), np.zeros(n)])
    m = _mapping(tmp_path / "map.toml", _one_rest_mapping(("w", "-w", "zero")))
    assert main(["import", str(m), "--out", str(tmp_path / "imported")]) == 0
    back = read_log(tmp_path / "imported")
    rate = np.radians(w)
    assert np.allclose(back.gyro[:, 0] / back.dt if back.gyro_output == "increment" else back.gyro[:, 0], rate,
                       rtol=1e-12, atol=0)
    assert np.array_equal(back.gyro[:, 1], -back.gyro[:, 0]) and not back.gyro[:, 2].any()


# a thermometer's fixed points in each unit a rig may log, and the same temperatures in °C: ice,
# boiling water, the point where the Fahrenheit and Celsius scales meet, a body
FIXED_POINTS_DEGC = [0.0, 100.0, -40.0, 37.0]
FIXED_POINTS = {"degC": FIXED_POINTS_DEGC, "degF": [32.0, 212.0, -40.0, 98.6], "K": [273.15, 373.15, 233.15, 310.15]}


@pytest.mark.parametrize("unit", sorted(FIXED_POINTS))
def test_a_temperature_column_in_any_unit_is_read_as_degC(tmp_path, capsys, unit):
    """A rig's thermometer in °F or kelvin (the foreign rig of benchmarks/foreign_rig.py writes
    °F) is read in °C, the unit every temperature effect's coefficient is per; the import says
    it converted."""
    n = 400
    t = np.arange(n) * 0.005
    temp = np.repeat(FIXED_POINTS[unit], n // 4)
    _write_delimited(tmp_path / "imu.csv", ["t", "one", "zero", "T"], [t, np.ones(n), np.zeros(n), temp])
    m = _mapping(tmp_path / "map.toml", _one_rest_mapping(("zero", "zero", "zero"),
                                                          f'[imu.temperature]\ncolumn = "T"\nunit = "{unit}"'))
    assert main(["import", str(m), "--out", str(tmp_path / "imported")]) == 0
    said = capsys.readouterr()
    assert ("converted to degC" in said.out + said.err) == (unit != "degC")
    back = read_log(tmp_path / "imported")
    assert np.allclose(back.temperature, np.repeat(FIXED_POINTS_DEGC, n // 4), rtol=0, atol=1e-9)


@pytest.mark.parametrize("edit, words", [
    # an empty cell was "np.float64(nan) is not finite"; a NaN written as such is said as a number
    (lambda ls: ls.__setitem__(5, ls[5].replace(",0,", ",,")), r"rec.csv: column 'g': row 5: empty value; expected a number"),
    (lambda ls: ls.__setitem__(5, ls[5].replace(",0,", ",nan,")), r"imu.gyro.x: row 5: nan is not finite"),
    # a blank line was skipped, and every later row number was one off the file's
    (lambda ls: ls.insert(4, ""), r"rec.csv: data row 4 \(line 5\): blank line; expected a sample on every line"),
    # times said as numbers, not numpy's reprs
    (lambda ls: ls.__setitem__(6, "0.01" + ls[6][ls[6].index(","):]), r"imu.time: row 6: 0.01 s after 0.025 s"),
])
def test_import_bad_cells_are_said_plainly_at_the_files_row(tmp_path, capsys, edit, words):
    t = np.arange(1, 11) * 0.005
    _write_delimited(tmp_path / "rec.csv", ["t", "g", "a"], [t, np.zeros(10), np.ones(10)])
    lines = (tmp_path / "rec.csv").read_text().splitlines()
    edit(lines)
    (tmp_path / "rec.csv").write_text("\n".join(lines) + "\n")
    m = _mapping(tmp_path / "map.toml", _PLAIN_MAPPING + SITE)
    assert main(["import", str(m), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert re.search(words, err), err
    assert "np.float64" not in err and "Traceback" not in err


def test_import_takes_blank_lines_at_the_end_of_a_csv(tmp_path, capsys):
    t = np.arange(1, 11) * 0.005
    _write_delimited(tmp_path / "rec.csv", ["t", "g", "a", "ang"], [t, np.zeros(10), np.ones(10), np.zeros(10)])
    (tmp_path / "rec.csv").write_text((tmp_path / "rec.csv").read_text() + "\n\n")
    m = _mapping(tmp_path / "map.toml", _PLAIN_MAPPING + SITE + '''
[table]
encoder_resolution = "exact"
[[table.axes]]
name = "outer"
axis = [0, 0, 1]
column = "ang"
unit = "rad"
''')
    assert main(["import", str(m), "--out", str(tmp_path / "o")]) == 0
    assert read_log(tmp_path / "o").n == 10


def test_import_names_an_empty_number_in_a_parquet_source(tmp_path, capsys):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = np.arange(1, 11) * 0.005
    g = pa.array([0.0] * 7 + [None] + [0.0] * 2, pa.float64())
    pq.write_table(pa.table({"t": t, "g": g, "a": np.ones(10)}), tmp_path / "rec.parquet")
    m = _mapping(tmp_path / "map.toml", _PLAIN_MAPPING.replace("rec.csv", "rec.parquet") + SITE)
    assert main(["import", str(m), "--out", str(tmp_path / "o")]) == 2
    assert "rec.parquet: column 'g': row 8: empty value; expected a number" in capsys.readouterr().err


def test_jitter_that_passes_for_gaps_is_said_with_the_interval_to_give(kilohertz_run, tmp_path, capsys):
    """A 1 kHz sensor stamped with ±0.1 ms of jitter under a max_interval_s of 1.2 ms: a late
    stamp after an early one stretches an interval past it, and jitter is taken for gaps (runs
    chosen by their long ends fit a clock too fast). The import says so and names the range a
    gap test needs: above 1 ms + the jitter's reach (3√2 × its RMS), below 2 ms − that."""
    fast, _, _ = kilohertz_run
    rng = np.random.default_rng(6)
    t_ms = (fast.time + rng.uniform(-1e-4, 1e-4, fast.n)) * 1e3
    inc = np.degrees(fast.gyro)
    vel = fast.acc * 1e3
    ang = [np.degrees(fast.gimbal[a]) for a in ("outer", "middle", "inner")]
    _write_delimited(tmp_path / "imu.csv", ["t_ms", "dx", "dy", "dz", "vx", "vy", "vz", "A", "B", "C"],
                     [t_ms, *inc.T, *vel.T, *ang])
    m = _mapping(tmp_path / "map.toml", f"""
[imu]
file = "imu.csv"
sample_rate_hz = 1000.0
[imu.time]
column = "t_ms"
unit = "ms"
timing = "regularise"
max_interval_s = 0.0012
{_sensor_toml("gyro", "increment", "deg", ["dx", "dy", "dz"])}{_sensor_toml("acc", "increment", "mm/s", ["vx", "vy", "vz"])}[table]
encoder_resolution = "exact"
{_axes_toml(["A", "B", "C"])}
{SITE}""")
    assert main(["import", str(m), "--out", str(tmp_path / "merged")]) == 0
    out = capsys.readouterr().out
    said = [ln for ln in out.splitlines() if "jitter is taken for gaps" in ln]
    assert len(said) == 1, out
    lo, hi = (float(v) for v in re.search(r"between ([\d.]+) and ([\d.]+) ms", said[0]).groups())
    reach = 3 * math.sqrt(2) * 1e-4 / math.sqrt(3) * 1e3  # ms, from the uniform jitter's RMS
    assert lo == pytest.approx(1 + reach, abs=0.01) and hi == pytest.approx(2 - reach, abs=0.01)


def test_a_clock_drifting_against_the_host_is_followed_through_lost_samples():
    """A sensor clock whose interval drifts by 20 ppm over two hours (a crystal warming), its
    stamps under ±0.3 ms of jitter and 0.2 % of its samples lost. One grid through the gaps sits
    off the stamps by a bow of 3.6 ms; each run on its own start (as regularise did before) was off
    by 14 us RMS. Followed on a smooth clock, the times are as good as a least-squares fit of its
    p coefficients allows: RMS error σ √(p / N) (the hat matrix's trace over N), here under 2x
    that; the clock's rate said to move by 20 ppm."""
    from components.logs.timebase import regularise

    rng = np.random.default_rng(3)
    d, n = 5e-3, 1_440_000
    k = np.arange(n)
    true = np.concatenate([[0.0], np.cumsum(d * (1 + 20e-6 * k / n))[:-1]])
    kept = rng.random(n) > 0.002
    reg = regularise(true[kept] + rng.uniform(-3e-4, 3e-4, int(kept.sum())), d, 1.5 * d)
    assert reg.drift is not None
    assert reg.drift.rate_span_ppm == pytest.approx(20, rel=0.05)
    err = reg.time - true[kept]
    jitter = 3e-4 / math.sqrt(3)
    segments = round((true[-1] - true[0]) / reg.drift.spacing_s)
    p = segments + 2 + 1  # the spline's coefficients and the grid's start
    rms = math.sqrt(float(np.mean(err**2)))
    print(f"RMS error {rms * 1e6:.3f} us; sigma sqrt(p/N) {jitter * math.sqrt(p / len(err)) * 1e6:.3f} us (p = {p})")
    assert rms < 2 * jitter * math.sqrt(p / len(err))
    assert reg.jitter_rms_s == pytest.approx(jitter, rel=0.01)