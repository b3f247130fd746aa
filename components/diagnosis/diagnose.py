"""Which physical effect is missing from a model: refit the model with each candidate effect of
the vocabulary added and rank the candidates by a proper test.

All refits share one linearised design (components.diagnosis.candidate_design: the least squares'
block rows at the model's geometry, whitened, compressed to R of their QR), so each candidate costs
a small weighted least-squares solve. For candidate c with k new columns
(the rank they add after projecting out the model's own columns):

    F = (Δχ² / k) / (χ²_c / (n − p_c)),   p = P(F_{k, n−p_c} > F)

p-values are Holm-corrected over the candidates (family-wise error α): a candidate passes when
its adjusted p is below α (ΔBIC = χ²_c − χ²_base + k ln n is reported, not required: as a gate it
cost 5–20 Cramér–Rao σ of detection power). The rows are whitened with the noise model, so
under a correct model the test has its nominal size. Each candidate's theoretical threshold is
reported: per parameter, the magnitude the test detects with 95 % power at the first Holm
level α/m (non-central F), and the magnitude from which it is named first rather than its
closest look-alike (the candidate whose columns take the largest share of its own) in 95 % of
logs (components.diagnosis.detection_thresholds): a pair like acc.k2 and acc.sf_asym on rests at ±1 g and 0 is detected
long before the log can tell which of the two it is.

Stochastic or deterministic: beside the effects, the noise terms the model lacks (components.diagnosis.noise_terms)
(``gyro.noise.bi``, ``gyro.noise.rrw``, ``acc.noise.bi``, ``acc.noise.rrw``) are candidates too,
each fitted by maximum likelihood on the base model's rows. When the best of them explains the
residual better than the best effect (Akaike: Δℓ against the number of parameters) and none of
the best significant effects stays significant both with that term in the noise model and with
each sensor's best noise term — these fitted beside the effect's own columns, so that they do
not take its misfit up as wander — the verdict is that the noise model is too simple, not a
missing effect: a slow wander from bias instability is not called a drift, and a large
systematic misfit that a huge random walk could take up is still called an effect. Forward
selection adds the verdict (an effect, or a noise term to the noise model) and ranks again, so
several are named in turn. Two candidates whose new columns are nearly the same
(largest canonical correlation > 0.98) cannot be told apart on this schedule; the diagnosis says
so and proposes a schedule change that separates them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from components.diagnosis.candidate_design import CandidateDesign
from components.diagnosis.candidate_notes import annotate
from components.diagnosis.noise_terms import NOISE_CANDIDATES, has_term, noise_candidates
from components.diagnosis.ranking import Candidate, rank
from components.diagnosis.taken_for_noise import taken_for_noise
from components.estimation.chunks import CHUNK_SAMPLES
from components.estimation.log_data import LogData
from components.model.effects import EFFECTS, effect_of, parameters_of
from components.model.noise import NoiseModel
from components.model.result import CalibrationResult
from components.model.table_parameters import table_stage

# the significant effects, best first, tried against the noise terms before the verdict is a noise
# term (each costs a fit of the terms and a ranking)
SURVIVAL_CHECKS = 3


@dataclass
class Diagnosis:
    verdict: str | None
    ranking: list[Candidate]
    found: list[str]             # forward selection, in turn (effects and noise terms)
    steps: list[dict]            # per selection step: effect, chi2_per_dof before/after
    base_chi2_per_dof: float
    rows: int
    alpha: float
    noise_candidates: list = field(default_factory=list)  # the first step's noise terms (dicts)
    verdict_kind: str | None = None   # "effect" | "noise" | None
    noise: object = None              # the noise model after the selection (NoiseModel or None)
    # candidates this log cannot see at any plausible magnitude: effect -> the motion it needs
    unseeable: dict = field(default_factory=dict)
    forward: bool = True  # forward selection ran (each passing candidate was re-tested after the verdict)
    # why the noise terms the model lacks were not tested ("" when they were, or it lacks none)
    noise_untested: str = ""
    # the effects named because identified noise had taken them for noise (taken_for_noise)
    taken_for_noise: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {"verdict": self.verdict, "verdict_kind": self.verdict_kind, "found": self.found,
                "ranking": [c.to_json() for c in self.ranking], "steps": self.steps,
                "noise_candidates": self.noise_candidates, "unseeable": dict(self.unseeable),
                "base_chi2_per_dof": self.base_chi2_per_dof, "rows": self.rows, "alpha": self.alpha}


def default_candidates(model_effects: list[str]) -> list[str]:
    """Every effect of the vocabulary the model does not have."""
    return [name for name in EFFECTS if name not in model_effects]


def diagnose(data: LogData, model: CalibrationResult, *, candidates: list[str] | None = None,
             alpha: float = 0.01, forward: bool = True, max_steps: int = 4, chunk_s: float = 1.0,
             rest_angle_sigma=None, noise: NoiseModel | None = None,
             chunk_samples: int = CHUNK_SAMPLES) -> Diagnosis:
    """Which effects of the vocabulary are missing from *model* on *data* (see the module
    docstring). ``noise``: the composite noise model the rows are whitened with (default: the
    model's own; without one, white noise of the level in the data's high-frequency content).
    ``chunk_samples``: the rows are built that many samples at a time (components.estimation.chunks)."""
    if noise is None:
        noise = model.noise_model()
    if rest_angle_sigma is None:
        # how far the table rests from its readings, as the calibration estimated it from the
        # moves (compare takes the same); one count uniform is only that estimate's start
        rest_angle_sigma = model.rest_angle_sigma()
    base_effects = list(model.effects)
    cands = candidates if candidates is not None else default_candidates(base_effects)
    noise_asked = [c for c in cands if c in NOISE_CANDIDATES] if candidates is not None else list(NOISE_CANDIDATES)
    untested = "" if noise_asked else "none among --candidates"
    cands = [c for c in cands if c not in base_effects and c not in NOISE_CANDIDATES]
    params = list(dict.fromkeys(parameters_of(base_effects) + parameters_of(cands)))
    # table-effect parameters for stages this table does not have contribute nothing
    stage_names = set(data.geometry.names)
    params = [p for p in params if effect_of(p).target != "table" or table_stage(p) in stage_names | {None}]
    if data.has_table:
        design = CandidateDesign.on_table_log(data, model, params, chunk_s, rest_angle_sigma, noise, chunk_samples)
    else:
        held = set(model.extra.get("positions", {}).get("held", {}))
        params = [p for p in params if effect_of(p).target != "table" and p not in held]
        if noise_asked:
            # the noise terms' likelihood needs the table log's rows in time (see docs/positions.md)
            untested = "a log without table angles has no rows in time for their likelihood"
        noise_asked = []
        design = CandidateDesign.on_positions_log(data, model, params, chunk_s, noise)
    available = {c: [p for p in EFFECTS[c].parameters if p in design.index] for c in cands}
    base = [p for p in parameters_of(base_effects) if p in design.index] + design.nuisance
    unseeable = _unseeable(design, base, available)
    found: list[str] = []
    steps: list[dict] = []
    first_ranking: list[Candidate] | None = None
    first_noise: list | None = None
    chi2_first = None
    kinds: list[str] = []
    noise_now = noise
    noise_terms = [t for t in noise_asked if not has_term(noise_now, t)]
    taken_records: list = []
    for _ in range(max_steps if forward else 1):
        ranking, chi2_base, dof_base = rank(design, base, available, alpha)
        stochastic = noise_candidates(design, base, noise_now, noise_terms, alpha) if noise_terms else []
        if first_ranking is None:
            first_ranking, chi2_first, first_noise = ranking, chi2_base / dof_base, stochastic
            _draw_signatures(design, base, ranking)
        winner = next((c for c in ranking if c.passes), None)
        best_noise = next((n for n in stochastic if n["significant"]), None)
        effect_gain = (0.5 * max(chi2_base - design.fit(base + available[winner.effect])[0], 0.0)
                       - winner.added_rank) if winner else -math.inf
        noise_wins = best_noise is not None and best_noise["aic_gain"] > max(effect_gain, 0.0)
        if noise_wins and winner is not None:
            # a noise term fitted on a systematic misfit takes it up as a huge wander and can
            # out-gain the effect; a physical effect stays significant with the terms in the
            # noise model, a wander they explain does not. Two checks, both needed: under the
            # best term as fitted (without the effect: a wander it explains leaves no effect;
            # without this check, 2 of 100 navigation-grade null logs under white analysis named
            # acc.drift), and under each sensor's best term (the best alone is often the other
            # sensor's), these fitted beside the effect's columns (fitted without them a term
            # takes the effect's own misfit up as wander: a gyro floor took a real 30 deg/h/h
            # drift, and the effect would never survive)
            surviving = _surviving_effects(design, base, available, alpha, best_noise["model"], noise_now)
            for cand in [c for c in ranking if c.passes and c.effect in surviving][:SURVIVAL_CHECKS]:
                beside = noise_candidates(design, base + available[cand.effect], noise_now, noise_terms, alpha)
                if not any(n["significant"] for n in beside):
                    noise_wins, winner = False, cand
                    break
                if cand.effect in _surviving_effects(design, base, available, alpha,
                                                     _with_best_terms(beside, noise_now), noise_now):
                    noise_wins, winner = False, cand
                    break
        if noise_wins:
            # the residual is better explained by a noise term than by any effect
            found.append(best_noise["term"])
            kinds.append("noise")
            noise_now = best_noise["model"]
            noise_terms.remove(best_noise["term"])
            design.rewhiten(noise_now)
            chi2_after, _, _, rank_after = design.fit(base)
            steps.append({"noise_term": best_noise["term"], "chi2_per_dof_before": chi2_base / dof_base,
                          "chi2_per_dof_after": chi2_after / max(design.n - rank_after, 1),
                          "loglik_gain": best_noise["loglik_gain"]})
            continue
        taken = None
        if winner is None:
            # nothing missing under identified noise may be an effect the identification took
            # for a slow noise term: tested with those terms free beside it
            taken = taken_for_noise(design, base, available, alpha, noise_now, rank)
            if taken is None:
                break
            # its line under the noise the ranking was made with (its p there, not without the terms)
            winner = next((c for c in ranking if c.effect == taken.effect), taken.candidate)
            taken_records.append(taken)
            noise_now = taken.noise
            design.rewhiten(noise_now)
        found.append(winner.effect)
        kinds.append("effect")
        base = base + available.pop(winner.effect)
        chi2_after, _, _, rank_after = design.fit(base)
        steps.append({"effect": winner.effect, "chi2_per_dof_before": chi2_base / dof_base,
                      "chi2_per_dof_after": chi2_after / max(design.n - rank_after, 1),
                      "p_adjusted": winner.p_adjusted, "bic_delta": winner.bic_delta}
                     | ({"taken_for_noise": taken.to_json()} if taken else {}))
        if not available:
            break
    out = Diagnosis(found[0] if found else None, first_ranking or [], found, steps,
                    chi2_first or float("nan"), design.n, alpha,
                    [{k: v for k, v in n.items() if k != "model"} for n in (first_noise or [])],
                    kinds[0] if kinds else None, noise_now, unseeable, forward, untested)
    out.taken_for_noise = taken_records
    for t in taken_records:
        shown = next((c for c in out.ranking if c.effect == t.effect), None)
        if shown is not None and not shown.indistinguishable:
            # its look-alikes, as the ranking without the identified terms found them
            shown.indistinguishable = list(t.candidate.indistinguishable)
    annotate(out)
    return out


def _draw_signatures(design: CandidateDesign, base: list[str], ranking: list[Candidate]) -> None:
    """Each candidate's signature: the base model's whitened residual ("y") against its strongest
    parameter's whitened column times its fitted value ("x"), every column in one pass over the
    rows (the rows are whitened a piece at a time: a pass per ranking would read a long log's
    rows from disk at every step of the selection)."""
    if not ranking:
        return
    resid = design.residual(base)
    columns = design.whitened_columns([c.signature["parameter"] for c in ranking])
    for k, c in enumerate(ranking):
        c.signature.update(x=columns[:, k] * c.signature["value"], y=resid)


def _with_best_terms(stochastic: list, current: NoiseModel | None) -> NoiseModel:
    """The noise model *current* with, for each sensor, its best significant noise term (the
    candidates *stochastic*, best first): what an effect must stay significant under to be
    called one. The best term alone was not enough: an accelerometer random walk out-gains a gyro
    floor, and with it in the model a gyro wander still read as gyro.drift (the verdict on a
    coloured-noise log with no drift under the white default)."""
    best = {}
    for n in stochastic:
        if n["significant"]:
            best.setdefault(n["term"].split(".")[0], n)
    first = next(iter(best.values()))
    chans = [first["model"].channels[k] if "gyro" not in best else best["gyro"]["model"].channels[k]
             for k in range(3)] + \
            [first["model"].channels[k] if "acc" not in best else best["acc"]["model"].channels[k] for k in range(3, 6)]
    terms = " + ".join(n["term"] for n in best.values())
    return NoiseModel(tuple(chans), (current.source + "; " if current is not None else "") + f"+ {terms}",
                      first["model"].sigmas)


def _surviving_effects(design: CandidateDesign, base: list[str], available: dict, alpha: float,
                       with_term: NoiseModel, current: NoiseModel | None) -> list[str]:
    """The effects still significant (Holm), best first, when the rows are whitened with
    *with_term*, the noise model with the candidate noise term; the design is left whitened with
    *current*."""
    design.rewhiten(with_term)
    try:
        ranking, _, _ = rank(design, base, available, alpha)
    finally:
        design.rewhiten(current)
    return [c.effect for c in ranking if c.passes]


def _unseeable(design: CandidateDesign, base: list[str], available: dict) -> dict:
    """Each candidate keeps the parameters this log determines beyond the model's own columns
    (components.estimation.determinability, in the vocabulary's order: one the log cannot tell
    from the model's and the candidate's earlier ones, or whose σ would exceed anything a real IMU
    has, is dropped, so no candidate shows a pseudo-inverse's value). An effect with none left is
    returned (effect -> the motion it needs): the log cannot see it, so it is not tested."""
    from components.estimation.determinability import undetermined_columns
    from components.model.excitation import needs
    from components.model.plausibility import plausible_limit

    nuis = [design.index[p] for p in base]
    out = {}
    for effect, ps in list(available.items()):
        cols = [design.index[p] for p in ps]
        J = design.compressed[:, cols + nuis]  # its columns' inner products are the whitened rows'
        undet = set(undetermined_columns(J, list(range(len(cols))), list(range(len(cols), len(cols) + len(nuis))),
                                         limits=np.array([plausible_limit(p) for p in ps])))
        seen = [p for k, p in enumerate(ps) if k not in undet]
        if seen:
            available[effect] = seen
        else:
            out[effect] = needs(ps[0]) if ps else "parameters this table does not have"
            del available[effect]
    return out
