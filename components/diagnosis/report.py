"""The model-against-measurement report: one self-contained HTML page (plots inlined as SVG, no
script, no server) and its JSON twin.

Contents: the ladder (χ²/dof and RMS per model version), where the current model fails
(segment × channel map of the normalised residual, residual against time with segments
shaded, residual split by condition), the diagnosis ranking with signature plots, and the
provenance (log and model files with their SHA-256, software versions).
"""
from __future__ import annotations

import html
import io
import json
from pathlib import Path

import numpy as np

from components.diagnosis.compare import CHANNELS

CSS = """
body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1100px;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:2em}
table{border-collapse:collapse;font-size:.9em}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}
th{background:#f4f4f4}td.l,th.l{text-align:left}.pass{color:#0a6b0a;font-weight:bold}.note{color:#555}
figure{margin:1em 0}figcaption{font-size:.85em;color:#555}
"""


def svg_of(fig) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    s = buf.getvalue()
    s = s[s.index("<svg"):]
    # the RDF metadata block only names the generator; drop it so the page holds no URLs
    a, b = s.find("<metadata>"), s.find("</metadata>")
    return s[:a] + s[b + len("</metadata>"):] if a >= 0 and b > a else s


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams["svg.fonttype"] = "none"
    plt.rcParams["svg.hashsalt"] = "calbench"  # deterministic element ids
    return plt


def segment_map(comparison) -> str:
    plt = pyplot()
    segs = list(comparison.per_segment)
    if not segs:
        return ""
    M = np.array([[np.nan if v is None else v for v in comparison.per_segment[s]] for s in segs])
    fig, ax = plt.subplots(figsize=(7, 0.25 * len(segs) + 1.5))
    im = ax.imshow(M, aspect="auto", cmap="magma_r", vmin=0, vmax=max(3.0, np.nanmax(M)))
    ax.set_xticks(range(6), CHANNELS)
    ax.set_yticks(range(len(segs)), segs, fontsize=7)
    fig.colorbar(im, ax=ax, label="block residual RMS / noise (1 = noise)")
    ax.set_title("where the model fails: segment × channel")
    return svg_of(fig)


def residual_vs_time(comparison) -> str:
    plt = pyplot()
    rows = comparison.rows
    t = comparison.time
    fig, axes = plt.subplots(6, 1, figsize=(9, 8), sharex=True)
    seg = np.asarray(comparison.segment).astype(str) if comparison.segment is not None else None
    for k, ax in enumerate(axes):
        sel = rows["channel"] == k
        tm = t[np.minimum((rows["start"][sel] + rows["stop"][sel]) // 2, len(t) - 1)]
        ax.plot(tm, rows["z"][sel], ".", ms=2, color="C0" if k < 3 else "C1")
        ax.axhline(3, color="grey", lw=0.5)
        ax.axhline(-3, color="grey", lw=0.5)
        ax.set_ylabel(CHANNELS[k], fontsize=8)
        if seg is not None:
            change = np.nonzero(seg[1:] != seg[:-1])[0] + 1
            bounds = np.concatenate([[0], change, [len(seg)]])
            for i, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
                if i % 2:
                    ax.axvspan(t[a], t[b - 1], color="0.92", lw=0)
    axes[0].set_title("normalised block residual against time (segments shaded alternately; ±3 = noise bound)")
    axes[-1].set_xlabel("time [s]")
    return svg_of(fig)


def conditions_plot(comparison) -> str:
    plt = pyplot()
    names = list(comparison.conditions)
    if not names:
        return ""
    M = np.array([[np.nan if v is None else v for v in comparison.conditions[n]] for n in names])
    fig, ax = plt.subplots(figsize=(9, 3.5))
    x = np.arange(len(names))
    for k in range(6):
        ax.bar(x + (k - 2.5) * 0.13, M[:, k], 0.13, label=CHANNELS[k])
    ax.axhline(1, color="k", lw=0.7)
    ax.set_xticks(x, names, rotation=40, ha="right", fontsize=7)
    ax.set_ylabel("block RMS / noise")
    ax.legend(fontsize=7, ncol=6)
    ax.set_title("residual split by condition")
    return svg_of(fig)


def signature_plot(candidate) -> str:
    plt = pyplot()
    sig = candidate.signature
    if not sig:
        return ""
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot(sig["x"], sig["y"], ".", ms=2)
    lim = np.nanmax(np.abs(sig["x"])) if len(sig["x"]) else 1
    ax.plot([-lim, lim], [-lim, lim], "r-", lw=0.8, label="fitted magnitude")
    ax.set_xlabel(f"{sig['parameter']} contribution (normalised)")
    ax.set_ylabel("model residual (normalised)")
    ax.set_title(candidate.effect, fontsize=9)
    ax.legend(fontsize=7)
    return svg_of(fig)


def ladder_plot(ladder: list[dict]) -> str:
    plt = pyplot()
    if not ladder:
        return ""
    fig, ax = plt.subplots(figsize=(6, 2.8))
    ax.semilogy(range(len(ladder)), [e["chi2_per_dof"] for e in ladder], "o-")
    ax.axhline(1, color="grey", lw=0.7)
    ax.set_xticks(range(len(ladder)), [e["model"][:24] for e in ladder], rotation=20, ha="right", fontsize=7)
    ax.set_ylabel("χ²/dof")
    ax.set_title("the ladder: error falling as effects are added")
    return svg_of(fig)


def allan_plot(identification) -> str:
    """Allan deviation of each channel's residual (68 % interval) with the identified model."""
    from components.model.noise import CHANNELS as NAMES
    from components.model.noise import TERMS, sensor_of

    plt = pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(10, 5.5), sharex=True)
    for k, c in enumerate(identification.channels):
        ax = axes[k // 3, k % 3]
        av = c.fast.allan
        lo, hi = av.interval()
        _, _, dunit, scale = TERMS[sensor_of(k)]["bias_instability"]
        ax.fill_between(av.tau, lo / scale, hi / scale, color="#9ecae1", alpha=0.6, lw=0, label="68 % interval")
        ax.loglog(av.tau, av.adev / scale, "o", ms=3, color="#08519c", label="residual")
        tau = np.geomspace(av.tau[0], av.tau[-1] * 30, 80)
        ax.loglog(tau, np.sqrt(c.noise.avar(tau)) / scale, "-", color="#d95f02", label="identified model")
        ax.set_title(NAMES[k], fontsize=9)
        ax.set_ylabel(f"ADEV [{dunit}]", fontsize=8)
        ax.tick_params(labelsize=7)
        if k >= 3:
            ax.set_xlabel("τ [s]", fontsize=8)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return svg_of(fig)


def _table(header: list[str], rows: list[list], left: int = 1) -> str:
    h = "".join(f'<th class="{"l" if i < left else ""}">{html.escape(str(c))}</th>' for i, c in enumerate(header))
    body = []
    for r in rows:
        body.append("<tr>" + "".join(f'<td class="{"l" if i < left else ""}">{c}</td>' for i, c in enumerate(r)) + "</tr>")
    return f"<table><tr>{h}</tr>{''.join(body)}</table>"


def _fmt(x, spec=".4g") -> str:
    return "" if x is None else format(x, spec)


def build_report(path: str | Path, *, title: str, comparison, diagnosis=None, ladder=None,
                 provenance: dict | None = None, noise=None) -> tuple[Path, Path]:
    """Write <path>.html and <path>.json (path without suffix or with .html). ``noise``: a noise
    identification (components.diagnosis.noise_id) to show: Allan deviation and model."""
    path = Path(path)
    if path.suffix == ".html":
        path = path.with_suffix("")
    from components.model.effects import EFFECTS

    ladder = ladder or []
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{CSS}</style></head><body><h1>{html.escape(title)}</h1>"]
    if ladder:
        parts.append("<h2>Ladder</h2>")
        rows = [[html.escape(e["model"]), _fmt(e["chi2_per_dof"], ".3f")]
                + [_fmt(e["rms"][c] / e["noise_floor"][c], ".3f") for c in CHANNELS] for e in ladder]
        parts.append(_table(["model", "χ²/dof"] + [f"{c} rms/noise" for c in CHANNELS], rows))
        parts.append(f"<figure>{ladder_plot(ladder)}</figure>")
    parts.append("<h2>Model against measurement</h2>")
    against = "whitened with the noise model" if getattr(comparison, "coloured", False) else "against the white-noise level"
    parts.append(f"<p>χ²/dof of block sums {against}: <b>{comparison.chi2_per_dof:.3f}</b> "
                 f"({comparison.dof} dof; a correct model scores 1 ± {np.sqrt(2 / max(comparison.dof, 1)):.3f}).</p>")
    rows = [[c, _fmt(v["rms"]), _fmt(v["noise_floor"]), _fmt(v["rms"] / v["noise_floor"], ".3f"),
             _fmt(v["chi2_per_dof"], ".3f"), _fmt(v["fit_percent"], ".4f"), _fmt(v["whiteness_p"], ".3f")]
            for c, v in comparison.channels.items()]
    parts.append(_table(["channel", "rms", "noise floor", "rms/noise", "χ²/dof", "fit %", "whiteness p"], rows))
    for fig, cap in ((segment_map(comparison), "Normalised residual per segment and channel."),
                     (residual_vs_time(comparison), "Block residuals in time order."),
                     (conditions_plot(comparison), "Residual by condition.")):
        if fig:
            parts.append(f"<figure class='plot'>{fig}<figcaption>{cap}</figcaption></figure>")
    if diagnosis is not None:
        parts.append("<h2>Diagnosis: which effect is missing</h2>")
        verdict = diagnosis.verdict or "no significant effect is missing"
        if diagnosis.verdict_kind == "noise":
            verdict = f"the noise model is too simple: {diagnosis.verdict} (a stochastic term, not an effect)"
        parts.append(f"<p>Verdict: <b>{html.escape(verdict)}</b>"
                     + (f" — found in turn: {html.escape(', '.join(diagnosis.found))}" if len(diagnosis.found) > 1 else "")
                     + f" (Holm-corrected F-test at α = {diagnosis.alpha} on the whitened rows; ΔBIC shown, not "
                     "required)</p>")
        rows = []
        for i, c in enumerate(diagnosis.ranking[:12], 1):
            unit, scale = EFFECTS[c.effect].display
            best = max(c.parameters.items(), key=lambda kv: abs(kv[1][0]) / (kv[1][1] or np.inf))
            mag = f"{best[0]} = {best[1][0] / scale:+.4g} ± {best[1][1] / scale:.2g} {unit}"
            note = "; ".join(f"cannot be told apart from {o} (ρ = {r:.3f}): {a}" for o, r, a in c.indistinguishable)
            rows.append([f"{i}", f"<span class='{'pass' if c.passes else ''}'>{c.effect}</span>",
                         _fmt(c.statistic, ".3g"), _fmt(c.p_adjusted, ".2g"), _fmt(c.bic_delta, ".4g"),
                         f"{100 * c.explained_fraction:.1f}%", html.escape(mag), html.escape(note)])
        parts.append(_table(["rank", "effect", "F", "p (Holm)", "ΔBIC", "explains", "magnitude", "note"], rows, left=2))
        parts.append("<div>")
        for c in diagnosis.ranking[:3]:
            parts.append(f"<figure class='plot' style='display:inline-block'>{signature_plot(c)}"
                         f"<figcaption>signature of {html.escape(c.effect)}</figcaption></figure>")
        parts.append("</div>")
    if noise is not None:
        parts.append("<h2>Noise: Allan deviation of the residual and the identified model</h2>")
        parts.append(f"<figure class='plot'>{allan_plot(noise)}<figcaption>Overlapping Allan deviation of the "
                     "residual in the static runs (dots), its 68 % interval from the equivalent degrees of freedom "
                     "(band) and the identified composite model (line).</figcaption></figure>")
        parts.append("<pre>" + html.escape("\n".join(noise.table())) + "</pre>")
    parts.append("<h2>Provenance</h2><pre>" + html.escape(json.dumps(provenance or {}, indent=1)) + "</pre>")
    parts.append("</body></html>")
    html_path = path.with_suffix(".html")
    html_path.parent.mkdir(parents=True, exist_ok=True)
    html_path.write_text("".join(parts))
    twin = {"title": title, "ladder": ladder, "comparison": comparison.summary(),
            "diagnosis": diagnosis.to_json() if diagnosis is not None else None,
            "noise": noise.model.to_dict() if noise is not None else None,
            "provenance": provenance or {}}
    json_path = path.with_suffix(".json")
    json_path.write_text(json.dumps(twin, indent=1, default=float))
    return html_path, json_path
