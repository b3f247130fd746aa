"""FMI 2.0 and FMI 3.0 co-simulation FMUs as units, loaded with fmpy: FMI 2.0 units expose
their raw entry points for the native span loop, FMI 3.0 units step on the Python path."""
from __future__ import annotations

import ctypes
import shutil
import tempfile
from pathlib import Path

from orchestrator.errors import UnitError
from orchestrator.units import STATUS, Unit, VarInfo, sha256_file

_TYPE_NAMES = {"Real": "Real", "Float64": "Real", "Float32": "Real", "Integer": "Integer",
               "Int32": "Integer", "Int64": "Integer", "Boolean": "Boolean", "String": "String",
               "Enumeration": "Integer"}
_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


def fmu_variables(md) -> dict[str, VarInfo]:
    """The variables of a model description (fmpy's), with their declared units' SI conversion."""
    units = {u.name: u for u in (md.unitDefinitions or [])}
    out = {}
    for v in md.modelVariables:
        if v.causality == "independent":
            continue
        factor, offset, exps = 1.0, 0.0, None
        u = units.get(v.unit) if v.unit else None
        if u is not None and u.baseUnit is not None:
            b = u.baseUnit
            factor, offset = float(b.factor or 1.0), float(b.offset or 0.0)
            exps = tuple(int(getattr(b, k) or 0) for k in _BASE)
        out[v.name] = VarInfo(v.name, v.causality, _TYPE_NAMES.get(v.type, v.type), v.unit,
                              int(v.valueReference), v.start, factor, offset, exps)
    return out


class FMU2Unit(Unit):
    """An FMI 2.0 co-simulation FMU, loaded with fmpy; the hot loop uses its raw entry points."""

    kind = "fmi2"

    def __init__(self, name: str, path: str | Path) -> None:
        from fmpy import read_model_description

        super().__init__(name)
        self.path = Path(path)
        self.md = read_model_description(str(self.path))
        if not self.md.fmiVersion.startswith("2"):
            raise UnitError(f"unit {name}: {self.path} is FMI {self.md.fmiVersion}, not 2.0")
        if self.md.coSimulation is None:
            raise UnitError(f"unit {name}: {self.path} has no co-simulation interface")
        cs = self.md.coSimulation
        self.can_interpolate_inputs = bool(cs.canInterpolateInputs)
        self.max_output_derivative_order = int(cs.maxOutputDerivativeOrder or 0)
        self.can_get_set_state = bool(cs.canGetAndSetFMUstate)
        self.variables = fmu_variables(self.md)
        self.fmu = None
        self._dir = None

    def instantiate(self, t0: float) -> None:
        from fmpy import extract
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        self._dir = extract(str(self.path), unzipdir=tempfile.mkdtemp(prefix=f"calbench-{self.name}-"))
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self._dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=self.name)
        libc = ctypes.CDLL(None)
        libc.calloc.restype = ctypes.c_void_p
        libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
        libc.free.argtypes = [ctypes.c_void_p]
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(self._on_log)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(libc.calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(libc.free)
        self._callbacks = cb  # must outlive the instance
        self._guard("instantiate", lambda: self.fmu.instantiate(callbacks=cb, loggingOn=False))
        self._guard("setupExperiment", lambda: self.fmu.setupExperiment(startTime=t0))
        self._guard("enterInitializationMode", self.fmu.enterInitializationMode)

    def _on_log(self, env, instance, status, category, message) -> None:
        msg = message.decode(errors="replace") if isinstance(message, bytes) else str(message)
        self.logs.append((STATUS[status] if 0 <= status < len(STATUS) else status, msg))

    def _guard(self, what: str, call):
        try:
            return call()
        except Exception as e:  # fmpy raises a plain Exception carrying the status
            tail = "\n  ".join(self.log_tail())
            raise UnitError(f"unit {self.name}: {what} failed ({e})"
                            + (f"\n  FMU log:\n  {tail}" if tail else "")) from None

    def exit_initialization(self) -> None:
        self._guard("exitInitializationMode", self.fmu.exitInitializationMode)

    def set_values(self, values: dict) -> None:
        for name, value in values.items():
            v = self.variables[name]
            if v.type == "Real":
                self._guard(f"setting {name}", lambda: self.fmu.setReal([v.vr], [float(value)]))
            elif v.type == "Integer":
                self._guard(f"setting {name}", lambda: self.fmu.setInteger([v.vr], [int(value)]))
            elif v.type == "Boolean":
                self._guard(f"setting {name}", lambda: self.fmu.setBoolean([v.vr], [bool(value)]))
            else:
                self._guard(f"setting {name}", lambda: self.fmu.setString([v.vr], [str(value)]))

    def get_values(self, names: list[str]) -> list:
        out = []
        for name in names:
            v = self.variables[name]
            getter = {"Real": self.fmu.getReal, "Integer": self.fmu.getInteger,
                      "Boolean": self.fmu.getBoolean, "String": self.fmu.getString}[v.type]
            out.append(self._guard(f"reading {name}", lambda: getter([v.vr]))[0])
        return out

    def do_step(self, t: float, h: float) -> None:
        self._guard(f"doStep at t = {t:.9g} s", lambda: self.fmu.doStep(t, h))

    def entry_points(self) -> dict[str, int]:
        """Addresses of the FMI functions and the instance, for the native loop."""
        dll = self.fmu.dll
        addr = {n: ctypes.cast(getattr(dll, f"fmi2{n}"), ctypes.c_void_p).value
                for n in ("DoStep", "SetReal", "GetReal", "SetInteger", "GetInteger",
                          "SetRealInputDerivatives")}
        addr["component"] = ctypes.cast(self.fmu.component, ctypes.c_void_p).value
        return addr

    def terminate(self) -> None:
        if self.fmu is not None:
            try:
                self.fmu.terminate()
            except Exception:
                pass  # already failed; the fault that brought us here is what matters

    def free(self) -> None:
        if self.fmu is not None:
            try:
                self.fmu.freeInstance()
            except Exception:
                pass
            self.fmu = None
        if self._dir:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None

    def provenance(self) -> dict:
        return {"kind": "fmi2", "path": str(self.path), "sha256": sha256_file(self.path),
                "modelIdentifier": self.md.coSimulation.modelIdentifier, "guid": self.md.guid,
                "generationTool": self.md.generationTool}


class FMU3Unit(Unit):
    """An FMI 3.0 co-simulation FMU, stepped through fmpy's FMU3Slave (Python path)."""

    kind = "fmi3"

    def __init__(self, name: str, path: str | Path) -> None:
        from fmpy import read_model_description

        super().__init__(name)
        self.path = Path(path)
        self.md = read_model_description(str(self.path))
        if not self.md.fmiVersion.startswith("3"):
            raise UnitError(f"unit {name}: {self.path} is FMI {self.md.fmiVersion}, not 3.0")
        if self.md.coSimulation is None:
            raise UnitError(f"unit {name}: {self.path} has no co-simulation interface")
        self.variables = fmu_variables(self.md)
        self.can_get_set_state = bool(getattr(self.md.coSimulation, "canGetAndSetFMUState", False))
        self.fmu = None
        self._dir = None

    def instantiate(self, t0: float) -> None:
        from fmpy import extract
        from fmpy.fmi3 import FMU3Slave

        self._dir = extract(str(self.path), unzipdir=tempfile.mkdtemp(prefix=f"calbench-{self.name}-"))
        self.fmu = FMU3Slave(guid=self.md.guid, unzipDirectory=self._dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier,
                             instanceName=self.name)
        self._guard("instantiate", lambda: self.fmu.instantiate(logMessage=self._on_log))
        self._guard("enterInitializationMode",
                    lambda: self.fmu.enterInitializationMode(startTime=t0))

    def _on_log(self, env, status, category, message) -> None:
        msg = message.decode(errors="replace") if isinstance(message, bytes) else str(message)
        self.logs.append((STATUS[status] if 0 <= status < len(STATUS) else status, msg))

    _guard = FMU2Unit._guard

    def exit_initialization(self) -> None:
        self._guard("exitInitializationMode", self.fmu.exitInitializationMode)

    def set_values(self, values: dict) -> None:
        for name, value in values.items():
            v = self.variables[name]
            setter = {"Real": (self.fmu.setFloat64, float), "Integer": (self.fmu.setInt32, int),
                      "Boolean": (self.fmu.setBoolean, bool), "String": (self.fmu.setString, str)}
            fn, conv = setter[v.type]
            self._guard(f"setting {name}", lambda: fn([v.vr], [conv(value)]))

    def get_values(self, names: list[str]) -> list:
        out = []
        for name in names:
            v = self.variables[name]
            getter = {"Real": self.fmu.getFloat64, "Integer": self.fmu.getInt32,
                      "Boolean": self.fmu.getBoolean, "String": self.fmu.getString}[v.type]
            out.append(self._guard(f"reading {name}", lambda: getter([v.vr]))[0])
        return out

    def do_step(self, t: float, h: float) -> None:
        def step():
            result = self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            if result[1]:  # terminateSimulation
                raise Exception("the FMU asked to terminate the simulation")
        self._guard(f"doStep at t = {t:.9g} s", step)

    terminate = FMU2Unit.terminate
    free = FMU2Unit.free

    def provenance(self) -> dict:
        return {"kind": "fmi3", "path": str(self.path), "sha256": sha256_file(self.path),
                "modelIdentifier": self.md.coSimulation.modelIdentifier,
                "instantiationToken": self.md.guid, "generationTool": self.md.generationTool}


def load_fmu_unit(name: str, path: str | Path) -> Unit:
    """FMU2Unit or FMU3Unit by the archive's declared FMI version."""
    from fmpy import read_model_description

    p = Path(path)
    if not p.exists():
        raise UnitError(f"unit {name}: FMU file {p} does not exist")
    try:
        md = read_model_description(str(p))
    except Exception as e:
        raise UnitError(f"unit {name}: {p} is not a readable FMU ({e})") from None
    return FMU3Unit(name, p) if md.fmiVersion.startswith("3") else FMU2Unit(name, p)


def read_fmu_variables(path: str | Path) -> dict[str, VarInfo]:
    """The variables of the FMU file *path* (its model description only: nothing is loaded)."""
    from fmpy import read_model_description

    return fmu_variables(read_model_description(str(path)))
