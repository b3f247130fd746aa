"""``calbench plan``: the Cramér–Rao bound per parameter of a schedule (or a log's motion) for a
noise model, before running it; optionally the system-level filter's observability."""
from __future__ import annotations

import argparse


def _cmd_plan(args: argparse.Namespace) -> int:
    from pathlib import Path

    from components.errors import UserError
    from components.estimation.crb import NoiseModel, cramer_rao
    from components.estimation.log_data import LogData
    from components.logs.logfile import read_log
    from components.model.effects import DEFAULT_EFFECTS, DEG, UG, effect_of, parse_effects
    from components.simulation.run import schedule_motion_log

    try:
        effects = parse_effects(args.effects) if args.effects else list(DEFAULT_EFFECTS)
    except ValueError as e:
        raise UserError(f"--effects: {e}") from None
    noise = NoiseModel.navigation_grade() if args.grade == "navigation" else NoiseModel(
        gyro_arw=0.1 * DEG / 60, acc_vrw=50 * UG, gyro_bi=1 * DEG / 3600 * 0.3, acc_bi=50 * UG)
    noise = NoiseModel(
        gyro_arw=args.arw * DEG / 60 if args.arw is not None else noise.gyro_arw,
        acc_vrw=args.vrw * UG if args.vrw is not None else noise.acc_vrw,
        gyro_bi=args.gyro_bi * DEG / 3600 if args.gyro_bi is not None else noise.gyro_bi,
        acc_bi=args.acc_bi * UG if args.acc_bi is not None else noise.acc_bi,
        bi_tau=args.bi_tau)
    target = args.schedule
    is_log = Path(target).with_suffix(".json").exists() and (
        Path(target).with_suffix(".csv").exists() or Path(target).with_suffix(".parquet").exists())
    if is_log:
        log = read_log(target)
    else:
        print(f"simulating schedule {target} (noise- and error-free) for its motion ...")
        log = schedule_motion_log(target, args.dwell)
    data = LogData.from_log(log)
    crb = cramer_rao(data, effects, noise)
    hours = (log.time[-1] - log.time[0] + log.dt) / 3600
    print(f"Cramér–Rao bound for {target}: {hours * 60:.1f} min, noise: ARW {noise.gyro_arw / (DEG / 60):.4g} deg/sqrt(h), "
          f"VRW {noise.acc_vrw / UG:.3g} ug/sqrt(Hz), bias instability {noise.gyro_bi / (DEG / 3600):.3g} deg/h "
          f"and {noise.acc_bi / UG:.3g} ug (tau {noise.bi_tau:g} s)")
    print(f"{'parameter':22s} {'sigma':>12s}  unit       {'sigma x sqrt(hours)':>20s}")
    for p, s in crb.items():
        unit, scale = effect_of(p).display
        print(f"{p:22s} {s / scale:12.4g}  {unit:10s} {s / scale * hours ** 0.5:20.4g}")
    if args.observability:
        from components.navigation.observability import plan_observability

        print(plan_observability(log, args.observability, noise.gyro_arw, noise.acc_vrw, effects))
    return 0


def register(sub) -> None:
    p = sub.add_parser("plan", help="Cramér–Rao bound per parameter of a schedule (or a log's motion) "
                                    "for a noise model, before running it")
    p.add_argument("schedule", help="ready-made schedule name, schedule .toml, or a log stem")
    p.add_argument("--effects", help="comma list of effects (default: bias, scale factor, misalignment)")
    p.add_argument("--grade", choices=("navigation", "tactical"), default="navigation")
    p.add_argument("--arw", type=float, help="gyro ARW [deg/sqrt(h)]")
    p.add_argument("--vrw", type=float, help="accelerometer VRW [ug/sqrt(Hz)]")
    p.add_argument("--gyro-bi", type=float, help="gyro bias instability [deg/h]")
    p.add_argument("--acc-bi", type=float, help="accelerometer bias instability [ug]")
    p.add_argument("--bi-tau", type=float, default=100.0, help="bias-instability correlation time [s]")
    p.add_argument("--dwell", type=float, help="override the schedule's dwell [s]")
    p.add_argument("--observability", metavar="CONFIG",
                   help="also the system-level filter's PWCS/SVD observability and its covariance "
                        "(white noise of the grade): a kf configuration (seed_003, ...: each stage on "
                        "its window) or 'effects' (the --effects on the whole run)")
    p.set_defaults(func=_cmd_plan)
