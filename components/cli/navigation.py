"""``calbench kf CONFIG LOG --out RESULT.json`` (or ``--simulate SCENARIO`` instead of LOG)."""
from __future__ import annotations

import argparse


def _cmd_kf(args: argparse.Namespace) -> int:
    from components.errors import UserError
    from components.logs.logfile import read_log
    from components.navigation.configs import load_config
    from components.navigation.system import calibrate_system

    try:
        cfg = load_config(args.config)
    except (ValueError, OSError) as e:
        raise UserError(f"kf: configuration {args.config}: {e}") from None
    if args.simulate and args.log:
        raise UserError("kf: give a LOG or --simulate SCENARIO, not both")
    if args.simulate:
        from components.simulation.run import run_scenario
        from components.simulation.scenario import load_scenario

        log = run_scenario(load_scenario(args.simulate), progress=False).log
        source = args.simulate
    elif args.log:
        log = read_log(args.log)
        source = args.log
    else:
        raise UserError("kf: give a LOG or --simulate SCENARIO")
    try:
        res, _ = calibrate_system(log, cfg)
    except ValueError as e:  # a window no label matches, no rest to align on, ...
        raise UserError(f"kf: {source} with configuration {cfg.name}: {e}") from None
    res.save(args.out)
    for p, v in res.values.items():
        from components.model.effects import effect_of

        unit, k = effect_of(p).display
        print(f"{p:18s} {v / k:12.4f} ± {res.sigmas[p] / k:9.4f} {unit}")
    print(f"wrote {args.out} ({res.method}, config {cfg.name})")
    return 0


def register(sub) -> None:
    k = sub.add_parser("kf", help="system-level Kalman-filter calibration (navigation velocity "
                                  "error on a stationary base): seed_001, seed_001_single, "
                                  "seed_003, seed_003_joint, seed_003_external, psins19 or a "
                                  "configuration TOML")
    k.add_argument("config", help="ready-made configuration name or .toml")
    k.add_argument("log", nargs="?", help="the log (either file of the pair, or the stem)")
    k.add_argument("--simulate", help="simulate this scenario file instead of reading a log")
    k.add_argument("--out", required=True, help="result file (JSON)")
    k.set_defaults(func=_cmd_kf)
