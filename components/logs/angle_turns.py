"""Table angles read to one turn (0 to 360°, or ±180°), made continuous.

Many turntable controllers report each axis's angle modulo a turn. calbench takes the change of
an angle between two readings as the table's travel over that interval, so a reading stepping
from 359.9° to 0.1° would be a turn backwards within one sample: the kinematics' rates, the gyro
misfit and every estimate after them wrong by a turn per sample (scale factors of −136 % and
misalignments of 0.3 on the conformance log read so, each flagged implausible but none naming
the wrap). No table travels half a turn between two readings of a log fine enough to calibrate
from (half a turn a sample is 18,000 °/s at 100 Hz, and a spline through such readings would be
meaningless anyway), so where an axis's readings all lie within one turn and step by more than
half a turn somewhere, each such step is taken as the reading's wrap: the whole turns of it are
taken off every reading after it. Readings spanning more than a turn are a continuous angle
already, and a step of half a turn among them is something else (a corrupt cell, angles in
degrees declared as radians), left for the checks that name it.
"""
from __future__ import annotations

import math

import numpy as np

from components.logs.spill import pieces

TURN = 2 * math.pi


# readings within one turn: their span at most a turn, to the rounding of 360° taken to radians
ONE_TURN_SPAN = TURN * (1 + 1e-9)


def wraps(angle: np.ndarray) -> int:
    """How many times the readings *angle* [rad] (N,) wrap: the steps of more than half a turn
    between consecutive readings, when all of them lie within one turn; else 0 (a piece of a
    spilled log at a time)."""
    low, high, steps, last = math.inf, -math.inf, 0, None
    for s in pieces(len(angle), angle):
        x = angle[s]
        if not len(x):
            continue
        low, high = min(low, float(x.min())), max(high, float(x.max()))
        steps += int(np.count_nonzero(np.abs(np.diff(x, prepend=x[0] if last is None else last)) > math.pi))
        last = float(x[-1])
    return steps if high - low <= ONE_TURN_SPAN else 0


def unwrap_turns(angle: np.ndarray) -> int:
    """Make the finite angle readings *angle* [rad] (N,) continuous, in place (a piece of a
    spilled log at a time), taking every step of more than half a turn for a wrap (the caller
    asks :func:`wraps` first); the number of such steps. The first reading keeps its value;
    readings without such a step are left bit for bit as they were."""
    turns = 0.0  # whole turns taken off the readings so far
    last = None  # the piece before's last reading, as read
    mended = 0
    for s in pieces(len(angle), angle):
        x = angle[s]
        if not len(x):
            continue
        step = np.diff(x, prepend=x[0] if last is None else last)
        last = float(x[-1])
        wrap = np.abs(step) > math.pi
        if wrap.any():
            whole = np.where(wrap, np.round(step / TURN), 0.0)
            x -= TURN * (turns + np.cumsum(whole))
            turns += float(whole.sum())
            mended += int(np.count_nonzero(wrap))
        elif turns:
            x -= TURN * turns
    return mended


def made_continuous(angle: np.ndarray) -> tuple[np.ndarray, int]:
    """(the readings *angle* made continuous where they wrap — in place, or in a copy of a
    read-only array —, the wraps mended)."""
    n = wraps(angle)
    if n:
        if not angle.flags.writeable:
            angle = angle.copy()
        unwrap_turns(angle)
    return angle, n


def said(mended: dict[str, int]) -> str | None:
    """One line naming the axes whose readings were made continuous, or None."""
    axes = {k: n for k, n in mended.items() if n}
    if not axes:
        return None
    each = ", ".join(f"gimbal_{k} {n} time{'s' if n > 1 else ''}" for k, n in axes.items())
    return (f"table angles read to one turn, made continuous: a step of more than half a turn between two "
            f"readings taken as the reading's wrap ({each})")
