"""The campaign file (TOML) and its expansion into cases.

::

    [campaign]
    name = "smoke"
    description = "free text"
    seed = 20240601          # master seed: every case's noise seed and sampled value derive from it
    replicates = 3           # Monte-Carlo seeds per (procedure, system, grid point)
    timeout_s = 120          # per case (a system may lower or raise it)

    [scenario]               # the base scenario (components.scenario format)
    file = "../scenarios/six_position.toml"     # relative to this file
    step = 0.01              # optional: replaces the file's [scenario] step
    [scenario.schedule_overrides]
    dwell = 1.0

    [systems.ours]           # an IMU to put on the table: builtin:, a .fmu path or build:<model folder>
    imu = "builtin:imu"
    [systems.acme]
    imu = "build:../../tests/fmus/supplier_imu"
    mapping = { "omega.x" = "AngularRate_X", ... }       # role name -> the FMU's name
    gyro_output = "rate"
    acc_output = "specific_force"
    timeout_s = 30
    replicates = 1           # fewer (or more) seeds for this system than [campaign] replicates
    [systems.acme.parameters]                            # fixed FMU parameters (its names, its units)
    SegfaultAt = 1e300
    [systems.acme.effects]                               # vocabulary -> [FMU parameter, its unit]
    "gyro.bias.x" = ["GyroBias_X", "deg/s"]

    [procedures.lsq]         # method: lsq (effects), cwccw, tilt, tilt_ignored
    method = "lsq"
    effects = ["gyro.bias", "gyro.sf", "gyro.mis", "acc.bias", "acc.sf", "acc.mis"]

    [variations."acc.bias.x"]          # a grid: every value is a grid point (cartesian product)
    values = ["-100 ug", "100 ug"]
    [variations."gyro.bias.z"]         # a distribution, drawn per replicate (seeded)
    distribution = "normal"            # normal (mean, sigma) | uniform (low, high)
    mean = "0 deg/h"
    sigma = "0.01 deg/h"
    [variations."schedule.dwell"]      # schedule parameters, noise names (gyro.noise.arw) too
    values = [1.0, 2.0]

    [[criteria]]
    id = "ACC-BIAS"                    # optional (default C1, C2, ...)
    requirement = "REQ-CAL-012"        # the requirement this criterion verifies
    kind = "estimate"                  # estimate | chi2 | crb | diagnosis
    parameters = ["acc.bias.*"]        # fnmatch patterns over the estimated parameters
    tolerance = "100 ug"               # |estimate - truth| <= tolerance, and/or
    crb_sigmas = 5                     # |estimate - truth| <= 5 x the Cramer-Rao sigma, and/or
    sigmas = 5                         # |estimate - truth| <= 5 x the reported sigma
    systems = ["ours"]                 # optional scope: systems, procedures
    # chi2:      max = 1.5 (min = 0.5): the model's chi2/dof on its own log
    # crb:       parameters, max = "20 ug": the schedule observes them to that sigma (observability)
    # diagnosis: verdict = "none" (no missing effect) or an effect name

    [expected]                         # the campaign as a regression test
    verdict = "pass"                   # every case not matched below
    [[expected.cases]]
    system = "segv"                    # match on system and/or procedure
    verdict = "error"
    reason = "SIGSEGV"                 # a substring of the error reason

Case ids (``<procedure>-<system>-g<grid>-r<replicate>``), noise seeds and sampled values are
derived from the file alone: the same file gives the same cases on any machine, with any
number of workers. A replicate's seed and draws do not depend on the procedure or the system:
every procedure and system sees the same truth (paired comparison).
"""
from __future__ import annotations

import copy
import fnmatch
import hashlib
import itertools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from orchestrator.tomlfile import read_toml

METHODS = ("lsq", "cwccw", "tilt", "tilt_ignored")
KINDS = ("estimate", "chi2", "crb", "diagnosis")
VERDICTS = ("pass", "fail", "error")


class CampaignError(ValueError):
    """A campaign file is wrong: names the file, the key and what was expected."""


@dataclass
class Criterion:
    id: str
    requirement: str
    kind: str
    description: str = ""
    parameters: list = field(default_factory=list)   # fnmatch patterns
    tolerance: object = None                         # text or number, parsed per parameter
    crb_sigmas: float | None = None
    sigmas: float | None = None
    max: object = None
    min: float | None = None
    verdict: str | None = None
    systems: list | None = None
    procedures: list | None = None

    def applies(self, procedure: str, system: str) -> bool:
        return ((self.systems is None or system in self.systems)
                and (self.procedures is None or procedure in self.procedures))

    def to_dict(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if v not in (None, [], "")}


@dataclass
class System:
    name: str
    imu: str                  # the spec as written
    path: Path                # resolved FMU file
    mapping: dict = field(default_factory=dict)
    gyro_output: str = "increment"
    acc_output: str = "increment"
    parameters: dict = field(default_factory=dict)
    effects: dict | None = None   # vocabulary -> (FMU name, SI per FMU unit); None: the FMU uses the vocabulary
    timeout_s: float | None = None
    replicates: int | None = None


@dataclass
class Procedure:
    name: str
    method: str
    effects: list = field(default_factory=list)
    options: dict = field(default_factory=dict)


@dataclass
class Variation:
    name: str
    values: list | None = None        # grid (SI)
    distribution: str | None = None
    a: float = 0.0                     # mean | low
    b: float = 0.0                     # sigma | high


@dataclass
class Case:
    id: str
    procedure: str
    system: str
    grid: int
    replicate: int
    seed: int
    variation: dict            # name -> SI value (grid and sampled)

    def key(self) -> dict:
        return {"id": self.id, "procedure": self.procedure, "system": self.system, "grid": self.grid,
                "replicate": self.replicate, "seed": self.seed, "variation": self.variation}


@dataclass
class Campaign:
    name: str
    source: Path
    base_dir: Path
    seed: int
    replicates: int
    timeout_s: float
    scenario: dict            # the base scenario, as a scenario dict
    scenario_base_dir: Path
    scenario_file: Path | None
    systems: dict
    procedures: dict
    variations: list
    criteria: list
    expected: dict | None
    description: str = ""
    cases: list = field(default_factory=list)

    def case(self, case_id: str) -> Case:
        return next(c for c in self.cases if c.id == case_id)

    def criteria_for(self, case: Case) -> list:
        return [c for c in self.criteria if c.applies(case.procedure, case.system)]

    def timeout_for(self, case: Case) -> float:
        t = self.systems[case.system].timeout_s
        return float(t if t is not None else self.timeout_s)

    def expected_for(self, case: Case) -> dict:
        """{"verdict", "reason"?} the [expected] block gives this case (None: no block)."""
        if self.expected is None:
            return None
        for m in self.expected.get("cases", []):
            if all(m.get(k) in (None, getattr(case, k)) for k in ("system", "procedure")):
                return {k: m[k] for k in ("verdict", "reason") if k in m}
        return {"verdict": self.expected.get("verdict", "pass")}


# ----------------------------------------------------------------------------- helpers
def derive_seed(master: int, *parts) -> int:
    """A 31-bit seed from the master seed and a path of names (stable across machines)."""
    text = "/".join([str(master)] + [str(p) for p in parts])
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "big") & 0x7FFFFFFF


def _where(src, *keys) -> str:
    return f"{src}: " + ".".join(str(k) for k in keys)


def _expect(cond: bool, src, key: str, got, expected: str) -> None:
    if not cond:
        raise CampaignError(f"{src}: {key} = {got!r}: expected {expected}")


def _keys(d: dict, allowed: set, src, where: str) -> None:
    extra = set(d) - allowed
    if extra:
        raise CampaignError(f"{src}: {where}: unknown key(s) {sorted(extra)}; expected some of {sorted(allowed)}")


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def parse_value(name: str, v, where: str) -> float:
    """SI value of a varied quantity: an effect parameter, a noise name or schedule.<param>."""
    from components.scenario import _NOISE_UNITS, ScenarioError, _effect_value, _value

    try:
        if name.startswith("schedule."):
            if not _is_num(v):
                raise ScenarioError(f"{where}: {name} = {v!r}: expected a number (the schedule's unit)")
            return float(v)
        if name in _NOISE_UNITS:
            si, units = _NOISE_UNITS[name]
            return _value(v, name, where, units, si)
        return _effect_value(name, v, where)
    except ScenarioError as e:
        raise CampaignError(str(e)) from None


def resolve_imu(spec: str, base_dir: Path) -> Path:
    """builtin:<name>, build:<model folder> (built now, cached) or a .fmu path."""
    if spec.startswith("build:"):
        from fmus.build import fmu_path

        folder = Path(spec[len("build:"):])
        folder = folder if folder.is_absolute() else (base_dir / folder).resolve()
        return fmu_path(folder, 2)
    from orchestrator.fmu_resolver import resolve_fmu

    return Path(resolve_fmu(spec, base_dir)).resolve()


# ----------------------------------------------------------------------------- parsing
def load_campaign(path: str | Path) -> Campaign:
    p = Path(path)
    return campaign_from_dict(read_toml(p, CampaignError, "campaign"), p)


def campaign_from_dict(data: dict, source: Path) -> Campaign:
    src = str(source)
    base = Path(source).resolve().parent
    _keys(data, {"campaign", "scenario", "systems", "procedures", "variations", "criteria", "expected"}, src, "top level")
    for k in ("campaign", "scenario", "systems", "procedures"):
        if not isinstance(data.get(k), dict):
            raise CampaignError(f"{src}: [{k}]: missing or not a table")
    c = data["campaign"]
    _keys(c, {"name", "description", "seed", "replicates", "timeout_s"}, src, "[campaign]")
    seed = c.get("seed", 0)
    _expect(isinstance(seed, int) and not isinstance(seed, bool), src, "[campaign] seed", seed, "an integer")
    reps = c.get("replicates", 1)
    _expect(isinstance(reps, int) and not isinstance(reps, bool) and reps >= 1, src, "[campaign] replicates",
            reps, "an integer >= 1")
    timeout = c.get("timeout_s", 300.0)
    _expect(_is_num(timeout) and timeout > 0, src, "[campaign] timeout_s", timeout, "a positive number [s]")

    scenario, sc_base, sc_file = _scenario(data["scenario"], src, base)
    systems = {n: _system(n, d, src, base) for n, d in data["systems"].items()}
    if not systems:
        raise CampaignError(f"{src}: [systems]: expected at least one system")
    procedures = {n: _procedure(n, d, src) for n, d in data["procedures"].items()}
    if not procedures:
        raise CampaignError(f"{src}: [procedures]: expected at least one procedure")
    variations = _variations(data.get("variations", {}), src)
    criteria = _criteria(data.get("criteria", []), src, systems, procedures)
    expected = _expected(data.get("expected"), src, systems, procedures)
    camp = Campaign(name=c.get("name", Path(src).stem), description=c.get("description", ""), source=Path(source),
                    base_dir=base, seed=seed, replicates=reps, timeout_s=float(timeout), scenario=scenario,
                    scenario_base_dir=sc_base, scenario_file=sc_file, systems=systems, procedures=procedures,
                    variations=variations, criteria=criteria, expected=expected)
    camp.cases = expand(camp)
    # the base scenario must parse with every grid point (clear error now, not in 40 workers)
    from components.scenario import ScenarioError

    for case in camp.cases:
        if case.replicate == 0 and case.procedure == next(iter(procedures)):
            try:
                scenario_for(camp, case, check_only=True)
            except ScenarioError as e:
                raise CampaignError(f"{src}: case {case.id}: {e}") from None
    return camp


def _scenario(d: dict, src, base: Path):
    _keys(d, {"file", "inline", "step", "seed", "schedule_overrides"}, src, "[scenario]")
    if ("file" in d) == ("inline" in d):
        raise CampaignError(f"{src}: [scenario]: expected exactly one of 'file' (a scenario file) or "
                            "'inline' (a table in the scenario format)")
    if "file" in d:
        f = d["file"]
        _expect(isinstance(f, str), src, "[scenario] file", f, "a path")
        fp = Path(f) if Path(f).is_absolute() else base / f
        sc = read_toml(fp, CampaignError, context=f"{src}: [scenario] file = {f!r}")
        sc_base, sc_file = fp.resolve().parent, fp.resolve()
    else:
        sc = copy.deepcopy(d["inline"])
        _expect(isinstance(sc, dict), src, "[scenario] inline", sc, "a table in the scenario format")
        sc_base, sc_file = base, None
    sc.setdefault("scenario", {})
    if "step" in d:
        _expect(_is_num(d["step"]) and d["step"] > 0, src, "[scenario] step", d["step"], "a positive step [s]")
        sc["scenario"]["step"] = d["step"]
    ov = d.get("schedule_overrides", {})
    _expect(isinstance(ov, dict), src, "[scenario] schedule_overrides", ov, "a table of schedule parameters")
    sc.setdefault("schedule", {}).setdefault("overrides", {}).update(ov)
    return sc, sc_base, sc_file


def _system(name: str, d, src, base: Path) -> System:
    w = f"[systems.{name}]"
    _expect(isinstance(d, dict), src, w, d, "a table")
    _keys(d, {"imu", "mapping", "gyro_output", "acc_output", "parameters", "effects", "timeout_s", "replicates"},
          src, w)
    reps = d.get("replicates")
    if reps is not None:
        _expect(isinstance(reps, int) and not isinstance(reps, bool) and reps >= 1, src, f"{w} replicates", reps,
                "an integer >= 1")
    imu = d.get("imu")
    _expect(isinstance(imu, str), src, f"{w} imu", imu, "'builtin:imu', 'build:<model folder>' or a .fmu path")
    try:
        path = resolve_imu(imu, base)
    except Exception as e:  # noqa: BLE001  (a build error names the model)
        raise CampaignError(f"{src}: {w} imu = {imu!r}: {e}") from None
    if not path.exists():
        raise CampaignError(f"{src}: {w} imu = {imu!r}: file {path} does not exist")
    mp = d.get("mapping", {})
    _expect(isinstance(mp, dict) and all(isinstance(v, str) for v in mp.values()), src, f"{w} mapping", mp,
            "a table of role name = FMU name")
    params = d.get("parameters", {})
    _expect(isinstance(params, dict) and all(_is_num(v) for v in params.values()), src, f"{w} parameters",
            params, "a table of FMU parameter = number")
    effects = None
    if "effects" in d:
        from components.scenario import _UNITS
        from components.effects import effect_of

        effects = {}
        for k, v in d["effects"].items():
            try:
                e = effect_of(k)
            except KeyError:
                raise CampaignError(f"{src}: {w}.effects: {k!r} is not a parameter of the effect vocabulary") from None
            units = dict(_UNITS.get(e.unit, {e.unit: 1.0}))
            if e.display[0]:
                units[e.display[0]] = e.display[1]
            if not (isinstance(v, list) and len(v) == 2 and isinstance(v[0], str) and v[1] in units):
                raise CampaignError(f"{src}: {w}.effects: {k} = {v!r}: expected [FMU parameter name, unit] with "
                                    f"unit one of {', '.join(units)}")
            effects[k] = (v[0], units[v[1]])
    t = d.get("timeout_s")
    if t is not None:
        _expect(_is_num(t) and t > 0, src, f"{w} timeout_s", t, "a positive number [s]")
    for k in ("gyro_output", "acc_output"):
        _expect(isinstance(d.get(k, ""), str), src, f"{w} {k}", d.get(k), "text")
    return System(name, imu, path, dict(mp), d.get("gyro_output", "increment"), d.get("acc_output", "increment"),
                  dict(params), effects, None if t is None else float(t), reps)


def _procedure(name: str, d, src) -> Procedure:
    from components.effects import DEFAULT_EFFECTS, EFFECTS

    w = f"[procedures.{name}]"
    _expect(isinstance(d, dict), src, w, d, "a table")
    _keys(d, {"method", "effects", "options"}, src, w)
    m = d.get("method", name)
    _expect(m in METHODS, src, f"{w} method", m, f"one of {', '.join(METHODS)}")
    effects = d.get("effects", list(DEFAULT_EFFECTS) if m == "lsq" else [])
    _expect(isinstance(effects, list) and all(e in EFFECTS for e in effects), src, f"{w} effects", effects,
            "a list of effect names of the vocabulary (components.effects)")
    if m != "lsq" and "effects" in d and m not in ("tilt", "tilt_ignored"):
        raise CampaignError(f"{src}: {w} effects: only lsq, tilt and tilt_ignored take effects")
    opts = d.get("options", {})
    _expect(isinstance(opts, dict), src, f"{w} options", opts, "a table of keyword options")
    return Procedure(name, m, list(effects), dict(opts))


def _variations(d, src) -> list:
    _expect(isinstance(d, dict), src, "[variations]", d, "a table of quantity = {values | distribution}")
    out = []
    for name in sorted(d):
        v = d[name]
        w = f'[variations."{name}"]'
        _expect(isinstance(v, dict), src, w, v, "a table with 'values' or 'distribution'")
        _keys(v, {"values", "distribution", "mean", "sigma", "low", "high"}, src, w)
        if ("values" in v) == ("distribution" in v):
            raise CampaignError(f"{src}: {w}: expected exactly one of 'values' (a grid) or 'distribution'")
        if "values" in v:
            vals = v["values"]
            _expect(isinstance(vals, list) and vals, src, f"{w} values", vals, "a non-empty list")
            out.append(Variation(name, values=[parse_value(name, x, f"{src}: {w} values") for x in vals]))
            continue
        dist = v["distribution"]
        if dist == "normal":
            need = ("mean", "sigma")
        elif dist == "uniform":
            need = ("low", "high")
        else:
            raise CampaignError(f"{src}: {w} distribution = {dist!r}: expected 'normal' or 'uniform'")
        for k in need:
            if k not in v:
                raise CampaignError(f"{src}: {w}: distribution {dist!r} needs {' and '.join(need)}")
        a, b = (parse_value(name, v[k], f"{src}: {w} {k}") for k in need)
        if dist == "normal" and b < 0 or dist == "uniform" and b < a:
            raise CampaignError(f"{src}: {w}: expected sigma >= 0 (normal) or high >= low (uniform)")
        out.append(Variation(name, distribution=dist, a=a, b=b))
    return out


def _criteria(lst, src, systems, procedures) -> list:
    from components.effects import EFFECTS

    _expect(isinstance(lst, list), src, "criteria", lst, "an array of tables [[criteria]]")
    out, ids = [], set()
    for i, d in enumerate(lst, 1):
        w = f"[[criteria]] #{i}"
        _expect(isinstance(d, dict), src, w, d, "a table")
        _keys(d, {"id", "requirement", "kind", "description", "parameters", "tolerance", "crb_sigmas", "sigmas",
                  "max", "min", "verdict", "systems", "procedures"}, src, w)
        cid = d.get("id", f"C{i}")
        _expect(isinstance(cid, str) and cid not in ids, src, f"{w} id", cid, "a unique text")
        ids.add(cid)
        w = f"[[criteria]] {cid}"
        req = d.get("requirement")
        _expect(isinstance(req, str) and req.strip() != "", src, f"{w} requirement", req,
                "the identifier of the requirement it verifies")
        kind = d.get("kind")
        _expect(kind in KINDS, src, f"{w} kind", kind, f"one of {', '.join(KINDS)}")
        for k, names in (("systems", systems), ("procedures", procedures)):
            if k in d:
                v = d[k]
                _expect(isinstance(v, list) and all(x in names for x in v), src, f"{w} {k}", v,
                        f"a list of names from [{k}] ({', '.join(names)})")
        crit = Criterion(cid, req, kind, d.get("description", ""), systems=d.get("systems"),
                         procedures=d.get("procedures"))
        if kind in ("estimate", "crb"):
            pats = d.get("parameters")
            _expect(isinstance(pats, list) and pats and all(isinstance(p, str) for p in pats), src,
                    f"{w} parameters", pats, "a non-empty list of parameter names or patterns (acc.bias.*)")
            crit.parameters = pats
            vocab = [q for e in EFFECTS.values() for q in e.parameters]
            names = match_parameters(pats, vocab)
            if not names:
                raise CampaignError(f"{src}: {w} parameters = {pats!r}: expected names or patterns of parameters "
                                    "of the effect vocabulary (e.g. acc.bias.x, acc.bias.*)")
            for key in ("tolerance", "max"):
                if key in d and not (kind == "chi2"):
                    for q in names:  # the limit must have each parameter's dimension
                        parse_value(q, d[key], f"{src}: {w} {key}")
        if kind == "estimate":
            if not any(k in d for k in ("tolerance", "crb_sigmas", "sigmas")):
                raise CampaignError(f"{src}: {w}: an estimate criterion needs tolerance, crb_sigmas or sigmas")
            for k in ("crb_sigmas", "sigmas"):
                if k in d:
                    _expect(_is_num(d[k]) and d[k] > 0, src, f"{w} {k}", d[k], "a positive number")
                    setattr(crit, k, float(d[k]))
            if "tolerance" in d:
                _expect(_is_num(d["tolerance"]) or isinstance(d["tolerance"], str), src, f"{w} tolerance",
                        d["tolerance"], "a number (SI) or '<number> <unit>'")
                crit.tolerance = d["tolerance"]
        elif kind == "crb":
            _expect("max" in d and (_is_num(d["max"]) or isinstance(d["max"], str)), src, f"{w} max", d.get("max"),
                    "the largest acceptable Cramer-Rao sigma: a number (SI) or '<number> <unit>'")
            crit.max = d["max"]
        elif kind == "chi2":
            _expect(_is_num(d.get("max")) and d["max"] > 0, src, f"{w} max", d.get("max"),
                    "the largest acceptable chi2/dof (a positive number)")
            crit.max = float(d["max"])
            if "min" in d:
                _expect(_is_num(d["min"]), src, f"{w} min", d["min"], "a number")
                crit.min = float(d["min"])
        else:
            v = d.get("verdict")
            _expect(v == "none" or v in EFFECTS, src, f"{w} verdict", v,
                    "'none' (no effect missing) or an effect name of the vocabulary")
            crit.verdict = v
        out.append(crit)
    return out


def _expected(d, src, systems, procedures):
    if d is None:
        return None
    _expect(isinstance(d, dict), src, "[expected]", d, "a table")
    _keys(d, {"verdict", "cases"}, src, "[expected]")
    _expect(d.get("verdict", "pass") in VERDICTS, src, "[expected] verdict", d.get("verdict"),
            f"one of {', '.join(VERDICTS)}")
    cases = d.get("cases", [])
    _expect(isinstance(cases, list), src, "[expected] cases", cases, "an array of tables [[expected.cases]]")
    for i, m in enumerate(cases, 1):
        w = f"[[expected.cases]] #{i}"
        _expect(isinstance(m, dict), src, w, m, "a table")
        _keys(m, {"system", "procedure", "verdict", "reason"}, src, w)
        _expect(m.get("verdict") in VERDICTS, src, f"{w} verdict", m.get("verdict"), f"one of {', '.join(VERDICTS)}")
        if "system" in m:
            _expect(m["system"] in systems, src, f"{w} system", m["system"], f"one of {', '.join(systems)}")
        if "procedure" in m:
            _expect(m["procedure"] in procedures, src, f"{w} procedure", m["procedure"],
                    f"one of {', '.join(procedures)}")
    return {"verdict": d.get("verdict", "pass"), "cases": cases}


# ----------------------------------------------------------------------------- expansion
def grid_points(camp: Campaign) -> list[dict]:
    grid = [v for v in camp.variations if v.values is not None]
    if not grid:
        return [{}]
    return [dict(zip([v.name for v in grid], combo)) for combo in itertools.product(*[v.values for v in grid])]


def draws(camp: Campaign, g: int, r: int) -> dict:
    out = {}
    for v in camp.variations:
        if v.distribution is None:
            continue
        rng = np.random.default_rng(derive_seed(camp.seed, "draw", g, r, v.name))
        out[v.name] = float(rng.normal(v.a, v.b) if v.distribution == "normal" else rng.uniform(v.a, v.b))
    return out


def expand(camp: Campaign) -> list[Case]:
    points = grid_points(camp)
    nrep = max([camp.replicates] + [s.replicates or 0 for s in camp.systems.values()])
    gw, rw = len(str(len(points) - 1)), len(str(nrep - 1))
    cases = []
    for pname in camp.procedures:
        for sname in camp.systems:
            for g, point in enumerate(points):
                for r in range(camp.systems[sname].replicates or camp.replicates):
                    var = {**point, **draws(camp, g, r)}
                    cases.append(Case(f"{pname}-{sname}-g{g:0{gw}d}-r{r:0{rw}d}", pname, sname, g, r,
                                      derive_seed(camp.seed, "noise", g, r), dict(sorted(var.items()))))
    ids = [c.id for c in cases]
    if len(set(ids)) != len(ids):
        raise CampaignError(f"{camp.source}: case ids collide (procedure and system names must not make "
                            "the same '<procedure>-<system>' twice)")
    return sorted(cases, key=lambda c: c.id)


def scenario_for(camp: Campaign, case: Case, check_only: bool = False):
    """(scenario dict, truth effects SI, not-injected effects) for one case."""
    from components.scenario import scenario_from_dict

    sc = copy.deepcopy(camp.scenario)
    sys_ = camp.systems[case.system]
    sc["scenario"]["seed"] = case.seed
    sc["scenario"]["name"] = case.id
    imu = sc.setdefault("imu", {})
    for k in ("noise", "effects", "parameters"):
        imu.setdefault(k, {})
    tt = sc.setdefault("turntable", {})
    tt.setdefault("effects", {})
    for name, v in case.variation.items():
        if name.startswith("schedule."):
            sc["schedule"]["overrides"][name[len("schedule."):]] = v
        elif name.startswith("table."):
            tt["effects"][name] = v
        elif "noise" in name.split("."):
            imu["noise"][name] = v
        else:
            imu["effects"][name] = v
    parsed = scenario_from_dict(sc, str(camp.scenario_file or camp.source), camp.scenario_base_dir)
    truth = {k: v for k, v in {**parsed.imu_effects, **parsed.table_effects}.items() if v != 0.0}
    lost = []
    imu["fmu"] = str(sys_.path)
    imu["mapping"] = dict(sys_.mapping)
    imu["gyro_output"], imu["acc_output"] = sys_.gyro_output, sys_.acc_output
    imu["parameters"] = {**imu["parameters"], **sys_.parameters}
    if sys_.effects is not None:
        # a supplier's FMU: vocabulary effects become its own parameters (its units); what it
        # has no parameter for is not injected (and not in the truth); it has no noise model
        params = dict(imu["parameters"])
        for name, si in parsed.imu_effects.items():
            if name in sys_.effects:
                fmu_name, scale = sys_.effects[name]
                params[fmu_name] = si / scale
            elif si != 0.0:
                lost.append(name)
                truth.pop(name, None)
        imu["parameters"], imu["effects"], imu["noise"] = params, {}, {}
    if check_only:
        return sc, truth, lost
    return sc, dict(sorted(truth.items())), sorted(lost)


def match_parameters(patterns: list, names) -> list:
    return [n for n in names if any(fnmatch.fnmatchcase(n, p) for p in patterns)]


def task_for(camp: Campaign, case: Case, marker_dir: str | None = None) -> dict:
    """Everything a worker needs to run the case (JSON): no reference to the campaign object."""
    sc, truth, lost = scenario_for(camp, case)
    proc = camp.procedures[case.procedure]
    crits = [c.to_dict() for c in camp.criteria_for(case)]
    return {"case": case.key(), "scenario": sc, "source": str(camp.scenario_file or camp.source),
            "base_dir": str(camp.scenario_base_dir),
            "procedure": {"name": proc.name, "method": proc.method, "effects": proc.effects,
                          "options": proc.options},
            "truth": truth, "not_injected": lost, "criteria": crits,
            "diagnose": any(c["kind"] == "diagnosis" for c in crits),
            "timeout_s": camp.timeout_for(case), "marker_dir": marker_dir}
