"""Scenario files: a schedule to run on a turntable FMU with an IMU FMU, the effects and noise
to inject, the site and the step.

A scenario file (TOML)::

    [scenario]
    name = "six-position-nav"
    description = "free text"
    step = 0.005                 # communication step = IMU sample interval [s]
    controller_rate_hz = 10      # the calibration controller's rate (a divisor of 1/step)
    seed = 1                     # IMU noise seed

    [schedule]
    name = "six_position"        # a ready-made schedule (components/control/schedules), or
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
    [turntable.effects]          # vocabulary names (components.model.effects), SI or "number unit"
    "table.base_tilt.x" = "1 arcmin"
    [turntable.parameters]       # any other FMU parameter, the FMU's names, SI
    "outer.rate_max" = 1.0

    [imu]
    fmu = "builtin:imu"          # or a supplier's FMU: docs/supplier.md (effect_map, noise_map,
    mapping = {}                 #   seed_parameter: how the vocabulary reaches its parameters)
    gyro_output = "increment"    # the unit's output kind (role option; or role_options = {...})
    acc_output = "increment"
    # count_weight = {gyro = "0.05 arcsec", acc = "0.1 mm/s"}  # one count, for "counts" outputs
    #                            #   (default: the FMU's gyro.count_weight / acc.count_weight)
    [imu.effects]                # vocabulary names = the IMU FMU's parameter names
    "gyro.bias.x" = "0.01 deg/h"
    "acc.sf.y" = "30 ppm"
    [imu.noise]
    "gyro.noise.arw" = "0.001 deg/sqrt(h)"
    "acc.noise.vrw" = "5 ug/sqrt(Hz)"
    "acc.noise.bi" = "20 ug"
    "acc.noise.bi_tau" = 10.0        # with bi_tau_max: flicker bias instability from 10 s to 1 h
    "acc.noise.bi_tau_max" = 3600.0  # (components/model/flicker.py); without: one Gauss-Markov
    [imu.parameters]             # any other FMU parameter

Values are SI numbers or strings "<number> <unit>" with a unit of the parameter's dimension
(rad: rad, deg, arcmin, arcsec, urad; rad/s: deg/h, deg/s; m/s2: ug, mg, g; 1: ppm; m: mm, cm;
s: ms, us; and each effect's display unit from components.model.effects).

This module reads the file into a :class:`Scenario`; ``components.simulation.run`` builds and
runs it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from components.control.schedule import DEG, Schedule, load_schedule
from components.errors import ScenarioError, ScheduleError
from components.model.quantities import NOISE_TERM_UNITS, UNITS, QuantityError, effect_value, noise_value, quantity
from components.model.table_parameters import table_stage
from components.simulation.temperature import profile_from_table
from orchestrator.tomlfile import read_toml

TRUTH_FORMAT = "calbench-truth/1"


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
    # a supplier's IMU: vocabulary -> its parameters (components.simulation.unit_maps); None: ours
    imu_effect_map: dict | None = None
    imu_noise_map: dict | None = None
    imu_seed_parameter: str | None = None
    imu_count_weight: dict | None = None   # {"gyro": rad, "acc": m/s} of one count, as stated
    schedule_spec: str = ""
    schedule_overrides: dict = field(default_factory=dict)
    geometry_axes: dict = field(default_factory=dict)   # role axis -> rotation axis (filled by build_system)
    source: str | None = None
    base_dir: Path = field(default_factory=Path.cwd)
    # ((time [s], temperature [degC]), ...): the IMU's environment, piecewise linear
    # (components.simulation.temperature); None: the IMU's own temperature parameters
    temperature_profile: tuple | None = None


# ----------------------------------------------------------------------------- parsing
def _effect_value(name: str, v, where: str) -> float:
    try:
        return effect_value(name, v, where)
    except QuantityError as e:
        raise ScenarioError(str(e)) from None


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
    _keys(data, {"scenario", "schedule", "site", "turntable", "imu", "temperature"}, source)
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
            raise ScenarioError(f"{w}.effects: {k!r}: expected a table effect (table.base_tilt, table.base_azimuth, "
                                "table.nonorth, table.wobble, table.encoder, table.reversal); IMU effects go in "
                                "[imu.effects]")
        table_effects[k] = _effect_value(k, v, f"{w}.effects")
    for k in table_effects:
        stage = table_stage(k)  # (None: the base's)
        if stage is not None and stage not in axes:
            raise ScenarioError(f"{w}.effects: {k!r}: the table has no axis {stage!r} (axes: {axes})")
    table_params = {k: _param(v, k, f"{w}.parameters") for k, v in _table(tt, "parameters", w).items()}

    im = _table(data, "imu", source)
    w = f"{source}: [imu]"
    _keys(im, {"fmu", "mapping", "gyro_output", "acc_output", "role_options", "effects", "noise", "parameters",
               "effect_map", "noise_map", "seed_parameter", "count_weight"}, w)
    maps = unit_maps_of(im, w)
    if "role_options" in im:
        ro = im["role_options"]
        if not isinstance(ro, dict) or set(ro) - {"gyro_output", "acc_output"}:
            raise ScenarioError(f"{w}: role_options = {ro!r}: expected {{gyro_output, acc_output}}")
        for k in ("gyro_output", "acc_output"):
            if k in ro and k in im and ro[k] != im[k]:
                raise ScenarioError(f"{w}: {k} is given twice, differently ({im[k]!r}, role_options {ro[k]!r})")
        im = {**im, **ro}
    imu_effects = {}
    for k, v in _table(im, "effects", w).items():
        if k.startswith("table."):
            raise ScenarioError(f"{w}.effects: {k!r} is a table effect: expected it in [turntable.effects]")
        imu_effects[k] = _effect_value(k, v, f"{w}.effects")
    imu_noise = {}
    for k, v in _table(im, "noise", w).items():
        try:
            imu_noise[k] = noise_value(k, v, f"{w}.noise")
        except QuantityError as e:
            raise ScenarioError(str(e)) from None
    for sensor in ("gyro", "acc"):
        lo, hi = imu_noise.get(f"{sensor}.noise.bi_tau", 100.0), imu_noise.get(f"{sensor}.noise.bi_tau_max", 0.0)
        if hi and hi <= lo:
            # (the IMU then simulates one Gauss–Markov term of bi_tau, not the flicker floor asked for)
            raise ScenarioError(f"{w}.noise: {sensor}.noise.bi_tau_max = {hi:g} s is not above bi_tau = {lo:g} s: the "
                                "flicker floor spans bi_tau to bi_tau_max (leave bi_tau_max out for one Gauss–Markov "
                                "term of bi_tau)")
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

    profile = profile_from_table(data.get("temperature"), f"{source}: [temperature]")
    mode = imu_params.get("temperature.mode")
    if profile is not None and mode is not None and mode != 2:
        raise ScenarioError(f"{source}: [imu.parameters] temperature.mode = {mode!r} and a [temperature] profile: the "
                            "profile drives the IMU in mode 2 (its input temperature_env); leave temperature.mode out")

    return Scenario(
        temperature_profile=profile,
        name=sc.get("name", Path(source).stem), description=sc.get("description", ""), schedule=schedule,
        step=float(step), controller_rate_hz=float(rate), seed=seed, site=site_out,
        table_fmu=tt.get("fmu", "builtin:turntable"), table_axes=list(axes), table_mapping=dict(tt.get("mapping", {})),
        table_effects=table_effects, table_parameters=table_params, counts_per_rev=cpr,
        acc_max=None if acc is None else float(acc) * DEG,
        imu_fmu=im.get("fmu", "builtin:imu"), imu_mapping=dict(im.get("mapping", {})),
        gyro_output=im.get("gyro_output", "increment"), acc_output=im.get("acc_output", "increment"),
        imu_effects=imu_effects, imu_noise=imu_noise, imu_parameters=imu_params, **maps,
        schedule_spec=spec, schedule_overrides=ov, source=source, base_dir=base_dir)


OUTPUT_KINDS = {"gyro_output": ("increment", "rate", "counts"), "acc_output": ("increment", "specific_force", "counts")}


def unit_maps_of(d: dict, where: str, error=ScenarioError) -> dict:
    """The effect map, noise map and seed parameter of an IMU unit description (scenario [imu],
    campaign [systems.X]), checked for shape; their FMU parameters and units are checked against
    the FMU when the run is built (components.simulation.unit_maps)."""
    out = {"imu_effect_map": None, "imu_noise_map": None, "imu_seed_parameter": None, "imu_count_weight": None}
    for key in ("effect_map", "noise_map"):
        if key not in d:
            continue
        m = d[key]
        ok = isinstance(m, dict) and all(isinstance(v, str) or (isinstance(v, list) and len(v) == 2 and all(
            isinstance(x, str) for x in v)) for v in m.values())
        if not ok:
            raise error(f"{where}: {key} = {m!r}: expected a table of vocabulary name = the FMU's parameter, or "
                        "[its parameter, its unit]")
        out[f"imu_{key}"] = dict(m)
    if "seed_parameter" in d:
        sp = d["seed_parameter"]
        if not isinstance(sp, str) or not sp:
            raise error(f"{where}: seed_parameter = {sp!r}: expected the FMU's seed parameter name")
        out["imu_seed_parameter"] = sp
    kinds_given = {}
    for k, kinds in OUTPUT_KINDS.items():
        v = d.get(k, (d.get("role_options") or {}).get(k) if isinstance(d.get("role_options"), dict) else None)
        if v is not None and v not in kinds:
            raise error(f"{where}: {k} = {v!r}: expected one of {', '.join(kinds)}")
        kinds_given[k.split("_")[0]] = v
    if "count_weight" in d:
        out["imu_count_weight"] = count_weights_of(d["count_weight"], kinds_given, where, error)
    return out


def count_weights_of(cw, kinds: dict, where: str, error=ScenarioError) -> dict:
    """``count_weight = {gyro = "0.05 arcsec", acc = "0.1 mm/s"}``: the angle and the velocity of
    one count of an IMU with count outputs, in SI; only for a sensor whose output is counts."""
    units = {"gyro": (UNITS["rad"], "rad"), "acc": (NOISE_TERM_UNITS["acc.noise.q"][1], "m/s")}
    if not isinstance(cw, dict) or not cw or set(cw) - set(units):
        raise error(f"{where}: count_weight = {cw!r}: expected a table {{gyro = \"0.05 arcsec\", acc = "
                    "\"0.1 mm/s\"}} (the weight of one count of each sensor with count outputs)")
    out = {}
    for sensor, v in cw.items():
        if kinds.get(sensor) != "counts":
            raise error(f"{where}: count_weight.{sensor} is given, but {sensor}_output = "
                        f"{kinds.get(sensor) or 'increment'!r}: a weight is for count outputs only")
        try:
            w = quantity(v, f"count_weight.{sensor}", where, *units[sensor])
        except QuantityError as e:
            raise error(str(e)) from None
        if not (math.isfinite(w) and w > 0):
            raise error(f"{where}: count_weight.{sensor} = {v!r}: expected a positive weight")
        out[sensor] = w
    return out


def _param(v, key: str, where: str):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ScenarioError(f"{where}: {key} = {v!r}: expected a number (SI)")
    return v


def load_scenario(path: str | Path, overrides: dict | None = None) -> Scenario:
    p = Path(path)
    data = read_toml(p, ScenarioError, "scenario")
    _refuse_bare_numbers(data, str(p))
    return scenario_from_dict(data, str(p), p.parent.resolve(), overrides)


def _refuse_bare_numbers(data: dict, source: str) -> None:
    """Effect values a person wrote without a unit (components.model.quantities.refuse_bare_number)."""
    from components.model.quantities import refuse_bare_number

    for unit in ("imu", "turntable"):
        effects = data.get(unit, {}).get("effects", {}) if isinstance(data.get(unit), dict) else {}
        for k, v in (effects.items() if isinstance(effects, dict) else ()):
            try:
                refuse_bare_number(k, v, f"{source}: [{unit}.effects]")
            except QuantityError as e:
                raise ScenarioError(str(e)) from None
