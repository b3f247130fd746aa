"""``check-fmu``: everything a user wants to know before plugging an FMU into a role —
static validation (fmpy), conformance to the role (with a mapping), and a dynamic smoke test
(instantiate, initialise, one step, FMU state save/restore, terminate)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator.errors import SystemError_, UnitError
from orchestrator.fmu_units import FMU2Unit, load_fmu_unit
from orchestrator.roles import RoleCheck, check_unit, get_role


@dataclass
class FmuVerdict:
    path: str
    role: str | None
    validation: list[str] = field(default_factory=list)
    role_check: RoleCheck | None = None
    smoke: list[str] = field(default_factory=list)  # problems found by the dynamic test
    smoke_notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.validation and (self.role_check is None or self.role_check.ok) and not self.smoke

    def report(self) -> str:
        lines = [f"FMU {self.path}"]
        lines.append("static validation: " + ("no problem" if not self.validation else f"{len(self.validation)} problem(s)"))
        lines += [f"  - {p}" for p in self.validation]
        if self.role_check is not None:
            lines.append(self.role_check.report())
        lines.append("dynamic smoke test: " + ("passed" if not self.smoke else "FAILED"))
        lines += [f"  - {p}" for p in self.smoke] + [f"  note: {n}" for n in self.smoke_notes]
        lines.append("verdict: " + ("ACCEPTED" if self.ok else "REFUSED"))
        return "\n".join(lines)


def check_fmu(path: str | Path, role: str | None = None, mapping: dict | None = None,
              role_options: dict | None = None, step: float = 0.005) -> FmuVerdict:
    from fmpy.validation import validate_fmu

    verdict = FmuVerdict(str(path), role)
    try:
        verdict.validation = [str(p) for p in validate_fmu(str(path))]
    except Exception as e:
        verdict.validation = [f"cannot be validated: {e}"]
    try:
        unit = load_fmu_unit("candidate", path)
    except UnitError as e:
        verdict.smoke.append(str(e))
        return verdict
    if role:
        try:
            role_def = get_role(role, **(role_options or {}))
        except (KeyError, TypeError, ValueError) as e:
            raise SystemError_(f"role {role!r} with options {role_options or {}}: "
                               f"{str(e).strip(chr(39))}") from None
        verdict.role_check = check_unit(unit, role_def, mapping)
    _smoke(unit, step, verdict)
    return verdict


def _smoke(unit, step: float, verdict: FmuVerdict) -> None:
    outputs = [n for n, v in unit.variables.items()
               if v.causality == "output" and v.type == "Real" and not v.shape]  # elements, not arrays
    try:
        unit.instantiate(0.0)
        unit.exit_initialization()
        unit.do_step(0.0, step)
        first = unit.get_values(outputs)
        bad = [n for n, x in zip(outputs, first) if not math.isfinite(float(x))]
        if bad:
            verdict.smoke.append(f"non-finite outputs after one step: {', '.join(bad)}")
        if isinstance(unit, FMU2Unit) and unit.can_get_set_state:
            state = unit.fmu.getFMUstate()
            unit.do_step(step, step)
            a = unit.get_values(outputs)
            unit.fmu.setFMUstate(state)
            unit.do_step(step, step)
            b = unit.get_values(outputs)
            unit.fmu.freeFMUstate(state)
            diff = [n for n, x, y in zip(outputs, a, b) if x != y]
            if diff:
                verdict.smoke.append("FMU state restore does not reproduce the step: " + ", ".join(diff[:5]))
            else:
                verdict.smoke_notes.append("FMU state save/restore reproduces a step bit for bit")
        elif isinstance(unit, FMU2Unit):
            verdict.smoke_notes.append("FMU declares no get/set FMU state support")
        verdict.smoke_notes.append(f"instantiate, initialise, step of {step:g} s, terminate: OK")
    except UnitError as e:
        verdict.smoke.append(str(e))
    except Exception as e:  # a vendor FMU may fail in ways fmpy reports loosely
        verdict.smoke.append(f"{type(e).__name__}: {e}")
    finally:
        unit.terminate()
        unit.free()
