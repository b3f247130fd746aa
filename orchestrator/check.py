"""``check-fmu``: everything a user wants to know before plugging an FMU into a role —
static validation (fmpy), what the orchestrator can run of it, conformance to the role (with a
mapping), and a dynamic smoke test (instantiate, set each input and tunable start value, initialise,
one step, read every variable, FMU state save/restore, terminate).

The smoke test talks to the FMU through fmpy directly, calling each variable's own type's
function (``fmi3GetFloat32`` for a Float32, ``fmi3GetInt8`` for an Int8, as many values as an
array's dimensions hold): a check that set a Float32 through ``fmi3SetFloat64`` would refuse a
valid FMU for the checker's own mistake."""
from __future__ import annotations

import ctypes
import math
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator.errors import SystemError_, UnitError
from orchestrator.fmu_units import load_fmu_unit
from orchestrator.roles import RoleCheck, check_unit, get_role

_FLOATS = ("Real", "Float32", "Float64")
# FMI 3 enumerations are read and written through the Int64 functions (FMI 3.0, 2.4.7.4)
_FMI3_API = {"Enumeration": "Int64"}
_FMI2_API = {"Enumeration": "Integer"}


@dataclass
class FmuVerdict:
    path: str
    role: str | None
    validation: list[str] = field(default_factory=list)
    role_check: RoleCheck | None = None
    smoke: list[str] = field(default_factory=list)  # problems found by the dynamic test
    smoke_notes: list[str] = field(default_factory=list)
    cannot_run: str | None = None  # why the orchestrator cannot run this (valid) FMU
    step: float | None = None  # the smoke test's communication step [s]
    step_source: str = ""

    @property
    def ok(self) -> bool:
        return (not self.validation and self.cannot_run is None
                and (self.role_check is None or self.role_check.ok) and not self.smoke)

    def report(self) -> str:
        lines = [f"FMU {self.path}"]
        lines.append("static validation: " + ("no problem" if not self.validation else f"{len(self.validation)} problem(s)"))
        lines += [f"  - {p}" for p in self.validation]
        if self.cannot_run is not None:
            lines.append(f"cannot run in the orchestrator: {self.cannot_run}")
            lines.append("verdict: REFUSED")
            return "\n".join(lines)
        if self.role_check is not None:
            lines.append(self.role_check.report())
        lines.append("dynamic smoke test: " + ("passed" if not self.smoke else "FAILED")
                     + (f" (step {self.step:g} s: {self.step_source})" if self.step is not None else ""))
        lines += [f"  - {p}" for p in self.smoke] + [f"  note: {n}" for n in self.smoke_notes]
        lines.append("verdict: " + ("ACCEPTED" if self.ok else "REFUSED"))
        return "\n".join(lines)


def unsupported_reason(md) -> str | None:
    """Why the orchestrator cannot run an FMU with model description *md* (fmpy's), or None.
    Only what it truly cannot do: it is a co-simulation master for FMI 2.0 and 3.0."""
    version = str(md.fmiVersion)
    if not version.startswith(("2", "3")):
        return f"FMI {version}: the orchestrator runs FMI 2.0 and 3.0 FMUs"
    if md.coSimulation is not None:
        return None
    offered = [k for k, iface in (("model exchange", md.modelExchange),
                                  ("scheduled execution", getattr(md, "scheduledExecution", None)))
               if iface is not None]
    if not offered:
        return "the model description declares no interface"
    why = {"model exchange": "a model-exchange FMU needs the master's own ODE solver and event "
                             "handling, which this co-simulation master does not have",
           "scheduled execution": "scheduled execution needs a scheduler activating the model "
                                  "partitions by their clocks; the orchestrator steps "
                                  "co-simulation FMUs on a fixed grid"}
    return (f"the FMU offers {' and '.join(offered)} only, no co-simulation interface: "
            + "; ".join(why[k] for k in offered))


# the smoke test's step when neither the user nor the FMU's DefaultExperiment gives one [s]
SMOKE_STEP = 0.005


def default_step(md) -> tuple[float, str]:
    """The smoke test's step [s] for model description *md* and where it comes from: the FMU's
    DefaultExperiment stepSize (its maker's choice: a model may refuse other steps), else
    :data:`SMOKE_STEP`."""
    exp = getattr(md, "defaultExperiment", None)
    try:
        h = float(exp.stepSize) if exp is not None and exp.stepSize is not None else None
    except (TypeError, ValueError):
        h = None
    if h is not None and math.isfinite(h) and h > 0:
        return h, "the FMU's DefaultExperiment"
    return SMOKE_STEP, "calbench's default: the FMU states no DefaultExperiment step"


def check_fmu(path: str | Path, role: str | None = None, mapping: dict | None = None,
              role_options: dict | None = None, step: float | None = None) -> FmuVerdict:
    """Validate, check against *role*, smoke-test at *step* [s] (None: the FMU's DefaultExperiment
    step, else :data:`SMOKE_STEP`)."""
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    verdict = FmuVerdict(str(path), role)
    try:
        verdict.validation = [str(p) for p in validate_fmu(str(path))]
    except Exception as e:
        verdict.validation = [f"cannot be validated: {e}"]
    try:
        md = read_model_description(str(path))
    except Exception as e:
        verdict.smoke.append(f"{path} is not a readable FMU ({e})")
        return verdict
    verdict.cannot_run = unsupported_reason(md)
    if verdict.cannot_run is not None:
        return verdict
    if role:
        try:
            role_def = get_role(role, **(role_options or {}))
        except (KeyError, TypeError, ValueError) as e:
            raise SystemError_(f"role {role!r} with options {role_options or {}}: {e}") from None
        try:
            unit = load_fmu_unit("candidate", path)
        except UnitError as e:
            verdict.smoke.append(str(e))
            return verdict
        verdict.role_check = check_unit(unit, role_def, mapping)
    verdict.step, verdict.step_source = (step, "given") if step is not None else default_step(md)
    _smoke(Path(path), md, verdict.step, verdict)
    return verdict


def _count(md, v) -> int:
    """How many values an (array) variable holds: the product of its dimensions, each a fixed
    size or the start value of the structural parameter it names."""
    n = 1
    by_vr = {w.valueReference: w for w in md.modelVariables}
    for d in getattr(v, "dimensions", None) or []:
        if d.start is not None:
            n *= int(d.start)
        else:
            n *= int(by_vr[d.valueReference].start)
    return n


def _start_values(v, n: int, api: str) -> list | None:
    """The declared start of *v* as *n* values of its own type, or None if it declares none."""
    if v.start is None:
        return None
    raw = v.start
    if isinstance(raw, str) and api != "String":
        parts = raw.split()
    elif isinstance(raw, (list, tuple)):
        parts = list(raw)
    else:
        parts = [raw]
    if api in _FLOATS:
        vals = [float(x) for x in parts]
    elif api == "Boolean":
        vals = [x if isinstance(x, bool) else str(x).lower() in ("true", "1") for x in parts]
    elif api == "String":
        vals = [str(raw)] * n
    elif api == "Binary":
        vals = [bytes.fromhex(x) if isinstance(x, str) else bytes(x) for x in parts]
    else:
        vals = [int(x) for x in parts]
    if len(vals) == 1 and n > 1:
        vals = vals * n
    return vals if len(vals) == n else None


def _smoke(path: Path, md, step: float, verdict: FmuVerdict) -> None:
    from fmpy import extract

    fmi3 = str(md.fmiVersion).startswith("3")
    skip = {"independent"} | ({"structuralParameter"} if fmi3 else set())
    variables = [v for v in md.modelVariables if v.causality not in skip and v.type != "Clock"]
    api_of = (lambda v: _FMI3_API.get(v.type, v.type)) if fmi3 else (lambda v: _FMI2_API.get(v.type, v.type))
    workdir = tempfile.mkdtemp(prefix="calbench-check-")
    fmu = None
    logs: list[str] = []
    try:
        unzipped = extract(str(path), unzipdir=workdir)
        fmu = _instantiate(md, unzipped, fmi3, logs)
        settable = [v for v in variables if v.causality in ("input", "parameter")
                    and v.variability != "constant" and v.initial != "calculated"]
        for v in settable:
            api = api_of(v)
            vals = _start_values(v, _count(md, v), api)
            if vals is not None:
                getattr(fmu, "set" + api)([v.valueReference], vals)
        fmu.exitInitializationMode()
        fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=step)
        first = _read_all(fmu, md, variables, api_of)
        bad = [v.name for v in variables if v.causality == "output" and api_of(v) in _FLOATS
               and not all(math.isfinite(x) for x in first[v.name])]
        if bad:
            verdict.smoke.append(f"non-finite outputs after one step: {', '.join(bad)}")
        types = sorted({v.type for v in variables})
        verdict.smoke_notes.append(f"set and read {len(variables)} variables through their own "
                                   f"types' functions ({', '.join(types)})")
        _state_roundtrip(fmu, md, variables, api_of, step, fmi3, verdict)
        verdict.smoke_notes.append(f"instantiate, initialise, step of {step:g} s, terminate: OK")
    except Exception as e:  # a vendor FMU may fail in ways fmpy reports loosely
        tail = "; ".join(logs[-3:])
        verdict.smoke.append(f"{e}" + (f" (FMU log: {tail})" if tail else ""))
    finally:
        if fmu is not None:
            for call in (fmu.terminate, fmu.freeInstance):
                try:
                    call()
                except Exception:
                    pass
        shutil.rmtree(workdir, ignore_errors=True)


def _instantiate(md, unzipped: str, fmi3: bool, logs: list[str]):
    """An instance in initialisation mode whose log messages go to *logs* (not to stdout, where
    fmpy's default logger prints them), so a failure can be reported with the FMU's own words."""
    cs = md.coSimulation

    def text(message) -> str:
        return message.decode(errors="replace") if isinstance(message, bytes) else str(message)

    if fmi3:
        from fmpy.fmi3 import FMU3Slave

        fmu = FMU3Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=cs.modelIdentifier,
                        instanceName="candidate")
        fmu.instantiate(loggingOn=True, logMessage=lambda env, status, category, message:
                        logs.append(text(message)))
        fmu.enterInitializationMode(startTime=0.0)
    else:
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=cs.modelIdentifier,
                        instanceName="candidate")
        libc = ctypes.CDLL(None)
        libc.calloc.restype = ctypes.c_void_p
        libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
        libc.free.argtypes = [ctypes.c_void_p]
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(lambda env, instance, status, category, message:
                                           logs.append(text(message)))
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(libc.calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(libc.free)
        fmu._calbench_callbacks = cb  # ctypes callbacks must outlive the instance
        fmu.instantiate(callbacks=cb, loggingOn=True)
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    return fmu


def _read_all(fmu, md, variables, api_of) -> dict[str, list]:
    out = {}
    fmi3 = str(md.fmiVersion).startswith("3")
    for v in variables:
        getter = getattr(fmu, "get" + api_of(v))
        n = _count(md, v)
        out[v.name] = list(getter([v.valueReference], n) if fmi3 else getter([v.valueReference]))
    return out


def _state_roundtrip(fmu, md, variables, api_of, step, fmi3, verdict) -> None:
    cs = md.coSimulation
    if not (getattr(cs, "canGetAndSetFMUstate", False) or getattr(cs, "canGetAndSetFMUState", False)):
        verdict.smoke_notes.append("FMU declares no get/set FMU state support")
        return
    get, put, free = ((fmu.getFMUState, fmu.setFMUState, fmu.freeFMUState) if fmi3 else
                      (fmu.getFMUstate, fmu.setFMUstate, fmu.freeFMUstate))
    outputs = [v for v in variables if v.causality == "output"]
    state = get()
    fmu.doStep(currentCommunicationPoint=step, communicationStepSize=step)
    a = _read_all(fmu, md, outputs, api_of)
    put(state)
    fmu.doStep(currentCommunicationPoint=step, communicationStepSize=step)
    b = _read_all(fmu, md, outputs, api_of)
    free(state)
    diff = [n for n in a if a[n] != b[n]]
    if diff:
        verdict.smoke.append("FMU state restore does not reproduce the step: " + ", ".join(diff[:5]))
    else:
        verdict.smoke_notes.append("FMU state save/restore reproduces a step bit for bit")
