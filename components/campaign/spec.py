"""A campaign: its systems, procedures, variations and criteria, expanded into cases with
deterministic ids, seeds and sampled values, and each case's task for a worker. The file that
describes one is read by :mod:`components.campaign.reader`.

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

from components.errors import CampaignError

METHODS = ("lsq", "cwccw", "tilt", "tilt_ignored")
KINDS = ("estimate", "chi2", "crb", "diagnosis")
VERDICTS = ("pass", "fail", "error")


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
    effect_map: dict | None = None   # the unit description's maps (components.simulation.unit_maps);
    timeout_s: float | None = None   #   None: the FMU's parameters are the vocabulary's
    replicates: int | None = None
    noise_map: dict | None = None
    seed_parameter: str | None = None
    count_weight: dict | None = None  # {"gyro": rad, "acc": m/s} of one count, as stated


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


def is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def parse_value(name: str, v, where: str) -> float:
    """SI value of a varied quantity: an effect parameter, a noise name or schedule.<param>."""
    from components.model.quantities import NOISE_UNITS, QuantityError, effect_value, noise_value, refuse_bare_number

    if name.startswith("schedule."):
        if not is_number(v):
            raise CampaignError(f"{where}: {name} = {v!r}: expected a number (the schedule's unit)")
        return float(v)
    try:
        if name not in NOISE_UNITS:
            refuse_bare_number(name, v, where)
        return noise_value(name, v, where) if name in NOISE_UNITS else effect_value(name, v, where)
    except QuantityError as e:
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
    from components.simulation.scenario import scenario_from_dict

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
    imu["fmu"] = str(sys_.path)
    imu["mapping"] = dict(sys_.mapping)
    imu["gyro_output"], imu["acc_output"] = sys_.gyro_output, sys_.acc_output
    imu["parameters"] = {**imu["parameters"], **sys_.parameters}
    for key, v in (("effect_map", sys_.effect_map), ("noise_map", sys_.noise_map),
                   ("seed_parameter", sys_.seed_parameter), ("count_weight", sys_.count_weight)):
        if v is not None:
            imu[key] = v
    parsed = scenario_from_dict(sc, str(camp.scenario_file or camp.source), camp.scenario_base_dir)
    # what this IMU can take of the case's effects and noise (its maps; ours: all): the truth is
    # what it got, the rest is listed as not injected
    from components.simulation.unit_maps import maps_for, plan_injection

    inj = plan_injection(parsed.imu_effects, parsed.imu_noise,
                         *maps_for(sys_.path, sys_.effect_map, sys_.noise_map, sys_.seed_parameter, str(camp.source)))
    truth = {k: v for k, v in {**inj.effects, **parsed.table_effects}.items() if v != 0.0}
    lost = {"effects": sorted(inj.not_injected["effects"]), "noise": sorted(inj.not_injected["noise"]),
            "seed": inj.seed_parameter is None, "noise_free": inj.noise_free}
    if check_only:
        return sc, truth, lost
    return sc, dict(sorted(truth.items())), lost


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
