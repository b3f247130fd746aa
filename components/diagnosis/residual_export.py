"""Residuals of a comparison written as CSV for users who plot them with their own tools.

Two files, because two different things are measured:

- per sample (``--residuals``), in the log's own output units, with a column
  ``encoder_limited``: 1 inside moves, where the gyro prediction is the motion rebuilt from
  encoder counts (differentiated quantised angles: on a correct model its 1-s sums there are
  several times the noise); only the rest-to-rest sum of a move is exact (docs/compare.md); and
  ``left_out``: 1 for a sample no statistic uses (the one after a gap, which spans it; masked or
  excluded samples).
- per block (``--block-residuals``): the normalised block residuals z the statistics use
  (N(0, 1) under a correct model, whatever the motion), with the misfit test of their
  segment × channel cell.
"""
from __future__ import annotations

import itertools

import numpy as np

from components.diagnosis.misfit import CHANNELS
from components.logs.spill import gathered


def write_residuals(path: str, log, comparison) -> None:
    """Residual (measured − model) per sample and channel of *log*, in its output kind: increments
    as increments, rates and specific force divided by the sample interval, counts in counts."""
    r = comparison.residual.copy()
    for s, (kind, w) in ((slice(0, 3), (log.gyro_output, log.gyro_count_rad)),
                         (slice(3, 6), (log.acc_output, log.acc_count_mps))):
        if kind in ("rate", "specific_force"):
            r[:, s] /= log.dt
        elif kind == "counts":
            r[:, s] /= w
    seg = iter(log.segment) if log.segment is not None else itertools.repeat("")
    limited = ~np.asarray(comparison.static, dtype=bool)
    left_out = (np.zeros(log.n, bool) if comparison.usable is None else ~np.asarray(comparison.usable, bool))
    with open(path, "w") as f:
        f.write("time,segment,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z,encoder_limited,left_out\n")
        for k in range(log.n):
            f.write(f"{float(log.time[k])!r},{next(seg)}," + ",".join(repr(float(x)) for x in r[k])
                    + f",{int(limited[k])},{int(left_out[k])}\n")


def write_block_residuals(path: str, comparison) -> None:
    """One row per block and channel: its time span, segment, whether it is a move, the
    normalised residual z, and whether its segment × channel cell misfits beyond noise."""
    rows = comparison.rows
    # the blocks' first and last times, a piece of a spilled log's column at a time
    # (components.logs.spill.gathered; through the mapping each read brings the pages around it)
    n = len(comparison.time)
    t_start = np.asarray(gathered(comparison.time, rows["start"]), dtype=float)
    t_stop = np.asarray(gathered(comparison.time, np.minimum(rows["stop"], n) - 1), dtype=float)
    seg = (comparison.segment[rows["start"]].astype(str) if comparison.segment is not None
           else np.full(len(rows["z"]), ""))
    mis = comparison.misfits
    flagged = {(c.name, c.channel) for c in mis.flagged("segment")} if mis is not None else set()
    order = np.lexsort((rows["channel"], rows["start"]))
    with open(path, "w") as f:
        f.write("t_start,t_stop,segment,channel,moving,z,segment_channel_flagged\n")
        for i in order:
            ch = CHANNELS[int(rows["channel"][i])]
            f.write(f"{float(t_start[i])!r},{float(t_stop[i])!r},{seg[i]},{ch},{int(bool(rows['moving'][i]))},"
                    f"{float(rows['z'][i])!r},{int((seg[i], ch) in flagged)}\n")
