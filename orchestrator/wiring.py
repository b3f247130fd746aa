"""From a system description and loaded units to scalar connections and a stepping order.

Names on connections are resolved through each unit's role bindings (role name -> the unit's
own name and unit conversion); a vector prefix (``plate.omega``) expands to its components.
Every distinct source output gets one slot of the exchange array; values in slots are SI.
"""
from __future__ import annotations

import difflib
import math
from dataclasses import dataclass

from orchestrator.errors import AlgebraicLoopError, SystemError_
from orchestrator.fmi_types import connectable
from orchestrator.roles import Binding
from orchestrator.system import System
from orchestrator.units import Unit

VECTOR_SUFFIXES = (("x", "y", "z"), ("w", "x", "y", "z"))


@dataclass(frozen=True)
class Endpoint:
    unit: str
    name: str        # name as written (role name where the unit has a role)
    var: str         # the unit's own variable name
    factor: float    # SI = factor * unit value + offset
    offset: float


@dataclass(frozen=True)
class ScalarConnection:
    source: Endpoint
    target: Endpoint
    derivative_order: int = 0


def _lookup(unit: Unit, bindings: dict[str, Binding], name: str) -> Endpoint | None:
    b = bindings.get(name)
    if b is not None:
        return Endpoint(unit.name, name, b.unit_name, b.factor, b.offset)
    if name in unit.variables:
        return Endpoint(unit.name, name, name, 1.0, 0.0)
    return None


def resolve(unit: Unit, bindings: dict[str, Binding], name: str, where: str) -> list[Endpoint]:
    """Scalar endpoints for *name* on *unit* (a vector prefix gives several)."""
    e = _lookup(unit, bindings, name)
    if e is not None:
        v = unit.variables.get(e.var)
        if v is not None and v.shape:
            # an FMI 3 array: its elements, flat in row-major order
            return [Endpoint(unit.name, f"{e.name}[{k}]", f"{e.var}[{k}]", e.factor, e.offset)
                    for k in range(math.prod(v.shape))]
        return [e]
    for suffixes in VECTOR_SUFFIXES:
        parts = [_lookup(unit, bindings, f"{name}.{s}") for s in suffixes]
        if all(parts):
            return parts
    candidates = list(dict.fromkeys(list(bindings) + list(unit.variables)))
    close = difflib.get_close_matches(name, candidates, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    raise SystemError_(f"{where}: unit {unit.name} has no variable {name!r}{hint}")


def expand_connections(system: System, units: dict[str, Unit],
                       bindings: dict[str, dict[str, Binding]]) -> list[ScalarConnection]:
    out: list[ScalarConnection] = []
    seen_targets: dict[tuple, str] = {}
    for i, c in enumerate(system.connections):
        where = f"{system.source or 'system'}: connections[{i}] ({c.source} -> {c.target})"
        su, sn = c.source.split(".", 1)
        tu, tn = c.target.split(".", 1)
        src = resolve(units[su], bindings.get(su, {}), sn, where)
        dst = resolve(units[tu], bindings.get(tu, {}), tn, where)
        if len(src) != len(dst):
            raise SystemError_(f"{where}: {len(src)} source value(s) but {len(dst)} target value(s)")
        for s, d in zip(src, dst):
            sv, dv = units[su].variables[s.var], units[tu].variables[d.var]
            if sv.causality != "output":
                raise SystemError_(f"{where}: {su}.{s.var} is a {sv.causality}, not an output")
            if dv.causality != "input":
                raise SystemError_(f"{where}: {tu}.{d.var} is a {dv.causality}, not an input")
            _check_types(where, f"{su}.{s.var}", sv, f"{tu}.{d.var}", dv)
            _check_units(where, (f"{su}.{s.name}", sv, _binding(bindings, su, s)),
                         (f"{tu}.{d.name}", dv, _binding(bindings, tu, d)), c.derivative_order)
            if c.derivative_order and (dv.type != "Real" or not units[tu].can_interpolate_inputs):
                raise SystemError_(f"{where}: unit {tu} cannot take input derivatives "
                                   "(canInterpolateInputs is false)")
            key = (tu, d.var, c.derivative_order)
            if key in seen_targets:
                raise SystemError_(f"{where}: input {tu}.{d.var} is already driven by {seen_targets[key]}")
            seen_targets[key] = f"{su}.{s.var}"
            out.append(ScalarConnection(s, d, c.derivative_order))
    return out


def _type_name(v) -> str:
    return v.fmi_type or v.type


def _check_types(where: str, src: str, sv, dst: str, dv) -> None:
    if not connectable(sv.tinfo, dv.tinfo):
        raise SystemError_(
            f"{where}: {src} is {_type_name(sv)} but {dst} is {_type_name(dv)}; a connection needs "
            "the same type or a lossless widening (Int8 -> Int32, Float32 -> Float64, "
            "Integer <-> Enumeration)")


def _binding(bindings: dict, unit: str, e: Endpoint) -> Binding | None:
    if e.name == e.var:
        return None
    return bindings.get(unit, {}).get(e.name.split("[")[0])


def _unit_of(var, binding: Binding | None, parse: bool):
    """(unit text, base exponents, factor, offset) of what an end puts into or takes from the
    exchange: a role binding's role unit, else the variable's declared unit definition, else
    (*parse*) its unit text read as SI; None if unknown."""
    from orchestrator import si

    if binding is None and var.base_exponents is not None:
        return var.unit, tuple(var.base_exponents), var.unit_factor, var.unit_offset
    text = binding.role_unit if binding is not None else (var.unit if parse else None)
    if not text:
        return None
    try:
        exps, factor, offset = si.parse(text)
    except ValueError:
        return None
    return text, tuple(exps), factor, offset


def _check_units(where: str, src: tuple, dst: tuple, derivative_order: int = 0) -> None:
    """What the source end puts into the exchange must be what the target end takes: the same
    dimension and scale (a k-th derivative: the target's unit per s^k). *src*, *dst*: (name,
    variable, its role binding or None). Between two ends by the FMUs' own names only declared
    unit definitions are compared (the exchange does not convert between an FMU's own units);
    an end by role name is in its role's unit (a specific force wired into a rate input ran,
    the gyro reading 9.8 rad/s)."""
    (sname, sv, sb), (dname, dv, db) = src, dst
    direct = sb is None and db is None
    su, du = _unit_of(sv, sb, not direct), _unit_of(dv, db, not direct)
    if su is None or du is None:
        return
    expected = list(du[1])
    expected[2] -= derivative_order  # the exponent of s (orchestrator.fmu_units._BASE)
    same = list(su[1]) == expected and math.isclose(su[2], du[2], rel_tol=1e-12) \
        and (derivative_order or math.isclose(su[3], du[3], rel_tol=1e-12, abs_tol=1e-12))
    if same:
        return
    what = f"the derivative {derivative_order} of {dname}" if derivative_order else dname
    per = f"/s{derivative_order}" if derivative_order else ""
    if direct:
        raise SystemError_(f"{where}: {sname} is in {su[0]} but {what} is in {du[0]}{per}; "
                           "connected variables need the same unit")
    # the same quantity in another scale: a direct end's own
    hint = "; connect both ends by role name to have them converted" if list(su[1]) == expected else ""
    raise SystemError_(f"{where}: {sname} is in {su[0]} but {what} takes {du[0]}{per}{hint}; "
                       "connected variables need the same quantity and unit")


def strongly_connected(nodes: list[str], edges: dict[str, list[str]]) -> list[list[str]]:
    """Strongly connected components, in reverse topological order of the condensation."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    comps: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges.get(v, []):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            comps.append(comp)

    for v in nodes:
        if v not in index:
            visit(v)
    return comps


def stepping_order(system: System, conns: list[ScalarConnection]) -> list[str]:
    """Gauss–Seidel order: sources before their consumers; units in a feedback cycle (broken by
    the one-step delay of co-simulation) keep the order in which the system declares them."""
    names = [u.name for u in system.units]
    if system.order:
        return list(system.order)
    edges: dict[str, list[str]] = {n: [] for n in names}
    for c in conns:
        if c.source.unit != c.target.unit and c.target.unit not in edges[c.source.unit]:
            edges[c.source.unit].append(c.target.unit)
    comps = strongly_connected(names, edges)[::-1]
    rank = {n: i for i, n in enumerate(names)}
    return [n for comp in comps for n in sorted(comp, key=rank.__getitem__)]


def algebraic_loops(conns: list[ScalarConnection], feedthrough: dict[str, dict[str, list[str]]]) -> list[list[str]]:
    """Cycles made only of direct feed-through (output depends on input within a unit) and
    connections, each as its sorted "unit.variable" nodes."""
    edges: dict[str, list[str]] = {}
    for c in conns:
        if c.derivative_order == 0:
            edges.setdefault(f"{c.source.unit}.{c.source.var}", []).append(f"{c.target.unit}.{c.target.var}")
    for unit, deps in feedthrough.items():
        for out, ins in deps.items():
            for i in ins:
                edges.setdefault(f"{unit}.{i}", []).append(f"{unit}.{out}")
    nodes = sorted(set(edges) | {w for ws in edges.values() for w in ws})
    return [sorted(comp) for comp in strongly_connected(nodes, edges) if len(comp) > 1]


def check_algebraic_loops(loops: list[list[str]], broken_by: str | None = None) -> list[str]:
    """The :func:`algebraic_loops`: no step order satisfies them without delay or iteration.
    Refused, unless the system breaks them with a one-step delay (*broken_by*: an explicit order,
    or Jacobi) or solves them (*broken_by* "iterative"); then each is returned as a note to
    report."""
    notes = []
    for comp in loops:
        loop = " -> ".join(comp)
        if broken_by == "iterative":
            notes.append(f"algebraic loop {loop} solved by fixed-point iteration at every step")
            continue
        if broken_by is None:
            raise AlgebraicLoopError(
                f"algebraic loop (outputs that depend instantaneously on each other): {loop}. "
                "Break it with a unit that has no direct feed-through, accept a one-step "
                "delay: set system.order (a unit reads the outputs of units after it one "
                'step late) or system.algorithm = "jacobi" (every input one step late), or '
                'solve it at every step: system.algorithm = "iterative" (units that can get and '
                "set their state).")
        notes.append(f"algebraic loop {loop} broken by {broken_by}: one-step delay")
    return notes


def fmu_feedthrough(unit: Unit) -> dict[str, list[str]]:
    """Direct dependencies of outputs on inputs declared by an FMU's ModelStructure, or by a
    Python component's ``feedthrough`` attribute."""
    md = getattr(unit, "md", None)
    if md is None:
        comp = getattr(unit, "component", None)
        return dict(getattr(comp, "feedthrough", {}) or {})
    out: dict[str, list[str]] = {}
    for o in md.outputs or []:
        deps = o.dependencies or []
        ins = [d.name for d in deps if d.causality == "input"]
        if ins:
            out[o.variable.name] = ins
    return out
