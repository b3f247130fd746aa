"""Where the table rests: the true angle at rest lies within the encoder's count of the logged
one, and that uncertainty bounds a rest-to-rest gyro block (the integral of the gyro over a move
equals the rotation between the two rest angles)."""
from __future__ import annotations

import numpy as np

from components.estimation.blocks import Blocks
from components.model.geometry import TableGeometry


def rest_directions(angles: np.ndarray, geo: TableGeometry, at: np.ndarray) -> np.ndarray:
    """Plate-frame rotation direction of each stage (B, n_axes, 3) at the logged angles of the
    samples *at*: how a small error of that stage's rest angle shows in the gyro triad."""
    th = np.atleast_2d(angles[at])
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


def rest_sigma(angles: np.ndarray, given=None) -> np.ndarray:
    """Per-axis σ of the true angle at rest: *given*, or a uniform count q/√12."""
    if given is not None:
        return np.broadcast_to(np.asarray(given, float), (angles.shape[1],)).copy()
    return encoder_quantum(angles) / np.sqrt(12.0)


def encoder_quantum(angles: np.ndarray) -> np.ndarray:
    """Per axis, the smallest step between distinct logged angles (the count), or 0."""
    out = []
    for k in range(angles.shape[1]):
        u = np.unique(angles[:, k])
        d = np.diff(u)
        d = d[d > 0]
        out.append(float(d.min()) if len(d) else 0.0)
    return np.array(out)
