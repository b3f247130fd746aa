"""Replaying a measurement log through FMUs, for model-against-measurement with a system's own
plant models:

- the IMU: the log's motion (reconstructed from the gimbal angles, components.model.motion) drives an
  IMU FMU — ours or a supplier's, through its role binding — and its output is the prediction
  compared with the log's IMU output;
- the servo: the log's commanded angles drive a turntable FMU in position mode and its encoder
  output is compared with the logged gimbal angles.

Both run on the orchestrator with a small Python source unit, at the log's sample step.
"""
from __future__ import annotations

from dataclasses import replace as dc_replace
from pathlib import Path

import numpy as np

from orchestrator.component import Component, Var
from orchestrator.loader import load_system
from orchestrator.system import Connection, System, UnitSpec

XYZ = "xyz"


class SampleReplay(Component):
    """Outputs, over each interval (t_k - h, t_k], given per-sample values (N, ...): the value
    of sample k, set at the step that starts at t_k - h (so a unit after it in Gauss–Seidel
    order sees the end-of-interval value)."""

    def __init__(self, name: str, signals: dict, initial: dict, t0: float, h: float,
                 types: dict | None = None) -> None:
        types = types or {}
        self.variables = [Var(n, "output", types.get(n, "Real"), float(initial.get(n, 0.0)))
                          for n in signals]
        super().__init__(name)
        self._signals = {n: np.asarray(v) for n, v in signals.items()}
        self._initial = initial
        self._t0, self._h = t0, h
        self._n = len(next(iter(self._signals.values())))

    def initialize(self, t0: float) -> None:
        for n, v in self._initial.items():
            self[n] = v

    def do_step(self, t: float, h: float) -> None:
        k = min(int(round((t + h - self._t0) / self._h)) - 1, self._n - 1)
        for n, v in self._signals.items():
            x = v[k]
            self[n] = int(x) if self._decl[n].type == "Integer" else float(x)


def _unit_of_role(system: System, role: str) -> UnitSpec:
    units = [u for u in system.units if u.role == role]
    if len(units) != 1:
        raise ValueError(f"{system.source}: expected exactly one unit with role {role!r}, found "
                         f"{[u.name for u in units] or 'none'}")
    return units[0]


def replay_imu(data, system_file: str | Path, motion=None) -> np.ndarray:
    """Predicted increments (N, 6) [rad, m/s] of the system's IMU unit on the log's motion."""
    from orchestrator.fmu_resolver import resolve_fmu
    from orchestrator.fmu_units import load_fmu_unit
    from orchestrator.master import Simulation

    system = load_system(system_file)
    spec = _unit_of_role(system, "imu")
    motion = motion if motion is not None else data.motion(data.geometry)
    h = float(np.median(motion.dt))
    t0 = float(data.time[0] - motion.dt[0])
    names = set(load_fmu_unit("probe", resolve_fmu(spec.fmu, system.base_dir)).variables)

    def offered(role_name: str) -> bool:
        return spec.mapping.get(role_name, role_name) in names

    signals, initial = {}, {}
    for c, k in zip(XYZ, range(3)):
        signals[f"omega.{c}"], initial[f"omega.{c}"] = motion.omega_end[:, k], motion.omega_start[0, k]
        signals[f"f.{c}"], initial[f"f.{c}"] = motion.f_end[:, k], motion.f_start[0, k]
    conns = [Connection("src.omega", "imu.omega"), Connection("src.f", "imu.f")]
    params = dict(spec.parameters)
    if offered("alpha.x"):
        for c, k in zip(XYZ, range(3)):
            signals[f"alpha.{c}"], initial[f"alpha.{c}"] = motion.alpha_end[:, k], 0.0
        conns.append(Connection("src.alpha", "imu.alpha"))
    if offered("omega_int.x") and offered("f_int.x") and "input_integrals" in names:
        for c, k in zip(XYZ, range(3)):
            signals[f"omega_int.{c}"], initial[f"omega_int.{c}"] = motion.ideal_gyro[:, k], 0.0
            signals[f"f_int.{c}"], initial[f"f_int.{c}"] = motion.ideal_acc[:, k], 0.0
        conns += [Connection("src.omega_int", "imu.omega_int"), Connection("src.f_int", "imu.f_int")]
        params.setdefault("input_integrals", 1)
    src = SampleReplay("src", signals, initial, t0, h)
    rep = System(name="imu-replay", step=h, start=t0, stop=t0 + h * len(data.time),
                 units=[UnitSpec("src", component=src),
                        dc_replace(spec, name="imu", parameters=params)],
                 connections=conns, record=["imu.gyro", "imu.acc"], order=["src", "imu"],
                 source=f"replay of {system_file}", base_dir=system.base_dir)
    sim = Simulation(rep, progress=False)
    sim.load()
    rec = sim.run()
    out = np.column_stack([rec[f"imu.{s}.{c}"][1:] for s in ("gyro", "acc") for c in XYZ])
    kinds = spec.role_options
    if kinds.get("gyro_output", "increment") == "rate":
        out[:, :3] *= motion.dt[:, None]
    if kinds.get("acc_output", "increment") in ("rate", "specific_force"):
        out[:, 3:] *= motion.dt[:, None]
    return out


def replay_servo(log, system_file: str | Path | None = None, parameters: dict | None = None) -> dict:
    """The turntable FMU driven by the log's commanded angles: per axis the RMS and largest
    difference between simulated and logged encoder angles, at rest and while moving."""
    from orchestrator.master import Simulation

    missing = [a for a in log.axis_names if a not in log.command]
    if missing:
        raise ValueError(f"{log.source}: no command_<axis> column for {missing}: the servo comparison "
                         "needs the commanded angles")
    if system_file is not None:
        system = load_system(system_file)
        spec = _unit_of_role(system, "turntable")
        base = system.base_dir
    else:
        spec, base = UnitSpec("table", fmu="builtin:turntable", role="turntable"), Path.cwd()
    h = log.dt
    t0 = float(log.time[0] - h)
    params = dict(spec.parameters)
    params.update(parameters or {})
    if system_file is None:
        params.setdefault("n_axes", len(log.axis_names))
        for a, v in zip(log.axis_names, log.axis_vectors):
            for c, x in zip(XYZ, v):
                params.setdefault(f"{a}.axis.{c}", float(x))
    for a in log.axis_names:
        params.setdefault(f"{a}.angle0", float(log.gimbal[a][0]))
    signals = {f"{a}.angle_cmd": log.command[a] for a in log.axis_names}
    initial = {f"{a}.angle_cmd": float(log.command[a][0]) for a in log.axis_names}
    types = {}
    conns = [Connection(f"src.{a}.angle_cmd", f"table.{a}.angle_cmd") for a in log.axis_names]
    for a in log.axis_names:
        # a log that also holds the mode and rate commands (extra columns, as calbench writes
        # them) replays rate-mode segments too; otherwise every sample is position mode
        if f"servo_mode_{a}" in log.extra and f"servo_rate_{a}" in log.extra:
            signals[f"{a}.mode"] = log.extra[f"servo_mode_{a}"].astype(int)
            signals[f"{a}.rate_cmd"] = log.extra[f"servo_rate_{a}"]
            initial[f"{a}.mode"], initial[f"{a}.rate_cmd"] = int(signals[f"{a}.mode"][0]), 0.0
            types[f"{a}.mode"] = "Integer"
            conns += [Connection(f"src.{a}.mode", f"table.{a}.mode"),
                      Connection(f"src.{a}.rate_cmd", f"table.{a}.rate_cmd")]
    src = SampleReplay("src", signals, initial, t0, h, types)
    rep = System(name="servo-replay", step=h, start=t0, stop=t0 + h * log.n,
                 units=[UnitSpec("src", component=src), dc_replace(spec, name="table", parameters=params,
                                                                  role_options={"axes": list(log.axis_names)})],
                 connections=conns, record=[f"table.{a}.angle" for a in log.axis_names],
                 order=["src", "table"], source="servo replay", base_dir=base)
    sim = Simulation(rep, progress=False)
    sim.load()
    rec = sim.run()
    out = {}
    for a in log.axis_names:
        sim_angle = rec[f"table.{a}.angle"][1:]
        meas = log.gimbal[a]
        d = meas - sim_angle
        cmd = log.command[a]
        moving = np.abs(np.diff(np.concatenate([[meas[0]], meas]))) > 0
        out[a] = {"rms": float(np.sqrt(np.mean(d**2))), "max": float(np.max(np.abs(d))),
                  "rms_moving": float(np.sqrt(np.mean(d[moving] ** 2))) if moving.any() else 0.0,
                  "rms_rest": float(np.sqrt(np.mean(d[~moving] ** 2))) if (~moving).any() else 0.0,
                  "tracking_rms": float(np.sqrt(np.mean((meas - cmd) ** 2))),
                  "simulated": sim_angle, "difference": d}
    return out
