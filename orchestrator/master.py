"""The master algorithm: load units, check roles, wire, initialise, step on a fixed grid,
record, and report faults with what was recorded so far.

FMI 2.0 units are stepped by the native span loop (orchestrator/native/span.c): value
references, slots and conversions are resolved once (:class:`~orchestrator.native.plan.SpanPlan`);
between two steps of a slower Python or FMI 3.0 unit the whole span runs in C. Python components
and FMI 3.0 units step in Python, here, at their own multiple of the communication step.
"""
from __future__ import annotations

import math
import platform
import sys
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from orchestrator.component_import import import_component
from orchestrator.component_unit import ComponentUnit
from orchestrator.errors import NativeSpanFault, RoleError, SimulationFault, SystemError_, UnitError
from orchestrator.fmu_resolver import resolve_fmu
from orchestrator.fmu_units import FMU2Unit, load_fmu_unit
from orchestrator.native.plan import SpanPlan
from orchestrator.recording import Recording
from orchestrator.roles import RoleCheck, check_unit, get_role
from orchestrator.system import System
from orchestrator.units import Unit, log_suffix, sha256_file
from orchestrator.wiring import (
    Endpoint,
    ScalarConnection,
    check_algebraic_loops,
    expand_connections,
    fmu_feedthrough,
    resolve,
    stepping_order,
)


@dataclass
class _PyPort:
    """A Python-stepped unit's exchange: inputs from slots, outputs to slots."""

    unit: Unit
    multiple: int
    inputs: list[tuple[str, int, float, float]]   # (var, slot, scale, shift)
    outputs: list[tuple[str, int, float, float]]  # (var, slot, factor, offset)


class Simulation:
    """One run of a :class:`System`. ``components`` may supply ready Python component instances
    by unit name (for units whose ``component`` is given in the file as a class path)."""

    def __init__(self, system: System, progress: bool | None = None) -> None:
        system.validate()
        self.system = system
        self.progress = progress
        self.units: dict[str, Unit] = {}
        self.bindings: dict[str, dict] = {}
        self.role_checks: list[RoleCheck] = []
        self.role_settings: dict[str, dict] = {}
        self.order: list[str] = []
        self.connections: list[ScalarConnection] = []
        self.stopped_at: float | None = None  # set when a unit ended the run before stop

    # ------------------------------------------------------------------ setup
    def load(self) -> None:
        for spec in self.system.units:
            if spec.fmu is not None:
                self.units[spec.name] = load_fmu_unit(spec.name, resolve_fmu(spec.fmu, self.system.base_dir))
            else:
                self.units[spec.name] = ComponentUnit(
                    spec.name, import_component(spec.component, spec.name, spec.config, self.system.base_dir))
        checks = []
        for spec in self.system.units:
            if spec.role:
                try:
                    role = get_role(spec.role, **spec.role_options)
                except (KeyError, TypeError, ValueError) as e:
                    opts = f" with role_options {spec.role_options}" if spec.role_options else ""
                    raise SystemError_(f"units.{spec.name}.role = {spec.role!r}{opts}: "
                                       f"{str(e).strip(chr(39))}") from None
                chk = check_unit(self.units[spec.name], role, spec.mapping)
                checks.append(chk)
                self.bindings[spec.name] = chk.bindings
                self.role_settings[spec.name] = self._role_settings(spec, role)
            elif spec.mapping:
                raise SystemError_(f"units.{spec.name}: a mapping needs a role")
        self.role_checks = checks
        if any(not c.ok for c in checks):
            raise RoleError(checks)
        self.connections = expand_connections(self.system, self.units, self.bindings)
        check_algebraic_loops(self.units, self.connections,
                              {n: fmu_feedthrough(u) for n, u in self.units.items()})
        self.order = stepping_order(self.system, self.connections)

    def _endpoint(self, unit: str, name: str, where: str) -> list[Endpoint]:
        return resolve(self.units[unit], self.bindings.get(unit, {}), name, where)

    def _role_settings(self, spec, role) -> dict:
        """The role's settings this unit has a parameter for, in its own names; a value the
        system file gives otherwise contradicts the role's options and is refused."""
        unit, out = self.units[spec.name], {}
        for name, value in role.settings.items():
            own = spec.mapping.get(name, name)
            v = unit.variables.get(own)
            if v is None or v.causality != "parameter":
                continue
            given = spec.parameters.get(name, spec.parameters.get(own))
            if given is not None and given != value:
                raise SystemError_(
                    f"units.{spec.name}.parameters: {name} = {given!r} contradicts the role's "
                    f"options {spec.role_options or '(defaults)'}, which need {name} = {value!r}; "
                    "set role_options instead")
            out[own] = value
        return out

    def _parameters(self, spec) -> dict:
        """Parameter values in the unit's own names and units (the role's settings first)."""
        out = dict(self.role_settings.get(spec.name, {}))
        for name, value in spec.parameters.items():
            (e,) = self._endpoint(spec.name, name, f"units.{spec.name}.parameters")
            v = self.units[spec.name].variables[e.var]
            if v.causality not in ("parameter", "input"):
                raise SystemError_(f"units.{spec.name}.parameters: {name} is a {v.causality}, not a parameter")
            if v.type == "Real" and isinstance(value, (int, float)) and not isinstance(value, bool):
                value = (float(value) - e.offset) / e.factor
            out[e.var] = value
        return out

    # ------------------------------------------------------------------ run
    def run(self, output: str | Path | None = None) -> Recording:
        """Run from start to stop; save the recording to *output* (Parquet) if given. On a fault,
        the partial recording is saved too and :class:`SimulationFault` is raised."""
        if not self.units:
            self.load()
        sysm = self.system
        h = sysm.step
        n_steps = int(round((sysm.stop - sysm.start) / h))
        if abs(n_steps * h - (sysm.stop - sysm.start)) > 1e-9 * max(1.0, abs(sysm.stop)):
            raise SystemError_(f"{sysm.source or 'system'}: stop - start = {sysm.stop - sysm.start} "
                               f"is not a whole number of steps of {h}")
        # slots: one per distinct source output, then recorded signals that are not sources
        slots: dict[tuple[str, str], int] = {}
        conv: dict[tuple[str, str], tuple[float, float]] = {}

        def slot(unit: str, var: str, factor: float, offset: float) -> int:
            key = (unit, var)
            if key not in slots:
                slots[key] = len(slots)
                conv[key] = (factor, offset)
            return slots[key]

        for c in self.connections:
            slot(c.source.unit, c.source.var, c.source.factor, c.source.offset)
        rec_names, rec_slots = [], []
        for pattern in sysm.record:
            unit, _, name = pattern.partition(".")
            if unit not in self.units:
                raise SystemError_(f"record.signals: {pattern!r}: no unit {unit!r}")
            for e in self._endpoint(unit, name, "record.signals"):
                v = self.units[unit].variables[e.var]
                if v.causality == "input":
                    src = next((c.source for c in self.connections
                                if c.target.unit == unit and c.target.var == e.var and c.derivative_order == 0), None)
                    if src is not None:
                        rec_slots.append(slots[(src.unit, src.var)])
                        rec_names.append(f"{unit}.{e.name}")
                        continue
                rec_slots.append(slot(unit, e.var, e.factor, e.offset))
                rec_names.append(f"{unit}.{e.name}")
        values = np.zeros(max(len(slots), 1))
        self._slots = slots

        every = sysm.record_every
        n_rows = n_steps // every + 1
        times = sysm.start + np.arange(n_rows) * (every * h)
        rec = Recording.allocate(rec_names, times, self.provenance())
        started = _time.time()
        try:
            self._initialise(values, slots, conv)
            rec.data[0] = values[rec_slots] if rec_slots else rec.data[0]
            rec.rows = 1
            self._loop(values, slots, conv, rec, rec_slots, n_steps)
        except (UnitError, NativeSpanFault) as e:
            rec.complete, rec.fault = False, str(e)
            rec.provenance["wall_time_s"] = _time.time() - started
            saved = rec.save(output) if output else None
            raise SimulationFault(str(e), rec, saved) from None
        finally:
            for u in self.units.values():
                u.terminate()
                u.free()
        rec.provenance["wall_time_s"] = _time.time() - started
        if output:
            rec.save(output)
        return rec

    def _initialise(self, values: np.ndarray, slots: dict, conv: dict) -> None:
        for spec in self.system.units:
            u = self.units[spec.name]
            u.instantiate(self.system.start)
            u.set_values(self._parameters(spec))
        # initial exchange in stepping order: each unit leaves initialisation with its inputs
        # taken from the units before it (which are already initialised)
        for name in self.order:
            u = self.units[name]
            self._set_inputs_from_slots(u, values)
            u.exit_initialization()
            self._outputs_to_slots(u, values, slots, conv, time=self.system.start)

    def _set_inputs_from_slots(self, u: Unit, values: np.ndarray) -> None:
        vals = {}
        for c in self.connections:
            if c.target.unit == u.name and c.derivative_order == 0:
                key = (c.source.unit, c.source.var)
                si = values[self._slots[key]] if key in self._slots else None
                if si is None:
                    continue
                v = u.variables[c.target.var]
                x = (si - c.target.offset) / c.target.factor
                vals[c.target.var] = int(round(x)) if v.type == "Integer" else x
        if vals:
            u.set_values(vals)

    def _outputs_to_slots(self, u: Unit, values: np.ndarray, slots: dict, conv: dict, time: float) -> None:
        names = [var for (unit, var) in slots if unit == u.name]
        if not names:
            return
        got = u.get_values(names)
        for var, x in zip(names, got):
            x = float(x)
            if not math.isfinite(x):
                raise UnitError(f"unit {u.name}: output {var} = {x} at t = {time:.9g} s"
                                + log_suffix(u))
            f, o = conv[(u.name, var)]
            values[slots[(u.name, var)]] = f * x + o

    # ------------------------------------------------------------------ stepping
    def _loop(self, values, slots, conv, rec: Recording, rec_slots: list[int], n_steps: int) -> None:
        sysm = self.system
        h, t0, every = sysm.step, sysm.start, sysm.record_every
        jacobi = sysm.algorithm == "jacobi"
        multiples = {s.name: s.step_multiple for s in sysm.units}
        # native plan for FMI 2 units, in stepping order; Python-stepped units as ports
        fmi2 = [n for n in self.order if isinstance(self.units[n], FMU2Unit)]
        spans = SpanPlan(self.units, fmi2, self.connections, slots, conv, multiples)
        plan_index = {n: i for i, n in enumerate(fmi2)}
        ports = {n: self._py_port(n, slots, conv, multiples[n]) for n in self.order if n not in plan_index}
        segments = self._segments(plan_index)
        rec_arr = np.ascontiguousarray(rec.data)
        rec.data = rec_arr
        rslots = np.asarray(rec_slots, dtype=np.int_)
        spans.attach(values, rec_arr, rslots, every, t0, h, jacobi)
        progress = self._progress(n_steps)

        def span(first: int, last: int, step: int, count: int, record: bool) -> None:
            if not spans.run(first, last, step, count, record):
                # the rows of the steps completed inside this span are in rec_arr already
                rec.rows = spans.err.step // every + 1
                raise NativeSpanFault(spans.fault_message())

        step = 0
        slow = sorted(set(multiples[n] for n in ports)) if ports else []
        while step < n_steps:
            acting = [n for n in ports if step % ports[n].multiple == 0]
            if not acting:
                nxt = min([((step // m) + 1) * m for m in slow] + [n_steps])
                span(0, len(fmi2), step, nxt - step, True)
                rec.rows = nxt // every + 1
                if progress:
                    progress.update(nxt - step)
                step = nxt
                continue
            t = t0 + step * h
            if jacobi:
                snapshot = {n: self._port_inputs(ports[n], values) for n in acting}
                span(0, len(fmi2), step, 1, False)
                outs = []
                for n in acting:
                    p = ports[n]
                    p.unit.set_values(snapshot[n])
                    p.unit.do_step(t, p.multiple * h)
                    outs.append(p)
                for p in outs:
                    self._port_outputs(p, values, t + p.multiple * h)
                if any(ports[n].unit.stop_requested() for n in acting):
                    self.stopped_at = t + h
                    step += 1
                    rec.rows = step // every + 1
                    break
            else:
                stop = False
                for seg in segments:
                    if isinstance(seg, tuple):
                        span(seg[0], seg[1], step, 1, False)
                    elif seg in acting:
                        p = ports[seg]
                        p.unit.set_values(self._port_inputs(p, values))
                        p.unit.do_step(t, p.multiple * h)
                        self._port_outputs(p, values, t + p.multiple * h)
                        if p.unit.stop_requested():
                            stop = True
                            break
                if stop:
                    # the unit ends the run at t: units after it in the order do not step
                    self.stopped_at = t
                    break
            step += 1
            if step % every == 0 and len(rslots):
                rec_arr[step // every] = values[rslots]
            rec.rows = step // every + 1
            if progress:
                progress.update(1)
        if progress:
            progress.close()

    def _segments(self, plan_index: dict[str, int]) -> list:
        """The stepping order as runs of FMI 2 units (plan index ranges) and Python-stepped units."""
        segs: list = []
        for n in self.order:
            if n in plan_index:
                i = plan_index[n]
                if segs and isinstance(segs[-1], tuple) and segs[-1][1] == i:
                    segs[-1] = (segs[-1][0], i + 1)
                else:
                    segs.append((i, i + 1))
            else:
                segs.append(n)
        return segs

    def _progress(self, n_steps: int):
        show = self.progress if self.progress is not None else sys.stderr.isatty()
        if not show:
            return None
        from tqdm import tqdm

        # shown only once a run has taken a few seconds
        return tqdm(total=n_steps, unit="step", delay=3.0, mininterval=0.5, leave=False,
                    desc=self.system.name)

    def _py_port(self, name: str, slots: dict, conv: dict, multiple: int) -> _PyPort:
        u = self.units[name]
        ins = []
        for c in self.connections:
            if c.target.unit == name and c.derivative_order == 0:
                s = slots[(c.source.unit, c.source.var)]
                ins.append((c.target.var, s, 1.0 / c.target.factor, -c.target.offset / c.target.factor))
        outs = [(var, idx, *conv[(unit, var)]) for (unit, var), idx in slots.items() if unit == name]
        return _PyPort(u, multiple, ins, outs)

    @staticmethod
    def _port_inputs(p: _PyPort, values: np.ndarray) -> dict:
        out = {}
        for var, s, scale, shift in p.inputs:
            x = scale * values[s] + shift
            out[var] = int(round(x)) if p.unit.variables[var].type == "Integer" else float(x)
        return out

    def _port_outputs(self, p: _PyPort, values: np.ndarray, time: float) -> None:
        if not p.outputs:
            return
        got = p.unit.get_values([o[0] for o in p.outputs])
        for (var, s, f, o), x in zip(p.outputs, got):
            x = float(x)
            if not math.isfinite(x):
                raise UnitError(f"unit {p.unit.name}: output {var} = {x} at t = {time:.9g} s"
                                + log_suffix(p.unit))
            values[s] = f * x + o

    # ------------------------------------------------------------------ provenance
    def provenance(self) -> dict:
        import fmpy

        sysm = self.system
        prov = {
            "system": {"name": sysm.name, "source": sysm.source, "step": sysm.step,
                       "start": sysm.start, "stop": sysm.stop, "algorithm": sysm.algorithm,
                       "order": self.order, "record_every": sysm.record_every},
            "units": {n: {**u.provenance(),
                          # what was set: the role's settings (ours: its output kind) and the file's
                          "parameters": {**self.role_settings.get(n, {}), **self.system.unit(n).parameters},
                          "role_options": self.system.unit(n).role_options,
                          "step_multiple": self.system.unit(n).step_multiple}
                      for n, u in self.units.items()},
            "versions": {"python": platform.python_version(), "numpy": np.__version__,
                         "fmpy": fmpy.__version__, "calbench": _calbench_version()},
            "host": platform.node(),
        }
        if sysm.source and Path(sysm.source).exists():
            prov["system"]["sha256"] = sha256_file(sysm.source)
        return prov


def _calbench_version() -> str:
    try:
        from importlib.metadata import version

        return version("calbench")
    except Exception:
        return "unknown"


def simulate(system: System, output: str | Path | None = None, progress: bool | None = None) -> Recording:
    """Load, check, run: the one-call API."""
    sim = Simulation(system, progress=progress)
    sim.load()
    return sim.run(output)
