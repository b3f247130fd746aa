"""Where the table rests: the true angle at rest lies within the encoder's count of the logged
one, and that uncertainty bounds a rest-to-rest gyro block (the integral of the gyro over a move
equals the rotation between the two rest angles)."""
from __future__ import annotations

import numpy as np

from components.errors import EstimationError
from components.estimation.blocks import Blocks
from components.logs.spill import gathered, pieces
from components.model.geometry import TableGeometry


def rest_directions(angles: np.ndarray, geo: TableGeometry, at: np.ndarray) -> np.ndarray:
    """Plate-frame rotation direction of each stage (B, n_axes, 3) at the logged angles of the
    samples *at*: how a small error of that stage's rest angle shows in the gyro triad."""
    th = np.atleast_2d(gathered(angles, at))  # a spilled log's: not its every page at once
    _, w0, _, _ = geo.kinematics(th)
    out = np.empty((len(th), th.shape[1], 3))
    for k in range(th.shape[1]):
        e = np.zeros_like(th)
        e[:, k] = 1.0
        out[:, k, :] = geo.kinematics(th, e)[1] - w0
    return out


def rest_variance(data, geo: TableGeometry, gb: Blocks, rest: np.ndarray) -> np.ndarray:
    """(B, 3) variance a moving gyro block gets from the rest angles at its two ends: a rest
    angle error δ_k of stage k shifts the integral of the gyro by b_k δ_k (b_k its rotation
    direction in plate axes), independently at the start and at the end of the move."""
    var = np.zeros((len(gb), 3))
    mv = np.nonzero(gb.moving)[0]
    if len(mv) == 0 or not np.any(rest):
        return var
    b = rest_directions(data.angles, geo, np.maximum(gb.stop[mv] - 1, 0))
    var[mv] = 2 * np.einsum("bki,k->bi", b**2, np.asarray(rest, float) ** 2)
    return var


# a smallest logged angle step beyond this is not an encoder count (a log of nominal attitudes on
# a 90° grid would otherwise allow tens of degrees of rest-angle error and hide any misfit)
GUESSED_COUNT_LIMIT = 1e-3  # rad (0.057°)


def rest_sigma(angles: np.ndarray, given=None, resolution=None) -> np.ndarray:
    """Per-axis σ of the true angle at rest: *given*; else one count uniform (q/√12) with q the
    log's stated encoder *resolution* (per axis [rad], or "exact": 0); else q the count the logged
    angles show (:func:`encoder_quantum`), refused where that cannot be an encoder count."""
    n_ax = angles.shape[1]
    if given is not None:
        return np.broadcast_to(np.asarray(given, float), (n_ax,)).copy()
    if isinstance(resolution, str) and resolution == "exact":
        return np.zeros(n_ax)
    if resolution is not None:
        return np.broadcast_to(np.asarray(resolution, float), (n_ax,)) / np.sqrt(12.0)
    q = encoder_quantum(angles)
    if np.any(q > GUESSED_COUNT_LIMIT):
        k = int(np.argmax(q))
        raise EstimationError(
            f"the table's encoder resolution is not stated and the steps between logged angles of axis "
            f"{k + 1} are whole numbers of {np.degrees(q[k]):.4g}°, which is not an encoder count: state it as "
            "'table.encoder_resolution_rad' in the log's metadata (a number [rad], one per axis, or \"exact\" "
            "when the logged angles at rest are the true ones; calbench-log/2)")
    return q / np.sqrt(12.0)


def resolution_note(angles: np.ndarray, resolution) -> str:
    """What the rest angles' uncertainty is taken from, for the command's printout."""
    if isinstance(resolution, str) and resolution == "exact":
        return "encoder: rest angles exact (log metadata)"
    if resolution is not None:
        return "encoder: one count = " + ", ".join(f"{np.degrees(x) * 3600:.4g}\"" for x in
                                                   np.atleast_1d(resolution)) + " (log metadata)"
    q = encoder_quantum(angles)
    return ("encoder: resolution not stated, one count taken as the largest step every logged angle step is a whole "
            "number of (" + ", ".join(f"{np.degrees(x) * 3600:.4g}\"" if x > 0 else "- (never moves)" for x in q)
            + ")")


# the count is sought as the smallest step divided by 1 ... COUNT_DIVISORS: every step between
# distinct logged angles must then be a whole number of counts to COUNT_TOLERANCE of one
COUNT_DIVISORS = 256
COUNT_TOLERANCE = 1e-3
COUNT_STEPS = 20_000  # distinct steps the whole-number test reads, at most


def _distinct(x: np.ndarray) -> np.ndarray:
    """np.unique(x) from the values where x changes (a rest repeats its angle: sorting every
    sample of an 8-hour log was 0.6 s a call), a piece at a time (a spilled log's angles are not
    brought into memory whole)."""
    if not len(x):
        return x
    changed = [x[:1]]
    for s in pieces(len(x) - 1, x):
        a = x[s.start:s.stop + 1]
        changed.append(a[1:][a[1:] != a[:-1]])
    return np.unique(np.concatenate(changed))


def encoder_quantum(angles: np.ndarray) -> np.ndarray:
    """Per axis, the count: the largest q of which every step between distinct logged angles is a
    whole multiple (a table that moves several counts a sample never logs a one-count step: a
    six-position log's smallest step was 13 counts); the smallest step where none of its first
    COUNT_DIVISORS fractions is such (angles rounded to decimals, reading noise); 0 for an axis
    that never moves."""
    out = []
    for k in range(angles.shape[1]):
        x = angles[:, k]
        u = _distinct(x)
        d = np.diff(u)
        d = d[d > 0]
        if not len(d):
            out.append(0.0)
            continue
        q0 = float(d.min())
        steps = np.unique(d)[:COUNT_STEPS]
        q = next((q0 / m for m in range(1, COUNT_DIVISORS + 1)
                  if np.max(np.abs(steps * m / q0 - np.round(steps * m / q0))) < COUNT_TOLERANCE), q0)
        out.append(q)
    return np.array(out)
