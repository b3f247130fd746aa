"""``calbench plan``: the Cramér–Rao bound per parameter of a schedule (or a log's motion) for a
noise model, before running it; optionally the system-level filter's observability."""
from __future__ import annotations

import argparse

from components.cli import json_option, noise_option


def _cmd_plan(args: argparse.Namespace) -> int:
    from pathlib import Path

    import numpy as np

    from components.diagnosis.noise_choice import choose_noise
    from components.errors import UserError
    from components.estimation.crb import cramer_rao, positions_cramer_rao
    from components.estimation.log_data import LogData
    from components.logs.logfile import log_stem, read_log
    from components.model.effects import DEFAULT_EFFECTS, DEG, UG, effect_of, parse_effects
    from components.model.excitation import needs
    from components.model.noise import describe, from_terms, grade
    from components.simulation.run import schedule_motion_log

    try:
        effects = parse_effects(args.effects) if args.effects else list(DEFAULT_EFFECTS)
    except ValueError as e:
        raise UserError(f"--effects: {e}") from None
    noise = grade(args.grade)
    by_hand = {}
    for opt, name, scale in (("arw", "gyro.noise.arw", DEG / 60), ("vrw", "acc.noise.vrw", UG),
                             ("gyro_bi", "gyro.noise.bi", DEG / 3600), ("acc_bi", "acc.noise.bi", UG)):
        if getattr(args, opt) is not None:
            by_hand[name] = getattr(args, opt) * scale
    noise = from_terms(by_hand, noise, noise.source + (" with " + ", ".join(by_hand) if by_hand else ""))
    if args.noise:
        if "identify" in args.noise or "white" in args.noise:
            raise UserError("plan: --noise identify/white need a log with noise; give a grade, a noise file or "
                            "NAME=VALUE terms")
        noise, _, _ = choose_noise(args.noise, None, base=noise)
    target = args.schedule
    # a .toml is a schedule (a log of the same stem beside it is not what was named)
    stem = str(log_stem(target))  # ('run.v2' is a stem: its files are run.v2.json and run.v2.csv)
    is_log = Path(target).suffix.lower() != ".toml" and Path(stem + ".json").exists() and (
        Path(stem + ".csv").exists() or Path(stem + ".parquet").exists())
    if is_log:
        log = read_log(target)
    else:
        print(f"simulating schedule {target} (noise- and error-free) for its motion ...")
        log = schedule_motion_log(target, args.dwell)
    data = LogData.from_log(log)
    held: dict = {}
    if log.has_table:
        crb = cramer_rao(data, effects, noise)
    else:
        # the rests' attitudes are unknowns of their own: a table schedule's bound would be
        # several times too optimistic for such a session
        print(f"{target} has no table angles: the bound of the positions method (each rest's attitude estimated), "
              "at the attitudes this log's fit finds")
        crb, held = positions_cramer_rao(data, effects, noise)
    hours = (log.time[-1] - log.time[0] + log.dt) / 3600
    print(f"Cramér–Rao bound for {target}: {hours * 60:.1f} min, noise ({noise.source}): {describe(noise)}")
    print(f"{'parameter':22s} {'sigma':>12s}  unit       {'sigma x sqrt(hours)':>20s}")
    bounds = {}
    for p, s in crb.items():
        unit, scale = effect_of(p).display
        bounds[p] = {"sigma": float(s) if np.isfinite(s) else None, "display_unit": unit,
                     "display_sigma": float(s / scale) if np.isfinite(s) else None,
                     "needs": None if np.isfinite(s) else needs(p)}
        if not np.isfinite(s):
            print(f"{p:22s} {'not determined':>12s}  (the schedule needs {needs(p)})")
            continue
        print(f"{p:22s} {s / scale:12.4g}  {unit:10s} {s / scale * hours ** 0.5:20.4g}")
    for p, why in held.items():
        print(f"{p:22s} {'held':>12s}  ({why})")
    json_option.record(args, target=str(target), duration_s=float(hours * 3600), noise=describe(noise),
                       effects=effects, crb=bounds, held=held)
    if args.observability:
        from components.navigation.observability import plan_observability

        print(plan_observability(log, args.observability, noise.channels[0].white, noise.channels[3].white,
                                 effects))
    return 0


def register(sub) -> None:
    p = sub.add_parser("plan", help="Cramér–Rao bound per parameter of a schedule (or a log's motion) "
                                    "for a noise model, before running it")
    p.add_argument("schedule", help="ready-made schedule name, schedule .toml, or a log stem")
    p.add_argument("--effects", help="comma list of effects (default: bias, scale factor, misalignment)")
    p.add_argument("--grade", choices=("navigation", "tactical"), default="navigation",
                   help="the noise of a typical grade: white, bias instability (flicker) and random walk")
    p.add_argument("--arw", type=float, help="gyro ARW [deg/sqrt(h)]")
    p.add_argument("--vrw", type=float, help="accelerometer VRW [ug/sqrt(Hz)]")
    p.add_argument("--gyro-bi", type=float, help="gyro bias instability [deg/h]")
    p.add_argument("--acc-bi", type=float, help="accelerometer bias instability [ug]")
    p.add_argument("--dwell", type=float, help="override the schedule's dwell [s]")
    noise_option.add(p, default="the --grade's noise, with --arw/--vrw/--gyro-bi/--acc-bi on top; a noise file "
                              "replaces it, NAME=VALUE terms go on top")
    p.add_argument("--observability", metavar="CONFIG",
                   help="also the system-level filter's PWCS/SVD observability and its covariance "
                        "(white noise of the grade): a kf configuration (seed_003, ...: each stage on "
                        "its window) or 'effects' (the --effects on the whole run)")
    p.set_defaults(func=_cmd_plan)
