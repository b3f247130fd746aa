"""A table file on its own clock as rigs write it, imported with the clock offset estimated:
read at the IMU's own rate with the encoder's counts (the conformance log's 1.2"), and stamped by
a host polling the controller with a clock coarser than its readings (Windows' 15.625 ms tick),
which ``table.time.timing = "regularise"`` replaces by the grid fitted to the stamps. Each
calibrates as the independent simulator's conformance log ``example`` does."""
from __future__ import annotations

import re

import numpy as np
import pytest
from rig_files import AXES, imu_columns, mapping, write_csv

from components.cli import main
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS

BEHIND = 0.0123  # s: the table's clock behind the IMU's (2.46 samples)
TICK = 0.015625  # s


@pytest.fixture(scope="module")
def example(conformance):
    log = read_log(conformance / "example")
    return log, calibrate(LogData.from_log(log), list(DEFAULT_EFFECTS))


def _import(tmp_path, log, every: int, stamps: np.ndarray, table: str = "", table_time: str = "") -> int:
    """``calbench import`` of the IMU's increments and a table file of every *every*-th reading at
    *stamps* [s] (its clock's), the offset estimated."""
    write_csv(tmp_path / "imu.csv", imu_columns(log, log.time, angles=False))
    write_csv(tmp_path / "table.csv", {"t": stamps * 1e3, **{c: np.degrees(log.gimbal[a][::every])
                                                             for c, a in zip("ABC", AXES)}})
    (tmp_path / "map.toml").write_text(mapping(log, table=f'clock_offset_s = "estimate"\n{table}',
                                               table_time=f'unit = "ms"\n{table_time}'))
    return main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")])


def _calibrates_as(tmp_path, ref, tol: float) -> None:
    fit = calibrate(LogData.from_log(read_log(tmp_path / "merged")), list(DEFAULT_EFFECTS))
    z = np.abs((np.asarray(fit.value) - ref.value) / ref.sigma)
    assert z.max() < tol, (fit.parameters[int(np.argmax(z))], z.max())


def _offset(out: str) -> tuple[float, float, str]:
    """(the offset matched on the rates [s], its σ [s], the whole line)."""
    line = next(ln for ln in out.splitlines() if "clock offset table -> IMU" in ln)
    got, sigma = re.search(r"matched on the rates ([+-][\d.]+) ± ([\d.e-]+) ms", line).groups()
    return float(got) * 1e-3, float(sigma) * 1e-3, line


def test_a_table_read_at_the_imu_rate_with_encoder_counts_gives_the_clock_offset(example, tmp_path, capsys):
    """Read at the IMU's instants, each table interval's end meets a reading; the turn between
    interpolated angles then carried the counts' full noise there and half of it between, and the
    estimate went to 0.8 ms off with a false curve of 1,400 ppm (every parameter dozens of σ off).
    The gyros' running sum is what is interpolated now: the offset within 4 of its σ, no rate
    between the clocks said, and the log calibrates as the simulator's."""
    log, ref = example
    assert _import(tmp_path, log, 1, log.time - BEHIND) == 0
    got, sigma, line = _offset(capsys.readouterr().out)
    assert abs(got - BEHIND) < 4 * sigma and sigma < 1e-4, line
    assert "ppm" not in line and "bowing" not in line, line
    _calibrates_as(tmp_path, ref, 0.1)


@pytest.mark.parametrize("every", [1, 2, 4])
def test_a_table_file_stamped_by_a_coarse_clock_is_regularised(example, tmp_path, capsys, every):
    """A host polling the controller at 200, 100 or 50 Hz stamps its readings with its 15.625 ms
    tick (at 200 and 100 Hz two in three or one in three alike; at 50 Hz none alike, the stamps
    stepping by one tick or two). The grid fitted to the stamps places the readings; the stamps
    lag the readings by half a tick on average, which the estimated offset takes up. The log
    calibrates as the same readings imported with their true times do."""
    log, _ = example
    polled = log.time[::every] - BEHIND
    stamps = np.floor((polled + 0.0371) / TICK) * TICK  # the tick the reading was taken in
    if every < 4:
        assert np.mean(np.diff(stamps) == 0) > 0.3
        # without saying so: one error at the first repeated stamp, naming the keys
        assert _import(tmp_path, log, every, stamps) == 2
        err = capsys.readouterr().err
        assert re.search(r"table.csv: table.time: row \d+: .* give table.time.timing = 'regularise' and "
                         r"table.sample_rate_hz", err), err
    assert _import(tmp_path, log, every, stamps, table_time='timing = "regularise"') == 2
    assert "table.time.timing' = 'regularise' needs 'table.sample_rate_hz'" in capsys.readouterr().err
    assert _import(tmp_path, log, every, polled, table=f"sample_rate_hz = {200.0 / every}") == 2
    assert "key 'table.sample_rate_hz': only the grid of table.time.timing = 'regularise' uses it" \
        in capsys.readouterr().err
    assert _import(tmp_path, log, every, polled) == 0
    capsys.readouterr()
    true_times = calibrate(LogData.from_log(read_log(tmp_path / "merged")), list(DEFAULT_EFFECTS))
    assert _import(tmp_path, log, every, stamps, table=f"sample_rate_hz = {200.0 / every}",
                   table_time='timing = "regularise"') == 0
    out = capsys.readouterr().out
    tick = float(re.search(r"table stamps regularised \(a clock of ([\d.]+) ms resolution", out).group(1))
    assert tick == pytest.approx(TICK * 1e3, rel=1e-3)
    assert "1 run(s)" in out and f"fitted rate {200.0 / every:.6f} Hz" in out, out
    # the stamps' mean lag behind the readings: half a tick less what the floor's phase averages to
    lag = float(np.mean(stamps - polled))
    got, sigma, line = _offset(out)
    assert abs(got - (BEHIND - lag)) < 4 * sigma + 4 * TICK / np.sqrt(len(stamps)), line
    # the two imports' offsets, combined with the least squares' (σ 2.8 µs each), differ by their
    # errors; 1 µs moved a calibration by ~0.06 σ of the parameters'
    _calibrates_as(tmp_path, true_times, 0.05)


def test_the_offset_at_the_table_s_first_sample_carries_the_rate_s_extrapolation(example, tmp_path, capsys):
    """The table's controller 50 ppm fast: the rate between the clocks is fitted, and the offset
    said at the table's first sample is the line's value there, extrapolated from where the moves
    pin it. Its σ is at least the rate's σ times that lever, from the centroid of the offset's
    information (the turn over an interval moves with the offset by the change of rate across it:
    each sample weighted by its squared change of turn; 0.8 of it for that approximation). The
    line's centre's σ alone was said, 25 us against a bound of 37, with the offset 44 us off."""
    log, _ = example
    fast = 50e-6
    assert _import(tmp_path, log, 1, (log.time - BEHIND) * (1 + fast)) == 0
    out = capsys.readouterr().out
    got, sigma, line = _offset(out)
    rate, s_rate = (float(v) * 1e-6 for v in re.search(r"the IMU's clock ([+-][\d.e+-]+) ± ([\d.e-]+) ppm against "
                                                         r"the table's", out).groups())
    truth = log.time[0] - (log.time[0] - BEHIND) * (1 + fast)
    assert abs(got - truth) < 4 * sigma, line
    assert abs(rate - (1 / (1 + fast) - 1)) < 4 * s_rate, line
    change = np.sum([np.diff(log.gimbal[a], n=2, prepend=[log.gimbal[a][0]] * 2) ** 2 for a in AXES], axis=0)
    centroid = float(np.sum(change * log.time) / np.sum(change))
    assert sigma >= 0.8 * s_rate * (centroid - log.time[0]), (sigma, s_rate * (centroid - log.time[0]))
