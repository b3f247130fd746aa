"""Effects an identified noise model took for noise.

Noise identified on a model's residual takes up whatever slow misfit the model leaves, and an
effect that changes slowly over the log is such a misfit — a temperature coefficient on a single
ramp, a drift: the identification calls it a random walk or a bias-instability floor, the effect
is not significant under that noise, and diagnose said nothing was missing. On a 36-minute MEMS
log with 20 ug/K on acc_z under a 22 K ramp, acc_z's random walk came out 176 ug/√h [94, 337]
and acc.temp.z 16 ± 6.6 ug/K (2.4 σ).

Whether the effect is there is a question about both at once: its likelihood ratio with the
slow terms free under both hypotheses, not held where the fit without the effect put them,

    LR = 2 [ max_q ℓ(model + effect, q) − max_q ℓ(model, q) ]
       = max_q { Δχ²(q) − 2 [ℓ*(model) − ℓ(model, q)] },

q over the noise as identified and the noise without the identified slow terms plus each
sensor's best one of them refitted (components.diagnosis.noise_terms) — on the model's rows, and
beside the effect's columns. ℓ is the ordinary likelihood of the channels' rows, the columns
profiled out; Δχ²(q) the effect's on the whitened design. The effects tried are those
significant under the noise without the identified slow terms, best first; the first whose LR
exceeds the χ² point of its added rank at α over the number of candidates (Bonferroni) is named,
and the selection goes on under the q that explains it best. On the ramp log: LR 78.8 against
17.7, acc.temp named (with acc.drift, its twin on a ramp). On the same MEMS run without the ramp
(K2 added, nothing missing): at most 8.3 against 17.3.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from components.diagnosis.noise_terms import ChannelRows, loglik, refit_terms
from components.estimation.distributions import chi2_isf
from components.estimation.noise_likelihood import SLOW
from components.model.noise import NoiseModel, sensor_of, sensor_term_name, term_name

# the effects significant without the identified slow terms, best first, tried (each costs a fit
# of the terms beside its columns and a whitening of the design)
TRIED = 3


@dataclass
class TakenForNoise:
    effect: str
    candidate: object          # its Candidate in the ranking without the identified slow terms
    likelihood_ratio: float
    critical: float
    terms: dict                # slow term with its axis -> magnitude refitted on the model's rows (SI)
    terms_beside: dict         # the same beside the effect's columns
    noise: NoiseModel          # the noise the selection goes on under
    significant_without: list  # the effects significant without the identified slow terms

    def to_json(self) -> dict:
        return {"effect": self.effect, "likelihood_ratio": self.likelihood_ratio, "critical": self.critical,
                "slow_terms": self.terms, "slow_terms_beside": self.terms_beside,
                "noise_after": self.noise.source}


def _identified(noise: NoiseModel, k: int, term: str) -> bool:
    """Channel *k* of *noise* has the slow *term*, identified by likelihood: it has a profile
    interval (a term given by hand has none)."""
    return getattr(noise.channels[k], term) > 0 and term_name(k, term) in noise.intervals


def identified_slow_terms(noise: NoiseModel | None) -> list[str]:
    """The slow terms (vocabulary names, ``acc.noise.rrw``) identified on some axis of *noise*."""
    if noise is None:
        return []
    return sorted({sensor_term_name(k, t) for k in range(6) for t in SLOW
                   if _identified(noise, k, t)})


def without_identified(noise: NoiseModel) -> NoiseModel:
    """*noise* without the slow terms it identified (what was given by hand stays)."""
    chans = [replace(c, **{t: 0.0 for t in SLOW if _identified(noise, k, t)})
             for k, c in enumerate(noise.channels)]
    return NoiseModel(tuple(chans), noise.source + "; without its identified slow terms", noise.sigmas)


def taken_for_noise(design, base: list[str], available: dict, alpha: float, noise: NoiseModel,
                    rank) -> TakenForNoise | None:
    """The first effect of *available* that the identified slow terms of *noise* took for noise
    (see the module docstring), or None; *rank*: the diagnosis's ranking
    (components.diagnosis.ranking.rank). The design is left whitened with *noise*."""
    terms = identified_slow_terms(noise)
    if not terms:
        return None
    without = without_identified(noise)
    channels = [k for k in range(6) if any(t.startswith(sensor_of(k) + ".") for t in terms)]
    rows_of = ChannelRows(design, base)
    refitted = refit_terms(rows_of, noise, terms)
    # the noise models compared, with ℓ of the model's rows under each
    models = {"identified": noise, "refitted": replace(refitted, source=noise.source + "; slow terms refitted")}
    ell = {name: loglik(rows_of, q, channels) for name, q in models.items()}
    best = max(ell.values())
    try:
        design.rewhiten(without)
        ranking, _, _ = rank(design, base, available, alpha)
        tried = [c for c in ranking if c.passes][:TRIED]
        if not tried:
            return None
        dchi2 = {}
        for name, q in models.items():
            design.rewhiten(q)
            chi2_base = design.fit(base)[0]
            dchi2[name] = {c.effect: chi2_base - design.fit(base + available[c.effect])[0] for c in tried}
        for c in tried:
            cols = base + available[c.effect]
            q_b = refit_terms(ChannelRows(design, cols), refitted, terms)
            q_b = replace(q_b, source=noise.source + f"; slow terms refitted beside {c.effect}")
            design.rewhiten(q_b)
            chi2_b = design.fit(base)[0] - design.fit(cols)[0]
            ell_b = loglik(rows_of, q_b, channels)
            lrs = {name: dchi2[name][c.effect] - 2 * (best - ell[name]) for name in models}
            lrs["beside"] = chi2_b - 2 * (best - ell_b)
            critical = chi2_isf(alpha / len(ranking), c.added_rank)
            name = max(lrs, key=lrs.get)
            if lrs[name] > critical:
                return TakenForNoise(c.effect, c, float(lrs[name]), float(critical),
                                     _magnitudes(refitted, terms), _magnitudes(q_b, terms),
                                     q_b if name == "beside" else models[name],
                                     [d.effect for d in ranking if d.passes])
        return None
    finally:
        design.rewhiten(noise)


def _magnitudes(noise: NoiseModel, terms: list[str]) -> dict:
    """Each channel's magnitude of *terms* (term name with its axis -> SI value)."""
    out = {}
    for k, c in enumerate(noise.channels):
        for t in SLOW:
            if sensor_term_name(k, t) in terms:
                out[term_name(k, t)] = float(getattr(c, t))
    return out
