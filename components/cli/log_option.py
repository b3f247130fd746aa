"""The ``--exclude`` option of the commands that read a log, and the reading itself: every such
command says what it leaves out and what it assumes about the table's encoder, in the same words."""
from __future__ import annotations

HELP = ("leave out a segment label or a time range T0:T1 [s] (repeatable); added to the log's own "
        "'exclude', mask, gaps and excluded segments")


def add(parser) -> None:
    parser.add_argument("--exclude", action="append", metavar="LABEL|T0:T1", help=HELP)


def parse_exclude(items: list[str] | None) -> list:
    """``--exclude`` values as the log's ``exclude`` items: labels, or [t0, t1] ranges."""
    from components.errors import UserError

    out: list = []
    for item in items or []:
        s = item.strip()
        if ":" in s:
            a, _, b = s.partition(":")
            try:
                t0, t1 = float(a), float(b)
            except ValueError:
                raise UserError(f"--exclude {item!r}: expected a segment label or a time range T0:T1 in "
                                "seconds") from None
            if not t0 < t1:
                raise UserError(f"--exclude {item!r}: expected T0 < T1")
            out.append([t0, t1])
        elif s:
            out.append(s)
        else:
            raise UserError("--exclude: empty value; expected a segment label or a time range T0:T1 [s]")
    return out


def read(args, *, say: bool = True, commands: bool = False):
    """(the MeasurementLog, its LogData with the exclusions applied) of ``args.log``; prints what
    is left out and, for a log with table angles, where the rest angles' uncertainty comes from.
    ``commands``: also read the commanded angles and extra columns (a replay through an FMU
    needs them; the estimators do not)."""
    from components.errors import UserError
    from components.estimation.log_data import LogData
    from components.estimation.rest_angles import resolution_note
    from components.logs.logfile import read_log

    log = read_log(args.log, lean=not commands)
    try:
        data = LogData.from_log(log, parse_exclude(getattr(args, "exclude", None)))
    except ValueError as e:
        raise UserError(str(e)) from None
    if say:
        from components.logs.angle_turns import said

        for line in describe(data) + ([said(log.turns_mended)] if log.turns_mended else []):
            print(line)
        if log.has_table:
            print(resolution_note(data.angles, data.encoder_resolution))
    import sys

    from components.estimation.semantics import check_semantics

    # the declared kinds and units against physics: a warning naming the evidence (stderr, so a
    # script's JSON on stdout stays whole), before a fit that would converge on nonsense
    for line in check_semantics(data, log):
        print(f"calbench: warning: {line}", file=sys.stderr)
    data.release()  # the pages these whole-log checks touched (a spilled log: components.logs.spill)
    return log, data


def describe(data) -> list[str]:
    """What the log leaves out, by reason (one line), or nothing."""
    if not data.left_out:
        return []
    import numpy as np

    n = len(data.time) - int(np.count_nonzero(data.usable))
    parts, kinds = [], []
    for k, v in data.left_out.items():
        if k.endswith("(kind excluded)"):
            kinds.append(v)
        else:
            parts.append(f"{k}: {v}")
    if kinds:
        parts.append(f"{len(kinds)} segment label(s) of kind excluded: {sum(kinds)}")
    return [f"left out: {n} of {len(data.time)} samples ({', '.join(parts)})"]
