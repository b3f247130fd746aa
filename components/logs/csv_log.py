"""The data file of a CSV log (docs/measurement-log.md): read whole, or — a long log read for the
estimators — a block of rows at a time into memory-mapped arrays (components.logs.spill), as a
Parquet log is a row group at a time. Either way the same float64 values and the same errors:
a row that breaks a rule is named by its data row and line, found the slow way when the fast
parser refuses the file."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from components.errors import LogFormatError
from components.logs.labels import SegmentLabels
from components.logs.rules import NONFINITE, NUMBER, XYZ, check_columns, numeric_columns
from components.logs.spill import release, spill_threshold, spilled_array

BLOCK_BYTES = 1 << 22  # the parser's block of text (rows are decoded a block at a time)
HEAVY = ("gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z", "temperature")  # spilled columns
MIN_ROW_BYTES = 16  # no data row is shorter ("0,0,0,0,0,0,0,0\n"): a smaller file is not counted


def csv_row(i: int) -> str:
    return f"data row {i + 1} (line {i + 2})"


def not_utf8(path: Path, e: UnicodeDecodeError) -> str:
    """What a file that is not UTF-8 text is, and what to do."""
    head = path.read_bytes()[:2]
    what = " (it looks like UTF-16: save it as UTF-8)" if head in (b"\xff\xfe", b"\xfe\xff") else ""
    return (f"{path}: byte {e.object[e.start]:#04x} at offset {e.start} is not UTF-8 text{what}; expected a UTF-8 "
            "file (docs/measurement-log.md)")


def wanted_columns(header: list[str], meta: dict, lean: bool) -> list[str]:
    """The columns to read: all, or (``lean``) those the estimators use."""
    if not lean:
        return list(header)
    keep = {"time", "temperature", "segment", "mask"} | {f"{s}_{c}" for s in ("gyro", "acc") for c in XYZ} \
        | {f"gimbal_{a}" for a in meta["axis_names"]}
    return [h for h in header if h in keep]


def sensor_groups(meta: dict) -> dict[str, list[str]]:
    """The columns read into one (N, k) array each: gyro, accelerometer, gimbal angles."""
    return {"gyro": [f"gyro_{c}" for c in XYZ], "acc": [f"acc_{c}" for c in XYZ],
            "gimbal": [f"gimbal_{a}" for a in meta["axis_names"]]}


def float_values(col) -> np.ndarray:
    """A numeric Arrow column as float64 numpy values. A float64 column is not cast: Arrow's
    cast is its compute module, whose import alone is ~40 ms of every command's start."""
    import pyarrow as pa

    return (col if col.type == pa.float64() else col.cast(pa.float64())).to_numpy()


def labels(col) -> SegmentLabels:
    """The segment labels of a (chunked) dictionary or string column, as runs (an empty value
    reads as the empty label, which a log refuses)."""
    import pyarrow as pa

    parts = []
    for ch in (col.chunks if hasattr(col, "chunks") else [col]):
        if not pa.types.is_dictionary(ch.type):
            ch = ch.dictionary_encode()
        names = ch.dictionary.to_pylist() + [""]
        codes = ch.indices.fill_null(len(names) - 1) if ch.indices.null_count else ch.indices
        parts.append(SegmentLabels.from_codes(codes.to_numpy(), names))
    return SegmentLabels.concatenate(parts) if parts else SegmentLabels.of([])


def read_csv(path: Path, meta: dict, lean: bool = False) -> tuple[dict, dict]:
    """(column name -> values, group -> (N, k) array) of a CSV log. ``lean`` (the estimators'
    columns only) and more rows than the spill threshold: streamed, the sensor columns into
    memory-mapped arrays; otherwise read whole (the groups then empty)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    header = _read_header(path)
    check_columns(header, meta, str(path))
    numeric = numeric_columns(header, meta)
    types = {c: pa.float64() for c in numeric}
    if "segment" in header:
        types["segment"] = pa.dictionary(pa.int32(), pa.string())
    options = dict(read_options=pcsv.ReadOptions(block_size=BLOCK_BYTES),
                   parse_options=pcsv.ParseOptions(ignore_empty_lines=False),
                   convert_options=pcsv.ConvertOptions(column_types=types, null_values=[""],
                                                       strings_can_be_null=False, quoted_strings_can_be_null=False,
                                                       include_columns=wanted_columns(header, meta, lean)))
    rows_at_most = _rows_at_most(path) if lean else 0
    try:
        if rows_at_most > spill_threshold():
            return _streamed(path, meta, header, numeric, pcsv.open_csv(path, **options), rows_at_most)
        table = pcsv.read_csv(path, **options)
    except (pa.ArrowInvalid, pa.ArrowTypeError) as e:
        _diagnose_csv(path, header, numeric, e)
        raise  # not reached
    cols: dict[str, np.ndarray] = {}
    for name in table.column_names:
        col = table.column(name)
        if name in types and name != "segment":
            _no_empty_value(path, header, numeric, table, name, 0)
            cols[name] = col.to_numpy()
        elif name == "segment":
            cols[name] = labels(col)
        else:
            cols[name] = col.to_numpy(zero_copy_only=False)
    return cols, {}


def _streamed(path: Path, meta: dict, header: list[str], numeric: list[str], reader, rows_at_most: int):
    """read_csv's long-log path: a block of rows at a time; the gyro, accelerometer and
    temperature columns into spilled arrays of *rows_at_most* rows, cut to the rows there are."""
    import pyarrow as pa

    names = reader.schema.names
    groups = {g: c for g, c in sensor_groups(meta).items() if all(x in names for x in c)}
    place = {c: (g, j) for g, cs in groups.items() for j, c in enumerate(cs)}
    stacked = {g: spilled_array((rows_at_most, len(c))) if c and set(c) <= set(HEAVY) else np.empty((rows_at_most, len(c)))
               for g, c in groups.items()}
    spilled = {c: spilled_array((rows_at_most,)) for c in names if c in HEAVY and c not in place}
    parts: dict[str, list] = {c: [] for c in names if c not in place and c not in spilled}
    row = 0
    try:
        for batch in reader:
            n = batch.num_rows
            if row + n > rows_at_most:
                raise LogFormatError(f"{path}: more data rows than lines ({rows_at_most}); expected one row a line")
            for name in names:
                col = batch.column(names.index(name))
                if name in numeric:
                    _no_empty_value(path, header, numeric, batch, name, row)
                if name in place:
                    g, j = place[name]
                    stacked[g][row:row + n, j] = col.to_numpy()
                    release(stacked[g])
                elif name in spilled:
                    spilled[name][row:row + n] = col.to_numpy()
                    release(spilled[name])
                elif name == "segment":
                    parts[name].append(labels(col))
                else:
                    parts[name].append(col.to_numpy(zero_copy_only=False))
            row += n
    except (pa.ArrowInvalid, pa.ArrowTypeError) as e:
        _diagnose_csv(path, header, numeric, e)
        raise  # not reached
    stacked = {g: a[:row] for g, a in stacked.items()}
    cols = {c: stacked[g][:, j] for c, (g, j) in place.items()}
    cols.update({c: a[:row] for c, a in spilled.items()})
    cols.update({c: (SegmentLabels.concatenate(p) if c == "segment" else np.concatenate(p)) if p else np.zeros(0)
                 for c, p in parts.items()})
    return cols, stacked


def _rows_at_most(path: Path) -> int:
    """An upper bound on the data rows: the file's line breaks (a pass over the bytes, ~1 s a
    GB), or 0 for a file too small to pass the spill threshold whatever its rows."""
    size = path.stat().st_size
    if size < MIN_ROW_BYTES * max(spill_threshold(), 1):
        return 0 if spill_threshold() > 0 else max(size, 1)
    lf = cr = 0
    with open(path, "rb") as f:
        while block := f.read(1 << 24):
            lf += block.count(b"\n")
            cr += block.count(b"\r")
    return max(lf, cr) + 1  # (a file of old Mac line ends has no \n)


def _no_empty_value(path: Path, header: list[str], numeric: list[str], table, name: str, row0: int) -> None:
    """An empty cell of a numeric column is refused, a blank line named as one."""
    col = table.column(table.schema.names.index(name))
    if not col.null_count:
        return
    i = int(np.argmax(col.is_null().to_numpy(zero_copy_only=False)))
    present = [c for c in numeric if c in table.schema.names]
    if all(table.column(table.schema.names.index(c))[i].as_py() is None for c in present):
        raise LogFormatError(f"{path}: {csv_row(row0 + i)}: blank line; expected {len(header)} fields "
                             "(a log has no blank line, between samples or after the last)")
    raise LogFormatError(f"{path}: {csv_row(row0 + i)}, column {name!r}: empty value; expected a number")


def _read_header(path: Path) -> list[str]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            first = f.readline()
    except UnicodeDecodeError as e:
        raise LogFormatError(not_utf8(path, e)) from None
    if not first.strip():
        raise LogFormatError(f"{path}: line 1: empty; expected the header row (time, gimbal_<axis>, ...)")
    return next(csv.reader([first]))


def _diagnose_csv(path: Path, header: list[str], numeric: list[str], err: Exception) -> None:
    """The fast parser refused the file: find the first bad row the slow way, for the message."""
    idx = {c: header.index(c) for c in numeric}
    with open(path, newline="", encoding="utf-8-sig", errors="replace") as f:
        r = csv.reader(f)
        next(r)
        for k, fields in enumerate(r):
            line = r.line_num
            if len(fields) != len(header):
                raise LogFormatError(f"{path}: data row {k + 1} (line {line}): {len(fields)} field(s); expected "
                                     f"{len(header)} (the header's columns), comma-separated with '.' as the "
                                     "decimal point")
            for c, j in idx.items():
                s = fields[j]
                if NONFINITE.match(s):
                    raise LogFormatError(f"{path}: data row {k + 1} (line {line}), column {c!r}: value {s!r} is "
                                         "not finite; expected a finite number")
                if not NUMBER.match(s):
                    raise LogFormatError(f"{path}: data row {k + 1} (line {line}), column {c!r}: {s!r} is not a "
                                         "number; expected a decimal number with '.' as the decimal point")
    raise LogFormatError(f"{path}: cannot be read as CSV ({err})")
