"""The exchange of a run: one slot per distinct source output or recorded variable.

Values a float64 holds exactly (floats, Booleans, integers up to 32 bits) live in one float64
array in SI units, which the native loop reads and writes; 64-bit integers, strings and binaries
live beside it as Python objects (only Python-stepped units produce them). A slot's value is
turned into a target's type only as :mod:`orchestrator.fmi_types` allows, never by rounding.
"""
from __future__ import annotations

import math

import numpy as np

from orchestrator.errors import UnitError
from orchestrator.fmi_types import exact_in_float64, from_slot
from orchestrator.units import Unit, VarInfo, log_suffix


class Exchange:
    def __init__(self, units: dict[str, Unit]) -> None:
        self.units = units
        self.slots: dict[tuple[str, str], int] = {}
        self.conv: dict[tuple[str, str], tuple[float, float]] = {}  # SI = factor * x + offset
        self.objects: dict[int, object] = {}  # slots that hold Python objects
        self.values = np.zeros(1)

    def slot(self, unit: str, var: str, factor: float = 1.0, offset: float = 0.0) -> int:
        key = (unit, var)
        if key not in self.slots:
            i = self.slots[key] = len(self.slots)
            self.conv[key] = (factor, offset)
            t = self.units[unit].variables[var].tinfo
            if not exact_in_float64(t):
                # what a unit reads before the source has given a value (a loop broken by the
                # order, at initialisation), as the float slots read 0.0
                self.objects[i] = {"string": "", "binary": b""}.get(t.family, 0)
        return self.slots[key]

    def allocate(self) -> np.ndarray:
        """The value array, once every slot is known (and, per unit, what its outputs need)."""
        self.values = np.zeros(max(len(self.slots), 1))
        self._outputs: dict[str, list] = {}
        for (unit, var), s in self.slots.items():
            family = self.units[unit].variables[var].tinfo.family
            self._outputs.setdefault(unit, []).append((var, s, family, *self.conv[(unit, var)]))
        return self.values

    def read(self, s: int):
        return self.objects[s] if s in self.objects else self.values[s]

    def as_input(self, v: VarInfo, s: int, scale: float, shift: float):
        """The value of slot *s* as input *v* takes it (its unit, its type)."""
        x = self.read(s)
        if v.tinfo.family == "float":
            return scale * float(x) + shift
        return from_slot(v.tinfo, x)

    def outputs_of(self, u: Unit) -> list[str]:
        return [var for (unit, var) in self.slots if unit == u.name]

    def store_outputs(self, u: Unit, time: float) -> None:
        """Read *u*'s exchanged outputs into their slots (floats checked finite, to SI)."""
        outs = self._outputs.get(u.name)
        if not outs:
            return
        for (var, s, family, f, o), x in zip(outs, u.get_values([out[0] for out in outs])):
            if s in self.objects:
                self.objects[s] = x
                continue
            if family in ("int", "enum") and (isinstance(x, bool) or x != int(x)):
                # a Python component can leave any object in an Integer output
                raise UnitError(f"unit {u.name}: Integer output {var} = {x!r} at t = {time:.9g} s "
                                "is not an integer")
            x = float(x)
            if not math.isfinite(x):
                raise UnitError(f"unit {u.name}: output {var} = {x} at t = {time:.9g} s" + log_suffix(u))
            self.values[s] = f * x + o
