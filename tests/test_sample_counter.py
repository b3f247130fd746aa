"""A sensor's sample counter (``[imu.counter]``): the conformance example written as a host
logs it, stamped with ±2 ms of jitter (a USB host: an interval anywhere from 1 to 9 ms, so no
stamp tells a lost sample from a late one), 0.5 % of its packets lost, and a 16-bit packet
counter that rolls over. With the counter the samples stand on the sensor's grid within the
least-squares scatter of a line through 83,000 jittered stamps, and the log calibrates as the
conformance log with those samples (and the one after each gap) masked."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from components.cli import main
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs.logfile import read_log
from components.model.effects import DEFAULT_EFFECTS

G0 = 9.80665
JITTER = 2e-3  # s, uniform ±
SITE = '[site]\nlatitude_deg = 39.9\nheight_m = 50.0\n'


@pytest.fixture(scope="module")
def example(conformance):
    return read_log(conformance / "example")


def _write(path, log, kept, stamps, counter):
    gyro, acc = np.degrees(log.gyro / log.dt), log.acc / log.dt / G0
    angles = [np.degrees(log.gimbal[a]) for a in ("outer", "middle", "inner")]
    cols = [stamps, counter, *gyro.T, *acc.T, *angles]
    lines = ["t,seq,gx,gy,gz,ax,ay,az,outer,middle,inner"]
    lines += [",".join("%.17g" % c[i] for c in cols) for i in np.flatnonzero(kept)]
    path.write_text("\n".join(lines) + "\n")


def _mapping(timing: str = "regularise", counter: bool = True, step: int = 1, rollover: int = 65536) -> str:
    axes = "".join(f'[[table.axes]]\nname = "{n}"\naxis = {v}\ncolumn = "{n}"\nunit = "deg"\n'
                   for n, v in (("outer", [0, 0, 1]), ("middle", [1, 0, 0]), ("inner", [0, 0, 1])))
    return ('[imu]\nfile = "rec.csv"\nsample_rate_hz = 200.0\n'
            f'[imu.time]\ncolumn = "t"\ntiming = "{timing}"\n'
            + (f'[imu.counter]\ncolumn = "seq"\nrollover = {rollover}\n' + (f"step = {step}\n" if step > 1 else "")
               if counter else "")
            + '[imu.gyro]\noutput = "rate"\nunit = "deg/s"\nx = "gx"\ny = "gy"\nz = "gz"\n'
            '[imu.acc]\noutput = "specific_force"\nunit = "g"\nx = "ax"\ny = "ay"\nz = "az"\n'
            '[table]\nencoder_resolution = "exact"\n' + axes + SITE)


def _rig(log, seed=3, step=1, rollover=65536, start=40000):
    rng = np.random.default_rng(seed)
    kept = rng.random(log.n) >= 0.005
    kept[[0, -1]] = True
    stamps = log.time + rng.uniform(-JITTER, JITTER, log.n)
    counter = (np.arange(log.n) * step + start) % rollover  # rolls over once
    return kept, stamps, counter


# a 16-bit packet counter; a 32-bit count of a 10 kHz clock, 50 a sample (as some IMUs stamp
# their samples themselves), rolling over 1,000 samples in
@pytest.mark.parametrize("step, rollover, start", [(1, 65536, 40000), (50, 2**32, 2**32 - 50_000)])
def test_a_sample_counter_places_jittered_samples_and_names_the_lost(example, tmp_path, capsys, step, rollover, start):
    log = example
    kept, stamps, counter = _rig(log, step=step, rollover=rollover, start=start)
    _write(tmp_path / "rec.csv", log, kept, stamps, counter)
    (tmp_path / "map.toml").write_text(_mapping(step=step, rollover=rollover))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 0
    said = capsys.readouterr().out
    lost = int((~kept).sum())
    assert re.search(rf"sample counter 'seq': {kept.sum()} of the {log.n} samples it counted are in the file \(rolled "
                     rf"over 1 time\(s\)\); "
                     rf"{lost} sample\(s\) lost", said), said
    assert "jitter is taken for gaps" not in said
    back = read_log(tmp_path / "imported")
    # on the sensor's grid: within five times the scatter of a least-squares line's ends
    # through N stamps of uniform jitter (start and slope: 2 σ/√N at the ends)
    bound = 5 * 2 * (JITTER / math.sqrt(3)) / math.sqrt(kept.sum())
    assert np.max(np.abs(back.time - log.time[kept])) < bound
    # the sample after each gap left out by the log (as the conformance log masked so)
    after = np.zeros(log.n, bool)
    after[1:] = ~kept[:-1] & kept[1:]
    data = LogData.from_log(back)
    assert int((~data.usable).sum()) == int(after.sum())
    from dataclasses import replace

    ref = calibrate(LogData.from_log(replace(log, mask=kept & ~after)), list(DEFAULT_EFFECTS))
    fit = calibrate(data, list(DEFAULT_EFFECTS))
    z = (fit.value - ref.value) / ref.sigma
    # 0.1 σ: the accelerometer's moving blocks are cut at other samples in a log without the
    # lost ones (tests/test_lost_rows.py), and the grid stands a few µs off
    assert np.max(np.abs(z)) < 0.1, (fit.parameters[int(np.argmax(np.abs(z)))], np.max(np.abs(z)))


def test_without_the_counter_the_same_stamps_cannot_tell_lost_samples(example, tmp_path, capsys):
    """What the counter is for: the same files without it. The runs between intervals that look
    like gaps get grids of their own, which overlap: one error naming the counter (it made a log
    with two samples at one time, refused only by the log's own check, naming the log's sample)."""
    log = example
    kept, stamps, counter = _rig(log)
    _write(tmp_path / "rec.csv", log, kept, stamps, counter)
    (tmp_path / "map.toml").write_text(_mapping(counter=False))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 2
    err = capsys.readouterr().err
    assert re.search(r"rec.csv: imu.time: the regular grids fitted to the stamps between what look like gaps overlap "
                     r"at row \d+ .* give \[imu.counter\]", err), err


@pytest.mark.parametrize("edit, timing, words", [
    # a packet logged twice: its row again after it
    (lambda rows: rows.insert(301, rows[300]), "regularise",
     r"imu.counter.column: row 301: 40299 after 40299; expected a counter that advances \(a packet logged twice\?\)"),
    # a counter that rolls over without the key
    (None, "regularise-no-rollover", r"row 25537: 0 after 65535; expected a counter that advances \(a counter that rolls "
                                     r"over: give imu.counter.rollover"),
    # stamps taken as the samples' times that hide a lost sample
    ("hide", "measured", r"row 1001: the counter skips samples, but the stamps are 5 ms apart.*give imu.time.timing = "
                         r"'regularise'"),
])
def test_a_counter_that_does_not_advance_or_is_hidden_by_the_stamps_is_one_error(example, tmp_path, capsys, edit,
                                                                                  timing, words):
    log = example
    kept = np.ones(log.n, bool)
    counter = (np.arange(log.n) + 40000) % 65536
    stamps = log.time.copy()
    if edit == "hide":
        kept[1000] = False
        stamps[1001:] -= log.dt  # a host that stamps what it receives, regularly
    _write(tmp_path / "rec.csv", log, kept, stamps, counter)
    if callable(edit):
        rows = (tmp_path / "rec.csv").read_text().splitlines()
        edit(rows)
        (tmp_path / "rec.csv").write_text("\n".join(rows) + "\n")
    mapping = _mapping(timing.split("-")[0])
    if timing.endswith("no-rollover"):
        mapping = mapping.replace("rollover = 65536\n", "")
    (tmp_path / "map.toml").write_text(mapping)
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert re.search(words, err), err
    assert "Traceback" not in err


def test_the_counters_grid_is_the_least_squares_line_through_the_stamps_at_its_counts():
    """regularise with the counter's index: the line numpy's polyfit puts through the stamps at
    those indices (lost samples and jitter of ±0.4 interval that no gap rule could read)."""
    from components.logs.timebase import regularise

    rng = np.random.default_rng(9)
    index = np.cumsum(1 + (rng.random(5000) < 0.01) * rng.integers(1, 4, 5000)) - 1
    t = 1000.0 + 0.001 * (1 + 37e-6) * index + rng.uniform(-0.4e-3, 0.4e-3, len(index))
    reg = regularise(t, 0.001, 0.0015, index)
    slope, intercept = np.polyfit(index.astype(float), t - 1000.0, 1)
    np.testing.assert_allclose(reg.time - 1000.0, intercept + slope * index, rtol=0, atol=1e-10)
    assert reg.rate_hz == pytest.approx(1 / slope, rel=1e-12)
    assert reg.runs == 1 + int(np.count_nonzero(np.diff(index) > 1))


def test_a_counter_with_a_sensor_clock_drifting_against_the_host(example, tmp_path, capsys):
    """The host stamps on a clock the sensor's drifts against by 20 ppm (soaking in as a crystal
    warms), ±2 ms of jitter, 0.5 % lost, the sensor's clock keeping time: the log's samples at
    the sensor's own times (the first's origin aside) to well under a microsecond, the
    calibration within 0.1 σ of the conformance log masked."""
    log = example
    kept, _, counter = _rig(log, seed=4)
    tau = log.time - log.time[0]
    rate = 1 + 20e-6 * (1 - np.exp(-tau / (tau[-1] / 4)))
    host = log.time[0] + np.concatenate([[0.0], np.cumsum(np.diff(tau) * 0.5 * (rate[1:] + rate[:-1]))])
    stamps = host + np.random.default_rng(5).uniform(-JITTER, JITTER, log.n)
    _write(tmp_path / "rec.csv", log, kept, stamps, counter)
    (tmp_path / "map.toml").write_text(_mapping().replace('timing = "regularise"',
                                                          'timing = "regularise"\nkeeps_time = "sensor"'))
    assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "imported")]) == 0
    assert "the sensor's clock drifts against the host's" in capsys.readouterr().out
    back = read_log(tmp_path / "imported")
    true = log.time[kept]
    assert np.max(np.abs((back.time - back.time[0]) - (true - true[0]))) < 1e-6
    after = np.zeros(log.n, bool)
    after[1:] = ~kept[:-1] & kept[1:]
    from dataclasses import replace

    ref = calibrate(LogData.from_log(replace(log, mask=kept & ~after)), list(DEFAULT_EFFECTS))
    fit = calibrate(LogData.from_log(back), list(DEFAULT_EFFECTS))
    assert np.max(np.abs((fit.value - ref.value) / ref.sigma)) < 0.1
