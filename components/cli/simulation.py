"""``calbench simulate SCENARIO --out STEM``: run a scenario and write the log and its truth."""
from __future__ import annotations

import argparse


def _cmd_simulate(args: argparse.Namespace) -> int:
    from components.simulation.run import run_scenario, write_outputs
    from components.simulation.scenario import load_scenario

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
    for line in injection_notes(result.truth):
        print(line)
    from components.cli import json_option

    json_option.record(args, scenario=sc.name, schedule=sc.schedule.name, samples=int(log.n),
                       duration_s=float(log.time[-1]), out=[str(p) for p in paths],
                       not_injected=result.truth.get("not_injected", {}))
    return 0


def injection_notes(truth: dict) -> list[str]:
    """What a run's IMU could not take, as the truth file records it."""
    lost = truth.get("not_injected", {})
    out = []
    for kind in ("effects", "noise"):
        if lost.get(kind):
            out.append(f"not injected (the IMU FMU has no parameter for them; see docs/supplier.md): {kind} "
                       f"{', '.join(lost[kind])}")
    if lost.get("seed"):
        out.append("the IMU FMU takes no seed: every run of it draws the same noise (or has none)")
    return out


def register(sub) -> None:
    sm = sub.add_parser("simulate", help="run a calibration scenario (schedule on turntable + IMU FMUs) and "
                                          "write a calbench-log/1 log plus <STEM>.truth.json")
    sm.add_argument("scenario", help="scenario file (.toml)")
    sm.add_argument("--out", required=True, metavar="STEM", help="output stem: STEM.csv, STEM.json, STEM.truth.json")
    sm.add_argument("--dwell", type=float, help="override the schedule's dwell parameter [s]")
    sm.add_argument("--seed", type=int, help="override the IMU noise seed")
    sm.add_argument("--format", choices=("csv", "parquet", "both"), default="csv", help="sample file format")
    sm.set_defaults(func=_cmd_simulate)
