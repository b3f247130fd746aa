"""The files ``calbench import`` reads: CSV/TSV (any delimiter, a decimal comma, header lines to
skip), Parquet, MATLAB .mat (scipy.io) and HDF5 (h5py, the optional extra ``calbench[hdf5]``),
each as named numeric columns; a column is referred to by name (a .mat variable or an HDF5
dataset path, ``name:k`` for column k of a 2-D array) or, in a file without a header, by its
0-based index."""
from __future__ import annotations

import re

import numpy as np

from components.errors import MappingError
from components.logs.labels import SegmentLabels
from components.logs.mapping import Channel, Source


class Columns:
    """The columns of one source file, fetched by :class:`Channel`."""

    def __init__(self, source: Source):
        self.source = source
        self.where = str(source.path)
        if not source.path.exists():
            raise MappingError(f"{self.where}: the input file does not exist")
        reader = {"csv": _csv, "tsv": _csv, "parquet": _parquet, "mat": _mat, "hdf5": _hdf5}[source.format]
        self.data: dict = reader(source)
        # the file's rows read (components.logs.lost_rows leaves a lost packet's out); None: all
        self.kept: np.ndarray | None = None

    def leave_out(self, rows: np.ndarray) -> None:
        """Every column from now on without the rows where *rows* (a bool per row of the file) is
        True; messages still name the file's own rows."""
        self.kept = ~np.asarray(rows, bool)

    def file_row(self, i: int) -> int:
        """The file's row number (1-based) of row *i* of the columns as they are given."""
        return int(np.flatnonzero(self.kept)[i]) + 1 if self.kept is not None else int(i) + 1

    def _lost_hint(self) -> str:
        return ("" if self.source.lost_rows else
                f" (a logger that writes a lost packet as a row with empty or NaN cells: give "
                f"{self.source.key}.lost_rows = true)")

    def names(self) -> list[str]:
        return [str(k) for k in self.data]

    def raw(self, ch: Channel, what: str, empty: bool = False) -> np.ndarray:
        """The column of *ch* as read (before scale and sign); *empty*: its empty cells as NaN,
        not an error."""
        col = ch.column
        key = col
        k = None
        if isinstance(col, str) and col not in self.data and ":" in col:
            key, _, idx = col.rpartition(":")
            try:
                k = int(idx)
            except ValueError:
                key = col
        if isinstance(col, int):
            keys = list(self.data)
            if col >= len(keys):
                raise MappingError(f"{self.where}: {what}: column index {col}, but the file has {len(keys)} columns")
            key = keys[col]
        if key not in self.data:
            shown = ", ".join(self.names()[:30])
            raise MappingError(f"{self.where}: {what}: no column {col!r}; the file has: {shown}")
        a = self.data[key]
        if callable(a):
            # HDF5 datasets and Parquet columns are read when used, and not kept: the caller
            # converts them, and a long log's raw columns beside their conversions were twice it
            # (a lost packet's empty cells read as NaN, its row left out below)
            try:
                a = a(empty or self.kept is not None)
            except EmptyCell as e:
                raise MappingError(f"{e}{'' if empty else self._lost_hint()}") from None
        if isinstance(a, SegmentLabels) and k is None:
            # text, as runs (one label a sample as an object array: 8 bytes a sample)
            return a if self.kept is None else self._kept_rows(a, what, str(key))
        a = np.asarray(a)
        if k is not None:
            if a.ndim != 2 or not 0 <= k < a.shape[1]:
                raise MappingError(f"{self.where}: {what}: {col!r} asks for column {k} of {key!r}, which has shape "
                                   f"{a.shape}")
            a = a[:, k]
        elif a.ndim == 2 and 1 in a.shape:
            a = a.ravel()
        if a.ndim != 1:
            raise MappingError(f"{self.where}: {what}: {key!r} has shape {a.shape}; expected one column (write "
                               f"'{key}:k' for column k)")
        return a if self.kept is None else self._kept_rows(a, what, str(key))

    def _kept_rows(self, a, what: str, key: str):
        if len(a) != len(self.kept):
            raise MappingError(f"{self.where}: {what}: {key!r} has {len(a)} rows; expected {len(self.kept)} as the "
                               "file's other columns")
        return a[self.kept]

    def values(self, ch: Channel, what: str, empty: bool = False) -> np.ndarray:
        """The column as float64, (raw − offset) × scale × sign; a non-number or non-finite value is
        an error naming its row. *empty*: the empty cells (and NaN) are NaN, the caller fills them."""
        return self._numbers(self.raw(ch, what, empty), ch, what, empty)

    def times(self, ch: Channel, what: str) -> tuple[np.ndarray, str | None]:
        """A time column: (its clock readings in seconds, what they were: :func:`clock_seconds`),
        or (its numbers as :meth:`values` gives them, None)."""
        a = self.raw(ch, what)
        read = clock_seconds(a)
        if read is None:
            return self._numbers(a, ch, what), None
        kind, seconds = read
        unread = np.isnan(seconds)
        if unread.any():
            i = int(np.argmax(unread))
            raise MappingError(f"{self.where}: {what}: row {self.file_row(i)}: {a[i]!r} is not a reading of the clock "
                               f"like row {self.file_row(0)}'s {a[0]!r} ({kind})")
        return seconds, kind

    def _numbers(self, a, ch: Channel, what: str, empty: bool = False) -> np.ndarray:
        """The raw column *a* as :meth:`values` gives it."""
        if a.dtype.kind not in "biuf":
            try:
                a = a.astype(float)
            except (TypeError, ValueError):
                bad = next(i for i, x in enumerate(a) if not _is_number(x))
                raise MappingError(f"{self.where}: {what}: row {self.file_row(bad)}: {a[bad]!r} is not a number") from None
        a = a.astype(float)
        bad = np.isinf(a) if empty else ~np.isfinite(a)
        if bad.any():
            i = int(np.argmax(bad))
            if self.kept is not None and np.isnan(a[i]):  # (read with the lost rows' empty cells as NaN)
                raise MappingError(f"{self.where}: {what}: row {self.file_row(i)}: empty value or NaN; expected a number")
            raise MappingError(f"{self.where}: {what}: row {self.file_row(i)}: {float(a[i])!r} is not finite"
                               + (self._lost_hint() if np.isnan(a[i]) else ""))
        return (a - ch.offset) * ch.scale * ch.sign

    def text(self, ch: Channel, what: str) -> np.ndarray:
        """A column of labels as text."""
        a = self.raw(ch, what)
        if isinstance(a, SegmentLabels):
            return a
        if a.dtype.kind in "SO":
            return np.array([x.decode() if isinstance(x, bytes) else str(x) for x in a], dtype=object)
        return a.astype(str).astype(object)


TIME_OF_DAY = re.compile(r"\s*(\d{1,2}):(\d{2}):(\d{2}(?:\.\d*)?)\s*$")


def clock_seconds(a) -> tuple[str, np.ndarray] | None:
    """A column of clock readings in seconds, and what they were: dates and times (a timestamp
    column: ISO 8601 text, which the CSV reader takes as such, or Parquet's own) as seconds since
    1970-01-01 (UTC where the file gives a zone), or the time of day ("08:00:00.005") as seconds
    since midnight; None for any other column."""
    if isinstance(a, np.ndarray) and a.dtype.kind == "M":
        ns = a.astype("datetime64[ns]")
        out = ns.view(np.int64) / 1e9
        out[np.isnat(ns)] = np.nan
        return "dates", out
    if not (isinstance(a, SegmentLabels) or (isinstance(a, np.ndarray) and a.dtype.kind in "OUS")) or not len(a):
        return None
    first = a[0]
    if not isinstance(first, str) or not TIME_OF_DAY.match(first):
        return None
    out = np.empty(len(a))
    for i, x in enumerate(a):
        m = TIME_OF_DAY.match(x) if isinstance(x, str) else None
        out[i] = int(m[1]) * 3600 + int(m[2]) * 60 + float(m[3]) if m else np.nan
    return "time of day", out


def _is_number(x) -> bool:
    try:
        float(x)
        return True
    except (TypeError, ValueError):
        return False


def _csv(src: Source) -> dict:
    """The file parsed once (Arrow's reader); each column converted when first used and then
    dropped from the parsed table (every column was copied to numpy at once, beside the table:
    twice the file in memory); a column used again is parsed again, alone. Text as labels sharing
    one string per distinct value."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    def parse(columns=None):
        try:
            return pcsv.read_csv(
                src.path,
                read_options=pcsv.ReadOptions(skip_rows=src.skip_rows, autogenerate_column_names=not src.header,
                                              encoding="utf8"),
                # blank lines kept as rows, so that one is said and the rows counted are the file's
                parse_options=pcsv.ParseOptions(delimiter=src.delimiter, ignore_empty_lines=False),
                # only an empty cell is empty ('nan', 'NA' are what they say: a NaN, a text)
                convert_options=pcsv.ConvertOptions(decimal_point=src.decimal, strings_can_be_null=False,
                                                    null_values=[""], include_columns=columns))
        except (pa.ArrowInvalid, pa.ArrowTypeError, UnicodeDecodeError) as e:
            raise MappingError(f"{src.path}: cannot be read as {src.format.upper()} with delimiter {src.delimiter!r}, "
                               f"{src.skip_rows} line(s) skipped, decimal {src.decimal!r} ({str(e).splitlines()[0]})") from None

    table = parse()
    rows = _without_trailing_blank_lines(table, src)
    held = {"table": table.slice(0, rows)}

    def taker(name: str):
        def take(empty: bool = False) -> np.ndarray:
            table = held["table"]
            if name not in table.column_names:
                return _array(parse([name]).column(0).slice(0, rows), f"{src.path}: column {name!r}", empty)
            col = table.column(name)
            held["table"] = table.drop_columns([name])
            return _array(col, f"{src.path}: column {name!r}", empty)
        return take

    return {name.strip(): taker(name) for name in held["table"].column_names}


def _without_trailing_blank_lines(table, src: Source) -> int:
    """The data rows of a parsed CSV *table* without the blank lines at its end (an editor's extra
    newline); a blank line between samples is a MappingError naming its row and line, unless
    the mapping says a logger writes a lost packet so (``lost_rows``: its empty cells make it one)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    blank = None
    for col in table.columns:
        empty = pc.is_null(col)
        if pa.types.is_string(col.type) or pa.types.is_large_string(col.type):
            empty = pc.or_(empty, pc.equal(col, ""))
        blank = empty if blank is None else pc.and_(blank, empty)
    if blank is None or not pc.any(blank).as_py():
        return table.num_rows
    blank = blank.to_numpy(zero_copy_only=False)
    rows = len(blank) - int(np.argmin(blank[::-1])) if not blank.all() else 0
    if blank[:rows].any() and not src.lost_rows:
        i = int(np.argmax(blank[:rows]))
        raise MappingError(f"{src.path}: data row {i + 1} (line {i + 1 + src.skip_rows + bool(src.header)}): blank "
                           "line; expected a sample on every line (a logger that writes a lost packet as a blank line: "
                           f"give {src.key}.lost_rows = true)")
    return rows


def _array(col, what: str, empty: bool = False) -> np.ndarray:
    """An Arrow column as numpy; text as labels sharing one string per distinct value
    (components.logs.csv_log.labels; one per row was ~50 bytes a sample). An empty value of a
    column of numbers is a MappingError naming *what* (file and column) and the row; with
    *empty*, a NaN."""
    import pyarrow as pa

    from components.logs.csv_log import labels

    if pa.types.is_string(col.type) or pa.types.is_large_string(col.type) or pa.types.is_dictionary(col.type):
        return labels(col)  # (which encodes text as a dictionary itself)
    if col.null_count and empty:
        a = col.to_numpy(zero_copy_only=False)  # (a timestamp's nulls are NaT)
        return a if a.dtype.kind == "M" else np.asarray(a, float)  # (a number's are NaN)
    if col.null_count and not pa.types.is_null(col.type):
        i = int(np.argmax(col.is_null().to_numpy(zero_copy_only=False)))
        raise EmptyCell(f"{what}: row {i + 1}: empty value; expected a number")
    return col.to_numpy(zero_copy_only=False)


class EmptyCell(MappingError):
    """A number column's empty cell (:meth:`Columns.raw` says what to give where it is a lost
    packet)."""


def _parquet(src: Source) -> dict:
    """Each column read when first used (an hour of 1 kHz data has columns a mapping never names,
    and the whole table beside its numpy copies was twice the file in memory); text as labels
    (:func:`_array`)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        pf = pq.ParquetFile(src.path, page_checksum_verification=True)
        names = pf.schema_arrow.names
    except (pa.ArrowInvalid, OSError) as e:
        raise MappingError(f"{src.path}: not a readable Parquet file ({e})") from None

    def reader(name: str):
        def read(empty: bool = False) -> np.ndarray:
            try:
                col = pf.read(columns=[name]).column(0)
            except (pa.ArrowInvalid, OSError) as e:
                raise MappingError(f"{src.path}: column {name!r} cannot be read ({e})") from None
            return _array(col, f"{src.path}: column {name!r}", empty)
        return read

    return {name: reader(name) for name in names}


def _mat(src: Source) -> dict:
    import scipy.io

    try:
        d = scipy.io.loadmat(src.path, squeeze_me=False)
    except (ValueError, TypeError, NotImplementedError, OSError) as e:
        hint = " (a MATLAB v7.3 file is HDF5: give format = 'hdf5')" if "v7.3" in str(e) or "HDF" in str(e) else ""
        raise MappingError(f"{src.path}: not a readable MATLAB file ({e}){hint}") from None
    return {k: v for k, v in d.items() if not k.startswith("__")}


def _hdf5(src: Source) -> dict:
    try:
        import h5py
    except ImportError:
        raise MappingError(f"{src.path}: reading HDF5 needs h5py: pip install 'calbench[hdf5]'") from None
    out: dict = {}
    try:
        f = h5py.File(src.path, "r")
    except OSError as e:
        raise MappingError(f"{src.path}: not a readable HDF5 file ({e})") from None

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            out[name] = (lambda empty=False, o=obj: o[()])  # (NaN is a dataset's own empty value)
    f.visititems(visit)
    return out
