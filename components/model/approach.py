"""The side each table stage came from: the sign of its last move, which a reversal error
(effects: table.reversal; geometry.Stage.reversal) turns into an offset of the plate from the
reading at every rest. Taken from the logged angles alone, so logs from other software have it."""
from __future__ import annotations

import numpy as np

from components.model.mask_runs import runs


def moving_runs(static: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of consecutive non-static intervals."""
    return list(zip(*runs(static, value=False)))


def run_sides(measured: np.ndarray, static: np.ndarray, side0: np.ndarray, band: np.ndarray, after_run=None):
    """The side each stage is on after each moving run: (runs [(a, b)], sides (R, n_axes) int8,
    the sample where each stage's side changes in each run (R, n_axes), b where it does not).

    A stage's side after a run is the direction it came from onto its final reading, seen from
    the last reading of the run more than *band* (per stage [rad]) away from it: an overshoot
    taken back counts, a reading that dithers a count or two at a rest (a hunting servo, the
    plate held by friction or within a backlash) does not, and a run that moves the stage less
    than *band* leaves its side. The side changes where the stage's reading first changes in the
    run (the play is taken up at the start of a move). ``after_run()``, if given, is called
    after each run (a caller's log on disk gives back the pages the run read)."""
    runs = moving_runs(static)
    n_ax = measured.shape[1]
    out = np.empty((len(runs), n_ax), np.int8)
    at = np.empty((len(runs), n_ax), np.int64)
    side = np.array(side0, np.int8, copy=True)
    for r, (a, b) in enumerate(runs):
        lo = max(a - 1, 0)
        for k in range(n_ax):
            seg = measured[lo:b, k]
            far = np.flatnonzero(np.abs(seg - seg[-1]) > band[k])
            at[r, k] = b
            if len(far):
                side[k] = np.sign(seg[-1] - seg[far[-1]])
                changes = np.flatnonzero(seg[1:] != seg[:-1])
                at[r, k] = lo + 1 + changes[0]
        out[r] = side
        if after_run is not None:
            after_run()
    return runs, out, at


def approach_sides(measured: np.ndarray, static: np.ndarray, side0: np.ndarray, band: np.ndarray) -> np.ndarray:
    """(N, n_axes) int8: per sample, the side each stage is on (:func:`run_sides`), *side0* before
    the first run."""
    n, n_ax = measured.shape
    out = np.empty((n, n_ax), np.int8)
    runs, after, at = run_sides(measured, static, side0, band)
    side = np.array(side0, np.int8, copy=True)
    pos = 0
    for r, (a, b) in enumerate(runs):
        out[pos:a] = side
        for k in range(n_ax):
            out[a:at[r, k], k] = side[k]
            out[at[r, k]:b, k] = after[r, k]
        side = after[r]
        pos = b
    out[pos:] = side
    return out
