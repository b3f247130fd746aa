"""Acceptance criteria judged on one case's numbers (estimates against truth, chi2/dof, CRB,
diagnosis verdict). Each outcome carries the criterion id and the requirement it verifies."""
from __future__ import annotations

import math

from components.campaign.spec import match_parameters, parse_value


def _fmt(x: float, unit_scale: tuple) -> str:
    unit, scale = unit_scale
    return f"{x / scale:.4g} {unit}".strip()


def _display(p: str) -> tuple:
    from components.model.effects import effect_of

    e = effect_of(p)
    return e.display if e.display[0] else (e.unit, 1.0)


def evaluate(criterion: dict, numbers: dict) -> dict:
    """``criterion``: Criterion.to_dict(); ``numbers``: {"estimates": {p: {value, sigma, truth,
    error, crb}}, "chi2_per_dof", "diagnosis"}. -> {id, requirement, kind, passed, message}."""
    kind = criterion["kind"]
    out = {"id": criterion["id"], "requirement": criterion["requirement"], "kind": kind}
    est = numbers.get("estimates", {})
    if kind in ("estimate", "crb"):
        names = match_parameters(criterion["parameters"], sorted(est))
        if not names:
            return {**out, "passed": False,
                    "message": f"no estimated parameter matches {criterion['parameters']}"}
        bad = []
        worst = 0.0
        for p in names:
            e = est[p]
            if kind == "crb":
                limit = parse_value(p, criterion["max"], f"criterion {criterion['id']} max")
                crb = e.get("crb")
                if crb is None or not math.isfinite(crb) or crb > limit:
                    bad.append(f"{p}: CRB sigma {_fmt(crb, _display(p)) if crb is not None else 'n/a'} > "
                               f"{_fmt(limit, _display(p))}")
                worst = max(worst, (crb or math.inf) / limit if limit > 0 else math.inf)
                continue
            err = abs(e["error"])
            limits = []
            if "tolerance" in criterion:
                limits.append(("tolerance", parse_value(p, criterion["tolerance"],
                                                        f"criterion {criterion['id']} tolerance")))
            if "crb_sigmas" in criterion:
                crb = e.get("crb")
                limits.append((f"{criterion['crb_sigmas']:g} CRB sigma",
                               criterion["crb_sigmas"] * crb if crb is not None and math.isfinite(crb) else -1.0))
            if "sigmas" in criterion:
                s = e.get("sigma")
                limits.append((f"{criterion['sigmas']:g} sigma",
                               criterion["sigmas"] * s if s is not None and math.isfinite(s) else -1.0))
            for what, lim in limits:
                if not err <= lim:
                    bad.append(f"{p}: |error| {_fmt(err, _display(p))} > {what} "
                               f"({_fmt(lim, _display(p)) if lim >= 0 else 'n/a'})")
                if lim > 0:
                    worst = max(worst, err / lim)
        if bad:
            return {**out, "passed": False, "message": "; ".join(bad), "worst_ratio": worst}
        return {**out, "passed": True, "message": f"{len(names)} parameter(s) within limits "
                                                  f"(worst at {100 * worst:.0f}% of its limit)",
                "worst_ratio": worst}
    if kind == "chi2":
        c = numbers.get("chi2_per_dof")
        lo = criterion.get("min", -math.inf)
        ok = c is not None and math.isfinite(c) and lo <= c <= criterion["max"]
        rng = f"[{lo:g}, {criterion['max']:g}]" if "min" in criterion else f"<= {criterion['max']:g}"
        return {**out, "passed": ok, "message": f"chi2/dof = {c:.4g}, expected {rng}" if c is not None
                else "chi2/dof not computed"}
    verdict = numbers.get("diagnosis")
    got = "none" if verdict is None else verdict
    ok = got == criterion["verdict"]
    return {**out, "passed": ok, "message": f"diagnosis verdict {got!r}, expected {criterion['verdict']!r}"}
