"""The model-against-measurement report: one self-contained HTML page (plots inlined as SVG, no
script, no server) and its JSON twin. ``calbench report``, ``--report`` on compare / diagnose /
add, ``calbench noise --report``, the demo and the campaign pages all write it here.

Every section names the model it shows. Contents: the models shown (before and after when there
are two) and the ladder; per model, where it fails (the cells that misfit beyond noise given how
many were looked at, a segment × channel heat map on a diverging scale centred on 1 = noise, the
residual against time, the split by condition) and its diagnosis (each candidate's status and
why, in place of values that are not estimates); the recovered values against a truth when one
is known; the noise (Allan deviation of the residual with the identified model); the provenance
(files with their SHA-256, software versions).
"""
from __future__ import annotations

import html
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from components.diagnosis.misfit import CHANNELS
from components.diagnosis.report_plots import (  # noqa: F401  (pyplot, svg_of: the campaign pages use them)
    allan_plot,
    conditions_plot,
    ladder_plot,
    pyplot,
    residual_vs_time,
    segment_map,
    signature_plot,
    svg_of,
)

CSS = """
body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1100px;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:2em}
table{border-collapse:collapse;font-size:.9em}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f4f4f4}td.l,th.l{text-align:left}.pass{color:#0a6b0a;font-weight:bold}.note{color:#555}
figure{margin:1em 0}.flag{color:#b2182b;font-weight:bold}.muted{color:#777}figcaption{font-size:.85em;color:#555}
"""


@dataclass
class ModelView:
    """One model the page shows: its name (as the ladder names it), its comparison with the log,
    and its diagnosis if one was run."""
    name: str
    comparison: object
    diagnosis: object = None
    role: str = ""   # "before" / "after" / ""


def _table(header: list[str], rows: list[list], left: int = 1) -> str:
    h = "".join(f'<th class="{"l" if i < left else ""}">{html.escape(str(c))}</th>' for i, c in enumerate(header))
    body = []
    for r in rows:
        body.append("<tr>" + "".join(f'<td class="{"l" if i < left else ""}">{c}</td>' for i, c in enumerate(r)) + "</tr>")
    return f"<table><tr>{h}</tr>{''.join(body)}</table>"


def _fmt(x, spec=".4g") -> str:
    return "" if x is None else format(x, spec)


def _h2(text: str, anchor: str) -> str:
    return f"<h2 id='{anchor}'>{html.escape(text)}</h2>"


def _where(view: ModelView, k: int) -> list[str]:
    c = view.comparison
    name = view.name
    parts = [_h2(f"Where {name} fails" + (f" ({view.role})" if view.role else ""), f"where-{k}")]
    against = f"whitened with the noise model ({c.noise_terms})" if c.noise_terms else "against the white-noise level"
    parts.append(f"<p>Model <b>{html.escape(name)}</b>: χ²/dof of block sums {against} <b>{c.chi2_per_dof:.3f}</b> "
                 f"({c.dof} dof; a correct model scores 1 ± {np.sqrt(2 / max(c.dof, 1)):.3f}).</p>")
    rows = [[ch, _fmt(v["rms"]), _fmt(v["noise_floor"]), _fmt(v["rms"] / v["noise_floor"], ".3f"),
             _fmt(v["chi2_per_dof"], ".3f"), _fmt(v["fit_percent"], ".4f"), _fmt(v["whiteness_p"], ".3f")]
            for ch, v in c.channels.items()]
    parts.append(_table(["channel", "rms", "noise floor", "rms/noise", "χ²/dof", "fit %", "whiteness p"], rows))
    if c.misfits is not None:
        flagged = any(c.misfits.flagged(f) for f in c.misfits.cells)
        parts.append("<ul class='misfits'>" + "".join(
            f"<li class='{'flag' if not line.startswith('no ') else ''}'>{html.escape(line)}</li>"
            for line in c.misfits.lines()) + "</ul>")
        parts.append("<p class='note'>A cell is flagged only when its χ² is significant after the Holm correction "
                     "over every cell looked at: the largest of hundreds of noise-only cells is well above 1 "
                     + ("and is not a failure." if not flagged else "— the flagged cells above are beyond that.")
                     + "</p>")
    for fig, cap in ((segment_map(c, name, gid=f"misfit-map-{k}"),
                      f"{name}: block RMS / noise per segment and channel, diverging scale centred on 1 "
                      "(white = noise, red = above, blue = below; logarithmic); × = beyond noise."),
                     (residual_vs_time(c, name), f"{name}: block residuals in time order."),
                     (conditions_plot(c, name), f"{name}: residual by condition.")):
        if fig:
            parts.append(f"<figure class='plot'>{fig}<figcaption>{html.escape(cap)}</figcaption></figure>")
    return parts


def _diagnosis(view: ModelView, k: int) -> list[str]:
    from components.diagnosis.candidate_notes import LEGEND, magnitude_text, verdict_lines

    d = view.diagnosis
    parts = [_h2(f"Diagnosis of {view.name}: which effect it lacks", f"diagnosis-{k}")]
    parts.append("<p>" + "<br>".join(html.escape(x.strip()) for x in verdict_lines(d))
                 + f" <span class='note'>(Holm-corrected F-test at α = {d.alpha} on the whitened rows of "
                 f"{html.escape(view.name)}; ΔBIC shown, not required)</span></p>")
    rows = []
    for i, c in enumerate(d.ranking[:12], 1):
        notes = ([f"{c.status}: {c.why}"] if c.why and c.status != "not significant" else []) + [
            f"cannot be told apart from {o} (ρ = {r:.3f}): {a}" for o, r, a in c.indistinguishable]
        cls = "pass" if c.passes else ("flag" if c.status in ("implausible", "unidentifiable") else "")
        rows.append([f"{i}", f"<span class='{cls}'>{html.escape(c.effect)}</span>", html.escape(c.status),
                     _fmt(c.statistic, ".3g"), _fmt(c.p_adjusted, ".2g"), _fmt(c.bic_delta, ".4g"),
                     f"{100 * c.explained_fraction:.1f}%", html.escape(magnitude_text(c)),
                     html.escape("; ".join(notes))])
    parts.append(_table(["rank", "effect", "status", "F", "p (Holm)", "ΔBIC", "explains", "magnitude", "why"],
                        rows, left=3))
    parts.append(f"<p class='note'>{html.escape(LEGEND)}</p><div>")
    for c in [c for c in d.ranking if c.status not in ("implausible", "unidentifiable")][:3]:
        parts.append(f"<figure class='plot' style='display:inline-block'>{signature_plot(c)}"
                     f"<figcaption>signature of {html.escape(c.effect)} in the residual of "
                     f"{html.escape(view.name)}</figcaption></figure>")
    parts.append("</div>")
    return parts


def build_report(path: str | Path, *, title: str, comparison=None, diagnosis=None, ladder=None,
                 provenance: dict | None = None, noise=None, model_name: str = "the model",
                 views: list[ModelView] | None = None, truth: list[str] | None = None,
                 truth_model: str | None = None, noise_model: str | None = None,
                 truth_values: list | None = None) -> tuple[Path, Path]:
    """Write <path>.html and <path>.json (path without suffix or with .html). ``views``: the models
    shown, before first (default: *comparison* and *diagnosis* as one view named *model_name*);
    ``truth``: lines of recovered values against a known truth (of *truth_model*); ``noise``: a
    noise identification (components.diagnosis.noise_id) of the residual of *noise_model*."""
    path = Path(path)
    if path.suffix == ".html":
        path = path.with_suffix("")
    views = views or [ModelView(model_name, comparison, diagnosis)]
    last = views[-1].name
    ladder = ladder or []
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{CSS}</style></head><body><h1>{html.escape(title)}</h1>"]
    parts.append("<p>Models shown: " + "; ".join(
        f"<b>{html.escape(v.name)}</b>" + (f" ({v.role})" if v.role else "") for v in views) + ".</p>")
    if ladder:
        parts.append(_h2("Ladder: χ²/dof and RMS per model version, " + " → ".join(e["model"] for e in ladder),
                         "ladder"))
        rows = [[html.escape(e["model"]), _fmt(e["chi2_per_dof"], ".3f")]
                + [_fmt(e["rms"][c] / e["noise_floor"][c], ".3f") for c in CHANNELS]
                + [html.escape(e.get("noise") or "not recorded")] for e in ladder]
        parts.append(_table(["model", "χ²/dof"] + [f"{c} rms/noise" for c in CHANNELS] + ["χ²/dof under the noise"],
                            rows))
        parts.append(f"<figure>{ladder_plot(ladder)}</figure>")
    for k, v in enumerate(views):
        parts += _where(v, k)
        if v.diagnosis is not None:
            parts += _diagnosis(v, k)
    if truth:
        parts.append(_h2(f"Recovered against the truth: {truth_model or last}", "truth"))
        parts.append("<pre>" + html.escape("\n".join(truth)) + "</pre>")
    if noise is not None:
        name = noise_model or last
        parts.append(_h2(f"Noise: Allan deviation of the residual of {name} and the identified model", "noise"))
        parts.append(f"<figure class='plot'>{allan_plot(noise)}<figcaption>Overlapping Allan deviation of the "
                     f"residual of {html.escape(name)} in the static runs (dots), its 68 % interval from the "
                     "equivalent degrees of freedom (band) and the identified composite model (line).</figcaption>"
                     "</figure>")
        parts.append("<pre>" + html.escape("\n".join(noise.table())) + "</pre>")
    parts.append(_h2("Provenance: the log and every model shown", "provenance"))
    parts.append("<pre>" + html.escape(json.dumps(provenance or {}, indent=1)) + "</pre>")
    parts.append("</body></html>")
    # the suffixes added to the name, not put in place of its last dotted part ('page.v2')
    html_path = Path(f"{path}.html")
    html_path.parent.mkdir(parents=True, exist_ok=True)
    html_path.write_text("".join(parts))
    diagnosed = [v for v in views if v.diagnosis is not None]
    twin = {"title": title, "ladder": ladder,
            "views": [{"model": v.name, "role": v.role, "comparison": v.comparison.summary(),
                       "diagnosis": v.diagnosis.to_json() if v.diagnosis is not None else None} for v in views],
            "comparison": views[-1].comparison.summary(),
            "diagnosis": diagnosed[-1].diagnosis.to_json() if diagnosed else None,
            "truth": list(truth or []),
            "truth_values": list(truth_values or []),  # the same as numbers (SI): parameter, truth, value, σ
            "noise": noise.model.to_dict() if noise is not None else None,
            "provenance": provenance or {}}
    json_path = Path(f"{path}.json")
    json_path.write_text(json.dumps(twin, indent=1, default=float))
    return html_path, json_path
