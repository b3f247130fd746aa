"""diagnose's refits on the compressed rows (R of the QR of [H | y]) against least squares on the
whitened rows themselves (numpy's lstsq and an explicit projection): the same χ², solution,
covariance, rank and projected inner products, for columns of scales 1e-9 to 1e6 and a
rank-deficient pair."""
from __future__ import annotations

import numpy as np
import pytest

from components.diagnosis import candidate_design
from components.diagnosis.candidate_design import CandidateDesign


def _design(n: int = 3000, seed: int = 4) -> tuple[CandidateDesign, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    H = rng.normal(size=(n, 7)) * np.array([1e-9, 1.0, 1e6, 1.0, 3.0, 1.0, 1.0])
    H[:, 6] = 2.0 * H[:, 5]          # a twin: the rank the rows give is 6
    y = H[:, :3] @ np.array([2e9, -1.0, 3e-6]) + rng.normal(size=n)
    d = CandidateDesign([f"p{k}" for k in range(7)], (y, H, np.ones(n), {}), None, 1.0, float(n), 1.0, np.ones(6))
    return d, y, H


@pytest.mark.parametrize("qr_rows", [None, 256])
def test_fit_equals_the_whitened_rows_least_squares(qr_rows, monkeypatch):
    """Also with the rows factored 256 at a time (an 8-hour log's are factored in blocks)."""
    if qr_rows:
        monkeypatch.setattr(candidate_design, "QR_ROWS", qr_rows)
    d, y, H = _design()
    for subset in (["p0", "p1", "p2"], ["p0", "p3", "p4", "p5"], ["p1", "p5", "p6"], list(d.index)):
        A = H[:, [d.index[p] for p in subset]]
        s = np.linalg.norm(A, axis=0)
        sol, _, rank, _ = np.linalg.lstsq(A / s, y, rcond=1e-10)
        r = y - (A / s) @ sol
        chi2, got, cov, got_rank = d.fit(subset)
        assert got_rank == rank
        assert abs(chi2 - r @ r) <= 1e-10 * (r @ r)
        # a rank-deficient pair: the minimum-norm solution, the same on both
        np.testing.assert_allclose(got * s, sol, rtol=1e-8, atol=1e-10 * np.abs(sol).max())
        want_cov = np.linalg.pinv((A / s).T @ (A / s), rcond=1e-12) / np.outer(s, s)
        np.testing.assert_allclose(cov, want_cov, rtol=1e-7, atol=1e-12 * np.abs(want_cov).max())


def test_residual_and_projections_are_the_whitened_rows():
    d, y, H = _design()
    base, extra = ["p0", "p1"], ["p3", "p4"]
    B = H[:, [0, 1]]
    np.testing.assert_allclose(d.residual(base), y - B @ np.linalg.lstsq(B, y, rcond=None)[0], rtol=0, atol=1e-9)
    Qb = np.linalg.qr(B / np.linalg.norm(B, axis=0))[0]
    C = H[:, [3, 4]] - Qb @ (Qb.T @ H[:, [3, 4]])
    # inner products of the projected columns: those the detection thresholds and twins use
    got = d.projected(base, extra)
    U = np.linalg.svd(C, full_matrices=False)[0]
    np.testing.assert_allclose(got.T @ got, np.eye(2), atol=1e-12)
    h = d.projected_column(base, "p3")
    assert abs(h @ h - C[:, 0] @ C[:, 0]) <= 1e-10 * (C[:, 0] @ C[:, 0])
    np.testing.assert_allclose(np.sort(np.abs(got.T @ h)), np.sort(np.abs(U.T @ C[:, 0])), rtol=1e-9)
