"""A long log's sensor columns on disk (components.logs.spill): read with the spill forced and
in small pieces, a log gives bit for bit the arrays, the estimates and σ, the comparison and the
diagnosis it gives in memory (issue #18: results equal to the in-memory ones)."""
from __future__ import annotations

import copy
import dataclasses
import errno
import os
import sys
import tomllib

import numpy as np
import pyarrow.parquet as pq
import pytest
from forked_chunks import send_chunks_to_workers

from components.cli.demo import SCENARIO
from components.diagnosis.compare import compare
from components.diagnosis.diagnose import diagnose
from components.estimation.log_data import LogData
from components.estimation.lsq import calibrate
from components.logs import spill
from components.logs.logfile import read_log, write_log
from components.model.effects import DEFAULT_EFFECTS
from components.model.result import result_from_fit
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

CHUNK = 5000
_POOLS = None  # the worker pools the pair's fixture counts


def _write(tmp_path, name, counts=False):
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["scenario"]["seed"] = 33
    if counts:
        d["imu"]["gyro_output"] = d["imu"]["acc_output"] = "counts"
    log = run_scenario(scenario_from_dict(d, source="test_spill"), progress=False).log
    write_log(tmp_path / name, log, fmt="parquet")
    # several row groups, so the spilled columns are decoded a row group at a time
    path = tmp_path / f"{name}.parquet"
    pq.write_table(pq.read_table(path), path, row_group_size=7000)
    return path


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    path = _write(tmp_path_factory.mktemp("spill"), "run")
    memory = LogData.from_log(read_log(path, lean=True))
    mp = pytest.MonkeyPatch()
    mp.setenv("CALBENCH_SPILL_SAMPLES", "0")
    mp.setattr(spill, "PIECE", 3000)  # passes in pieces smaller than a chunk
    global _POOLS
    _POOLS = send_chunks_to_workers(mp)  # the spilled prediction filled by forked workers
    spilled = LogData.from_log(read_log(path, lean=True))
    yield memory, spilled
    mp.undo()


def _bits(a):
    return np.asarray(a, float).view(np.int64)


def test_the_spilled_columns_are_the_same_bits(pair):
    memory, spilled = pair
    for k in ("time", "angles", "gyro", "acc", "temperature"):
        assert spill.is_spilled(getattr(spilled, k)) and not spill.is_spilled(getattr(memory, k)), k
    for k in ("time", "angles", "gyro", "acc", "temperature"):
        assert np.array_equal(_bits(getattr(memory, k)), _bits(getattr(spilled, k))), k
    # the labels, read a row group at a time when spilled: runs across the groups' seams are one
    assert list(memory.segment) == list(spilled.segment)
    assert len(spilled.segment.starts) == len(memory.segment.starts) < len(spilled.segment) / 100


def test_the_medians_a_piece_at_a_time_are_numpys(pair, monkeypatch):
    """The white-noise σ (a median absolute deviation of the static differences) and the median
    interval, taken a piece at a time from the spilled log (never its differences whole), equal
    numpy's on the differences made whole, bit for bit."""
    from components.estimation import order_statistics
    from components.estimation.blocks import white_noise_sigma

    monkeypatch.setattr(order_statistics, "DIRECT_BELOW", 1000)  # the pieces' path on this short log
    monkeypatch.setattr(spill, "PIECE", 3000)
    _, spilled = pair
    t = np.asarray(spilled.time)
    both = spilled.static[1:] & spilled.static[:-1]
    for inc in (spilled.gyro, spilled.acc):
        d = np.diff(np.asarray(inc), axis=0)[both]
        mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
        assert np.array_equal(white_noise_sigma(inc, spilled.static), 1.4826 * mad / np.sqrt(2))
    assert spilled.interval_median() == np.median(np.diff(t))
    assert spilled.interval_median(first=0.5) == np.median(np.concatenate([[0.5], np.diff(t)]))


def test_estimates_comparison_and_diagnosis_equal_in_memory(pair):
    memory, spilled = pair
    effects = list(DEFAULT_EFFECTS)
    fits = [calibrate(d, effects, chunk_samples=CHUNK) for d in pair]
    assert fits[0].parameters == fits[1].parameters
    assert np.array_equal(fits[0].value, fits[1].value)
    assert np.array_equal(fits[0].covariance, fits[1].covariance)
    model = result_from_fit(fits[0], effects, memory)
    before = _POOLS.started
    comps = [compare(d, model, fitted_parameters=len(model.values), chunk_samples=CHUNK) for d in pair]
    assert _POOLS.started > before  # the spilled prediction did come from workers
    assert comps[0].chi2 == comps[1].chi2 and comps[0].dof == comps[1].dof
    assert comps[0].channels == comps[1].channels
    assert np.array_equal(comps[0].residual, comps[1].residual)
    assert comps[0].per_segment == comps[1].per_segment and comps[0].conditions == comps[1].conditions
    diags = [diagnose(d, model, forward=False, chunk_samples=CHUNK) for d in pair]
    assert diags[0].verdict == diags[1].verdict == "acc.k2"
    assert [(c.effect, c.statistic) for c in diags[0].ranking] == [(c.effect, c.statistic) for c in diags[1].ranking]


def test_a_spilled_logs_usable_mask_is_on_disk_and_the_same(pair, monkeypatch):
    """Samples left out (--exclude and a segment label): a spilled log's usable mask is a
    spilled file, made a piece at a time, with the in-memory log's bits and counts."""
    memory, spilled = pair
    path = memory.source["log"]
    exclude = [[20.0, 35.5], "move-pos03"]
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", str(1 << 40))  # (the module's pair spills by default)
    kept = LogData.from_log(read_log(path, lean=True), exclude)
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
    monkeypatch.setattr(spill, "PIECE", 3000)
    on_disk = LogData.from_log(read_log(path, lean=True), exclude)
    assert spill.is_spilled(on_disk.valid) and not spill.is_spilled(kept.valid)
    assert np.array_equal(on_disk.valid, kept.valid) and on_disk.left_out == kept.left_out
    t = np.asarray(kept.time)
    assert kept.left_out["t = 20-35.5 s (exclude)"] == int(((t >= 20.0) & (t <= 35.5)).sum()) > 0
    assert kept.left_out["segment 'move-pos03' (exclude)"] == int((np.asarray(kept.segment, object)
                                                                   == "move-pos03").sum()) > 0


def test_spilled_groups_read_by_name_and_empty_cells_named(pair, tmp_path, monkeypatch):
    """A spilled column is read a row group at a time: in a file holding the columns in another
    order they still land on their axes, and an empty cell in a later row group is named by its
    row and column."""
    import pyarrow as pa

    from components.errors import LogFormatError

    memory, _ = pair
    src = _write(tmp_path, "src")
    table = pq.read_table(src)
    order = [c for c in table.column_names if c not in ("gyro_x", "acc_y")] + ["acc_y", "gyro_x"]
    shuffled = tmp_path / "shuffled.parquet"
    pq.write_table(table.select(order), shuffled, row_group_size=7000)
    (tmp_path / "shuffled.json").write_text(src.with_suffix(".json").read_text())
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
    got = LogData.from_log(read_log(shuffled, lean=True))
    assert spill.is_spilled(got.gyro) and spill.is_spilled(got.acc)
    for k in ("gyro", "acc"):
        assert np.array_equal(_bits(getattr(memory, k)), _bits(getattr(got, k))), k
    acc_y = table.column("acc_y").to_numpy().astype(object)
    acc_y[15000] = None
    holed = tmp_path / "holed.parquet"
    pq.write_table(table.set_column(table.column_names.index("acc_y"), "acc_y", pa.array(acc_y, pa.float64())),
                   holed, row_group_size=7000)
    (tmp_path / "holed.json").write_text(src.with_suffix(".json").read_text())
    with pytest.raises(LogFormatError, match=r"row 15001, column 'acc_y': empty value"):
        read_log(holed, lean=True)


def test_a_spilled_pulse_output_is_converted_a_piece_at_a_time(tmp_path, monkeypatch):
    path = _write(tmp_path, "counts", counts=True)
    memory = LogData.from_log(read_log(path, lean=True))
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
    monkeypatch.setattr(spill, "PIECE", 3000)
    spilled = LogData.from_log(read_log(path, lean=True))
    assert spill.is_spilled(spilled.gyro)
    assert np.array_equal(_bits(memory.gyro), _bits(spilled.gyro))
    assert np.array_equal(_bits(memory.acc), _bits(spilled.acc))


@pytest.mark.parametrize("spilled", [False, True])
def test_a_corrupt_sample_is_named_in_memory_and_spilled(conformance, tmp_path, monkeypatch, spilled):
    """The range check, a piece at a time: one gyro value at 10^4 rad/s (beyond any gyro's
    1000 rad/s) put at a known sample is found there, whichever piece it falls in."""
    from components.errors import EstimationError

    write_log(tmp_path / "ideal", read_log(conformance / "ideal"), fmt="parquet")
    # (stated both ways: the module's fixture forces the spill for its own tests)
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0" if spilled else str(1 << 40))
    monkeypatch.setattr(spill, "PIECE", 300)
    log = read_log(tmp_path / "ideal.parquet", lean=True)
    assert spill.is_spilled(log.gyro) == spilled
    k = 1234
    log.gyro[k, 1] = 1e4 * log.dt
    with pytest.raises(EstimationError, match=rf"sample {k + 1} .*column gyro_y"):
        LogData.from_log(log)


@pytest.fixture(scope="module")
def csv_pair(tmp_path_factory):
    """The module's log written as CSV, read whole and streamed (spill forced, parser blocks of
    ~20 kB: the 60 k rows in a few hundred blocks)."""
    from components.logs import csv_log

    d = tmp_path_factory.mktemp("spill_csv")
    write_log(d / "run", read_log(_write(d, "src")), fmt="csv")
    mp = pytest.MonkeyPatch()
    # (stated both ways: the module's first fixture may be forcing the spill while this one runs)
    mp.setenv("CALBENCH_SPILL_SAMPLES", str(1 << 40))
    whole = read_log(d / "run.csv", lean=True)
    mp.setenv("CALBENCH_SPILL_SAMPLES", "0")
    mp.setattr(csv_log, "BLOCK_BYTES", 20000)
    streamed = read_log(d / "run.csv", lean=True)
    yield d / "run.csv", whole, streamed
    mp.undo()


def test_a_streamed_csv_log_is_the_same_bits(csv_pair):
    _, whole, streamed = csv_pair
    assert spill.is_spilled(streamed.gyro) and spill.is_spilled(streamed.acc)
    assert not spill.is_spilled(whole.gyro)
    for name in ("time", "gyro", "acc", "temperature"):
        a, b = getattr(whole, name), getattr(streamed, name)
        assert a is not None and a.shape == b.shape, name
        assert np.array_equal(_bits(a), _bits(b)), name
    assert whole.gimbal.keys() == streamed.gimbal.keys()
    for axis in whole.gimbal:
        assert np.array_equal(_bits(whole.gimbal[axis]), _bits(streamed.gimbal[axis])), axis
    assert list(whole.segment) == list(streamed.segment)
    fit = calibrate(LogData.from_log(streamed), list(DEFAULT_EFFECTS))
    assert np.array_equal(fit.value, calibrate(LogData.from_log(whole), list(DEFAULT_EFFECTS)).value)


@pytest.mark.parametrize("line, words", [
    (1, r"data row 1000 \(line 1001\), column 'acc_y': 'x1' is not a number"),
    (0, r"data row 1000 \(line 1001\): blank line"),
    (2, r"data row 1000 \(line 1001\), column 'acc_y': empty value"),
])
def test_a_bad_row_of_a_streamed_csv_is_named(csv_pair, tmp_path, monkeypatch, line, words):
    """Past the parser's first blocks, the row and column of a bad cell are named as in a whole
    read (a word, a blank line, an empty cell)."""
    from components.errors import LogFormatError
    from components.logs import csv_log

    path, _, _ = csv_pair
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    fields = lines[1000].split(",")
    j = header.index("acc_y")
    fields[j] = {1: "x1", 2: ""}.get(line, fields[j])
    lines[1000] = "" if line == 0 else ",".join(fields)
    bad = tmp_path / "run.csv"
    bad.write_text("\n".join(lines) + "\n")
    (tmp_path / "run.json").write_text(path.with_suffix(".json").read_text())
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
    monkeypatch.setattr(csv_log, "BLOCK_BYTES", 20000)
    with pytest.raises(LogFormatError, match=words):
        read_log(bad, lean=True)


@pytest.mark.parametrize("shape", [(5000,), (5000, 3)])
def test_rows_gathered_from_a_spilled_column_a_piece_at_a_time_are_its_rows(monkeypatch, shape):
    """spill.gathered(a, index) is a[index] for indices in any order, repeated, at the ends and
    on piece boundaries, whether *a* is spilled (read a piece at a time) or not."""
    monkeypatch.setattr(spill, "PIECE", 64)
    rng = np.random.default_rng(2)
    values = rng.standard_normal(shape)
    on_disk = spill.spilled_array(shape)
    on_disk[:] = values
    index = np.concatenate([rng.integers(0, shape[0], 700), [0, shape[0] - 1, 64, 63, 128, 64], [17] * 3])
    for a in (values, on_disk):
        got = spill.gathered(a, index)
        assert got.shape == (len(index),) + shape[1:]
        assert np.array_equal(got, values[index])
    assert spill.gathered(on_disk, np.zeros(0, int)).shape == (0,) + shape[1:]


def test_rows_and_columns_gathered_from_a_wide_spilled_array(monkeypatch):
    """spill.gathered(a, index, columns) is a[index][:, columns]; rows as wide as a design's
    (hundreds of columns) are read fewer at a time, so a piece stays the same bytes."""
    monkeypatch.setattr(spill, "PIECE", 64)
    rng = np.random.default_rng(3)
    values = rng.standard_normal((3000, 300))
    on_disk = spill.spilled_array(values.shape)
    on_disk[:] = values
    # a piece of wide rows holds no more bytes than a piece of a sample's six values, and at least a row
    narrow = spill.spilled_array((10, 6))
    assert spill.piece_rows(narrow) == spill.PIECE
    assert 1 <= spill.piece_rows(on_disk) and spill.piece_rows(on_disk) * 300 <= spill.PIECE * 6
    assert spill.piece_rows(spill.spilled_array((10, 3))) == spill.PIECE  # (narrower: not more than PIECE)
    # a view of every 28th sample: a piece of it spans no more of the file than a piece of samples
    every = spill.spilled_array((10_000, 6))[::28]
    assert 1 <= spill.piece_rows(every) and spill.piece_rows(every) * 28 <= spill.PIECE
    index = np.concatenate([rng.integers(0, 3000, 500), [0, 2999, 1, 1]])
    for columns in ([7, 3, 299], []):
        for a in (values, on_disk):
            assert np.array_equal(spill.gathered(a, index, columns), values[index][:, columns])


def test_a_spilled_arrays_product_a_piece_at_a_time_is_its_product(monkeypatch):
    """spill.product(a, x, columns) is a[:, columns] @ x row for row, a few rows at a time, on
    a spilled array as on a plain one (pieces not dividing the rows, a vector and a matrix x)."""
    monkeypatch.setattr(spill, "PIECE", 64)
    rng = np.random.default_rng(4)
    values = rng.standard_normal((1001, 300))
    on_disk = spill.spilled_array(values.shape)
    on_disk[:] = values
    for columns, x in ((None, rng.standard_normal(300)), ([5, 299, 0], rng.standard_normal(3)),
                       ([1, 2], rng.standard_normal((2, 4)))):
        A = values if columns is None else values[:, columns]
        want, bound = A @ x, 1e-13 * (np.abs(A) @ np.abs(x))  # (a dot product's rounding: BLAS may block it apart)
        for a in (values, on_disk):
            got = spill.product(a, x, columns)
            assert got.shape == want.shape and np.all(np.abs(got - want) <= bound)


@pytest.mark.parametrize("shape", [(5000,), (5000, 3), (0, 3)])
def test_rows_written_through_a_spilled_arrays_file_are_read_through_its_mapping(shape):
    """spill.write_rows(a, start, v) is a[start:start + len(v)] = v, for a spilled array (written
    to its file, read back through the mapping), a view of one and a plain array; rows beyond
    the array are refused, not written past its end."""
    rng = np.random.default_rng(5)
    values = rng.standard_normal(shape)
    on_disk, plain = spill.spilled_array(shape), np.zeros(shape)
    for a in (on_disk, plain):
        for start in range(0, shape[0], 1234):
            spill.write_rows(a, start, values[start:start + 1234])
        assert np.array_equal(a, values)
    if shape[0] and len(shape) == 2:
        spill.write_rows(on_disk[:, 1], 10, np.full(5, 7.0))  # a strided view: through the mapping
        assert np.all(on_disk[10:15, 1] == 7.0) and np.array_equal(on_disk[10:15, 0], values[10:15, 0])
    with pytest.raises(IndexError):
        spill.write_rows(on_disk, shape[0] - 1, values[:2] if shape[0] else np.zeros((2,) + shape[1:]))


@pytest.mark.skipif(not hasattr(os, "posix_fallocate"), reason="no posix_fallocate: a sparse file there")
def test_a_spilled_arrays_disk_blocks_are_allocated_when_it_is_made():
    """The file behind a spilled array holds its blocks from the start (not a sparse hole that
    allocates at each page written, or fails at a write through the mapping on a full disk): the
    file system counts at least its size in blocks before a row is written; zeros read back.
    (Skipped where the temporary directory's file system cannot reserve: a sparse file there.)"""
    import tempfile

    with tempfile.TemporaryFile() as probe:
        try:
            os.posix_fallocate(probe.fileno(), 0, 4096)
        except OSError as e:
            if e.errno not in spill.NO_ROOM:
                pytest.skip(f"this file system cannot reserve blocks ({e.strerror})")
    a = spill.spilled_array((300_000, 3))
    st = os.fstat(a._spill_file.fileno())
    assert st.st_size == a.nbytes
    assert st.st_blocks * 512 >= a.nbytes
    assert not a[::997].any()


def _failing_fallocate(code):
    def fallocate(fd, offset, length):
        raise OSError(code, os.strerror(code))
    return fallocate


def test_a_temporary_directory_too_small_for_a_spill_is_one_error_naming_it(monkeypatch):
    """No room for a long log's columns is one error naming the directory, the size and TMPDIR,
    raised when the array is made, not a crash at a later write."""
    import tempfile

    from components.errors import SpillError

    monkeypatch.setattr(os, "posix_fallocate", _failing_fallocate(errno.ENOSPC), raising=False)
    with pytest.raises(SpillError) as e:
        spill.spilled_array((1_000_000, 6))
    msg = str(e.value)
    assert tempfile.gettempdir() in msg and "0.05 GB" in msg and "TMPDIR" in msg
    assert os.strerror(errno.ENOSPC) in msg


@pytest.mark.parametrize("code", [errno.EOPNOTSUPP, errno.EINVAL])
def test_a_file_system_that_cannot_reserve_blocks_still_spills(monkeypatch, code):
    """Where the temporary directory's file system cannot reserve blocks (not a want of space),
    the array is a sparse file as before: made, written and read back, no error."""
    monkeypatch.setattr(os, "posix_fallocate", _failing_fallocate(code), raising=False)
    a = spill.spilled_array((1000, 3))
    values = np.arange(3000.0).reshape(1000, 3)
    spill.write_rows(a, 0, values)
    assert np.array_equal(a, values)


def test_no_room_to_spill_a_log_is_could_not_run_on_the_command_line(tmp_path, monkeypatch, capsys):
    """calibrate on a long log with a full temporary directory: exit 3 (could not run, not bad
    input) and one line naming the directory and TMPDIR, no traceback."""
    import tempfile

    from components.cli import main

    path = _write(tmp_path, "full")
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", "0")
    monkeypatch.setattr(os, "posix_fallocate", _failing_fallocate(errno.ENOSPC), raising=False)
    code = main(["calibrate", str(path), "--out", str(tmp_path / "r.json")])
    err = capsys.readouterr().err
    assert code == 3
    assert "could not run" in err and tempfile.gettempdir() in err and "TMPDIR" in err
    assert "Traceback" not in err and not (tmp_path / "r.json").exists()


@pytest.mark.parametrize("spilled", ["0", str(1 << 40)])
def test_an_empty_label_is_refused_naming_its_row(tmp_path, monkeypatch, spilled):
    """An empty text label in a Parquet log (and a null one) is an empty value, as in a CSV log;
    the empty one was read as a label of its own (a segment of one sample in the schedule)."""
    import pyarrow as pa

    from components.errors import LogFormatError

    src = _write(tmp_path, "src")
    table = pq.read_table(src)
    labels = [str(x) for x in table.column("segment").to_pylist()]
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", spilled)
    for name, value in (("empty", ""), ("null", None)):
        holed = list(labels)
        holed[9000] = value
        path = tmp_path / f"{name}.parquet"
        pq.write_table(table.set_column(table.column_names.index("segment"), "segment", pa.array(holed, pa.string())),
                       path, row_group_size=7000)
        (tmp_path / f"{name}.json").write_text(src.with_suffix(".json").read_text())
        with pytest.raises(LogFormatError, match=r"row 9001, column 'segment': empty value; expected text"):
            read_log(path, lean=True)


@pytest.mark.parametrize("spilled", ["0", str(1 << 40)])
def test_a_damaged_parquet_log_is_refused_not_read_as_zeros(tmp_path, monkeypatch, spilled):
    """calbench writes its Parquet pages with checksums and checks them as it reads: bytes zeroed
    inside the file (a bad copy, a disk error) are an error naming the file; without checksums
    they decoded to zeros and 6e-322s in one column, and calibrate went on with exit 0."""
    from components.errors import LogFormatError

    write_log(tmp_path / "written", read_log(_write(tmp_path, "src")), fmt="parquet")
    src = tmp_path / "written.parquet"
    raw = bytearray(src.read_bytes())
    mid = len(raw) // 2
    raw[mid:mid + 2000] = bytes(2000)
    src.write_bytes(bytes(raw))
    monkeypatch.setenv("CALBENCH_SPILL_SAMPLES", spilled)
    with pytest.raises(LogFormatError, match=r"written\.parquet: .*cannot be read"):
        read_log(src, lean=True)


def _resident_bytes(array) -> int:
    """The resident bytes of the mapping *array* lies in (Linux: /proc/self/smaps)."""
    at = array.ctypes.data
    with open("/proc/self/smaps") as f:
        inside = False
        for line in f:
            head = line.split()[0]
            if "-" in head and all(c in "0123456789abcdef-" for c in head):
                lo, hi = (int(x, 16) for x in head.split("-"))
                inside = lo <= at < hi
            elif inside and line.startswith("Rss:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no mapping holds the array")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/smaps")
def test_the_sample_checks_give_back_a_spilled_time_columns_pages():
    """check_samples reads a spilled time column a piece at a time and gives each piece's pages
    back: after it, at most about a piece of the column is resident (before, its interval pass
    left the whole column in: 32 MB here, 242 MB on an 8-hour 1 kHz log)."""
    from components.logs.rules import check_samples
    from components.logs.spill import PIECE, release, spilled_array, write_rows

    n = 16 * PIECE
    t = spilled_array((n,))
    write_rows(t, 0, np.arange(1, n + 1) * 1e-3)  # (through the file: no page mapped yet)
    release(t)
    meta = {"sample_rate_hz": 1000.0, "gyro_output": "increment", "acc_output": "increment"}
    check_samples({"time": t}, meta, "a log", lambda i: f"row {i + 1}")
    assert _resident_bytes(t) <= 2 * PIECE * t.itemsize, _resident_bytes(t)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/smaps")
def test_the_median_of_a_spilled_column_gives_its_pages_back(monkeypatch):
    """order_statistics.median of a spilled column (the plate's intervals a comparison takes the
    median of) is np.median's, and leaves at most about a piece of the column resident (it gave
    back the pages of a plain-array view of the column, which has none: the whole column, 240 MB
    on an 8-hour 1 kHz log, stayed in)."""
    from components.estimation import order_statistics
    from components.estimation.order_statistics import median
    from components.logs.spill import release, spilled_array, write_rows

    # (a piece of its own: a module fixture here sets a smaller one for its tests' duration)
    monkeypatch.setattr(spill, "PIECE", PIECE := 1 << 14)
    n = 16 * PIECE + 3
    assert n > order_statistics.DIRECT_BELOW  # the median by pieces, not np.median on the whole
    values = 1e-3 + np.random.default_rng(8).normal(0, 1e-9, n)
    dt = spilled_array((n,))
    write_rows(dt, 0, values)
    release(dt)
    # the bracket's sample (every stride-th value: on every page of a long column) is taken a
    # piece at a time too: at most about a piece resident once it is made, not the column
    at_sample = []
    by_pieces = order_statistics.median_of_pieces

    def counted(pieces, n, sample):
        def first_pass():  # (the sample is sorted before the first pass)
            if not at_sample:
                at_sample.append(_resident_bytes(dt))
            return pieces()
        return by_pieces(first_pass, n, sample)

    monkeypatch.setattr(order_statistics, "median_of_pieces", counted)
    assert median(dt) == np.median(values)
    assert at_sample and at_sample[0] <= 2 * PIECE * dt.itemsize, at_sample
    assert _resident_bytes(dt) <= 2 * PIECE * dt.itemsize, _resident_bytes(dt)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/smaps")
def test_a_results_schedule_reads_a_spilled_time_column_a_piece_at_a_time(monkeypatch):
    """The schedule a result records (each segment's first and last time) is the same from a
    spilled time column read a piece at a time (LogData.times_at) as from the column in memory,
    and leaves at most about a piece of the column resident: read at each run's ends through the
    mapping, every read brought the pages around it along (768 runs of an 8-hour 1 kHz log: 220
    MB, the peak of its calibrate)."""
    from types import SimpleNamespace

    from components.estimation.log_data import LogData
    from components.logs.labels import SegmentLabels
    from components.logs.spill import release, spilled_array, write_rows
    from components.model.result import schedule_of

    monkeypatch.setattr(spill, "PIECE", PIECE := 1 << 14)
    n = 64 * PIECE
    times = 0.25 + np.arange(n) * 1e-3
    t = spilled_array((n,))
    write_rows(t, 0, times)
    release(t)
    starts = np.concatenate([[0], np.sort(np.random.default_rng(5).choice(np.arange(1, n), 700, replace=False))])
    seg = SegmentLabels(starts, np.arange(len(starts)) % 3, ["move", "rest", "turn"], n)
    data = SimpleNamespace(time=t)  # (times_at needs only the column)
    got = schedule_of(t, seg, take=lambda i: LogData.times_at(data, i))
    assert got == schedule_of(times, seg)
    assert got[0][1] == 0.25 - 1e-3 and got[-1][2] == times[-1]
    assert _resident_bytes(t) <= 2 * PIECE * 8


def test_a_spilled_logs_static_mask_is_on_disk_and_the_in_memory_one(pair):
    """The static mask of a spilled log (a byte a sample, the most of what a long log's command
    kept in memory) goes to disk beside its columns, as do its rest samples that are usable; both
    are the masks of the log in memory."""
    memory, spilled = pair
    assert spill.is_spilled(spilled.static) and not spill.is_spilled(memory.static)
    assert np.array_equal(memory.static, spilled.static)
    # the demo's log has no left-out sample: leave some out, as a mask or a gap would
    valid = np.ones(len(memory.time), bool)
    valid[::7] = False
    masked = [dataclasses.replace(d, valid=valid) for d in pair]
    want = np.asarray(memory.static) & valid
    assert spill.is_spilled(masked[1].static_usable) and not spill.is_spilled(masked[0].static_usable)
    assert np.array_equal(masked[0].static_usable, want) and np.array_equal(masked[1].static_usable, want)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/smaps")
def test_the_static_mask_and_the_white_level_give_a_spilled_masks_pages_back():
    """A long log's static mask is made a piece at a time into its file, and the white level's
    pass over the rest pairs reads it a piece at a time: after each, at most about a piece of the
    mask is resident (before, the mask was in memory whole, and the pairs at rest were a second
    whole mask beside it)."""
    from components.estimation.blocks import white_noise_sigma
    from components.logs.spill import PIECE, release, spilled_array, write_rows
    from components.model.geometry import Stage, TableGeometry

    n = 16 * PIECE
    rng = np.random.default_rng(5)
    angles = spilled_array((n, 1))
    # rests of 100 000 samples, moves of 5 000 between them
    write_rows(angles, 0, (np.floor(np.arange(n) / 105_000) + np.clip(np.arange(n) % 105_000 - 100_000, 0, None)
                           / 5000.0)[:, None])
    gyro = spilled_array((n, 3))
    write_rows(gyro, 0, rng.normal(0, 1e-6, (n, 3)))
    release(angles, gyro)
    data = LogData(time=np.arange(n) * 1e-3, angles=angles, gyro=gyro, acc=gyro,
                   geometry=TableGeometry((Stage("inner", (0.0, 0.0, 1.0)),), latitude=0.7))
    st = data.static
    assert spill.is_spilled(st) and _resident_bytes(st) <= 2 * PIECE, _resident_bytes(st)
    a = np.asarray(angles)[:, 0]
    assert np.array_equal(st, np.concatenate([[True], a[1:] == a[:-1]]))
    release(st)
    sigma = white_noise_sigma(gyro, st)
    assert _resident_bytes(st) <= 2 * PIECE, _resident_bytes(st)
    # and it is the white level: the rest pairs' differences have σ √2 (a MAD, 1 % at this size)
    assert np.allclose(sigma, 1e-6, rtol=0.01)
