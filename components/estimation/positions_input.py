"""The input side of a multi-position calibration (:mod:`.positions`): the arrays and effects
checked, the description of each segment label (``kinds``) parsed, and the log's samples sorted
into rests (cut into chunks) and turns (from the last rest sample before to the first after)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from components.errors import EstimationError
from components.logs.labels import SegmentLabels
from components.logs.segments import parse_segments
from components.model.effects import DEFAULT_EFFECTS, parse_effects

SUPPORTED = DEFAULT_EFFECTS  # gyro.bias, gyro.sf, gyro.mis, acc.bias, acc.sf, acc.mis


def checked_log(time, gyro_inc, acc_inc, segment, valid):
    """The arrays as (t, gyro increments, acc increments, segment labels as text, usable flags),
    or an EstimationError naming what does not fit."""
    t = np.asarray(time, float)
    yg = np.asarray(gyro_inc, float)
    ya = np.asarray(acc_inc, float)
    n = len(t)
    if t.ndim != 1 or yg.shape != (n, 3) or ya.shape != (n, 3):
        raise EstimationError(f"time (N,), gyro_inc (N, 3), acc_inc (N, 3) expected; got {t.shape}, "
                              f"{yg.shape}, {ya.shape}")
    # (labels of any kind from the Python API are taken as their text)
    seg = segment if isinstance(segment, SegmentLabels) else np.asarray(segment).astype(str).astype(object)
    if seg.shape != (n,):
        raise EstimationError(f"segment: expected one label per sample ({n}), got shape {seg.shape}")
    seg = SegmentLabels.of(seg)
    ok = np.ones(n, bool) if valid is None else np.asarray(valid, bool)
    if ok.shape != (n,):
        raise EstimationError(f"valid: expected one flag per sample ({n}), got shape {ok.shape}")
    if n < 2 or np.any(np.diff(t) <= 0):
        raise EstimationError("time: expected at least two samples, strictly increasing")
    bad = ok & ~(np.all(np.isfinite(yg), axis=1) & np.all(np.isfinite(ya), axis=1))
    if np.any(bad):
        raise EstimationError(f"increments not finite at {int(bad.sum())} usable sample(s), the first at "
                              f"t = {t[np.argmax(bad)]:.6g} s: mark them in 'valid'")
    return t, yg, ya, seg, ok


def checked_effects(effects) -> list[str]:
    """The effects as vocabulary names, only those the method fits."""
    try:
        effects = parse_effects(effects)
    except ValueError as e:
        raise EstimationError(f"effects: {e}") from None
    unsupported = [e for e in effects if e not in SUPPORTED]
    if unsupported:
        raise EstimationError(f"effects {unsupported}: the positions method fits only {', '.join(SUPPORTED)}")
    return effects


def parse_kinds(kinds: dict) -> dict:
    """``{label: {"kind": "static"[, "up": ...]} | {"kind": "rotation", "axis": ..., "angle_deg": ...}
    | {"kind": "excluded"}}`` checked -> {label: {"kind", "up" (vector or None), "axis", "angle" [rad]}}
    (components.logs.segments, with the estimator's error)."""
    return parse_segments(kinds, "kinds", EstimationError)


def _runs(labels: SegmentLabels) -> list[tuple[str, int, int]]:
    """(label, start, stop) per run of equal labels."""
    return [(label, a, b) for a, b, label in labels.runs()]


def _stretches(mask: np.ndarray, a: int, b: int) -> list[tuple[int, int]]:
    """Contiguous runs of True in mask[a:b] as absolute [start, stop)."""
    m = np.concatenate([[False], mask[a:b], [False]]).astype(np.int8)
    d = np.diff(m)
    return [(a + int(s), a + int(e)) for s, e in zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0])]


def _chunks(a: int, b: int, n: int) -> list[tuple[int, int]]:
    """[a, b) cut into pieces of about n samples."""
    k = max(1, int(math.ceil((b - a) / n)))
    edges = np.linspace(a, b, k + 1).round().astype(int)
    return list(zip(edges[:-1], edges[1:]))


@dataclass
class TurnSpan:
    """A rotation segment and the samples its row sums."""

    name: str
    label: str
    lo: int                   # summed samples [lo, hi): the run and the rest sample on each side if usable
    hi: int
    axis: np.ndarray          # unit, body frame B
    angle: float              # rad, stated
    before: str               # the rests' names on either side
    after: str


@dataclass
class Segments:
    """The log's samples sorted: the rests with usable samples, in chunks, and the turns."""

    names: list[str]          # per rest: the label, or label#k for the k-th run of a label used twice
    labels: list[str]
    ranges: list[tuple[int, int]]          # the run's samples [start, stop)
    chunks: list[tuple[int, int, int]]     # (rest index, start, stop)
    turns: list[TurnSpan]
    use: np.ndarray           # (N,) samples in the rests' rows
    excluded: dict[str, int]  # label -> samples left out ('(valid = False)': masked)


def split_segments(seg: SegmentLabels, ok: np.ndarray, desc: dict, t: np.ndarray, dt_med: float, chunk_s: float,
                   notes: list[str]) -> Segments:
    """The runs of ``seg`` as rests and turns (``desc`` from :func:`parse_kinds`); what is left
    out is counted in ``excluded`` and said in ``notes``."""
    items, excluded = _items(seg, desc, notes)
    if not np.all(ok):
        excluded["(valid = False)"] = int((~ok).sum())
    use = np.zeros(len(seg), bool)
    for kind, _, _, a, b in items:
        if kind == "static":
            use[a:b] = ok[a:b]
    turns = _turn_spans(items, ok, use, t, desc, notes)
    names, labels, ranges, chunks = [], [], [], []
    n_chunk = max(1, int(round(chunk_s / dt_med)))
    for kind, name, lab, a, b in items:
        if kind != "static":
            continue
        st = _stretches(use, a, b)
        if sum(e - s for s, e in st) < 2:
            notes.append(f"static {name!r} left out: fewer than two usable samples")
            continue
        p = len(names)
        names.append(name)
        labels.append(lab)
        ranges.append((a, b))
        for s, e in st:
            chunks += [(p, c0, c1) for c0, c1 in _chunks(s, e, n_chunk)]
    if not names:
        raise EstimationError("no static segment with usable samples: the positions method needs the IMU at "
                              "rest in several attitudes (segments of kind 'static')")
    return Segments(names, labels, ranges, chunks, turns, use, excluded)


def _items(seg: SegmentLabels, desc: dict, notes: list[str]) -> tuple[list, dict[str, int]]:
    """[(kind, name, label, start, stop)] per run, and the samples of excluded runs per label."""
    runs = _runs(seg)
    count = {}
    for lab, _, _ in runs:
        count[lab] = count.get(lab, 0) + 1
    seen: dict[str, int] = {}
    items = []
    excluded: dict[str, int] = {}
    unlisted = set()
    for lab, a, b in runs:
        seen[lab] = seen.get(lab, 0) + 1
        name = lab if count[lab] == 1 else f"{lab}#{seen[lab]}"
        k = desc.get(lab, {"kind": "excluded"})
        if lab not in desc:
            unlisted.add(lab)
        if k["kind"] == "excluded":
            excluded[lab] = excluded.get(lab, 0) + (b - a)
        items.append((k["kind"], name, lab, a, b))
    if unlisted:
        notes.append(f"labels not described, excluded: {', '.join(sorted(unlisted))}")
    return items, excluded


def _turn_spans(items: list, ok: np.ndarray, use: np.ndarray, t: np.ndarray, desc: dict,
                notes: list[str]) -> list[TurnSpan]:
    """Each rotation run with the rest sample on each side, which then leaves the rests' rows
    (``use``): its row is the sum from rest to rest."""
    turns = []
    for idx, (kind, name, lab, a, b) in enumerate(items):
        if kind != "rotation":
            continue
        prev = items[idx - 1] if idx > 0 else None
        nxt = items[idx + 1] if idx + 1 < len(items) else None
        for side, nb in (("before", prev), ("after", nxt)):
            if nb is None or nb[0] != "static":
                what = "the log's " + ("start" if side == "before" else "end") if nb is None else \
                    f"segment {nb[2]!r} ({nb[0]})"
                raise EstimationError(f"rotation {name!r} (t = {t[a]:.6g}-{t[b - 1]:.6g} s): {side} it comes {what}: "
                                      "a rotation must go from rest to rest, with a static segment on each side")
        if not np.all(ok[a:b]):
            notes.append(f"rotation {name!r} left out: {int((~ok[a:b]).sum())} of its samples are left out "
                         "(gap or mask), so its integral is unknown")
            continue
        lo = a - 1 if ok[a - 1] else a
        hi = b + 1 if ok[b] else b
        use[lo:a] = False
        use[b:hi] = False
        turns.append(TurnSpan(name, lab, lo, hi, desc[lab]["axis"], desc[lab]["angle"], prev[1], nxt[1]))
    return turns
