"""The native span plan: a run's FMI 2 units, in stepping order, resolved once into the C
structs that the span loop (``span.c``) walks.

Function addresses, value references, exchange slots and unit conversions are looked up here,
once per run, so that the steps in which no Python-stepped unit acts run entirely in C; a fault
inside the loop comes back as an error record, read here into a message naming the unit, the
call and the time.
"""
from __future__ import annotations

import ctypes

import numpy as np

from orchestrator import native
from orchestrator.fmu_units import FMU2Unit
from orchestrator.units import STATUS, Unit, log_suffix
from orchestrator.wiring import ScalarConnection


class SpanPlan:
    """The FMI 2 units *names* (in stepping order) of a loaded run, ready for the span loop.

    *slots* maps each exchanged ``(unit, variable)`` to its index in the exchange array, *convs*
    to its ``(factor, offset)`` to SI, *multiples* each unit's step multiple. A plan index range
    ``first:last`` in :meth:`run` is a run of consecutive units of *names*."""

    def __init__(self, units: dict[str, Unit], names: list[str], connections: list[ScalarConnection],
                 slots: dict, convs: dict, multiples: dict) -> None:
        self.units = units
        self.names = names
        self.plan, self._keep, self._meta = _build(units, names, connections, slots, convs, multiples)
        self._lib = native.library()
        self.err = native.SpanError()

    def attach(self, values: np.ndarray, rec: np.ndarray, rec_slots: np.ndarray, every: int,
               t0: float, h: float, jacobi: bool) -> None:
        """Point the loop at the exchange array *values* and the recording rows *rec* (slots
        *rec_slots*, every *every*-th step). The loop writes through raw pointers: the arrays
        must stay alive and in place while spans run."""
        self._args = dict(
            values=values.ctypes.data_as(native.c_double_p),
            rec=rec.ctypes.data_as(native.c_double_p) if len(rec_slots) else None,
            n_rec=len(rec_slots), rec_slots=rec_slots.ctypes.data_as(native.c_long_p),
            every=every, rec_rows=rec.shape[0], t0=t0, h=h, jacobi=1 if jacobi else 0)
        self._arrays = (values, rec, rec_slots)

    def run(self, first: int, last: int, step: int, count: int, record: bool) -> bool:
        """Step plan units ``first:last`` over *count* steps from *step*, recording the rows
        that fall in them if *record*. False when a unit failed: ``err`` says where (the rows
        of the steps completed before it are written), :meth:`fault_message` says what."""
        if first == last:
            return True
        a = self._args
        st = self._lib.calbench_run_span(self.plan if self.names else None, first, last, a["values"],
                                         a["t0"], a["h"], step, count, a["jacobi"],
                                         a["rec"] if record else None, a["n_rec"], a["rec_slots"],
                                         a["every"], 0, a["rec_rows"], ctypes.byref(self.err))
        return not st

    def fault_message(self) -> str:
        """What failed in the last :meth:`run` that returned False."""
        err, t0, h = self.err, self._args["t0"], self._args["h"]
        u = self.units[self.names[err.unit]]
        meta = self._meta[err.unit]
        t = t0 + err.step * h
        call = native.CALLS.get(err.call, f"call {err.call}")
        if err.call == 7:
            var = meta["rout"][err.index]
            value = self.plan[err.unit].rout_buf[err.index]
            # the output belongs to the end of the unit's step (as on the Python path)
            t_out = t0 + (err.step + self.plan[err.unit].multiple) * h
            head = f"unit {u.name}: output {var} = {value} at t = {t_out:.9g} s (step {err.step})"
        else:
            st = STATUS[err.status] if 0 <= err.status < len(STATUS) else err.status
            head = f"unit {u.name}: {call} returned {st} at t = {t:.9g} s (step {err.step})"
        return head + log_suffix(u)


def _build(units: dict[str, Unit], names: list[str], connections: list[ScalarConnection],
           slots: dict, convs: dict, multiples: dict):
    """(plan structs, the numpy buffers they point into, per unit the variable names of its
    real inputs and outputs for messages)."""
    plan = (native.UnitPlan * max(len(names), 1))()
    keep: list = []  # numpy buffers the C structs point into

    def arr(values, dtype):
        a = np.ascontiguousarray(np.asarray(values, dtype=dtype))
        if a.size == 0:
            a = np.zeros(1, dtype=dtype)
        keep.append(a)
        ctype = {np.uintc: native.c_uint_p, np.int_: native.c_long_p, np.float64: native.c_double_p,
                 np.intc: native.c_int_p}[dtype]
        return a.ctypes.data_as(ctype)

    meta = []
    for i, name in enumerate(names):
        u: FMU2Unit = units[name]  # type: ignore[assignment]
        ep = u.entry_points()
        p = plan[i]
        p.component = ep["component"]
        p.do_step, p.set_real, p.get_real = ep["DoStep"], ep["SetReal"], ep["GetReal"]
        p.set_int, p.get_int, p.set_der = ep["SetInteger"], ep["GetInteger"], ep["SetRealInputDerivatives"]
        p.multiple = multiples[name]
        rin, iin, der = [], [], []
        for c in connections:
            if c.target.unit != name:
                continue
            v = u.variables[c.target.var]
            if v.type not in ("Real", "Integer"):
                # fmi2SetReal on a Boolean is what this loop once did: such units step in Python
                raise ValueError(f"unit {name}: {v.name} is {v.type}; the native loop exchanges "
                                 "Real and Integer only")
            s = slots[(c.source.unit, c.source.var)]
            if c.derivative_order:
                der.append((v.vr, s, 1.0 / c.target.factor, c.derivative_order))
            elif v.type == "Integer":
                iin.append((v.vr, s))
            else:
                rin.append((v.vr, s, 1.0 / c.target.factor, -c.target.offset / c.target.factor, v.name))
        p.n_rin = len(rin)
        p.rin_vr = arr([r[0] for r in rin], np.uintc)
        p.rin_slot = arr([r[1] for r in rin], np.int_)
        p.rin_scale = arr([r[2] for r in rin], np.float64)
        p.rin_shift = arr([r[3] for r in rin], np.float64)
        p.rin_buf = arr(np.zeros(len(rin)), np.float64)
        p.n_iin = len(iin)
        p.iin_vr = arr([r[0] for r in iin], np.uintc)
        p.iin_slot = arr([r[1] for r in iin], np.int_)
        p.iin_buf = arr(np.zeros(len(iin)), np.intc)
        p.n_der = len(der)
        p.der_vr = arr([r[0] for r in der], np.uintc)
        p.der_slot = arr([r[1] for r in der], np.int_)
        p.der_scale = arr([r[2] for r in der], np.float64)
        p.der_order = arr([r[3] for r in der], np.intc)
        p.der_buf = arr(np.zeros(len(der)), np.float64)
        outs = [(var, idx) for (unit, var), idx in slots.items() if unit == name]
        rout = [(u.variables[v].vr, idx, v) for v, idx in outs if u.variables[v].type == "Real"]
        iout = [(u.variables[v].vr, idx, v) for v, idx in outs if u.variables[v].type == "Integer"]
        p.n_rout = len(rout)
        p.rout_vr = arr([r[0] for r in rout], np.uintc)
        p.rout_slot = arr([r[1] for r in rout], np.int_)
        p.rout_scale = arr([convs[(name, r[2])][0] for r in rout], np.float64)
        p.rout_shift = arr([convs[(name, r[2])][1] for r in rout], np.float64)
        p.rout_buf = arr(np.zeros(len(rout)), np.float64)
        p.n_iout = len(iout)
        p.iout_vr = arr([r[0] for r in iout], np.uintc)
        p.iout_slot = arr([r[1] for r in iout], np.int_)
        p.iout_buf = arr(np.zeros(len(iout)), np.intc)
        meta.append({"rin": [r[4] for r in rin], "rout": [r[2] for r in rout]})
    return plan, keep, meta
