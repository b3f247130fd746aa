"""The campaign file (TOML), read into a :class:`~components.campaign.spec.Campaign`.

::

    [campaign]
    name = "smoke"
    description = "free text"
    seed = 20240601          # master seed: every case's noise seed and sampled value derive from it
    replicates = 3           # Monte-Carlo seeds per (procedure, system, grid point)
    timeout_s = 120          # per case (a system may lower or raise it)

    [scenario]               # the base scenario (components.simulation.scenario format)
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
    [systems.acme.effect_map]                            # vocabulary -> the FMU's parameter [, its unit]
    "gyro.bias.x" = ["GyroBias_X", "deg/s"]              # (docs/supplier.md; noise_map, seed_parameter too)

    [procedures.lsq]         # method: lsq (effects), cwccw, tilt, tilt_ignored
    method = "lsq"
    effects = ["gyro.bias", "gyro.sf", "gyro.mis", "acc.bias", "acc.sf", "acc.mis"]
    options = { noise = ["identify"] }   # lsq: the noise model, as calbench --noise (default white)

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
"""
from __future__ import annotations

import copy
from pathlib import Path

from components.campaign.spec import (
    KINDS,
    METHODS,
    VERDICTS,
    Campaign,
    Criterion,
    Procedure,
    System,
    Variation,
    expand,
    is_number,
    match_parameters,
    parse_value,
    resolve_imu,
    scenario_for,
)
from components.errors import CampaignError
from orchestrator.tomlfile import read_toml


def _where(src, *keys) -> str:
    return f"{src}: " + ".".join(str(k) for k in keys)


def _expect(cond: bool, src, key: str, got, expected: str) -> None:
    if not cond:
        raise CampaignError(f"{src}: {key} = {got!r}: expected {expected}")


def _keys(d: dict, allowed: set, src, where: str) -> None:
    extra = set(d) - allowed
    if extra:
        raise CampaignError(f"{src}: {where}: unknown key(s) {sorted(extra)}; expected some of {sorted(allowed)}")


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
    _expect(is_number(timeout) and timeout > 0, src, "[campaign] timeout_s", timeout, "a positive number [s]")

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
    from components.errors import ScenarioError

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
        _expect(is_number(d["step"]) and d["step"] > 0, src, "[scenario] step", d["step"], "a positive step [s]")
        sc["scenario"]["step"] = d["step"]
    ov = d.get("schedule_overrides", {})
    _expect(isinstance(ov, dict), src, "[scenario] schedule_overrides", ov, "a table of schedule parameters")
    sc.setdefault("schedule", {}).setdefault("overrides", {}).update(ov)
    return sc, sc_base, sc_file


def _system(name: str, d, src, base: Path) -> System:
    w = f"[systems.{name}]"
    _expect(isinstance(d, dict), src, w, d, "a table")
    _keys(d, {"imu", "mapping", "gyro_output", "acc_output", "role_options", "parameters", "effect_map", "noise_map",
              "seed_parameter", "count_weight", "effects", "timeout_s", "replicates"}, src, w)
    if "effects" in d:
        raise CampaignError(f"{src}: {w}.effects: renamed effect_map (the same table: vocabulary name = [the FMU's "
                            "parameter, its unit]), as in scenario files (docs/supplier.md)")
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
    _expect(isinstance(params, dict) and all(is_number(v) for v in params.values()), src, f"{w} parameters",
            params, "a table of FMU parameter = number")
    from components.errors import ScenarioError
    from components.simulation.scenario import unit_maps_of
    from components.simulation.unit_maps import maps_for

    maps = unit_maps_of(d, f"{src}: {w}", CampaignError)
    try:
        # the maps against the FMU's declared parameters and units: a unit mistake stops the
        # campaign before its first case
        maps_for(path, maps["imu_effect_map"], maps["imu_noise_map"], maps["imu_seed_parameter"], f"{src}: {w}")
    except ScenarioError as e:
        raise CampaignError(str(e)) from None
    ro = d.get("role_options", {})
    _expect(isinstance(ro, dict) and not set(ro) - {"gyro_output", "acc_output"}, src, f"{w} role_options", ro,
            "{gyro_output, acc_output}")
    d = {**d, **ro}
    t = d.get("timeout_s")
    if t is not None:
        _expect(is_number(t) and t > 0, src, f"{w} timeout_s", t, "a positive number [s]")
    for k in ("gyro_output", "acc_output"):
        _expect(isinstance(d.get(k, ""), str), src, f"{w} {k}", d.get(k), "text")
    _count_weights_known(d, maps["imu_count_weight"] or {}, path, src, w)
    return System(name, imu, path, dict(mp), d.get("gyro_output", "increment"), d.get("acc_output", "increment"),
                  dict(params), maps["imu_effect_map"], None if t is None else float(t), reps,
                  maps["imu_noise_map"], maps["imu_seed_parameter"], maps["imu_count_weight"])


def _count_weights_known(d: dict, stated: dict, path: Path, src, w: str) -> None:
    """Count outputs need the weight of a count (unit_maps.unknown_count_weight): refused before
    the first case, as a scenario run would refuse each case."""
    from fmpy import read_model_description

    from components.simulation.unit_maps import unknown_count_weight

    kinds = {s: d.get(f"{s}_output") for s in ("gyro", "acc")}
    if "counts" not in kinds.values():
        return
    why = unknown_count_weight(kinds, stated, {v.name for v in read_model_description(str(path)).modelVariables},
                               path.name)
    if why:
        raise CampaignError(f"{src}: {w}: {why}")


def _procedure(name: str, d, src) -> Procedure:
    from components.model.effects import DEFAULT_EFFECTS, EFFECTS

    w = f"[procedures.{name}]"
    _expect(isinstance(d, dict), src, w, d, "a table")
    _keys(d, {"method", "effects", "options"}, src, w)
    m = d.get("method", name)
    _expect(m in METHODS, src, f"{w} method", m, f"one of {', '.join(METHODS)}")
    effects = d.get("effects", list(DEFAULT_EFFECTS) if m == "lsq" else [])
    _expect(isinstance(effects, list) and all(e in EFFECTS for e in effects), src, f"{w} effects", effects,
            "a list of effect names of the vocabulary (components.model.effects)")
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
    from components.model.effects import EFFECTS, parameters_of

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
            # a least-squares procedure estimates its effects' parameters only: a criterion on none of
            # them would fail every case at run time ("no estimated parameter matches")
            for pname, proc in procedures.items():
                if proc.method != "lsq" or (crit.procedures is not None and pname not in crit.procedures):
                    continue
                fitted = set(parameters_of(proc.effects))
                if not any(q in fitted for q in names):
                    raise CampaignError(f"{src}: {w} parameters = {pats!r}: procedure {pname!r} estimates none of "
                                        f"them (its effects: {', '.join(proc.effects)}); add the effect to "
                                        f"[procedures.{pname}] effects, or name the criterion's procedures")
            for key in ("tolerance", "max"):
                if key in d and not (kind == "chi2"):
                    for q in names:  # the limit must have each parameter's dimension
                        parse_value(q, d[key], f"{src}: {w} {key}")
        if kind == "estimate":
            if not any(k in d for k in ("tolerance", "crb_sigmas", "sigmas")):
                raise CampaignError(f"{src}: {w}: an estimate criterion needs tolerance, crb_sigmas or sigmas")
            for k in ("crb_sigmas", "sigmas"):
                if k in d:
                    _expect(is_number(d[k]) and d[k] > 0, src, f"{w} {k}", d[k], "a positive number")
                    setattr(crit, k, float(d[k]))
            if "tolerance" in d:
                _expect(is_number(d["tolerance"]) or isinstance(d["tolerance"], str), src, f"{w} tolerance",
                        d["tolerance"], "a number (SI) or '<number> <unit>'")
                crit.tolerance = d["tolerance"]
        elif kind == "crb":
            _expect("max" in d and (is_number(d["max"]) or isinstance(d["max"], str)), src, f"{w} max", d.get("max"),
                    "the largest acceptable Cramer-Rao sigma: a number (SI) or '<number> <unit>'")
            crit.max = d["max"]
        elif kind == "chi2":
            _expect(is_number(d.get("max")) and d["max"] > 0, src, f"{w} max", d.get("max"),
                    "the largest acceptable chi2/dof (a positive number)")
            crit.max = float(d["max"])
            if "min" in d:
                _expect(is_number(d["min"]), src, f"{w} min", d["min"], "a number")
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


