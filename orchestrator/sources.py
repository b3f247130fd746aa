"""Built-in signal sources: Python components with one output ``y`` that drive an input without
any code of the user's, named in a system file like any component::

    [units.cmd]
    component = "orchestrator.sources:Sine"
    [units.cmd.config]
    amplitude = 0.5      # y = offset + amplitude * sin(2 pi frequency t + phase)
    frequency = 2.0      # Hz
    [[connections]]
    from = "cmd.y"
    to = "plant.u"

Each source gives its exact value at every communication point (after ``initialize`` the value
at the start time; after a step from t to t + h the value at t + h), so it adds no coupling
error of its own beyond the input hold of the unit it drives. ``Table`` reads two named columns
of a CSV file (path relative to the system file) and interpolates linearly or holds the last
row; before the first and after the last time it holds the end values.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

from orchestrator.component import Component, Var
from orchestrator.errors import SystemError_

__all__ = ["Constant", "Step", "Ramp", "Sine", "Table"]


def _number(unit: str, key: str, value, minimum: float | None = None, positive: bool = False) -> float:
    """A finite number from a config value, or a SystemError_ naming the unit and key."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SystemError_(f"units.{unit}.config.{key} = {value!r}: expected a finite number")
    if positive and not value > 0:
        raise SystemError_(f"units.{unit}.config.{key} = {value!r}: expected a positive number")
    if minimum is not None and value < minimum:
        raise SystemError_(f"units.{unit}.config.{key} = {value!r}: expected a number >= {minimum:g}")
    return float(value)


class _Source(Component):
    """y = value(t) at every communication point."""

    variables = [Var("y", "output", description="the source's value")]

    def value(self, t: float) -> float:
        raise NotImplementedError

    def initialize(self, t0: float) -> None:
        self["y"] = self.value(t0)

    def do_step(self, t: float, h: float) -> None:
        self["y"] = self.value(t + h)

    def provenance(self) -> dict:
        return {**super().provenance(), "config": self.config}


class Constant(_Source):
    """y = value."""

    def __init__(self, name: str, value: float = 0.0) -> None:
        super().__init__(name)
        self.config = {"value": _number(name, "value", value)}

    def value(self, t: float) -> float:
        return self.config["value"]


class Step(_Source):
    """y = before for t < time, after from t = time on."""

    def __init__(self, name: str, time: float = 0.0, before: float = 0.0, after: float = 1.0) -> None:
        super().__init__(name)
        self.config = {"time": _number(name, "time", time), "before": _number(name, "before", before),
                       "after": _number(name, "after", after)}

    def value(self, t: float) -> float:
        c = self.config
        # a communication point that is the step time up to rounding of k * h counts as reached
        return c["after"] if t >= c["time"] - 1e-12 * max(1.0, abs(c["time"])) else c["before"]


class Ramp(_Source):
    """y = offset until start_time, then offset + slope * (t - start_time)."""

    def __init__(self, name: str, slope: float = 1.0, start_time: float = 0.0, offset: float = 0.0) -> None:
        super().__init__(name)
        self.config = {"slope": _number(name, "slope", slope), "start_time": _number(name, "start_time", start_time),
                       "offset": _number(name, "offset", offset)}

    def value(self, t: float) -> float:
        c = self.config
        return c["offset"] + c["slope"] * max(0.0, t - c["start_time"])


class Sine(_Source):
    """y = offset + amplitude * sin(2 pi frequency t + phase); frequency in Hz, phase in rad."""

    def __init__(self, name: str, amplitude: float = 1.0, frequency: float = 1.0, phase: float = 0.0,
                 offset: float = 0.0) -> None:
        super().__init__(name)
        self.config = {"amplitude": _number(name, "amplitude", amplitude),
                       "frequency": _number(name, "frequency", frequency, minimum=0.0),
                       "phase": _number(name, "phase", phase), "offset": _number(name, "offset", offset)}

    def value(self, t: float) -> float:
        c = self.config
        return c["offset"] + c["amplitude"] * math.sin(2 * math.pi * c["frequency"] * t + c["phase"])


INTERPOLATIONS = ("linear", "hold")


class Table(_Source):
    """y from a CSV file's column *value* against its column *time* (strictly increasing),
    interpolated linearly or held from each row to the next ("hold")."""

    relative_paths = ("file",)  # resolved against the system file's folder

    def __init__(self, name: str, file: str = "", time: str = "time", value: str = "value",
                 interpolation: str = "linear") -> None:
        super().__init__(name)
        where = f"units.{name}.config"
        if interpolation not in INTERPOLATIONS:
            raise SystemError_(f"{where}.interpolation = {interpolation!r}: expected one of {INTERPOLATIONS}")
        if not isinstance(file, str) or not file:
            raise SystemError_(f"{where}.file = {file!r}: expected the path of a CSV file")
        self.config = {"file": file, "time": time, "value": value, "interpolation": interpolation}
        self.times, self.values = _read_table(Path(file), time, value, where)

    def value(self, t: float) -> float:
        ts, ys = self.times, self.values
        if t <= ts[0]:
            return ys[0]
        if t >= ts[-1]:
            return ys[-1]
        # the last row at or before t (a communication point within rounding of a row's time
        # counts as that row, so a held value changes where the file says)
        lo, hi = 0, len(ts) - 1
        tol = 1e-12 * max(1.0, abs(t))
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if ts[mid] <= t + tol:
                lo = mid
            else:
                hi = mid
        if self.config["interpolation"] == "hold" or abs(t - ts[lo]) <= tol:
            return ys[lo]
        w = (t - ts[lo]) / (ts[hi] - ts[lo])
        return ys[lo] + w * (ys[hi] - ys[lo])


def _read_table(path: Path, time: str, value: str, where: str) -> tuple[list[float], list[float]]:
    if not path.is_file():
        raise SystemError_(f"{where}.file = {str(path)!r}: no such file")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        header = [h.strip() for h in (reader.fieldnames or [])]
        for key, col in (("time", time), ("value", value)):
            if col not in header:
                raise SystemError_(f"{where}.{key} = {col!r}: {path} has no such column; its columns: {header}")
        ts, ys = [], []
        for row in reader:
            row = {k.strip(): v for k, v in row.items() if k is not None}
            line = reader.line_num
            try:
                t, y = float(row[time]), float(row[value])
            except (TypeError, ValueError):
                raise SystemError_(f"{path}, line {line}: {time} = {row.get(time)!r}, {value} = "
                                   f"{row.get(value)!r}: expected numbers") from None
            if not (math.isfinite(t) and math.isfinite(y)):
                raise SystemError_(f"{path}, line {line}: expected finite numbers")
            if ts and not t > ts[-1]:
                raise SystemError_(f"{path}, line {line}: {time} = {t!r} after {ts[-1]!r}: "
                                   "expected strictly increasing times")
            ts.append(t)
            ys.append(y)
    if not ts:
        raise SystemError_(f"{path}: no rows; expected a header and at least one row")
    return ts, ys
