"""Which physical effect is missing from a model: refit the model with each candidate effect of
the vocabulary added and rank the candidates by a proper test.

All refits share one linearised design (components.estimation.lsq: block rows, the model's geometry), so
each candidate costs a small weighted least-squares solve. For candidate c with k new columns
(the rank they add after projecting out the model's own columns):

    F = (Δχ² / k) / (χ²_c / (n − p_c)),   p = P(F_{k, n−p_c} > F)

p-values are Holm-corrected over the candidates (family-wise error α), and the Bayesian
information criterion must agree: ΔBIC = χ²_c − χ²_base + k ln n < 0. The verdict is the best
candidate that passes both, or null. Forward selection adds the verdict and ranks again, so
several missing effects are named in turn. Two candidates whose new columns are nearly the same
(largest canonical correlation > 0.98) cannot be told apart on this schedule; the diagnosis says
so and proposes a schedule change that separates them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from components.estimation.blocks import observation_blocks, white_noise_sigma
from components.estimation.design import design
from components.estimation.log_data import LogData
from components.estimation.rest_angles import rest_sigma
from components.estimation.whitening import whiten
from components.model.effects import EFFECTS, effect_of, parameters_of
from components.model.noise import NoiseModel
from components.model.result import CalibrationResult

# Which schedule change separates two effects (order-free pairs), else a generic hint per effect.
_SEPARATE = {
    frozenset({"acc.temp", "acc.drift"}): "make the temperature non-monotonic in time (a heat/cool cycle), so temperature and elapsed time differ",
    frozenset({"gyro.temp", "gyro.drift"}): "make the temperature non-monotonic in time (a heat/cool cycle), so temperature and elapsed time differ",
    frozenset({"acc.k2", "acc.sf_asym"}): "add ±45° positions: K2 grows with f² (half at 45°), the asymmetry with |f|",
    frozenset({"acc.k2", "acc.bias"}): "add positions with the axis horizontal and at ±45°: K2 vanishes at 0 g, a bias does not",
    frozenset({"acc.k3", "acc.sf"}): "add ±45° positions: K3 scales with f³, the scale factor with f",
    frozenset({"table.base_tilt", "acc.mis"}): "index the outer (azimuth) axis through 0/90/180/270° (seed 000): a base tilt turns with the outer axis, a misalignment does not",
    frozenset({"table.base_tilt", "acc.bias"}): "index the outer axis through 0/90/180/270°: a tilt reverses sign between opposite positions",
    frozenset({"gyro.sf_asym", "gyro.bias"}): "rotate at two different rates in both directions",
    frozenset({"acc.lever", "acc.k2"}): "rotate at two rates about each axis: the lever term grows with ω², K2 does not change with rate",
    frozenset({"imu.time_offset", "acc.lever"}): "index with different accelerations: the time offset follows df/dt, the tangential lever term ω̇",
}
_GENERIC = {
    "gyro": "add rotations about each axis in both directions at two rates, and more attitudes",
    "acc": "add attitudes (±1 g and ±45° on each axis)",
    "imu": "add fast indexing moves in several directions",
    "table": "rotate each stage through full turns with the IMU in two mountings",
}


def separation_advice(a: str, b: str) -> str:
    key = frozenset({a, b})
    if key in _SEPARATE:
        return _SEPARATE[key]
    return f"{a}: {_GENERIC[EFFECTS[a].target]}; {b}: {_GENERIC[EFFECTS[b].target]}"


@dataclass
class Candidate:
    effect: str
    statistic: float
    p_value: float
    p_adjusted: float
    bic_delta: float
    explained_fraction: float
    added_rank: int
    parameters: dict  # name -> (value, sigma) SI
    passes: bool = False
    indistinguishable: list = field(default_factory=list)  # [(effect, correlation, advice)]
    implausible: list = field(default_factory=list)  # parameters fitted far outside the physical range
    correlated: list = field(default_factory=list)  # [(param, other param, rho)] within the fit
    signature: dict | None = None

    def to_json(self) -> dict:
        e = EFFECTS[self.effect]
        unit, scale = e.display
        return {"effect": self.effect, "statistic": self.statistic, "p_value": self.p_value,
                "p_adjusted": self.p_adjusted, "bic_delta": self.bic_delta,
                "explained_fraction": self.explained_fraction, "passes": self.passes,
                "parameters": {p: [v, s] for p, (v, s) in self.parameters.items()},
                "display_unit": unit,
                "parameters_display": {p: [v / scale, s / scale] for p, (v, s) in self.parameters.items()},
                "indistinguishable": [{"effect": o, "correlation": r, "advice": a}
                                      for o, r, a in self.indistinguishable],
                "implausible": list(self.implausible)}


@dataclass
class Diagnosis:
    verdict: str | None
    ranking: list[Candidate]
    found: list[str]             # forward selection, in turn
    steps: list[dict]            # per selection step: effect, chi2_per_dof before/after
    base_chi2_per_dof: float
    rows: int
    alpha: float

    def to_json(self) -> dict:
        return {"verdict": self.verdict, "found": self.found,
                "ranking": [c.to_json() for c in self.ranking], "steps": self.steps,
                "base_chi2_per_dof": self.base_chi2_per_dof, "rows": self.rows, "alpha": self.alpha}


class _Design:
    """Whitened block design of all parameters of the model and of every candidate."""

    def __init__(self, data: LogData, model: CalibrationResult, params: list[str],
                 chunk_s: float, rest_angle_sigma, noise: NoiseModel | None = None):
        from components.diagnosis.compare import model_geometry

        geo = model_geometry(data, model)
        table_params = [p for p in params if effect_of(p).target == "table"]
        T0 = model.temperature_ref

        def motion_for(g):
            return data.motion(g, T0)

        motion = motion_for(geo)
        dt = float(np.median(np.diff(data.time)))
        n_chunk = max(1, int(round(chunk_s / dt)))
        gb, ab = observation_blocks(motion.static, data.angles, n_chunk)
        # noise from the high-frequency content of the data (differences remove the model)
        sg = white_noise_sigma(data.gyro, motion.static)
        sa = white_noise_sigma(data.acc, motion.static)
        if noise is not None and noise.coloured:
            white = noise.white_sigma(dt)
            sg, sa = np.where(white[:3] > 0, white[:3], sg), np.where(white[3:] > 0, white[3:], sa)
        sg = np.where(np.isfinite(sg) & (sg > 0), sg, 0.0) + 1e-13 * 7.3e-5 * dt
        sa = np.where(np.isfinite(sa) & (sa > 0), sa, 0.0) + 1e-13 * 9.8 * dt
        rest = rest_sigma(data.angles, rest_angle_sigma)
        y, H, w, rows = design(data, motion, params, gb, ab, sg, sa, rest, geo, table_params, motion_for)
        span = float(data.time[-1] - data.time[0] + dt)
        yw, Hw, _ = whiten(y, H, rows, 1.0 / w**2, noise, dt, span, chunk_s)
        # table columns are derivatives at the model's geometry: the model's table values are
        # already in the motion, so their unknowns here are corrections (start at 0)
        self.params = params
        self.index = {p: k for k, p in enumerate(params)}
        self.y = yw
        self.H = Hw
        self.noise = noise
        self.rows = rows
        self.n = len(y)
        self.motion = motion

    def fit(self, subset: list[str]) -> tuple[float, np.ndarray, np.ndarray, int]:
        """χ², values, covariance and rank of the WLS fit on *subset* of the parameters."""
        if not subset:
            return float(self.y @ self.y), np.zeros(0), np.zeros((0, 0)), 0
        A = self.H[:, [self.index[p] for p in subset]]
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        As = A / scale
        sol, _, rank, sv = np.linalg.lstsq(As, self.y, rcond=1e-10)
        r = self.y - As @ sol
        cov = np.linalg.pinv(As.T @ As, rcond=1e-12) / np.outer(scale, scale)
        return float(r @ r), sol / scale, cov, int(rank)

    def residual(self, subset: list[str]) -> np.ndarray:
        if not subset:
            return self.y.copy()
        A = self.H[:, [self.index[p] for p in subset]]
        sol = np.linalg.lstsq(A, self.y, rcond=1e-10)[0]
        return self.y - A @ sol

    def projected(self, base: list[str], extra: list[str]) -> np.ndarray:
        """Columns of *extra* with the span of *base* projected out (orthonormal basis)."""
        C = self.H[:, [self.index[p] for p in extra]]
        if base:
            B = self.H[:, [self.index[p] for p in base]]
            Q, _ = np.linalg.qr(B / np.maximum(np.linalg.norm(B, axis=0), 1e-300))
            C = C - Q @ (Q.T @ C)
        norms = np.linalg.norm(C, axis=0)
        C = C[:, norms > 1e-9 * max(norms.max(initial=0.0), 1e-300)]
        if C.shape[1] == 0:
            return C
        U, s, _ = np.linalg.svd(C, full_matrices=False)
        return U[:, s > 1e-8 * s[0]]


def default_candidates(model_effects: list[str]) -> list[str]:
    """Every effect of the vocabulary the model does not have."""
    return [name for name in EFFECTS if name not in model_effects]


def diagnose(data: LogData, model: CalibrationResult, *, candidates: list[str] | None = None,
             alpha: float = 0.01, forward: bool = True, max_steps: int = 4, chunk_s: float = 1.0,
             rest_angle_sigma=None, noise: NoiseModel | None = None) -> Diagnosis:
    """Which effects of the vocabulary are missing from *model* on *data* (see the module
    docstring). ``noise``: the composite noise model the rows are whitened with (default: the
    model's own; without one, white noise of the level in the data's high-frequency content)."""
    if noise is None:
        noise = model.noise_model()
    base_effects = list(model.effects)
    cands = candidates if candidates is not None else default_candidates(base_effects)
    cands = [c for c in cands if c not in base_effects]
    params = list(dict.fromkeys(parameters_of(base_effects) + parameters_of(cands)))
    # table-effect parameters for stages this table does not have contribute nothing
    stage_names = set(data.geometry.names)
    params = [p for p in params if not (effect_of(p).target == "table" and p.split(".")[2] not in
                                        stage_names and not p.startswith("table.base_tilt"))]
    design = _Design(data, model, params, chunk_s, rest_angle_sigma, noise)
    available = {c: [p for p in EFFECTS[c].parameters if p in design.index] for c in cands}
    base = [p for p in parameters_of(base_effects) if p in design.index]
    found: list[str] = []
    steps: list[dict] = []
    first_ranking: list[Candidate] | None = None
    chi2_first = None
    for _ in range(max_steps if forward else 1):
        ranking, chi2_base, dof_base = _rank(design, base, available, alpha)
        if first_ranking is None:
            first_ranking, chi2_first = ranking, chi2_base / dof_base
        winner = next((c for c in ranking if c.passes), None)
        if winner is None:
            break
        found.append(winner.effect)
        base = base + available.pop(winner.effect)
        chi2_after, _, _, rank_after = design.fit(base)
        steps.append({"effect": winner.effect, "chi2_per_dof_before": chi2_base / dof_base,
                      "chi2_per_dof_after": chi2_after / max(design.n - rank_after, 1),
                      "p_adjusted": winner.p_adjusted, "bic_delta": winner.bic_delta})
        if not available:
            break
    return Diagnosis(found[0] if found else None, first_ranking or [], found, steps,
                     chi2_first or float("nan"), design.n, alpha)


def _rank(design: _Design, base: list[str], available: dict, alpha: float):
    chi2_b, _, _, rank_b = design.fit(base)
    dof_b = max(design.n - rank_b, 1)
    resid_b = design.residual(base)
    out: list[Candidate] = []
    for effect, ps in available.items():
        if not ps:
            continue
        basis = design.projected(base, ps)
        k = basis.shape[1]
        if k == 0:
            continue  # the schedule does not excite this effect at all beyond the model
        chi2_c, sol, cov, rank_c = design.fit(base + ps)
        dchi2 = max(chi2_b - chi2_c, 0.0)
        dof_c = max(design.n - rank_c, 1)
        F = (dchi2 / k) / max(chi2_c / dof_c, 1e-300)
        logp = float(stats.f.logsf(F, k, dof_c))
        sig = np.sqrt(np.clip(np.diag(cov), 0, None))
        values = dict(zip(base + ps, zip(sol.tolist(), sig.tolist())))
        # a fitted magnitude far outside anything physical means the linearised model is being
        # used to absorb something else (table angles beyond the small-angle range, or a
        # near-degenerate column): such a candidate is reported but cannot be the verdict
        # (sensor effects are linear in their parameters, so only an absurd value is suspect: the
        # typical magnitudes are navigation grade, tactical grade is up to 1000 times them, and a
        # drift or temperature coefficient must be far above them to show in a short run)
        typical = EFFECTS[effect].typical
        factor = 1000 if EFFECTS[effect].target == "table" else 1e5
        implausible = [p for p in ps if abs(values[p][0]) > max(factor * typical,
                                                                  0.01 if EFFECTS[effect].unit == "rad" else 0)]
        cand = Candidate(effect, float(F), math.exp(logp), 1.0,
                         float(chi2_c - chi2_b + k * math.log(design.n)),
                         float(dchi2 / chi2_b) if chi2_b > 0 else 0.0, k,
                         {p: values[p] for p in ps})
        cand._logp = logp  # type: ignore[attr-defined]
        cand.implausible = implausible
        cand._basis = basis  # type: ignore[attr-defined]
        # correlations of the new parameters with the model's own ones in this fit
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = cov / np.outer(sig, sig)
        names = base + ps
        for i, p in enumerate(names[len(base):], start=len(base)):
            for j in range(len(base)):
                if abs(corr[i, j]) > 0.95:
                    cand.correlated.append((p, names[j], float(corr[i, j])))
        # signature: base residual against the strongest new parameter's regressor
        best = max(ps, key=lambda p: abs(values[p][0]) / (values[p][1] or np.inf))
        col = design.H[:, design.index[best]] * values[best][0]
        cand.signature = {"parameter": best, "x": col, "y": resid_b}
        out.append(cand)
    # Holm correction over the candidates, ranking by evidence
    out.sort(key=lambda c: (c._logp, -c.statistic))  # type: ignore[attr-defined]
    m = len(out)
    running = 0.0
    for i, c in enumerate(out):
        adj = min(1.0, (m - i) * math.exp(c._logp))  # type: ignore[attr-defined]
        running = max(running, adj)
        c.p_adjusted = running
        c.passes = c.p_adjusted < alpha and c.bic_delta < 0 and not c.implausible
    # candidates that cannot be told apart from a passing one
    for c in out[:6]:
        if not c.passes:
            continue
        for d in out:
            if d is c or d.explained_fraction < 0.5 * c.explained_fraction:
                continue
            s = np.linalg.svd(c._basis.T @ d._basis, compute_uv=False)  # type: ignore[attr-defined]
            if len(s) and s[0] > 0.98:
                c.indistinguishable.append((d.effect, float(s[0]), separation_advice(c.effect, d.effect)))
    for c in out:
        del c._basis  # type: ignore[attr-defined]
    return out, chi2_b, dof_b

