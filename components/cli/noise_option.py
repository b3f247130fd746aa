"""The ``--noise SPEC`` option that calibrate, compare, diagnose, add and plan share
(components.diagnosis.noise_choice says what each SPEC means)."""
from __future__ import annotations

HELP = ("noise model (repeatable, applied in order): identify | white | navigation | tactical | a noise "
        ".json file | NAME=VALUE, e.g. acc.noise.bi='10 ug' (default: the model's own, else white noise "
        "from the static data; pulse counts: identified)")


def add(parser, default: str | None = None) -> None:
    """``default``: what the command takes without --noise, when not the model's or the data's."""
    text = HELP if default is None else HELP.split(" (default:")[0] + f" (default: {default})"
    parser.add_argument("--noise", action="append", metavar="SPEC", help=text)
