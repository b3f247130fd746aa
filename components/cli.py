"""calbench: IMU calibration on turntables by FMI co-simulation — simulate, calibrate, compare,
diagnose, plan, verify."""
from __future__ import annotations

import argparse
import sys


class UserError(Exception):
    """A mistake in what the user gave us: printed as one clear line, no traceback."""


def _cmd_build_fmus(args: argparse.Namespace) -> int:
    from fmus.build import FMI_VERSIONS, MODELS, build_fmu

    versions = FMI_VERSIONS if args.fmi is None else (args.fmi,)
    for model in MODELS:
        for v in versions:
            path = build_fmu(model, v, force=True)
            print(f"built {model:9s} FMI {v}.0  {path}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from components.demo import run_demo

    return run_demo(args.out, seed=args.seed, dwell=args.dwell)


def _cmd_tumble(args: argparse.Namespace) -> int:
    from components.tumble import run_tumble

    return run_tumble(seed=args.seed, dwell=args.dwell, step=args.step)


def _cmd_run(args: argparse.Namespace) -> int:
    from orchestrator.master import Simulation
    from orchestrator.loader import load_system

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
    out = args.out or f"{system.name}.parquet"
    rec = sim.run(out)
    print(f"{system.name}: {rec.rows} rows x {len(rec.signals)} signals, "
          f"{rec.provenance['wall_time_s']:.2f} s wall -> {out}")
    return 0


def _cmd_verify(args: argparse.Namespace) -> int:
    from orchestrator.loader import load_system
    from orchestrator.verify import verify

    system = load_system(args.system)
    if args.stop is not None:
        system.stop = args.stop
    agg = {}
    for it in args.aggregate or []:
        k, sep, v = it.partition("=")
        if not sep:
            raise UserError(f"--aggregate {it!r}: expected SIGNAL=sample|sum")
        agg[k.strip()] = v.strip()
    report = verify(system, rel_tol=args.rel_tol, engine_abs=args.engine_tol, engine_rel=args.engine_tol,
                    aggregate=agg, engine=not args.no_engine)
    print(report.table())
    return 0 if report.ok else 1


def _cmd_simulate(args: argparse.Namespace) -> int:
    from components.scenario import load_scenario, run_scenario, write_outputs

    overrides = {}
    if args.dwell is not None:
        overrides["dwell"] = args.dwell
    sc = load_scenario(args.scenario, overrides)
    if args.seed is not None:
        sc.seed = args.seed
    result = run_scenario(sc)
    paths = write_outputs(result, args.out, args.format)
    log = result.log
    print(f"{sc.name}: schedule {sc.schedule.name}, {log.n} samples over {log.time[-1]:.1f} s, "
          f"{len(result.controller.labels)} segment labels -> " + ", ".join(str(p) for p in paths))
    return 0


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
        k, _, v = it.partition("=")
        options[k] = v
    verdict = check_fmu(args.fmu, args.role, _parse_mapping(args.map), options, args.step)
    print(verdict.report())
    return 0 if verdict.ok else 1


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="calbench", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    b = sub.add_parser("build-fmus", help="rebuild the turntable and IMU FMUs from source now")
    b.add_argument("--fmi", type=int, choices=(2, 3), help="only this FMI version")
    b.set_defaults(func=_cmd_build_fmus)

    r = sub.add_parser("run", help="run a system file (TOML or SSP) and save its recording (Parquet)")
    r.add_argument("system", help="system file (.toml or .ssp)")
    r.add_argument("--out", help="recording file (default: <system name>.parquet)")
    r.add_argument("--stop", type=float, help="override the stop time [s]")
    r.set_defaults(func=_cmd_run)

    c = sub.add_parser("check-fmu", help="validate an FMU, check it against a role, smoke-test it")
    c.add_argument("fmu", help="the .fmu file")
    c.add_argument("--role", choices=("imu", "turntable"), help="role the FMU should fill")
    c.add_argument("--map", action="append", metavar="ROLE_NAME=FMU_NAME",
                   help="map a role variable onto the FMU's own name (repeatable)")
    c.add_argument("--option", action="append", metavar="KEY=VALUE",
                   help="role option, e.g. gyro_output=rate (imu) (repeatable)")
    c.add_argument("--step", type=float, default=0.005, help="step of the smoke test [s]")
    c.set_defaults(func=_cmd_check_fmu)

    v = sub.add_parser("verify", help="estimate the coupling error of the step (runs at h, h/2, h/4) "
                                      "and compare with libcosim; exit 1 if out of tolerance")
    v.add_argument("system", help="system file (.toml or .ssp)")
    v.add_argument("--rel-tol", type=float, default=1e-6, help="coupling error / signal RMS (1e-6)")
    v.add_argument("--engine-tol", type=float, default=1e-12, help="engine difference, abs and rel (1e-12)")
    v.add_argument("--aggregate", action="append", metavar="SIGNAL=sample|sum",
                   help="how a finer run maps onto the coarse grid (repeatable; adds to record.aggregate)")
    v.add_argument("--stop", type=float, help="override the stop time [s]")
    v.add_argument("--no-engine", action="store_true", help="skip the libcosim comparison")
    v.set_defaults(func=_cmd_verify)

    sm = sub.add_parser("simulate", help="run a calibration scenario (schedule on turntable + IMU FMUs) and "
                                          "write a calbench-log/1 log plus <STEM>.truth.json")
    sm.add_argument("scenario", help="scenario file (.toml)")
    sm.add_argument("--out", required=True, metavar="STEM", help="output stem: STEM.csv, STEM.json, STEM.truth.json")
    sm.add_argument("--dwell", type=float, help="override the schedule's dwell parameter [s]")
    sm.add_argument("--seed", type=int, help="override the IMU noise seed")
    sm.add_argument("--format", choices=("csv", "parquet", "both"), default="csv", help="sample file format")
    sm.set_defaults(func=_cmd_simulate)

    from components.cli_calibration import add_commands as _calibration_commands

    _calibration_commands(sub)
    __import__("components.procedures.cli", fromlist=["add_commands"]).add_commands(sub)
    __import__("components.navigation.cli", fromlist=["add_kf_commands"]).add_kf_commands(sub)
    __import__("components.campaign.cli", fromlist=["add_campaign_commands"]).add_campaign_commands(sub)

    dm = sub.add_parser("demo", help="simulate a run with a hidden effect, calibrate, compare, "
                                     "diagnose, add the winner, compare again, write the report")
    dm.add_argument("--out", default="calbench-demo", help="output folder")
    dm.add_argument("--seed", type=int, help="IMU noise seed (default: the scenario's)")
    dm.add_argument("--dwell", type=float, help="dwell per attitude [s] (default 8)")
    dm.set_defaults(func=_cmd_demo)

    t = sub.add_parser("tumble", help="co-simulate the table tumbling a navigation-grade IMU "
                                      "through the six axis-up attitudes and check its outputs")
    t.add_argument("--seed", type=int, default=1, help="IMU noise seed")
    t.add_argument("--dwell", type=float, default=10.0, help="static dwell per attitude [s]")
    t.add_argument("--step", type=float, default=0.005, help="communication step [s]")
    t.set_defaults(func=_cmd_tumble)
    return p


def main(argv: list[str] | None = None) -> int:
    from fmus.build import BuildError
    from orchestrator.errors import AlgebraicLoopError, RoleError, SimulationFault, SystemError_
    from components.logfile import LogFormatError
    from components.result import ResultFormatError
    from components.scenario import ScenarioError
    from components.schedule import ScheduleError


    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (UserError, BuildError, SystemError_, RoleError, SimulationFault, AlgebraicLoopError,
            LogFormatError, ResultFormatError, ScenarioError, ScheduleError) as e:
        print(f"calbench: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
