"""Which variables ``record.signals`` names: ``"unit.var"`` (a role name, the unit's own name, a
vector prefix or an FMI 3 array, which give several), ``"unit"`` (every output of the unit) or a
glob pattern ``"unit.x*"`` (every variable whose name matches, role names included)."""
from __future__ import annotations

import fnmatch

from orchestrator.errors import SystemError_
from orchestrator.units import Unit
from orchestrator.wiring import Endpoint, resolve


def record_endpoints(units: dict[str, Unit], bindings: dict[str, dict],
                     patterns: list[str]) -> list[tuple[str, Endpoint]]:
    """(unit, endpoint) for every recorded scalar, in the order of *patterns*, each once."""
    out: list[tuple[str, Endpoint]] = []
    seen: set[tuple[str, str]] = set()
    for pattern in patterns:
        unit, _, name = pattern.partition(".")
        if unit not in units:
            raise SystemError_(f"record.signals: {pattern!r}: no unit {unit!r}")
        u, b = units[unit], bindings.get(unit, {})
        if not name:
            names = [n for n, v in u.variables.items() if v.causality == "output" and not v.shape]
            if not names:
                raise SystemError_(f"record.signals: {pattern!r}: unit {unit} has no outputs")
        elif name not in b and name not in u.variables and any(ch in name for ch in "*?["):
            candidates = list(b) + [n for n, v in u.variables.items() if not v.shape]
            names = [n for n in dict.fromkeys(candidates) if fnmatch.fnmatchcase(n, name)]
            if not names:
                raise SystemError_(f"record.signals: {pattern!r}: no variable of unit {unit} "
                                   f"matches {name!r}")
        else:
            names = [name]
        for n in names:
            for e in resolve(u, b, n, "record.signals"):
                if (unit, e.var) not in seen:
                    seen.add((unit, e.var))
                    out.append((unit, e))
    return out
