"""Lost packets a logger writes as rows (``lost_rows = true`` in a mapping's ``[imu]`` or
``[table]``): a row with an empty or NaN cell in a number column the import reads, or a blank
line, is a packet lost on its way to the logger. Its row is left out of every column of the
file; its neighbours' stamps then lie a gap apart, and a gap is what the import already knows
(the sample after it left out, a table's angles interpolated across it)."""
from __future__ import annotations

import numpy as np

from components.errors import MappingError
from components.logs.labels import SegmentLabels
from components.logs.mapping import Channel
from components.logs.sources import Columns
from components.model.mask_runs import runs

SHOWN_ROWS = 3


def _missing(a) -> np.ndarray:
    """Per row: the cell is empty (or NaN, NaT)."""
    if isinstance(a, SegmentLabels) or (isinstance(a, np.ndarray) and a.dtype.kind in "OUS"):
        return np.array([x is None or (isinstance(x, float) and x != x) or str(x).strip() == "" for x in a], bool)
    a = np.asarray(a)
    if a.dtype.kind == "M":
        return np.isnat(a)
    return np.isnan(a) if a.dtype.kind == "f" else np.zeros(len(a), bool)


def leave_out_lost_rows(cols: Columns, channels: list[tuple[Channel, str]], notes: list[str]) -> np.ndarray | None:
    """With the source's ``lost_rows``: the rows where any of *channels* ((channel, its mapping
    key)) is empty or NaN, left out of *cols* from now on and said in *notes*; the bool per file
    row, or None without the key."""
    if not cols.source.lost_rows:
        return None
    lost, first = None, {}
    for ch, what in channels:
        miss = _missing(cols.raw(ch, what, empty=True))
        if miss.any():
            first[what] = int(np.argmax(miss))
        lost = miss if lost is None else lost | miss
    n = 0 if lost is None else int(lost.sum())
    if not n:
        notes.append(f"{cols.where}: {cols.source.key}.lost_rows: no row with an empty or NaN cell")
        return lost
    if n == len(lost):
        raise MappingError(f"{cols.where}: {cols.source.key}.lost_rows: every row has an empty or NaN cell "
                           f"(first in {', '.join(sorted(first, key=first.get))}); expected samples")
    rows = np.flatnonzero(lost)
    shown = ", ".join(str(r + 1) for r in rows[:SHOWN_ROWS]) + (", ..." if n > SHOWN_ROWS else "")
    starts, stops = runs(lost)
    notes.append(f"{cols.where}: {n} row(s) with an empty or NaN cell ({cols.source.key}.lost_rows; rows {shown}; "
                 f"{len(starts)} run(s), the longest {int(np.max(stops - starts))}) taken for lost packets and left "
                 "out: a gap each")
    cols.leave_out(lost)
    return lost
