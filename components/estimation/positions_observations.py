"""The log reduced to the rows of a multi-position calibration (:mod:`.positions`): per rest the
sums of increments over each chunk and over the whole rest, per turn the summed gyro increments
and the matrix M_r that carries the Earth rate through it, and the rows' white-noise σ."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from components.errors import EstimationError
from components.estimation.blocks import white_noise_sigma
from components.estimation.design import ACC_SCALE, GYRO_SCALE, noise_floor
from components.estimation.positions_input import Segments
from components.model.geometry import rodrigues

ANGLE_TOL = (0.1, 5.0)    # a turn's gyro angle within 10 % + 5° of the stated one


@dataclass
class Rests:
    """The static rows: each chunk's sums (χ² is taken over them) and each rest's total (with
    white noise the fit needs no more than the total)."""

    chunk_rest: np.ndarray    # (chunks,) the rest each chunk belongs to
    chunk_T: np.ndarray       # (chunks,) duration [s]
    chunk_g: np.ndarray       # (chunks, 3) Σ Δθ [rad]
    chunk_a: np.ndarray       # (chunks, 3) Σ Δv [m/s]
    T: np.ndarray             # (P,) per rest: duration used [s]
    S_g: np.ndarray           # (P, 3) Σ Δθ
    S_a: np.ndarray           # (P, 3) Σ Δv
    samples: np.ndarray       # (P,) samples used


@dataclass
class Turn:
    """One rotation's row: Σ Δθ from rest to rest and what the model needs of its profile."""

    name: str
    label: str
    lo: int                   # summed samples [lo, hi)
    hi: int
    axis: np.ndarray
    angle: float              # rad, stated
    T: float                  # s
    sum: np.ndarray           # Σ Δθ [rad]
    M: np.ndarray             # Σ_k R(a, θ_k)ᵀ Δt_k [s]
    q: int                    # the rest before it
    q_after: int              # and after it
    before: str
    after: str


def reduce_rests(segs: Segments, yg: np.ndarray, ya: np.ndarray, dt: np.ndarray) -> Rests:
    """The rests' sums of increments per chunk and per rest (``dt`` [s] per sample)."""
    P = len(segs.names)
    chunk_list = segs.chunks
    ch_p = np.array([c[0] for c in chunk_list])
    ch_a = np.array([c[1] for c in chunk_list])
    ch_b = np.array([c[2] for c in chunk_list])
    # cumulative sums make every chunk's sum two look-ups
    cdt = np.concatenate([[0.0], np.cumsum(dt)])
    cg = np.vstack([np.zeros(3), np.cumsum(yg, axis=0)])
    ca = np.vstack([np.zeros(3), np.cumsum(ya, axis=0)])
    ch_T = cdt[ch_b] - cdt[ch_a]
    ch_g = cg[ch_b] - cg[ch_a]
    ch_acc = ca[ch_b] - ca[ch_a]
    T_p = np.bincount(ch_p, ch_T, P)
    S_g = np.column_stack([np.bincount(ch_p, ch_g[:, i], P) for i in range(3)])
    S_a = np.column_stack([np.bincount(ch_p, ch_acc[:, i], P) for i in range(3)])
    n_used = np.bincount(ch_p, ch_b - ch_a, P)
    return Rests(ch_p, ch_T, ch_g, ch_acc, T_p, S_g, S_a, n_used)


def reduce_turns(segs: Segments, yg: np.ndarray, dt: np.ndarray) -> list[Turn]:
    """Each turn's sum and M_r; a turn whose gyros disagree with its stated axis and angle is a
    wrong label (EstimationError), not a calibration error to fit."""
    pidx = {nm: i for i, nm in enumerate(segs.names)}
    rots = []
    for sp in segs.turns:
        name, axis, angle, lo, hi = sp.name, sp.axis, sp.angle, sp.lo, sp.hi
        missing = [(side, nm) for side, nm in (("before", sp.before), ("after", sp.after)) if nm not in pidx]
        if missing:
            side, nm = missing[0]
            raise EstimationError(f"rotation {name!r}: the static segment {side} it ({nm!r}) has no usable samples "
                                  "(left out by the mask, an exclusion or gaps): a turn's row needs the rest on "
                                  "each side; leave the rotation out too, or keep that rest")
        s = yg[lo:hi] @ axis
        total = float(s.sum())
        if abs(total - angle) > ANGLE_TOL[0] * abs(angle) + math.radians(ANGLE_TOL[1]):
            raise EstimationError(f"rotation {name!r}: the gyros turn {math.degrees(total):+.1f}° about "
                                  f"{np.round(axis, 3).tolist()}, the segment says {math.degrees(angle):+.1f}°: "
                                  "check its axis and angle")
        # θ_k from the gyro itself, scaled to the stated angle: its errors change M_r by ~1e-9 rad
        theta = (np.cumsum(s) - s / 2) * (angle / total)
        R = rodrigues(axis, theta)
        M = np.einsum("k,kji->ij", dt[lo:hi], R)   # Σ R(a, θ_k)ᵀ Δt_k
        rots.append(Turn(name=name, label=sp.label, lo=lo, hi=hi, axis=axis, angle=angle,
                         T=float(dt[lo:hi].sum()), sum=yg[lo:hi].sum(axis=0), M=M,
                         q=pidx[sp.before], q_after=pidx[sp.after], before=sp.before, after=sp.after))
    return rots


COLOURED_NOT_USED = "the noise model's coloured terms are not used by the first positions fit (white part only)"


def white_sigmas(noise, yg: np.ndarray, ya: np.ndarray, use: np.ndarray, dt_med: float,
                 notes: list[str]) -> tuple[np.ndarray, np.ndarray, str]:
    """Per-sample white σ of the gyros [rad] and accelerometers [m/s] that weight the rows, and
    where they come from: the white part of ``noise`` (a NoiseModel) or, without one or where it
    has no white term, the static data."""
    if noise is not None:
        white = np.asarray(noise.white_sigma(dt_med), float)
        est = white_noise_sigma(np.hstack([yg, ya]), use)
        missing = ~(white > 0)
        if np.any(missing):
            white = np.where(missing, est, white)
            notes.append("the noise model has no white term on some channels: their σ is estimated from "
                         "the static data")
        source = f"white part of the given noise model ({noise.source or 'given'})"
        if noise.coloured:
            notes.append(COLOURED_NOT_USED)
    else:
        white = white_noise_sigma(np.hstack([yg, ya]), use)
        source = "estimated from the static data"
    sg = noise_floor(white[:3], GYRO_SCALE * dt_med)
    sa = noise_floor(white[3:], ACC_SCALE * dt_med)
    return sg, sa, source
