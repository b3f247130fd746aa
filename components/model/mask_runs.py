"""Runs of a per-sample mask (a log's rests and moves, its usable stretches), found a piece of
the mask at a time. The whole mask at once made two to four temporaries of one to eight bytes a
sample (padded copies, differences, edge masks: 30-240 MB each on an 8-hour 1 kHz log) at every
call; a piece at a time they are a piece's, and a mask kept on disk (components.logs.spill) is
read as it is stored."""
from __future__ import annotations

import numpy as np

PIECE = 1 << 20  # samples of the mask looked at together


def runs(mask: np.ndarray, value: bool = True, piece: int = PIECE) -> tuple[np.ndarray, np.ndarray]:
    """(starts, stops) int64: the [start, stop) ranges of consecutive samples where *mask* is
    *value*, in order."""
    n = len(mask)
    starts, stops = [], []
    before = False  # whether the sample before the piece is in a run
    for a in range(0, n, piece):
        m = np.asarray(mask[a:a + piece], bool)
        inside = m if value else ~m
        edge = np.empty(len(inside) + 1, bool)
        edge[0] = before
        edge[1:] = inside
        at = np.flatnonzero(edge[1:] != edge[:-1])  # where a sample differs from the one before it
        starts.append(at[inside[at]] + a)
        stops.append(at[~inside[at]] + a)
        before = bool(inside[-1])
    if before:
        stops.append(np.array([n]))
    empty = np.zeros(0, np.int64)
    return np.concatenate([empty, *starts], dtype=np.int64), np.concatenate([empty, *stops], dtype=np.int64)
