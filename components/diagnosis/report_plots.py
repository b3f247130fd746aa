"""The report's plots, each an inline SVG string (matplotlib, Agg, deterministic ids, no metadata)."""
from __future__ import annotations

import io

import numpy as np

from components.diagnosis.misfit import CHANNELS
from components.logs.spill import gathered

# scatter plots with more points than this draw them as one embedded image in the SVG: each point
# as a vector element was ~110 bytes, and an 8-hour log's page came to 78 MB
DENSE_POINTS = 2000
RASTER_DPI = 150


def svg_of(fig) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", dpi=RASTER_DPI)
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


# segments the heat map shows at most: an 8-hour log has 768, a map of every one was a 29 000-pixel
# image and most of the report's peak memory (0.9 GB), and no one reads it
MAP_ROWS = 48


def map_segments(per_segment: dict, flagged=()) -> list[str]:
    """The segments the heat map shows, in the log's order: every one when they are at most
    :data:`MAP_ROWS`, else the *flagged* ones (beyond noise) and then those whose block RMS / noise
    lies farthest from 1 on some channel (logarithmically: ½ as far as 2), up to MAP_ROWS."""
    segs = list(per_segment)
    if len(segs) <= MAP_ROWS:
        return segs

    def distance(s):
        v = np.array([np.nan if x is None else x for x in per_segment[s]], float)
        v = np.abs(np.log(v[np.isfinite(v) & (v > 0)]))
        return float(v.max()) if len(v) else -1.0

    flagged = set(flagged)
    order = sorted(segs, key=lambda s: (s not in flagged, -distance(s)))
    keep = set(order[:MAP_ROWS])
    return [s for s in segs if s in keep]


def segment_map(comparison, model_name: str, gid: str = "misfit-map") -> str:
    """Segment × channel heat map of the block RMS / noise on a diverging scale centred on 1 (white
    = noise, blue = below, red = above), logarithmic so that ½ and 2 are equally far from 1; cells
    that misfit beyond noise given how many were looked at (components.diagnosis.misfit) are
    marked ×. A log of more than :data:`MAP_ROWS` segments shows those of :func:`map_segments`
    (every segment's figures are in the page's JSON twin)."""
    from matplotlib.colors import LogNorm

    plt = pyplot()
    mis = comparison.misfits
    flagged = [c.name for c in mis.flagged("segment")] if mis is not None else []
    segs = map_segments(comparison.per_segment, flagged)
    if not segs:
        return ""
    M = np.array([[np.nan if v is None else v for v in comparison.per_segment[s]] for s in segs])
    top = max(3.0, float(np.nanmax(M)) if np.isfinite(M).any() else 3.0)
    fig, ax = plt.subplots(figsize=(7, 0.25 * len(segs) + 1.5))
    im = ax.imshow(np.clip(M, 1 / top, top), aspect="auto", cmap="RdBu_r", norm=LogNorm(1 / top, top),
                   interpolation="nearest")
    ax.set_xticks(range(6), CHANNELS)
    ax.set_yticks(range(len(segs)), segs, fontsize=7)
    if mis is not None:
        for c in mis.flagged("segment"):
            if c.name in segs:
                ax.text(CHANNELS.index(c.channel), segs.index(c.name), "×", ha="center", va="center", fontsize=9)
    ticks = [t for t in (1 / top, 0.5, 1.0, 2.0, top) if 1 / top <= t <= top]
    cb = fig.colorbar(im, ax=ax, label="block RMS / noise (1 = noise)", ticks=ticks)
    cb.ax.set_yticklabels([f"{t:.3g}" for t in ticks])
    cb.ax.minorticks_off()
    cb.ax.set_gid(f"{gid}-legend")
    ax.set_gid(gid)
    shown = "" if len(segs) == len(comparison.per_segment) else \
        f"; the {len(segs)} of {len(comparison.per_segment)} segments farthest from noise"
    ax.set_title(f"where {model_name} fails: segment × channel (× = beyond noise{shown})", fontsize=9)
    return svg_of(fig)


def residual_vs_time(comparison, model_name: str) -> str:
    plt = pyplot()
    rows = comparison.rows
    t = comparison.time
    fig, axes = plt.subplots(6, 1, figsize=(9, 8), sharex=True)
    bounds = None
    if comparison.segment is not None:
        seg = comparison.segment
        bounds = np.append(seg.starts, len(seg))
    # the times at the blocks' middles and the segments' ends, a piece of a spilled log's column
    # at a time (read through its mapping, each brings the pages around it along: the column)
    mid = gathered(t, np.minimum((rows["start"] + rows["stop"]) // 2, len(t) - 1))
    if bounds is not None:
        first, last = gathered(t, bounds[:-1]), gathered(t, bounds[1:] - 1)
    for k, ax in enumerate(axes):
        sel = rows["channel"] == k
        tm = mid[sel]
        ax.plot(tm, rows["z"][sel], ".", ms=2, color="C0" if k < 3 else "C1", rasterized=len(tm) > DENSE_POINTS)
        ax.axhline(3, color="grey", lw=0.5)
        ax.axhline(-3, color="grey", lw=0.5)
        ax.set_ylabel(CHANNELS[k], fontsize=8)
        if bounds is not None:
            for i in range(1, len(first), 2):
                ax.axvspan(first[i], last[i], color="0.92", lw=0)
    axes[0].set_title(f"{model_name}: normalised block residual against time (segments shaded alternately; "
                      "±3 = noise bound)", fontsize=9)
    axes[-1].set_xlabel("time [s]")
    return svg_of(fig)


def conditions_plot(comparison, model_name: str) -> str:
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
    mis = comparison.misfits
    if mis is not None:
        for c in mis.flagged("condition"):
            i, k = names.index(c.name), CHANNELS.index(c.channel)
            ax.text(i + (k - 2.5) * 0.13, c.ratio, "×", ha="center", va="bottom", fontsize=8)
    ax.set_xticks(x, names, rotation=40, ha="right", fontsize=7)
    ax.set_ylabel("block RMS / noise")
    ax.legend(fontsize=7, ncol=6)
    ax.set_title(f"{model_name}: residual split by condition (× = beyond noise)", fontsize=9)
    return svg_of(fig)


def signature_plot(candidate) -> str:
    plt = pyplot()
    sig = candidate.signature
    if not sig:
        return ""
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot(sig["x"], sig["y"], ".", ms=2, rasterized=len(sig["x"]) > DENSE_POINTS)
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
        ax.loglog(tau, np.sqrt(c.noise.avar_realised(tau)) / scale, "-", color="#d95f02", label="identified model")
        ax.set_title(NAMES[k], fontsize=9)
        ax.set_ylabel(f"ADEV [{dunit}]", fontsize=8)
        ax.tick_params(labelsize=7)
        if k >= 3:
            ax.set_xlabel("τ [s]", fontsize=8)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return svg_of(fig)
