"""A gyro driven beyond its output range (components.estimation.semantics._clipped, the
``gyro_range_radps`` key): the independent simulator's conformance log, its z gyro clipped at
25°/s while the table turns it at 30°/s, is named as clipped, and with the range given it
calibrates to the simulator's truth; logs that are not clipped (the noise-free one, whose
constant rates repeat to the bit, and pulse counts, whose top count recurs) are not named."""
from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import math
import re

import numpy as np
import pytest
from rig_files import AXES, imported, imu_columns, mapping, write_csv

from components.cli import main
from components.errors import LogFormatError, MappingError
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.estimation.semantics import PLATEAU, check_semantics
from components.logs.logfile import read_log, write_log
from components.logs.mapping import load_mapping
from components.logs.measurement import RANGE_MARGIN
from components.model.effects import DEFAULT_EFFECTS

FULL_SCALE = math.radians(25.0)  # rad/s; the log's fastest rotation about z is 30°/s


def _clipped(log):
    """*log* as its gyros would read with an output range of FULL_SCALE (increments over the
    nominal interval stop at the range times the interval)."""
    limit = FULL_SCALE / log.sample_rate_hz
    return dataclasses.replace(log, gyro=np.clip(log.gyro, -limit, limit))


def _as_counts(log, weight: float = 1e-6):
    """*log*'s gyros as whole pulses of *weight* rad, the remainder carried as a counter does."""
    total = np.round(np.cumsum(log.gyro_increment(), axis=0) / weight)
    return dataclasses.replace(log, gyro=np.diff(total, axis=0, prepend=0.0), gyro_output="counts",
                               gyro_count_rad=weight)


def _findings(log) -> list[str]:
    return check_semantics(LogData.from_log(log), log)


@pytest.fixture(scope="module")
def example(conformance):
    truth = json.loads((conformance / "example.truth.json").read_text())["baseline"]
    return read_log(conformance / "example"), truth


def _gyro_z(log, truth):
    """(estimate − truth) / σ of gyro.sf.z and of every gyro parameter, by the log's calibration."""
    fit = calibrate(LogData.from_log(log), list(DEFAULT_EFFECTS))
    want = {f"gyro.sf.{a}": truth["gyro_scale_factor_ppm"][i] * 1e-6 for i, a in enumerate("xyz")}
    want.update({f"gyro.bias.{a}": truth["gyro_bias_rad_s"][i] for i, a in enumerate("xyz")})
    z = {p: (fit.value[fit.parameters.index(p)] - v) / fit.sigma[fit.parameters.index(p)] for p, v in want.items()}
    return z["gyro.sf.z"], z


def test_a_clipped_gyro_is_named(example):
    log, truth = example
    clipped = _clipped(log)
    found = _findings(clipped)
    assert len(found) == 1, found
    assert "gyro_z" in found[0] and "+25°/s" in found[0] and "-25°/s" in found[0]
    assert "imu.gyro_range_radps" in found[0] and "--exclude" in found[0]
    # what it warns of: the clipped samples taken for the gyro's scale factor (thousands of σ)
    assert abs(_gyro_z(clipped, truth)[0]) > 1000


def test_with_its_range_given_the_clipped_log_calibrates_to_the_truth(example, tmp_path):
    log, truth = example
    given = dataclasses.replace(_clipped(log), gyro_range=np.full(3, FULL_SCALE))
    write_log(tmp_path / "clipped", given)
    assert json.loads((tmp_path / "clipped.json").read_text())["imu"]["gyro_range_radps"] == [FULL_SCALE] * 3
    back = read_log(tmp_path / "clipped")
    # left out: the samples at the range and one either side (counted here from the increments)
    at = np.any(np.abs(given.gyro) >= FULL_SCALE / log.sample_rate_hz * (1 - RANGE_MARGIN), axis=1)
    near = at | np.r_[False, at[:-1]] | np.r_[at[1:], False]
    (reason, hit), = back.left_out().items()
    assert reason.startswith("gyro at its output range") and np.array_equal(hit, near)
    assert near.sum() > 4000
    assert _findings(back) == []
    z_sf, z = _gyro_z(back, truth)
    assert max(abs(v) for v in z.values()) < 3.5, z


@pytest.mark.parametrize("name, counts", [("ideal", False), ("ideal", True), ("example", True)])
def test_unclipped_logs_whose_top_reading_recurs_are_not_named(conformance, name, counts):
    """The noise-free log's constant rates repeat their increments to the bit, and pulse counts
    of 1e-6 rad repeat their top count at 30°/s; the table sees the gyro read it alike there and
    in its other moves, so neither is taken for a clipped output."""
    log = read_log(conformance / name)
    log = _as_counts(log) if counts else log
    top = int(np.count_nonzero(log.gyro[:, 2] == log.gyro[:, 2].max()))
    assert top >= PLATEAU  # the plateau the check must see past is there
    assert _findings(log) == []


def test_the_noisy_log_is_not_named(example):
    assert _findings(example[0]) == []


def test_an_import_mapping_gives_the_range_in_its_unit(example, tmp_path):
    log, _ = example
    clipped = _clipped(log)
    write_csv(tmp_path / "imu.csv", imu_columns(clipped, log.time))
    (tmp_path / "map.toml").write_text(mapping(log, gyro='output = "increment"\nunit = "rad"\nrange = "25 deg/s"'))
    got = imported(tmp_path)
    np.testing.assert_allclose(got.gyro_range, FULL_SCALE, rtol=1e-15)
    assert sum(v.sum() for v in got.left_out().values()) > 4000
    for bad, says in (('"-25 deg/s"', "positive"), ('["25 deg/s", "25 deg/s"]', "2 value(s)"),
                      ('"25 furlongs"', "imu.gyro.range")):
        (tmp_path / "bad.toml").write_text(mapping(log, gyro=f'output = "increment"\nunit = "rad"\nrange = {bad}'))
        with pytest.raises(MappingError, match=r"imu\.gyro\.range") as e:
            load_mapping(tmp_path / "bad.toml")
        assert says in str(e.value)


def test_a_bad_range_in_a_log_is_refused_naming_the_key(example, tmp_path):
    log, _ = example
    write_log(tmp_path / "v2", dataclasses.replace(log, gyro_range=np.full(3, FULL_SCALE)))
    meta = json.loads((tmp_path / "v2.json").read_text())
    for value, says in ((-1.0, "positive"), ([1.0, 2.0], "2 value(s)"), ("fast", "positive number")):
        meta["imu"]["gyro_range_radps"] = value
        (tmp_path / "v2.json").write_text(json.dumps(meta))
        with pytest.raises(LogFormatError, match="imu.gyro_range_radps") as e:
            read_log(tmp_path / "v2")
        assert says in str(e.value)
    meta["imu"]["gyro_range_radps"] = 1.0
    meta["format"] = "calbench-log/1"
    (tmp_path / "v2.json").write_text(json.dumps(meta))
    with pytest.raises(LogFormatError, match="belongs to 'calbench-log/2'"):
        read_log(tmp_path / "v2")


def _matched_offset(tmp_path, log, imu_log, gyro_keys: str) -> tuple[float, float]:
    """The clock offset matched on the rates [s] and its σ, of the import of *imu_log*'s
    increments beside a table file of *log*'s angles on a clock 12.3 ms behind."""
    write_csv(tmp_path / "imu.csv", imu_columns(imu_log, log.time, angles=False))
    write_csv(tmp_path / "table.csv", {"t": (log.time - 0.0123) * 1e3,
                                       **{c: np.degrees(log.gimbal[a]) for c, a in zip("ABC", AXES)}})
    (tmp_path / "map.toml").write_text(mapping(log, gyro=gyro_keys, table='clock_offset_s = "estimate"',
                                               table_time='unit = "ms"'))
    said = io.StringIO()
    with contextlib.redirect_stdout(said):
        assert main(["import", str(tmp_path / "map.toml"), "--out", str(tmp_path / "merged")]) == 0
    got = re.search(r"matched on the rates ([+-][\d.]+) ± ([\d.e-]+) ms", said.getvalue()).groups()
    return float(got[0]) * 1e-3, float(got[1]) * 1e-3


def test_a_table_file_beside_a_clipped_gyro_is_matched_without_the_clipped_samples(example, tmp_path):
    """The clock offset is matched on how far the gyros say the plate turned: a clipped increment
    says less than it did. With the range given the samples at it are left out of the match too,
    and the offset is as precise as beside the unclipped gyro (its σ was 1.3 ms, 60 times it)."""
    log, _ = example
    increments = 'output = "increment"\nunit = "rad"'
    _, plain = _matched_offset(tmp_path, log, log, increments)
    got, sigma = _matched_offset(tmp_path, log, _clipped(log), increments + '\nrange = "25 deg/s"')
    assert sigma < 1.5 * plain and abs(got - 0.0123) < 4 * sigma, (got, sigma, plain)
