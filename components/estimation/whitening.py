"""Whitening of the observation rows under a coloured noise model: generalised least squares
at a cost linear in the log's length.

The block sums of one channel, in time order, are y_k = h_k θ + e_k with e_k correlated through
the noise terms' states at the block boundaries (components.model.block_noise.BlockNoise). The
Kalman filter of that state-space model turns them into innovations ν_k with variances S_k;
ν_k / √S_k = (L⁻¹ y)_k for the Cholesky factor L of their covariance in time order, so applying
the same (data-independent) filter to y and to every column of H gives the whitened rows whose
ordinary least squares is the GLS estimate, whose Hᵀ H is the Fisher information and whose sum
of squares is χ². Channels are independent. With white noise the filter is the division by the
block's σ that the estimators have always done (the same bits).
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from components.errors import EstimationError
from components.estimation.stacked_qr import StackedQR
from components.logs.spill import gathered, pieces
from components.model.block_noise import BlockNoise, block_noise
from components.model.noise import NoiseModel


def whiten_channel(values: np.ndarray, bn: BlockNoise) -> tuple[np.ndarray, np.ndarray]:
    """Whitened rows (B, k) of *values* (B, k) in block order, and the innovation variances (B,)."""
    values = np.asarray(values, float)
    return ChannelWhitener(bn, values.shape[1])(values)


class ChannelWhitener:
    """The whitening filter of one channel run over its blocks a piece at a time: each call
    whitens the next blocks' rows (k columns) and leaves the filter's state — its covariance and
    each column's estimate — for the next call, so the pieces together are the whole channel
    whitened in one call, bit for bit, and a long log's rows need never be held whole."""

    def __init__(self, bn: BlockNoise, ncol: int):
        self.bn, self.ncol, self.done = bn, int(ncol), 0
        m = bn.states
        self._work = np.empty(2 * m * m + 2 * m * self.ncol + 2 * m + self.ncol)

    def __call__(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Whitened rows and innovation variances of the next len(*values*) blocks."""
        bn, k0 = self.bn, self.done
        values = np.ascontiguousarray(values, dtype=float)
        nb = len(values)
        if values.ndim != 2 or values.shape[1] != self.ncol or k0 + nb > len(bn.r):
            raise ValueError(f"rows {k0}..{k0 + nb} of {self.ncol} columns for a channel of {len(bn.r)} blocks "
                             f"whitened with {self.ncol} columns: got shape {values.shape}")
        self.done = k0 + nb
        at = slice(k0, k0 + nb)
        if bn.states == 0:
            return values * (1.0 / np.sqrt(bn.r[at]))[:, None], bn.r[at].copy()
        m = bn.states
        out = np.empty((nb, self.ncol))
        S_all = np.empty(nb)
        resume = int(k0 > 0)
        if bn.spin is None:
            arrays = [np.ascontiguousarray(a[at], dtype=float) for a in (bn.phi, bn.q, bn.c, bn.cross, bn.r)]
            arrays += [np.ascontiguousarray(bn.p0, dtype=float), values]
            failed = _kernel()(nb, m, self.ncol, resume, *[_ptr(a) for a in arrays], _ptr(out), _ptr(S_all),
                               _ptr(self._work))
        else:
            partner = np.ascontiguousarray(bn.partner, dtype=np.int64)
            arrays = [np.ascontiguousarray(a[at], dtype=float) for a in (bn.phi, bn.spin)]
            rest = [np.ascontiguousarray(a[at], dtype=float) for a in (bn.q, bn.c, bn.cross, bn.r)]
            rest += [np.ascontiguousarray(bn.p0, dtype=float), values]
            failed = _turning_kernel()(nb, m, self.ncol, resume, *[_ptr(a) for a in arrays], _ptr(partner),
                                       *[_ptr(a) for a in rest], _ptr(out), _ptr(S_all), _ptr(self._work))
        if failed:
            k = failed - 1
            self.done = k0  # (the state is spoilt: no piece may follow)
            raise EstimationError(
                f"whitening under the noise model failed at block {k0 + k + 1} of {len(bn.r)}: its predicted variance "
                f"is {S_all[k]:.3g} (the noise model's state covariance lost its positive definiteness; "
                "its terms span too many decades for the log's length — give a simpler noise model with --noise)")
        return out, S_all


# the arrays go in as bare addresses: a typed pointer (data_as) costs 3 µs each, 10 per call,
# and the noise likelihood whitens ~10^5 times a `calbench noise`
_ADDRESS = ctypes.c_void_p
_KERNELS: dict = {}


def _entry(name: str, argtypes: list):
    """An entry of whiten_kernel.c (compiled on first use and cached), returning long."""
    if name not in _KERNELS:
        from orchestrator.native import compiled

        fn = getattr(compiled(Path(__file__).with_name("whiten_kernel.c")), name)
        fn.restype = ctypes.c_long
        fn.argtypes = argtypes
        _KERNELS[name] = fn
    return _KERNELS[name]


def _kernel():
    """The filter's recursion in C."""
    return _entry("calbench_whiten", [ctypes.c_long] * 4 + [_ADDRESS] * 10)


def _turning_kernel():
    """The filter whose transition also turns pairs of states."""
    return _entry("calbench_whiten_turning", [ctypes.c_long] * 4 + [_ADDRESS] * 12)


def _ptr(a: np.ndarray) -> int:
    """The address of *a*'s data (C-contiguous, of the kernel's type: double, or long for partner)."""
    return a.ctypes.data


def channel_rows(rows: dict, channel: int) -> np.ndarray:
    """Indices of one channel's rows (0-2 gyro, 3-5 accelerometer), in block order."""
    sensor = "gyro" if channel < 3 else "acc"
    return np.nonzero((rows["sensor"] == sensor) & (rows["axis"] == channel % 3))[0]


def block_timing(rows: dict, idx: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(durations, gaps) [s] of the rows *idx* (one channel's, in block order) for
    components.model.block_noise: each block's length and what lies between it and the
    block before (left-out samples, a dropped move; 0 for the first)."""
    start, stop = rows["start"][idx], rows["stop"][idx]
    gaps = np.zeros(len(idx))
    gaps[1:] = (start[1:] - stop[:-1]) * dt
    if np.any(gaps < 0):
        k = int(np.argmax(gaps < 0))
        raise ValueError(f"block rows out of time order: row {idx[k + 1]} starts at sample {start[k + 1]}, before "
                         f"row {idx[k]} ends at {stop[k]}")
    return (stop - start) * dt, gaps


def advance_of(rows: dict, idx: np.ndarray) -> np.ndarray | None:
    """The advance of the rows *idx* (one channel's, in block order) for
    components.model.block_noise (a pulse output's count phase through its rests,
    components.estimation.count_phase), or None when the rows have none for that channel."""
    if "advance" not in rows:
        return None
    adv = rows["advance"][idx]
    if not np.any(np.isfinite(adv)):
        return None
    return adv


@dataclass(frozen=True)
class ChannelBlocks:
    """One channel's block rows as the noise likelihood and block_noise take them, in block order."""

    y: np.ndarray
    H: np.ndarray  # the columns the channel sees (those not zero on every one of its rows)
    durations: np.ndarray  # [s]
    gaps: np.ndarray  # [s] (block_timing)
    white_var: np.ndarray  # the rows' variance from white noise and rest angles
    advance: np.ndarray | None  # a pulse output's count phase (advance_of)


def channel_blocks(rows: dict, channel: int, dt: float, y: np.ndarray, H: np.ndarray, weight: np.ndarray,
                   columns: list[int] | None = None) -> ChannelBlocks:
    """:class:`ChannelBlocks` of *channel* from a design's rows (*y*, *H* — or its *columns* —
    and the rows' *weight*, 1/σ); a spilled *H* is read a piece at a time."""
    idx = channel_rows(rows, channel)
    Hc = gathered(H, idx, columns)
    durations, gaps = block_timing(rows, idx, dt)
    return ChannelBlocks(y[idx], Hc[:, np.any(Hc != 0, axis=0)], durations, gaps, 1.0 / weight[idx] ** 2,
                         advance_of(rows, idx))


def whiten(y: np.ndarray, H: np.ndarray, rows: dict, white_var: np.ndarray, noise: NoiseModel | None,
           dt: float, span: float, t_lo: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(whitened y, whitened H, innovation variance per row) of the design's rows.
    ``white_var``: each row's variance from white noise and rest angles; ``noise``: the coloured
    terms (None or white: only ``white_var``); ``dt`` [s] the sample interval, ``span`` [s] the
    log's duration, ``t_lo`` [s] the shortest time scale the flicker floor is realised from."""
    if noise is None or not noise.coloured:
        w = 1.0 / np.sqrt(white_var)
        return y * w, H * w[:, None], np.asarray(white_var, float).copy()
    yw = np.empty_like(y, dtype=float)
    Hw = np.empty_like(H, dtype=float)
    S = np.empty(len(y))
    for ch in range(6):
        idx = channel_rows(rows, ch)
        if len(idx) == 0:
            continue
        bn = _channel_noise(rows, idx, white_var, noise.channels[ch], dt, span, t_lo)
        vals, s = whiten_channel(np.column_stack([y[idx], H[idx]]), bn)
        yw[idx], Hw[idx], S[idx] = vals[:, 0], vals[:, 1:], s
    return yw, Hw, S


def _channel_noise(rows: dict, idx: np.ndarray, white_var: np.ndarray, channel, dt: float, span: float,
                   t_lo: float) -> BlockNoise:
    """The block noise of the rows *idx* (one channel's, in block order) under *channel*'s terms."""
    durations, gaps = block_timing(rows, idx, dt)
    return block_noise(channel, durations, white_var[idx], span, t_lo, advance_of(rows, idx), gaps)


def whitened_r(y: np.ndarray, H: np.ndarray, rows: dict, white_var: np.ndarray, noise: NoiseModel | None,
               dt: float, span: float, t_lo: float = 1.0, piece: int | None = None) -> np.ndarray:
    """R of the QR of the whitened [H | y] (components.estimation.stacked_qr), the rows whitened
    a piece at a time (:func:`whitened_pieces`): any least squares on the whitened rows, on any
    subset of H's columns, has on R's few rows the same solution, χ², covariance and rank (its
    last column is y's: the part outside every column's span is its last row). The whitened
    rows are never held whole: on an 8-hour log ~40 MB a copy, and a solve made several."""
    r = StackedQR(H.shape[1] + 1)
    for _, M in whitened_pieces(y, H, rows, white_var, noise, dt, span, t_lo, piece):
        r.add(M)
    return r.r


# rows whitened at a time by whitened_pieces (at 300 columns a piece is 40 MB)
PIECE_ROWS = 1 << 14


def whitened_pieces(y: np.ndarray, H: np.ndarray, rows: dict, white_var: np.ndarray, noise: NoiseModel | None,
                    dt: float, span: float, t_lo: float = 1.0, piece: int | None = None,
                    columns: list[int] | None = None):
    """The design's rows whitened as :func:`whiten` whitens them (the same bits), a piece of
    *piece* rows at a time in row order: yields (the piece's slice of rows, its whitened
    [H | y], or [H[:, columns] | y]; columns None: all). Each channel's filter carries its state from one piece to the next
    (:class:`ChannelWhitener`), so only a piece of the whitened rows is ever in memory, and of
    a spilled *H* (components.logs.spill) only a piece's pages."""
    n = len(y)
    p = H.shape[1] if columns is None else len(columns)
    coloured = noise is not None and noise.coloured
    if coloured:
        channel = np.full(n, -1, np.int8)
        whiteners = {}
        for ch in range(6):
            idx = channel_rows(rows, ch)
            if len(idx):
                channel[idx] = ch
                whiteners[ch] = ChannelWhitener(_channel_noise(rows, idx, white_var, noise.channels[ch], dt, span,
                                                               t_lo), p + 1)
    else:
        w = 1.0 / np.sqrt(white_var)
    # (a column of y alone reads none of H's pages, so gives none back)
    for at in pieces(n, *([H] if p else []), step=piece or PIECE_ROWS):
        M = np.empty((at.stop - at.start, p + 1))
        M[:, p] = y[at]
        if p:
            M[:, :p] = H[at] if columns is None else H[at][:, columns]
        if not coloured:
            M *= w[at, None]
        else:
            of = channel[at]
            for ch in np.unique(of):
                mine = of == ch
                M[mine] = whiteners[int(ch)](M[mine])[0]
        yield at, M
