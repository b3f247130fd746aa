"""A Python :class:`~orchestrator.component.Component` as a unit: its variables, life cycle and
exceptions seen through the :class:`~orchestrator.units.Unit` interface."""
from __future__ import annotations

import importlib

from orchestrator.component import Component
from orchestrator.errors import SystemError_, UnitError
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

    def terminate(self) -> None:
        try:
            self.component.terminate()
        except Exception:
            pass

    def stop_requested(self) -> bool:
        return bool(getattr(self.component, "stop_requested", False))

    def provenance(self) -> dict:
        return {"kind": "python", **self.component.provenance()}


def import_component(spec, name: str, config: dict) -> Component:
    """The component *spec* names (an instance, a class, or 'module:Class'), constructed with
    *config*."""
    if isinstance(spec, Component):
        return spec
    if isinstance(spec, type) and issubclass(spec, Component):
        return construct_component(spec, name, config)
    if isinstance(spec, str) and ":" in spec:
        mod, cls = spec.split(":", 1)
        try:
            obj = getattr(importlib.import_module(mod), cls)
        except (ImportError, AttributeError) as e:
            raise SystemError_(f"units.{name}.component = {spec!r}: cannot import ({e})") from None
        if not (isinstance(obj, type) and issubclass(obj, Component)):
            raise SystemError_(f"units.{name}.component = {spec!r}: not a Component subclass")
        return construct_component(obj, name, config)
    raise SystemError_(f"units.{name}.component = {spec!r}: expected 'module:Class'")


def construct_component(cls: type, name: str, config: dict) -> Component:
    try:
        return cls(name, **config)
    except TypeError as e:
        raise SystemError_(f"units.{name}.config: {cls.__name__} does not accept {sorted(config)} ({e})") from None
