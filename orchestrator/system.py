"""The system description: units, roles, parameters, connections, steps, recording.

The same object comes from a TOML file (:func:`load_toml_system`, here, because the TOML layout
mirrors these classes), from an SSP archive (:mod:`orchestrator.ssp_load`) or is built in Python;
:func:`orchestrator.loader.load_system` picks the reader by the file's suffix. TOML layout::

    [system]
    name = "tumble"
    step = 0.005            # communication step [s]
    start = 0.0
    stop = 60.0
    algorithm = "gauss-seidel"   # or "jacobi", or "iterative" (algebraic loops solved each step)
    loop_tolerance = 1e-10       # "iterative": relative change at which a loop has converged
    loop_max_iterations = 100
    order = ["ctrl", "table", "imu"]   # optional; default: from the connection graph

    [units.table]
    fmu = "table.fmu"        # path relative to this file, or "<scheme>:<name>" (e.g. builtin:turntable)
    role = "turntable"
    step_multiple = 1
    [units.table.parameters]
    "site.latitude" = 0.6964

    [units.imu]
    fmu = "vendor_imu.fmu"
    role = "imu"
    [units.imu.mapping]      # role variable -> the unit's own name
    "omega.x" = "AngularRate_X"

    [units.ctrl]
    component = "components.control.sequencer:AttitudeSequence"   # Python component class
    step_multiple = 20
    [units.ctrl.config]      # keyword arguments of the component's constructor
    sequence = [[0.0, 0.0, 0.0, 0.0], [5.0, 0.0, 1.5707963267948966, 0.0]]

    [[connections]]
    from = "table.plate.omega"   # a vector prefix connects .x .y .z (or .w .x .y .z)
    to = "imu.omega"

    [record]
    signals = ["imu.gyro", "table.outer.angle"]
    every = 1                # record every n-th communication step
    aggregate = {"imu.gyro" = "sum"}   # optional, per signal (prefix): how `calbench verify`
                             # brings a finer run onto this grid: "sample" (default) or "sum"
                             # (per-interval quantities such as increments)

Variable names on connections and in ``record`` are role names when the unit has a role (the
mapping translates them), the unit's own names otherwise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator.errors import SystemError_
from orchestrator.tomlfile import read_toml

ALGORITHMS = ("gauss-seidel", "jacobi", "iterative")
AGGREGATIONS = ("sample", "sum", "mean")


@dataclass
class UnitSpec:
    name: str
    fmu: str | None = None
    component: object = None  # "module:Class", a Component subclass, or an instance
    role: str | None = None
    role_options: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)
    mapping: dict = field(default_factory=dict)
    step_multiple: int = 1
    config: dict = field(default_factory=dict)  # Python components: constructor keyword arguments


@dataclass
class Connection:
    source: str  # "unit.variable"
    target: str
    # 0: the value; k >= 1: the source gives the k-th time derivative of the target input
    # (passed with FMI 2 setRealInputDerivatives to a unit that can interpolate inputs)
    derivative_order: int = 0


@dataclass
class System:
    name: str = "system"
    step: float = 0.005
    start: float = 0.0
    stop: float = 1.0
    algorithm: str = "gauss-seidel"
    order: list[str] | None = None
    loop_tolerance: float = 1e-10      # algorithm "iterative" (orchestrator.loop_solver)
    loop_max_iterations: int = 100
    units: list[UnitSpec] = field(default_factory=list)
    connections: list[Connection] = field(default_factory=list)
    record: list[str] = field(default_factory=list)
    record_every: int = 1
    record_aggregate: dict = field(default_factory=dict)  # signal (or prefix) -> "sample" | "sum"
    source: str | None = None  # file it came from
    base_dir: Path = field(default_factory=Path.cwd)

    def unit(self, name: str) -> UnitSpec:
        for u in self.units:
            if u.name == name:
                return u
        raise KeyError(name)

    def grid(self) -> tuple[int, float]:
        """(number of steps, length of a shortened last step): a stop that is not a whole number
        of steps after start is reached by a shorter last step (0.0 when it is)."""
        span = self.stop - self.start
        n = int(round(span / self.step))
        if abs(n * self.step - span) <= 1e-9 * max(1.0, abs(self.stop)):
            return n, 0.0
        n_full = int(math.floor(span / self.step))
        slow = [u.name for u in self.units if u.step_multiple != 1]
        if slow:
            raise SystemError_(f"{self.source or 'system'}: stop - start = {span} is not a whole "
                               f"number of steps of {self.step}, and units {slow} step at a multiple "
                               "of it; choose a stop on their grid")
        return n_full + 1, span - n_full * self.step

    def validate(self) -> None:
        where = self.source or "system"
        if not self.step > 0:
            raise SystemError_(f"{where}: system.step = {self.step}: expected a positive step [s]")
        if not self.stop > self.start:
            raise SystemError_(f"{where}: system.stop = {self.stop} must be after start = {self.start}")
        if self.algorithm not in ALGORITHMS:
            raise SystemError_(f"{where}: system.algorithm = {self.algorithm!r}: expected one of {ALGORITHMS}")
        if not (isinstance(self.loop_tolerance, (int, float)) and 0 < self.loop_tolerance < 1):
            raise SystemError_(f"{where}: system.loop_tolerance = {self.loop_tolerance!r}: expected a relative "
                               "tolerance in (0, 1)")
        if isinstance(self.loop_max_iterations, bool) or not isinstance(self.loop_max_iterations, int) \
                or self.loop_max_iterations < 1:
            raise SystemError_(f"{where}: system.loop_max_iterations = {self.loop_max_iterations!r}: expected an "
                               "integer >= 1")
        names = [u.name for u in self.units]
        if not names:
            raise SystemError_(f"{where}: no units")
        for u in self.units:
            if "." in u.name or not u.name:
                raise SystemError_(f"{where}: unit name {u.name!r}: expected a non-empty name without '.'")
            if (u.fmu is None) == (u.component is None):
                raise SystemError_(f"{where}: units.{u.name}: give exactly one of 'fmu' or 'component'")
            if not (isinstance(u.step_multiple, int) and u.step_multiple >= 1):
                raise SystemError_(f"{where}: units.{u.name}.step_multiple = {u.step_multiple!r}: "
                                   "expected an integer >= 1")
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise SystemError_(f"{where}: duplicate unit names {sorted(dup)}")
        for i, c in enumerate(self.connections):
            for end in (c.source, c.target):
                unit = end.split(".", 1)[0]
                if "." not in end or unit not in names:
                    raise SystemError_(f"{where}: connections[{i}]: {end!r}: expected "
                                       f"'<unit>.<variable>' with unit one of {names}")
        if self.order is not None and sorted(self.order) != sorted(names):
            raise SystemError_(f"{where}: system.order {self.order} must list every unit once: {names}")
        if not (isinstance(self.record_every, int) and self.record_every >= 1):
            raise SystemError_(f"{where}: record.every = {self.record_every!r}: expected an integer >= 1")
        for sig, how in self.record_aggregate.items():
            if how not in AGGREGATIONS:
                raise SystemError_(f"{where}: record.aggregate.{sig} = {how!r}: expected one of {AGGREGATIONS}")


def _expect(d: dict, key: str, types, where: str, default=...):
    if key not in d:
        if default is ...:
            raise SystemError_(f"{where}: missing key {key!r}")
        return default
    v = d[key]
    if not isinstance(v, types):
        tn = types.__name__ if isinstance(types, type) else " or ".join(t.__name__ for t in types)
        raise SystemError_(f"{where}.{key} = {v!r}: expected {tn}")
    return v


def _no_unknown(d: dict, allowed: set, where: str) -> None:
    extra = set(d) - allowed
    if extra:
        raise SystemError_(f"{where}: unknown key(s) {sorted(extra)}; expected some of {sorted(allowed)}")


def system_from_dict(data: dict, source: str = "system", base_dir: Path | None = None) -> System:
    known_top = {"system", "units", "connections", "record"}
    extra = set(data) - known_top
    if extra:
        raise SystemError_(f"{source}: unknown section(s) {sorted(extra)}; expected {sorted(known_top)}")
    s = _expect(data, "system", dict, source, {})
    _no_unknown(s, {"name", "step", "start", "stop", "algorithm", "order", "loop_tolerance", "loop_max_iterations"},
                f"{source}: system")
    num = (int, float)
    sysobj = System(
        name=_expect(s, "name", str, f"{source}: system", "system"),
        step=float(_expect(s, "step", num, f"{source}: system", 0.005)),
        start=float(_expect(s, "start", num, f"{source}: system", 0.0)),
        stop=float(_expect(s, "stop", num, f"{source}: system")),
        algorithm=_expect(s, "algorithm", str, f"{source}: system", "gauss-seidel"),
        order=_expect(s, "order", list, f"{source}: system", None),
        loop_tolerance=float(_expect(s, "loop_tolerance", num, f"{source}: system", 1e-10)),
        loop_max_iterations=_expect(s, "loop_max_iterations", int, f"{source}: system", 100),
        source=source,
        base_dir=base_dir or Path.cwd(),
    )
    units = _expect(data, "units", dict, source)
    for name, u in units.items():
        where = f"{source}: units.{name}"
        if not isinstance(u, dict):
            raise SystemError_(f"{where}: expected a table")
        allowed = {"fmu", "component", "role", "role_options", "parameters", "mapping", "step_multiple",
                   "config"}
        extra = set(u) - allowed
        if extra:
            raise SystemError_(f"{where}: unknown key(s) {sorted(extra)}; expected some of {sorted(allowed)}")
        sysobj.units.append(UnitSpec(
            name=name,
            fmu=_expect(u, "fmu", str, where, None),
            component=_expect(u, "component", str, where, None),
            role=_expect(u, "role", str, where, None),
            role_options=_expect(u, "role_options", dict, where, {}),
            parameters=_expect(u, "parameters", dict, where, {}),
            mapping=_expect(u, "mapping", dict, where, {}),
            step_multiple=_expect(u, "step_multiple", int, where, 1),
            config=_expect(u, "config", dict, where, {}),
        ))
    for i, c in enumerate(_expect(data, "connections", list, source, [])):
        where = f"{source}: connections[{i}]"
        if not isinstance(c, dict):
            raise SystemError_(f"{where}: expected a table with 'from' and 'to'")
        _no_unknown(c, {"from", "to", "derivative_order"}, where)
        sysobj.connections.append(Connection(_expect(c, "from", str, where), _expect(c, "to", str, where),
                                             _expect(c, "derivative_order", int, where, 0)))
    rec = _expect(data, "record", dict, source, {})
    _no_unknown(rec, {"signals", "every", "aggregate"}, f"{source}: record")
    sysobj.record = list(_expect(rec, "signals", list, f"{source}: record", []))
    sysobj.record_every = _expect(rec, "every", int, f"{source}: record", 1)
    sysobj.record_aggregate = dict(_expect(rec, "aggregate", dict, f"{source}: record", {}))
    sysobj.validate()
    return sysobj


def load_toml_system(path: str | Path) -> System:
    """The :class:`System` in a TOML system file (relative FMU paths are relative to its folder).
    :func:`orchestrator.loader.load_system` reads SSP archives as well."""
    p = Path(path)
    data = read_toml(p, SystemError_, "system")
    return system_from_dict(data, source=str(p), base_dir=p.parent.resolve())
