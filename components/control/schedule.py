"""Calibration schedules as data: a TOML file read into dataclasses.

A schedule is what the calibration controller (:mod:`components.control.controller`) walks. Layout::

    [schedule]
    name = "six-position"
    description = "free text"

    [parameters]            # named values a step may use as "$name" or "-$name" (the CLI / a scenario
    dwell = 30.0            # overrides them: `--dwell 5`)

    [settings]              # all optional
    settle_tol_deg = 4.29e-5        # |angle - command| to count as settled (default 2 counts of 2^24/rev)
    settle_rate_tol_dps = 5.7e-4    # |rate| to count as settled (default 1e-5 rad/s)
    settle_hold = 0.5               # s the two must hold
    index_timeout = 60.0            # s an index (or the stop of a rotation) may take to settle

    [[steps]]
    kind = "index"          # to angles_deg = [outer, middle, inner] (one per table axis,
    angles_deg = [0, 90, 0] # base to plate) and wait until settled; the shortest way round
    label = "pos01"         # (absolute = true: the angles as given, multi-turn)

    [[steps]]
    kind = "dwell"          # hold still for `duration` s
    duration = "$dwell"

    [[steps]]
    kind = "rotate"         # accelerate, n whole turns, stop exactly at start + n * 360 deg
    axis = "outer"          # a table axis: the controller's axis name, or outer/middle/inner
    rate_dps = -10.0        # = 1st/2nd/3rd axis from the base; signed
    turns = 2

    [[steps]]
    kind = "rate"           # constant rate for `duration` s, then stop (and hold where it stopped)
    axis = "inner"
    rate_dps = 30.0
    duration = 20.0

    [[steps]]
    kind = "tumble"         # expands into index + dwell pairs labelled pos01, pos02, ...
    attitudes_deg = [[0, 0, 0], [0, 180, 0]]
    dwell = "$dwell"
    prefix = "pos"          # optional; numbering continues over the schedule per prefix

    [[steps]]
    kind = "repeat"         # the nested steps `times` times; labels get "-c1", "-c2", ...
    times = 2
    [[steps.steps]]
    kind = "dwell"
    duration = 1.0

Every step takes an optional ``label``: the segment label of its samples (an index's samples
are labelled ``move-<label>``). Default labels: ``<kind><step number>`` (``dwell03``).

Units: SI inside (rad, rad/s, s). In the file, keys ending ``_deg`` / ``_dps`` are degrees and
degrees per second, converted here; durations are seconds.

Every mistake raises :class:`ScheduleError` naming the file, the step number (1-based, ``3.2``
for the 2nd step inside the 3rd), the key, and what was expected.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

from components.errors import ScheduleError

DEG = math.pi / 180.0
COUNTS_PER_REV = 2 ** 24
KINDS = ("index", "dwell", "rotate", "rate", "tumble", "repeat")
AXIS_POSITIONS = ("outer", "middle", "inner")


@dataclass(frozen=True)
class Settings:
    settle_tol: float = 2 * 2 * math.pi / COUNTS_PER_REV   # rad
    settle_rate_tol: float = 1e-5                           # rad/s
    settle_hold: float = 0.5                                # s
    index_timeout: float = 60.0                             # s


@dataclass(frozen=True)
class Index:
    angles: tuple[float, ...]   # rad, base-to-plate order
    label: str
    absolute: bool = False      # False: each axis the shortest way round (mod 360 deg)
    origin: str = ""            # step number in the file, for messages
    kind: str = "index"

    @property
    def segment_labels(self) -> list[str]:
        return [f"move-{self.label}"]


@dataclass(frozen=True)
class Dwell:
    duration: float             # s
    label: str
    origin: str = ""
    kind: str = "dwell"

    @property
    def segment_labels(self) -> list[str]:
        return [self.label]


@dataclass(frozen=True)
class Rotate:
    axis: str | int             # axis name, or 0-based position from the base
    rate: float                 # rad/s, signed
    turns: int
    label: str
    origin: str = ""
    kind: str = "rotate"

    @property
    def segment_labels(self) -> list[str]:
        return [self.label]


@dataclass(frozen=True)
class Rate:
    axis: str | int
    rate: float                 # rad/s, signed
    duration: float             # s
    label: str
    origin: str = ""
    kind: str = "rate"

    @property
    def segment_labels(self) -> list[str]:
        return [self.label]


Step = Index | Dwell | Rotate | Rate


@dataclass
class Schedule:
    name: str
    steps: list[Step]           # expanded: tumble and repeat are resolved
    settings: Settings = field(default_factory=Settings)
    parameters: dict = field(default_factory=dict)
    description: str = ""
    source: str = "schedule"

    @property
    def labels(self) -> list[str]:
        """Segment labels in order of first appearance (the controller's ``segment`` indexes this)."""
        out: dict[str, None] = {}
        for s in self.steps:
            for lab in s.segment_labels:
                out.setdefault(lab, None)
        return list(out)

    def n_angles(self) -> int | None:
        """Number of table axes the index steps address (None: no index step)."""
        for s in self.steps:
            if isinstance(s, Index):
                return len(s.angles)
        return None

    def time_bound(self, acc: float = 200 * DEG) -> float:
        """An upper bound of the run time [s] for a table that settles within the timeouts and
        accelerates at ``acc`` [rad/s^2] or faster."""
        st = self.settings
        total = 0.0
        for s in self.steps:
            if isinstance(s, Dwell):
                total += s.duration
            elif isinstance(s, Index):
                total += st.index_timeout
            elif isinstance(s, Rotate):
                total += s.turns * 2 * math.pi / abs(s.rate) + 2 * abs(s.rate) / acc + st.index_timeout
            elif isinstance(s, Rate):
                total += s.duration + 2 * abs(s.rate) / acc + 2 * st.index_timeout
        return total + 1.0

    def describe(self) -> str:
        lines = [f"schedule {self.name}: {len(self.steps)} steps, {len(self.labels)} segment labels"]
        for s in self.steps:
            if isinstance(s, Index):
                lines.append(f"  index  {s.label:14s} " + " ".join(f"{a / DEG:9.3f}" for a in s.angles) + " deg")
            elif isinstance(s, Dwell):
                lines.append(f"  dwell  {s.label:14s} {s.duration:g} s")
            elif isinstance(s, Rotate):
                lines.append(f"  rotate {s.label:14s} axis {s.axis} {s.rate / DEG:+g} deg/s x {s.turns} turns")
            else:
                lines.append(f"  rate   {s.label:14s} axis {s.axis} {s.rate / DEG:+g} deg/s for {s.duration:g} s")
        return "\n".join(lines)


# ----------------------------------------------------------------------------- parsing
_STEP_KEYS = {
    "index": {"kind", "label", "angles_deg", "absolute"},
    "dwell": {"kind", "label", "duration"},
    "rotate": {"kind", "label", "axis", "rate_dps", "turns"},
    "rate": {"kind", "label", "axis", "rate_dps", "duration"},
    "tumble": {"kind", "label", "attitudes_deg", "dwell", "prefix", "absolute"},
    "repeat": {"kind", "times", "steps"},
}
_SETTINGS = {"settle_tol_deg": ("settle_tol", DEG), "settle_rate_tol_dps": ("settle_rate_tol", DEG),
             "settle_hold": ("settle_hold", 1.0), "index_timeout": ("index_timeout", 1.0)}


class _Parser:
    def __init__(self, source: str, parameters: dict):
        self.source = source
        self.parameters = parameters
        self.counters: dict[str, int] = {}

    def err(self, where: str, msg: str) -> ScheduleError:
        return ScheduleError(f"{self.source}: {where}: {msg}")

    def value(self, d: dict, key: str, where: str, expected: str, check, default=...):
        if key not in d:
            if default is ...:
                raise self.err(where, f"missing key {key!r} ({expected})")
            return default
        v = d[key]
        shown = repr(v)
        if isinstance(v, str) and (v.startswith("$") or v.startswith("-$")):
            neg = v.startswith("-")
            name = v[2:] if neg else v[1:]
            if name not in self.parameters:
                known = ", ".join(sorted(self.parameters)) or "none"
                raise self.err(where, f"key {key!r} = {v!r}: no parameter {name!r} (parameters: {known})")
            v = -self.parameters[name] if neg else self.parameters[name]
            shown = f"{d[key]!r} = {v!r}"
        ok, out = check(v)
        if not ok:
            raise self.err(where, f"key {key!r} = {shown}: expected {expected}")
        return out

    # checks: (ok, converted value)
    @staticmethod
    def number(v):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            return False, None
        return True, float(v)

    @classmethod
    def positive(cls, v):
        ok, x = cls.number(v)
        return (ok and x > 0), x

    @classmethod
    def nonzero(cls, v):
        ok, x = cls.number(v)
        return (ok and x != 0), x

    @staticmethod
    def count(v):
        return (isinstance(v, int) and not isinstance(v, bool) and v >= 1), v

    @staticmethod
    def text(v):
        return (isinstance(v, str) and v.strip() != "" and v == v.strip()), v

    @staticmethod
    def boolean(v):
        return isinstance(v, bool), v

    @staticmethod
    def axis(v):
        if isinstance(v, str) and v.strip():
            return True, v
        if isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 2:
            return True, v
        return False, None

    @classmethod
    def angles(cls, v):
        if not isinstance(v, list) or not 1 <= len(v) <= 3:
            return False, None
        out = []
        for a in v:
            ok, x = cls.number(a)
            if not ok:
                return False, None
            out.append(x * DEG)
        return True, tuple(out)

    def next_label(self, prefix: str) -> str:
        self.counters[prefix] = self.counters.get(prefix, 0) + 1
        return f"{prefix}{self.counters[prefix]:02d}"

    def steps(self, raw, where: str, prefix_no: str, suffix: str) -> list[Step]:
        if not isinstance(raw, list) or not raw:
            raise self.err(where, "expected a non-empty list of step tables ([[steps]])")
        out: list[Step] = []
        for i, d in enumerate(raw, start=1):
            no = f"{prefix_no}{i}"
            out += self.step(d, no, suffix)
        return out

    def step(self, d, no: str, suffix: str) -> list[Step]:
        where = f"step {no}"
        if not isinstance(d, dict):
            raise self.err(where, "expected a table with a 'kind'")
        kind = d.get("kind")
        if kind not in KINDS:
            raise self.err(where, f"key 'kind' = {kind!r}: expected one of {', '.join(KINDS)}")
        where = f"step {no} ({kind})"
        extra = set(d) - _STEP_KEYS[kind]
        if extra:
            raise self.err(where, f"unknown key(s) {sorted(extra)}; expected some of {sorted(_STEP_KEYS[kind])}")
        label = self.value(d, "label", where, "a non-empty text without surrounding blanks", self.text, None)
        lab = (label or f"{kind}{no.replace('.', '-')}") + suffix
        if kind == "index":
            angles = self.value(d, "angles_deg", where, "a list of 1 to 3 angles [deg], outer first", self.angles)
            absolute = self.value(d, "absolute", where, "true or false", self.boolean, False)
            return [Index(angles, lab, absolute, no)]
        if kind == "dwell":
            return [Dwell(self.value(d, "duration", where, "a positive duration [s]", self.positive), lab, no)]
        if kind == "rotate":
            return [Rotate(self.value(d, "axis", where, "an axis name or position 0..2", self.axis),
                           self.value(d, "rate_dps", where, "a nonzero signed rate [deg/s]", self.nonzero) * DEG,
                           self.value(d, "turns", where, "a whole number of turns >= 1", self.count), lab, no)]
        if kind == "rate":
            return [Rate(self.value(d, "axis", where, "an axis name or position 0..2", self.axis),
                         self.value(d, "rate_dps", where, "a nonzero signed rate [deg/s]", self.nonzero) * DEG,
                         self.value(d, "duration", where, "a positive duration [s]", self.positive), lab, no)]
        if kind == "tumble":
            att = d.get("attitudes_deg")
            if not isinstance(att, list) or not att:
                raise self.err(where, f"key 'attitudes_deg' = {att!r}: expected a non-empty list of "
                                      "[outer, middle, inner] angle lists [deg]")
            dwell = self.value(d, "dwell", where, "a positive dwell [s]", self.positive)
            prefix = self.value(d, "prefix", where, "a non-empty text", self.text, "pos")
            absolute = self.value(d, "absolute", where, "true or false", self.boolean, False)
            out: list[Step] = []
            n = None
            for k, a in enumerate(att):
                ok, angles = self.angles(a)
                if not ok:
                    raise self.err(where, f"key 'attitudes_deg', entry {k + 1} = {a!r}: expected a list of "
                                          "1 to 3 angles [deg]")
                if n is not None and len(angles) != n:
                    raise self.err(where, f"key 'attitudes_deg', entry {k + 1} has {len(angles)} angles, "
                                          f"entry 1 has {n}: expected the same number for every attitude")
                n = len(angles)
                pl = self.next_label(prefix) + suffix
                out += [Index(angles, pl, absolute, no), Dwell(dwell, pl, no)]
            return out
        # repeat
        times = self.value(d, "times", where, "a whole number >= 1", self.count)
        if "steps" not in d:
            raise self.err(where, "missing key 'steps' (the steps to repeat, [[steps.steps]])")
        out = []
        for c in range(1, times + 1):
            sfx = f"{suffix}-c{c}" if times > 1 else suffix
            out += self.steps(d["steps"], f"step {no}: key 'steps'", f"{no}.", sfx)
        return out


def schedule_from_dict(data: dict, source: str = "schedule", overrides: dict | None = None) -> Schedule:
    """A :class:`Schedule` from parsed TOML. ``overrides`` replace values of ``[parameters]``
    (only parameters the schedule declares, with numbers)."""
    if not isinstance(data, dict):
        raise ScheduleError(f"{source}: expected a table")
    extra = set(data) - {"schedule", "parameters", "settings", "steps"}
    if extra:
        raise ScheduleError(f"{source}: unknown section(s) {sorted(extra)}; expected some of "
                            "['parameters', 'schedule', 'settings', 'steps']")
    head = data.get("schedule", {})
    if not isinstance(head, dict):
        raise ScheduleError(f"{source}: [schedule]: expected a table with name, description")
    extra = set(head) - {"name", "description"}
    if extra:
        raise ScheduleError(f"{source}: [schedule]: unknown key(s) {sorted(extra)}; expected name, description")
    name = head.get("name", Path(source).stem)
    desc = head.get("description", "")
    if not isinstance(name, str) or not isinstance(desc, str):
        raise ScheduleError(f"{source}: [schedule]: name and description must be text")
    params = data.get("parameters", {})
    if not isinstance(params, dict):
        raise ScheduleError(f"{source}: [parameters]: expected a table of named numbers")
    params = dict(params)
    for k, v in params.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ScheduleError(f"{source}: [parameters]: {k} = {v!r}: expected a number")
    for k, v in (overrides or {}).items():
        if k not in params:
            known = ", ".join(sorted(params)) or "none"
            raise ScheduleError(f"{source}: override {k} = {v!r}: the schedule has no parameter {k!r} "
                                f"(parameters: {known})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or isinstance(params[k], int) and not isinstance(v, int):
            raise ScheduleError(f"{source}: override {k} = {v!r}: expected a {type(params[k]).__name__} "
                                f"like the schedule's {params[k]!r}")
        params[k] = v
    raw_settings = data.get("settings", {})
    if not isinstance(raw_settings, dict):
        raise ScheduleError(f"{source}: [settings]: expected a table")
    settings = Settings()
    for k, v in raw_settings.items():
        if k not in _SETTINGS:
            raise ScheduleError(f"{source}: [settings]: unknown key {k!r}; expected some of {sorted(_SETTINGS)}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0 or not math.isfinite(v):
            raise ScheduleError(f"{source}: [settings]: {k} = {v!r}: expected a positive number")
        fname, scale = _SETTINGS[k]
        settings = replace(settings, **{fname: float(v) * scale})
    p = _Parser(source, params)
    if "steps" not in data:
        raise ScheduleError(f"{source}: no [[steps]]: expected at least one step")
    steps = p.steps(data["steps"], "[[steps]]", "", "")
    n = None
    for s in steps:
        if isinstance(s, Index):
            if n is not None and len(s.angles) != n:
                raise ScheduleError(f"{source}: step {s.origin} (index): {len(s.angles)} angles where earlier "
                                    f"steps have {n}: expected one angle per table axis in every step")
            n = len(s.angles)
    return Schedule(name=name, steps=steps, settings=settings, parameters=params, description=desc,
                    source=source)


def schedules_dir():
    return resources.files("components.control") / "schedules"


def available_schedules() -> list[str]:
    """Names of the ready-made schedules (package data components/control/schedules/*.toml)."""
    return sorted(p.name[:-5] for p in schedules_dir().iterdir() if p.name.endswith(".toml"))


def load_schedule(spec: str | Path, overrides: dict | None = None, base_dir: Path | None = None) -> Schedule:
    """A schedule by ready-made name (``six_position`` or ``six-position``) or by file path
    (relative paths from ``base_dir``, default the working directory)."""
    spec_s = str(spec)
    ready = spec_s.replace("-", "_")
    if not spec_s.endswith(".toml") and "/" not in spec_s and "\\" not in spec_s:
        if ready not in available_schedules():
            raise ScheduleError(f"schedule {spec_s!r}: no ready-made schedule of that name (expected one of "
                                f"{', '.join(available_schedules())}, or a path to a .toml file)")
        res = schedules_dir() / f"{ready}.toml"
        text, source = res.read_text(encoding="utf-8"), f"schedule {ready}"
    else:
        path = Path(spec_s)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise ScheduleError(f"schedule file {path} does not exist") from None
        source = str(path)
    return loads_schedule(text, source, overrides)


def loads_schedule(text: str, source: str = "schedule", overrides: dict | None = None) -> Schedule:
    """A schedule from TOML text."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ScheduleError(f"{source}: not valid TOML ({e})") from None
    return schedule_from_dict(data, source, overrides)
