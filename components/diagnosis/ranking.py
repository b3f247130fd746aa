"""The candidates of a diagnosis ranked by a proper test: each candidate effect refitted beside
the model's columns on the shared whitened design (components.diagnosis.candidate_design),

    F = (Δχ² / k) / (χ²_c / (n − p_c)),   p = P(F_{k, n−p_c} > F),

Holm-corrected over the candidates (family-wise error α), with what makes a value no estimate
(implausible, unidentifiable), the look-alikes it cannot be told from and its theoretical
detection thresholds (components.diagnosis.detection_thresholds)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from components.diagnosis.candidate_design import CandidateDesign
from components.diagnosis.candidate_notes import separation_advice
from components.diagnosis.detection_thresholds import theoretical_thresholds
from components.estimation.distributions import f_logsf
from components.model.effects import EFFECTS
from components.model.plausibility import expected_magnitude, plausible_limit

# candidates whose new columns have a canonical correlation above this cannot be told apart on
# the schedule (the ranking says so and how to separate them)
TWINS = 0.98


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
    unidentifiable: list = field(default_factory=list)  # parameters with σ beyond the physical range
    limits: dict = field(default_factory=dict)  # parameter -> the magnitude beyond which it is implausible
    aic_gain: float = 0.0  # Δχ²/2 − k: what the effect gains by Akaike (compared with a noise term's)
    status: str = ""  # candidate_notes.annotate: verdict, implausible, unidentifiable, ...
    why: str = ""     # the sentence that explains the status
    correlated: list = field(default_factory=list)  # [(param, other param, rho)] within the fit
    signature: dict | None = None
    threshold: dict = field(default_factory=dict)  # parameter -> magnitude detected with 95 % power
    # parameter -> (magnitude named first, not the closest look-alike, with 95 % probability — at
    # least the threshold —, that look-alike, the cosine between them)
    naming: dict = field(default_factory=dict)

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
                "implausible": list(self.implausible), "unidentifiable": list(self.unidentifiable),
                "status": self.status, "why": self.why,
                "threshold": dict(self.threshold),
                "threshold_display": {p: v / scale for p, v in self.threshold.items()},
                # null: never named first on this schedule (its look-alike is a twin)
                "naming_threshold": {p: {"value": v if math.isfinite(v) else None,
                                         "display": v / scale if math.isfinite(v) else None,
                                         "look_alike": o, "cosine": r}
                                     for p, (v, o, r) in self.naming.items()}}


# a log without table angles: the rests' attitudes are estimated, so the rows see an effect only
# through what an attitude cannot take up (at rest the specific force's magnitude)
POSITIONS_TWINS = ("the rests' attitudes are estimated on a log without table angles, so only what a tilt cannot "
                   "take up (at rest the specific force's magnitude) tells effects apart, and more tilts may not: "
                   "log the table angles; with known attitudes: ")


def rank(design: CandidateDesign, base: list[str], available: dict, alpha: float):
    chi2_b, _, _, rank_b = design.fit(base)
    dof_b = max(design.n - rank_b, 1)
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
        logp = float(f_logsf(F, k, dof_c))
        sig = np.sqrt(np.clip(np.diag(cov), 0, None))
        values = dict(zip(base + ps, zip(sol.tolist(), sig.tolist())))
        # a fitted magnitude far outside anything physical means the linearised model is being
        # used to absorb something else (table angles beyond the small-angle range, or a
        # near-degenerate column): such a candidate is reported but cannot be the verdict.
        # Sensor effects are linear in their parameters, so only an absurd value is suspect:
        # beyond what a real IMU of any grade has (plausibility.py), or 1e5 times the magnitude
        # typical of the log's grade (a drift or temperature coefficient must be far above it
        # to show in a short run; a tactical log's noise, 100 times a navigation grade's, lets
        # through 100 times more). Table effects are small angles: 1000 times their typical.
        if EFFECTS[effect].target == "table":
            limits = {p: min(plausible_limit(p), max(1000 * EFFECTS[effect].typical, 0.01)) for p in ps}
        else:
            limits = {p: min(plausible_limit(p), 1e5 * expected_magnitude(p, design.grade)) for p in ps}
        implausible = [p for p in ps if abs(values[p][0]) > limits[p]]
        cand = Candidate(effect, float(F), math.exp(logp), 1.0,
                         float(chi2_c - chi2_b + k * math.log(design.n)),
                         float(dchi2 / chi2_b) if chi2_b > 0 else 0.0, k,
                         {p: values[p] for p in ps})
        # a σ wider than the physical range: the log does not bound the parameter, its value is a guess
        cand.unidentifiable = [p for p in ps if p not in implausible and values[p][1] > plausible_limit(p)]
        cand.aic_gain = 0.5 * dchi2 - k
        cand.limits = limits
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
        # signature: the strongest new parameter, its regressor drawn against the base's residual
        # for the first ranking only (_draw_signatures)
        best = max(ps, key=lambda p: abs(values[p][0]) / (values[p][1] or np.inf))
        cand.signature = {"parameter": best, "value": values[best][0]}
        out.append(cand)
    # Holm correction over the candidates, ranking by evidence
    out.sort(key=lambda c: (c._logp, -c.statistic))  # type: ignore[attr-defined]
    m = len(out)
    running = 0.0
    for i, c in enumerate(out):
        adj = min(1.0, (m - i) * math.exp(c._logp))  # type: ignore[attr-defined]
        running = max(running, adj)
        c.p_adjusted = running
        c.passes = c.p_adjusted < alpha and not c.implausible and not c.unidentifiable
    # candidates that cannot be told apart from a passing one
    for c in out[:6]:
        if not c.passes:
            continue
        for d in out:
            if d is c or d.explained_fraction < 0.5 * c.explained_fraction:
                continue
            s = np.linalg.svd(c._basis.T @ d._basis, compute_uv=False)  # type: ignore[attr-defined]
            if len(s) and s[0] > TWINS:
                advice = separation_advice(c.effect, d.effect, c.signature["parameter"], d.signature["parameter"])
                if design.nuisance:
                    advice = POSITIONS_TWINS + advice
                c.indistinguishable.append((d.effect, float(s[0]), advice))
    theoretical_thresholds(out, design, base, available, alpha)
    for c in out:
        del c._basis  # type: ignore[attr-defined]
    # what is shown first is what could be an estimate: implausible and unidentifiable candidates
    # go below the others (the order among each group stays by evidence)
    out.sort(key=lambda c: bool(c.implausible or c.unidentifiable))
    return out, chi2_b, dof_b
