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

METADATA_KEY = b"calbench.provenance"


@dataclass
class Recording:
    signals: list[str]
    time: np.ndarray
    data: np.ndarray  # shape (rows, signals)
    provenance: dict = field(default_factory=dict)
    rows: int = 0  # rows filled (less than len(time) when the run stopped early)
    complete: bool = True
    fault: str | None = None

    @classmethod
    def allocate(cls, signals: list[str], times: np.ndarray, provenance: dict) -> "Recording":
        data = np.full((len(times), len(signals)), np.nan)
        return cls(list(signals), times, data, provenance)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[: self.rows, self.signals.index(name)]
        except ValueError:
            raise KeyError(f"signal {name!r} was not recorded; recorded: {self.signals}") from None

    @property
    def t(self) -> np.ndarray:
        return self.time[: self.rows]

    def save(self, path: str | Path) -> Path:
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = Path(path)
        cols = {"time": self.t}
        for j, s in enumerate(self.signals):
            cols[s] = self.data[: self.rows, j]
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
        data = np.column_stack([table.column(n).to_numpy() for n in names]) if names else \
            np.zeros((table.num_rows, 0))
        complete, fault = meta.pop("complete", True), meta.pop("fault", None)
        return cls(names, table.column("time").to_numpy(), data, meta, table.num_rows, complete, fault)
