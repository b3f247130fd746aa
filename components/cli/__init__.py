"""calbench: IMU calibration on turntables by FMI co-simulation — simulate, calibrate, compare,
diagnose, plan, verify.

The command line only dispatches: each module of this package registers its sub-commands
(``register(sub)``), parses, calls one library function of ``components`` and prints. Errors for
users come from ``components.errors`` (and ``orchestrator``'s and the FMU build's): one line on
stderr, exit 2; everything else is a bug and keeps its traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys
import warnings

# in the order the commands appear in --help
COMMAND_MODULES = ("cosim", "simulation", "log_import", "calibration", "diagnosis", "noise", "report", "planning", "procedures",
                   "navigation", "campaign", "demo")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="calbench", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(f"components.cli.{name}").register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    from components.errors import CalbenchError
    from fmus.build import BuildError
    from orchestrator.errors import OrchestratorError

    args = build_parser().parse_args(argv)
    with warnings.catch_warnings(record=True) as caught:
        # numpy's and scipy's warnings are calbench's to handle: a user sees one line each, said
        # as what it is, never a raw stack of them
        warnings.simplefilter("always", RuntimeWarning)
        try:
            return args.func(args)
        except (CalbenchError, OrchestratorError, BuildError) as e:
            print(f"calbench: error: {e}", file=sys.stderr)
            return 2
        finally:
            seen = set()
            for w in caught:
                if issubclass(w.category, RuntimeWarning) and str(w.message) not in seen:
                    seen.add(str(w.message))
                    print(f"calbench: warning: a numerical step warned ({w.message}, in "
                          f"{w.filename.rsplit('/', 1)[-1]}:{w.lineno}); the results above may be affected: please "
                          "report it with the input", file=sys.stderr)
                elif not issubclass(w.category, RuntimeWarning):
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


if __name__ == "__main__":
    sys.exit(main())
