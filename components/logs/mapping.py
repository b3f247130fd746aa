"""The mapping file of ``calbench import`` (TOML, docs/import.md): which file holds what, in which
unit and kind, and what calbench must be told that the foreign file does not say. Parsed and
checked here; every mistake is one :class:`MappingError` naming the mapping file and the key."""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from components.errors import MappingError
from components.logs.mapping_keys import SOURCE_KEYS, check_keys
from components.model.effects import DEG, G0

AX = "xyz"
FORMATS = ("csv", "tsv", "parquet", "mat", "hdf5")
SUFFIX_FORMAT = {".csv": "csv", ".txt": "csv", ".tsv": "tsv", ".parquet": "parquet", ".mat": "mat",
                 ".h5": "hdf5", ".hdf5": "hdf5", ".hdf": "hdf5"}
# per channel kind: the units a user may name, in SI per unit
RATE_UNITS = {"rad/s": 1.0, "deg/s": DEG, "deg/h": DEG / 3600, "mrad/s": 1e-3, "rpm": 2 * math.pi / 60}
ANGLE_UNITS = {"rad": 1.0, "deg": DEG, "arcsec": DEG / 3600, "mrad": 1e-3, "urad": 1e-6}
FORCE_UNITS = {"m/s2": 1.0, "g": G0, "mg": 1e-3 * G0, "ug": 1e-6 * G0}
VELOCITY_UNITS = {"m/s": 1.0, "mm/s": 1e-3, "cm/s": 1e-2}
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
TEMPERATURE_UNITS = ("degC", "K", "degF")
GYRO_KINDS = {"rate": RATE_UNITS, "increment": ANGLE_UNITS, "counts": ANGLE_UNITS}
ACC_KINDS = {"specific_force": FORCE_UNITS, "increment": VELOCITY_UNITS, "counts": VELOCITY_UNITS}
TIMINGS = ("nominal", "measured", "regularise")
CLOCKS = ("host", "sensor")  # imu.time.keeps_time: which clock keeps time where the two drift apart
# table.time.clock: what stamps a table file, the host that stamps the IMU's samples or the table
# controller's own clock (it tells where the angles are matched when the host's clock drifts)
TABLE_CLOCKS = ("host", "controller")


@dataclass
class Source:
    """One input file and how to read it."""

    path: Path
    format: str
    delimiter: str = ","
    skip_rows: int = 0          # lines before the header row
    decimal: str = "."
    header: bool = True         # False: columns are referred to by index (0-based)
    key: str = "imu"            # the mapping's table that names this file ("imu", "table"), for messages
    lost_rows: bool = False     # a row with an empty or NaN number is a lost packet, left out


@dataclass
class Channel:
    """A column of the source (``-name`` flips the sign), its unit, and the raw-to-unit map
    value = (raw − offset) × scale (ADC counts)."""

    column: str | int
    sign: float = 1.0
    scale: float = 1.0
    offset: float = 0.0


@dataclass
class Sensor:
    output: str                 # rate | increment | counts (gyro); specific_force | increment | counts
    unit_si: float              # SI per unit of the values after (raw − offset) × scale
    count_weight: float | None  # counts: one count [rad] or [m/s]
    axes: list[Channel] = field(default_factory=list)
    unit: str = ""              # the unit as the mapping names it ("" for counts)
    accumulated: bool = False   # the columns are running totals of the increments (or counts)
    rollover: float | None = None  # a total's period in the column's raw values (a 16-bit counter: 65536)
    full_scale: list | None = None  # the output's range per axis, SI (rad/s; m/s²), if given


@dataclass
class Axis:
    name: str
    vector: list[float]
    channel: Channel
    unit_si: float
    command: Channel | None = None


@dataclass
class Mapping:
    where: str                  # the mapping file, for messages
    imu: Source
    time: Channel
    time_si: float
    sample_rate_hz: float
    timing: str
    max_interval_s: float | None
    gyro: Sensor
    acc: Sensor
    temperature: Channel | None = None
    temperature_unit: str = "degC"
    # the temperature read less often than the samples, its cells between readings empty
    temperature_sparse: bool = False
    labels: Channel | None = None
    label_ranges: list = field(default_factory=list)   # [(t0, t1, label)] [s, IMU clock]
    segments: dict | None = None
    exclude: list = field(default_factory=list)
    site: dict = field(default_factory=dict)
    table: Source | None = None
    table_time: Channel | None = None
    table_time_si: float = 1.0
    axes: list[Axis] = field(default_factory=list)
    clock_offset: float | str | None = None  # s (table + offset = IMU time), "estimate", or None (same clock)
    clock_rate: float = 0.0     # the IMU's clock gains this (s/s) on the table's (table.clock_rate_ppm)
    clock_curve: object = None  # the offset beyond its line, as an estimate found it (clock_curve.ClockCurve)
    encoder_resolution: object = None
    # round the logged angles to whole counts of encoder_resolution (readings with noise finer
    # than the count: an interpolating encoder, a filtered angle)
    round_to_count: bool = False
    description: str = ""
    keeps_time: str = "host"    # a drift followed by regularise: the host's clock keeps time, or the sensor's
    table_clock: str | None = None  # what stamps the table file (TABLE_CLOCKS); None: not said
    # the period [s] of a time counter that rolls over (a 32-bit microsecond count: 4294.967296 s)
    time_rollover_s: float | None = None
    table_time_rollover_s: float | None = None
    # "measured": the table file's stamps are its samples' times; "regularise": a clock coarser
    # than its samples stamped them, and a grid at table_rate_hz fitted to them replaces them
    table_timing: str = "measured"
    table_rate_hz: float | None = None
    # a sample counter (a packet's sequence number): its column, its period where it rolls over,
    # and the counts it advances by a sample
    counter: Channel | None = None
    counter_rollover: float | None = None
    counter_step: int = 1


def _rollover(t: dict, key: str, unit_si: float, where: str) -> float | None:
    """The period [s] of a time counter that rolls over, given as ``rollover`` in the column's
    unit (4294967296 for a 32-bit count of microseconds), or None."""
    if "rollover" not in t:
        return None
    r = _number(t["rollover"], f"{key}.rollover", where, "the counter's period in its unit (e.g. 4294967296)")
    if not r > 0:
        raise MappingError(f"{where}: key '{key}.rollover' = {r!r}: expected the counter's period, a positive number "
                           "in the column's unit")
    return r * unit_si


def _get(d: dict, key: str, where: str, expected: str, required: bool = True, default=None):
    if key not in d:
        if required:
            raise MappingError(f"{where}: missing key {key!r}; expected {expected}")
        return default
    return d[key]


def _number(v, key: str, where: str, expected: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise MappingError(f"{where}: key {key!r} = {v!r}: expected {expected}")
    return float(v)


def _unit(v, key: str, where: str, units) -> str:
    if v not in units:
        raise MappingError(f"{where}: key {key!r} = {v!r}: expected one of {', '.join(units)}")
    return v


def _quantity(v, key: str, where: str, units: dict) -> float:
    """A number with a unit of *units* (``"0.01 deg"``) in SI (components.model.quantities)."""
    from components.model.quantities import QuantityError, quantity

    try:
        return quantity(v, key, where, units, next(iter(units)))
    except QuantityError as e:
        raise MappingError(str(e)) from None


def _channel(v, key: str, where: str, d: dict | None = None) -> Channel:
    """A column reference: a name (``"gx"``, ``"-gx"`` flipped), or a 0-based index (``3``; no
    sign: a file without a header names its columns f0, f1, ..., and ``"-f3"`` flips the fourth)."""
    sign = 1.0
    if isinstance(v, str):
        s = v.strip()
        if s.startswith("-"):
            sign, s = -1.0, s[1:].strip()
        if not s:
            raise MappingError(f"{where}: key {key!r} = {v!r}: expected a column name")
        col: str | int = s
    elif isinstance(v, int) and not isinstance(v, bool) and v >= 0:
        col = v
    else:
        raise MappingError(f"{where}: key {key!r} = {v!r}: expected a column name (a leading '-' flips the sign) "
                           "or a 0-based column index")
    ch = Channel(col, sign)
    if d:
        if "scale" in d:
            ch.scale = _number(d["scale"], f"{key.rsplit('.', 1)[0]}.scale", where, "a number (unit per raw count)")
        if "offset" in d:
            ch.offset = _number(d["offset"], f"{key.rsplit('.', 1)[0]}.offset", where, "a number (raw zero)")
    return ch


def _source(d: dict, key: str, where: str, base: Path) -> Source:
    f = _get(d, "file", f"{where} [{key}]", "the input file (relative to the mapping file)")
    if not isinstance(f, str) or not f:
        raise MappingError(f"{where}: key '{key}.file' = {f!r}: expected a file name")
    path = (base / f) if not Path(f).is_absolute() else Path(f)
    fmt = d.get("format") or SUFFIX_FORMAT.get(path.suffix.lower())
    if fmt not in FORMATS:
        raise MappingError(f"{where}: key '{key}.format' = {fmt!r} (file {path.name}): expected one of "
                           f"{', '.join(FORMATS)}")
    src = Source(path, fmt, delimiter="\t" if fmt == "tsv" else ",", key=key)
    if "delimiter" in d:
        if not isinstance(d["delimiter"], str) or len(d["delimiter"]) != 1:
            raise MappingError(f"{where}: key '{key}.delimiter' = {d['delimiter']!r}: expected one character")
        src.delimiter = d["delimiter"]
    if "skip_rows" in d:
        k = d["skip_rows"]
        if isinstance(k, bool) or not isinstance(k, int) or k < 0:
            raise MappingError(f"{where}: key '{key}.skip_rows' = {k!r}: expected a whole number >= 0")
        src.skip_rows = k
    if "decimal" in d:
        if d["decimal"] not in (".", ","):
            raise MappingError(f"{where}: key '{key}.decimal' = {d['decimal']!r}: expected '.' or ','")
        src.decimal = d["decimal"]
        if src.decimal == src.delimiter:
            raise MappingError(f"{where}: key '{key}.decimal' is the delimiter {src.delimiter!r} too")
    if "header" in d:
        if not isinstance(d["header"], bool):
            raise MappingError(f"{where}: key '{key}.header' = {d['header']!r}: expected true or false")
        src.header = d["header"]
    if "lost_rows" in d:
        if not isinstance(d["lost_rows"], bool):
            raise MappingError(f"{where}: key '{key}.lost_rows' = {d['lost_rows']!r}: expected true or false")
        src.lost_rows = d["lost_rows"]
    return src


def _sensor(d: dict, key: str, where: str, kinds: dict, weight_units: dict, range_units: dict) -> Sensor:
    if not isinstance(d, dict):
        raise MappingError(f"{where}: key {key!r}: expected a table with output, unit, x, y, z")
    check_keys(d, key, where)
    out = _unit(_get(d, "output", f"{where} [{key}]", f"one of {', '.join(kinds)}"), f"{key}.output", where, kinds)
    weight, unit = None, ""
    if out == "counts":
        weight = _quantity(_get(d, "count", f"{where} [{key}]", "the weight of one count, e.g. '1e-6 rad'"),
                           f"{key}.count", where, weight_units)
        if not weight > 0:
            raise MappingError(f"{where}: key '{key}.count': expected a positive count weight")
        unit_si = weight
    else:
        unit = _unit(_get(d, "unit", f"{where} [{key}]", f"one of {', '.join(kinds[out])}"), f"{key}.unit", where,
                     kinds[out])
        unit_si = kinds[out][unit]
    s = Sensor(out, unit_si, weight, unit=unit)
    for a in AX:
        s.axes.append(_channel(_get(d, a, f"{where} [{key}]", f"the column of the {a} axis"), f"{key}.{a}", where, d))
    acc = d.get("accumulated", False)
    if not isinstance(acc, bool):
        raise MappingError(f"{where}: key '{key}.accumulated' = {acc!r}: expected true (the columns are running totals) "
                           "or false")
    if acc and out not in ("increment", "counts"):
        raise MappingError(f"{where}: key '{key}.accumulated' = true with output = {out!r}: a running total is of "
                           "increments or counts; expected output = 'increment' or 'counts'")
    s.accumulated = acc
    if "rollover" in d:
        if not acc:
            raise MappingError(f"{where}: key '{key}.rollover': a rollover is a running total's; expected "
                               f"'{key}.accumulated' = true beside it")
        r = _number(d["rollover"], f"{key}.rollover", where, "the total's period in the column's values (e.g. 65536)")
        if not r > 0:
            raise MappingError(f"{where}: key '{key}.rollover' = {r!r}: expected the total's period, a positive number")
        s.rollover = r
    if "range" in d:
        given = d["range"] if isinstance(d["range"], list) else [d["range"]] * 3
        if len(given) != 3:
            raise MappingError(f"{where}: key '{key}.range' has {len(given)} value(s); expected the output's full "
                               f"scale, one for all axes or a list of three, each '<number> <unit>' ({', '.join(range_units)})")
        s.full_scale = [_quantity(v, f"{key}.range", where, range_units) for v in given]
        if not all(v > 0 for v in s.full_scale):
            raise MappingError(f"{where}: key '{key}.range' = {d['range']!r}: expected a positive full scale")
    return s


def load_mapping(path: str | Path) -> Mapping:
    """The mapping file *path*, checked."""
    p = Path(path)
    where = str(p)
    try:
        d = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MappingError(f"{where}: the mapping file does not exist") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise MappingError(f"{where}: not a valid TOML file ({e})") from None
    base = p.parent
    check_keys(d, "", where)
    imu = _get(d, "imu", where, "an [imu] table: the IMU's file and columns")
    if not isinstance(imu, dict):
        raise MappingError(f"{where}: key 'imu': expected a table")
    check_keys(imu, "imu", where)
    src = _source(imu, "imu", where, base)
    fs = _number(_get(imu, "sample_rate_hz", f"{where} [imu]", "the IMU's nominal sample rate [Hz]"),
                 "imu.sample_rate_hz", where, "a positive sample rate [Hz]")
    if fs <= 0:
        raise MappingError(f"{where}: key 'imu.sample_rate_hz' = {fs!r}: expected a positive sample rate [Hz]")
    t = _get(imu, "time", f"{where} [imu]", "a [imu.time] table: column and unit")
    if not isinstance(t, dict):
        raise MappingError(f"{where}: key 'imu.time': expected a table with column and unit")
    check_keys(t, "imu.time", where)
    time = _channel(_get(t, "column", f"{where} [imu.time]", "the time column"), "imu.time.column", where)
    tu = TIME_UNITS[_unit(t.get("unit", "s"), "imu.time.unit", where, TIME_UNITS)]
    timing = _unit(t.get("timing", "nominal"), "imu.time.timing", where, TIMINGS)
    mx = t.get("max_interval_s")
    if mx is not None:
        mx = _number(mx, "imu.time.max_interval_s", where, "the longest interval that is not a gap [s]")
        if mx * fs <= 1.0:
            raise MappingError(f"{where}: key 'imu.time.max_interval_s' = {mx!r}: expected more than 1/sample_rate_hz")
    rollover = _rollover(t, "imu.time", tu, where)
    keeps = _unit(t.get("keeps_time", "host"), "imu.time.keeps_time", where, CLOCKS)
    if "keeps_time" in t and timing != "regularise":
        raise MappingError(f"{where}: key 'imu.time.keeps_time' = {keeps!r}: it says which clock keeps time where a "
                           f"sensor's and its host's drift apart, which only timing = 'regularise' follows (timing is "
                           f"{timing!r})")
    m = Mapping(where, src, time, tu, fs, timing, mx,
                _sensor(_get(imu, "gyro", f"{where} [imu]", "an [imu.gyro] table"), "imu.gyro", where, GYRO_KINDS,
                        ANGLE_UNITS, RATE_UNITS),
                _sensor(_get(imu, "acc", f"{where} [imu]", "an [imu.acc] table"), "imu.acc", where, ACC_KINDS,
                        VELOCITY_UNITS, FORCE_UNITS))
    m.time_rollover_s = rollover
    if "temperature" in imu:
        td = imu["temperature"]
        if not isinstance(td, dict):
            raise MappingError(f"{where}: key 'imu.temperature': expected a table with column and unit")
        check_keys(td, "imu.temperature", where)
        m.temperature = _channel(_get(td, "column", f"{where} [imu.temperature]", "the column"),
                                 "imu.temperature.column", where, td)
        m.temperature_unit = _unit(td.get("unit", "degC"), "imu.temperature.unit", where, TEMPERATURE_UNITS)
        sparse = td.get("sparse", False)
        if not isinstance(sparse, bool):
            raise MappingError(f"{where}: key 'imu.temperature.sparse' = {sparse!r}: expected true (read less often "
                               "than the samples: the cells between readings empty) or false")
        m.temperature_sparse = sparse
    _counter(imu, m, where)
    _labels(d, m, where)
    _table(d, m, where, base)
    if keeps == "sensor" and m.table is not None and m.table_clock is None:
        # the two answers differ by the host's bow (milliseconds); neither is a safe default
        raise MappingError(f"{where}: key 'table.time.clock' is needed with imu.time.keeps_time = 'sensor' (the host's "
                           "clock drifting): say what stamps the table file, 'host' (the host that stamps the IMU's "
                           "samples: the angles are taken at its stamps) or 'controller' (the table controller's own "
                           "clock: the angles are matched against the sensor's clock)")
    site = d.get("site", {})
    if not isinstance(site, dict):
        raise MappingError(f"{where}: key 'site': expected a table")
    check_keys(site, "site", where)
    lat = _number(_get(site, "latitude_deg", f"{where} [site]", "the latitude [deg]"), "site.latitude_deg", where,
                  "a latitude in degrees")
    if not -90 <= lat <= 90:
        raise MappingError(f"{where}: key 'site.latitude_deg' = {lat!r}: expected a latitude in [-90, 90] degrees")
    g = site.get("gravity_mps2")
    m.site = {"latitude_deg": lat,
              "height_m": _number(site.get("height_m", 0.0), "site.height_m", where, "a height [m]"),
              "gravity_mps2": None if g is None else _number(g, "site.gravity_mps2", where, "gravity [m/s²]")}
    desc = d.get("description", "")
    if not isinstance(desc, str):
        raise MappingError(f"{where}: key 'description' = {desc!r}: expected text")
    m.description = desc
    m.keeps_time = keeps
    return m


def _counter(imu: dict, m: Mapping, where: str) -> None:
    """[imu.counter]: the sensor's sample counter (column, rollover: its period in counts, step:
    the counts a sample advances it by, default 1)."""
    if "counter" not in imu:
        return
    c = imu["counter"]
    if not isinstance(c, dict):
        raise MappingError(f"{where}: key 'imu.counter': expected a table with the counter's column")
    check_keys(c, "imu.counter", where)
    m.counter = _channel(_get(c, "column", f"{where} [imu.counter]", "the counter's column"), "imu.counter.column",
                         where)
    m.counter_rollover = _rollover(c, "imu.counter", 1.0, where)
    step = c.get("step", 1)
    if isinstance(step, bool) or not isinstance(step, int) or step < 1:
        raise MappingError(f"{where}: key 'imu.counter.step' = {step!r}: expected the counts a sample advances the "
                           "counter by, a whole number >= 1")
    m.counter_step = step


def _labels(d: dict, m: Mapping, where: str) -> None:
    lab = d.get("labels")
    if lab is not None:
        if not isinstance(lab, dict):
            raise MappingError(f"{where}: key 'labels': expected a table with column or ranges")
        check_keys(lab, "labels", where)
        if "column" in lab:
            m.labels = _channel(lab["column"], "labels.column", where)
            if m.labels.sign < 0:
                raise MappingError(f"{where}: key 'labels.column' = {lab['column']!r}: a label column has no sign")
        for i, r in enumerate(lab.get("ranges", [])):
            k = f"labels.ranges[{i}]"
            if not isinstance(r, dict):
                raise MappingError(f"{where}: key {k!r}: expected {{from, to, label}}")
            check_keys(r, "labels.ranges", where, k)
            t0 = _number(_get(r, "from", f"{where} [{k}]", "the start [s, IMU clock]"), f"{k}.from", where, "a time [s]")
            t1 = _number(_get(r, "to", f"{where} [{k}]", "the end [s, IMU clock]"), f"{k}.to", where, "a time [s]")
            name = _get(r, "label", f"{where} [{k}]", "the label")
            if not t0 < t1 or not isinstance(name, str) or not name:
                raise MappingError(f"{where}: key {k!r} = {r!r}: expected from < to and a non-empty label")
            m.label_ranges.append((t0, t1, name))
        if m.labels is not None and m.label_ranges:
            raise MappingError(f"{where}: key 'labels': give a column or ranges, not both")
    segs = d.get("segments")
    if segs is not None:
        from components.logs.segments import parse_segments

        parse_segments(segs, f"{where}: key 'segments'", MappingError)
        m.segments = segs
    ex = d.get("exclude", [])
    from components.logs.rules import parse_exclude

    try:
        m.exclude = parse_exclude(ex, f"{where}: key 'exclude'")
    except ValueError as e:
        raise MappingError(str(e)) from None


def _table(d: dict, m: Mapping, where: str, base: Path) -> None:
    tab = d.get("table")
    if tab is None:
        return
    if not isinstance(tab, dict):
        raise MappingError(f"{where}: key 'table': expected a table")
    check_keys(tab, "table", where)
    unused = [k for k in SOURCE_KEYS if k in tab and k != "file"] if "file" not in tab else []
    if unused:
        raise MappingError(f"{where}: key 'table.{unused[0]}' describes a table file, but [table] names none (no "
                           "'table.file'): the table's columns are in the IMU's file, read as [imu] says"
                           + (" (give imu.lost_rows)" if unused[0] == "lost_rows" else ""))
    m.table = _source(tab, "table", where, base) if "file" in tab else None
    if m.table is not None:
        tt = _get(tab, "time", f"{where} [table]", "a [table.time] table: the table file's time column and unit")
        if not isinstance(tt, dict):
            raise MappingError(f"{where}: key 'table.time': expected a table with column and unit")
        check_keys(tt, "table.time", where)
        m.table_time = _channel(_get(tt, "column", f"{where} [table.time]", "the time column"), "table.time.column",
                                where)
        m.table_time_si = TIME_UNITS[_unit(tt.get("unit", "s"), "table.time.unit", where, TIME_UNITS)]
        m.table_time_rollover_s = _rollover(tt, "table.time", m.table_time_si, where)
        m.table_timing = _unit(tt.get("timing", "measured"), "table.time.timing", where, ("measured", "regularise"))
        if "sample_rate_hz" in tab:
            m.table_rate_hz = _number(tab["sample_rate_hz"], "table.sample_rate_hz", where, "a positive sample rate [Hz]")
            if not m.table_rate_hz > 0:
                raise MappingError(f"{where}: key 'table.sample_rate_hz' = {m.table_rate_hz!r}: expected a positive "
                                   "sample rate [Hz]")
        if m.table_rate_hz is not None and m.table_timing != "regularise":
            raise MappingError(f"{where}: key 'table.sample_rate_hz': only the grid of table.time.timing = 'regularise' "
                               "uses it (the table's stamps are its readings' times); give both or neither")
        if m.table_timing == "regularise" and m.table_rate_hz is None:
            raise MappingError(f"{where}: key 'table.time.timing' = 'regularise' needs 'table.sample_rate_hz': the "
                               "rate the table file's samples were taken at (the grid replacing its stamps)")
        if "clock" in tt:
            m.table_clock = _unit(tt["clock"], "table.time.clock", where, TABLE_CLOCKS)
        off = tab.get("clock_offset_s", "estimate")
        if off != "estimate":
            off = _number(off, "table.clock_offset_s", where, "'estimate' or the offset [s] (table time + offset "
                                                              "= IMU time)")
        m.clock_offset = off
        if "clock_rate_ppm" in tab:
            if off == "estimate":
                raise MappingError(f"{where}: key 'table.clock_rate_ppm': with table.clock_offset_s = 'estimate' the "
                                   "rate between the clocks is estimated with the offset; give both or neither")
            m.clock_rate = _number(tab["clock_rate_ppm"], "table.clock_rate_ppm", where,
                                   "how many ppm the IMU's clock runs fast against the table's") * 1e-6
    axes = _get(tab, "axes", f"{where} [table]", "a list of {name, axis, column, unit}")
    if not isinstance(axes, list) or not axes:
        raise MappingError(f"{where}: key 'table.axes': expected a non-empty list of {{name, axis, column, unit}}")
    for i, a in enumerate(axes):
        k = f"table.axes[{i}]"
        if not isinstance(a, dict):
            raise MappingError(f"{where}: key {k!r}: expected {{name, axis, column, unit}}")
        check_keys(a, "table.axes", where, k)
        name = _get(a, "name", f"{where} [{k}]", "the axis name")
        vec = _get(a, "axis", f"{where} [{k}]", "the unit axis vector [x, y, z]")
        if not (isinstance(vec, list) and len(vec) == 3 and all(isinstance(x, (int, float)) for x in vec)):
            raise MappingError(f"{where}: key '{k}.axis' = {vec!r}: expected a unit vector of 3 numbers")
        unit = _unit(a.get("unit", "rad"), f"{k}.unit", where, ANGLE_UNITS)
        ch = _channel(_get(a, "column", f"{where} [{k}]", "the angle column"), f"{k}.column", where, a)
        cmd = _channel(a["command"], f"{k}.command", where) if "command" in a else None
        m.axes.append(Axis(str(name), [float(x) for x in vec], ch, ANGLE_UNITS[unit], cmd))
    res = tab.get("encoder_resolution")
    if res is not None:
        m.encoder_resolution = "exact" if res == "exact" else _quantity(res, "table.encoder_resolution", where,
                                                                        ANGLE_UNITS)
    rounding = tab.get("round_to_count", False)
    if not isinstance(rounding, bool):
        raise MappingError(f"{where}: key 'table.round_to_count' = {rounding!r}: expected true or false")
    if rounding and (m.encoder_resolution is None or m.encoder_resolution == "exact"):
        raise MappingError(f"{where}: key 'table.round_to_count' = true needs 'table.encoder_resolution' as an "
                           "angle (one count, e.g. \"0.0001 deg\"): the count to round the angles to")
    m.round_to_count = rounding
