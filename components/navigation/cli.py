"""``calbench kf CONFIG LOG --out RESULT.json`` (or ``--simulate SCENARIO`` instead of LOG)."""
from __future__ import annotations

import argparse


def _cmd_kf(args: argparse.Namespace) -> int:
    from components.logfile import read_log
    from components.navigation.configs import load_config
    from components.navigation.system import calibrate_system

    cfg = load_config(args.config)
    if args.simulate:
        from components.scenario import load_scenario, run_scenario

        log = run_scenario(load_scenario(args.simulate), progress=False).log
    elif args.log:
        log = read_log(args.log)
    else:
        raise SystemExit("kf: give a LOG or --simulate SCENARIO")
    res, _ = calibrate_system(log, cfg)
    res.save(args.out)
    for p, v in res.values.items():
        from components.effects import effect_of

        unit, k = effect_of(p).display
        print(f"{p:18s} {v / k:12.4f} ± {res.sigmas[p] / k:9.4f} {unit}")
    print(f"wrote {args.out} ({res.method}, config {cfg.name})")
    return 0


def add_kf_commands(sub) -> None:
    k = sub.add_parser("kf", help="system-level Kalman-filter calibration (navigation velocity "
                                  "error on a stationary base): seed_001, seed_001_single, "
                                  "seed_003, psins19 or a configuration TOML")
    k.add_argument("config", help="ready-made configuration name or .toml")
    k.add_argument("log", nargs="?", help="the log (either file of the pair, or the stem)")
    k.add_argument("--simulate", help="simulate this scenario file instead of reading a log")
    k.add_argument("--out", required=True, help="result file (JSON)")
    k.set_defaults(func=_cmd_kf)
