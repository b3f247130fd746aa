"""The co-simulation commands: ``build-fmus``, ``run``, ``check-fmu``, ``verify`` and ``tumble``
(the plant FMUs, any system file, a supplier FMU against its role, the coupling error)."""
from __future__ import annotations

import argparse
import sys

from components.cli import json_option
from components.cli.arg_types import positive
from components.errors import UserError

# verify's exit codes beyond the shared 0 (fine) and 2 (bad input)
VERIFY_OUT_OF_TOLERANCE = 1
VERIFY_COULD_NOT_RUN = 3
# check-fmu's interface cost step [s] when --step is not given: the built-in turntable's grid
# (a whole number of its servo periods), whatever the candidate's DefaultExperiment says
COST_STEP = 0.005


def _cmd_build_fmus(args: argparse.Namespace) -> int:
    from fmus.build import FMI_VERSIONS, MODELS, build_fmu

    versions = FMI_VERSIONS if args.fmi is None else (args.fmi,)
    built = []
    for model in MODELS:
        for v in versions:
            path = build_fmu(model, v, force=True)
            print(f"built {model:9s} FMI {v}.0  {path}")
            built.append({"model": model, "fmi": v, "path": str(path)})
    json_option.record(args, built=built)
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from orchestrator.loader import load_system
    from orchestrator.master import Simulation

    if args.out and Path(args.out).suffix.lower() != ".parquet":
        raise UserError(f"--out {args.out}: a recording is written as Parquet; name it .parquet")
    system = load_system(args.system)
    if args.stop is not None:
        system.stop = args.stop
    sim = Simulation(system)
    sim.load()
    for chk in sim.role_checks:
        print(chk.report())
    from fmpy.validation import validate_fmu

    for name, unit in sim.units.items():
        path = getattr(unit, "path", None)
        if path is not None:
            problems = validate_fmu(str(path))
            for p in problems:
                print(f"unit {name}: validation: {p}")
    # an SSP archive's inner system is often just "root": the file names the run
    default = Path(args.system).stem if str(args.system).lower().endswith(".ssp") else system.name
    out = args.out or f"{default}.parquet"
    rec = sim.run(out)
    for note in sim.notes:
        print(f"note: {note}")
    if sim.stopped_at is not None:
        print(f"{system.name}: a unit ended the run at t = {sim.stopped_at:.9g} s")
    print(f"{system.name}: {rec.rows} rows x {len(rec.signals)} signals, "
          f"{rec.provenance['wall_time_s']:.2f} s wall -> {out}")
    json_option.record(args, system=system.name, rows=int(rec.rows), signals=list(rec.signals), out=str(out))
    return 0


def _cmd_verify(args: argparse.Namespace) -> int:
    from orchestrator.errors import LibcosimError, NativeSpanFault, SimulationFault
    from orchestrator.loader import load_system
    from orchestrator.system import AGGREGATIONS
    from orchestrator.verify import verify

    # bad input (the system file, an option) raises and leaves with exit 2 like every command
    system = load_system(args.system)
    if args.stop is not None:
        system.stop = args.stop
    agg = {}
    for it in args.aggregate or []:
        k, sep, v = it.partition("=")
        if not sep or v.strip() not in AGGREGATIONS:
            raise UserError(f"--aggregate {it!r}: expected SIGNAL={'|'.join(AGGREGATIONS)}")
        agg[k.strip()] = v.strip()
    system.validate()
    try:
        report = verify(system, rel_tol=args.rel_tol, engine_abs=args.engine_tol,
                        engine_rel=args.engine_tol, aggregate=agg, engine=not args.no_engine)
    except (SimulationFault, NativeSpanFault, LibcosimError) as e:
        print(f"calbench verify: could not run {args.system}: {e}", file=sys.stderr)
        return VERIFY_COULD_NOT_RUN
    print(report.table())
    json_option.record(args, ok=bool(report.ok), engine_missing=bool(report.engine_missing), table=report.table(),
                       signals=[_signal_json(s) for s in report.signals], skipped=list(report.skipped))
    if not report.ok:
        return VERIFY_OUT_OF_TOLERANCE
    if report.engine_missing:
        print("calbench verify: the coupling check passed, but the engine comparison could not run",
              file=sys.stderr)
        return VERIFY_COULD_NOT_RUN
    return 0


def _check_parameters(fmu: str, parameters: dict) -> None:
    """--parameter names the FMU's own parameters (a readable FMU: the checks below say if not)."""
    import difflib
    from pathlib import Path

    from orchestrator.fmu_units import read_fmu_variables

    if not parameters:
        return
    try:
        variables = read_fmu_variables(fmu)
    except Exception:   # not a readable FMU: check_fmu's validation names why
        return
    own = [n for n, v in variables.items() if v.causality in ("parameter", "structuralParameter")]
    for name in parameters:
        if name not in own:
            close = difflib.get_close_matches(name, own, n=2)
            raise UserError(f"--parameter {name}: {Path(fmu).name} has no parameter {name!r}"
                            + (f" (did you mean {', '.join(close)}?)" if close else ""))


def _signal_json(s) -> dict:
    """One signal of a verify report as numbers a CI script reads (NaN and infinity as null)."""
    import math
    from dataclasses import asdict

    d = {**asdict(s), "rel_error": s.rel_error, "ok": bool(s.ok)}
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}


def _parse_mapping(items: list[str]) -> dict:
    out = {}
    for it in items or []:
        if "=" not in it:
            raise UserError(f"--map {it!r}: expected ROLE_NAME=FMU_NAME")
        k, v = it.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _cmd_check_fmu(args: argparse.Namespace) -> int:
    from pathlib import Path

    from orchestrator.check import check_fmu

    if not Path(args.fmu).exists():
        raise UserError(f"FMU file {args.fmu} does not exist")
    options = {}
    for it in args.option or []:
        k, sep, v = it.partition("=")
        if not sep or not k.strip():
            raise UserError(f"--option {it!r}: expected KEY=VALUE")
        options[k.strip()] = v.strip()
    parameters = {}
    for it in args.parameter or []:
        k, sep, v = it.partition("=")
        try:
            parameters[k.strip()] = float(v)
        except ValueError:
            sep = ""
        if not sep or not k.strip():
            raise UserError(f"--parameter {it!r}: expected NAME=NUMBER (in the FMU's own units)")
    mapping = _parse_mapping(args.map)
    if args.role == "imu" and not args.no_cost:
        # the interface cost's options, before the checks print a verdict
        from components.simulation.interface_cost import check_cost_inputs

        check_cost_inputs(args.step or COST_STEP, args.grade, args.noise_fraction)
        _check_parameters(args.fmu, parameters)
    verdict = check_fmu(args.fmu, args.role, mapping, options, args.step)
    print(verdict.report())
    json_option.record(args, fmu=str(args.fmu), role=args.role, accepted=bool(verdict.ok),
                       validation=verdict.validation, smoke=verdict.smoke, cannot_run=verdict.cannot_run,
                       role_check=verdict.role_check.report() if verdict.role_check is not None else None)
    if args.role == "imu" and verdict.ok and not args.no_cost:
        from components.simulation.interface_cost import interface_cost

        cost = interface_cost(args.fmu, mapping, options, parameters, args.step or COST_STEP, args.grade,
                              args.noise_fraction)
        print(cost.report())
        json_option.record(args, interface_cost=cost.report())
    return 0 if verdict.ok else 1


def _cmd_tumble(args: argparse.Namespace) -> int:
    from components.simulation.tumble import run_tumble

    summary: dict = {}
    code = run_tumble(seed=args.seed, dwell=args.dwell, step=args.step, summary=summary)
    json_option.record(args, **summary)
    return code


def register(sub) -> None:
    b = sub.add_parser("build-fmus", help="rebuild the turntable and IMU FMUs from source now")
    b.add_argument("--fmi", type=int, choices=(2, 3), help="only this FMI version")
    b.set_defaults(func=_cmd_build_fmus)

    r = sub.add_parser("run", help="run a system file (TOML or SSP) and save its recording (Parquet)")
    r.add_argument("system", help="system file (.toml or .ssp)")
    r.add_argument("--out", help="recording file (default: <system name>.parquet)")
    r.add_argument("--stop", type=positive, help="override the stop time [s]")
    r.set_defaults(func=_cmd_run)

    c = sub.add_parser("check-fmu", help="validate an FMU, check it against a role, smoke-test it")
    c.add_argument("fmu", help="the .fmu file")
    c.add_argument("--role", choices=("imu", "turntable"), help="role the FMU should fill")
    c.add_argument("--map", action="append", metavar="ROLE_NAME=FMU_NAME",
                   help="map a role variable onto the FMU's own name (repeatable)")
    c.add_argument("--option", action="append", metavar="KEY=VALUE",
                   help="role option, e.g. gyro_output=rate (imu) (repeatable)")
    c.add_argument("--step", type=positive,
                   help="communication step of the smoke test and the interface cost [s] (default: the "
                        f"smoke test at the FMU's DefaultExperiment step, else {COST_STEP}; the cost at {COST_STEP})")
    c.add_argument("--parameter", action="append", metavar="NAME=NUMBER",
                   help="a parameter for the interface cost, in the FMU's own name and unit (e.g. "
                        "its noise set to 0) (repeatable)")
    c.add_argument("--grade", choices=("navigation", "tactical"), default="navigation",
                   help="whose white noise per sample the coupling error is set against (imu)")
    c.add_argument("--noise-fraction", type=positive, default=0.1,
                   help="the share of that noise the coupling error may reach (0.1)")
    c.add_argument("--no-cost", action="store_true",
                   help="skip the interface cost (role imu: the coupling error while the table "
                        "indexes, at the step and at 2, 5, 10, 20 ms)")
    c.set_defaults(func=_cmd_check_fmu)

    v = sub.add_parser("verify", help="estimate the coupling error of the step (runs at h, h/2, h/4, "
                                      "and the other algorithm at h) and compare with libcosim; exit 0 within tolerance, 1 out of "
                                      "tolerance, 2 bad input, 3 could not run (a unit failed, "
                                      "libcosimpy not installed)")
    v.add_argument("system", help="system file (.toml or .ssp)")
    v.add_argument("--rel-tol", type=positive, default=1e-6, help="coupling error / signal RMS (1e-6)")
    v.add_argument("--engine-tol", type=positive, default=1e-12, help="engine difference, abs and rel (1e-12)")
    v.add_argument("--aggregate", action="append", metavar="SIGNAL=sample|sum|mean",
                   help="how a finer run maps onto the coarse grid (repeatable; overrides "
                        "record.aggregate and what the unit's role declares)")
    v.add_argument("--stop", type=positive, help="override the stop time [s]")
    v.add_argument("--no-engine", action="store_true", help="skip the libcosim comparison")
    v.set_defaults(func=_cmd_verify)

    t = sub.add_parser("tumble", help="co-simulate the table tumbling a navigation-grade IMU "
                                      "through the six axis-up attitudes and check its outputs")
    t.add_argument("--seed", type=int, default=1, help="IMU noise seed")
    t.add_argument("--dwell", type=positive, default=10.0, help="static dwell per attitude [s]")
    t.add_argument("--step", type=positive, default=0.005, help="communication step [s]")
    t.set_defaults(func=_cmd_tumble)
