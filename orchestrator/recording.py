"""Recorded signals of a run: preallocated arrays plus the run's provenance, saved as Parquet.

Parquet (via pyarrow) rather than HDF5: it is columnar like the access pattern (one signal over
the whole run), compresses float columns well, carries key/value metadata for the provenance,
is what the ``calbench-log/1`` spec already allows for samples, and reads in pandas, polars,
DuckDB and MATLAB without a C library of our own to install.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from orchestrator.fmi_types import TYPES, arrow_type, exact_in_float64

METADATA_KEY = b"calbench.provenance"


@dataclass
class Recording:
    """Signals over time. Every signal whose values a float64 holds exactly (floats, Booleans,
    integers up to 32 bits) is a column of ``data``; the others (64-bit integers, strings,
    binaries) are lists in ``objects`` by column index (their ``data`` column is NaN). ``types``
    holds each signal's :class:`~orchestrator.fmi_types.TypeInfo` (None: Float64): the type it
    is returned and saved with."""

    signals: list[str]
    time: np.ndarray
    data: np.ndarray  # shape (rows, signals)
    provenance: dict = field(default_factory=dict)
    rows: int = 0  # rows filled (less than len(time) when the run stopped early)
    complete: bool = True
    fault: str | None = None
    types: list = field(default_factory=list)
    objects: dict = field(default_factory=dict)

    @classmethod
    def allocate(cls, signals: list[str], times: np.ndarray, provenance: dict,
                 types: list | None = None) -> "Recording":
        data = np.full((len(times), len(signals)), np.nan)
        types = list(types) if types is not None else [None] * len(signals)
        objects = {j: [None] * len(times) for j, t in enumerate(types)
                   if t is not None and not exact_in_float64(t)}
        return cls(list(signals), times, data, provenance, types=types, objects=objects)

    def _type(self, j: int):
        return self.types[j] if j < len(self.types) else None

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            j = self.signals.index(name)
        except ValueError:
            raise KeyError(f"signal {name!r} was not recorded; recorded: {self.signals}") from None
        t = self._type(j)
        if j in self.objects:
            out = np.empty(self.rows, dtype=object)
            out[:] = self.objects[j][: self.rows]
            return out
        col = self.data[: self.rows, j]
        if t is None or t.family == "float":
            return col
        return col.astype(arrow_type(t).to_pandas_dtype())

    def column(self, j: int):
        """Signal *j* as an arrow array of its own type."""
        import pyarrow as pa

        t = self._type(j)
        if t is None:
            return pa.array(self.data[: self.rows, j])
        if j in self.objects:
            return pa.array(self.objects[j][: self.rows], type=arrow_type(t))
        return pa.array(self[self.signals[j]], type=arrow_type(t))

    @property
    def t(self) -> np.ndarray:
        return self.time[: self.rows]

    def save(self, path: str | Path) -> Path:
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = Path(path)
        cols = {"time": self.t}
        for j, s in enumerate(self.signals):
            cols[s] = self.column(j)
        table = pa.table(cols)
        meta = {"complete": self.complete, "fault": self.fault, **self.provenance}
        table = table.replace_schema_metadata({METADATA_KEY: json.dumps(meta, default=str).encode()})
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(path.suffix + ".tmp")
        pq.write_table(table, tmp)
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Recording":
        import pyarrow.parquet as pq

        table = pq.read_table(path)
        meta = json.loads((table.schema.metadata or {}).get(METADATA_KEY, b"{}"))
        names = [n for n in table.column_names if n != "time"]
        types, objects = [], {}
        data = np.full((table.num_rows, len(names)), np.nan)
        for j, n in enumerate(names):
            t = type_of_arrow(table.schema.field(n).type)
            types.append(t)
            col = table.column(n)
            if t is not None and not exact_in_float64(t):
                objects[j] = col.to_pylist()
            else:
                data[:, j] = col.to_numpy(zero_copy_only=False).astype(float)
        complete, fault = meta.pop("complete", True), meta.pop("fault", None)
        return cls(names, table.column("time").to_numpy(), data, meta, table.num_rows, complete, fault,
                   types, objects)


def type_of_arrow(at):
    """The TypeInfo a Parquet column's arrow type was saved from (None for float64)."""
    import pyarrow as pa

    if pa.types.is_float64(at):
        return None
    for t in TYPES.values():
        if arrow_type(t) == at:
            return t
    return None
