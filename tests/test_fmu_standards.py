"""Standards conformance of the plant FMUs, for every model and both FMI versions.

These tests know nothing about the physics: they read the variable table, drive each FMU with a
scenario that makes its outputs move, and check what any FMU must satisfy — valid model
description, independent instances, FMU state save/restore/serialise, the same numbers through
another master (libcosim) and through the FMI 3 build, and a build chain whose cache key and
archive are right.
"""
from __future__ import annotations

import ctypes
import re
import shutil
import tempfile
import zipfile
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

from fmus import build
from fmus.build import BuildError, build_fmu, load_table, source_key

MODELS = ("turntable", "imu")
H = 0.005  # communication step [s]
N_STEPS = 200  # 1 s


# ----------------------------------------------------------------------------- helpers

def _require_model(model: str) -> None:
    """The model's C sources are written by other people; skip (not fail) while they are
    absent."""
    table = load_table(model)
    missing = [s for s in table.sources if not (build.HERE / model / s).exists()]
    if missing:
        pytest.skip(f"{model}: model sources {missing} do not exist yet")


@lru_cache(maxsize=None)
def _fmu(model: str, version: int) -> Path:
    return build_fmu(model, version)


def fmu(model: str, version: int) -> Path:
    _require_model(model)
    return _fmu(model, version)


def scenario(model: str, variant: int = 0) -> dict:
    """Start values (parameters and inputs) that make every part of the model work. *variant*
    changes parameters/seed/commands so that two variants give different outputs."""
    table = load_table(model)
    names = {v.name for v in table.variables}
    if model == "imu":
        s = {
            "gyro.bias.x": 1e-3, "gyro.bias.y": -2e-3, "gyro.sf.y": 3e-4, "gyro.mis.xy": 2e-4,
            "gyro.gsens.xz": 1e-5, "acc.bias.z": 0.02, "acc.sf.x": -4e-4, "acc.mis.zx": 1e-4,
            "acc.k2.z": 1e-4, "gyro.noise.arw": 2e-4, "gyro.noise.bi": 1e-5,
            "acc.noise.vrw": 1e-3, "acc.noise.bi": 1e-4, "seed": 12345 + 77 * variant,
            "gyro.output": 1, "acc.output": 1,
            "omega.x": 0.1, "omega.y": -0.2 + 0.05 * variant, "omega.z": 0.3,
            "f.x": 0.5, "f.y": -0.3, "f.z": 9.8 - 0.1 * variant,
        }
    elif model == "turntable":
        cmd = ((0.3, -0.2, 0.5), (-0.4, 0.25, 1.0))[variant % 2]
        s = {f"{a}.angle_cmd": c for a, c in zip(("outer", "middle", "inner"), cmd)}
        s.update({f"{a}.mode": 0 for a in ("outer", "middle", "inner")})
        s["base.tilt.x"] = 1e-4 * (1 + variant)
    else:  # a new model: its defaults only
        s = {}
    unknown = sorted(set(s) - names)
    assert not unknown, f"{model}: scenario names {unknown} are not in the variable table"
    return s


def real_outputs(md) -> list:
    return [v for v in md.modelVariables
            if v.causality == "output" and v.type in ("Real", "Float64")]


class Instance:
    """One FMU instance through fmpy, on an already extracted FMU (several instances of one
    extraction share one loaded binary, as in a real master)."""

    def __init__(self, unzipdir: str, md, name: str, start: dict, t0: float = 0.0):
        self.md = md
        self.fmi3 = md.fmiVersion.startswith("3")
        self.vars = {v.name: v for v in md.modelVariables}
        self.log: list[tuple[int, str]] = []
        cls = FMU3Slave if self.fmi3 else FMU2Slave
        self.fmu = cls(guid=md.guid, unzipDirectory=unzipdir,
                       modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        if self.fmi3:
            self.fmu.instantiate(logMessage=self._log3)
            self.fmu.enterInitializationMode(startTime=t0)
        else:
            self._callbacks = fmi2CallbackFunctions()  # kept alive with the instance
            self._callbacks.logger = fmi2CallbackLoggerTYPE(self._log2)
            self.fmu.instantiate(callbacks=self._callbacks)
            self.fmu.setupExperiment(startTime=t0)
            self.fmu.enterInitializationMode()
        self.set(start)
        self.fmu.exitInitializationMode()
        self.t = t0
        self.out_vrs = [v.valueReference for v in real_outputs(md)]

    def _log3(self, env, status, category, message):
        self.log.append((int(status), message.decode()))

    def _log2(self, env, instance_name, status, category, message):
        self.log.append((int(status), message.decode()))

    def set(self, values: dict) -> None:
        for name, value in values.items():
            v = self.vars[name]
            if v.type in ("Real", "Float64"):
                (self.fmu.setFloat64 if self.fmi3 else self.fmu.setReal)([v.valueReference],
                                                                         [float(value)])
            else:
                (self.fmu.setInt32 if self.fmi3 else self.fmu.setInteger)([v.valueReference],
                                                                         [int(value)])

    def outputs(self) -> np.ndarray:
        get = self.fmu.getFloat64 if self.fmi3 else self.fmu.getReal
        return np.array(get(self.out_vrs), dtype=float)

    def step(self, h: float = H) -> np.ndarray:
        self.fmu.doStep(self.t, h)
        self.t += h
        return self.outputs()

    def run(self, n: int) -> np.ndarray:
        return np.array([self.step() for _ in range(n)])

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


@pytest.fixture
def unzipped():
    """Extract an FMU into a temporary folder, removed afterwards: unzipped(path) -> (dir, md)."""
    dirs = []

    def go(path: Path):
        d = extract(str(path), unzipdir=tempfile.mkdtemp(prefix="calbench-std-"))
        dirs.append(d)
        return d, read_model_description(str(path))

    yield go
    for d in dirs:
        shutil.rmtree(d, ignore_errors=True)


def _moving(outs: np.ndarray) -> bool:
    """Do the outputs change over the run (is the scenario non-trivial)?"""
    return bool(np.any(np.ptp(outs, axis=0) > 0))


# ----------------------------------------------------------------------------- validation

@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_validate_fmu(model, version):
    problems = validate_fmu(str(fmu(model, version)))
    assert problems == []


@pytest.mark.parametrize("model", MODELS)
def test_fmi3_exports_every_function_of_the_standard(model, unzipped):
    """Every function declared in fmi3Functions.h is exported (importers resolve them all)."""
    header = (Path(build._fmi_headers()) / "fmi3Functions.h").read_text()
    declared = re.findall(r"^FMI3_Export\s+\w+TYPE\s+(fmi3\w+);", header, re.M)
    assert len(declared) > 60
    d, md = unzipped(fmu(model, 3))
    lib = ctypes.CDLL(str(Path(d) / "binaries" / build._platform_dir(3)
                          / (md.coSimulation.modelIdentifier + build._shared_suffix())))
    missing = [f for f in declared if not hasattr(lib, f)]
    assert missing == []


# ----------------------------------------------------------------------------- instances

@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_instances_are_independent(model, version, unzipped):
    d, md = unzipped(fmu(model, version))
    n = 60
    separate = []
    for variant in (0, 1):
        inst = Instance(d, md, f"alone{variant}", scenario(model, variant))
        separate.append(inst.run(n))
        inst.close()
    assert _moving(separate[0]), "scenario does not move the outputs"
    assert not np.array_equal(separate[0], separate[1]), "variants should differ"

    a = Instance(d, md, "a", scenario(model, 0))
    b = Instance(d, md, "b", scenario(model, 1))
    ra, rb = [], []
    for _ in range(n):  # interleaved on one loaded binary: a, b, a, b, ...
        ra.append(a.step())
        rb.append(b.step())
    a.close()
    b.close()
    np.testing.assert_array_equal(np.array(ra), separate[0])
    np.testing.assert_array_equal(np.array(rb), separate[1])


# ----------------------------------------------------------------------------- FMU state

@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_fmu_state_get_set(model, version, unzipped):
    d, md = unzipped(fmu(model, version))
    inst = Instance(d, md, "s", scenario(model))
    inst.run(40)  # t1 = 0.2 s
    t1 = inst.t
    state = inst.fmu.getFMUState()
    first = inst.run(60)  # to t2 = 0.5 s
    assert _moving(first)
    inst.fmu.setFMUState(state)
    inst.t = t1
    again = inst.run(60)
    np.testing.assert_array_equal(again, first)
    # restoring the same state twice works (the state object is not consumed)
    inst.fmu.setFMUState(state)
    inst.t = t1
    np.testing.assert_array_equal(inst.run(60), first)
    inst.fmu.freeFMUState(state)
    inst.close()


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_fmu_state_serialize_roundtrip(model, version, unzipped):
    d, md = unzipped(fmu(model, version))
    inst = Instance(d, md, "s", scenario(model))
    inst.run(40)
    t1 = inst.t
    state = inst.fmu.getFMUState()
    blob = inst.fmu.serializeFMUState(state)
    inst.fmu.freeFMUState(state)
    first = inst.run(60)

    deserialize = inst.fmu.deserializeFMUState if inst.fmi3 else inst.fmu.deSerializeFMUstate
    restored = deserialize(blob)
    inst.fmu.setFMUState(restored)
    inst.t = t1
    np.testing.assert_array_equal(inst.run(60), first)
    inst.fmu.freeFMUState(restored)

    # the serialised state carries everything: a fresh instance continues identically
    other = Instance(d, md, "other", scenario(model))
    deserialize = other.fmu.deserializeFMUState if other.fmi3 else other.fmu.deSerializeFMUstate
    st = deserialize(blob)
    other.fmu.setFMUState(st)
    other.fmu.freeFMUState(st)
    other.t = t1
    np.testing.assert_array_equal(other.run(60), first)
    other.close()
    inst.close()


# ----------------------------------------------------------------------------- other masters

def _fmpy_reference(model: str, unzipped, version: int = 2) -> tuple[list, np.ndarray]:
    d, md = unzipped(fmu(model, version))
    inst = Instance(d, md, "ref", scenario(model))
    # the same communication points as an integer-nanosecond master: t_k = k h
    outs = []
    for k in range(N_STEPS):
        inst.fmu.doStep(k * H, (k + 1) * H - k * H)
        outs.append(inst.outputs())
    inst.close()
    return [v.name for v in real_outputs(md)], np.array(outs)


@pytest.mark.parametrize("model", MODELS)
def test_libcosim_matches_fmpy(model, unzipped):
    from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    path = fmu(model, 2)
    names, ref = _fmpy_reference(model, unzipped)
    assert _moving(ref), "scenario does not move the outputs"

    log_output_level(CosimLogLevel.ERROR)
    ex = CosimExecution.from_step_size(int(round(H * 1e9)))
    slave = CosimLocalSlave(fmu_path=str(path), instance_name=model)
    idx = ex.add_local_slave(slave)
    assert idx >= 0
    lc_vars = {v.name.decode(): v for v in ex.slave_variables(idx)}
    md = read_model_description(str(path))
    # libcosim reads the same value references from the model description
    for v in md.modelVariables:
        assert lc_vars[v.name].reference == v.valueReference, v.name
    for name, value in scenario(model).items():
        v = lc_vars[name]
        if v.type == CosimVariableType.REAL.value:
            assert ex.real_initial_value(idx, v.reference, float(value)), name
        else:
            assert v.type == CosimVariableType.INTEGER.value, name
            assert ex.integer_initial_value(idx, v.reference, int(value)), name
    out_refs = [lc_vars[n].reference for n in names]
    assert all(lc_vars[n].causality == CosimVariableCausality.OUTPUT.value for n in names)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    got = []
    for _ in range(N_STEPS):
        assert ex.step(), ex.status()
        got.append(obs.last_real_values(idx, out_refs))
    assert ex.status().current_time == N_STEPS * int(round(H * 1e9))
    np.testing.assert_allclose(np.array(got), ref, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("model", MODELS)
def test_fmi3_build_matches_fmi2(model, unzipped):
    outs = {}
    for version in (2, 3):
        d, md = unzipped(fmu(model, version))
        inst = Instance(d, md, "v", scenario(model))
        outs[version] = ([v.name for v in real_outputs(md)], inst.run(N_STEPS))
        inst.close()
    assert outs[2][0] == outs[3][0]
    assert _moving(outs[2][1])
    np.testing.assert_array_equal(outs[3][1], outs[2][1])  # bit-identical


# ----------------------------------------------------------------------------- FMI 3 layer

@pytest.mark.parametrize("model", MODELS)
def test_fmi3_layer_behaviour(model, unzipped):
    d, md = unzipped(fmu(model, 3))
    table = load_table(model)

    # a wrong instantiation token is refused, with a message
    bad = FMU3Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=d,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bad")
    log = []
    with pytest.raises(Exception):
        bad.instantiate(logMessage=lambda env, st, cat, msg: log.append(msg.decode()))
    assert any("instantiationToken" in m for m in log)
    bad.freeLibrary()

    inst = Instance(d, md, "l3", scenario(model))
    lib, c = inst.fmu.dll, inst.fmu.component
    vr = (ctypes.c_uint32 * 1)()
    val = (ctypes.c_double * 1)()

    # doStep outputs
    ev, term, early, last = (ctypes.c_bool(True), ctypes.c_bool(True), ctypes.c_bool(True),
                             ctypes.c_double(-1.0))
    st = lib.fmi3DoStep(c, ctypes.c_double(0.0), ctypes.c_double(H), ctypes.c_bool(True),
                        ctypes.byref(ev), ctypes.byref(term), ctypes.byref(early),
                        ctypes.byref(last))
    assert st == 0 and not ev.value and not term.value and not early.value
    assert last.value == H
    inst.t = H
    # the independent variable is readable
    vr[0] = next(v.valueReference for v in md.modelVariables if v.causality == "independent")
    assert lib.fmi3GetFloat64(c, vr, ctypes.c_size_t(1), val, ctypes.c_size_t(1)) == 0
    assert val[0] == H
    # ... but not settable
    assert lib.fmi3SetFloat64(c, vr, ctypes.c_size_t(1), val, ctypes.c_size_t(1)) == 3
    # a step from the wrong time is refused, naming both times
    n_log = len(inst.log)
    assert lib.fmi3DoStep(c, ctypes.c_double(1.0), ctypes.c_double(H), ctypes.c_bool(True),
                          ctypes.byref(ev), ctypes.byref(term), ctypes.byref(early),
                          ctypes.byref(last)) == 3
    assert last.value == H
    assert "FMU is at t" in inst.log[-1][1] and len(inst.log) > n_log
    # a fixed parameter cannot be set after initialisation: the message names it
    fixed = next(v for v in table.variables
                 if v.causality == "parameter" and v.variability == "fixed" and v.type == "Real")
    vr[0] = table.value_reference(fixed.name)
    assert lib.fmi3SetFloat64(c, vr, ctypes.c_size_t(1), val, ctypes.c_size_t(1)) == 3
    assert fixed.name in inst.log[-1][1]
    # an output cannot be set at all
    out = real_outputs(md)[0]
    vr[0] = out.valueReference
    assert lib.fmi3SetFloat64(c, vr, ctypes.c_size_t(1), val, ctypes.c_size_t(1)) == 3
    assert out.name in inst.log[-1][1]
    # nValues must match for scalars
    assert lib.fmi3GetFloat64(c, vr, ctypes.c_size_t(1), val, ctypes.c_size_t(2)) == 3
    # the functions of what this FMU does not offer exist and say so
    for fn in ("fmi3EnterEventMode", "fmi3EnterConfigurationMode", "fmi3EvaluateDiscreteStates",
               "fmi3EnterStepMode", "fmi3EnterContinuousTimeMode"):
        n_log = len(inst.log)
        assert getattr(lib, fn)(c) == 3, fn
        assert len(inst.log) == n_log + 1 and inst.log[-1][0] == 3, fn
    assert lib.fmi3GetFloat32(c, vr, ctypes.c_size_t(1), (ctypes.c_float * 1)(),
                              ctypes.c_size_t(1)) == 3
    # the instance still works after all these refused calls
    inst.step()
    # after terminate, no more steps; reset brings it back to Instantiated
    assert lib.fmi3Terminate(c) == 0
    assert lib.fmi3DoStep(c, ctypes.c_double(inst.t), ctypes.c_double(H), ctypes.c_bool(True),
                          ctypes.byref(ev), ctypes.byref(term), ctypes.byref(early),
                          ctypes.byref(last)) == 3
    assert lib.fmi3Reset(c) == 0
    assert lib.fmi3EnterInitializationMode(c, ctypes.c_bool(False), ctypes.c_double(0.0),
                                           ctypes.c_double(0.0), ctypes.c_bool(False),
                                           ctypes.c_double(0.0)) == 0
    assert lib.fmi3ExitInitializationMode(c) == 0
    inst.t = 0.0
    inst.step()
    inst.fmu.freeInstance()


# ----------------------------------------------------------------------------- state machine

def _raw(inst: Instance, name: str, *args) -> int:
    """Call the C function fmi2<name> or fmi3<name> on the instance; returns its status."""
    return getattr(inst.fmu.dll, ("fmi3" if inst.fmi3 else "fmi2") + name)(inst.fmu.component,
                                                                          *args)


def _raw_do_step(inst: Instance, t: float) -> int:
    if not inst.fmi3:
        return _raw(inst, "DoStep", ctypes.c_double(t), ctypes.c_double(H), 1)
    flags, last = [ctypes.c_bool() for _ in range(3)], ctypes.c_double()
    return _raw(inst, "DoStep", ctypes.c_double(t), ctypes.c_double(H), ctypes.c_bool(True),
                *map(ctypes.byref, flags), ctypes.byref(last))


def _raw_real(inst: Instance, vr: int, value: float | None = None) -> tuple[int, float]:
    """Get (value None) or set one Real / Float64 variable; returns (status, value)."""
    vrs, val = (ctypes.c_uint32 * 1)(vr), (ctypes.c_double * 1)(value or 0.0)
    name = ("Get" if value is None else "Set") + ("Float64" if inst.fmi3 else "Real")
    n_values = (ctypes.c_size_t(1),) if inst.fmi3 else ()
    return _raw(inst, name, vrs, ctypes.c_size_t(1), val, *n_values), val[0]


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_state_machine_refuses_calls_out_of_mode(model, version, unzipped):
    """Both layers check, on entry to every function, the modes it may be called in. After
    terminate no step and no set is accepted (FMI 2 used to step on), the outputs stay readable;
    after reset nothing can be read or stepped until the instance is initialised again."""
    d, md = unzipped(fmu(model, version))
    inst = Instance(d, md, "modes", scenario(model))
    inp = next(v for v in md.modelVariables
               if v.causality == "input" and v.type in ("Real", "Float64"))
    out = real_outputs(md)[0].valueReference
    inst.step()
    assert _raw(inst, "Terminate") == 0
    n_log = len(inst.log)
    assert _raw_do_step(inst, inst.t) == 3
    assert len(inst.log) == n_log + 1 and "DoStep is not allowed in Terminated" in inst.log[-1][1]
    assert _raw_real(inst, inp.valueReference, 0.1)[0] == 3
    st, value = _raw_real(inst, out)
    assert st == 0 and np.isfinite(value)
    assert _raw(inst, "Terminate") == 0  # a second terminate is harmless

    assert _raw(inst, "Reset") == 0
    assert _raw_do_step(inst, 0.0) == 3
    assert _raw_real(inst, out)[0] == 3  # no outputs before initialisation has begun
    assert _raw(inst, "ExitInitializationMode") == 3  # not entered
    assert "not allowed in Instantiated" in inst.log[-1][1]
    if inst.fmi3:
        inst.fmu.enterInitializationMode(startTime=0.0)
    else:
        inst.fmu.setupExperiment(startTime=0.0)
        inst.fmu.enterInitializationMode()
        assert _raw(inst, "SetupExperiment", 0, 0.0, 0.0, 0, 0.0) == 3  # too late
    assert _raw(inst, "EnterInitializationMode", *((0, 0.0, 0.0, 0, 0.0) if inst.fmi3 else ())) == 3
    inst.set(scenario(model))
    inst.fmu.exitInitializationMode()
    inst.t = 0.0
    assert np.all(np.isfinite(inst.run(3)))
    inst.close()


# ----------------------------------------------------------------------------- build chain

@pytest.fixture
def fmus_copy(tmp_path, monkeypatch):
    """A private copy of the fmus package's sources that the build chain reads instead of the
    real ones (build.HERE/COMMON redirected), and a private cache."""
    root = tmp_path / "fmus"
    shutil.copytree(build.HERE, root, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(build, "HERE", root)
    monkeypatch.setattr(build, "COMMON", root / "common")
    monkeypatch.setenv("CALBENCH_CACHE", str(tmp_path / "cache"))
    return root


def test_source_key_changes_with_every_input(fmus_copy):
    model = "imu"  # the table import is the only model-specific part; any model would do
    base = source_key(model, 2)
    assert source_key(model, 2) == base  # deterministic
    assert source_key(model, 3) != base
    inputs = ([fmus_copy / "modeldef.py", fmus_copy / "build.py"]
              + sorted((fmus_copy / "common").glob("*.[ch]"))
              + sorted(p for p in (fmus_copy / model).iterdir() if p.suffix in (".c", ".h", ".py")))
    assert any(p.name == "fmi3_layer.c" for p in inputs)
    assert any(p.parent.name == model and p.suffix == ".py" for p in inputs)
    keys = {base}
    for p in inputs:
        original = p.read_bytes()
        p.write_bytes(original + (b"\n# changed\n" if p.suffix == ".py" else b"\n/* changed */\n"))
        k = source_key(model, 2)
        assert k != base, f"changing {p.name} does not change the cache key"
        keys.add(k)
        p.write_bytes(original)
        assert source_key(model, 2) == base
    assert len(keys) == len(inputs) + 1
    # a new source file in the model's folder counts too
    extra = fmus_copy / model / "extra.h"
    extra.write_text("/* new */\n")
    assert source_key(model, 2) != base


def test_compile_error_surfaces_as_build_error(fmus_copy):
    _require_model("imu")
    layer = fmus_copy / "common" / "fmi2_layer.c"
    layer.write_text(layer.read_text() + "\nint calbench_broken(void) { return no_such_symbol_xyz; }\n")
    with pytest.raises(BuildError) as err:
        build_fmu("imu", 2)
    msg = str(err.value)
    assert "no_such_symbol_xyz" in msg and "error" in msg
    assert "fmi2_layer.c" in msg
    # a warning is an error too (-Werror)
    layer.write_text(layer.read_text().replace("return no_such_symbol_xyz;",
                                               "int unused_xyz; return 0;"))
    with pytest.raises(BuildError) as err:
        build_fmu("imu", 2)
    assert "unused_xyz" in str(err.value)
    # so is a function declared but defined in none of the files (else found only when loaded)
    layer.write_text(layer.read_text().replace("int unused_xyz; return 0;",
                                               "return calbench_missing_xyz();")
                     .replace("int calbench_broken(void)",
                              "int calbench_missing_xyz(void);\nint calbench_broken(void)"))
    with pytest.raises(BuildError) as err:
        build_fmu("imu", 2)
    assert "calbench_missing_xyz" in str(err.value)
    assert not list((fmus_copy.parent / "cache" / "fmus").glob("*.fmu"))


def test_fmu_path_is_cached(fmus_copy):
    _require_model("imu")
    p1 = build.fmu_path("imu", 2)
    mtime = p1.stat().st_mtime_ns
    assert build.fmu_path("imu", 2) == p1 and p1.stat().st_mtime_ns == mtime
    c = fmus_copy / "common" / "model_support.c"
    c.write_text(c.read_text() + "\n/* touched */\n")
    p2 = build.fmu_path("imu", 2)
    assert p2 != p1 and p2.exists()
    # a changed source gives a new instantiation token, so a stale binary cannot be mixed up
    assert read_model_description(str(p2)).guid != read_model_description(str(p1)).guid


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_fmu_archive_contents(model, version):
    path = fmu(model, version)
    table = load_table(model)
    with zipfile.ZipFile(path) as z:
        names = set(z.namelist())
    plat = build._platform_dir(version)
    expected = {"modelDescription.xml",
                f"binaries/{plat}/{table.identifier}{build._shared_suffix()}",
                "sources/config.h", f"sources/fmi{version}_layer.c", "sources/fmi_common.c",
                "sources/fmi_common.h", "sources/model_support.c",
                "sources/model_instance.h", "sources/model_state.h",
                "sources/buildDescription.xml"}
    expected |= {f"sources/{s}" for s in table.sources}
    expected |= {f"sources/{n}" for n in build.LAYER_SOURCES[version] + build.COMMON_SOURCES}
    expected |= {f"sources/{h.name}" for h in [*build.COMMON.glob("*.h"),
                                               *(build.HERE / model).glob("*.h")]}
    assert expected <= names, sorted(expected - names)
    assert not any("\\" in n for n in names)


_DEFINE = re.compile(r"^#define\s+(VR_\w+)\s+(\d+)\s+/\*\s+(.+?) \[", re.M)


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_config_h_agrees_with_model_description(model, version):
    path = fmu(model, version)
    md = read_model_description(str(path))
    with zipfile.ZipFile(path) as z:
        header = z.read("sources/config.h").decode()
    defined = {m.group(3): (m.group(1), int(m.group(2))) for m in _DEFINE.finditer(header)}
    xml = {v.name: v for v in md.modelVariables if v.causality != "independent"}
    assert set(defined) == set(xml)
    for name, (c_name, vr) in defined.items():
        assert xml[name].valueReference == vr, name
        assert c_name == "VR_" + re.sub(r"[^A-Za-z0-9]", "_", name)
    # arrays indexed by value reference hold the variables in that order
    n_real = int(re.search(r"#define N_REAL (\d+)", header).group(1))
    base = int(re.search(r"#define INTEGER_VR_BASE (\d+)", header).group(1))
    real_names = re.findall(r'"([^"]*)"', re.search(r"REAL_NAME\[N_REAL\] = \{(.*)\};",
                                                    header).group(1))
    assert len(real_names) == n_real == base
    assert all(xml[n].valueReference == j for j, n in enumerate(real_names))
    assert all(xml[n].type in ("Real", "Float64") for n in real_names)
    token = re.search(r'#define INSTANTIATION_TOKEN "([^"]+)"', header).group(1)
    assert token == md.guid
    if version == 3:
        time_vr = int(re.search(r"#define TIME_VR (\d+)", header).group(1))
        indep = [v for v in md.modelVariables if v.causality == "independent"]
        assert [v.valueReference for v in indep] == [time_vr]


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("model", MODELS)
def test_bad_parameter_is_named_and_reset_recovers(model, version, unzipped):
    """The contract: model_initialize checks every parameter and names the bad one. A NaN is
    bad for any parameter. After the error, reset brings the instance back to life."""
    d, md = unzipped(fmu(model, version))
    table = load_table(model)
    param = next(v for v in table.reals if v.causality == "parameter")
    inst = Instance.__new__(Instance)  # instantiate by hand: initialisation must fail
    inst.md, inst.fmi3, inst.log = md, version == 3, []
    inst.vars = {v.name: v for v in md.modelVariables}
    f = inst.fmu = (FMU3Slave if inst.fmi3 else FMU2Slave)(
        guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="bad")
    if inst.fmi3:
        f.instantiate(logMessage=inst._log3)
    else:
        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(
            lambda env, name, st, cat, msg: inst.log.append((int(st), msg.decode())))
        f.instantiate(callbacks=cb)
        f.setupExperiment(startTime=0.0)

    def enter():
        if inst.fmi3:
            f.enterInitializationMode(startTime=0.0)
        else:
            f.enterInitializationMode()

    enter()
    inst.set(dict(scenario(model), **{param.name: float("nan")}))
    with pytest.raises(Exception):
        f.exitInitializationMode()
    assert any(st >= 3 and param.name in msg for st, msg in inst.log), inst.log
    f.reset()
    if not inst.fmi3:
        f.setupExperiment(startTime=0.0)
    enter()
    inst.set(scenario(model))
    f.exitInitializationMode()
    inst.t, inst.out_vrs = 0.0, [v.valueReference for v in real_outputs(md)]
    assert np.all(np.isfinite(inst.run(5)))
    inst.close()
