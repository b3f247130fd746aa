"""What a segment label of a log is (``segments`` in a ``calbench-log/2`` log,
docs/measurement-log.md): at rest (with the body axis that points up, or an unknown attitude), a
rotation of known total angle about a body axis, or excluded. Checked once here for the log
reader and for the estimators that take the descriptions from Python."""
from __future__ import annotations

import math

import numpy as np

from components.errors import LogFormatError

AX = "xyz"
KINDS = {"static": {"kind", "up"}, "rotation": {"kind", "axis", "angle_deg"}, "excluded": {"kind"}}


def body_vector(v, where: str, error=LogFormatError) -> np.ndarray:
    """A body axis: "x", "-y", "+z" or a unit vector [x, y, z]."""
    expected = "expected a body axis 'x', '-y', ... or a unit vector [x, y, z]"
    if isinstance(v, str):
        s = v.strip().lower()
        sign = -1.0 if s.startswith("-") else 1.0
        s = s.lstrip("+-")
        if s not in ("x", "y", "z"):
            raise error(f"{where} = {v!r}: {expected}")
        out = np.zeros(3)
        out[AX.index(s)] = sign
        return out
    if not (isinstance(v, (list, tuple, np.ndarray)) and len(v) == 3 and all(
            isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool) for x in v)):
        raise error(f"{where} = {v!r}: {expected}")
    out = np.asarray(v, float)
    if not np.all(np.isfinite(out)):
        raise error(f"{where} = {v!r}: {expected}")
    if abs(np.linalg.norm(out) - 1.0) > 1e-6:
        raise error(f"{where} = {v!r}: expected a unit vector (its length is {np.linalg.norm(out):.6g})")
    return out / np.linalg.norm(out)


def parse_segments(kinds, where: str = "segments", error=LogFormatError) -> dict:
    """``{label: {"kind": "static"[, "up": ...]} | {"kind": "rotation", "axis": ..., "angle_deg": ...}
    | {"kind": "excluded"}}`` checked -> {label: {"kind", "up" (vector or None), "axis", "angle"
    [rad]}}; a broken description raises *error* naming ``where`` and the label."""
    if not isinstance(kinds, dict):
        raise error(f"{where}: expected an object label -> segment description, got {type(kinds).__name__}")
    out = {}
    for label, d in kinds.items():
        w = f"{where}: segment {str(label)!r}"
        if not isinstance(d, dict) or d.get("kind") not in KINDS:
            raise error(f"{w}: expected {{'kind': 'static' | 'rotation' | 'excluded', ...}}, got {d!r}")
        k = d["kind"]
        extra = set(d) - KINDS[k]
        if extra:
            raise error(f"{w}: unknown key(s) {sorted(extra)} for kind {k!r}; expected some of {sorted(KINDS[k])}")
        e = {"kind": k}
        if k == "static":
            e["up"] = body_vector(d["up"], f"{w}: up", error) if d.get("up") is not None else None
        elif k == "rotation":
            if "axis" not in d or "angle_deg" not in d:
                raise error(f"{w}: a rotation needs 'axis' (a body axis) and 'angle_deg' (its total angle)")
            e["axis"] = body_vector(d["axis"], f"{w}: axis", error)
            a = d["angle_deg"]
            if isinstance(a, bool) or not isinstance(a, (int, float)) or not math.isfinite(a) or a == 0:
                raise error(f"{w}: angle_deg = {a!r}: expected a non-zero number of degrees")
            e["angle"] = math.radians(a)
        out[str(label)] = e
    return out
