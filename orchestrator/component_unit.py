"""A Python :class:`~orchestrator.component.Component` as a unit: its variables, life cycle and
exceptions seen through the :class:`~orchestrator.units.Unit` interface."""
from __future__ import annotations

import copy

from orchestrator.component import Component
from orchestrator.errors import UnitError
from orchestrator.units import Unit, VarInfo


class ComponentUnit(Unit):
    """A Python :class:`~orchestrator.component.Component` behind the unit interface."""

    kind = "python"

    def __init__(self, name: str, component: Component) -> None:
        super().__init__(name)
        self.component = component
        self.variables = {v.name: VarInfo(v.name, v.causality, v.type, v.unit, i, v.start)
                          for i, v in enumerate(component.variables)}
        self._t0 = 0.0

    def _guard(self, what: str, call):
        try:
            return call()
        except UnitError:
            raise
        except Exception as e:
            raise UnitError(f"unit {self.name}: {what} raised {type(e).__name__}: {e}") from e

    def instantiate(self, t0: float) -> None:
        self._t0 = t0

    def exit_initialization(self) -> None:
        self._guard("initialize", lambda: self.component.initialize(self._t0))

    def set_values(self, values: dict) -> None:
        for k, v in values.items():
            self.component[k] = v

    def get_values(self, names: list[str]) -> list:
        return [self.component[n] for n in names]

    def do_step(self, t: float, h: float) -> None:
        self._guard(f"do_step at t = {t:.9g} s", lambda: self.component.do_step(t, h))

    # a component's state is its instance's attributes (its values and whatever it keeps)
    can_get_set_state = True

    def get_state(self):
        return self._guard("copying its state (copy.deepcopy of its attributes)",
                           lambda: copy.deepcopy(self.component.__dict__))

    def set_state(self, state) -> None:
        self.component.__dict__.clear()
        self.component.__dict__.update(copy.deepcopy(state))

    def terminate(self) -> None:
        try:
            self.component.terminate()
        except Exception:
            pass

    def stop_requested(self) -> bool:
        return bool(getattr(self.component, "stop_requested", False))

    def provenance(self) -> dict:
        return {"kind": "python", **self.component.provenance()}

