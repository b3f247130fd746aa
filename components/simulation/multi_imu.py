"""One turntable run, many IMUs: Monte-Carlo seeds and hidden-effect variants on a shared motion.

The table and its controller do not depend on the IMU (it is a pure sink), so a study that varies
only the IMU — its noise seed, its effects, its temperature — can put every variant on the same
plate in one simulation: each variant is its own instance of the scenario's IMU FMU, connected to
the same table outputs. The logs share their gimbal angles exactly, so the estimators' cached
geometry columns (components.estimation.lsq) serve all of them.

Optionally a temperature source (a Python unit with output ``temperature_env``) drives the IMUs
that run in temperature mode 2, e.g. a heat/cool cycle that separates a temperature coefficient
from a linear drift.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

from components.simulation.temperature import TemperatureSource


@dataclass
class Variant:
    """An IMU instance: effects (vocabulary names, SI) and FMU parameters replace or extend the
    scenario's; ``seed`` defaults to the scenario's."""
    name: str
    effects: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)
    seed: int | None = None
    replace_effects: bool = False  # True: the scenario's [imu.effects] are dropped
    temperature_env: bool = False  # connect the temperature source to this instance


def heat_cool_cycle(mean: float = 25.0, amplitude: float = 5.0, period: float = 120.0) -> Callable:
    """T(t) = mean + amplitude sin(2π t / period): non-monotonic, so T − T0 and t differ."""
    return lambda t: mean + amplitude * math.sin(2 * math.pi * t / period)


def run_variants(sc, variants: list[Variant], temperature_profile: Callable | None = None,
                 progress: bool | None = False):
    """Run the scenario once with one IMU instance per variant.

    Returns ``{variant name: (MeasurementLog, truth dict)}``; each truth is the scenario's truth
    with that instance's effects, noise seed and parameters."""
    from components.errors import ScenarioError
    from components.logs.recording import log_from_recording
    from components.simulation.run import build_system, truth_of
    from orchestrator.master import Simulation
    from orchestrator.system import Connection, UnitSpec

    names = [v.name for v in variants]
    if len(set(names)) != len(names):
        raise ValueError("variant names must be distinct")
    system, ctrl, info = build_system(sc)
    imu_spec = next(u for u in system.units if u.name == "imu")
    imu_conns = [c for c in system.connections if c.target.startswith("imu.")]
    imu_rec = [r for r in system.record if r.startswith("imu.")]
    base_params = dict(imu_spec.parameters)
    units = [u for u in system.units if u.name != "imu"]
    conns = [c for c in system.connections if not c.target.startswith("imu.")]
    record = [r for r in system.record if not r.startswith("imu.")]
    order = [u for u in (system.order or []) if u != "imu"]
    if temperature_profile is not None:
        if sc.temperature_profile is not None:
            raise ScenarioError(f"{sc.source}: [temperature] profile is given, and run_variants a temperature "
                                "profile besides: give one")
        units.insert(0, UnitSpec("tempsrc", component=TemperatureSource("tempsrc", temperature_profile)))
        order.insert(0, "tempsrc")
    unit_names = {}
    for k, v in enumerate(variants):
        un = f"imu{k}"
        unit_names[v.name] = un
        params = {p: x for p, x in base_params.items()
                  if not (v.replace_effects and p in sc.imu_effects)}
        params.update(v.effects)
        params.update(v.parameters)
        params["seed"] = sc.seed if v.seed is None else v.seed
        units.append(UnitSpec(un, fmu=imu_spec.fmu, role=imu_spec.role, role_options=dict(imu_spec.role_options),
                              parameters=params, mapping=dict(imu_spec.mapping)))
        conns += [Connection(c.source, un + c.target[3:], c.derivative_order) for c in imu_conns]
        if v.temperature_env:
            if temperature_profile is None:
                raise ValueError(f"variant {v.name}: temperature_env needs a temperature_profile")
            conns.append(Connection("tempsrc.temperature_env", f"{un}.temperature_env"))
        record += [un + r[3:] for r in imu_rec]
        order.append(un)
    system.units, system.connections, system.record, system.order = units, conns, record, order

    ctrl.stop_when_done = True
    sim = Simulation(system, progress=progress)
    sim.load()
    rec = sim.run()
    if not ctrl.finished:
        raise ScenarioError(f"{sc.source}: the schedule did not finish by t = {system.stop:g} s")
    rec.provenance.setdefault("system", {})["stopped_at"] = sim.stopped_at
    meta = {
        "site": {"latitude_deg": sc.site["latitude_deg"], "height_m": sc.site["height_m"],
                 "gravity_mps2": sc.site["gravity_mps2"] or None},
        "table": {"axes": [{"name": a, "axis": info["geometry"][a]} for a in sc.table_axes]},
        "imu": {"gyro_output": sc.gyro_output, "acc_output": sc.acc_output,
                "gyro_count_rad": None, "acc_count_mps": None},
    }
    if "counts" in (sc.gyro_output, sc.acc_output):
        raise ValueError("run_variants: increment outputs only")
    out = {}
    for v in variants:
        un = unit_names[v.name]
        log = log_from_recording(rec, metadata=meta, table="table", imu=un, axes=sc.table_axes,
                                 segment_signal="ctrl.segment", segment_labels=ctrl.labels,
                                 description=f"{sc.name}: variant {v.name}")
        eff = {p: x for p, x in sc.imu_effects.items() if not v.replace_effects}
        eff.update({p: x for p, x in v.effects.items()})
        vinfo = dict(info, imu_parameters=next(u for u in units if u.name == un).parameters)
        sc_v = _ScenarioView(sc, eff, sc.seed if v.seed is None else v.seed)
        truth = truth_of(sc_v, ctrl, vinfo, rec)
        out[v.name] = (log, truth)
    return out


class _ScenarioView:
    """The scenario with one variant's IMU effects and seed (for the truth record)."""

    def __init__(self, sc, imu_effects: dict, seed: int):
        self._sc, self.imu_effects, self.seed = sc, imu_effects, seed

    def __getattr__(self, name):
        return getattr(self._sc, name)
