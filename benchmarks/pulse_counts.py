"""A pulse-output logger for the benchmarks: a sensor's increments in, the whole counts of its
pulse output out, as a laser-gyro or pulse-output IMU's logger writes them.

The remainder below one count is carried on (the counts are those of the running sum), so a log
fed a piece at a time gives the counts of the whole log's sums."""
from __future__ import annotations

import numpy as np


class PulseLogger:
    def __init__(self, weight: float, start: np.ndarray):
        """*weight*: one count [rad or m/s]; *start*: the running sum before the first sample, per
        axis, in [0, weight) (where the logger's remainder happens to stand)."""
        self.weight = float(weight)
        self.total = np.array(start, float)
        self.whole = np.floor(self.total / self.weight)

    def counts(self, increments: np.ndarray) -> np.ndarray:
        """int64 counts of *increments* ((n,) or (n, axes), SI), the remainder carried on."""
        sums = self.total + np.cumsum(increments, axis=0)
        whole = np.floor(sums / self.weight)
        out = np.diff(whole, axis=0, prepend=self.whole[None] if whole.ndim > 1 else self.whole)
        self.total, self.whole = sums[-1], whole[-1]
        return out.astype(np.int64)
