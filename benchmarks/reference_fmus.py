"""Conformance against fmpy: every co-simulation FMU under a directory (meant for a local build
of the modelica Reference-FMUs, https://github.com/modelica/Reference-FMUs, fetched and built by
the user; nothing of it is in this repository) runs through calbench and through
``fmpy.simulate_fmu`` at the same output times, one line per model:

    FMI  model                     max diff  steps  changes  verdict

* calbench: ``orchestrator.master.simulate`` on a one-unit system with the model's
  DefaultExperiment (start, stop, stepSize; a missing stepSize is (stop - start) / 500, said on
  the line), every output recorded, inputs left at their start values.
* fmpy: ``simulate_fmu`` as co-simulation with ``output_interval`` = the same step.
* max diff: the largest |calbench - fmpy| over the outputs and the common output times
  (integers and Booleans as numbers; strings count 1 per row that differs); steps: the output
  rows after the first; changes: the rows at which a discrete (non-Real) output changed, in
  calbench / fmpy (a model's events, as far as a co-simulation run shows them).
* verdict: ``same`` (max diff <= --atol + --rtol * max|y|), ``differs``, ``calbench failed:
  <reason>`` or ``fmpy failed: <reason>``; FMUs without a co-simulation interface are listed as
  ``not run: <reason>``; a model still running after ``--timeout`` seconds (default 120) is
  ``timed out`` (Roberts' default experiment, 1e-5 to 1e8 s, is one).

Run: ``python benchmarks/reference_fmus.py DIR [--atol A] [--rtol R] [--stop MODEL=SECONDS]`` (DIR is searched for
``*.fmu`` recursively, e.g. the Reference-FMUs' ``build/`` or an unpacked release with ``2.0/``
and ``3.0/``). Exit 0 when every model that ran is ``same``, 1 otherwise, 2 when DIR has none.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_REAL = ("Real", "Float32", "Float64")


@dataclass
class ModelLine:
    fmi: str
    model: str
    verdict: str
    max_diff: float | None = None
    steps: int | None = None
    changes: tuple[int, int] | None = None
    note: str = ""

    def __str__(self) -> str:
        diff = "" if self.max_diff is None else f"{self.max_diff:.3e}"
        steps = "" if self.steps is None else str(self.steps)
        ch = "" if self.changes is None else f"{self.changes[0]}/{self.changes[1]}"
        note = f" ({self.note})" if self.note else ""
        return f"{self.fmi:4s} {self.model:28s} {diff:>10s} {steps:>6s} {ch:>9s}  {self.verdict}{note}"


HEADER = f"{'FMI':4s} {'model':28s} {'max diff':>10s} {'steps':>6s} {'changes':>9s}  verdict"


def _first_line(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0] if text else ''}"


def compare_model(path: Path, atol: float = 1e-12, rtol: float = 1e-12, stops: dict | None = None) -> ModelLine:
    from fmpy import read_model_description

    from orchestrator.check import unsupported_reason

    try:
        md = read_model_description(str(path))
    except Exception as e:
        return ModelLine("?", path.stem, f"not run: unreadable ({_first_line(e)})")
    fmi, model = str(md.fmiVersion)[:3], md.modelName or path.stem
    why = unsupported_reason(md)
    if why is not None:
        return ModelLine(fmi, model, f"not run: {why.split(':')[0]}")
    de = md.defaultExperiment
    start = float(de.startTime) if de is not None and de.startTime is not None else 0.0
    stop = float(de.stopTime) if de is not None and de.stopTime is not None else start + 1.0
    note = ""
    for key in (md.modelName, path.stem):
        if stops and key in stops:
            note = f"stop {stops[key]:g} s by --stop, DefaultExperiment {stop:g} s"
            stop = stops[key]
            break
    if de is not None and de.stepSize is not None:
        step = float(de.stepSize)
    else:
        step = (stop - start) / 500
        note = (note + "; " if note else "") + f"no stepSize in DefaultExperiment: {step:g} s"
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    names = [v.name for v in outputs]
    line = ModelLine(fmi, model, "", note=note)
    try:
        ours = _calbench(path, start, stop, step, names)
    except Exception as e:  # a failure of calbench is the result to report, whatever it is
        line.verdict = f"calbench failed: {_first_line(e)}"
        return line
    try:
        theirs = _fmpy(path, start, stop, step, names)
    except Exception as e:
        line.verdict = f"fmpy failed: {_first_line(e)}"
        return line
    t_ours, t_theirs = ours[0], theirs["time"]
    # the common output times: a calbench row k and an fmpy row at the same time within rounding
    j = np.searchsorted(t_theirs, t_ours - 1e-9 * step)
    ok = (j < len(t_theirs)) & (np.abs(t_theirs[np.minimum(j, len(t_theirs) - 1)] - t_ours) <= 1e-9 * step)
    rows_ours, rows_theirs = np.nonzero(ok)[0], j[ok]
    worst, scale, changes = 0.0, 0.0, [0, 0]
    discrete_ours, discrete_theirs = np.zeros(len(rows_ours), bool), np.zeros(len(rows_theirs), bool)
    unrecorded = []
    for v in outputs:
        a = np.asarray(ours[1][v.name])[rows_ours]
        if v.name not in (theirs.dtype.names or ()):  # fmpy records no String or Binary output
            unrecorded.append(v.name)
            continue
        b = np.asarray(theirs[v.name])[rows_theirs]
        if v.type == "String" or a.dtype.kind in "USO" or b.dtype.kind in "USO":
            worst = max(worst, float(np.sum(a != b)))
            continue
        if b.ndim > 1:  # an array variable: fmpy gives one column of arrays
            b = b.reshape(len(b), -1)
            a = np.asarray(a, dtype=float).reshape(len(a), -1)
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        if a.size:
            worst = max(worst, float(np.max(np.abs(a - b))))
            scale = max(scale, float(np.max(np.abs(b))))
        if v.type not in _REAL and len(a) > 1:
            discrete_ours[1:] |= np.any((a[1:] != a[:-1]).reshape(len(a) - 1, -1), axis=1)
            discrete_theirs[1:] |= np.any((b[1:] != b[:-1]).reshape(len(b) - 1, -1), axis=1)
    changes = [int(discrete_ours.sum()), int(discrete_theirs.sum())]
    line.max_diff, line.steps, line.changes = worst, len(t_ours) - 1, tuple(changes)
    if unrecorded:
        line.note = (line.note + "; " if line.note else "") + f"not recorded by fmpy: {', '.join(unrecorded)}"
    missing = len(t_ours) - len(rows_ours)
    if missing:
        line.note = (line.note + "; " if line.note else "") + f"{missing} calbench rows have no fmpy row"
    line.verdict = "same" if worst <= atol + rtol * scale and not missing else "differs"
    return line


def _calbench(path: Path, start: float, stop: float, step: float, names: list[str]):
    from orchestrator.master import simulate
    from orchestrator.system import System, UnitSpec

    system = System(name=path.stem, step=step, start=start, stop=stop,
                    units=[UnitSpec("m", fmu=str(path.resolve()))], record=[f"m.{n}" for n in names])
    rec = simulate(system, progress=False)
    if not rec.complete:
        raise RuntimeError(rec.fault or "incomplete run")
    def values(n: str):
        if f"m.{n}" in rec.signals:
            return rec[f"m.{n}"]
        # an array variable is recorded one column per element, m.y[0], m.y[1], ... (row-major)
        elements = [s for s in rec.signals if s.startswith(f"m.{n}[")]
        return np.stack([rec[s] for s in elements], axis=1)

    return rec.t, {n: values(n) for n in names}


def _fmpy(path: Path, start: float, stop: float, step: float, names: list[str]):
    from fmpy import simulate_fmu

    return simulate_fmu(str(path), start_time=start, stop_time=stop, step_size=step,
                        output_interval=step, fmi_type="CoSimulation", output=names, validate=False)


def _compare_with_limit(path: Path, atol: float, rtol: float, timeout: float, stops: dict) -> ModelLine:
    """compare_model in a child process, ended after *timeout* s: a model whose default
    experiment asks for more than a fixed-step co-simulation can do in time (Roberts: 1e-5 to
    1e8 s) must not stop the rest of the list."""
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=lambda: queue.put(compare_model(path, atol, rtol, stops)))
    child.start()
    child.join(timeout)
    if child.is_alive():
        child.kill()
        child.join()
        try:
            from fmpy import read_model_description

            md = read_model_description(str(path))
            fmi, model = str(md.fmiVersion)[:3], md.modelName or path.stem
        except Exception:
            fmi, model = "?", path.stem
        return ModelLine(fmi, model, f"timed out after {timeout:g} s")
    try:
        return queue.get(timeout=10)
    except Exception:
        return ModelLine("?", path.stem, f"failed: the child process ended with code {child.exitcode}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("directory", type=Path, help="searched recursively for *.fmu")
    ap.add_argument("--atol", type=float, default=1e-12)
    ap.add_argument("--rtol", type=float, default=1e-12)
    ap.add_argument("--timeout", type=float, default=120.0,
                    help="seconds per model (both engines); a model still running then is reported as timed out")
    ap.add_argument("--stop", action="append", default=[], metavar="MODEL=SECONDS",
                    help="run MODEL (its modelName or file stem) to this stop time instead of its DefaultExperiment's "
                         "(e.g. Roberts=1: its 1e8 s take a fixed-step co-simulation 1e14 internal steps)")
    args = ap.parse_args(argv)
    stops = {}
    for item in args.stop:
        name, _, value = item.partition("=")
        try:
            stops[name] = float(value)
        except ValueError:
            ap.error(f"--stop {item!r}: expected MODEL=SECONDS")
    fmus = sorted(args.directory.rglob("*.fmu"))
    if not fmus:
        print(f"reference_fmus: no *.fmu under {args.directory}", file=sys.stderr)
        return 2
    print(HEADER)
    lines = []
    for p in fmus:
        line = _compare_with_limit(p, args.atol, args.rtol, args.timeout, stops)
        lines.append(line)
        print(line, flush=True)
    ran = [x for x in lines if not x.verdict.startswith("not run")]
    same = sum(x.verdict == "same" for x in ran)
    print(f"{same} of {len(ran)} models run are the same in calbench and fmpy "
          f"({len(lines) - len(ran)} not run)")
    return 0 if same == len(ran) else 1


if __name__ == "__main__":
    sys.exit(main())
