"""``calbench verify``: how large is the coupling error of a system's communication step, and does
an independent engine compute the same thing?

1. Step refinement. The system runs at its step h, at h/2 and at h/4 (every unit keeps its
   ``step_multiple``, so every unit's own step halves too). The three recordings are brought onto
   the grid of the h-run's recorded rows (every ``record.every`` * h):
   ``sample`` takes the value at the grid time; ``sum`` adds a finer run's values over each grid
   interval (per-interval totals: IMU increments, pulse counts); ``mean`` averages them (per-interval
   means: an IMU's mean rate or mean specific force). A signal's aggregation comes from the command
   line, then the system file (``[record] aggregate = {"imu.gyro" = "sum"}``, a name or a vector
   prefix), then the unit's role (the IMU role's outputs say which kind they are, so a mean-rate
   IMU is averaged and an increment IMU summed without being told), else ``sample``. Per signal, with d1 = ||y_h - y_h/2|| and d2 = ||y_h/2 - y_h/4|| (RMS over the grid rows
   after the first), the observed order is p = log2(d1 / d2) and the Richardson estimate of the
   h-run's error is d1 * 2^p / (2^p - 1). When the differences do not shrink (p below 0.5, or
   d2 = 0 while d1 > 0) no extrapolation is trusted and the estimate is d1 + d2 (flagged "no
   convergence"). A signal passes when estimate <= rel_tol * RMS(y_h) (+ a floor of 1e-300).
   Random signals whose realisation depends on the step (IMU noise) never converge; verify a
   system with its noise off.
2. Algorithm comparison. Units that integrate on their own fixed grid give identical runs at
   h, h/2 and h/4, so step refinement sees no coupling error even when a connection is a whole
   step late. The system therefore also runs at h with another algorithm (Gauss–Seidel in the
   connection graph's order for a Jacobi system; Jacobi for a Gauss–Seidel one, or Gauss–Seidel
   in the graph's order when its own order delays a connection) and per signal d = ||y_own - y_other|| (RMS over
   the grid rows after the first) is taken: at least one of the two runs is then off by d / 2,
   and verify counts that lower bound against the system's own algorithm where step refinement
   sees no change at all (its blind spot) and the algorithm delays a connection (Jacobi delays
   every one; Gauss–Seidel those whose source steps after their target). Where refinement does
   see the error it is trusted and the bound only shown: a unit may expect its inputs as of a
   step's start (our IMU's input_timing), which makes the other algorithm the wrong one. A
   Gauss–Seidel system that delays no connection is not judged by it (the difference would be
   Jacobi's delay, not this run's error). A signal fails when either estimate exceeds the
   tolerance.
3. Types. Real (Float32/Float64) signals are compared as above; integers, enumerations and
   Booleans exactly (the number of grid rows that differ, which must be 0); strings by equality;
   what cannot be compared (binary values, arrays) is listed as skipped.
4. Engine check. When every unit is an FMI 2.0 FMU that libcosim can run, the system runs in
   libcosim at h and the orchestrator runs with libcosim's algorithm semantics (Jacobi, see
   :mod:`orchestrator.libcosim`); if the system itself uses Gauss–Seidel, that is one extra
   orchestrator run in Jacobi. Per signal: max |a - b| <= engine_abs + engine_rel * max |a|.
   Otherwise the check is skipped and the reason printed (Python components cannot run in
   libcosim).
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np

from orchestrator.errors import LibcosimUnsupported, SystemError_
from orchestrator.master import simulate
from orchestrator.recording import Recording
from orchestrator.roles import get_role
from orchestrator.system import AGGREGATIONS, System


@dataclass
class SignalResult:
    name: str
    aggregate: str
    rms: float
    d1: float
    d2: float
    order: float           # observed order p (nan when undefined)
    error: float           # estimated coupling error of the h-run (RMS over the grid)
    converged: bool
    coupling_ok: bool
    engine_diff: float | None = None
    engine_ok: bool | None = None
    kind: str = "real"     # "real", "exact" (integers, Booleans: rows that differ), "equal" (strings)
    alg_diff: float | None = None   # RMS (real) or rows (exact) by which the algorithms differ
    alg_bound: float | None = None  # the lower bound counted against this run (None: not judged)

    @property
    def rel_error(self) -> float:
        err = max(self.error, self.alg_bound or 0.0)
        if self.kind != "real":
            return err  # rows that differ
        return err / self.rms if self.rms > 0 else (0.0 if err == 0 else math.inf)

    @property
    def ok(self) -> bool:
        return self.coupling_ok and self.engine_ok is not False


@dataclass
class VerifyReport:
    system: str
    step: float
    rel_tol: float
    engine_abs: float
    engine_rel: float
    signals: list[SignalResult] = field(default_factory=list)
    engine_note: str = ""
    engine_missing: bool = False   # libcosimpy is not installed: the engine check could not run
    interface_notes: list[str] = field(default_factory=list)
    algorithm_note: str = ""
    skipped: list[str] = field(default_factory=list)  # signals that cannot be compared, and why

    @property
    def ok(self) -> bool:
        return all(s.ok for s in self.signals)

    def table(self) -> str:
        head = (f"{'signal':28s} {'agg':6s} {'RMS':>10s} {'order p':>8s} {'coupling err':>12s} "
                f"{'alg bound':>10s} {'rel':>9s} {'':4s} {'engine diff':>11s} {'':4s}")
        lines = [f"verify {self.system}: step h = {self.step:g} s, refined to h/2 and h/4; "
                 f"coupling tolerance {self.rel_tol:g} x RMS, engine tolerance "
                 f"{self.engine_abs:g} + {self.engine_rel:g} x max|y|", head, "-" * len(head)]
        for s in self.signals:
            p = "n/a" if not math.isfinite(s.order) else f"{s.order:.2f}"
            if not s.converged:
                p = "no conv"
            eng = "skipped" if s.engine_diff is None else f"{s.engine_diff:.2e}"
            eok = "" if s.engine_ok is None else ("ok" if s.engine_ok else "FAIL")
            # the bound in parentheses is shown, not judged (step refinement saw the error)
            alg = ("n/a" if s.alg_diff is None else f"{s.alg_diff / 2:.3e}" if s.alg_bound is not None
                   else f"({s.alg_diff / 2:.2e})")
            if s.kind != "real":  # exact comparisons count the grid rows that differ
                p = s.kind
                alg = "n/a" if s.alg_diff is None else f"{int(s.alg_diff)} rows"
                lines.append(f"{s.name:28s} {s.aggregate:6s} {'':>10s} {p:>8s} {int(s.error):7d} rows "
                             f"{alg:>10s} {'':>9s} {'ok' if s.coupling_ok else 'FAIL':4s} {eng:>11s} {eok:4s}")
                continue
            lines.append(f"{s.name:28s} {s.aggregate:6s} {s.rms:10.3e} {p:>8s} {s.error:12.3e} "
                         f"{alg:>10s} {s.rel_error:9.2e} {'ok' if s.coupling_ok else 'FAIL':4s} {eng:>11s} {eok:4s}")
        lines += [f"not compared: {n}" for n in self.skipped]
        if self.algorithm_note:
            lines.append(self.algorithm_note)
        lines += self.interface_notes
        if self.engine_note:
            lines.append(self.engine_note)
        lines.append(f"{'PASS' if self.ok else 'FAIL'}: {sum(s.ok for s in self.signals)} of "
                     f"{len(self.signals)} signals within tolerance")
        return "\n".join(lines)


def aggregation_of(system: System, signal: str, overrides: dict | None = None) -> str:
    """The aggregation of a recorded signal: the longest matching name or prefix (``imu.gyro``
    matches ``imu.gyro.x``) in *overrides*, then in the system's ``record.aggregate``, then what
    the unit's role declares for that variable."""
    for table in (overrides or {}, system.record_aggregate):
        best = None
        for key in table:
            if signal == key or signal.startswith(key + "."):
                if best is None or len(key) > len(best):
                    best = key
        if best is not None:
            how = table[best]
            if how not in AGGREGATIONS:
                raise SystemError_(f"aggregate {best} = {how!r}: expected one of {AGGREGATIONS}")
            return how
    return _role_aggregation(system, signal)


def _role_aggregation(system: System, signal: str) -> str:
    unit, _, var = signal.partition(".")
    spec = next((u for u in system.units if u.name == unit), None)
    if spec is None or not spec.role:
        return "sample"
    try:
        role = get_role(spec.role, **(spec.role_options or {}))
    except (KeyError, TypeError, ValueError):
        return "sample"  # the system's validation reports a bad role; verify does not guess
    declared = role.variable(var)
    return declared.aggregate if declared is not None else "sample"


def _refined(system: System, factor: int) -> System:
    s = copy.deepcopy(system)
    s.step = system.step / factor
    s.record_every = 1
    return s


def on_grid(rec: Recording, block: int, how: list[str]) -> np.ndarray:
    """Rows of a run recorded every step, brought onto a grid of every *block*-th row:
    ``sample`` columns take the row at the grid point, ``sum`` columns add the *block* rows of
    the interval that ends there, ``mean`` columns average them (row 0 keeps the initial value)."""
    data = rec.data[: rec.rows]
    n = (rec.rows - 1) // block
    out = data[:: block][: n + 1].copy()
    if n == 0:   # a run shorter than one grid interval: only row 0
        return out
    sums = data[1: n * block + 1].reshape(n, block, -1).sum(axis=1)
    for j, h in enumerate(how):
        if h == "sum":
            out[1:, j] = sums[:, j]
        elif h == "mean":
            out[1:, j] = sums[:, j] / block
    return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else 0.0


def verify(system: System, rel_tol: float = 1e-6, engine_abs: float = 1e-12, engine_rel: float = 1e-12,
           aggregate: dict | None = None, engine: bool = True) -> VerifyReport:
    system.validate()
    from orchestrator.master import Simulation

    sim = Simulation(system)
    sim.load()
    every = system.record_every
    runs = [simulate(_refined(system, r), progress=False) for r in (1, 2, 4)]
    names = runs[0].signals
    for key in aggregate or {}:
        if not any(n == key or n.startswith(key + ".") for n in names):
            raise SystemError_(f"--aggregate {key}: no recorded signal is or starts with {key!r} (recorded: "
                               f"{', '.join(names[:12])}{' ...' if len(names) > 12 else ''})")
    how = [aggregation_of(system, n, aggregate) for n in names]
    # an aggregation given against what the unit's role declares its output to be (a mean rate
    # summed, increments averaged) makes the finer runs disagree by the step ratio: a false FAIL
    contrary = {}
    for n, h in zip(names, how):
        declared = _role_aggregation(system, n)
        if {h, declared} == {"sum", "mean"}:
            contrary.setdefault((h, declared), []).append(n)
    report = VerifyReport(system.source or system.name, system.step, rel_tol, engine_abs, engine_rel)
    for (h, declared), which in contrary.items():
        report.interface_notes.append(
            f"note: {', '.join(which[:6])}{' ...' if len(which) > 6 else ''} aggregated by '{h}' (record.aggregate or "
            f"--aggregate), but the unit's role declares them '{declared}' outputs (its role_options): the finer "
            f"runs then differ by the step ratio; --aggregate SIGNAL={declared} if the role is right")
    other, judged = _other_algorithm(system, sim, report)
    for j, name in enumerate(names):
        kind, why = _kind(sim, name, runs[0][name])
        if kind == "skip":
            report.skipped.append(f"{name} ({why})")
            continue
        agg = how[j] if kind == "real" else "sample"
        cols = [_column_on_grid(np.asarray(rec[name]), every * r, agg) for rec, r in zip(runs, (1, 2, 4))]
        rows = min(len(c) for c in cols)
        if rows < 2:
            # only t = 0 is on the coarse grid: there is nothing to compare, and no verdict
            raise SystemError_(f"{system.source or system.name}: step {system.step:g} s over a run of "
                               f"{system.stop - system.start:g} s leaves no communication step after t = 0 to "
                               "compare; verify needs a run of several steps (a longer stop, a shorter step)")
        c1, c2, c4 = (c[1:rows] for c in cols)
        alt = None
        if other is not None:
            a = _column_on_grid(np.asarray(other[name]), every, agg)
            n = min(rows, len(a))
            alt = (c1[: n - 1], a[1:n])
        if kind == "real":
            res = _real_result(name, agg, c1, c2, c4, rel_tol)
            if alt is not None:
                res.alg_diff = _rms(alt[0] - alt[1])
                if judged and res.d1 == 0.0 and res.d2 == 0.0:
                    res.alg_bound = res.alg_diff / 2
                    res.coupling_ok = res.coupling_ok and res.alg_bound <= rel_tol * res.rms + 1e-300
        else:
            d1, d2 = _differ(c1, c2), _differ(c2, c4)
            res = SignalResult(name, agg, math.nan, d1, d2, math.nan, d1 + d2, True, d1 + d2 == 0, kind=kind)
            if alt is not None:
                res.alg_diff = _differ(*alt)
                if judged and d1 == 0 and d2 == 0:
                    res.alg_bound = res.alg_diff
                    res.coupling_ok = res.coupling_ok and res.alg_diff == 0
        report.signals.append(res)
    _explain_algorithm_comparison(report)
    report.interface_notes += interface_notes(system, sim)
    if engine:
        reuse = (other if other is not None and other.provenance["system"]["algorithm"] == "jacobi"
                 and every == 1 else None)
        _engine_check(system, runs[0], report, reuse)
    else:
        report.engine_note = "engine comparison not requested"
    return report


def _real_result(name: str, agg: str, g1, g2, g4, rel_tol: float) -> SignalResult:
    """Richardson's estimate from the h, h/2, h/4 runs of a real signal."""
    g1, g2, g4 = (np.asarray(g, dtype=float) for g in (g1, g2, g4))
    d1, d2 = _rms(g1 - g2), _rms(g2 - g4)
    rms = _rms(g1)
    if d1 == 0.0 and d2 == 0.0:
        p, err, conv = math.nan, 0.0, True
    elif d2 > 0.0 and d1 > 0.0 and math.log2(d1 / d2) >= 0.5:
        p = math.log2(d1 / d2)
        err, conv = d1 * 2 ** p / (2 ** p - 1), True
    else:
        p = math.log2(d1 / d2) if d1 > 0 and d2 > 0 else math.nan
        err, conv = d1 + d2, False
    return SignalResult(name, agg, rms, d1, d2, p, err, conv, err <= rel_tol * rms + 1e-300)


def _differ(a: np.ndarray, b: np.ndarray) -> int:
    n = min(len(a), len(b))
    return int(sum(1 for x, y in zip(a[:n], b[:n]) if x != y))


_REAL = ("Real", "Float32", "Float64")
_EXACT = ("Integer", "Boolean", "Enumeration", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32",
          "Int64", "UInt64")


def _kind(sim, name: str, column) -> tuple[str, str]:
    """How a recorded signal is compared: by its variable's declared type, else its column's."""
    col = np.asarray(column)
    if col.ndim != 1:
        return "skip", "an array signal; verify compares scalars"
    unit, _, var = name.partition(".")
    vtype = None
    try:
        (e,) = sim._endpoint(unit, var, "record.signals")
        vtype = sim.units[unit].variables[e.var].type
    except Exception:  # a recorded name the unit resolves differently: fall back to the values
        pass
    if vtype in _REAL or (vtype is None and col.dtype.kind == "f"):
        return "real", ""
    if vtype in _EXACT or (vtype is None and col.dtype.kind in "biu"):
        return "exact", ""
    if vtype == "String" or col.dtype.kind in "USO":
        return "equal", ""
    return "skip", f"type {vtype or col.dtype}: no comparison defined"


def _column_on_grid(col: np.ndarray, block: int, how: str) -> np.ndarray:
    """One recorded column on the grid of every *block*-th row (see :func:`on_grid`)."""
    n = (len(col) - 1) // block
    out = col[::block][: n + 1].copy()
    if how in ("sum", "mean") and n > 0:
        sums = np.asarray(col[1: n * block + 1], dtype=float).reshape(n, block).sum(axis=1)
        out = np.asarray(out, dtype=float)
        out[1:] = sums if how == "sum" else sums / block
    return out


def _delayed_connections(sim) -> list[str]:
    """Connections Gauss–Seidel delays by a step: the source steps after the target."""
    pos = {n: i for i, n in enumerate(sim.order)}
    return [f"{c.source.unit}.{c.source.name} -> {c.target.unit}.{c.target.name}"
            for c in sim.connections if c.derivative_order == 0
            and pos.get(c.source.unit, -1) >= pos.get(c.target.unit, -1)]


def _other_algorithm(system: System, sim, report: VerifyReport):
    """The run at h to compare with, and whether its difference is counted against this system
    (see the module's point 2). Returns (recording or None, judged).

    Jacobi is compared with Gauss–Seidel in the connection graph's order. A Gauss–Seidel system
    whose order delays a connection is compared with Gauss–Seidel in the graph's order when that
    order delays none (a feed-forward system stepped in a poor order); in a loop some connection
    is late in every order, and no algorithm comparison can see that shared delay."""
    from orchestrator.master import Simulation

    if not sim.connections:
        report.algorithm_note = "algorithm comparison: no connections, nothing to compare"
        return None, False
    if sim.loop_groups:
        report.algorithm_note = ("algorithm comparison: the algebraic loops are solved at every step (iterative); "
                                 "no other algorithm runs them without a delay to compare with")
        return None, False
    o = _refined(system, 1)  # every step recorded, brought onto the grid like the refined runs
    o.order = None
    if system.algorithm == "jacobi":
        o.algorithm = "gauss-seidel"
        judged, why = True, "jacobi delays every connection by one step"
    else:
        delayed = _delayed_connections(sim)
        if not delayed:
            o.algorithm = "jacobi"
            judged, why = False, ""
        else:
            alt = Simulation(o)
            alt.load()
            still = _delayed_connections(alt)
            if still:
                report.algorithm_note = (
                    "algorithm comparison: a loop delays " + ", ".join(still[:3]) + " in every "
                    "gauss-seidel order; no algorithm comparison sees that shared delay")
                return None, False
            judged = True
            why = (f"the order {system.order} delays " + ", ".join(delayed[:3])
                   + (" ..." if len(delayed) > 3 else "") + f", the graph's order {alt.order} none")
    other = simulate(o, progress=False)
    if judged:
        report.algorithm_note = (f"algorithm comparison: {system.algorithm} vs {o.algorithm} at h; "
                                 f"{why}, so half their difference ('alg bound') is a lower bound of "
                                 "one run's coupling error, judged where step refinement shows no change")
    else:
        report.algorithm_note = ("algorithm comparison: gauss-seidel delays no connection here; its "
                                 "difference from jacobi is jacobi's delay, not this run's error, "
                                 "so it is not judged")
    return other, judged


def _explain_algorithm_comparison(report: VerifyReport) -> None:
    """Say so when only the algorithm comparison sees the error."""
    seen = [s for s in report.signals if s.alg_bound and s.error == 0.0 and not s.coupling_ok]
    if seen:
        report.algorithm_note += ("\nstep refinement shows no change: the units integrate on their "
                                  "own grid; the algorithm comparison does (" +
                                  ", ".join(s.name for s in seen[:5]) + ")")


def interface_notes(system: System, sim=None) -> list[str]:
    """What each role unit's interface leaves out: the role's optional inputs the unit does not
    offer, and those it offers that nothing drives. Both show in the coupling error above (the
    unit reconstructs between communication points what it is not given)."""
    if sim is None:
        from orchestrator.master import Simulation

        sim = Simulation(system)
        sim.load()
    driven = {(c.target.unit, c.target.name) for c in sim.connections}
    notes = []
    for spec in system.units:
        if not spec.role:
            continue
        role = get_role(spec.role, **spec.role_options)
        optional = [v.name for v in role.variables if v.causality == "input" and not v.required]
        absent = _vectors([n for n in optional if n not in sim.bindings[spec.name]])
        idle = _vectors([n for n in optional if n in sim.bindings[spec.name] and (spec.name, n) not in driven])
        if absent:
            notes.append(f"unit {spec.name} (role {spec.role}) does not take the optional inputs "
                         f"{', '.join(absent)}")
        if idle:
            notes.append(f"unit {spec.name} (role {spec.role}) takes {', '.join(idle)}, but nothing "
                         "drives them")
    return notes


def _vectors(names: list[str]) -> list[str]:
    """``alpha.x, alpha.y, alpha.z`` as ``alpha``."""
    out = []
    for n in names:
        stem, _, last = n.rpartition(".")
        key = stem if stem and last in ("x", "y", "z") else n
        if key not in out:
            out.append(key)
    return out


def _engine_check(system: System, base: Recording, report: VerifyReport,
                  jacobi_run: Recording | None = None) -> None:
    from orchestrator.libcosim import run_libcosim

    try:
        theirs = run_libcosim(copy.deepcopy(system))
    except ImportError:
        report.engine_missing = True
        report.engine_note = ("engine comparison with libcosim not run: libcosimpy is not installed "
                              "(pip install \"calbench[verify]\", or --no-engine to skip it)")
        return
    except LibcosimUnsupported as e:
        reasons = str(e).split("cannot run in libcosim:", 1)[-1].strip().split("\n")
        report.engine_note = "engine check skipped: " + "; ".join(r.strip() for r in reasons if r.strip())
        return
    if system.algorithm == "jacobi":
        ours = base
        note = "orchestrator (jacobi) vs libcosim (fixed-step, Jacobi) at h"
    else:
        if jacobi_run is None:
            j = copy.deepcopy(system)
            j.algorithm = "jacobi"
            jacobi_run = simulate(j, progress=False)
        ours = jacobi_run
        note = ("the system uses gauss-seidel; libcosim has only its Jacobi fixed-step algorithm, so "
                "the engine check compares the orchestrator run in jacobi with libcosim at h")
    report.engine_note = note
    for s in report.signals:
        a, b = np.asarray(ours[s.name]), np.asarray(theirs[s.name])
        if s.kind != "real":  # integers, Booleans, strings: equal or not
            s.engine_diff = float(_differ(a, b))
            s.engine_ok = s.engine_diff == 0 and len(a) == len(b)
            continue
        a, b = a.astype(float), b.astype(float)
        diff = float(np.max(np.abs(a - b)))
        s.engine_diff = diff
        s.engine_ok = diff <= report.engine_abs + report.engine_rel * float(np.max(np.abs(a)))
