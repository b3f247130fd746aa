"""The master algorithm: load units, check roles, wire, initialise, step on a fixed grid,
record, and report faults with what was recorded so far.

FMI 2.0 units that exchange Real and Integer values are stepped by the native span loop
(orchestrator/native/span.c): value references, slots and conversions are resolved once
(:class:`~orchestrator.native.plan.SpanPlan`); between two steps of a slower Python-stepped unit
the whole span runs in C. Python components, FMI 3.0 units and FMI 2.0 units with a Boolean or
String exchange step in Python, here, at their own multiple of the communication step (the
exchange, :mod:`orchestrator.exchange`, carries every FMI type). A unit that asks to end the
run ends it at the time it reached (``stopped_at``), a normal end.
"""
from __future__ import annotations

import sys
import time as _time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from orchestrator import native
from orchestrator.component_import import import_component
from orchestrator.component_unit import ComponentUnit
from orchestrator.errors import NativeSpanFault, RoleError, SimulationFault, SystemError_, UnitError
from orchestrator.exchange import Exchange
from orchestrator.fmu_resolver import resolve_fmu
from orchestrator.fmu_units import FMU2Unit, load_fmu_unit
from orchestrator.loop_solver import FixedPointIteration, bind_slots, check_iterable, loop_groups
from orchestrator.native.plan import SpanPlan
from orchestrator.record_select import record_endpoints
from orchestrator.recording import Recording
from orchestrator.roles import RoleCheck, check_unit, get_role
from orchestrator.run_provenance import run_provenance
from orchestrator.start_values import start_values
from orchestrator.system import System
from orchestrator.units import Unit
from orchestrator.wiring import (
    Endpoint,
    ScalarConnection,
    algebraic_loops,
    check_algebraic_loops,
    expand_connections,
    fmu_feedthrough,
    resolve,
    stepping_order,
)


@dataclass
class _PyPort:
    """A Python-stepped unit's inputs from slots (its outputs go through the exchange)."""

    unit: Unit
    multiple: int
    inputs: list[tuple[str, int, float, float]]   # (var, slot, scale, shift)
    derivatives: list[tuple[str, int, float, int]]  # (var, slot, scale, order): FMI 2 only


class _EndedEarly(Exception):
    """A unit asked to end the run without reaching the end of the step that starts at *step*."""

    def __init__(self, step: int) -> None:
        self.step = step


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
        self.notes: list[str] = []  # what the run did that a user should know (said once)
        self.loop_groups: list = []  # algebraic loops solved by iteration (algorithm "iterative")
        self._loop_of: dict = {}  # unit name -> its loop group

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
                    raise SystemError_(f"units.{spec.name}.role = {spec.role!r}{opts}: {e}") from None
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
        alg = self.system.algorithm
        broken_by = ('algorithm = "jacobi"' if alg == "jacobi" else alg if alg == "iterative"
                     else "the explicit system.order" if self.system.order else None)
        loops = algebraic_loops(self.connections, {n: fmu_feedthrough(u) for n, u in self.units.items()})
        self.notes += check_algebraic_loops(loops, broken_by)
        self.order = stepping_order(self.system, self.connections)
        if alg == "iterative":
            self.loop_groups = loop_groups(self.order, self.connections,
                                           [{node.split(".", 1)[0] for node in loop} for loop in loops])
            check_iterable(self.loop_groups, self.units, {s.name: s.step_multiple for s in self.system.units},
                           self.system.source or self.system.name)
            self._loop_of = {n: g for g in self.loop_groups for n in g.units}

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
        """Start values in the unit's own names, types and units (the role's settings first)."""
        where = f"units.{spec.name}.parameters"
        out = dict(self.role_settings.get(spec.name, {}))
        out.update(start_values(self.units[spec.name], lambda n: self._endpoint(spec.name, n, where),
                                spec.parameters, where))
        return out

    # ------------------------------------------------------------------ run
    def run(self, output: str | Path | None = None) -> Recording:
        """Run from start to stop; save the recording to *output* (Parquet) if given. On a fault,
        the partial recording is saved too and :class:`SimulationFault` is raised. A unit that
        asks to end the run ends it (``stopped_at``) as a normal end."""
        if not self.units:
            self.load()
        sysm = self.system
        n_steps, h_last = self._grid()
        ex = self.exchange = Exchange(self.units)
        for c in self.connections:
            ex.slot(c.source.unit, c.source.var, c.source.factor, c.source.offset)
        rec_names, rec_slots = [], []
        for unit, e in record_endpoints(self.units, self.bindings, sysm.record):
            v = self.units[unit].variables[e.var]
            src = None
            if v.causality == "input":
                src = next((c.source for c in self.connections
                            if c.target.unit == unit and c.target.var == e.var and c.derivative_order == 0), None)
            rec_slots.append(ex.slots[(src.unit, src.var)] if src is not None
                             else ex.slot(unit, e.var, e.factor, e.offset))
            src_unit, src_var = (src.unit, src.var) if src is not None else (unit, e.var)
            rec_names.append((f"{unit}.{e.name}", self.units[src_unit].variables[src_var]))
        values = ex.allocate()
        bind_slots(self.loop_groups, self.connections, ex, sysm.source or sysm.name)
        self._solver = FixedPointIteration(sysm.loop_tolerance, sysm.loop_max_iterations)

        every = sysm.record_every
        n_grid = n_steps - (1 if h_last else 0)
        times = sysm.start + np.arange(n_grid // every + 1) * (every * sysm.step)
        if h_last:
            times = np.append(times, sysm.stop)
        rec = Recording.allocate([n for n, _ in rec_names], times, self.provenance(),
                                 types=[v.tinfo for _, v in rec_names])
        self._rec_slots = rec_slots
        self._rec_index = np.asarray(rec_slots, dtype=np.int_)
        self._object_columns = [(j, s) for j, s in enumerate(rec_slots) if s in ex.objects]
        started = _time.time()
        try:
            self._initialise()
            self._record_row(rec, 0)
            rec.rows = 1
            self._loop(values, rec, rec_slots, n_grid)
            if h_last and self.stopped_at is None:
                self._last_step(rec, sysm.start + n_grid * sysm.step, h_last)
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
        rec.provenance["system"]["stopped_at"] = self.stopped_at
        self.notes += [FixedPointIteration.note(g) for g in self.loop_groups]
        rec.provenance["notes"] = list(self.notes)
        if output:
            rec.save(output)
        return rec

    def _grid(self) -> tuple[int, float]:
        """(steps, length of a shortened last step or 0), the shortening said once in the notes."""
        n, h_last = self.system.grid()
        note = (f"stop - start = {self.system.stop - self.system.start:.9g} s is not a whole number "
                f"of steps of {self.system.step:.9g} s: the last step is shortened to {h_last:.9g} s "
                f"to reach stop = {self.system.stop:.9g} s")
        if h_last and note not in self.notes:
            self.notes.append(note)
        return n, h_last

    def _initialise(self) -> None:
        for spec in self.system.units:
            u = self.units[spec.name]
            u.instantiate(self.system.start)
            u.set_values(self._parameters(spec))
            u.enter_initialization()
        # initial exchange in stepping order: each unit leaves initialisation with its inputs
        # taken from the units before it (which are already initialised)
        for name in self.order:
            u = self.units[name]
            self._set_inputs_from_slots(u)
            u.exit_initialization()
            self.exchange.store_outputs(u, self.system.start)

    def _set_inputs_from_slots(self, u: Unit) -> None:
        ex, vals = self.exchange, {}
        for c in self.connections:
            if c.target.unit == u.name and c.derivative_order == 0:
                s = ex.slots[(c.source.unit, c.source.var)]
                vals[c.target.var] = ex.as_input(u.variables[c.target.var], s, 1.0 / c.target.factor,
                                                 -c.target.offset / c.target.factor)
        if vals:
            u.set_values(vals)

    def _record_row(self, rec: Recording, row: int) -> None:
        if self._rec_slots:
            rec.data[row] = self.exchange.values[self._rec_index]
        if self._object_columns:
            self._record_objects(rec, row, row + 1)

    def _record_objects(self, rec: Recording, lo: int, hi: int) -> None:
        """Rows lo..hi of the signals held as objects (the native loop records only floats; the
        units that produce objects are stepped in Python, so these are constant over a span)."""
        for j, s in self._object_columns:
            rec.objects[j][lo:hi] = [self.exchange.objects[s]] * (hi - lo)

    def _last_step(self, rec: Recording, t: float, h: float) -> None:
        """The shortened last step, on the Python path (the native loop keeps one step length)."""
        ports = {n: self._py_port(n, 1) for n in self.order}

        def port_step(p, t, inputs, derivatives) -> bool:
            p.unit.set_values(inputs)
            if derivatives:
                p.unit.set_input_derivatives(derivatives)
            p.unit.do_step(t, h)
            return False

        if self.system.algorithm == "jacobi":
            # every unit's inputs as they were before any unit stepped
            snap = {n: (self._port_inputs(p), self._port_derivatives(p)) for n, p in ports.items()}
            for n, p in ports.items():
                port_step(p, t, *snap[n])
            for p in ports.values():
                self.exchange.store_outputs(p.unit, t + h)
        else:
            for n in self.order:
                group = self._loop_of.get(n)
                if group is None:
                    self._step_port(ports[n], t, h, port_step)
                elif n == group.units[0]:
                    self._solve_loop(group, [ports[m] for m in group.units], t, h, port_step)
        self._record_row(rec, len(rec.time) - 1)
        rec.rows = len(rec.time)

    # ------------------------------------------------------------------ stepping
    def _native_ok(self, name: str) -> bool:
        """An FMI 2 unit whose exchanged variables are all Real or Integer (Enumeration) runs in
        the native loop; one with Boolean or String ones steps on the Python path."""
        u = self.units[name]
        if not isinstance(u, FMU2Unit) or name in self._loop_of:
            return False
        used = set(self.exchange.outputs_of(u))
        used |= {c.target.var for c in self.connections if c.target.unit == name}
        return all(u.variables[v].type in ("Real", "Integer") for v in used)

    def _loop(self, values, rec: Recording, rec_slots: list[int], n_steps: int) -> None:
        sysm, ex = self.system, self.exchange
        h, t0, every = sysm.step, sysm.start, sysm.record_every
        jacobi = sysm.algorithm == "jacobi"
        multiples = {s.name: s.step_multiple for s in sysm.units}
        # native plan for FMI 2 units, in stepping order; Python-stepped units as ports
        fmi2 = [n for n in self.order if self._native_ok(n)]
        spans = SpanPlan(self.units, fmi2, self.connections, ex.slots, ex.conv, multiples)
        plan_index = {n: i for i, n in enumerate(fmi2)}
        ports = {n: self._py_port(n, multiples[n]) for n in self.order if n not in plan_index}
        loop_ports = {g.units[0]: [ports[n] for n in g.units] for g in self.loop_groups}
        segments = self._segments(plan_index)
        rec_arr = np.ascontiguousarray(rec.data)
        rec.data = rec_arr
        rslots = np.asarray(rec_slots, dtype=np.int_)
        spans.attach(values, rec_arr, rslots, every, t0, h, jacobi)
        progress = self._progress(n_steps)

        def span(first: int, last: int, step: int, count: int, record: bool) -> int | None:
            """Step plan units first:last; the step at whose end a unit asked to end the run,
            or None."""
            if spans.run(first, last, step, count, record):
                return None
            err = spans.err
            u = self.units[fmi2[err.unit]]
            t = t0 + err.step * h
            if not (err.call == native.CALL_DO_STEP and err.status == 2 and u.asked_to_end(t)):
                # the rows of the steps completed inside this span are in rec_arr already
                rec.rows = err.step // every + 1
                raise NativeSpanFault(spans.fault_message())
            s, end = err.step, t + multiples[u.name] * h
            if u.ended_at < end - 1e-9 * h:
                raise _EndedEarly(s)
            # the step is completed: the units after it in the range step too (Jacobi: before
            # the outputs of the units before it are read, so that they see the old values)
            if jacobi:
                span(err.unit + 1, last, s, 1, False)
                for n in fmi2[first:err.unit + 1]:
                    if s % multiples[n] == 0:
                        ex.store_outputs(self.units[n], end)
            else:
                ex.store_outputs(u, end)
                span(err.unit + 1, last, s, 1, False)
            return s

        def port_step(p: _PyPort, t: float, inputs: dict, derivatives: list) -> bool:
            """Step a Python-stepped unit; True if it asked to end the run after a whole step."""
            p.unit.set_values(inputs)
            if derivatives:
                p.unit.set_input_derivatives(derivatives)
            p.unit.do_step(t, p.multiple * h)
            if p.unit.ended_at is not None and p.unit.ended_at < t + p.multiple * h - 1e-9 * h:
                raise _EndedEarly(step)
            return p.unit.ended_at is not None

        step = 0
        slow = sorted(set(multiples[n] for n in ports)) if ports else []
        try:
            while step < n_steps:
                acting = [n for n in ports if step % ports[n].multiple == 0]
                ending = None
                if not acting:
                    nxt = min([((step // m) + 1) * m for m in slow] + [n_steps])
                    ending = span(0, len(fmi2), step, nxt - step, True)
                    last = nxt if ending is None else ending + 1
                    self._record_objects(rec, step // every + 1, last // every + 1)
                    if progress:
                        progress.update(last - step)
                    step = last
                    rec.rows = step // every + 1
                    if ending is None:
                        continue
                    self._end_at(rec, step)
                    break
                t = t0 + step * h
                if jacobi:
                    snapshot = {n: (self._port_inputs(ports[n]), self._port_derivatives(ports[n]))
                                for n in acting}
                    ending = span(0, len(fmi2), step, 1, False)
                    for n in acting:
                        if port_step(ports[n], t, *snapshot[n]):
                            ending = step
                    for n in acting:
                        ex.store_outputs(ports[n].unit, t + ports[n].multiple * h)
                    if ending is None and any(ports[n].unit.stop_requested() for n in acting):
                        self.stopped_at = t + h
                        step += 1
                        rec.rows = step // every + 1
                        break
                else:
                    stop = False
                    for seg in segments:
                        if isinstance(seg, tuple):
                            if span(seg[0], seg[1], step, 1, False) is not None:
                                ending = step
                        elif seg in acting:
                            group = self._loop_of.get(seg)
                            if group is None:
                                p = ports[seg]
                                if self._step_port(p, t, h, port_step):
                                    ending = step
                                if p.unit.stop_requested():
                                    stop = True
                                    break
                            elif seg == group.units[0]:  # the loop's other units step with it
                                if self._solve_loop(group, loop_ports[seg], t, h, port_step):
                                    ending = step
                                if any(p.unit.stop_requested() for p in loop_ports[seg]):
                                    stop = True
                                    break
                    if stop:
                        # the unit ends the run at t: units after it in the order do not step
                        self.stopped_at = t
                        break
                step += 1
                if ending is not None:
                    self._end_at(rec, step)
                    break
                if step % every == 0:
                    self._record_row(rec, step // every)
                rec.rows = step // every + 1
                if progress:
                    progress.update(1)
        except _EndedEarly as e:
            # a unit asked to end the run but did not reach the end of its step: the run ends
            # at the step's start, the last row recorded
            self.stopped_at = t0 + e.step * h
            rec.rows = e.step // every + 1
        if progress:
            progress.close()

    def _step_port(self, p, t: float, h: float, port_step) -> bool:
        """One Python-stepped port: its inputs in, a step, its outputs to the exchange; True if
        its unit asked to end the run."""
        ended = port_step(p, t, self._port_inputs(p), self._port_derivatives(p))
        self.exchange.store_outputs(p.unit, t + p.multiple * h)
        return ended

    def _solve_loop(self, group, ports: list, t: float, h: float, port_step) -> bool:
        """Step a loop *group*'s ports in order until its values converge; True if a unit asked
        to end the run."""
        return self._solver.step(group, ports, self.exchange.values, t,
                                 lambda p: self._step_port(p, t, h, port_step))

    def _end_at(self, rec: Recording, step: int) -> None:
        """A unit ended the run at the end of base step *step* - 1: the run stops there and its
        last sample is recorded, as one more row when it falls between rows of the record grid."""
        every, t = self.system.record_every, self.system.start + step * self.system.step
        self.stopped_at = t
        row = -(-step // every)  # the first grid row at or after the end
        if row >= len(rec.time):
            rec.time = np.append(rec.time, t)
            rec.data = np.vstack([rec.data, np.full((1, rec.data.shape[1]), np.nan)])
            for col in rec.objects.values():
                col.append(None)
        rec.time[row] = t
        self._record_row(rec, row)
        rec.rows = row + 1

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

    def _py_port(self, name: str, multiple: int) -> _PyPort:
        slots = self.exchange.slots
        ins = [(c.target.var, slots[(c.source.unit, c.source.var)], 1.0 / c.target.factor,
                -c.target.offset / c.target.factor)
               for c in self.connections if c.target.unit == name and c.derivative_order == 0]
        ders = [(c.target.var, slots[(c.source.unit, c.source.var)], 1.0 / c.target.factor,
                 c.derivative_order)
                for c in self.connections if c.target.unit == name and c.derivative_order]
        return _PyPort(self.units[name], multiple, ins, ders)

    def _port_derivatives(self, p: _PyPort) -> list:
        """Input derivatives (only FMI 2 units take them), scaled as the native loop does."""
        values = self.exchange.values
        return [(var, order, scale * values[s]) for var, s, scale, order in p.derivatives]

    def _port_inputs(self, p: _PyPort) -> dict:
        return {var: self.exchange.as_input(p.unit.variables[var], s, scale, shift)
                for var, s, scale, shift in p.inputs}

    # ------------------------------------------------------------------ provenance
    def provenance(self) -> dict:
        return run_provenance(self)


def simulate(system: System, output: str | Path | None = None, progress: bool | None = None) -> Recording:
    """Load, check, run: the one-call API."""
    sim = Simulation(system, progress=progress)
    sim.load()
    return sim.run(output)
