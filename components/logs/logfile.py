"""Measurement logs, formats ``calbench-log/1`` and ``calbench-log/2`` (docs/measurement-log.md).

:func:`read_log` reads the pair ``<stem>.csv`` (or ``<stem>.parquet``) + ``<stem>.json`` into a
:class:`MeasurementLog`, enforcing every rule of the spec; :func:`write_log` writes one;
:func:`components.logs.recording.log_from_recording` makes one from an orchestrator recording of a
turntable + IMU run; the rules themselves are in components/logs/rules.py.

Every broken rule raises :class:`LogFormatError` naming the file, the key or the data row
("data row 17 (line 18)": 1-based, the header is line 1) and what was expected.

Choices the spec leaves open, stated here:

* **Gaps.** A sample interval ``t[k] - t[k-1]`` is refused when it differs from
  ``1 / sample_rate_hz`` by more than ``max(1 % of the interval, 1e-6 s)``. One missing sample is a
  100 % deviation, so any dropped sample is caught, while timestamp jitter and rounding of a
  logger (a µs clock is 0.1 % of a 1 kHz interval; times written with a few decimals) pass. The
  1e-6 s floor keeps very fast loggers with µs timestamps usable.
* **Required keys.** Every key of the spec's example is required, including
  ``site.gravity_mps2`` (``null`` has a meaning: normal gravity, so a missing key is not taken
  as ``null``), except ``description`` (free text, default "") and the count weights, which are
  required (non-null, positive) only for an output of kind ``counts``; other keys are kept.
* **Counts** must be whole numbers. Axis vectors must have unit length within 1e-9.
  ``latitude_deg`` must be in [-90, 90], ``sample_rate_hz`` and ``gravity_mps2`` positive.
* **CSV.** Empty cells in numeric columns, and blank lines, are refused; surrounding blanks in
  a number are tolerated (pyarrow's parser). A file with both ``<stem>.csv`` and
  ``<stem>.parquet`` read by its stem reads the CSV; give the file name to read the other.
* **Increments and what is left out**: components/logs/measurement.py.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from components.errors import LogFormatError
from components.logs.angle_turns import made_continuous
from components.logs.csv_log import csv_row, float_values, labels, not_utf8, read_csv, sensor_groups, wanted_columns
from components.logs.labels import SegmentLabels
from components.logs.measurement import MeasurementLog
from components.logs.rules import (  # noqa: F401  (FORMAT: re-exported)
    FORMAT,
    FORMAT_V2,
    MAX_METADATA_DEPTH,
    XYZ,
    check_columns,
    check_samples,
    numeric_columns,
    parse_metadata,
)
from components.logs.spill import release, spill_threshold, spilled_array, write_rows


# ---------------------------------------------------------------------------- reading
def sample_file(path: str | Path) -> Path:
    """The samples' file (.csv or .parquet) of the log *path* names (either file or the stem)."""
    return _pair(path)[0]


def _pair(path: str | Path) -> tuple[Path, Path]:
    p = Path(path)
    if p.suffix.lower() in (".csv", ".parquet"):
        data, meta = p, p.with_suffix(".json")
    elif p.suffix.lower() == ".json":
        meta = p
        cands = [p.with_suffix(".csv"), p.with_suffix(".parquet")]
        data = next((c for c in cands if c.exists()), cands[0])
    else:
        meta = Path(str(p) + ".json")
        cands = [Path(str(p) + ".csv"), Path(str(p) + ".parquet")]
        data = next((c for c in cands if c.exists()), cands[0])
    if not data.exists():
        other = " or .parquet" if data.suffix == ".csv" else ""
        raise LogFormatError(f"{data}: sample file does not exist (expected {data.name}{other} next to "
                             f"{meta.name})")
    if not meta.exists():
        raise LogFormatError(f"{meta}: metadata file does not exist (expected next to {data.name})")
    return data, meta


MAX_METADATA_BYTES = 16 << 20   # a metadata file is a page of keys; a bigger one is not metadata


def _read_meta(path: Path) -> dict:
    size = path.stat().st_size
    if size > MAX_METADATA_BYTES:
        raise LogFormatError(f"{path}: {size} bytes of metadata; expected at most {MAX_METADATA_BYTES} (the small "
                             "object of docs/measurement-log.md)")
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise LogFormatError(f"{path}: not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    except RecursionError:
        raise LogFormatError(f"{path}: metadata nested deeper than {MAX_METADATA_DEPTH} levels; expected the flat "
                             "object of docs/measurement-log.md") from None
    except UnicodeDecodeError as e:
        raise LogFormatError(not_utf8(path, e)) from None
    return parse_metadata(raw, str(path))


def _read_parquet(path: Path, meta: dict, lean: bool = False) -> tuple[dict, dict]:
    """(column name -> values, group -> (N, k) array) of a Parquet log; the gyro, accelerometer
    and gimbal columns are written straight into their group's array (``cols`` holds views of
    it), so that a long log is held once, not as columns beside their stack."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        names = pq.read_schema(path).names
        # (read_dictionary naming a column the file lacks is a KeyError, not "no such column")
        # pages written with a checksum (calbench writes them) are checked as they are read: a
        # damaged file is an error, not a log with zeros in it
        pf = pq.ParquetFile(path, read_dictionary=["segment"] if "segment" in names else None,
                            page_checksum_verification=True)
        schema = pf.schema_arrow
    except (pa.ArrowInvalid, OSError) as e:
        raise LogFormatError(f"{path}: not a readable Parquet file ({e})") from None
    header = schema.names
    check_columns(header, meta, str(path))
    numeric = set(numeric_columns(header, meta))
    n = pf.metadata.num_rows
    # a long log read for the estimators: its sensor columns on disk (components.logs.spill)
    spill = lean and n > spill_threshold()
    heavy = ({"time", "gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z", "temperature"}
             | {f"gimbal_{a}" for a in meta["axis_names"]}) if spill else set()
    stacked = {g: spilled_array((n, len(c))) if c and set(c) <= heavy else np.empty((n, len(c)))
               for g, c in sensor_groups(meta).items()}
    place = {c: (g, j) for g, cs in sensor_groups(meta).items() for j, c in enumerate(cs)}
    cols: dict[str, np.ndarray] = {}
    names = wanted_columns(header, meta, lean)
    for name in names:
        typ = schema.field(name).type
        if name in numeric and not (pa.types.is_floating(typ) or pa.types.is_integer(typ)):
            raise LogFormatError(f"{path}: column {name!r} has type {typ}; expected numbers")
        if name == "segment":
            t = typ.value_type if pa.types.is_dictionary(typ) else typ
            if not (pa.types.is_string(t) or pa.types.is_large_string(t)):
                raise LogFormatError(f"{path}: column 'segment' has type {typ}; expected text")
        if name in heavy and name not in place:
            cols[name] = spilled_array((n,))

    def checked(name, col, row):
        if col.null_count and (name in numeric or name == "segment"):
            i = row + int(np.argmax(col.is_null().to_numpy(zero_copy_only=False)))
            raise LogFormatError(f"{path}: row {i + 1}, column {name!r}: empty value; expected "
                                 + ("text" if name == "segment" else "a number"))
        return col

    def put(name, col):
        col = checked(name, col, 0)
        if name in place:
            g, j = place[name]
            stacked[g][:, j] = float_values(col)
            cols[name] = stacked[g][:, j]
        else:
            cols[name] = light(name, col)

    def light(name, col):
        """A column outside the sensor groups as calbench holds it: numbers as float64, the
        segment labels as runs, anything else as it is."""
        if name in numeric:
            return float_values(col)
        return labels(col) if name == "segment" else col.to_numpy()

    def put_by_row_group(name):
        """A light column of a spilled log a row group at a time: the segment labels as each
        group's runs, joined (the whole column read at once was its Arrow indices, their numpy
        copy and the run-finding's temporaries: ~9 bytes a sample at the read's peak)."""
        parts, row = [], 0
        for i in range(pf.num_row_groups):
            col = checked(name, _read_columns(pf, [name], path, i).column(0), row)
            parts.append(light(name, col))
            row += len(col)
        cols[name] = SegmentLabels.concatenate(parts) if name == "segment" else np.concatenate(parts)

    # the light columns a column at a time (the whole Arrow table beside its numpy copies held 3x
    # the log at once)
    for name in (c for c in names if c not in heavy):
        if spill and pf.num_row_groups > 1:
            put_by_row_group(name)
        else:
            put(name, _read_columns(pf, [name], path).column(0))
    # the spilled ones a row group at a time, the columns of one (N, k) array together: each
    # row group's rows of the array are put together in memory and written to its file once
    spilled = [c for c in names if c in heavy]
    together = [[c for c in cs if c in spilled] for cs in sensor_groups(meta).values()]
    together = [cs for cs in together if cs] + [[c] for c in spilled if c not in place]
    for cs in together:
        target = stacked[place[cs[0]][0]] if cs[0] in place else cols[cs[0]]
        row = 0
        for i in range(pf.num_row_groups):
            table = _read_columns(pf, cs, path, i)
            block = np.empty((table.num_rows,) + target.shape[1:])
            for name in cs:
                values = float_values(checked(name, table.column(name), row))
                if name in place:
                    block[:, place[name][1]] = values
                else:
                    block[:] = values
            write_rows(target, row, block)  # (every column of a group is there: check_columns)
            row += table.num_rows
            del table, block
        for name in cs:
            if name in place:
                cols[name] = stacked[place[name][0]][:, place[name][1]]
    # Arrow's allocator keeps what it freed for reuse; the log is read, give it back
    pa.default_memory_pool().release_unused()
    return cols, stacked


def _read_columns(pf, names: list[str], path: Path, row_group: int | None = None):
    """The columns *names* of the Parquet file as a table: whole, or one row group."""
    import pyarrow as pa

    try:
        return pf.read(columns=names) if row_group is None else pf.read_row_group(row_group, columns=names)
    except (pa.ArrowInvalid, OSError) as e:
        what = f"column {names[0]!r}" if len(names) == 1 else f"row group {row_group}"
        raise LogFormatError(f"{path}: {what} cannot be read ({e})") from None


def read_log(path: str | Path, *, lean: bool = False) -> MeasurementLog:
    """Read a ``calbench-log/1`` pair; *path* is either file of the pair or the common stem.
    ``lean``: only the columns the estimators use (time, gimbal angles, gyro, accelerometer,
    temperature, segment, mask), not the commands and extra columns (on an hours-long log at
    1 kHz they are gigabytes no estimate reads); a long Parquet log's sensor columns are then
    memory-mapped from a temporary file (components.logs.spill)."""
    data, meta_path = _pair(path)
    meta = _read_meta(meta_path)
    if data.suffix.lower() == ".parquet":
        cols, stacked = _read_parquet(data, meta, lean)
        row = lambda i: f"row {i + 1}"  # noqa: E731
    else:
        cols, stacked = read_csv(data, meta, lean)
        row = csv_row
    check_samples(cols, meta, str(data), row)
    axes = meta["axis_names"]
    turns = _continuous_angles(cols, axes)
    known = {"time", "temperature", "segment", "mask"} | {f"{s}_{c}" for s in ("gyro", "acc") for c in XYZ} | \
        {f"{p}_{a}" for p in ("gimbal", "command") for a in axes}
    seg = cols.get("segment")
    # (by the runs' labels, not a code: a dictionary may hold the empty text under more than one)
    empty = np.flatnonzero(seg.names[seg.codes] == "") if isinstance(seg, SegmentLabels) else []
    if len(empty):
        raise LogFormatError(f"{data}: {row(int(seg.starts[empty[0]]))}, column 'segment': empty value; expected text")
    _check_labels(meta, seg, str(meta_path))
    log = MeasurementLog(
        time=cols["time"],
        gimbal={a: cols[f"gimbal_{a}"] for a in axes},
        angle_matrix=stacked.get("gimbal"),
        command={a: cols[f"command_{a}"] for a in axes if f"command_{a}" in cols},
        gyro=stacked["gyro"] if "gyro" in stacked else np.column_stack([cols[f"gyro_{c}"] for c in XYZ]),
        acc=stacked["acc"] if "acc" in stacked else np.column_stack([cols[f"acc_{c}"] for c in XYZ]),
        temperature=cols.get("temperature"),
        segment=cols.get("segment"),
        extra={k: v for k, v in cols.items() if k not in known},
        source=str(data),
        mask=cols["mask"].astype(bool) if "mask" in cols else None,
        turns_mended=turns,
        **{k: meta[k] for k in ("axis_names", "axis_vectors", "sample_rate_hz", "gyro_output", "acc_output",
                                "gyro_count_rad", "acc_count_mps", "latitude_deg", "height_m", "gravity_mps2",
                                "description", "extra_metadata", "encoder_resolution", "timing", "max_interval_s",
                                "segments", "exclude", "noise", "gyro_range", "acc_range")},
    )
    log.reasons_left_out()  # an 'exclude' label the log does not hold is refused here, naming the file
    return log


def _continuous_angles(cols: dict, axes: list[str]) -> dict[str, int]:
    """A controller's angles read to one turn (0-360°) made continuous, in place (a column
    Arrow lent read-only is copied first; the commands stay as read): axis -> wraps mended
    (components.logs.angle_turns)."""
    mended = {}
    for a in (a for a in axes if f"gimbal_{a}" in cols):
        cols[f"gimbal_{a}"], n = made_continuous(cols[f"gimbal_{a}"])
        if n:
            mended[a] = n
    return mended


def _check_labels(meta: dict, seg, where: str) -> None:
    """A log without table angles: every static or rotation description names a label the log
    holds (a typo would silently drop a position)."""
    kinds = meta.get("segment_kinds")
    if not kinds or seg is None:
        return
    have = set(SegmentLabels.of(seg).distinct())
    missing = [lab for lab, d in kinds.items() if d["kind"] != "excluded" and lab not in have]
    if missing:
        raise LogFormatError(f"{where}: key 'segments' describes label(s) {', '.join(map(repr, missing))} that no "
                             "sample carries; expected labels of the 'segment' column")


# ---------------------------------------------------------------------------- writing
def write_log(stem: str | Path, log: MeasurementLog, fmt: str = "csv") -> list[Path]:
    """Write ``<stem>.json`` and ``<stem>.csv`` (``fmt="csv"``), ``<stem>.parquet``
    (``"parquet"``) or both (``"both"``). Numbers are written in the shortest form that reads
    back to the same double (bit-exact round trip). The log is validated first."""

    if fmt not in ("csv", "parquet", "both"):
        raise ValueError(f"fmt {fmt!r}: expected 'csv', 'parquet' or 'both'")
    stem = log_stem(stem)
    log.validate(f"log for {stem}")
    cols = log.columns()
    # text columns (the segment labels) as a dictionary: their labels sorted, once
    labels = {k: _labels_of(v) for k, v in cols.items()
              if k == "segment" or (isinstance(v, np.ndarray) and v.dtype.kind in "OU")}
    n = log.n
    out = [_write_metadata(stem, log)]
    if fmt in ("csv", "both"):
        out.append(_write_csv(Path(str(stem) + ".csv"), cols, labels, n))
    if fmt in ("parquet", "both"):
        import pyarrow.parquet as pq

        p = Path(str(stem) + ".parquet")
        writer = None
        try:
            for rows in _row_slices(n):
                table = _table_of(cols, labels, rows)
                if writer is None:
                    writer = pq.ParquetWriter(p, table.schema, write_page_checksum=True)
                writer.write_table(table, row_group_size=WRITE_ROWS)
        finally:
            if writer is not None:
                writer.close()
        out.append(p)
    return out


def rewrite_parquet(src: str | Path, stem: str | Path, log: MeasurementLog, columns: list[str]) -> list[Path]:
    """``<stem>.json`` (the metadata of *log*) and ``<stem>.parquet``: the Parquet log *src*
    a row group at a time, its *columns* taken from *log* (the same samples, e.g. corrected),
    every other column as it is: a long log rewritten without its other columns in memory."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    stem = log_stem(stem)
    meta_path = _write_metadata(stem, log)
    out = Path(str(stem) + ".parquet")
    cols = log.columns()
    pf = pq.ParquetFile(src, page_checksum_verification=True)
    if pf.metadata.num_rows != log.n:
        raise LogFormatError(f"{src}: {pf.metadata.num_rows} rows; the log to write has {log.n}")
    writer, row = None, 0
    try:
        for i in range(pf.num_row_groups):
            table = pf.read_row_group(i)
            rows = slice(row, row + table.num_rows)
            for name in columns:
                table = table.set_column(table.schema.get_field_index(name), name,
                                         pa.array(np.ascontiguousarray(cols[name][rows], dtype=float)))
            if writer is None:
                writer = pq.ParquetWriter(out, table.schema, write_page_checksum=True)
            writer.write_table(table)
            release(*(cols[name] for name in columns))
            row += table.num_rows
    finally:
        if writer is not None:
            writer.close()
    return [meta_path, out]


def log_stem(stem: str | Path) -> Path:
    """The log's stem, whether given as the stem or as one of its files."""
    stem = Path(stem)
    return stem.with_suffix("") if stem.suffix.lower() in (".csv", ".parquet", ".json") else stem


def _write_metadata(stem: Path, log: MeasurementLog) -> Path:
    """``<stem>.json``: the metadata of *log* (its directory made)."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    path = Path(str(stem) + ".json")
    path.write_text(json.dumps(log.metadata(), indent=1) + "\n", encoding="utf-8")
    return path


# rows converted and written at a time: a long log is never held twice (as its columns and as
# an Arrow table beside them: 12 GB for an 8-hour log's apply)
WRITE_ROWS = 1 << 20


def _row_slices(n: int):
    yield from (slice(a, min(a + WRITE_ROWS, n)) for a in range(0, n, WRITE_ROWS)) if n else (slice(0, 0),)


def _labels_of(v) -> np.ndarray:
    """The distinct labels of a text column as str, sorted (np.unique's order), a piece at a time."""
    if isinstance(v, SegmentLabels):
        return np.array(v.distinct(), dtype=str)
    got: set = set()
    for rows in _row_slices(len(v)):
        got.update(np.unique(np.asarray(v[rows], dtype=object).astype(str)).tolist())
    return np.array(sorted(got), dtype=str)


def _table_of(cols: dict, labels: dict, rows: slice):
    """The Arrow table of the samples *rows*; text columns as dictionaries of their *labels*."""
    import pyarrow as pa

    arrays = {}
    for k, v in cols.items():
        if k in labels and isinstance(v, SegmentLabels):
            piece = v[rows]
            codes = np.repeat(np.searchsorted(labels[k], piece.names.astype(str))[piece.codes], piece.lengths)
            arrays[k] = pa.DictionaryArray.from_arrays(pa.array(codes.astype(np.int32)),
                                                       pa.array(labels[k].tolist(), type=pa.string()))
        elif k in labels:
            codes = np.searchsorted(labels[k], np.asarray(v[rows], dtype=object).astype(str)).astype(np.int32)
            arrays[k] = pa.DictionaryArray.from_arrays(pa.array(codes), pa.array(labels[k].tolist(), type=pa.string()))
        else:
            arrays[k] = pa.array(np.ascontiguousarray(v[rows]))
    return pa.table(arrays)


def _write_csv(path: Path, cols: dict, labels: dict, n: int) -> Path:
    import pyarrow as pa
    import pyarrow.csv as pcsv

    special = re.compile(r'[,"\r\n]')

    def needs_quote(s: str) -> bool:
        return bool(special.search(s)) or s != s.strip()

    quote = any(needs_quote(str(s)) for lab in labels.values() for s in lab)
    header = ",".join(f'"{c}"' if needs_quote(c) else c for c in cols) + "\n"
    tmp = path.with_name(path.name + ".tmp")
    with pa.OSFile(str(tmp), "wb") as f:
        f.write(header.encode())
        for rows in _row_slices(n):
            pcsv.write_csv(_table_of(cols, labels, rows), f,
                           pcsv.WriteOptions(include_header=False, batch_size=1 << 16,
                                             quoting_style="needed" if quote else "none"))
    tmp.replace(path)
    return path


