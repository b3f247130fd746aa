"""The rules of the ``calbench-log/1`` and ``calbench-log/2`` formats (docs/measurement-log.md),
checked on metadata and sample columns; every broken rule raises :class:`LogFormatError` naming
the file, the key or the data row and what was expected. Choices the spec leaves open are stated
in components/logs/logfile.py.

Version 2 adds what logs of other rigs need, all optional: no table angles (``table.axes`` = []),
the encoder resolution, measured timing with gaps, what each segment label is, time ranges and
labels to leave out, the noise if known, and a ``mask`` column. A key of version 2 in a file that
says version 1 is refused (it would otherwise be kept and ignored without a word)."""
from __future__ import annotations

import math
import re

import numpy as np

from components.errors import LogFormatError
from components.logs.spill import pieces

FORMAT = "calbench-log/1"
FORMAT_V2 = "calbench-log/2"
FORMATS = (FORMAT, FORMAT_V2)
TIMINGS = ("nominal", "measured")
# keys only version 2 gives a meaning to: (path, what it is)
V2_KEYS = (("table.encoder_resolution_rad", "the encoder resolution"), ("imu.timing", "the timing rule"),
           ("imu.max_interval_s", "the longest interval that is not a gap"), ("imu.noise", "the noise model"),
           ("segments", "what each segment label is"), ("exclude", "what to leave out"),
           ("imu.gyro_range_radps", "the gyros' output range"), ("imu.acc_range_mps2", "the accelerometers' output range"))
# the output range keys: (sensor, key, its unit)
RANGE_KEYS = (("gyro", "gyro_range_radps", "rad/s"), ("acc", "acc_range_mps2", "m/s²"))
# the metadata's keys per block: another key is kept and ignored (other software's own), unless
# it is within a letter or two of one of these, a typing mistake that would silently drop the
# key meant ('timming': the samples taken at their nominal times)
KNOWN_KEYS = {
    "": ("format", "site", "table", "imu", "description", "segments", "exclude"),
    "site": ("latitude_deg", "height_m", "gravity_mps2"),
    "table": ("axes", "encoder_resolution_rad"),
    "imu": ("sample_rate_hz", "gyro_output", "acc_output", "gyro_count_rad", "acc_count_mps", "timing",
            "max_interval_s", "noise", "gyro_range_radps", "acc_range_mps2"),
}
MAX_METADATA_DEPTH = 32
GYRO_OUTPUTS = {"rate": "rad/s", "increment": "rad", "counts": "counts of gyro_count_rad"}
ACC_OUTPUTS = {"specific_force": "m/s²", "increment": "m/s", "counts": "counts of acc_count_mps"}
GAP_REL_TOL = 0.01
GAP_ABS_TOL = 1e-6
AXIS_NORM_TOL = 1e-9
XYZ = ("x", "y", "z")
NUMBER = re.compile(r"^\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*$")
NONFINITE = re.compile(r"^\s*[+-]?(nan|inf|infinity)\s*$", re.IGNORECASE)


def _key(meta: dict, path: str, where: str, expected: str, required: bool = True):
    node = meta
    parts = path.split(".")
    for i, p in enumerate(parts):
        if not isinstance(node, dict):
            raise LogFormatError(f"{where}: key {'.'.join(parts[:i])!r}: expected an object")
        if p not in node:
            if not required:
                return None
            raise LogFormatError(f"{where}: missing key {path!r}; expected {expected}")
        node = node[p]
    return node


def _number(v, path: str, where: str, expected: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise LogFormatError(f"{where}: key {path!r} = {v!r}: expected {expected}")
    return float(v)


def parse_metadata(meta, where: str) -> dict:
    if not isinstance(meta, dict):
        raise LogFormatError(f"{where}: expected a JSON object at the top level")
    _check_depth(meta, where)
    fmt = _key(meta, "format", where, f'"{FORMAT}" or "{FORMAT_V2}"')
    if fmt not in FORMATS:
        hint = " (a newer version of the format: update calbench)" if isinstance(fmt, str) and \
            fmt.startswith("calbench-log/") else ""
        raise LogFormatError(f"{where}: key 'format' = {fmt!r}: expected {FORMAT!r} or {FORMAT_V2!r}{hint}")
    v2 = fmt == FORMAT_V2
    if not v2:
        for path, what in V2_KEYS:
            if _key(meta, path, where, "", required=False) is not None:
                raise LogFormatError(f"{where}: key {path!r} ({what}) belongs to {FORMAT_V2!r}, but 'format' is "
                                     f"{FORMAT!r}; set 'format' to {FORMAT_V2!r}")
    _misspelt_keys(meta, where)
    out: dict = {"format": fmt}
    lat = _number(_key(meta, "site.latitude_deg", where, "a latitude in degrees"), "site.latitude_deg",
                  where, "a latitude in degrees")
    if not -90.0 <= lat <= 90.0:
        raise LogFormatError(f"{where}: key 'site.latitude_deg' = {lat!r}: expected a latitude in [-90, 90] degrees")
    out["latitude_deg"] = lat
    out["height_m"] = _number(_key(meta, "site.height_m", where, "a height [m]"), "site.height_m", where,
                              "a height [m]")
    g = _key(meta, "site.gravity_mps2", where, "a gravity [m/s²] or null (normal gravity)")
    if g is not None:
        g = _number(g, "site.gravity_mps2", where, "a positive gravity [m/s²] or null (normal gravity)")
        if g <= 0:
            raise LogFormatError(f"{where}: key 'site.gravity_mps2' = {g!r}: expected a positive gravity "
                                 "[m/s²] or null (normal gravity)")
    out["gravity_mps2"] = g
    axes = _key(meta, "table.axes", where, "a list of {name, axis}")
    if not isinstance(axes, list) or (not axes and not v2):
        expected = "a list of {name, axis} ([] for a log without table angles)" if v2 else \
            f"a non-empty list of {{name, axis}} (a log without table angles is {FORMAT_V2!r} with 'axes': [])"
        raise LogFormatError(f"{where}: key 'table.axes' = {axes!r}: expected {expected}")
    names, vecs = [], []
    for i, a in enumerate(axes):
        k = f"table.axes[{i}]"
        if not isinstance(a, dict):
            raise LogFormatError(f"{where}: key {k!r}: expected an object with 'name' and 'axis'")
        if "name" not in a:
            raise LogFormatError(f"{where}: missing key '{k}.name'; expected the axis name")
        if "axis" not in a:
            raise LogFormatError(f"{where}: missing key '{k}.axis'; expected a unit vector [x, y, z]")
        n = a["name"]
        if not isinstance(n, str) or not re.fullmatch(r"[A-Za-z0-9_]+", n):
            raise LogFormatError(f"{where}: key '{k}.name' = {n!r}: expected a name of letters, digits, '_'")
        if n in names:
            raise LogFormatError(f"{where}: key '{k}.name' = {n!r}: axis named twice")
        v = a["axis"]
        if not (isinstance(v, list) and len(v) == 3 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)):
            raise LogFormatError(f"{where}: key '{k}.axis' = {v!r}: expected a unit vector of 3 numbers")
        vec = np.array(v, dtype=float)
        norm = float(np.linalg.norm(vec))
        if norm == 0.0:
            raise LogFormatError(f"{where}: key '{k}.axis' = {v!r}: zero vector; expected a unit vector")
        if abs(norm - 1.0) > AXIS_NORM_TOL:
            raise LogFormatError(f"{where}: key '{k}.axis' = {v!r}: length {norm:.15g}; expected a unit "
                                 f"vector (length 1 within {AXIS_NORM_TOL:g})")
        names.append(n)
        vecs.append(vec)
    out["axis_names"], out["axis_vectors"] = names, np.array(vecs)
    fs = _number(_key(meta, "imu.sample_rate_hz", where, "a positive sample rate [Hz]"), "imu.sample_rate_hz",
                 where, "a positive sample rate [Hz]")
    if fs <= 0:
        raise LogFormatError(f"{where}: key 'imu.sample_rate_hz' = {fs!r}: expected a positive sample rate [Hz]")
    out["sample_rate_hz"] = fs
    for sensor, kinds, wkey, wunit in (("gyro", GYRO_OUTPUTS, "gyro_count_rad", "rad"),
                                       ("acc", ACC_OUTPUTS, "acc_count_mps", "m/s")):
        kind = _key(meta, f"imu.{sensor}_output", where, f"one of {', '.join(kinds)}")
        if kind not in kinds:
            raise LogFormatError(f"{where}: key 'imu.{sensor}_output' = {kind!r}: unknown output kind; "
                                 f"expected one of {', '.join(kinds)}")
        out[f"{sensor}_output"] = kind
        w = _key(meta, f"imu.{wkey}", where, "", required=False)
        if kind == "counts":
            if w is None:
                raise LogFormatError(f"{where}: key 'imu.{wkey}' is {'null' if 'imu' in meta and wkey in meta['imu'] else 'missing'}"
                                     f" but imu.{sensor}_output is 'counts'; expected the weight of one count [{wunit}]")
            w = _number(w, f"imu.{wkey}", where, f"a positive count weight [{wunit}]")
            if w <= 0:
                raise LogFormatError(f"{where}: key 'imu.{wkey}' = {w!r}: expected a positive count weight [{wunit}]")
        elif w is not None:
            w = _number(w, f"imu.{wkey}", where, f"a count weight [{wunit}] or null")
        out[wkey] = w
    d = meta.get("description", "")
    if not isinstance(d, str):
        raise LogFormatError(f"{where}: key 'description' = {d!r}: expected text")
    out["description"] = d
    out.update(_parse_v2(meta, out, where) if v2 else
               {"encoder_resolution": None, "timing": "nominal", "max_interval_s": None, "segments": None,
                "segment_kinds": None, "exclude": [], "noise": None, "gyro_range": None, "acc_range": None})
    out["extra_metadata"] = {k: v for k, v in meta.items()
                             if k not in ("format", "site", "table", "imu", "description", "segments", "exclude")}
    return out


def _misspelt_keys(meta: dict, where: str) -> None:
    """A key near one the format defines (KNOWN_KEYS; difflib's ratio 0.85 and up) but not it is
    one error naming both."""
    import difflib

    for block, known in KNOWN_KEYS.items():
        node = meta.get(block) if block else meta
        if not isinstance(node, dict):
            continue
        for k in node:
            near = difflib.get_close_matches(str(k), known, n=1, cutoff=0.85) if k not in known else []
            if near:
                at = f"{block}.{k}" if block else k
                raise LogFormatError(f"{where}: key {at!r} is not one of the format's: did you mean "
                                     f"'{f'{block}.' if block else ''}{near[0]}'? (other software's keys are kept and "
                                     "ignored, but not one a letter or two from the format's own)")


def _check_depth(meta, where: str) -> None:
    """Metadata nested deeper than any real file (a hostile or broken one) is refused before
    anything recurses through it."""
    stack = [(meta, 1)]
    while stack:
        node, d = stack.pop()
        if d > MAX_METADATA_DEPTH:
            raise LogFormatError(f"{where}: metadata nested deeper than {MAX_METADATA_DEPTH} levels; expected the "
                                 "flat object of docs/measurement-log.md")
        if isinstance(node, dict):
            stack.extend((v, d + 1) for v in node.values())
        elif isinstance(node, list):
            stack.extend((v, d + 1) for v in node)


def _parse_v2(meta: dict, out: dict, where: str) -> dict:
    """The optional keys of version 2, checked (docs/measurement-log.md, "Version 2")."""
    from components.logs.segments import parse_segments

    v2: dict = {}
    n_axes = len(out["axis_names"])
    res = _key(meta, "table.encoder_resolution_rad", where, "", required=False)
    if res is not None:
        expected = ("one count of the encoders [rad]: a positive number, a list of one per axis, or \"exact\" "
                    "(the logged angles at rest are the true ones)")
        if res == "exact":
            pass
        elif isinstance(res, list):
            if len(res) != n_axes:
                raise LogFormatError(f"{where}: key 'table.encoder_resolution_rad' has {len(res)} value(s) for "
                                     f"{n_axes} axes; expected {expected}")
            res = np.array([_number(x, "table.encoder_resolution_rad", where, expected) for x in res])
        else:
            res = np.full(n_axes, _number(res, "table.encoder_resolution_rad", where, expected))
        if not isinstance(res, str) and np.any(res <= 0):
            raise LogFormatError(f"{where}: key 'table.encoder_resolution_rad' = {res.tolist()!r}: expected {expected}")
        if n_axes == 0:
            raise LogFormatError(f"{where}: key 'table.encoder_resolution_rad' is given but 'table.axes' is []: "
                                 "a log without table angles has no encoder")
    v2["encoder_resolution"] = res
    timing = _key(meta, "imu.timing", where, "", required=False)
    if timing is None:
        timing = "nominal"
    if timing not in TIMINGS:
        raise LogFormatError(f"{where}: key 'imu.timing' = {timing!r}: expected 'nominal' (every interval is "
                             "1/sample_rate_hz) or 'measured' (each sample's own interval, gaps allowed)")
    v2["timing"] = timing
    mx = _key(meta, "imu.max_interval_s", where, "", required=False)
    if mx is not None:
        mx = _number(mx, "imu.max_interval_s", where, "the longest interval that is not a gap [s]")
        if timing != "measured":
            raise LogFormatError(f"{where}: key 'imu.max_interval_s' is given but 'imu.timing' is 'nominal': gaps "
                                 "are allowed only with 'imu.timing': 'measured'")
        if mx * out["sample_rate_hz"] <= 1.0:
            raise LogFormatError(f"{where}: key 'imu.max_interval_s' = {mx!r}: expected more than the nominal "
                                 f"interval 1/sample_rate_hz = {1.0 / out['sample_rate_hz']!r} s")
    v2["max_interval_s"] = mx
    segs = meta.get("segments")
    v2["segments"] = segs
    v2["segment_kinds"] = parse_segments(segs, f"{where}: key 'segments'") if segs is not None else None
    if n_axes == 0 and not v2["segment_kinds"]:
        raise LogFormatError(f"{where}: 'table.axes' is [] (no table angles) but there is no 'segments' key: "
                             "expected what each segment label is ({\"pos1\": {\"kind\": \"static\"}, \"rotX\": "
                             "{\"kind\": \"rotation\", \"axis\": \"x\", \"angle_deg\": 360}, ...})")
    v2["exclude"] = parse_exclude(meta.get("exclude", []), f"{where}: key 'exclude'")
    noise = _key(meta, "imu.noise", where, "", required=False)
    if noise is not None:
        from components.model.noise import NoiseModel

        try:
            NoiseModel.from_dict(noise)   # (it names what is missing or wrong, key by key)
        except ValueError as e:
            raise LogFormatError(f"{where}: key 'imu.noise': {e}; expected a calbench-noise/1 model (its "
                                 "'channels' block, as `calbench noise --out` writes)") from None
    v2["noise"] = noise
    for sensor, key, unit in RANGE_KEYS:
        v2[f"{sensor}_range"] = _output_range(_key(meta, f"imu.{key}", where, "", required=False), f"imu.{key}",
                                              where, unit)
    return v2


def _output_range(v, key: str, where: str, unit: str) -> np.ndarray | None:
    """A sensor's output range (full scale) per axis [*unit*], from a number for all three axes
    or a list of three; None when not given."""
    if v is None:
        return None
    expected = f"the output's full scale [{unit}]: a positive number, or a list of three (x, y, z)"
    vals = v if isinstance(v, list) else [v] * 3
    if len(vals) != 3:
        raise LogFormatError(f"{where}: key {key!r} has {len(vals)} value(s); expected {expected}")
    out = np.array([_number(x, key, where, expected) for x in vals])
    if np.any(out <= 0):
        raise LogFormatError(f"{where}: key {key!r} = {v!r}: expected {expected}")
    return out


def parse_exclude(items, where: str) -> list:
    """``[[t0, t1], "label", ...]`` checked -> the same list with float ranges (t0 < t1, s)."""
    if not isinstance(items, list):
        raise LogFormatError(f"{where} = {items!r}: expected a list of time ranges [t0, t1] [s] and/or segment "
                             "labels")
    out = []
    for i, it in enumerate(items):
        if isinstance(it, str):
            out.append(it)
            continue
        ok = isinstance(it, list) and len(it) == 2 and all(
            isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in it)
        if not ok or not it[0] < it[1]:
            raise LogFormatError(f"{where}[{i}] = {it!r}: expected a time range [t0, t1] with t0 < t1 [s] or a "
                                 "segment label")
        out.append([float(it[0]), float(it[1])])
    return out


# ---------------------------------------------------------------------------- columns / samples
def numeric_columns(header: list[str], meta: dict) -> list[str]:
    known = ["time"] + [c for c in header if c.startswith(("gimbal_", "command_"))]
    known += [f"{s}_{c}" for s in ("gyro", "acc") for c in XYZ] + ["temperature"]
    if meta.get("format") == FORMAT_V2:
        known.append("mask")
    return [c for c in header if c in known]


def check_columns(header: list[str], meta: dict, where: str) -> None:
    seen = set()
    for c in header:
        if c in seen:
            raise LogFormatError(f"{where}: column {c!r} appears twice in the header")
        seen.add(c)
    axes = meta["axis_names"]
    required = ["time"] + [f"gimbal_{a}" for a in axes] + [f"{s}_{c}" for s in ("gyro", "acc") for c in XYZ]
    for c in required:
        if c not in seen:
            why = f" (table.axes names axis {c[7:]!r})" if c.startswith("gimbal_") else ""
            raise LogFormatError(f"{where}: missing column {c!r}{why}; the header has: {', '.join(header)}")
    if not axes and "segment" not in seen:
        raise LogFormatError(f"{where}: missing column 'segment': a log without table angles ('table.axes' = []) "
                             f"needs a segment label per sample; the header has: {', '.join(header)}")
    for c in header:
        for prefix in ("gimbal_", "command_"):
            if c.startswith(prefix) and c[len(prefix):] not in axes:
                raise LogFormatError(f"{where}: column {c!r} is for axis {c[len(prefix):]!r}, which the "
                                     f"metadata's table.axes does not name (axes: {', '.join(axes)})")


def check_samples(cols: dict[str, np.ndarray], meta: dict, where: str, row) -> None:
    """Rules on the values; ``row(i)`` labels the 0-based sample i. (Segment labels that are not
    text are refused where a log takes them: MeasurementLog, components.logs.labels.)"""
    t = cols["time"]
    if len(t) == 0:
        raise LogFormatError(f"{where}: no samples; expected one row per IMU sample (after the header line, in a CSV file)")
    for name, a in cols.items():
        if name == "segment" or name not in numeric_columns(list(cols), meta):
            continue
        # a piece at a time: a whole column's mask was 30 MB of fresh pages per column of an
        # 8-hour log; a spilled column's pages go back after each piece (components.logs.spill)
        for s in pieces(len(a), a):
            ok = np.isfinite(a[s])
            if not ok.all():
                i = s.start + int(np.argmin(ok))
                raise LogFormatError(f"{where}: {row(i)}, column {name!r}: value {float(a[i])!r} is not finite; "
                                     "expected a finite number")
    h = 1.0 / meta["sample_rate_hz"]
    tol = max(GAP_REL_TOL * h, GAP_ABS_TOL)
    nominal = meta.get("timing", "nominal") == "nominal"
    # the intervals a piece at a time too: the whole log's differences and masks were 0.9 s of
    # fresh pages on an 8-hour log; the first offending row is the same
    first_off = None
    for s in pieces(len(t) - 1, t):
        dt = np.diff(t[s.start:s.stop + 1])
        if not (dt > 0).all():
            i = s.start + int(np.argmax(~(dt > 0))) + 1
            raise LogFormatError(f"{where}: {row(i)}, column 'time': {float(t[i])!r} s after {float(t[i - 1])!r} s; "
                                 "expected strictly increasing times")
        if nominal and first_off is None:
            off = np.abs(dt - h) > tol
            if off.any():
                first_off = s.start + int(np.argmax(off)) + 1
    if first_off is not None:
        i = first_off
        raise LogFormatError(
            f"{where}: {row(i)}, column 'time': interval {float(t[i] - t[i - 1])!r} s from the previous sample (t = {float(t[i - 1])!r} s"
            f" to {float(t[i])!r} s); expected 1/sample_rate_hz = {h!r} s within {tol:g} s (a gap or a wrong sample rate;"
            " a logger's own clock with jitter and gaps is 'imu.timing': 'measured' in calbench-log/2)")
    mask = cols.get("mask")
    if mask is not None:
        bad = (mask != 0) & (mask != 1)
        if bad.any():
            i = int(np.argmax(bad))
            raise LogFormatError(f"{where}: {row(i)}, column 'mask': {float(mask[i])!r}; expected 1 (use the sample) "
                                 "or 0 (leave it out)")
    for sensor in ("gyro", "acc"):
        if meta[f"{sensor}_output"] != "counts":
            continue
        for c in XYZ:
            a = cols[f"{sensor}_{c}"]
            # a piece at a time: a whole spilled column's rounding faulted in its sensor's three
            # columns and a copy of it beside them (compare on an 8-hour pulse log peaked at 2.93 GB
            # here, against 1.91 GB on the same log as increments)
            for s in pieces(len(a), a):
                frac = a[s] != np.round(a[s])
                if frac.any():
                    i = s.start + int(np.argmax(frac))
                    raise LogFormatError(f"{where}: {row(i)}, column '{sensor}_{c}': {float(a[i])!r} is not a whole "
                                         f"number; expected integer counts (imu.{sensor}_output is 'counts')")
