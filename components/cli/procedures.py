"""``calbench procedure NAME LOG --out RESULT.json`` and ``calbench procedure NAME --simulate
SCENARIO [--out RESULT.json] [--log-out STEM]``: one of the classical procedures on a log, or on
the log of a freshly simulated scenario (then the errors against the injected truth are
printed). ``latitude --simulate`` drives the co-simulation spin by spin."""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path


def _print_values(res) -> None:
    from components.model.effects import effect_of

    print(f"{'parameter':22s} {'value':>14s} {'sigma':>12s}  unit")
    for p, v in res.values.items():
        unit, scale = effect_of(p).display
        print(f"{p:22s} {v / scale:+14.6g} {res.sigmas.get(p, float('nan')) / scale:12.3g}  {unit}")


def _print_latitude(res) -> None:
    lp = res.extra["latitude_procedure"]
    arcmin = math.pi / 180 / 60
    az_sigma = f" (sigma {lp['sigma_azimuth_rad'] / arcmin:.3f} arcmin)" if "sigma_azimuth_rad" in lp else ""
    print(f"latitude = {math.degrees(lp['latitude_rad']):.6f} deg "
          f"(sigma {lp['sigma_latitude_rad'] / arcmin:.3f} arcmin), azimuth = "
          f"{math.degrees(lp['azimuth_rad']):.5f} deg{az_sigma}, vertical corrections: {lp['iterations']}")


def _cmd_procedure(args: argparse.Namespace) -> int:
    from components.errors import UserError
    from components.logs.logfile import read_log, write_log
    from components.procedures import PROCEDURES, get
    from components.procedures.common import errors_against_truth, print_errors

    name = args.name
    if name not in PROCEDURES:
        raise UserError(f"unknown procedure {name!r}; expected one of {', '.join(PROCEDURES)}")
    if (args.log is None) == (args.simulate is None):
        raise UserError("give either a LOG or --simulate SCENARIO")
    if args.log is not None and args.out is None:
        raise UserError("--out RESULT.json is required with a LOG")  # said before the work, not after it
    if args.log is not None and str(args.log).endswith(".toml"):
        raise UserError(f"{args.log}: a scenario, not a log; simulate it with --simulate {args.log}")
    opts = {}
    if args.beta is not None:
        if name != "cwccw":
            raise UserError("--beta applies to the cwccw procedure only")
        opts["beta"] = args.beta
    if args.static_labels is not None:
        if name != "cwccw":
            raise UserError("--static-labels applies to the cwccw procedure only")
        opts["static_labels"] = args.static_labels
    truth = None
    if args.simulate:
        from components.simulation.run import run_scenario
        from components.simulation.scenario import load_scenario

        ov = {"dwell": args.dwell} if args.dwell is not None else None
        sc = load_scenario(args.simulate, ov)
        if args.seed is not None:
            sc.seed = args.seed
        if name == "latitude":
            from components.procedures import latitude

            log, _, decisions = latitude.drive(sc, verbose=True)
            truth_lat = latitude.truth_of(sc)
        else:
            r = run_scenario(sc)
            log, truth = r.log, r.truth
        if args.log_out:
            paths = write_log(args.log_out, log)
            if truth is not None:
                Path(str(Path(args.log_out).with_suffix("")) + ".truth.json").write_text(json.dumps(truth, indent=1))
            print(f"log -> {', '.join(map(str, paths))}")
    else:
        log = read_log(args.log)
    try:
        res = get(name)(log, **opts)
    except ValueError as e:
        raise UserError(f"procedure {name}: {e}") from None
    _print_values(res)
    if name != "latitude":
        # the closed forms weigh every sample alike: under bias instability or random walk their
        # σ are too small (calibrate's least squares whitens with the identified noise)
        print("sigma: white noise per sample (the closed forms' own); under bias instability or random walk it is "
              "too small: calbench calibrate LOG --noise identify gives σ under the coloured noise")
    for note in res.extra.get("notes", []):
        print(f"note: {note}")
    if name == "latitude":
        _print_latitude(res)
    if args.simulate:
        print(f"errors against the truth of {args.simulate}:")
        if name == "latitude":
            from components.procedures import latitude

            err = latitude.errors(res, truth_lat)
            for k, v in err.items():
                if k != "iterations":  # a count, not an error: the latitude line says it
                    print(f"  {k:18s} {v:+.4f}")
            res.extra["errors_against_truth"] = err
        else:
            rows = errors_against_truth(res, truth)
            print_errors(rows)
            res.extra["errors_against_truth"] = rows
    from components.cli import json_option
    from components.cli.calibration import result_json

    json_option.record(args, procedure=name, **result_json(res), out=args.out,
                       errors_against_truth=res.extra.get("errors_against_truth"))
    if args.out:
        res.save(args.out)
        print(f"-> {args.out}")
    return 0


def register(sub) -> None:
    from components.procedures import PROCEDURES

    p = sub.add_parser("procedure", help="a classical calibration procedure (closed forms of the seeds) "
                                         f"on a log or a simulated scenario: {', '.join(PROCEDURES)}")
    p.add_argument("name", help=f"procedure: {', '.join(PROCEDURES)}")
    p.add_argument("log", nargs="?", help="the log (either file of the pair, or the stem)")
    p.add_argument("--out", help="result file (JSON); required with a LOG")
    p.add_argument("--simulate", metavar="SCENARIO", help="simulate this scenario first (latitude: "
                                                          "drives it spin by spin) and print the errors")
    p.add_argument("--log-out", metavar="STEM", help="with --simulate: also write the simulated log")
    p.add_argument("--dwell", type=float, help="with --simulate: override the schedule's dwell [s]")
    p.add_argument("--seed", type=int, help="with --simulate: override the IMU noise seed")
    p.add_argument("--beta", type=float, help="cwccw: scale acceleration [m/s^2] (default: the log's gravity)")
    p.add_argument("--static-labels", help="cwccw: regular expression the static segments' labels must match")
    p.set_defaults(func=_cmd_procedure)
