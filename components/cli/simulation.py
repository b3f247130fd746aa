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
    from components.errors import UserError
    from orchestrator.errors import RoleError

    try:
        result = run_scenario(sc)
    except RoleError as e:
        # the scenario's units against their roles: said with the file, whose [imu]/[turntable]
        # tables (fmu, mapping, role_options) are where a user mends it
        raise UserError(f"{args.scenario}: the units of its [imu] and [turntable] tables against their roles:\n{e}") from None
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
    if args.check:
        _check_against_truth(args, log, result.truth)
    return 0


def _check_against_truth(args, log, truth: dict) -> None:
    """The least squares with the default effects and every injected one, on the log just
    simulated, printed against the truth as ``procedure --simulate`` does: a check that the run
    holds what the scenario says (each error against its σ)."""
    from components.cli import json_option
    from components.diagnosis.noise_choice import choose_noise
    from components.errors import UserError
    from components.estimation.log_data import LogData
    from components.estimation.lsq import calibrate
    from components.model.effects import DEFAULT_EFFECTS, effect_of
    from components.model.noise import from_fmu_parameters
    from components.model.result import result_from_fit
    from components.procedures.common import errors_against_truth, print_errors

    if not log.has_table:
        raise UserError("simulate --check: the log has no table angles; check it with calbench kf or calibrate")
    effects = list(dict.fromkeys(list(DEFAULT_EFFECTS) + [effect_of(p).name for p in truth.get("effects", {})]))
    data = LogData.from_log(log)
    # the noise as calibrate takes it (pulse counts: their quantization from the count weight);
    # a scenario that injected slow noise knows it: judged under white noise every σ would be a
    # white-noise σ and half the parameters "off by more than 3 sigma" for no fault of the run
    noise, said, _ = choose_noise(None, data, effects=effects)
    injected = from_fmu_parameters(truth.get("noise", {}), *data.count_weight,
                                   source="the scenario's [imu.noise] (injected)")
    if injected.coloured and any(c.bias_instability or c.random_walk or c.gauss_markov for c in injected.channels):
        noise, said = injected, injected.source
    res = result_from_fit(calibrate(data, effects, noise=noise), effects, data)
    rows = errors_against_truth(res, truth)
    print(f"check: least squares with {', '.join(effects)}, noise {said}; errors against the truth of "
          f"{args.scenario}:")
    print_errors(rows)
    json_option.record(args, errors_against_truth=rows)


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
    sm.add_argument("--check", action="store_true",
                    help="calibrate the simulated log (default effects and the injected ones) and print the errors "
                         "against the truth, in σ")
    sm.set_defaults(func=_cmd_simulate)
