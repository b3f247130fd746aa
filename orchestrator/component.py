"""Python components: units written in Python with the life cycle and variable declarations of
an FMI co-simulation slave, so the master treats them exactly like FMUs.

A component declares its variables once, as a class attribute::

    class Lag(Component):
        variables = [Var("u", "input"), Var("y", "output"), Var("tau", "parameter", start=1.0,
                                                                 unit="s")]

        def do_step(self, t, h):
            self["y"] += (self["u"] - self["y"]) * (1 - math.exp(-h / self["tau"]))

Values are read and written by name (``self[name]``). ``initialize(t0)`` runs once after the
parameters and initial inputs are set; ``do_step(t, h)`` advances from t to t + h with the
inputs the master set before the call and leaves the outputs for t + h.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

CAUSALITIES = ("parameter", "input", "output", "local")
TYPES = ("Real", "Integer", "Boolean", "String")


@dataclass(frozen=True)
class Var:
    name: str
    causality: str
    type: str = "Real"
    start: object = 0.0
    unit: str | None = None
    description: str = ""

    def __post_init__(self) -> None:
        if self.causality not in CAUSALITIES:
            raise ValueError(f"variable {self.name}: causality {self.causality!r}, expected one of {CAUSALITIES}")
        if self.type not in TYPES:
            raise ValueError(f"variable {self.name}: type {self.type!r}, expected one of {TYPES}")


class Component:
    """Base class of Python units. Subclasses set ``variables`` and override ``do_step``."""

    variables: ClassVar[list[Var]] = []
    #: set to True in do_step to end the run at this step (the master stops before the units
    #: after this one in the order step; the recording ends there)
    stop_requested: bool = False

    def __init__(self, name: str) -> None:
        self.name = name
        self._values: dict[str, object] = {v.name: v.start for v in self.variables}
        self._decl = {v.name: v for v in self.variables}

    def __getitem__(self, key: str):
        return self._values[key]

    def __setitem__(self, key: str, value) -> None:
        if key not in self._decl:
            raise KeyError(f"component {self.name}: no variable {key!r}")
        self._values[key] = value

    def initialize(self, t0: float) -> None:
        """Called once, after parameters and initial inputs are set."""

    def do_step(self, t: float, h: float) -> None:
        raise NotImplementedError

    def terminate(self) -> None:
        """Called once at the end of the run (also after a fault)."""

    def provenance(self) -> dict:
        """What identifies this component's behaviour in a result record."""
        cls = type(self)
        return {"class": f"{cls.__module__}:{cls.__qualname__}"}
