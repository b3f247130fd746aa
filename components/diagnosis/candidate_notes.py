"""What a person reads about each candidate of a diagnosis, so no line shows a nonsense number
as an estimate and no line contradicts the verdict.

Each candidate gets a ``status`` and a ``why``:

- ``verdict``: the effect named missing.
- ``also significant``: passes the test but ranks below the verdict (forward selection names
  it in turn if it is still significant once the verdict is in the model).
- ``implausible``: a parameter fitted beyond anything a real IMU or table has
  (components.model.plausibility), or beyond the diagnosis's own limit: the linearised model is
  absorbing something else, so its value is not shown as an estimate.
- ``unidentifiable``: a parameter the log bounds no better than the plausible range (σ beyond
  the plausible limit): its value is a guess, not shown either.
- ``noise explains it``: significant, but a noise term the model lacks explains the residual
  better (the verdict is then the noise model).
- ``not significant``: its Holm-adjusted p is at or above α.

Two candidates that cannot be told apart get advice that separates them: the motion each
parameter needs (components.model.excitation), or the schedule change known for that pair.
"""
from __future__ import annotations

import math

from components.model.effects import EFFECTS, effect_of
from components.model.excitation import needs
from components.model.plausibility import plausible_limit

# Which schedule change separates two effects (order-free pairs): the change that moves one
# and leaves the other.
SEPARATE = {
    frozenset({"acc.temp", "acc.drift"}): "make the temperature non-monotonic in time (a heat/cool cycle), so temperature and elapsed time differ",
    frozenset({"gyro.temp", "gyro.drift"}): "make the temperature non-monotonic in time (a heat/cool cycle), so temperature and elapsed time differ",
    frozenset({"acc.k2", "acc.sf_asym"}): "rest the axis at more tilts between 0 and 1 g (±30°, ±45°, ±60°): K2 grows with f² (half at 45°), the asymmetry with |f| (0.71 at 45°): more levels of |f|, and longer rests at the intermediate ones, lower their correlation",
    frozenset({"acc.k2", "acc.bias"}): "add positions with the axis horizontal and at ±45°: K2 vanishes at 0 g, a bias does not",
    frozenset({"acc.k3", "acc.sf"}): "add ±45° positions: K3 scales with f³, the scale factor with f",
    frozenset({"table.base_tilt", "acc.mis"}): "index the outer (azimuth) axis through 0/90/180/270° (seed 000): a base tilt turns with the outer axis, a misalignment does not",
    frozenset({"table.base_tilt", "acc.bias"}): "index the outer axis through 0/90/180/270°: a tilt reverses sign between opposite positions",
    frozenset({"gyro.sf_asym", "gyro.bias"}): "rotate at two different rates in both directions",
    frozenset({"acc.lever", "acc.k2"}): "rotate at two rates about each axis: the lever term grows with ω², K2 does not change with rate",
    frozenset({"imu.time_offset", "acc.lever"}): "index with different accelerations: the time offset follows df/dt, the tangential lever term ω̇",
    frozenset({"acc.time_offset", "acc.lever"}): "index with different accelerations: the time offset follows df/dt, the tangential lever term ω̇",
    frozenset({"imu.time_offset", "acc.time_offset"}): "the gyro rows here are rest-to-rest sums, which no time shift changes, so both move only the accelerometer rows: the system-level filter (calbench kf) separates them — a late accelerometer against the gyros shows in the navigation velocity, the whole IMU late against the table does not",
    frozenset({"table.encoder", "table.reversal"}): "reach the same rests from both sides (index back and forth): a reversal error changes with the side of approach, an encoder error only with the angle",
    frozenset({"table.base_azimuth", "table.nonorth"}): "no schedule separates them while the IMU's misalignments are fitted (a heading is the middle stage's axis turned about up together with a turn of the IMU the misalignments take up): survey the table's heading (or give it in the outer angles' zero), or hold the misalignments known from another calibration",
    frozenset({"table.nonorth", "table.wobble"}): "mount the IMU a second way on the plate (turned 90° about the inner axis) and turn each stage through full turns: a wobble is a tilt that turns with its stage and changes with the mounting, a non-orthogonality is fixed between the axes",
}


def separation_advice(a: str, b: str, pa: str | None = None, pb: str | None = None) -> str:
    """How to tell effect *a* from effect *b* (their strongest parameters *pa*, *pb*): the known
    schedule change for the pair, else the motion each needs that the other does not."""
    key = frozenset({a, b})
    if key in SEPARATE:
        return SEPARATE[key]
    na = needs(pa or EFFECTS[a].parameters[0])
    nb = needs(pb or EFFECTS[b].parameters[0])
    if na == nb:
        return (f"both need {na}, and on this schedule their columns coincide: vary what one depends on "
                f"and the other does not ({a}: {EFFECTS[a].description}; {b}: {EFFECTS[b].description})")
    return f"{a} is seen by {na}, {b} by {nb}: add the motion one has and the other lacks"


def display(parameter: str, value: float, sigma: float) -> str:
    e = effect_of(parameter)
    unit, scale = e.display
    return f"{parameter} = {value / scale:+.4g} ± {sigma / scale:.2g} {unit}"


def limit_text(parameter: str, limit: float | None = None) -> str:
    e = effect_of(parameter)
    unit, scale = e.display
    return f"{(plausible_limit(parameter) if limit is None else limit) / scale:.3g} {unit}"


def annotate(diagnosis) -> None:
    """Set ``status`` and ``why`` on every candidate of *diagnosis* (see the module docstring)."""
    alpha = diagnosis.alpha
    noise_verdict = diagnosis.verdict if diagnosis.verdict_kind == "noise" else None
    noise_gain = next((n["aic_gain"] for n in diagnosis.noise_candidates if n["term"] == noise_verdict), None)
    for c in diagnosis.ranking:
        if c.implausible:
            p = c.implausible[0]
            c.status = "implausible"
            c.why = (f"{p} would be {display(p, *c.parameters[p]).split(' = ', 1)[1]}, beyond the plausible range "
                     f"(limit {limit_text(p, c.limits.get(p))}): the linearised model absorbs something else here (angles beyond "
                     "the small-angle range, a near-degenerate column, or a wrong input); not an estimate")
        elif c.unidentifiable:
            p = c.unidentifiable[0]
            c.status = "unidentifiable"
            c.why = (f"this log bounds {p} only to ± {display(p, *c.parameters[p]).split(' ± ', 1)[1]}, wider "
                     f"than any real IMU's range ({limit_text(p)}): its value is a guess; it needs {needs(p)}")
        elif c.effect == diagnosis.verdict and diagnosis.verdict_kind == "effect":
            c.status, c.why = "verdict", ""
        elif c.passes and c.effect in diagnosis.found:
            c.status = "also significant"
            c.why = f"found in turn once {', '.join(diagnosis.found[:diagnosis.found.index(c.effect)])} is in the model"
        elif c.passes and noise_verdict:
            c.status = "noise explains it"
            c.why = (f"the noise term {noise_verdict} explains the residual better (Akaike gain {noise_gain:.4g} "
                     f"against {c.aic_gain:.4g})" + ("; forward selection, with it in the noise model, did "
                                                     "not name this effect" if diagnosis.forward else ""))
        elif c.passes:
            c.status = "also significant"
            c.why = (f"significant on its own; forward selection, with {', '.join(diagnosis.found)} in the model, "
                     "did not name it" if diagnosis.forward else
                     f"significant on its own; {diagnosis.verdict} explains more (add it and diagnose again to see "
                     "whether this one remains)")
        else:
            c.status, c.why = "not significant", f"Holm-adjusted p ≥ α = {alpha}"


def strongest(c) -> str:
    """The candidate's parameter fitted at the most σ from zero (the one its line shows)."""
    return max(c.parameters, key=lambda p: abs(c.parameters[p][0]) / (c.parameters[p][1] or float("inf")))


def magnitude_text(c) -> str:
    """The candidate's strongest parameter as an estimate, or why it is not one."""
    if c.status in ("implausible", "unidentifiable"):
        return f"{c.status} (not an estimate)"
    best = strongest(c)
    return display(best, *c.parameters[best])


LEGEND = ("* significant (Holm-adjusted p < α) and plausible; ! not an estimate (implausible or unidentifiable: "
          "its note says why); ~ significant, but a missing noise term explains it better")
RANKING_HEADER = (f"{'rank':4s} {'effect':16s} {'F':>10s} {'p (Holm)':>10s} {'dBIC':>10s} {'explains':>8s}  magnitude"
                  "  [95 % detection threshold]")
# the mark after the rank: the verdict and what passes the test, what is significant but cannot
# be an estimate, and the rest
MARKS = {"verdict": "*", "also significant": "*", "implausible": "!", "unidentifiable": "!",
         "noise explains it": "~"}


def ranking_line(i: int, c) -> str:
    """One console line of the ranking; implausible and unidentifiable candidates show their
    status instead of a value."""
    thr = ""
    if c.status not in ("implausible", "unidentifiable") and c.threshold:
        best = strongest(c)
        if best in c.threshold:
            unit, scale = effect_of(best).display
            thr = f"  [{c.threshold[best] / scale:.2g}]"
    mark = MARKS.get(c.status, " ")
    return (f"{i:3d}{mark} {c.effect:16s} {c.statistic:10.3g} {c.p_adjusted:10.2g} {c.bic_delta:10.4g} "
            f"{100 * c.explained_fraction:7.1f}%  {magnitude_text(c)}{thr}")


def candidate_notes_lines(c) -> list[str]:
    """The why of a candidate's status (when there is one to say) and its look-alikes."""
    out = []
    if c.status in ("implausible", "unidentifiable", "noise explains it", "also significant") and c.why:
        out.append(f"{c.status}: {c.why}")
    for other, rho, advice in c.indistinguishable:
        out.append(f"cannot be told apart from {other} on this schedule (correlation {rho:.3f}): {advice}")
    if c.status in ("verdict", "also significant") and c.naming and not c.indistinguishable:
        best = strongest(c)
        naming, rival, rho = c.naming.get(best, (0.0, None, 0.0))
        if rival and math.isfinite(naming) and abs(c.parameters[best][0]) < naming \
                and naming > 1.1 * c.threshold.get(best, 0.0):
            unit, scale = effect_of(best).display
            out.append(f"its look-alike {rival} (cosine {rho:.2f}) could be the one at this magnitude: this log "
                       f"names the right one of the two in 95 % of cases from {naming / scale:.2g} {unit} "
                       f"({naming / c.threshold[best]:.1f} x the detection threshold); add both and compare, or "
                       f"run a schedule that separates them")
    return out


def verdict_lines(d) -> list[str]:
    """The verdict, and — when candidates with p < α are not it — which and why, so the verdict
    never contradicts the table above it."""
    found = f"; in turn: {', '.join(d.found)}" if len(d.found) > 1 else ""
    if d.verdict is None:
        lines = ["verdict: no significant effect is missing and the noise model suffices" if not d.noise_untested
                 else f"verdict: no significant effect is missing (the noise terms the model lacks were not tested: "
                      f"{d.noise_untested})"]
    elif d.verdict_kind == "noise":
        lines = [f"verdict: the noise model is too simple: {d.verdict} explains the residual better than any "
                 "effect (a stochastic term, not a missing effect; add it with `calbench add --effect "
                 f"{d.verdict}`){found}"]
    else:
        lines = [f"verdict: {d.verdict} is missing{found}"]
        top = next((c for c in d.ranking if c.effect == d.verdict), None)
        # significant: under the noise the ranking was made with, or without the identified slow
        # terms that had taken the verdict for noise
        significant = {o.effect for o in d.ranking if o.p_adjusted < d.alpha} | \
            {e for t in d.taken_for_noise if t.effect == d.verdict for e in t.significant_without}
        twins = [(e, r) for e, r, _ in (top.indistinguishable if top else []) if e in significant]
        if twins:
            # which of them is first is chance on this log: the verdict must not pretend to know
            lines[0] = (f"verdict: {d.verdict} or {' or '.join(e for e, _ in twins)} is missing: this log cannot "
                        f"tell them apart (correlation {max(r for _, r in twins):.3f}), so which comes first is "
                        f"chance; see the ranking's notes for the motion that separates them{found}")
    lines += [taken_line(t) for t in d.taken_for_noise]
    kinds = ["noise" if "noise_term" in st else "effect" for st in d.steps]
    if "effect" in kinds and "noise" in kinds[kinds.index("effect") + 1:]:
        # the ranking above was made under a noise model the log then showed too simple: a
        # look-alike can win there by the wander's misfit (acc.sf_asym for a K2 under bias instability)
        late = [f for f, k in zip(d.found, kinds) if k == "noise"]
        lines.append(f"   the effects were ranked under a noise model this log shows too simple ({', '.join(late)} found "
                     "after them): rank them again with the noise identified (--noise identify, or add "
                     f"{late[0]} first) before taking the order of look-alikes as found")
    # (the ones named in turn after the verdict are named above: not listed again as "not the verdict")
    others = [c for c in d.ranking if c.p_adjusted < d.alpha and c.status != "verdict" and c.effect not in d.found]
    if others:
        by = {}
        for c in others:
            by.setdefault(c.status, []).append(c.effect)
        lines.append(f"   {len(others)} other candidate(s) with p < α = {d.alpha} are not the verdict: "
                     + "; ".join(f"{s}: {', '.join(es)}" for s, es in by.items()) + " (each line says why)")
    return lines


def taken_line(t) -> str:
    """Why an effect not significant under the identified noise is named
    (components.diagnosis.taken_for_noise): the slow terms it had been taken for, as refitted
    without and beside it, and its likelihood ratio with them free under both."""
    from components.estimation.noise_likelihood import SLOW
    from components.model.noise import CHANNELS, TERMS, sensor_of, term_name

    moved = []
    for k in range(6):
        for term in SLOW:
            name = term_name(k, term)
            if name not in t.terms:
                continue
            before, after = t.terms[name], t.terms_beside.get(name, t.terms[name])
            if abs(after - before) > 0.1 * max(abs(before), abs(after)):
                _, _, unit, scale = TERMS[sensor_of(k)][term]
                moved.append(f"{CHANNELS[k]}'s {term.replace('_', ' ')} {before / scale:.3g} -> {after / scale:.3g} {unit}")
    return (f"   {t.effect} is not significant under the identified noise, which had taken it for noise: refitted "
            f"beside it, {'; '.join(moved) or 'the slow terms change little'}; its likelihood ratio with the slow "
            f"terms free under both is {t.likelihood_ratio:.3g} against {t.critical:.3g} (χ² of its rank at α over the "
            "candidates)")
