"""Scenarios: a schedule run on a turntable FMU with an IMU FMU, written as a calbench-log/1
measurement log plus the injected truth.

A scenario file (TOML)::

    [scenario]
    name = "six-position-nav"
    description = "free text"
    step = 0.005                 # communication step = IMU sample interval [s]
    controller_rate_hz = 10      # the calibration controller's rate (a divisor of 1/step)
    seed = 1                     # IMU noise seed

    [schedule]
    name = "six_position"        # a ready-made schedule (components/schedules), or
    # path = "my_schedule.toml"  # a schedule file (relative to this file)
    [schedule.overrides]         # values of the schedule's [parameters]
    dwell = 30.0

    [site]
    latitude_deg = 39.9
    height_m = 50.0
    gravity_mps2 = 0.0           # 0: WGS-84 normal gravity

    [turntable]
    fmu = "builtin:turntable"    # or a path (relative to this file)
    axes = ["outer", "middle", "inner"]     # role axis names, base to plate
    mapping = {}                 # role variable -> the FMU's name
    # counts_per_rev = 16777216  # default: from <axis>.encoder.bits of the FMU
    # acc_max_dps2 = 200.0       # default: from <axis>.acc_max of the FMU
    [turntable.effects]          # vocabulary names (components.effects), SI or "number unit"
    "table.base_tilt.x" = "1 arcmin"
    [turntable.parameters]       # any other FMU parameter, the FMU's names, SI
    "outer.rate_max" = 1.0

    [imu]
    fmu = "builtin:imu"
    mapping = {}
    gyro_output = "increment"    # the unit's output kind (role option)
    acc_output = "increment"
    [imu.effects]                # vocabulary names = the IMU FMU's parameter names
    "gyro.bias.x" = "0.01 deg/h"
    "acc.sf.y" = "30 ppm"
    [imu.noise]
    "gyro.noise.arw" = "0.001 deg/sqrt(h)"
    "acc.noise.vrw" = "5 ug/sqrt(Hz)"
    [imu.parameters]             # any other FMU parameter

Values are SI numbers or strings "<number> <unit>" with a unit of the parameter's dimension
(rad: rad, deg, arcmin, arcsec, urad; rad/s: deg/h, deg/s; m/s2: ug, mg, g; 1: ppm; m: mm, cm;
s: ms, us; and each effect's display unit from components.effects).

:func:`run_scenario` builds the system (controller -> turntable -> IMU, connections per role)
with the orchestrator's Python API, runs it until the controller reports done, and
:func:`write_outputs` writes ``<stem>.csv`` + ``<stem>.json`` (calbench-log/1) and
``<stem>.truth.json`` (everything injected: nonzero effect parameters in SI, noise, seed,
geometry, site, schedule, segment times, FMU SHA-256s).
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from components.controller import CalibrationController
from components.effects import EFFECTS, G0, effect_of
from components.schedule import DEG, Schedule, ScheduleError, load_schedule
from orchestrator.tomlfile import read_toml

TRUTH_FORMAT = "calbench-truth/1"
ARCSEC = DEG / 3600.0
DEG_H = DEG / 3600.0
UG = 1e-6 * G0

# SI unit -> readable units of that dimension (SI per unit)
_UNITS = {
    "rad": {"rad": 1.0, "deg": DEG, "arcmin": 60 * ARCSEC, "arcsec": ARCSEC, "urad": 1e-6, "mrad": 1e-3},
    "rad/s": {"rad/s": 1.0, "deg/h": DEG_H, "deg/s": DEG},
    "m/s2": {"m/s2": 1.0, "ug": UG, "mg": 1e-3 * G0, "g": G0},
    "1": {"1": 1.0, "ppm": 1e-6},
    "m": {"m": 1.0, "mm": 1e-3, "cm": 1e-2},
    "s": {"s": 1.0, "ms": 1e-3, "us": 1e-6},
}
_NOISE_UNITS = {
    "gyro.noise.arw": ("rad/sqrt(s)", {"deg/sqrt(h)": DEG / 60.0, "rad/sqrt(s)": 1.0}),
    "gyro.noise.bi": ("rad/s", _UNITS["rad/s"]),
    "gyro.noise.bi_tau": ("s", _UNITS["s"]),
    "gyro.noise.rrw": ("rad/s/sqrt(s)", {"rad/s/sqrt(s)": 1.0, "deg/h/sqrt(h)": DEG_H / 60.0}),
    "acc.noise.vrw": ("m/s/sqrt(s)", {"m/s/sqrt(s)": 1.0, "ug/sqrt(Hz)": UG, "m/s/sqrt(h)": 1 / 60.0}),
    "acc.noise.bi": ("m/s2", _UNITS["m/s2"]),
    "acc.noise.bi_tau": ("s", _UNITS["s"]),
    "acc.noise.rrw": ("m/s2/sqrt(s)", {"m/s2/sqrt(s)": 1.0, "ug/sqrt(s)": UG, "ug/sqrt(h)": UG / 60.0}),
}


class ScenarioError(ValueError):
    """A scenario file is wrong: names the file, the key and what was expected."""


@dataclass
class Scenario:
    name: str
    schedule: Schedule
    step: float = 0.005
    controller_rate_hz: float = 10.0
    seed: int = 1
    description: str = ""
    site: dict = field(default_factory=lambda: {"latitude_deg": 39.9, "height_m": 50.0, "gravity_mps2": 0.0})
    table_fmu: str = "builtin:turntable"
    table_axes: list = field(default_factory=lambda: ["outer", "middle", "inner"])
    table_mapping: dict = field(default_factory=dict)
    table_effects: dict = field(default_factory=dict)     # vocabulary name -> SI
    table_parameters: dict = field(default_factory=dict)  # FMU name -> SI
    counts_per_rev: int | None = None
    acc_max: float | None = None                          # rad/s^2
    imu_fmu: str = "builtin:imu"
    imu_mapping: dict = field(default_factory=dict)
    gyro_output: str = "increment"
    acc_output: str = "increment"
    imu_effects: dict = field(default_factory=dict)
    imu_noise: dict = field(default_factory=dict)
    imu_parameters: dict = field(default_factory=dict)
    schedule_spec: str = ""
    schedule_overrides: dict = field(default_factory=dict)
    geometry_axes: dict = field(default_factory=dict)   # role axis -> rotation axis (filled by build_system)
    source: str | None = None
    base_dir: Path = field(default_factory=Path.cwd)


# ----------------------------------------------------------------------------- parsing
def _value(v, key: str, where: str, units: dict, si: str):
    if isinstance(v, bool):
        raise ScenarioError(f"{where}: {key} = {v!r}: expected a number [{si}] or '<number> <unit>'")
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str):
        parts = v.split(None, 1)
        try:
            x = float(parts[0])
        except (ValueError, IndexError):
            x = None
        if x is not None and len(parts) == 2 and parts[1].strip() in units:
            return x * units[parts[1].strip()]
    raise ScenarioError(f"{where}: {key} = {v!r}: expected a number [{si}] or '<number> <unit>' with unit one of "
                        f"{', '.join(units)}")


def _effect_value(name: str, v, where: str) -> float:
    try:
        e = effect_of(name)
    except KeyError:
        raise ScenarioError(f"{where}: {name!r} is not a parameter of the effect vocabulary "
                            f"(components.effects; effects: {', '.join(EFFECTS)})") from None
    units = dict(_UNITS.get(e.unit, {e.unit: 1.0}))
    if e.display[0]:
        units[e.display[0]] = e.display[1]
    return _value(v, name, where, units, e.unit)


def _table(d: dict, key: str, where: str) -> dict:
    v = d.get(key, {})
    if not isinstance(v, dict):
        raise ScenarioError(f"{where}: {key}: expected a table")
    return v


def _keys(d: dict, allowed: set, where: str) -> None:
    extra = set(d) - allowed
    if extra:
        raise ScenarioError(f"{where}: unknown key(s) {sorted(extra)}; expected some of {sorted(allowed)}")


def scenario_from_dict(data: dict, source: str = "scenario", base_dir: Path | None = None,
                       overrides: dict | None = None) -> Scenario:
    """``overrides``: schedule parameter values that replace the file's (e.g. from ``--dwell``)."""
    base_dir = base_dir or Path.cwd()
    _keys(data, {"scenario", "schedule", "site", "turntable", "imu"}, source)
    sc = _table(data, "scenario", source)
    w = f"{source}: [scenario]"
    _keys(sc, {"name", "description", "step", "controller_rate_hz", "seed"}, w)
    step = sc.get("step", 0.005)
    if isinstance(step, bool) or not isinstance(step, (int, float)) or not step > 0:
        raise ScenarioError(f"{w}: step = {step!r}: expected a positive step [s]")
    rate = sc.get("controller_rate_hz", 10.0)
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not rate > 0:
        raise ScenarioError(f"{w}: controller_rate_hz = {rate!r}: expected a positive rate [Hz]")
    m = 1.0 / (rate * step)
    if abs(m - round(m)) > 1e-9 or round(m) < 1:
        raise ScenarioError(f"{w}: controller_rate_hz = {rate!r}: expected a rate whose period is a whole "
                            f"number of steps of {step} s")
    seed = sc.get("seed", 1)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise ScenarioError(f"{w}: seed = {seed!r}: expected an integer")

    sd = _table(data, "schedule", source)
    w = f"{source}: [schedule]"
    _keys(sd, {"name", "path", "overrides"}, w)
    if ("name" in sd) == ("path" in sd):
        raise ScenarioError(f"{w}: expected exactly one of 'name' (a ready-made schedule) or 'path' (a file)")
    spec = sd.get("name", sd.get("path"))
    if not isinstance(spec, str):
        raise ScenarioError(f"{w}: {'name' if 'name' in sd else 'path'} = {spec!r}: expected text")
    ov = dict(_table(sd, "overrides", w))
    ov.update(overrides or {})
    try:
        if "path" in sd:
            p = Path(spec)
            schedule = load_schedule(p if p.is_absolute() else base_dir / p, ov)
            if not spec.endswith(".toml"):
                raise ScenarioError(f"{w}: path = {spec!r}: expected a .toml file")
        else:
            schedule = load_schedule(spec, ov)
    except ScheduleError as e:
        raise ScenarioError(f"{source}: {e}") from None

    site = _table(data, "site", source)
    w = f"{source}: [site]"
    _keys(site, {"latitude_deg", "height_m", "gravity_mps2"}, w)
    site_out = {"latitude_deg": 39.9, "height_m": 50.0, "gravity_mps2": 0.0}
    for k, v in site.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ScenarioError(f"{w}: {k} = {v!r}: expected a number")
        site_out[k] = float(v)
    if not -90 <= site_out["latitude_deg"] <= 90:
        raise ScenarioError(f"{w}: latitude_deg = {site_out['latitude_deg']}: expected [-90, 90]")

    tt = _table(data, "turntable", source)
    w = f"{source}: [turntable]"
    _keys(tt, {"fmu", "axes", "mapping", "counts_per_rev", "acc_max_dps2", "effects", "parameters"}, w)
    axes = tt.get("axes", ["outer", "middle", "inner"])
    if not isinstance(axes, list) or not 1 <= len(axes) <= 3 or not all(isinstance(a, str) and a for a in axes):
        raise ScenarioError(f"{w}: axes = {axes!r}: expected a list of 1 to 3 axis names, base to plate")
    cpr = tt.get("counts_per_rev")
    if cpr is not None and (isinstance(cpr, bool) or not isinstance(cpr, int) or cpr < 0):
        raise ScenarioError(f"{w}: counts_per_rev = {cpr!r}: expected an integer >= 0 (0: no rounding)")
    acc = tt.get("acc_max_dps2")
    if acc is not None and (isinstance(acc, bool) or not isinstance(acc, (int, float)) or not acc > 0):
        raise ScenarioError(f"{w}: acc_max_dps2 = {acc!r}: expected a positive acceleration [deg/s^2]")
    table_effects = {}
    for k, v in _table(tt, "effects", w).items():
        if not k.startswith("table."):
            raise ScenarioError(f"{w}.effects: {k!r}: expected a table effect (table.base_tilt, table.nonorth, "
                                "table.wobble, table.encoder); IMU effects go in [imu.effects]")
        table_effects[k] = _effect_value(k, v, f"{w}.effects")
    for k in table_effects:
        parts = k.split(".")
        if len(parts) == 4 and parts[2] not in axes:
            raise ScenarioError(f"{w}.effects: {k!r}: the table has no axis {parts[2]!r} (axes: {axes})")
    table_params = {k: _param(v, k, f"{w}.parameters") for k, v in _table(tt, "parameters", w).items()}

    im = _table(data, "imu", source)
    w = f"{source}: [imu]"
    _keys(im, {"fmu", "mapping", "gyro_output", "acc_output", "effects", "noise", "parameters"}, w)
    imu_effects = {}
    for k, v in _table(im, "effects", w).items():
        if k.startswith("table."):
            raise ScenarioError(f"{w}.effects: {k!r} is a table effect: expected it in [turntable.effects]")
        imu_effects[k] = _effect_value(k, v, f"{w}.effects")
    imu_noise = {}
    for k, v in _table(im, "noise", w).items():
        if k not in _NOISE_UNITS:
            raise ScenarioError(f"{w}.noise: {k!r}: expected one of {', '.join(_NOISE_UNITS)}")
        si, units = _NOISE_UNITS[k]
        imu_noise[k] = _value(v, k, f"{w}.noise", units, si)
    imu_params = {k: _param(v, k, f"{w}.parameters") for k, v in _table(im, "parameters", w).items()}
    if "seed" in imu_params:
        raise ScenarioError(f"{w}.parameters: seed: give the seed as [scenario] seed")
    for k in ("gyro_output", "acc_output"):
        if k in im and not isinstance(im[k], str):
            raise ScenarioError(f"{w}: {k} = {im[k]!r}: expected text")
    for k in ("fmu",):
        for d, ww in ((tt, "[turntable]"), (im, "[imu]")):
            if k in d and not isinstance(d[k], str):
                raise ScenarioError(f"{source}: {ww}: fmu = {d[k]!r}: expected 'builtin:<name>' or a path")
    for d, ww in ((tt, "[turntable]"), (im, "[imu]")):
        mp = d.get("mapping", {})
        if not isinstance(mp, dict) or not all(isinstance(v, str) for v in mp.values()):
            raise ScenarioError(f"{source}: {ww}: mapping = {mp!r}: expected a table of role name = FMU name")

    return Scenario(
        name=sc.get("name", Path(source).stem), description=sc.get("description", ""), schedule=schedule,
        step=float(step), controller_rate_hz=float(rate), seed=seed, site=site_out,
        table_fmu=tt.get("fmu", "builtin:turntable"), table_axes=list(axes), table_mapping=dict(tt.get("mapping", {})),
        table_effects=table_effects, table_parameters=table_params, counts_per_rev=cpr,
        acc_max=None if acc is None else float(acc) * DEG,
        imu_fmu=im.get("fmu", "builtin:imu"), imu_mapping=dict(im.get("mapping", {})),
        gyro_output=im.get("gyro_output", "increment"), acc_output=im.get("acc_output", "increment"),
        imu_effects=imu_effects, imu_noise=imu_noise, imu_parameters=imu_params,
        schedule_spec=spec, schedule_overrides=ov, source=source, base_dir=base_dir)


def _param(v, key: str, where: str):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ScenarioError(f"{where}: {key} = {v!r}: expected a number (SI)")
    return v


def load_scenario(path: str | Path, overrides: dict | None = None) -> Scenario:
    p = Path(path)
    data = read_toml(p, ScenarioError, "scenario")
    return scenario_from_dict(data, str(p), p.parent.resolve(), overrides)


# ----------------------------------------------------------------------------- building
def _fmu_path(spec: str, base_dir: Path) -> Path:
    from orchestrator.fmu_resolver import resolve_fmu

    return resolve_fmu(spec, base_dir)


def _starts(path: Path) -> dict:
    from fmpy import read_model_description

    out = {}
    for v in read_model_description(str(path)).modelVariables:
        if v.start is not None:
            try:
                out[v.name] = float(v.start)
            except ValueError:
                pass
    return out


def table_fmu_parameters(sc: Scenario, fmu_axis: dict) -> dict:
    """FMU parameters (the FMU's names, SI) for the table: site, the table effects mapped onto
    the FMU's parameters, then the explicit parameters."""
    from components.geometry import perpendicular_pair
    import numpy as np

    out = {"site.latitude": math.radians(sc.site["latitude_deg"]), "site.height": sc.site["height_m"],
           "site.gravity": sc.site["gravity_mps2"]}
    nonorth: dict = {}
    pairs: dict = {}
    for k, v in sc.table_effects.items():
        parts = k.split(".")
        if parts[1] == "base_tilt":
            out[f"base.tilt.{parts[2]}"] = v
            continue
        ax, comp = fmu_axis[parts[2]], parts[3]
        if parts[1] == "nonorth":
            nonorth.setdefault(parts[2], {})[comp] = v
        elif parts[1] == "wobble":
            pairs.setdefault((f"{ax}.wobble", "cs"), {})[comp] = v
        elif parts[1] == "encoder":
            h = comp[1]
            pairs.setdefault((f"{ax}.encoder.h{h}", "sc"), {})[comp[0]] = v
    for (prefix, kind), d in pairs.items():
        if kind == "cs":    # A cos(phi), A sin(phi)
            c, s = d.get("c", 0.0), d.get("s", 0.0)
            out[f"{prefix}.amp"], out[f"{prefix}.phase"] = math.hypot(c, s), math.atan2(s, c)
        else:               # s sin(th) + c cos(th) = A sin(th + phi)
            s, c = d.get("s", 0.0), d.get("c", 0.0)
            out[f"{prefix}.amp"], out[f"{prefix}.phase"] = math.hypot(s, c), math.atan2(c, s)
    for axis, d in nonorth.items():
        a = np.asarray(sc.geometry_axes[axis], float)
        u, v = perpendicular_pair(a / np.linalg.norm(a))
        vec = d.get("u", 0.0) * u + d.get("v", 0.0) * v
        for i, c in enumerate("xyz"):
            out[f"{fmu_axis[axis]}.nonorth.{c}"] = float(vec[i])
    out.update(sc.table_parameters)
    return out


def build_system(sc: Scenario, record: list[str] | None = None):
    """(System, controller, info) for the scenario; ``record`` adds signals to record."""
    from orchestrator.system import Connection, System, UnitSpec

    table_path = _fmu_path(sc.table_fmu, sc.base_dir)
    imu_path = _fmu_path(sc.imu_fmu, sc.base_dir)
    for what, p in (("turntable", table_path), ("imu", imu_path)):
        if not p.exists():
            raise ScenarioError(f"{sc.source}: [{what}] fmu: file {p} does not exist")
    tstart, istart = _starts(table_path), _starts(imu_path)
    axes = sc.table_axes
    fmu_axis = {a: sc.table_mapping.get(f"{a}.angle", f"{a}.angle").rsplit(".", 1)[0] for a in axes}
    # geometry: axis vectors from the parameters or the FMU's start values
    geo = {}
    for a in axes:
        names = [f"{fmu_axis[a]}.axis.{c}" for c in "xyz"]
        vals = [sc.table_parameters.get(n, tstart.get(n)) for n in names]
        if any(v is None for v in vals):
            raise ScenarioError(f"{sc.source}: [turntable]: the FMU has no parameters {names} for the "
                                f"rotation axis of {a!r}: expected the builtin turntable's geometry parameters")
        geo[a] = [float(v) for v in vals]
    sc.geometry_axes = geo
    tparams = table_fmu_parameters(sc, fmu_axis)
    if "n_axes" in tstart and "n_axes" not in tparams:
        tparams["n_axes"] = len(axes)
    # encoder resolution and acceleration limit the controller assumes
    cpr = sc.counts_per_rev
    if cpr is None:
        bits = {int(tparams.get(f"{fmu_axis[a]}.encoder.bits", tstart.get(f"{fmu_axis[a]}.encoder.bits", 24)))
                for a in axes}
        if len(bits) > 1:
            raise ScenarioError(f"{sc.source}: [turntable]: the axes have different encoder resolutions {bits}: "
                                "give counts_per_rev")
        b = bits.pop()
        cpr = 2 ** b if b > 0 else 0
    acc = [sc.acc_max if sc.acc_max is not None else
           float(tparams.get(f"{fmu_axis[a]}.acc_max", tstart.get(f"{fmu_axis[a]}.acc_max", 200 * DEG)))
           for a in axes]
    imu_names = set(istart) | _names(imu_path)
    iparams = {**sc.imu_effects, **sc.imu_noise, **sc.imu_parameters}
    if sc.imu_mapping.get("seed", "seed") in imu_names:
        iparams["seed"] = sc.seed  # a supplier's IMU may have no noise seed
    multiple = int(round(1.0 / (sc.controller_rate_hz * sc.step)))
    ctrl = CalibrationController("ctrl", sc.schedule, axes=axes, counts_per_rev=cpr, acc_max=acc)
    conns = []
    for a in axes:
        for v in ("mode", "angle_cmd", "rate_cmd"):
            conns.append(Connection(f"ctrl.{a}.{v}", f"table.{a}.{v}"))
        for v in ("angle", "rate"):
            conns.append(Connection(f"table.{a}.{v}", f"ctrl.{a}.{v}"))
    conns += [Connection("table.plate.omega", "imu.omega"), Connection("table.plate.f", "imu.f")]
    if sc.imu_mapping.get("alpha.x", "alpha.x") in imu_names:
        conns.append(Connection("table.plate.alpha", "imu.alpha"))
    # exact step integrals of the plate motion, when the table gives them and the IMU takes
    # them: without them the IMU's interpolation between samples misses the servo's transients
    # (a stop inside a step costs ~7e-6 rad, two orders above a navigation-grade gyro's noise)
    table_names = set(tstart) | _names(table_path)
    integrals = [(src, dst) for src, dst in (("plate.omega_int", "omega_int"), ("plate.f_int", "f_int"))
                 if sc.table_mapping.get(f"{src}.x", f"{src}.x") in table_names
                 and sc.imu_mapping.get(f"{dst}.x", f"{dst}.x") in imu_names]
    if len(integrals) == 2 and "input_integrals" in imu_names and "input_integrals" not in iparams:
        conns += [Connection(f"table.{src}", f"imu.{dst}") for src, dst in integrals]
        iparams["input_integrals"] = 1
    rec = ["imu.gyro", "imu.acc", "ctrl.segment", "ctrl.done"]
    if sc.imu_mapping.get("temperature", "temperature") in imu_names:
        rec.append("imu.temperature")
    rec += [f"table.{a}.angle" for a in axes] + [f"table.{a}.angle_cmd" for a in axes]
    # the full command (mode and rate too): extra log columns a servo replay can use
    rec += [f"table.{a}.mode" for a in axes] + [f"table.{a}.rate_cmd" for a in axes]
    rec += [r for r in (record or []) if r not in rec]
    period = multiple * sc.step
    bound = sc.schedule.time_bound(min(acc))
    n_steps = int(math.ceil(bound / period)) * multiple
    system = System(
        name=sc.name, step=sc.step, start=0.0, stop=n_steps * sc.step, order=["ctrl", "table", "imu"],
        units=[UnitSpec("ctrl", component=ctrl, step_multiple=multiple),
               UnitSpec("table", fmu=str(table_path), role="turntable", role_options={"axes": list(axes)},
                        parameters=tparams, mapping=dict(sc.table_mapping)),
               UnitSpec("imu", fmu=str(imu_path), role="imu",
                        role_options={"gyro_output": sc.gyro_output, "acc_output": sc.acc_output},
                        parameters=iparams, mapping=dict(sc.imu_mapping))],
        connections=conns, record=rec, source=sc.source, base_dir=sc.base_dir)
    info = {"table_path": table_path, "imu_path": imu_path, "geometry": geo, "table_parameters": tparams,
            "imu_parameters": iparams, "counts_per_rev": cpr, "acc_max": acc, "controller_multiple": multiple}
    return system, ctrl, info


def _names(path: Path) -> set:
    from fmpy import read_model_description

    return {v.name for v in read_model_description(str(path)).modelVariables}


@dataclass
class RunResult:
    scenario: Scenario
    recording: object
    controller: CalibrationController
    log: object
    truth: dict
    info: dict


def run_scenario(sc: Scenario, record: list[str] | None = None, progress: bool | None = None) -> RunResult:
    """Run the scenario until the controller is done; the log and the truth in memory."""
    from components.log_recording import log_from_recording

    system, ctrl, info = build_system(sc, record)
    from orchestrator.master import Simulation

    ctrl.stop_when_done = True
    sim = Simulation(system, progress=progress)
    sim.load()
    rec = sim.run()
    if not ctrl.finished:
        raise ScenarioError(f"{sc.source}: the schedule did not finish by t = {system.stop:g} s "
                            f"(step {ctrl.schedule.steps[ctrl._i].origin})")
    rec.provenance.setdefault("system", {})["stopped_at"] = sim.stopped_at
    meta = {
        "site": {"latitude_deg": sc.site["latitude_deg"], "height_m": sc.site["height_m"],
                 "gravity_mps2": sc.site["gravity_mps2"] or None},
        "table": {"axes": [{"name": a, "axis": info["geometry"][a]} for a in sc.table_axes]},
        "imu": {"gyro_output": sc.gyro_output, "acc_output": sc.acc_output},
    }
    for sensor, key, wpar, wdef in (("gyro", "gyro_count_rad", "gyro.count_weight", 1e-6),
                                    ("acc", "acc_count_mps", "acc.count_weight", 1e-5)):
        meta["imu"][key] = float(info["imu_parameters"].get(wpar, wdef)) \
            if meta["imu"][f"{sensor}_output"] == "counts" else None
    desc = sc.description or f"simulated run of scenario {sc.name}"
    log = log_from_recording(rec, metadata=meta, table="table", imu="imu", axes=sc.table_axes,
                             segment_signal="ctrl.segment", segment_labels=ctrl.labels, description=desc)
    for a in sc.table_axes:
        # kept as extra columns (the spec keeps unknown columns): the servo replay of
        # components.replay drives a turntable FMU with the same mode and rate commands
        log.extra[f"servo_mode_{a}"] = np.asarray(rec[f"table.{a}.mode"][1:], dtype=float)
        log.extra[f"servo_rate_{a}"] = np.asarray(rec[f"table.{a}.rate_cmd"][1:], dtype=float)
    truth = _truth(sc, ctrl, info, rec)
    return RunResult(sc, rec, ctrl, log, truth, info)


def _sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _step_dict(s) -> dict:
    d = {"kind": s.kind, "label": s.label, "origin": s.origin}
    if s.kind == "index":
        d.update(angles_rad=list(s.angles), absolute=s.absolute)
    elif s.kind == "dwell":
        d.update(duration_s=s.duration)
    elif s.kind == "rotate":
        d.update(axis=s.axis, rate_rps=s.rate, turns=s.turns)
    else:
        d.update(axis=s.axis, rate_rps=s.rate, duration_s=s.duration)
    return d


def _truth(sc: Scenario, ctrl: CalibrationController, info: dict, rec) -> dict:
    sched = sc.schedule
    st = sched.settings
    effects = {k: v for k, v in {**sc.imu_effects, **sc.table_effects}.items() if v != 0.0}

    return {
        "format": TRUTH_FORMAT,
        "scenario": {"name": sc.name, "description": sc.description, "source": sc.source,
                     "sha256": _sha256(sc.source) if sc.source and Path(sc.source).exists() else None},
        "seed": sc.seed,
        "effects": effects,
        "noise": dict(sc.imu_noise),
        "imu": {"fmu": str(info["imu_path"]), "sha256": _sha256(info["imu_path"]),
                "parameters": {k: v for k, v in info["imu_parameters"].items() if v != 0 or k == "seed"},
                "gyro_output": sc.gyro_output, "acc_output": sc.acc_output, "sample_interval_s": sc.step},
        "turntable": {"fmu": str(info["table_path"]), "sha256": _sha256(info["table_path"]),
                      "parameters": info["table_parameters"], "counts_per_rev": info["counts_per_rev"],
                      "acc_max_rps2": info["acc_max"]},
        "site": dict(sc.site),
        "geometry": {"axes": [{"name": a, "axis": info["geometry"][a]} for a in sc.table_axes],
                     "base_tilt_rad": [info["table_parameters"].get("base.tilt.x", 0.0),
                                       info["table_parameters"].get("base.tilt.y", 0.0)],
                     "base_azimuth_rad": info["table_parameters"].get("base.azimuth", 0.0)},
        "schedule": {"name": sched.name, "spec": sc.schedule_spec, "source": sched.source,
                     "parameters": sched.parameters, "overrides": sc.schedule_overrides,
                     "settings": {"settle_tol_rad": st.settle_tol, "settle_rate_tol_rps": st.settle_rate_tol,
                                  "settle_hold_s": st.settle_hold, "index_timeout_s": st.index_timeout},
                     "steps": [_step_dict(s) for s in sched.steps], "labels": ctrl.labels},
        "segments": ctrl.events,
        "controller": {"rate_hz": sc.controller_rate_hz, "step_multiple": info["controller_multiple"]},
        "run": {"step_s": sc.step, "stopped_at_s": rec.provenance.get("system", {}).get("stopped_at"),
                "versions": rec.provenance.get("versions", {})},
    }


def write_outputs(result: RunResult, stem: str | Path, fmt: str = "csv") -> list[Path]:
    """``<stem>.csv``/``.parquet`` + ``<stem>.json`` (calbench-log/1) and ``<stem>.truth.json``."""
    from components.logfile import write_log

    stem = Path(stem)
    if stem.suffix.lower() in (".csv", ".parquet", ".json"):
        stem = stem.with_suffix("")
    paths = write_log(stem, result.log, fmt)
    tp = Path(str(stem) + ".truth.json")
    tp.write_text(json.dumps(result.truth, indent=1) + "\n", encoding="utf-8")
    return paths + [tp]
