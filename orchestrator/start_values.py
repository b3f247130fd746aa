"""Start values a system file gives a unit (``units.<name>.parameters``): which variables a
master may set before initialisation, and each value checked against its variable's type.

FMI 2 (section 3.2.3) and FMI 3 (section 2.4.7) let a master set, before or during
initialisation, the parameters, the inputs, and every variable with ``initial="exact"`` or
``"approx"`` (a state's start value, say); never a constant, nor a variable the FMU calculates
(``initial="calculated"``). Python components take their parameters and inputs.
"""
from __future__ import annotations

from orchestrator.errors import SystemError_
from orchestrator.fmi_types import check_value
from orchestrator.units import Unit, VarInfo

SETTABLE_CAUSALITIES = ("parameter", "input", "structuralParameter")


def check_settable(unit: Unit, v: VarInfo, where: str) -> None:
    if v.variability == "constant":
        raise SystemError_(f"{where}: {v.name} is a constant; FMI does not let a master set "
                           "constants")
    if v.name in getattr(unit, "dimension_parameters", ()):
        raise SystemError_(f"{where}: {v.name} sets the size of an array; array sizes stay as the "
                           "model description declares them")
    if v.causality in SETTABLE_CAUSALITIES or v.initial in ("exact", "approx"):
        return
    initial = f' with initial="{v.initial}"' if v.initial else ""
    raise SystemError_(
        f"{where}: {v.name} is a {v.causality}{initial}, not settable: a master sets before "
        'initialisation only parameters, inputs and variables with initial="exact" or "approx"')


def start_values(unit: Unit, endpoints, given: dict, where: str) -> dict:
    """*given* (names as written: role names or the unit's own) as values in the unit's own names,
    types and units. *endpoints(name)* resolves a name to its scalar endpoints; an array or a
    vector takes a list of as many values."""
    out = {}
    for name, value in given.items():
        eps = endpoints(name)
        if len(eps) > 1:
            if not isinstance(value, list) or len(value) != len(eps):
                raise SystemError_(f"{where}.{name} = {value!r}: expected a list of {len(eps)} "
                                   "values (one per element)")
            pairs = list(zip(eps, value))
        else:
            pairs = [(eps[0], value)]
        for e, x in pairs:
            v = unit.variables[e.var]
            check_settable(unit, v, where)
            x = check_value(v.tinfo, x, f"{where}.{e.name}")
            if v.tinfo.family == "float":
                x = (x - e.offset) / e.factor
            out[e.var] = x
    return out
