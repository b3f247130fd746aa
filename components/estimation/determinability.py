"""What a log determines: before an estimate, which parameters (or combinations of them) the rows
can tell apart at all.

Each column of the whitened design is scaled to unit length; the nuisance columns (attitudes of a
log without table angles) are projected out; Gram–Schmidt then takes the columns in the
vocabulary's order and measures what each adds beyond those accepted before it. A column with less than
``INDEPENDENT`` of its length outside the span of the others is not determined: the rows cannot tell its parameter from a
combination of the others (or see it at all). It is held (at 0 or its prior) instead of being
given a value ± 0 or ± nan, and the combination it moves with is named.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import qr

INDEPENDENT = 1e-6   # fraction of a unit column outside the span of the others, below: undetermined
LIKE_SHARE = 0.05    # a partner is named when it carries this share of the undetermined column
# a determined parameter whose σ is this many times the σ the rows give it alone (the others
# known) is confounded: the rows hardly tell it from the others, which are named
CONFOUNDED = 30.0


def undetermined_columns(J: np.ndarray, req: list[int], nuisance: list[int], tol: float = INDEPENDENT,
                         limits: np.ndarray | None = None) -> list[int]:
    """Requested columns of *J* the rows cannot determine, with the *nuisance* columns always in
    the model: every column scaled to unit length, the nuisance span projected out, then
    Gram–Schmidt in the requested order (the vocabulary's: bias before scale factor before misalignment); a
    column with less than *tol* of its length outside the span of the ones before it is
    undetermined — of two parameters the rows cannot tell apart, the later is held and the
    earlier carries their sum. With *limits* (one per requested column, in its unit; *J*
    whitened) a column is undetermined too when what it adds gives it a σ above its limit (the
    plausible magnitude of the parameter): a trace of signal, such as a rest 1e-7 rad off an axis,
    is not a determination."""

    def unit(M):
        s = np.linalg.norm(M, axis=0)
        return M / np.where(s > 0, s, 1.0), s > 0

    X, nonzero = unit(J[:, req])
    norms = np.linalg.norm(J[:, req], axis=0)
    if nuisance:
        N, _ = unit(J[:, nuisance])
        Q, R, _ = qr(N, mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        Q = Q[:, d > tol * (d.max() if len(d) else 1.0)]
        X = X - Q @ (Q.T @ X)
    out = [req[k] for k in np.nonzero(~nonzero)[0]]
    keep = [k for k in range(len(req)) if nonzero[k]]
    basis = np.empty((X.shape[0], len(keep)))
    nb = 0
    for k in keep:
        # what this column adds beyond the accepted ones before it (Gram–Schmidt, twice for
        # accuracy); a held column does not enter the basis, so it hides nothing after it
        r = X[:, k].copy()
        for _ in range(2):
            r -= basis[:, :nb] @ (basis[:, :nb].T @ r)
        d = float(np.linalg.norm(r))
        sigma = 1.0 / (d * norms[k]) if d > 0 else np.inf    # σ given the accepted ones
        if d < tol or (limits is not None and sigma > limits[k]):
            out.append(req[k])
        else:
            basis[:, nb] = r / d
            nb += 1
    return sorted(out)


@dataclass
class Determinability:
    """Which requested parameters a design determines; for each one it does not, the determined
    parameters its column moves with (coefficient: how much of the others' combination equals
    one unit of it) — empty when the rows do not see it at all."""

    determined: list[str]
    undetermined: dict[str, list[tuple[str, float]]] = field(default_factory=dict)
    # determined, but with a σ CONFOUNDED times or more the σ it would have alone: parameter ->
    # (that ratio, the parameters its column moves with and their coefficients)
    confounded: dict[str, tuple[float, list[tuple[str, float]]]] = field(default_factory=dict)

    def describe(self, parameter: str) -> str:
        """"not seen by this log" or "moves with acc.bias.x (−9.8) and ...": what the rows cannot
        tell this parameter from."""
        like = self.undetermined.get(parameter, [])
        if not like:
            return "not seen by this log"
        return "cannot be told from " + ", ".join(f"{p} ({c:+.3g})" for p, c in like)

    def describe_confounded(self, parameter: str) -> str:
        """"its σ is 1500 × ... moves with gyro.mis.zy (+1) and ...": why a determined parameter's σ
        is large (empty when it is not confounded)."""
        if parameter not in self.confounded:
            return ""
        ratio, like = self.confounded[parameter]
        partners = ", ".join(f"{p} ({c:+.3g})" for p, c in like) or "a combination of the others"
        return (f"its sigma is {ratio:.3g} x what this log gives it with the others known: it moves with "
                f"{partners}, which this log hardly tells apart from it")


def assess(H: np.ndarray, params: list[str], nuisance: int = 0, tol: float = INDEPENDENT) -> Determinability:
    """Determinability of *params* from the whitened design *H* whose last *nuisance* columns are
    nuisance parameters (always estimated, never named); a parameter whose σ given the ones
    before it exceeds its plausible limit (components.model.plausibility) is not determined."""
    from components.model.plausibility import plausible_limit

    n = len(params)
    req = list(range(n))
    nuis = list(range(n, n + nuisance))
    undet = undetermined_columns(H, req, nuis, tol, np.array([plausible_limit(p) for p in params]))
    det = [k for k in req if k not in undet]
    out = Determinability([params[k] for k in det])
    out.confounded = _confounded(H, params, det, nuis)
    if not undet:
        return out
    basis = H[:, det + nuis]
    sc = np.linalg.norm(basis, axis=0)
    sc[sc == 0] = 1.0
    for k in undet:
        col = H[:, k]
        if not np.any(col):
            out.undetermined[params[k]] = []
            continue
        coef = np.linalg.lstsq(basis / sc, col, rcond=None)[0] / sc
        share = np.abs(coef[:len(det)]) * np.linalg.norm(H[:, det], axis=0) / np.linalg.norm(col)
        order = np.argsort(-share)
        out.undetermined[params[k]] = [(params[det[i]], float(coef[i])) for i in order[:3] if share[i] > LIKE_SHARE]
    return out


def _confounded(H: np.ndarray, params: list[str], det: list[int], nuis: list[int]) -> dict:
    """The determined columns whose σ the others inflate by :data:`CONFOUNDED` or more, each with
    the determined parameters that carry its column (coefficients as in :meth:`Determinability.describe`).
    From the Gram matrix of the unit columns: σ relative to alone is √((XᵀX)⁻¹)ₖₖ, and the
    regression of a column on the others is the normal equations on that matrix."""
    cols = det + nuis
    if len(det) < 2 or H.shape[0] == 0:
        return {}
    norms = np.linalg.norm(H[:, cols], axis=0)
    norms[norms == 0] = 1.0
    X = H[:, cols] / norms
    G = X.T @ X
    ratio = np.sqrt(np.clip(np.diag(np.linalg.pinv(G, rcond=1e-12, hermitian=True)), 0.0, None))
    out = {}
    for i, k in enumerate(det):
        if not ratio[i] >= CONFOUNDED:
            continue
        others = [j for j in range(len(cols)) if j != i]
        c = np.linalg.lstsq(G[np.ix_(others, others)], G[others, i], rcond=1e-12)[0]  # unit columns
        share = np.abs(c[:len(det) - 1])
        order = np.argsort(-share)
        names = [params[cols[others[j]]] for j in range(len(det) - 1)]
        # one unit of parameter k is coefficient × (unit of the partner) of the combination
        coef = c[:len(det) - 1] * norms[i] / norms[others[:len(det) - 1]]
        out[params[k]] = (float(ratio[i]), [(names[j], float(coef[j])) for j in order[:3] if share[j] > LIKE_SHARE])
    return out
