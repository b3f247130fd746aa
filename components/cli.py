"""The ``calbench`` command line."""
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


def _cmd_tumble(args: argparse.Namespace) -> int:
    from components.tumble import run_tumble

    return run_tumble(seed=args.seed, dwell=args.dwell, step=args.step)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="calbench", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    b = sub.add_parser("build-fmus", help="rebuild the turntable and IMU FMUs from source now")
    b.add_argument("--fmi", type=int, choices=(2, 3), help="only this FMI version")
    b.set_defaults(func=_cmd_build_fmus)

    t = sub.add_parser("tumble", help="co-simulate the table tumbling a navigation-grade IMU "
                                      "through the six axis-up attitudes and check its outputs")
    t.add_argument("--seed", type=int, default=1, help="IMU noise seed")
    t.add_argument("--dwell", type=float, default=10.0, help="static dwell per attitude [s]")
    t.add_argument("--step", type=float, default=0.005, help="communication step [s]")
    t.set_defaults(func=_cmd_tumble)
    return p


def main(argv: list[str] | None = None) -> int:
    from fmus.build import BuildError

    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (UserError, BuildError) as e:
        print(f"calbench: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
