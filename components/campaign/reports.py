"""Write every report of a campaign from its output folder: summary.json, junit.xml,
report.html and the compare/diagnose pages of the worst cases (re-run in this process: a case
is deterministic, so its page shows the very log and model its record judged)."""
from __future__ import annotations

from pathlib import Path

from components.campaign.html import render
from components.campaign.junit import junit_xml
from components.campaign.spec import task_for
from components.campaign.store import Store, atomic_write
from components.campaign.summary import dumps, summarize


def worst_cases(camp, records: dict, n: int = 5) -> list[dict]:
    """The n non-passing or nearest-to-failing cases: errors first, then by the largest ratio of a
    criterion's quantity to its limit."""
    out = []
    for case in camp.cases:
        rec = records.get(case.id)
        if rec is None:
            continue
        if rec["verdict"] == "error":
            out.append({"id": case.id, "verdict": "error", "score": float("inf"), "why": rec["reason"]})
            continue
        ratios = [(r.get("worst_ratio", 0.0 if r["passed"] else float("inf")), r) for r in rec["criteria"]
                  if r.get("applicable", True)]
        if not ratios:
            continue
        score, r = max(ratios, key=lambda t: t[0])
        out.append({"id": case.id, "verdict": rec["verdict"], "score": score,
                    "why": f"{r['id']} [{r['requirement']}]: {r['message']}"})
    out.sort(key=lambda w: (-w["score"], w["id"]))
    return out[:n]


def case_page(camp, case_id: str, out: Path) -> Path:
    """<out>/pages/<case id>.html: the components.diagnosis.report page of the case (compare + diagnose)."""
    from components.campaign.case import numbers_of
    from components.diagnosis.diagnose import diagnose
    from components.diagnosis.report import build_report

    case = camp.case(case_id)
    task = task_for(camp, case)
    numbers, data, model, comp = numbers_of(task)
    diag = diagnose(data, model, forward=False)
    prov = {"campaign": camp.name, "case": case.key(), "procedure": task["procedure"], "truth": task["truth"],
            "fmus": numbers["fmus"]}
    html_path, _ = build_report(out / "pages" / case_id, title=f"campaign {camp.name}: case {case_id}",
                                comparison=comp, diagnosis=diag, provenance=prov)
    return html_path


def write_reports(camp, out: str | Path, pages: int = 3, stream=None) -> dict:
    store = Store(out)
    recs = {r["id"]: r for r in store.records({c.id for c in camp.cases})}
    manifest = store.read_manifest() or {}
    summary = summarize(camp, recs)
    atomic_write(store.out / "summary.json", dumps(summary))
    atomic_write(store.out / "junit.xml", junit_xml(camp, recs))
    worst = worst_cases(camp, recs, max(pages, 5))
    links = {}
    for w in [w for w in worst if w["verdict"] != "error"][:pages]:
        try:
            p = case_page(camp, w["id"], store.out)
            links[w["id"]] = str(p.relative_to(store.out))
        except Exception as e:  # noqa: BLE001  (a page we cannot draw does not sink the report)
            if stream is not None:
                print(f"campaign: no page for {w['id']}: {type(e).__name__}: {e}", file=stream)
    for p in (store.out / "pages").glob("*.html") if (store.out / "pages").is_dir() else []:
        links.setdefault(p.stem, str(p.relative_to(store.out)))
    atomic_write(store.out / "report.html", render(camp, summary, recs, manifest, worst, links))
    return summary
