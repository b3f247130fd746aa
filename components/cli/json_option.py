"""``--json [FILE|-]`` on every command, for scripts and CI: one JSON object per run with the
command, its exit code and the numbers it printed (each command adds its own with :func:`record`).
``--json -`` (or ``--json`` alone) writes the object to stdout and moves the human text to stderr,
so a script can parse stdout whole.

Exit codes, the same on every command (README "Exit codes"):
0 ok, 1 a check failed (a threshold, a verdict, a refused FMU, a failed filter check),
2 bad input (a file, an option), 3 could not run (a unit or the FMU build failed, a missing engine).
"""
from __future__ import annotations

import json
import sys

OK, CHECK_FAILED, BAD_INPUT, COULD_NOT_RUN = 0, 1, 2, 3

HELP = "write what the command found as one JSON object to FILE, or to stdout with '-' (the text then goes to stderr)"


def add(parser, help: str = HELP) -> None:
    parser.add_argument("--json", nargs="?", const="-", metavar="FILE|-", help=help)


def has(parser) -> bool:
    return "--json" in parser._option_string_actions


def record(args, **fields) -> None:
    """Add *fields* to the JSON object of this run (later calls add to or replace earlier keys)."""
    if not hasattr(args, "_json_record"):
        args._json_record = {}
    args._json_record.update(fields)


def to_stdout(args) -> bool:
    return getattr(args, "json", None) == "-"


def write(args, exit_code: int, stdout, error: str | None = None) -> None:
    """Write the run's object (``command``, ``exit_code``, ``error`` when there was one, then what the
    command recorded) to ``args.json``; *stdout* is the real stdout (the text went to stderr)."""
    target = getattr(args, "json", None)
    if not target:
        return
    doc = {"command": args.command, "exit_code": exit_code}
    if error is not None:
        doc["error"] = error
    doc.update(getattr(args, "_json_record", {}))
    text = json.dumps(_plain(doc), indent=1, allow_nan=False)
    if target == "-":
        stdout.write(text + "\n")
        stdout.flush()
    else:
        with open(target, "w") as f:
            f.write(text + "\n")


def _plain(x):
    """numpy scalars and arrays as JSON numbers and lists; NaN and infinity as null (JSON has neither)."""
    import math

    import numpy as np

    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, (str, int, float, bool)) or x is None:
        return x
    return str(x)


def redirect_text(args):
    """A context that sends the command's printed text to stderr when its JSON goes to stdout."""
    import contextlib

    return contextlib.redirect_stdout(sys.stderr) if to_stdout(args) else contextlib.nullcontext()
