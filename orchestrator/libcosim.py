"""Run a :class:`~orchestrator.system.System` in libcosim (through libcosimpy), the independent
co-simulation engine the orchestrator is checked against.

What libcosim computes (libcosim ``fixed_step_algorithm``, the algorithm behind
``cosim_execution_create``; read from ``src/cosim/algorithm/fixed_step_algorithm.cpp`` and
``src/cosim/slave_simulator.cpp``):

* Initialisation: every slave gets its initial values, ``setupExperiment`` and
  ``enterInitializationMode``; then N rounds (N = number of slaves) of "set the inputs received
  so far, read the outputs" for every slave, each round followed by a transfer along all
  connections; then ``exitInitializationMode`` and one more transfer. For a feed-forward system
  this leaves each input equal to its source's output after initialisation, which is what the
  orchestrator's initial exchange (in stepping order) gives too.
* Each communication step k (t_k = k h, integer nanoseconds): *all* slaves first set the inputs
  they were last given, call ``doStep(t_k, h)`` and read their outputs (in parallel on a thread
  pool); only after every slave has finished are the outputs transferred along the connections.
  A unit therefore steps over [t_k, t_k+1] with the outputs its sources had at t_k: this is
  exactly the orchestrator's ``algorithm = "jacobi"`` (native span loop: set all inputs from the
  slots, step all, then write all outputs to the slots). libcosim has no Gauss–Seidel mode.
* Communication points are passed as doubles from integer nanoseconds: ``doStep(k*h_ns/1e9,
  (k+1)*h_ns/1e9 - k*h_ns/1e9)``. The orchestrator passes ``start + k*h`` and ``h``; these may
  differ in the last bit. An FMU whose result depends on such last-bit differences would not
  compare bit-identically (the project's FMUs do not: their internal step is derived from the
  step size by rounding).
* libcosim transfers values unchanged (no unit conversion, no input derivatives), and the C API
  that libcosimpy wraps has no step-size hint per slave (multi-rate decimation), so systems that
  need any of these are refused here with a message saying which.

Only FMI 2.0 FMU units can run here; Python components and FMI 3.0 units are refused.
"""
from __future__ import annotations

import ctypes
import time as _time

import numpy as np

from orchestrator.errors import LibcosimError, LibcosimUnsupported
from orchestrator.fmu_units import FMU2Unit
from orchestrator.master import Simulation
from orchestrator.record_select import record_endpoints
from orchestrator.recording import Recording
from orchestrator.system import System

_TYPES = {"Real": 0, "Integer": 1, "String": 2, "Boolean": 3}  # CosimVariableType values


def _conversion(c) -> tuple[float, float]:
    """(factor, offset) that turns the source's own value into the target's own value."""
    f = c.source.factor / c.target.factor
    o = (c.source.offset - c.target.offset) / c.target.factor
    return f, o


def check_supported(system: System, sim: Simulation | None = None) -> Simulation:
    """Load the system (roles, bindings, connections as the orchestrator resolves them) and
    refuse, with every reason at once, what libcosim cannot run. Returns the loaded Simulation."""
    if sim is None:
        sim = Simulation(system)
        sim.load()
    problems = []
    for g in sim.loop_groups:
        problems.append(f"the algebraic loop of {g.units} is solved by iteration at every step; libcosim's fixed-step "
                        "algorithm runs it with a one-step delay")
    for spec in system.units:
        u = sim.units[spec.name]
        if not isinstance(u, FMU2Unit):
            kind = {"python": "a Python component", "fmi3": "an FMI 3.0 FMU"}.get(u.kind, u.kind)
            problems.append(f"unit {spec.name} is {kind}; libcosim runs FMI 2.0 FMUs only")
        if spec.step_multiple != 1:
            problems.append(f"unit {spec.name}: step_multiple = {spec.step_multiple}; libcosimpy's "
                            "API has no per-slave step size (decimation), only 1 is supported")
    for c in sim.connections:
        name = f"{c.source.unit}.{c.source.name} -> {c.target.unit}.{c.target.name}"
        if c.derivative_order:
            problems.append(f"connection {name}: input derivatives (order {c.derivative_order}) "
                            "cannot be passed by libcosim")
            continue
        f, o = _conversion(c)
        if f != 1.0 or o != 0.0:
            problems.append(f"connection {name} ({c.source.var} -> {c.target.var}) needs the unit "
                            f"conversion target = {f:.17g} * source + {o:.17g}; libcosim "
                            "transfers values unconverted")
    problems += _libcosimpy_bugs(system, sim)
    h_ns = round(system.step * 1e9)
    if h_ns <= 0 or abs(h_ns * 1e-9 - system.step) > 1e-12 * system.step:
        problems.append(f"system.step = {system.step} s is not a whole number of nanoseconds")
    if system.start != 0.0:
        problems.append(f"system.start = {system.start}: libcosimpy starts executions at t = 0")
    if problems:
        raise LibcosimUnsupported(
            f"{system.source or system.name}: cannot run in libcosim:\n  " + "\n  ".join(problems))
    return sim


def _libcosimpy_version() -> tuple[int, ...] | None:
    """The installed libcosimpy's version (from its metadata, without importing it), or None."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return tuple(int(x) for x in version("libcosimpy").split(".")[:3] if x.isdigit())
    except (PackageNotFoundError, ValueError):
        return None


def _libcosimpy_bugs(system: System, sim: Simulation) -> list[str]:
    """What libcosimpy 0.0.6 (and earlier) fails on with a traceback of its own, named before
    it is called: ``connect_integer_variables`` calls a method the class never defines (it is
    spelled ``__connect_int_variables``), and an FMI 2 Enumeration is an Integer to libcosim's
    C API but not to its initial-value setter, which libcosimpy offers only for Real, Integer,
    Boolean and String. Both checks are kept while the installed version is 0.0.6 or older (or
    unknown)."""
    installed = _libcosimpy_version()
    if installed is not None and installed > (0, 0, 6):
        return []
    out = []
    for c in sim.connections:
        types = {sim.units[e.unit].variables[e.var].type for e in (c.source, c.target)}
        if "Integer" in types:
            out.append(f"connection {c.source.unit}.{c.source.name} -> {c.target.unit}.{c.target.name} "
                       "is an Integer connection, which libcosimpy 0.0.6 cannot make "
                       "(its connect_integer_variables calls a method it does not define)")
    for spec in system.units:
        u = sim.units[spec.name]
        md = getattr(u, "md", None)
        if md is None:
            continue
        raw = {v.name: v.type for v in md.modelVariables}
        for var in sim._parameters(spec):
            if raw.get(var) == "Enumeration":
                out.append(f"units.{spec.name}.parameters: {var} is an FMI 2 Enumeration; libcosimpy "
                           "0.0.6 has no initial-value setter for enumerations")
    return out


def _observed(sim: Simulation) -> list[tuple[str, str, str, float, float]]:
    """Recorded signals as (recorded name, unit, own variable, factor, offset), resolved like
    :meth:`Simulation.run`: a connected input is recorded as the output that drives it."""
    out = []
    for pattern in sim.system.record:
        unit = pattern.partition(".")[0]
        if unit not in sim.units:
            raise LibcosimUnsupported(f"record.signals: {pattern!r}: no unit {unit!r}")
    # the same selection as the master's (whole units, patterns), so both engines record alike
    for unit, e in record_endpoints(sim.units, sim.bindings, sim.system.record):
        src = None
        if sim.units[unit].variables[e.var].causality == "input":
            src = next((c.source for c in sim.connections if c.target.unit == unit
                        and c.target.var == e.var and c.derivative_order == 0), None)
        if src is not None:
            out.append((f"{unit}.{e.name}", src.unit, src.var, src.factor, src.offset))
        else:
            out.append((f"{unit}.{e.name}", unit, e.var, e.factor, e.offset))
    return out


def _sample_reader():
    from libcosimpy._internal import libcosimc

    lib = libcosimc()
    fns = {}
    for kind, ctype, cname in (("Real", ctypes.c_double, "cosim_observer_slave_get_real_samples"),
                               ("Integer", ctypes.c_int, "cosim_observer_slave_get_integer_samples")):
        fn = getattr(lib, cname)
        fn.restype = ctypes.c_int64
        fn.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint32, ctypes.c_int64, ctypes.c_size_t,
                       ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        fns[kind] = (fn, ctype)
    return fns


def run_libcosim(system: System, chunk: int = 4096) -> Recording:
    """Run *system* in libcosim and return a :class:`Recording` with the same signals, time rows
    and SI values as :meth:`Simulation.run` would. Raises :class:`LibcosimUnsupported` before
    anything runs when the system needs what libcosim cannot do (checked before libcosimpy is
    imported, so an unsupported system is told why without the engine installed)."""
    sim = check_supported(system)
    from libcosimpy._internal import get_last_error_message
    from libcosimpy.CosimEnums import CosimVariableType
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    h = system.step
    n_steps = int(round((system.stop - system.start) / h))
    every = system.record_every
    n_rows = n_steps // every + 1
    times = system.start + np.arange(n_rows) * (every * h)
    prov = sim.provenance()
    prov["engine"] = {"name": "libcosim", "libcosimpy": _libcosimpy_about(),
                      "algorithm": "libcosim fixed_step_algorithm (Jacobi)"}
    signals = _observed(sim)
    rec = Recording.allocate([s[0] for s in signals], times, prov)

    log_output_level(CosimLogLevel.ERROR)
    ex = CosimExecution.from_step_size(int(round(h * 1e9)))
    index: dict[str, int] = {}
    slaves = []  # keep the slave objects alive as long as the execution
    for spec in system.units:
        u = sim.units[spec.name]
        s = CosimLocalSlave(fmu_path=str(u.path), instance_name=spec.name)
        slaves.append(s)
        idx = ex.add_local_slave(s)
        if idx < 0:
            raise LibcosimError(f"unit {spec.name}: libcosim cannot load {u.path}: {get_last_error_message()}")
        index[spec.name] = idx
        for var, value in sim._parameters(spec).items():
            v = u.variables[var]
            setter = {"Real": (ex.real_initial_value, float), "Integer": (ex.integer_initial_value, int),
                      "Boolean": (ex.boolean_initial_value, bool),
                      "String": (ex.string_initial_value, str)}[v.type]
            if not setter[0](idx, v.vr, setter[1](value)):
                raise LibcosimError(f"unit {spec.name}: libcosim refused the initial value {var} = "
                                    f"{value!r}: {get_last_error_message()}")
    for c in sim.connections:
        sv = sim.units[c.source.unit].variables[c.source.var]
        tv = sim.units[c.target.unit].variables[c.target.var]
        if sv.type != tv.type:
            raise LibcosimUnsupported(f"connection {c.source.unit}.{c.source.var} -> {c.target.unit}."
                                      f"{c.target.var}: {sv.type} to {tv.type}; libcosim connects "
                                      "variables of the same type only")
        connect = {"Real": ex.connect_real_variables, "Integer": ex.connect_integer_variables,
                   "Boolean": ex.connect_boolean_variables, "String": ex.connect_string_variables}[sv.type]
        # libcosimpy returns the C status here (0 success, -1 failure), not a bool
        if connect(index[c.source.unit], sv.vr, index[c.target.unit], tv.vr) != 0:
            raise LibcosimError(f"libcosim cannot connect {c.source.unit}.{c.source.var} -> "
                                f"{c.target.unit}.{c.target.var}: {get_last_error_message()}")

    # observe each recorded variable once; the buffer holds one chunk of steps (+ the first row)
    chunk = max(1, min(chunk, n_steps))
    obs = CosimObserver.create_time_series(chunk + 2)
    ex.add_observer(obs)
    observed: dict[tuple[str, str], tuple[int, int, str]] = {}
    for _, unit, var, _, _ in signals:
        v = sim.units[unit].variables[var]
        if v.type not in ("Real", "Integer"):
            raise LibcosimUnsupported(f"record.signals: {unit}.{var} is {v.type}; only Real and "
                                      "Integer signals are recorded")
        if (unit, var) not in observed:
            observed[(unit, var)] = (index[unit], v.vr, v.type)
            obs.start_time_series(index[unit], v.vr, CosimVariableType(_TYPES[v.type]))
    readers = _sample_reader()
    obs_ptr = ctypes.cast(obs.ptr(), ctypes.c_void_p)
    col = {key: j for j, key in enumerate(observed)}
    conv = np.array([[f, o] for _, _, _, f, o in signals]).reshape(-1, 2)
    cols = [col[(unit, var)] for _, unit, var, _, _ in signals]

    def fetch(first: int, count: int) -> np.ndarray:
        """Observed raw values for steps first .. first+count-1, shape (count, observed)."""
        out = np.empty((count, len(observed)))
        steps = np.empty(count, dtype=np.int64)
        tps = np.empty(count, dtype=np.int64)
        for (unit, var), (si, vr, typ) in observed.items():
            fn, ctype = readers[typ]
            buf = np.empty(count, dtype=np.float64 if typ == "Real" else np.intc)
            got = fn(obs_ptr, si, vr, first, count, buf.ctypes.data, steps.ctypes.data, tps.ctypes.data)
            if got != count or steps[0] != first or steps[-1] != first + count - 1:
                raise LibcosimError(f"libcosim observer returned {got} samples of {unit}.{var} from "
                                    f"step {first}, expected {count}")
            out[:, col[(unit, var)]] = buf
        return out

    started = _time.time()
    done = 0
    while done < n_steps:
        n = min(chunk, n_steps - done)
        if not ex.step(n):
            rec.complete, rec.fault = False, f"libcosim step failed after step {done}: {get_last_error_message()}"
            raise LibcosimError(rec.fault, rec)
        first = 0 if done == 0 else done + 1
        raw = fetch(first, done + n - first + 1)
        steps = np.arange(first, done + n + 1)
        keep = steps % every == 0
        if len(signals):
            vals = raw[keep][:, cols] * conv[:, 0] + conv[:, 1]
            rec.data[steps[keep] // every] = vals
        done += n
        rec.rows = done // every + 1
    if ex.status().current_time != int(round(h * 1e9)) * n_steps:
        raise LibcosimError(f"libcosim ended at {ex.status().current_time} ns, expected "
                            f"{int(round(h * 1e9)) * n_steps} ns")
    rec.provenance["wall_time_s"] = _time.time() - started
    del ex, slaves
    return rec


def _libcosimpy_about() -> str:
    try:
        from libcosimpy.__about__ import __version__

        return __version__
    except Exception:
        return "unknown"
