"""Per-sample residuals of a comparison written as CSV in the log's own output units, for users
who plot them with their own tools."""
from __future__ import annotations

import numpy as np


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
    seg = np.asarray(log.segment).astype(str) if log.segment is not None else np.full(log.n, "")
    with open(path, "w") as f:
        f.write("time,segment,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z\n")
        for k in range(log.n):
            # float(): a numpy scalar's repr is "np.float64(0.005)", which no CSV reader takes
            f.write(f"{float(log.time[k])!r},{seg[k]}," + ",".join(repr(float(x)) for x in r[k]) + "\n")
