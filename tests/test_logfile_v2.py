"""calbench-log/2: logs from other rigs — no table angles, a logger's own clock with jitter and
gaps, a mask, exclusions, the encoder resolution — read, written and checked; every broken rule
is one error naming the file and the key or row."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from components.errors import EstimationError, LogFormatError
from components.estimation.blocks import observation_blocks
from components.estimation.log_data import LogData
from components.estimation.rest_angles import rest_sigma
from components.logs.logfile import MeasurementLog, read_log, write_log

RNG = np.random.default_rng(5)


def _handheld(n: int = 400, fs: float = 100.0, jitter: float = 0.0, gap_at: int | None = None) -> MeasurementLog:
    t = np.arange(1, n + 1) / fs + RNG.uniform(-jitter, jitter, n)
    if gap_at is not None:
        t[gap_at:] += 0.5
    seg = np.array(["pos1"] * (n // 4) + ["move"] * (n // 4) + ["pos2"] * (n - n // 2), dtype=object)
    return MeasurementLog(
        time=t, gimbal={}, gyro=RNG.normal(0, 1e-3, (n, 3)), acc=RNG.normal(0, 1e-2, (n, 3)) + [0, 0, 9.8],
        axis_names=[], axis_vectors=np.zeros((0, 3)), sample_rate_hz=fs, gyro_output="rate",
        acc_output="specific_force", latitude_deg=45.0, segment=seg,
        timing="measured" if jitter or gap_at is not None else "nominal",
        segments={"pos1": {"kind": "static", "up": "z"}, "pos2": {"kind": "static"},
                  "move": {"kind": "excluded"}})


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_log_without_table_round_trips(tmp_path, fmt):
    log = _handheld(jitter=2e-4, gap_at=300)
    log.mask = np.ones(log.n, bool)
    log.mask[10:13] = False
    log.exclude = [[0.3, 0.35], "pos2"]
    write_log(tmp_path / "h", log, fmt)
    meta = json.loads((tmp_path / "h.json").read_text())
    assert meta["format"] == "calbench-log/2" and meta["table"]["axes"] == []
    back = read_log(tmp_path / f"h.{fmt}")
    assert not back.has_table and back.angles.shape == (log.n, 0)
    assert back.timing == "measured" and back.exclude == [[0.3, 0.35], "pos2"]
    assert np.array_equal(back.time, log.time) and np.array_equal(back.gyro, log.gyro)
    assert np.array_equal(back.mask, log.mask) and list(back.segment) == list(log.segment)
    # rates become increments with each sample's own interval (the first: the nominal one)
    dt = np.concatenate([[0.01], np.diff(log.time)])
    assert np.allclose(back.gyro_increment(), log.gyro * dt[:, None], rtol=0, atol=1e-18)
    reasons = back.left_out()
    assert reasons["gap (the sample after it)"].sum() == 1 and reasons["gap (the sample after it)"][300]
    assert reasons["mask = 0"].sum() == 3
    assert reasons["segment 'move' (kind excluded)"].sum() == 100
    assert reasons["segment 'pos2' (exclude)"].sum() == 200
    in_range = (log.time >= 0.3) & (log.time <= 0.35)
    assert np.array_equal(reasons["t = 0.3-0.35 s (exclude)"], in_range)
    usable = back.usable()
    assert usable.sum() == log.n - len(set(np.nonzero(~usable)[0]))
    data = LogData.from_log(back, exclude=[[0.0, 0.05]])
    assert data.left_out["t = 0-0.05 s (exclude)"] == int((log.time <= 0.05).sum())
    assert not data.usable[:4].any() and data.segment_kinds["pos1"]["up"].tolist() == [0, 0, 1]


@pytest.mark.parametrize("step", [1, 37, 300, 301, 10_000])
def test_the_usable_mask_a_piece_at_a_time_is_every_reason_at_once(tmp_path, step):
    """A long log's usable mask is made a piece at a time (no whole mask per reason): at every
    piece length — a gap on a piece's first sample included — it is the samples no reason
    leaves out, each reason's count its own, all read here from the columns directly."""
    log = _handheld(jitter=2e-4, gap_at=300)
    log.mask = np.ones(log.n, bool)
    log.mask[10:13] = False
    log.exclude = [[0.3, 0.35], "pos2"]
    gap = np.concatenate([[False], np.diff(log.time) > 1.5 / log.sample_rate_hz])
    seg = np.asarray(log.segment, object)
    expect = {"gap (the sample after it)": gap, "mask = 0": ~log.mask,
              "t = 0.3-0.35 s (exclude)": (log.time >= 0.3) & (log.time <= 0.35),
              "segment 'pos2' (exclude)": seg == "pos2", "segment 'move' (kind excluded)": seg == "move"}
    out = np.zeros(log.n, bool)
    counts = log.usable_into(out, step=step)
    assert counts == {k: int(m.sum()) for k, m in expect.items()}
    assert np.array_equal(out, ~np.logical_or.reduce(list(expect.values())))


def test_a_version_1_log_is_written_as_version_1(tmp_path, conformance):
    log = read_log(conformance / "ideal")
    write_log(tmp_path / "again", log)
    assert json.loads((tmp_path / "again.json").read_text())["format"] == "calbench-log/1"
    log.encoder_resolution = "exact"
    write_log(tmp_path / "v2", log)
    meta = json.loads((tmp_path / "v2.json").read_text())
    assert meta["format"] == "calbench-log/2" and meta["table"]["encoder_resolution_rad"] == "exact"
    assert read_log(tmp_path / "v2").encoder_resolution == "exact"


def test_jitter_is_refused_under_nominal_timing_and_read_under_measured(tmp_path):
    log = _handheld(jitter=2e-4)
    log.timing = "nominal"
    with pytest.raises(LogFormatError, match=r"interval .* expected 1/sample_rate_hz .*'imu.timing': 'measured'"):
        write_log(tmp_path / "j", log)
    log.timing = "measured"
    write_log(tmp_path / "j", log)
    assert read_log(tmp_path / "j").timing == "measured"


def test_blocks_leave_out_what_is_not_usable():
    """A static chunk keeps its usable stretches; a gyro move with a left-out sample is dropped."""
    static = np.array([True] * 10 + [False] * 5 + [True] * 10)
    angles = np.concatenate([np.zeros(10), np.linspace(0.1, 0.5, 5), np.full(10, 0.5)])[:, None]
    valid = np.ones(25, bool)
    valid[3] = False
    valid[12] = False
    gb, ab = observation_blocks(static, angles, 4, valid)
    covered_g = np.zeros(25, int)
    for a, b in zip(gb.start, gb.stop):
        covered_g[a:b] += 1
    assert covered_g[3] == 0 and not gb.moving.any() and covered_g[10:15].sum() == 0
    assert covered_g[:3].all() and covered_g[4:10].all() and covered_g[15:].all()
    covered_a = np.zeros(25, int)
    for a, b in zip(ab.start, ab.stop):
        covered_a[a:b] += 1
    assert covered_a[3] == 0 and covered_a[12] == 0 and covered_a[10:12].all() and covered_a[13:15].all()
    assert covered_a.max() == 1


def test_encoder_resolution_is_stated_or_refused():
    angles = np.repeat(np.array([[0.0], [math.pi / 2]]), 5, axis=0)  # nominal attitudes only
    with pytest.raises(EstimationError, match=r"steps between logged angles of axis 1 are whole numbers of 90°.*"
                                              r"table.encoder_resolution_rad"):
        rest_sigma(angles)
    assert rest_sigma(angles, resolution="exact").tolist() == [0.0]
    assert rest_sigma(angles, resolution=np.array([1e-5]))[0] == pytest.approx(1e-5 / math.sqrt(12))
    fine = np.array([[0.0], [1e-5], [3e-5]])
    assert rest_sigma(fine)[0] == pytest.approx(1e-5 / math.sqrt(12))


def _meta(**changes) -> dict:
    meta = {"format": "calbench-log/2", "site": {"latitude_deg": 45.0, "height_m": 0.0, "gravity_mps2": None},
            "table": {"axes": []},
            "imu": {"sample_rate_hz": 100.0, "gyro_output": "increment", "acc_output": "increment",
                    "gyro_count_rad": None, "acc_count_mps": None},
            "segments": {"a": {"kind": "static"}}}
    for path, v in changes.items():
        node = meta
        keys = path.split("__")
        for k in keys[:-1]:
            node = node[k]
        if v is KeyError:
            del node[keys[-1]]
        else:
            node[keys[-1]] = v
    return meta


def _write(tmp_path, meta: dict, rows: str | None = None):
    (tmp_path / "m.json").write_text(json.dumps(meta))
    header = "time,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z,segment"
    body = rows or "\n".join(f"{0.01 * (k + 1):.2f},0,0,0,0,0,0.098,a" for k in range(4))
    (tmp_path / "m.csv").write_text(header + "\n" + body + "\n")
    return tmp_path / "m"


@pytest.mark.parametrize("changes, match", [
    ({"segments": KeyError}, r"m.json: 'table.axes' is \[\] \(no table angles\) but there is no 'segments' key"),
    ({"segments": {"a": {"kind": "rest"}}}, r"m.json: key 'segments': segment 'a': expected \{'kind'"),
    ({"segments": {"a": {"kind": "static"}, "b": {"kind": "static"}}},
     r"m.json: key 'segments' describes label\(s\) 'b' that no sample carries"),
    ({"table__encoder_resolution_rad": 1e-5}, r"encoder_resolution_rad' is given but 'table.axes' is \[\]"),
    ({"imu__timing": "jittery"}, r"key 'imu.timing' = 'jittery': expected 'nominal'"),
    ({"imu__max_interval_s": 0.05}, r"'imu.max_interval_s' is given but 'imu.timing' is 'nominal'"),
    ({"imu__timing": "measured", "imu__max_interval_s": 0.005}, r"max_interval_s' = 0.005: expected more than"),
    ({"exclude": [[2, 1]]}, r"key 'exclude'\[0\] = \[2, 1\]: expected a time range \[t0, t1\] with t0 < t1"),
    ({"exclude": ["nope"]}, r"exclude 'nope': no segment has this label \(labels: a\)"),
    ({"imu__noise": {"channels": 3}}, r"key 'imu.noise'"),
    ({"format": "calbench-log/1", "segments": KeyError}, r"key 'table.axes' = \[\]: expected a non-empty list .* 'calbench-log/2' with"),
])
def test_version_2_rules(tmp_path, changes, match):
    with pytest.raises(LogFormatError, match=match):
        read_log(_write(tmp_path, _meta(**changes)))


@pytest.mark.parametrize("changes, match", [
    ({"imu__timming": "measured"}, r"m.json: key 'imu.timming' is not one of the format's: did you mean 'imu.timing'"),
    ({"imu__gyro_range_rad_s": 1.0}, r"key 'imu.gyro_range_rad_s' .* did you mean 'imu.gyro_range_radps'"),
    ({"descripton": "x"}, r"key 'descripton' .* did you mean 'description'"),
])
def test_a_key_a_letter_or_two_from_one_of_the_format_is_refused(tmp_path, changes, match):
    """Other software's keys are kept (a simulator's 'model', calbench's own 'import'); a key within
    a letter or two of one the format defines is a typing mistake that would drop the key meant
    without a word (a misspelt 'timing': the samples taken at their nominal times)."""
    read_log(_write(tmp_path, _meta(imu__model="ACME-9", vendor={"serial": 7})))
    with pytest.raises(LogFormatError, match=match):
        read_log(_write(tmp_path, _meta(**changes)))


def test_mask_and_segment_columns_are_checked(tmp_path):
    meta = _meta()
    (tmp_path / "m.json").write_text(json.dumps(meta))
    (tmp_path / "m.csv").write_text("time,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z\n0.01,0,0,0,0,0,0\n")
    with pytest.raises(LogFormatError, match=r"m.csv: missing column 'segment': a log without table angles"):
        read_log(tmp_path / "m")
    rows = "0.01,0,0,0,0,0,0,a,1\n0.02,0,0,0,0,0,0,a,2\n"
    (tmp_path / "m.csv").write_text("time,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z,segment,mask\n" + rows)
    with pytest.raises(LogFormatError, match=r"data row 2 \(line 3\), column 'mask': 2.0; expected 1"):
        read_log(tmp_path / "m")


def test_deeply_nested_metadata_is_one_clear_error(tmp_path):
    _write(tmp_path, _meta())
    for depth in (100, 100_000):
        text = json.dumps(_meta())[:-1] + ', "deep": ' + '{"x": ' * depth + "{}" + "}" * depth + "}"
        (tmp_path / "m.json").write_text(text)
        with pytest.raises(LogFormatError, match=r"m.json: metadata nested deeper than 32 levels"):
            read_log(tmp_path / "m")


def test_metadata_size_is_bounded(tmp_path, monkeypatch):
    import components.logs.logfile as lf

    _write(tmp_path, _meta())
    monkeypatch.setattr(lf, "MAX_METADATA_BYTES", 100)
    with pytest.raises(LogFormatError, match=r"m.json: \d+ bytes of metadata; expected at most 100"):
        read_log(tmp_path / "m")


def test_the_count_is_the_step_every_logged_step_is_a_whole_number_of():
    """A table that moves several counts a sample never logs a one-count step: the count is still
    the one every step between distinct angles is a whole number of; an axis that never moves
    has none (0); steps with no common count (reading noise) give the smallest step."""
    from components.estimation.rest_angles import encoder_quantum

    q = 3.7e-7
    moving = np.array([0, 13, 26, 40, 53, 66, 66, 66, 79, 92, 106, 119, 119]) * q  # 13-14 counts a sample
    still = np.zeros_like(moving)
    got = encoder_quantum(np.column_stack([moving, still]))
    assert got[0] == pytest.approx(q, rel=1e-9) and got[1] == 0.0
    noisy = moving + np.random.default_rng(1).normal(0.0, 0.05 * q, len(moving))  # reading noise: no common count
    assert encoder_quantum(noisy[:, None])[0] == pytest.approx(np.diff(np.unique(noisy)).min())
