"""A sensor's sample counter (``[imu.counter]``: a packet's sequence number, a data counter
register): each sample's place on the sensor's own clock, read instead of guessed from host
stamps. Stamps jittered by more than half an interval cannot tell a lost sample from a late
stamp; the counter can, and it names a packet logged twice, which stamps that repeat cannot."""
from __future__ import annotations

import numpy as np

from components.errors import MappingError
from components.logs.mapping import Mapping
from components.logs.sources import Columns
from components.logs.timebase import index_gaps, unrolled

KEY = "imu.counter.column"


def sample_index(m: Mapping, cols: Columns, notes: list[str]) -> np.ndarray | None:
    """(N,) int64: each sample's index on the sensor's clock from the first (the counter counted
    on through its rollovers, over its step), or None without a counter. One error at the first
    row where it is not a whole count, not a whole step on, or does not advance."""
    if m.counter is None:
        return None
    raw = cols.values(m.counter, KEY)
    frac = raw != np.round(raw)
    if frac.any():
        i = int(np.argmax(frac))
        raise MappingError(f"{cols.where}: {KEY}: row {cols.file_row(i)}: {float(raw[i])!r} is not a whole count")
    c, rolled = unrolled(raw, m.counter_rollover)
    steps = np.diff(c)
    off_step = steps % m.counter_step != 0
    if off_step.any():
        i = int(np.argmax(off_step)) + 1
        raise MappingError(f"{cols.where}: {KEY}: row {cols.file_row(i)}: the counter advances by {steps[i - 1]:g} from "
                           f"the row before; expected whole steps of imu.counter.step = {m.counter_step}")
    k = np.concatenate([[0], np.cumsum(steps // m.counter_step)]).astype(np.int64)
    still = np.diff(k) <= 0
    if still.any():
        i = int(np.argmax(still)) + 1
        same = raw[i] == raw[i - 1]
        raise MappingError(
            f"{cols.where}: {KEY}: row {cols.file_row(i)}: {float(raw[i]):g} after {float(raw[i - 1]):g}; expected a "
            "counter that advances" + (" (a packet logged twice?)" if same else
                                       (" (a counter that rolls over: give imu.counter.rollover, its period in counts, "
                                        "e.g. 65536)" if m.counter_rollover is None else "")))
    skipped = np.diff(k) - 1
    lost = int(skipped.sum())
    notes.append(f"sample counter {m.counter.column!r}: {len(k)} of the {int(k[-1]) + 1} samples it counted are in the file"
                 + (f" (rolled over {rolled} time(s))" if rolled else "")
                 + (f"; {lost} sample(s) lost in {int(np.count_nonzero(skipped))} gap(s), the most at once "
                    f"{int(skipped.max())}" if lost else "; none lost"))
    return k


def skips(index: np.ndarray | None) -> np.ndarray | None:
    """(N,) bool: the counter skipped samples before this one (None without a counter)."""
    return None if index is None else index_gaps(index)
