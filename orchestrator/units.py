"""What the master steps, whatever it is: the :class:`Unit` interface (variables by name, life
cycle, log capture, provenance) that FMUs (:mod:`orchestrator.fmu_units`) and Python components
(:mod:`orchestrator.component_unit`) implement, so that roles, wiring and the master need not
know which kind a unit is."""
from __future__ import annotations

import hashlib
import os
from collections import deque
from dataclasses import dataclass
from pathlib import Path

from orchestrator.errors import UnitError
from orchestrator.fmi_types import TypeInfo, info

STATUS = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]


@dataclass(frozen=True)
class VarInfo:
    name: str
    causality: str
    type: str  # family: Real, Integer, Boolean, String, Binary (Float32 -> Real, Int8 -> Integer)
    unit: str | None
    vr: int
    start: object = None
    # unit definition declared by the FMU: SI value = factor * value + offset, and the SI base
    # unit exponents; None when the FMU declares none
    unit_factor: float = 1.0
    unit_offset: float = 0.0
    base_exponents: tuple | None = None
    fmi_type: str = ""         # as declared: Float32, Int8, Enumeration, ... ("" = type)
    variability: str = "continuous"
    initial: str | None = None  # exact, approx, calculated (None: not declared / not FMI)
    shape: tuple = ()           # an FMI 3 array's dimensions; () for a scalar
    element: tuple | None = None  # (array variable, flat index) for an array element
    fmi3: bool = False

    @property
    def tinfo(self) -> TypeInfo:
        return info(self.fmi_type or self.type, self.fmi3)


_HASHED: dict = {}   # (path, size, mtime_ns) -> hex digest, for this process


def sha256_file(path: str | Path) -> str:
    """SHA-256 of a file's bytes. A file unchanged since it was hashed in this process (same
    size and modification time) is not read again: a command checks a log's hash for the model,
    the baseline, the truth and the provenance, and an 8-hour log costs 0.9 s a read."""
    st = os.stat(path)
    key = (os.path.realpath(path), st.st_size, st.st_mtime_ns)
    if key not in _HASHED:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _HASHED[key] = h.hexdigest()
    return _HASHED[key]



class Unit:
    """Common interface of everything the master steps."""

    kind = "abstract"
    name: str
    variables: dict[str, VarInfo]
    can_interpolate_inputs = False
    max_output_derivative_order = 0
    #: set by do_step when an FMU asks to end the run (FMI 2 fmi2Terminated, FMI 3
    #: terminateSimulation): the time it reached
    ended_at: float | None = None

    def __init__(self, name: str) -> None:
        self.name = name
        self.logs: deque = deque(maxlen=200)

    def log_tail(self, n: int = 10) -> list[str]:
        return [f"[{s}] {m}" for s, m in list(self.logs)[-n:]]

    # life cycle
    def instantiate(self, t0: float) -> None: ...
    def enter_initialization(self) -> None: ...
    def exit_initialization(self) -> None: ...
    def do_step(self, t: float, h: float) -> None: ...
    def terminate(self) -> None: ...
    def free(self) -> None: ...
    def set_values(self, values: dict) -> None: ...
    def get_values(self, names: list[str]) -> list: ...
    def provenance(self) -> dict: return {}

    # the state, to repeat a step (an algebraic loop solved by iteration)
    can_get_set_state = False

    def get_state(self):
        raise UnitError(f"unit {self.name}: cannot get its state")

    def set_state(self, state) -> None:
        raise UnitError(f"unit {self.name}: cannot set its state")

    def free_state(self, state) -> None:
        pass

    def stop_requested(self) -> bool:
        """Has the unit asked to end the run (a Python component's ``stop_requested``)?"""
        return False


def log_suffix(u: Unit) -> str:
    """The unit's last log lines, to end a fault message with (nothing when it logged none)."""
    tail = u.log_tail()
    return ("\n  FMU log:\n  " + "\n  ".join(tail)) if tail else ""
