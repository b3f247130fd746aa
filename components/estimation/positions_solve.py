"""The estimate of a multi-position calibration (:mod:`.positions`): which requested parameters
its rows determine, the Gauss–Newton iteration on those and the attitudes jointly, and the
covariance at the solution."""
from __future__ import annotations

import numpy as np

from components.estimation.determinability import undetermined_columns
from components.estimation.positions_model import CAL_NAMES, Model

STEP_TOL = 1e-4           # iterations stop when no parameter moves by this fraction of its σ


def determined(model: Model, th: np.ndarray, C: np.ndarray, requested: list[str],
               notes: list[str]) -> tuple[list[int], list[int]]:
    """The columns of the requested parameters split into (free, undetermined), judged on the
    Jacobian at the start after the attitudes' columns; the undetermined are held at 0."""
    req_cols = [CAL_NAMES.index(p) for p in requested]
    Jd = model.jacobian(th, C, determinability=True)
    undetermined = undetermined_columns(Jd, req_cols, model.attitude_columns)
    if undetermined:
        names = [CAL_NAMES[c] for c in undetermined]
        notes.append(f"not determined by these data, held at 0: {', '.join(names)}")
    free = [c for c in req_cols if c not in undetermined]
    return free, undetermined


def gauss_newton(model: Model, th: np.ndarray, C: np.ndarray, free: list[int], max_iterations: int,
                 notes: list[str]) -> tuple[np.ndarray, np.ndarray, int]:
    """The parameters ``free`` and the attitudes at the least-squares solution, and the
    iterations taken; a run that does not converge is said in ``notes``."""
    cols = free + model.attitude_columns
    head = [len(free) + model.na * p + 2 for p in range(model.P)] if model.na == 3 else []
    # Gauss-Newton, with Newton's curvature for the headings: a heading known to ~15° (MEMS gyros)
    # has a residual curvature comparable to its information, and Gauss-Newton alone then
    # crawls (steps shrinking by 0.9 per iteration were seen) or overshoots
    it = 0
    for it in range(1, max_iterations + 1):
        pred, J = model.predict(th, C), model.jacobian(th, C)
        r = (model.y_obs - pred) / model.sig_row
        Js = J[:, cols]
        sc = np.linalg.norm(Js, axis=0)
        sc[sc == 0] = 1.0
        Jn = Js / sc
        H = Jn.T @ Jn
        grad = Jn.T @ r
        if head:
            curv = model.heading_curvature(th, C, r) / sc[head] ** 2
            H[head, head] += np.maximum(curv, -0.5 * H[head, head])
        try:
            d = np.linalg.solve(H, grad)
        except np.linalg.LinAlgError:
            d, *_ = np.linalg.lstsq(Jn, r, rcond=None)
        size = float(np.max(np.abs(d))) if len(d) else 0.0
        d = d / sc
        old = float(r @ r)
        lam = 1.0
        for _ in range(30):
            th2, C2 = model.step(th, C, lam * d, free)
            if model.chi2(th2, C2) <= old * (1 + 1e-12) + 1e-12:
                break
            lam /= 2
        th, C = th2, C2
        if size * lam < STEP_TOL:
            break
    else:
        notes.append(f"Gauss-Newton stopped after {max_iterations} iterations without converging")
    return th, C, it


def covariance(model: Model, th: np.ndarray, C: np.ndarray, free: list[int]) -> np.ndarray:
    """(JᵀJ)⁻¹ of the whitened Jacobian over the parameters ``free`` then the attitude angles."""
    Js = model.jacobian(th, C)[:, free + model.attitude_columns]
    # columns scaled to unit length first: the parameters span many decades
    sc = np.linalg.norm(Js, axis=0)
    sc[sc == 0] = 1.0
    return np.linalg.pinv((Js / sc).T @ (Js / sc)) / np.outer(sc, sc)
