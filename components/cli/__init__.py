"""calbench: IMU calibration on turntables by FMI co-simulation — simulate, calibrate, compare,
diagnose, plan, verify.

The command line only dispatches: each module of this package registers its sub-commands
(``register(sub)``), parses, calls one library function of ``components`` and prints. Errors for
users come from ``components.errors`` (and ``orchestrator``'s and the FMU build's): one line on
stderr, exit 2 (bad input) or 3 (could not run: a unit or the build failed); everything else is a
bug and keeps its traceback. Every command takes ``--json [FILE|-]`` (``json_option``).
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
    from components.cli import json_option

    for parser in sub.choices.values():
        if not json_option.has(parser):
            json_option.add(parser)
    return p


def _error_classes():
    """(could-not-run classes, bad-input classes): a run that failed underway (a unit's fault, the
    FMU build, a table that never settled, a missing engine, no room to spill a long log) exits 3,
    any other user error 2."""
    from components.errors import CalbenchError, ScheduleFault, SpillError
    from fmus.errors import BuildError
    from orchestrator.errors import (
        LibcosimError,
        LibcosimUnsupported,
        NativeSpanFault,
        OrchestratorError,
        SimulationFault,
    )

    return ((SimulationFault, NativeSpanFault, LibcosimError, LibcosimUnsupported, BuildError, ScheduleFault,
             SpillError),
            (CalbenchError, OrchestratorError))


def main(argv: list[str] | None = None) -> int:
    from components.cli import json_option

    if argv is None:  # a command of its own (not a call from Python, which owns its process)
        from components.cli.allocator import keep_freed_memory

        keep_freed_memory()

    COULD_NOT_RUN, BAD_INPUT = _error_classes()
    args = build_parser().parse_args(argv)
    from components import progress

    # long computations show a bar on a terminal (after two seconds), never in a pipe or a file
    progress.enable(sys.stderr.isatty() and not getattr(args, "quiet", False))
    stdout = sys.stdout
    caught: list = []
    try:
        with warnings.catch_warnings(record=True) as caught, json_option.redirect_text(args):
            # numpy's and scipy's warnings are calbench's to handle: a user sees one line each, said
            # as what it is, never a raw stack of them
            warnings.simplefilter("always", RuntimeWarning)
            code, error = None, None  # stays None on a bug: no JSON then, the traceback speaks
            try:
                code = args.func(args)
                return code
            except COULD_NOT_RUN as e:
                code, error = json_option.COULD_NOT_RUN, str(e)
                print(f"calbench: error: could not run: {e}", file=sys.stderr)
                return code
            except BAD_INPUT as e:
                code, error = json_option.BAD_INPUT, str(e)
                print(f"calbench: error: {e}", file=sys.stderr)
                return code
            finally:
                if code is not None:
                    json_option.write(args, code, stdout, error)
    finally:
        # after the recording block: a warning passed on inside it would be recorded again, onto
        # the list being walked (a loop without end)
        _pass_on(caught)


def _pass_on(caught: list) -> None:
    """Each numerical warning as one line of calbench's; any other warning to the caller's filters."""
    seen = set()
    for w in caught:
        if issubclass(w.category, RuntimeWarning):
            if str(w.message) not in seen:
                seen.add(str(w.message))
                print(f"calbench: warning: a numerical step warned ({w.message}, in "
                      f"{w.filename.rsplit('/', 1)[-1]}:{w.lineno}); the results above may be affected: please "
                      "report it with the input", file=sys.stderr)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)

if __name__ == "__main__":
    sys.exit(main())
