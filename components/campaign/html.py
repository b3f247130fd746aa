"""The campaign's HTML report: one self-contained page (inline SVG, no script).

Contents: the verdict and counts (and the regression verdict of the [expected] block), the
requirement -> criterion -> cases -> verdict traceability matrix, the pass/fail table of every
case, per-parameter Monte-Carlo histograms of the estimation error in units of the Cramer-Rao
sigma (a standard normal if the procedure is efficient and the truth is recovered), the worst
cases with a link to their own compare/diagnose page, and the manifest."""
from __future__ import annotations

import html
import json

import numpy as np

from components.diagnosis.report import CSS, pyplot, svg_of

_EXTRA_CSS = ".fail{color:#b00;font-weight:bold}.error{color:#a60;font-weight:bold}" \
             "td.wrap{text-align:left;max-width:30em}details{margin:.5em 0}"


def _e(x) -> str:
    return html.escape(str(x))


def _cls(v) -> str:
    return {"pass": "pass", "fail": "fail", "error": "error"}.get(v, "")


def _table(header, rows, left=()) -> str:
    h = "".join(f"<th class='l'>{_e(x)}</th>" if i in left else f"<th>{_e(x)}</th>" for i, x in enumerate(header))
    body = "".join("<tr>" + "".join(f"<td class='l'>{c}</td>" if i in left else f"<td>{c}</td>"
                                    for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def histograms(records: list[dict], max_params: int = 24) -> str:
    """One figure: per parameter, the histogram of error / CRB sigma over the group's cases."""
    from components.model.effects import effect_of

    per: dict = {}
    for r in records:
        for p, e in (r.get("estimates") or {}).items():
            if e.get("crb") and e.get("error") is not None:
                per.setdefault(p, []).append(e["error"] / e["crb"])
    if not per:
        return ""
    names = sorted(per)[:max_params]
    plt = pyplot()
    ncol = min(6, len(names))
    nrow = int(np.ceil(len(names) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(2.0 * ncol, 1.7 * nrow), squeeze=False)
    x = np.linspace(-4, 4, 101)
    for ax, p in zip(axes.flat, names):
        z = np.asarray(per[p])
        lim = max(4.0, float(np.max(np.abs(z))) * 1.05)
        ax.hist(np.clip(z, -lim, lim), bins=np.linspace(-lim, lim, 17), density=True, color="#7aa6d8")
        ax.plot(x, np.exp(-x**2 / 2) / np.sqrt(2 * np.pi), color="#333", lw=0.8)
        ax.set_title(f"{p}\nmean {z.mean():+.2f} sd {z.std():.2f} (n={len(z)})", fontsize=6)
        ax.tick_params(labelsize=5)
        ax.set_yticks([])
        effect_of(p)  # noqa: B018  (only vocabulary names reach here)
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.supxlabel("error / Cramér–Rao σ (curve: standard normal)", fontsize=7)
    fig.tight_layout()
    return svg_of(fig)


def render(camp, summary: dict, records: dict, manifest: dict, worst: list[dict], pages: dict) -> str:
    c = summary["counts"]
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>campaign {_e(camp.name)}</title>"
             f"<style>{CSS}{_EXTRA_CSS}</style></head><body><h1>Campaign {_e(camp.name)}</h1>"]
    if camp.description:
        parts.append(f"<p class='note'>{_e(camp.description)}</p>")
    verdict = "pass" if summary["all_passed"] else "fail" if c["fail"] else "error" if c["error"] else "incomplete"
    parts.append(f"<p>Verdict: <span class='{_cls(verdict)}'>{verdict}</span> — {c['pass']} passed, {c['fail']} failed, "
                 f"{c['error']} errored, {c['missing']} not run, of {c['total']} cases.</p>")
    if summary["expected"] is not None:
        ok = summary["expected"]["ok"]
        mm = summary["expected"]["mismatches"]
        parts.append(f"<p>Regression ([expected] block): <span class='{'pass' if ok else 'fail'}'>"
                     f"{'as expected' if ok else 'NOT as expected'}</span>"
                     + (f" — differs: {_e(', '.join(mm))}" if mm else "") + "</p>")

    lost_rows = []
    for sname in camp.systems:
        rec = next((r for cid, r in sorted(records.items()) if r and r.get("system") == sname), None)
        lost = (rec or {}).get("not_injected") or {}
        if isinstance(lost, dict) and (lost.get("effects") or lost.get("noise") or lost.get("seed")):
            lost_rows.append([_e(sname), _e(", ".join(lost.get("effects", [])) or "—"),
                              _e(", ".join(lost.get("noise", [])) or ("none asked" if lost.get("noise_free") else "—")),
                              "no (every replicate draws the same)" if lost.get("seed") else "yes"])
    if lost_rows:
        parts.append("<h2>What each IMU could not take</h2><p class='note'>Effects and noise the campaign asked for "
                     "that an IMU FMU has no parameter for (its effect_map / noise_map, docs/supplier.md): not "
                     "injected and not in its truth; criteria that need noise are not applicable on a noise-free "
                     "IMU.</p>")
        parts.append(_table(["system", "effects not injected", "noise not injected", "seed applied"], lost_rows,
                            left={0, 1, 2, 3}))
    parts.append("<h2>Traceability: requirement → criterion → cases → verdict</h2>")
    rows = []
    for req in summary["requirements"]:
        for i, cr in enumerate(req["criteria"]):
            k = cr["counts"]
            rows.append([f"<b>{_e(req['requirement'])}</b> <span class='{_cls(req['verdict'])}'>{_e(req['verdict'])}</span>"
                         if i == 0 else "", _e(cr["id"]), _e(cr["kind"]), _e(cr["description"]),
                         f"{k['pass']}", f"{k['fail']}", f"{k.get('n/a', 0)}", f"{k['error']}", f"{k['missing']}",
                         f"<span class='{_cls(cr['verdict'])}'>{_e(cr['verdict'])}</span>"])
    parts.append(_table(["requirement", "criterion", "kind", "description", "pass", "fail", "not applicable", "error",
                         "not run", "verdict"], rows, left={0, 1, 2, 3}))
    parts.append("<details><summary>cases per criterion</summary>")
    for req in summary["requirements"]:
        for cr in req["criteria"]:
            cells = ", ".join(f"<span class='{_cls(x['outcome'])}'>{_e(x['case'])}</span>" for x in cr["cases"])
            parts.append(f"<p><b>{_e(req['requirement'])} / {_e(cr['id'])}</b>: {cells}</p>")
    parts.append("</details>")

    parts.append("<h2>Cases</h2>")
    rows = []
    var_names = sorted({k for case in camp.cases for k in case.variation})
    for row, case in zip(summary["cases"], camp.cases):
        rec = records.get(case.id) or {}
        link = f"<a href='{_e(pages[case.id])}'>{_e(case.id)}</a>" if case.id in pages else _e(case.id)
        exp = row["expected"]
        rows.append([link, _e(case.procedure), _e(case.system), f"{case.seed}"]
                    + [f"{case.variation[k]:.4g}" if k in case.variation else "" for k in var_names]
                    + [_e("" if rec.get("chi2_per_dof") is None else f"{rec['chi2_per_dof']:.3f}"),
                       f"<span class='{_cls(row['verdict'])}'>{_e(row['verdict'] or 'not run')}</span>",
                       _e(row["reason"] or ""),
                       "" if exp is None else ("✓" if exp["ok"] else f"<span class='fail'>expected {_e(exp['verdict'])}</span>")])
    parts.append(_table(["case", "procedure", "system", "seed"] + [f"{k} [SI]" for k in var_names]
                        + ["χ²/dof", "verdict", "reason", "expected"], rows, left={0, 1, 2, len(var_names) + 6}))

    parts.append("<h2>Monte-Carlo: estimation errors against the Cramér–Rao bound</h2>")
    groups: dict = {}
    for case in camp.cases:
        rec = records.get(case.id)
        if rec is not None and rec["verdict"] != "error":
            groups.setdefault((case.procedure, case.system), []).append(rec)
    for (p, s), recs in groups.items():
        fig = histograms(recs)
        if fig:
            parts.append(f"<h3>{_e(p)} on {_e(s)} ({len(recs)} cases)</h3><figure class='plot'>{fig}"
                         "<figcaption>Per parameter: histogram of (estimate − truth) / CRB σ over the cases "
                         "(grid points and seeds); an efficient, unbiased procedure gives the standard normal."
                         "</figcaption></figure>")
        else:
            parts.append(f"<p class='note'>{_e(p)} on {_e(s)}: no Cramér–Rao bound (no noise model).</p>")

    parts.append("<h2>Worst cases</h2>")
    rows = [[f"<a href='{_e(pages[w['id']])}'>{_e(w['id'])}</a>" if w["id"] in pages else _e(w["id"]),
             f"<span class='{_cls(w['verdict'])}'>{_e(w['verdict'])}</span>", f"{w['score']:.3g}", _e(w["why"])]
            for w in worst]
    parts.append(_table(["case", "verdict", "worst ratio to its limit", "why"], rows, left={0, 3})
                 if rows else "<p>none</p>")

    parts.append("<h2>Manifest</h2>")
    files = manifest.get("files", {})
    parts.append(_table(["input", "path", "SHA-256"], [[_e(k), _e(v["path"]), f"<code>{_e(v['sha256'])}</code>"]
                                                      for k, v in files.items()], left={0, 1, 2}))
    sess = [[_e(s.get("start")), _e(s.get("end")), _e(s.get("scheduler") or f"local, {s.get('workers')} workers"),
             f"{len(s.get('ran', []))}", f"{s.get('skipped_done', 0)}", "yes" if s.get("interrupted") else ""]
            for s in manifest.get("sessions", [])]
    parts.append(_table(["session start", "end", "cluster", "cases run", "already done", "interrupted"], sess,
                        left={0, 1, 2}))
    slim = {k: v for k, v in manifest.items() if k not in ("files", "sessions")}
    parts.append("<details><summary>software, host, seeds</summary><pre>"
                 + _e(json.dumps(slim, indent=1, sort_keys=True)) + "</pre></details>")
    parts.append("</body></html>")
    return "".join(parts)
