"""Table angles read to one turn (components.logs.angle_turns): a controller's 0-360° or ±180°
readings are made continuous when a log is read or imported, and calibrate as the continuous
original (the independent simulator's conformance log, whose angles run to 4π)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from rig_files import AXES, imported, imu_columns, mapping, write_csv

from components.cli import main
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs import spill
from components.logs.angle_turns import unwrap_turns, wraps
from components.logs.logfile import read_log, write_log
from components.model.effects import DEFAULT_EFFECTS

TURN = 2 * math.pi


def _one_turn(angle: np.ndarray, lowest: float) -> np.ndarray:
    """*angle* read to one turn from *lowest*, as a controller reports it."""
    return lowest + np.mod(angle - lowest, TURN)


@pytest.mark.parametrize("lowest", [0.0, -math.pi])
def test_readings_to_one_turn_are_the_travel_again(monkeypatch, lowest):
    """Turns both ways, rests on the wrap, a wrap on a piece's first reading: the readings made
    continuous are the travel (from the first reading), and the wraps counted are the whole
    turns the travel crossed, counted apart from the readings."""
    monkeypatch.setattr(spill, "PIECE", 97)
    steps = np.concatenate([np.full(700, 0.05), np.zeros(300), np.full(1100, -0.07), np.full(400, 0.021)])
    travel = 0.4 + np.concatenate([[0.0], np.cumsum(steps)])
    read = _one_turn(travel, lowest)
    crossed = int(np.count_nonzero(np.diff(np.floor((travel - lowest) / TURN))))
    assert crossed >= 10
    got = read.copy()
    assert wraps(read) == crossed
    assert unwrap_turns(got) == crossed
    np.testing.assert_allclose(got, travel - (travel[0] - read[0]), rtol=0, atol=1e-12)
    calm = np.cumsum(np.full(1000, 0.003))  # no wrap: left bit for bit
    kept = calm.copy()
    assert wraps(calm) == 0 and unwrap_turns(kept) == 0 and np.array_equal(kept, calm)


def test_a_jump_among_readings_spanning_more_than_a_turn_is_no_wrap(monkeypatch):
    """Readings beyond one turn are a continuous angle already: a jump of half a turn among them
    (a corrupt cell, a value in degrees among radians) is no wrap, and is left for the checks
    that name it."""
    monkeypatch.setattr(spill, "PIECE", 97)
    travel = np.cumsum(np.full(3000, 0.004))  # 12 rad: nearly two turns
    corrupt = travel.copy()
    corrupt[1500] = 359.9
    assert wraps(corrupt) == 0
    assert wraps(_one_turn(travel, 0.0)) == 1  # the same travel read to one turn wraps once


@pytest.fixture(scope="module")
def example(conformance):
    log = read_log(conformance / "example")
    return log, calibrate(LogData.from_log(log), list(DEFAULT_EFFECTS))


def _close(fit, ref, tol=1e-6):
    """Every parameter within *tol* of its σ of the reference fit."""
    assert fit.parameters == ref.parameters
    z = np.abs((np.asarray(fit.value) - ref.value) / ref.sigma)
    assert z.max() < tol, (fit.parameters[int(np.argmax(z))], z.max())


@pytest.mark.parametrize("fmt, spilled", [("csv", False), ("parquet", False), ("parquet", True)])
def test_a_log_read_to_one_turn_calibrates_as_the_continuous_one(example, tmp_path, capsys, monkeypatch, fmt,
                                                                  spilled):
    """Read from CSV, from Parquet, and from Parquet into a spilled file (the angles mended
    through its mapping a piece at a time)."""
    log, ref = example
    if spilled:
        monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
        monkeypatch.setattr(spill, "PIECE", 4099)
    wrapped = dataclasses.replace(log, gimbal={a: _one_turn(v, 0.0) for a, v in log.gimbal.items()},
                                  angle_matrix=None)
    assert max(np.abs(np.diff(v)).max() for v in wrapped.gimbal.values()) > 6  # the wraps are there
    write_log(tmp_path / "wrapped", wrapped, fmt)
    back = read_log(tmp_path / f"wrapped.{fmt}", lean=True)
    assert spill.is_spilled(back.angles) == spilled
    for a in AXES:
        np.testing.assert_allclose(back.gimbal[a], log.gimbal[a], rtol=0, atol=1e-13)
    assert back.turns_mended == {a: n for a in AXES
                                 if (n := int(np.count_nonzero(np.abs(np.diff(wrapped.gimbal[a])) > math.pi)))}
    _close(calibrate(LogData.from_log(back), list(DEFAULT_EFFECTS)), ref)
    assert main(["calibrate", str(tmp_path / f"wrapped.{fmt}"), "--out", str(tmp_path / "fit.json")]) == 0
    said = capsys.readouterr()
    assert "table angles read to one turn, made continuous" in said.out
    assert "gimbal_inner" in said.out and "IMPLAUSIBLE" not in said.out + said.err


def _import(tmp_path, log, table_deg: dict, offset: float, name: str):
    """``calbench import`` of the IMU's increments and a table file of *table_deg* on a clock
    *offset* behind the IMU's (given); the imported log."""
    write_csv(tmp_path / "imu.csv", imu_columns(log, log.time, angles=False))
    write_csv(tmp_path / "table.csv", {"t": log.time - offset, **{c: table_deg[a] for c, a in zip("ABC", AXES)}})
    (tmp_path / "map.toml").write_text(mapping(log, table=f"clock_offset_s = {offset!r}", table_time=""))
    return imported(tmp_path, name)


def test_an_import_of_a_table_file_read_to_one_turn(example, tmp_path, capsys):
    """A table controller's file on a clock half a sample behind the IMU's, its angles in
    degrees within ±180°: the wraps are mended before the angles are interpolated to the IMU's
    times (a reading interpolated across a wrap is half a turn off, and no reader can mend it
    after), so the import is the continuous file's import, and calibrates as it does."""
    log, _ = example
    offset = 0.5 * log.dt
    continuous = _import(tmp_path, log, {a: np.degrees(log.gimbal[a]) for a in AXES}, offset, "continuous")
    assert "read to one turn" not in capsys.readouterr().out
    wrapped = _import(tmp_path, log, {a: np.degrees(_one_turn(log.gimbal[a], -math.pi)) for a in AXES}, offset,
                      "wrapped")
    out = capsys.readouterr().out
    assert "table.csv: table angles read to one turn, made continuous" in out
    assert wrapped.turns_mended == {}  # written continuous
    for a in AXES:
        np.testing.assert_allclose(wrapped.gimbal[a] - wrapped.gimbal[a][0], continuous.gimbal[a] - continuous.gimbal[a][0],
                                   rtol=0, atol=1e-12)
    _close(calibrate(LogData.from_log(wrapped), list(DEFAULT_EFFECTS)),
           calibrate(LogData.from_log(continuous), list(DEFAULT_EFFECTS)))
