"""Build and run a scenario: the system (calibration controller -> turntable FMU -> IMU FMU,
connected per role) through the orchestrator's Python API, run until the controller reports
done; the recording becomes a calbench-log/1 log, and :func:`write_outputs` writes
``<stem>.csv`` + ``<stem>.json`` and ``<stem>.truth.json`` (everything injected: nonzero effect
parameters in SI, noise, seed, geometry, site, schedule, segment times, FMU SHA-256s).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from components.control.controller import CalibrationController
from components.control.schedule import DEG
from components.errors import ScenarioError
from components.model.result import file_sha256
from components.simulation.roles import OUTPUT_CODES
from components.simulation.scenario import TRUTH_FORMAT, Scenario, scenario_from_dict
from components.simulation.unit_maps import maps_for, plan_injection, unknown_count_weight


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
    import numpy as np

    from components.model.geometry import perpendicular_pair

    out = {"site.latitude": math.radians(sc.site["latitude_deg"]), "site.height": sc.site["height_m"],
           "site.gravity": sc.site["gravity_mps2"]}
    nonorth: dict = {}
    pairs: dict = {}
    for k, v in sc.table_effects.items():
        parts = k.split(".")
        if parts[1] == "base_tilt":
            out[f"base.tilt.{parts[2]}"] = v
            continue
        if parts[1] == "base_azimuth":
            out["base.azimuth"] = v
            continue
        if parts[1] == "reversal":
            out[f"{fmu_axis[parts[2]]}.encoder.reversal"] = v
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


def _check_servo_step(sc: Scenario, rate) -> None:
    """A table whose servo runs at a fixed rate (ours: the parameter servo.rate) steps by whole
    servo periods only (its own check, to 1e-9 of the step): refused here as bad input, before a
    run that its first step would stop."""
    if not rate:
        return
    period = 1.0 / float(rate)
    n = round(sc.step / period)
    if n < 1 or abs(sc.step - n * period) > 1e-9 * sc.step:
        near = sorted({max(1, math.floor(sc.step / period)), max(1, math.ceil(sc.step / period))})
        raise ScenarioError(f"{sc.source}: [scenario] step = {sc.step:g} s: the turntable's servo runs at "
                            f"servo.rate = {float(rate):g} Hz, so a step must be a whole number of its periods "
                            f"({period:g} s): e.g. " + " or ".join(f"{k * period:g} s" for k in near))


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
    _check_servo_step(sc, tparams.get("servo.rate", tstart.get("servo.rate")))
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
    # the rate limit the table FMU states (a parameter or its start value), where it states one
    rmax = [tparams.get(f"{fmu_axis[a]}.rate_max", tstart.get(f"{fmu_axis[a]}.rate_max")) for a in axes]
    rmax = [float(r) for r in rmax] if all(r is not None for r in rmax) else None
    imu_names = set(istart) | _names(imu_path)
    # the vocabulary's effects and noise through the unit's maps (ours: the identity); what the
    # FMU has no parameter for is not injected, and the truth says so
    em, nm, seed_par = maps_for(imu_path, sc.imu_effect_map, sc.imu_noise_map, sc.imu_seed_parameter,
                                f"{sc.source}: [imu]")
    injection = plan_injection(sc.imu_effects, sc.imu_noise, em, nm, seed_par)
    # a parameter set twice, by an injected effect or noise term and by hand, would run with the
    # hand's value while the truth records the injected one
    both = sorted(set(injection.parameters) & set(sc.imu_parameters))
    if seed_par is not None and seed_par in injection.parameters:
        both.append(seed_par)
    if both:
        raise ScenarioError(f"{sc.source}: [imu.parameters] sets {', '.join(map(repr, both))}, which "
                            f"[imu.effects] / [imu.noise] (or the seed) already set through the unit's maps: give "
                            "each once (the truth records the effects)")
    iparams = {**injection.parameters, **sc.imu_parameters}
    if seed_par is not None:
        iparams[seed_par] = sc.seed
    multiple = int(round(1.0 / (sc.controller_rate_hz * sc.step)))
    ctrl = CalibrationController("ctrl", sc.schedule, axes=axes, counts_per_rev=cpr, acc_max=acc, rate_max=rmax)
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
    # an IMU that chooses its output kind by parameter (ours: gyro.output / acc.output) is told
    # the kind the scenario declares, so the role's unit and the FMU's output agree
    for sensor, kind in (("gyro", sc.gyro_output), ("acc", sc.acc_output)):
        if f"{sensor}.output" in imu_names and f"{sensor}.output" not in iparams:
            iparams[f"{sensor}.output"] = OUTPUT_CODES[kind]
    weights = count_weights(sc, istart, imu_names, iparams)
    if len(integrals) == 2 and "input_integrals" in imu_names and "input_integrals" not in iparams:
        conns += [Connection(f"table.{src}", f"imu.{dst}") for src, dst in integrals]
        iparams["input_integrals"] = 1
    units, order = [], ["ctrl", "table", "imu"]
    if sc.temperature_profile is not None:
        from components.simulation.temperature import TemperatureSource, piecewise_linear

        env = sc.imu_mapping.get("temperature_env", "temperature_env")
        if env not in imu_names:
            raise ScenarioError(f"{sc.source}: [temperature] profile: the IMU {imu_path.name} has no input {env!r} to "
                                "take it (map its environment temperature input in [imu] mapping)")
        if "temperature.mode" in imu_names:
            iparams["temperature.mode"] = 2  # (ours: follow the input; a supplier's IMU as it is made)
        units.append(UnitSpec("tempsrc", component=TemperatureSource("tempsrc", piecewise_linear(sc.temperature_profile))))
        order.insert(0, "tempsrc")
        conns.append(Connection("tempsrc.temperature_env", "imu.temperature_env"))
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
        name=sc.name, step=sc.step, start=0.0, stop=n_steps * sc.step, order=order,
        units=units + [UnitSpec("ctrl", component=ctrl, step_multiple=multiple),
               UnitSpec("table", fmu=str(table_path), role="turntable", role_options={"axes": list(axes)},
                        parameters=tparams, mapping=dict(sc.table_mapping)),
               UnitSpec("imu", fmu=str(imu_path), role="imu",
                        role_options={"gyro_output": sc.gyro_output, "acc_output": sc.acc_output},
                        parameters=iparams, mapping=dict(sc.imu_mapping))],
        connections=conns, record=rec, source=sc.source, base_dir=sc.base_dir)
    info = {"table_path": table_path, "imu_path": imu_path, "geometry": geo, "table_parameters": tparams,
            "imu_parameters": iparams, "counts_per_rev": cpr, "acc_max": acc, "controller_multiple": multiple,
            "injection": injection, "count_weights": weights}
    return system, ctrl, info


def count_weights(sc: Scenario, istart: dict, imu_names: set, iparams: dict) -> dict:
    """The weight (SI: rad, m/s) of one count of each sensor whose output is counts, for the
    log: stated in the unit description (and then set on an FMU that has our
    ``<sensor>.count_weight`` parameter), else that parameter's value. A supplier's pulse IMU
    without either is refused before the run: a log with counts of unknown weight calibrates
    to scale factors off by that weight."""
    stated = sc.imu_count_weight or {}
    kinds = {"gyro": sc.gyro_output, "acc": sc.acc_output}
    why = unknown_count_weight(kinds, stated, set(iparams) | set(istart), Path(sc.imu_fmu).name)
    if why:
        raise ScenarioError(f"{sc.source}: [imu]: {why}")
    out = {}
    for sensor, kind in kinds.items():
        if kind != "counts":
            continue
        par = f"{sensor}.count_weight"
        if sensor in stated:
            if par in sc.imu_parameters and sc.imu_parameters[par] != stated[sensor]:
                raise ScenarioError(f"{sc.source}: [imu]: count_weight.{sensor} = {stated[sensor]:g} and "
                                    f"parameters {par} = {sc.imu_parameters[par]!r} differ: give one")
            if par in imu_names:
                iparams[par] = stated[sensor]
            out[sensor] = stated[sensor]
        else:
            out[sensor] = float(iparams.get(par, istart.get(par)))
    return out


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
    from components.logs.recording import log_from_recording

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
    for sensor, key in (("gyro", "gyro_count_rad"), ("acc", "acc_count_mps")):
        meta["imu"][key] = info["count_weights"].get(sensor)
    desc = sc.description or f"simulated run of scenario {sc.name}"
    log = log_from_recording(rec, metadata=meta, table="table", imu="imu", axes=sc.table_axes,
                             segment_signal="ctrl.segment", segment_labels=ctrl.labels, description=desc)
    cpr = info["counts_per_rev"]
    if sc.table_fmu.startswith("builtin:turntable") and cpr:
        # the built-in table's encoder is known: the log states its count, which the logged angles
        # alone may not show (a spin of whole quarter degrees a sample never logs one count)
        log.encoder_resolution = np.full(len(sc.table_axes), 2 * np.pi / cpr)
    for a in sc.table_axes:
        # kept as extra columns (the spec keeps unknown columns): the servo replay of
        # components.simulation.replay drives a turntable FMU with the same mode and rate commands
        log.extra[f"servo_mode_{a}"] = np.asarray(rec[f"table.{a}.mode"][1:], dtype=float)
        log.extra[f"servo_rate_{a}"] = np.asarray(rec[f"table.{a}.rate_cmd"][1:], dtype=float)
    truth = truth_of(sc, ctrl, info, rec)
    return RunResult(sc, rec, ctrl, log, truth, info)


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


def truth_of(sc: Scenario, ctrl: CalibrationController, info: dict, rec) -> dict:
    sched = sc.schedule
    st = sched.settings
    inj = info["injection"]
    effects = {k: v for k, v in {**inj.effects, **sc.table_effects}.items() if v != 0.0}

    return {
        "format": TRUTH_FORMAT,
        "scenario": {"name": sc.name, "description": sc.description, "source": sc.source,
                     "sha256": file_sha256(sc.source) if sc.source and Path(sc.source).exists() else None},
        "seed": sc.seed if inj.seed_parameter is not None else None,
        "effects": effects,
        "noise": dict(inj.noise),
        # asked for but not reachable through the IMU's maps: not in the truth above
        "not_injected": {**inj.not_injected, "seed": inj.seed_parameter is None},
        "imu": {"fmu": str(info["imu_path"]), "sha256": file_sha256(info["imu_path"]),
                "parameters": {k: v for k, v in info["imu_parameters"].items() if v != 0 or k == "seed"},
                "gyro_output": sc.gyro_output, "acc_output": sc.acc_output, "sample_interval_s": sc.step},
        "turntable": {"fmu": str(info["table_path"]), "sha256": file_sha256(info["table_path"]),
                      "parameters": info["table_parameters"], "counts_per_rev": info["counts_per_rev"],
                      "acc_max_rps2": info["acc_max"]},
        # as the log states it: the scenario's 0 (normal gravity) is the log's null
        "site": {**sc.site, "gravity_mps2": sc.site["gravity_mps2"] or None},
        # the environment the IMU followed (None: its own temperature parameters)
        "temperature_profile": None if sc.temperature_profile is None else [list(k) for k in sc.temperature_profile],
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
    from components.logs.logfile import log_stem, write_log

    stem = log_stem(stem)
    paths = write_log(stem, result.log, fmt)
    from components.model.result import file_sha256

    # the truth names the samples it is the truth of (a truth file beside another run's log,
    # with the same schedule, is otherwise indistinguishable: report judged against it)
    # (by format, not by name: the same run under another stem is the same truth, byte for byte)
    truth = {**result.truth, "samples_sha256": {p.suffix[1:]: file_sha256(p) for p in paths
                                                if p.suffix in (".csv", ".parquet")}}
    tp = Path(str(stem) + ".truth.json")
    tp.write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
    return paths + [tp]


def schedule_motion_log(schedule: str, dwell: float | None = None, step: float = 0.005):
    """Noise- and error-free simulated log of a schedule (name or path) on the built-in FMUs:
    the motion a plan is judged on."""
    sched = {"path": str(Path(schedule).resolve())} if schedule.endswith(".toml") else {"name": schedule}
    if dwell is not None:
        sched["overrides"] = {"dwell": dwell}
    sc = scenario_from_dict({"scenario": {"name": f"plan-{Path(schedule).stem}", "step": step},
                             "schedule": sched, "site": {"latitude_deg": 39.9, "height_m": 50.0},
                             "turntable": {"fmu": "builtin:turntable"}, "imu": {"fmu": "builtin:imu"}},
                            source=f"plan {schedule}")
    return run_scenario(sc, progress=False).log
