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
2. Engine check. When every unit is an FMI 2.0 FMU that libcosim can run, the system runs in
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

    @property
    def rel_error(self) -> float:
        return self.error / self.rms if self.rms > 0 else (0.0 if self.error == 0 else math.inf)

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

    @property
    def ok(self) -> bool:
        return all(s.ok for s in self.signals)

    def table(self) -> str:
        head = (f"{'signal':28s} {'agg':6s} {'RMS':>10s} {'order p':>8s} {'coupling err':>12s} "
                f"{'rel':>9s} {'':4s} {'engine diff':>11s} {'':4s}")
        lines = [f"verify {self.system}: step h = {self.step:g} s, refined to h/2 and h/4; "
                 f"coupling tolerance {self.rel_tol:g} x RMS, engine tolerance "
                 f"{self.engine_abs:g} + {self.engine_rel:g} x max|y|", head, "-" * len(head)]
        for s in self.signals:
            p = "n/a" if not math.isfinite(s.order) else f"{s.order:.2f}"
            if not s.converged:
                p = "no conv"
            eng = "skipped" if s.engine_diff is None else f"{s.engine_diff:.2e}"
            eok = "" if s.engine_ok is None else ("ok" if s.engine_ok else "FAIL")
            lines.append(f"{s.name:28s} {s.aggregate:6s} {s.rms:10.3e} {p:>8s} {s.error:12.3e} "
                         f"{s.rel_error:9.2e} {'ok' if s.coupling_ok else 'FAIL':4s} {eng:>11s} {eok:4s}")
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
    every = system.record_every
    runs = [simulate(_refined(system, r), progress=False) for r in (1, 2, 4)]
    names = runs[0].signals
    how = [aggregation_of(system, n, aggregate) for n in names]
    grids = [on_grid(rec, every * r, how) for rec, r in zip(runs, (1, 2, 4))]
    rows = min(g.shape[0] for g in grids)
    g1, g2, g4 = (g[1:rows] for g in grids)
    report = VerifyReport(system.source or system.name, system.step, rel_tol, engine_abs, engine_rel)
    for j, name in enumerate(names):
        d1, d2 = _rms(g1[:, j] - g2[:, j]), _rms(g2[:, j] - g4[:, j])
        rms = _rms(g1[:, j])
        if d1 == 0.0 and d2 == 0.0:
            p, err, conv = math.nan, 0.0, True
        elif d2 > 0.0 and d1 > 0.0 and math.log2(d1 / d2) >= 0.5:
            p = math.log2(d1 / d2)
            err, conv = d1 * 2 ** p / (2 ** p - 1), True
        else:
            p = math.log2(d1 / d2) if d1 > 0 and d2 > 0 else math.nan
            err, conv = d1 + d2, False
        report.signals.append(SignalResult(name, how[j], rms, d1, d2, p, err, conv,
                                           err <= rel_tol * rms + 1e-300))
    report.interface_notes = interface_notes(system)
    if engine:
        _engine_check(system, runs[0], report)
    else:
        report.engine_note = "engine comparison not requested"
    return report


def interface_notes(system: System) -> list[str]:
    """What each role unit's interface leaves out: the role's optional inputs the unit does not
    offer, and those it offers that nothing drives. Both show in the coupling error above (the
    unit reconstructs between communication points what it is not given)."""
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


def _engine_check(system: System, base: Recording, report: VerifyReport) -> None:
    from orchestrator.libcosim import run_libcosim

    try:
        theirs = run_libcosim(copy.deepcopy(system))
    except ImportError:
        report.engine_missing = True
        report.engine_note = ("engine comparison with libcosim not run: libcosimpy is not installed "
                              "(pip install \"calbench[verify]\", or --no-engine to skip it)")
        return
    except LibcosimUnsupported as e:
        report.engine_note = ("engine comparison with libcosim skipped: "
                              + str(e).split(":", 1)[-1].strip().replace("\n  ", "; "))
        return
    if system.algorithm == "jacobi":
        ours = base
        note = "orchestrator (jacobi) vs libcosim (fixed-step, Jacobi) at h"
    else:
        j = copy.deepcopy(system)
        j.algorithm = "jacobi"
        ours = simulate(j, progress=False)
        note = ("the system uses gauss-seidel; libcosim has only its Jacobi fixed-step algorithm, so "
                "the engine check compares the orchestrator run in jacobi with libcosim at h")
    report.engine_note = note
    a, b = ours.data[: ours.rows], theirs.data[: theirs.rows]
    for j, s in enumerate(report.signals):
        col = ours.signals.index(s.name)
        diff = float(np.max(np.abs(a[:, col] - b[:, theirs.signals.index(s.name)])))
        s.engine_diff = diff
        s.engine_ok = diff <= report.engine_abs + report.engine_rel * float(np.max(np.abs(a[:, col])))
