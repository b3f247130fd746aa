"""R of the QR of a tall matrix whose rows come a piece at a time.

The R of [A; B] is the R of [R_A; B] (Q being orthonormal), so each piece is stacked under the R
of the rows before it and factored again (Householder, LAPACK geqrf through numpy): the rows are
never held whole, and R (at most as many rows as columns) carries every least squares on any
subset of the columns — the same solution, χ² and singular values as on all the rows.
Householder QR is backward stable column by column, so columns of any scale keep their accuracy.
"""
from __future__ import annotations

import numpy as np


class StackedQR:
    """R of the rows added so far, (min(rows, columns), columns)."""

    def __init__(self, columns: int):
        self.r = np.zeros((0, int(columns)))

    def add(self, rows: np.ndarray) -> None:
        """Stack *rows* (k, columns) under the R so far and factor again (numpy's QR works on a
        copy of the stack: one piece and R)."""
        M = np.empty((len(self.r) + len(rows), self.r.shape[1]))
        M[:len(self.r)] = self.r
        M[len(self.r):] = rows
        self.r = np.linalg.qr(M, mode="r")


def scaled_lstsq(A: np.ndarray, y: np.ndarray, rcond: float | None) -> tuple[np.ndarray, float, np.ndarray, int]:
    """(solution, χ², covariance, rank) of the least squares A x ≈ y, A's columns scaled to unit
    length for the solve (parameters of every unit: *rcond* then cuts directions the rows cannot
    see, not small units). On R's rows (:class:`StackedQR`) it is the solve on the rows R came from."""
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    As = A / scale
    sol, _, rank, _ = np.linalg.lstsq(As, y, rcond=rcond)
    r = y - As @ sol
    cov = np.linalg.pinv(As.T @ As, rcond=1e-12) / np.outer(scale, scale)
    return sol / scale, float(r @ r), cov, int(rank)
