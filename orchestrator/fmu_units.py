"""FMI 2.0 and FMI 3.0 co-simulation FMUs as units, loaded with fmpy: FMI 2.0 units expose
their raw entry points for the native span loop, FMI 3.0 units step on the Python path."""
from __future__ import annotations

import ctypes
import dataclasses
import math
import shutil
import tempfile
from pathlib import Path

from orchestrator.errors import UnitError
from orchestrator.fmi_types import info
from orchestrator.units import STATUS, Unit, VarInfo, sha256_file

_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
# fmi2GetRealStatus / fmi2GetBooleanStatus kinds (fmi2StatusKind)
_FMI2_LAST_SUCCESSFUL_TIME, _FMI2_TERMINATED = 2, 3


def fmu_variables(md) -> dict[str, VarInfo]:
    """The variables of a model description (fmpy's), with their declared units' SI conversion.
    An FMI 3 array ``x`` of shape (2, 3) is listed as itself and as its elements ``x[0]`` ...
    ``x[5]`` (flat, row-major), so that connections and recordings can take it element-wise."""
    units = {u.name: u for u in (md.unitDefinitions or [])}
    fmi3 = md.fmiVersion.startswith("3")
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
        shape = tuple(int(n) for n in (getattr(v, "shape", None) or ()))
        if v.type == "Clock":
            raise UnitError(f"variable {v.name} is a Clock: clocked co-simulation (event mode) "
                            "is not supported")
        family = info(v.type, fmi3).family_name
        var = VarInfo(v.name, v.causality, family, v.unit, int(v.valueReference), v.start, factor,
                      offset, exps, fmi_type=v.type, variability=v.variability or "continuous",
                      initial=v.initial, shape=shape, fmi3=fmi3)
        out[v.name] = var
        for k in range(math.prod(shape) if shape else 0):
            name = f"{v.name}[{k}]"
            out[name] = dataclasses.replace(var, name=name, shape=(), element=(v.name, k),
                                            start=None)
    return out


def _get_scalar(unit, name: str, v: VarInfo):
    getter = getattr(unit.fmu, unit.accessor(v, "get"))
    return unit._guard(f"reading {name}", lambda: getter([v.vr]))[0]


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
        # initialisation mode is entered after the start values are set (enter_initialization):
        # a variable with initial="approx" may only be set before it
        self._in_init = False

    def _on_log(self, env, instance, status, category, message) -> None:
        msg = message.decode(errors="replace") if isinstance(message, bytes) else str(message)
        self.logs.append((STATUS[status] if 0 <= status < len(STATUS) else status, msg))

    def _guard(self, what: str, call):
        try:
            return call()
        except Exception as e:  # fmpy raises a plain Exception carrying the status
            raise UnitError(self._failure(what, e)) from None

    def _failure(self, what: str, e: Exception) -> str:
        tail = "\n  ".join(self.log_tail())
        return f"unit {self.name}: {what} failed ({e})" + (f"\n  FMU log:\n  {tail}" if tail else "")

    # fmpy's FMI 2 slave answers to the FMI 3 names too: FMU3Unit shares these
    def get_state(self):
        return self._guard(f"{self.kind}GetFMUState", self.fmu.getFMUState)

    def set_state(self, state) -> None:
        self._guard(f"{self.kind}SetFMUState", lambda: self.fmu.setFMUState(state))

    def free_state(self, state) -> None:
        self._guard(f"{self.kind}FreeFMUState", lambda: self.fmu.freeFMUState(state))

    def exit_initialization(self) -> None:
        self.enter_initialization()
        self._guard("exitInitializationMode", self.fmu.exitInitializationMode)

    @staticmethod
    def accessor(v: VarInfo, verb: str) -> str:
        """fmpy's method for the variable's type: FMI 2 has four (an Enumeration is an Integer)."""
        return verb + {"Real": "Real", "Integer": "Integer", "Boolean": "Boolean",
                       "String": "String"}[v.type]

    def set_values(self, values: dict) -> None:
        for name, value in values.items():
            v = self.variables[name]
            setter = getattr(self.fmu, self.accessor(v, "set"))
            self._guard(f"setting {name}", lambda: setter([v.vr], [value]))

    def set_input_derivatives(self, items: list[tuple[str, int, float]]) -> None:
        """(input, order, value) for fmi2SetRealInputDerivatives."""
        vrs = [self.variables[var].vr for var, _, _ in items]
        self._guard("setRealInputDerivatives", lambda: self.fmu.setRealInputDerivatives(
            vrs, [order for _, order, _ in items], [x for _, _, x in items]))

    def get_values(self, names: list[str]) -> list:
        out = []
        for name in names:
            x = _get_scalar(self, name, self.variables[name])
            out.append(x.decode("utf-8") if isinstance(x, bytes) else x)
        return out

    def do_step(self, t: float, h: float) -> None:
        try:
            self.fmu.doStep(t, h)
        except Exception as e:
            if getattr(e, "status", None) == 2 and self.asked_to_end(t):
                return
            raise UnitError(self._failure(f"doStep at t = {t:.9g} s", e)) from None

    def asked_to_end(self, t: float) -> bool:
        """After a doStep from *t* returned fmi2Discard: did the FMU ask to end the run
        (fmi2Terminated)? If so, :attr:`ended_at` is the time it reached."""
        try:
            if not self.fmu.getBooleanStatus(_FMI2_TERMINATED):
                return False
        except Exception:
            return False  # an FMU that cannot say it terminated did not ask to
        try:
            self.ended_at = float(self.fmu.getRealStatus(_FMI2_LAST_SUCCESSFUL_TIME))
        except Exception:
            self.ended_at = t  # no time reached beyond the step's start is known
        return True

    def enter_initialization(self) -> None:
        if not self._in_init:
            self._guard("enterInitializationMode", self.fmu.enterInitializationMode)
            self._in_init = True

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
        try:
            self.variables = fmu_variables(self.md)
        except UnitError as e:
            raise UnitError(f"unit {name}: {self.path}: {e}") from None
        # (fmpy reads FMI 3's canGetAndSetFMUState into the FMI 2 spelling)
        cs = self.md.coSimulation
        self.can_get_set_state = bool(getattr(cs, "canGetAndSetFMUstate", getattr(cs, "canGetAndSetFMUState", False)))
        # structural parameters that size an array: array sizes stay as declared
        self.dimension_parameters = {d.variable.name for v in self.md.modelVariables
                                     for d in v.dimensions if d.variable is not None}
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
        self._t0 = t0
        self._in_init = False

    def enter_initialization(self) -> None:
        if not self._in_init:
            self._guard("enterInitializationMode",
                        lambda: self.fmu.enterInitializationMode(startTime=self._t0))
            self._in_init = True

    def _on_log(self, env, status, category, message) -> None:
        msg = message.decode(errors="replace") if isinstance(message, bytes) else str(message)
        self.logs.append((STATUS[status] if 0 <= status < len(STATUS) else status, msg))

    _guard = FMU2Unit._guard
    _failure = FMU2Unit._failure
    get_state, set_state, free_state = FMU2Unit.get_state, FMU2Unit.set_state, FMU2Unit.free_state

    def exit_initialization(self) -> None:
        self.enter_initialization()
        self._guard("exitInitializationMode", self.fmu.exitInitializationMode)

    @staticmethod
    def accessor(v: VarInfo, verb: str) -> str:
        """fmpy's method for the variable's type (an FMI 3 Enumeration is an Int64)."""
        return verb + ("Int64" if v.fmi_type == "Enumeration" else v.fmi_type)

    def set_values(self, values: dict) -> None:
        arrays: dict[str, list] = {}
        for name, value in values.items():
            v = self.variables[name]
            if v.element is not None:
                # one element of an array: the array is set whole, its other elements as they are
                parent, k = v.element
                if parent not in arrays:
                    arrays[parent] = self._get_array(parent)
                arrays[parent][k] = value
            elif v.shape:
                arrays[name] = list(value)
            else:
                setter = getattr(self.fmu, self.accessor(v, "set"))
                self._guard(f"setting {name}", lambda: setter([v.vr], [value]))
        for parent, flat in arrays.items():
            v = self.variables[parent]
            setter = getattr(self.fmu, self.accessor(v, "set"))
            self._guard(f"setting {parent}", lambda: setter([v.vr], flat))

    def _get_array(self, name: str) -> list:
        v = self.variables[name]
        getter = getattr(self.fmu, self.accessor(v, "get"))
        return list(self._guard(f"reading {name}", lambda: getter([v.vr], math.prod(v.shape))))

    def get_values(self, names: list[str]) -> list:
        arrays: dict[str, list] = {}
        out = []
        for name in names:
            v = self.variables[name]
            if v.element is not None:
                parent, k = v.element
                if parent not in arrays:
                    arrays[parent] = self._get_array(parent)
                out.append(arrays[parent][k])
            elif v.shape:
                out.append(self._get_array(name))
            else:
                out.append(_get_scalar(self, name, v))
        return out

    def do_step(self, t: float, h: float) -> None:
        def step():
            return self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        _event, terminate, early, reached = self._guard(f"doStep at t = {t:.9g} s", step)
        if terminate:
            # the FMU asks to end the run: it has reached lastSuccessfulTime (t + h unless it
            # returned early)
            self.ended_at = float(reached) if early else t + h

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
    if p.is_dir():
        raise UnitError(f"unit {name}: {p} is a directory; expected an .fmu file")
    try:
        md = read_model_description(str(p))
    except Exception as e:
        raise UnitError(f"unit {name}: {p} is not a readable FMU ({e})") from None
    _check_binary(name, p, md)
    return FMU3Unit(name, p) if md.fmiVersion.startswith("3") else FMU2Unit(name, p)


def _check_binary(name: str, path: Path, md) -> None:
    """The archive holds a co-simulation binary for this machine (fmpy's own message is a
    traceback from the depths of loading)."""
    import zipfile

    import fmpy

    if md.coSimulation is None:
        return
    fmi3 = md.fmiVersion.startswith("3")
    folder = fmpy.platform_tuple if fmi3 else fmpy.platform
    ext = {"linux": ".so", "darwin": ".dylib", "windows": ".dll"}.get(fmpy.system, ".so")
    want = f"binaries/{folder}/{md.coSimulation.modelIdentifier}{ext}"
    try:
        with zipfile.ZipFile(path) as z:
            names = z.namelist()
    except (zipfile.BadZipFile, OSError):
        return   # fmpy read the description, so this is an unpacked FMU or similar: let it load
    if want not in names:
        have = sorted({n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") >= 2})
        raise UnitError(f"unit {name}: {path} has no binary for this machine ({want} missing; its binaries: "
                        f"{', '.join(have) or 'none'}): ask the supplier for a {folder} build or the sources")


def read_fmu_variables(path: str | Path) -> dict[str, VarInfo]:
    """The variables of the FMU file *path* (its model description only: nothing is loaded)."""
    from fmpy import read_model_description

    return fmu_variables(read_model_description(str(path)))
