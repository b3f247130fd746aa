"""The JSON summary: counts, every case's verdict (sorted by case id), the requirement ->
criteria -> cases -> verdict traceability, and the regression verdict of the [expected] block."""
from __future__ import annotations

import json


def expectation(camp, case, rec: dict | None) -> dict | None:
    exp = camp.expected_for(case)
    if exp is None:
        return None
    got = None if rec is None else rec["verdict"]
    ok = got == exp["verdict"] and (exp.get("reason") is None or exp["reason"] in (rec or {}).get("reason") or "")
    return {**exp, "got": got, "ok": bool(ok)}


def traceability(camp, records: dict) -> list[dict]:
    """Per requirement: its criteria, each with the cases it applies to and their outcome."""
    out = {}
    for crit in camp.criteria:
        req = out.setdefault(crit.requirement, {"requirement": crit.requirement, "criteria": []})
        cases = []
        for case in camp.cases:
            if not crit.applies(case.procedure, case.system):
                continue
            rec = records.get(case.id)
            res = None
            if rec is not None:
                res = next((r for r in rec["criteria"] if r["id"] == crit.id), None)
            outcome = ("missing" if rec is None else "error" if rec["verdict"] == "error"
                       else "n/a" if res and res.get("applicable") is False
                       else "pass" if res and res["passed"] else "fail")
            cases.append({"case": case.id, "outcome": outcome})
        counts = {k: sum(c["outcome"] == k for c in cases) for k in ("pass", "fail", "error", "missing", "n/a")}
        judged = [c for c in cases if c["outcome"] != "n/a"]
        verdict = ("fail" if counts["fail"] else "error" if counts["error"] else
                   "incomplete" if counts["missing"] else "pass" if judged else
                   "not applicable" if cases else "no case")
        req["criteria"].append({"id": crit.id, "kind": crit.kind, "description": crit.description,
                                "cases": cases, "counts": counts, "verdict": verdict})
    for req in out.values():
        vs = [c["verdict"] for c in req["criteria"]]
        req["verdict"] = next((v for v in ("fail", "error", "incomplete", "no case") if v in vs),
                              "not applicable" if vs and all(v == "not applicable" for v in vs) else "pass")
    return [out[k] for k in sorted(out)]


def summarize(camp, records: dict, sessions: list | None = None) -> dict:
    rows = []
    for case in camp.cases:
        rec = records.get(case.id)
        rows.append({"id": case.id, "procedure": case.procedure, "system": case.system, "grid": case.grid,
                     "replicate": case.replicate, "seed": case.seed,
                     "verdict": None if rec is None else rec["verdict"],
                     "reason": None if rec is None else rec.get("reason"),
                     "expected": expectation(camp, case, rec)})
    counts = {k: sum(r["verdict"] == k for r in rows) for k in ("pass", "fail", "error")}
    counts["missing"] = sum(r["verdict"] is None for r in rows)
    counts["total"] = len(rows)
    exp = None
    if camp.expected is not None:
        bad = [r["id"] for r in rows if not r["expected"]["ok"]]
        exp = {"ok": not bad, "mismatches": bad}
    return {"format": "calbench-campaign-summary/1", "campaign": camp.name, "counts": counts,
            "complete": counts["missing"] == 0, "all_passed": counts["pass"] == counts["total"],
            "expected": exp, "requirements": traceability(camp, records), "cases": rows}


def dumps(summary: dict) -> str:
    return json.dumps(summary, indent=1, sort_keys=True) + "\n"
