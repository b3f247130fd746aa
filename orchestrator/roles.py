"""Roles: the named set of variables a unit must offer to be plugged into a place of a system,
and the check of a unit against its role (with a supplier's name mapping and unit conversion).

The orchestrator knows roles only as data; the domain registers its roles (see
``components.simulation.roles``) with :func:`register_role`.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Callable

from orchestrator import si
from orchestrator.errors import UnitParseError
from orchestrator.plugins import load_plugins
from orchestrator.units import Unit, VarInfo


@dataclass(frozen=True)
class RoleVariable:
    name: str
    causality: str  # input, output, parameter
    type: str = "Real"
    unit: str | None = None  # SI unit the role exchanges
    required: bool = True
    description: str = ""
    # how an output refines when the step is halved (verify): "sample" a value at an instant,
    # "sum" a per-interval total (an increment, a count), "mean" a per-interval mean (a mean rate)
    aggregate: str = "sample"
    # a Real the unit may also give as an Integer (a pulse count): read as a number all the same
    accepts_integer: bool = False
    # what a unit whose unit does not convert may mean instead (the role's options that would
    # take it), said with the problem
    unit_hint: str = ""


@dataclass
class Role:
    name: str
    variables: list[RoleVariable]
    description: str = ""
    # parameters that configure a unit to give what the role's options declare (an IMU that
    # chooses its output kind by parameter): a unit that has a parameter of this name (its own or
    # through its mapping) takes the value; a system file setting it otherwise is refused
    settings: dict = field(default_factory=dict)

    def variable(self, name: str) -> RoleVariable | None:
        return next((v for v in self.variables if v.name == name), None)


_ROLE_FACTORIES: dict[str, Callable[..., Role]] = {}


def register_role(name: str, factory: Callable[..., Role]) -> None:
    """``factory(**options)`` builds the role (options come from the system file, e.g. axes)."""
    _ROLE_FACTORIES[name] = factory


def get_role(name: str, **options) -> Role:
    """The role *name* with its *options*; a ValueError naming an unknown role or option (and
    what there is), not a factory's TypeError."""
    import difflib
    import inspect

    if name not in _ROLE_FACTORIES:
        load_plugins()
    if name not in _ROLE_FACTORIES:
        known = ", ".join(sorted(_ROLE_FACTORIES)) or "none registered"
        raise ValueError(f"unknown role {name!r} (known: {known})")
    factory = _ROLE_FACTORIES[name]
    params = inspect.signature(factory).parameters
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    allowed = [k for k, p in params.items() if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    for key in options:
        if key not in allowed and not takes_any:
            close = difflib.get_close_matches(key, allowed, n=1)
            raise ValueError(f"role {name!r} has no option {key!r}" + (f" (did you mean {close[0]!r}?)" if close else "")
                             + f"; its options: {', '.join(allowed) or 'none'}")
    return factory(**options)


def known_roles() -> list[str]:
    load_plugins()
    return sorted(_ROLE_FACTORIES)


@dataclass(frozen=True)
class Binding:
    """How one role variable is reached in a unit: its name there and the conversion
    SI = factor * unit_value + offset."""

    role_name: str
    unit_name: str
    factor: float = 1.0
    offset: float = 0.0
    role_unit: str | None = None   # the role variable's unit: what the converted value is in


@dataclass
class RoleCheck:
    unit: str
    role: str
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    bindings: dict[str, Binding] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.problems

    def report(self) -> str:
        head = f"unit {self.unit} against role {self.role}: " + (
            "conforms" if self.ok else f"{len(self.problems)} problem(s)")
        lines = [head] + [f"  - {p}" for p in self.problems] + [f"  note: {n}" for n in _merged(self.notes)]
        return "\n".join(lines)


def _merged(notes: list[str]) -> list[str]:
    """Notes that differ only in a vector's component ("gyro.x: ...", "gyro.y: ...") as one
    ("gyro.x, gyro.y: ..."), in the order they first came."""
    groups: dict[str, list[str]] = {}
    for n in notes:
        name, sep, text = n.partition(": ")
        key = text if sep and "." in name else n
        groups.setdefault(key, []).append(name if sep and "." in name else None)
    out = []
    for key, names in groups.items():
        out.append(key if None in names else f"{', '.join(names)}: {key}")
    return out


def _conversion(rv: RoleVariable, v: VarInfo) -> tuple[float, float] | str:
    """(factor, offset) from the unit's declared unit to the role's SI unit, or a problem."""
    if rv.unit is None or rv.type != "Real":
        return 1.0, 0.0
    want, f_role, off_role = si.parse(rv.unit)
    if not v.unit:
        return (1.0, 0.0)
    if v.base_exponents is not None:
        have, factor, offset = v.base_exponents, v.unit_factor, v.unit_offset
    else:
        try:
            have, factor, offset = si.parse(v.unit)
        except UnitParseError:
            return (f"{v.name}: unit {v.unit!r} has no unit definition in the FMU and is not an SI "
                    f"unit string; expected {rv.unit}")
    if tuple(have) != tuple(want):
        return f"{v.name}: unit {v.unit!r} cannot be converted to {rv.unit}"
    # SI = factor * value + offset, then into the role's (possibly offset) unit
    return factor / f_role, (offset - off_role) / f_role


def check_unit(unit: Unit, role: Role, mapping: dict[str, str] | None = None) -> RoleCheck:
    """Check *unit* against *role*. ``mapping`` maps role names to the unit's own names."""
    mapping = dict(mapping or {})
    res = RoleCheck(unit.name, role.name)
    for key in mapping:
        if role.variable(key) is None:
            res.problems.append(f"mapping names {key!r}, which is not a variable of role {role.name}")
    for rv in role.variables:
        name = mapping.get(rv.name, rv.name)
        v = unit.variables.get(name)
        if v is None:
            if rv.required:
                via = f" (mapped to {name!r})" if name != rv.name else ""
                # a name's case first (AngularRate_x for AngularRate_X), then its spelling
                near = [v for v in unit.variables if v.lower() == name.lower()] or \
                    difflib.get_close_matches(name, list(unit.variables), n=1, cutoff=0.8)
                res.problems.append(f"missing {rv.causality} {rv.name}{via} [{rv.unit or '-'}, {rv.type}]"
                                    + (f"; did you mean {near[0]!r}?" if near else ""))
            else:
                res.notes.append(f"optional {rv.causality} {rv.name} not offered")
            continue
        caus_ok = v.causality == rv.causality or (
            rv.causality == "parameter" and v.causality in ("parameter", "calculatedParameter"))
        if not caus_ok:
            res.problems.append(f"{name}: causality {v.causality}, role {role.name} needs {rv.causality}")
        if v.type != rv.type and not (rv.accepts_integer and v.type == "Integer"):
            res.problems.append(f"{name}: type {v.type}, role {role.name} needs {rv.type}")
        conv = _conversion(rv, v)
        if isinstance(conv, str):
            res.problems.append(conv + (f" ({rv.unit_hint})" if rv.unit_hint else ""))
            continue
        if rv.unit and rv.type == "Real" and not v.unit:
            res.notes.append(f"{name}: no unit declared, taken as {rv.unit}")
        elif conv != (1.0, 0.0):
            res.notes.append(f"{name}: {v.unit} converted to {rv.unit} (x {conv[0]:.12g}"
                             + (f", + {conv[1]:g})" if conv[1] else ")"))
        res.bindings[rv.name] = Binding(rv.name, name, *conv, rv.unit if rv.type == "Real" else None)
    return res
