"""``calbench report LOG --model RESULT.json``: one self-contained HTML page for the model on the
log — before and after from the result's ladder, where each model fails, the diagnosis with its
statuses explained, the noise, the provenance (components.diagnosis.report_run). ``add_option``
gives compare / diagnose / add their ``--report PAGE.html``."""
from __future__ import annotations

import argparse
import json

from components.cli import log_option, model_option, noise_option


def add_option(parser) -> None:
    parser.add_argument("--report", metavar="PAGE.html", help="also write the HTML report of the model on this log "
                                                              "(as `calbench report`)")


def load_truth(path: str, log=None) -> dict:
    """parameter -> SI value from a truth file written by `calbench simulate` (its "effects");
    with *log*, the truth must be of its run (:func:`_of_this_run`: a truth of another scenario
    gave errors of hundreds of σ without a word)."""
    from components.errors import UserError

    try:
        d = json.loads(open(path).read())
    except (OSError, ValueError) as e:
        raise UserError(f"--truth {path}: cannot read it as JSON ({e})") from None
    if not isinstance(d, dict) or not isinstance(d.get("effects"), dict):
        raise UserError(f"--truth {path}: no \"effects\" object (parameter -> SI value), expected the "
                        "STEM.truth.json `calbench simulate` writes")
    mismatch = _other_samples(d, log) if log is not None else None
    if mismatch:
        raise UserError(f"--truth {path}: the truth of {mismatch}, not of {log.source or 'the log'} (its samples' "
                        "SHA-256 differs); expected the STEM.truth.json `calbench simulate` wrote beside this log")
    if log is not None and not _of_this_run(d, log):
        sc = d.get("scenario")
        name = sc.get("name", "?") if isinstance(sc, dict) else "?"
        raise UserError(f"--truth {path}: the truth of scenario {name!r}, whose segments and length are not those "
                        f"of {log.source or 'the log'}; expected the STEM.truth.json `calbench simulate` wrote beside "
                        "this log")
    return {str(k): float(v) for k, v in d["effects"].items()}


def _other_samples(truth: dict, log) -> str | None:
    """What *truth* records of its samples when *log*'s are not them; None when they are or when
    the truth records none (older truth files: the segment check below decides)."""
    from pathlib import Path

    from components.model.result import file_sha256

    files = truth.get("samples_sha256")
    if not isinstance(files, dict) or not files or not log.source or not Path(log.source).exists():
        return None
    own = file_sha256(Path(log.source))
    if own in files.values():
        return None
    return "another run's samples (" + ", ".join(f"{k} {v[:12]}" for k, v in files.items()) + ")"


def _of_this_run(truth: dict, log) -> bool:
    """Is *truth* the run of *log*: the log's segment labels, run by run, the truth's schedule's,
    or else the same length within 1 % (a log cut or relabelled after the run)? Without segments
    in either, nothing to tell by: yes."""

    segs = [str(s.get("label")) for s in truth.get("segments", []) if isinstance(s, dict)]
    if not segs or log.segment is None or not log.n:
        return True
    runs = [label for _, _, label in log.segment.runs()]
    sched = [x for i, x in enumerate(segs) if i == 0 or x != segs[i - 1]]
    if runs == sched[:len(runs)]:
        return True
    stopped = (truth.get("run") or {}).get("stopped_at_s")
    length = float(log.time[-1] - log.time[0] + log.dt)
    return isinstance(stopped, (int, float)) and abs(stopped - length) <= 0.01 * max(stopped, length)


def _truth_provenance(path: str | None) -> dict:
    """The --truth file on the page's provenance: its path, SHA-256 and the run's seed."""
    if not path:
        return {}
    import json
    from pathlib import Path

    from components.model.result import file_sha256

    seed = json.loads(Path(path).read_text()).get("seed")
    return {"truth": {"file": str(path), "sha256": file_sha256(Path(path)), "seed": seed}}


def write(page: str, log, data, model, model_path: str | None, noise, **kw) -> None:
    from components.diagnosis.report_run import write_model_report

    html_path, _ = write_model_report(page, log, data, model, model_path=model_path, noise=noise, **kw)
    print(f"report: {html_path}")


def _cmd_report(args: argparse.Namespace) -> int:
    from components.diagnosis.noise_choice import choose_noise
    from components.errors import UserError
    from components.model.result import CalibrationResult

    log, data = log_option.read(args)
    if not data.has_table:
        raise UserError(f"report: {args.log} has no table angles: the page's heat map, time plot and noise need "
                        "them; use `calbench compare` and `calbench diagnose` on this log")
    model = CalibrationResult.load(args.model)
    baseline = CalibrationResult.load(args.baseline) if args.baseline else None
    noise, said, _ = choose_noise(args.noise, data, model)
    print(f"noise: {said}")
    # a result (or baseline) of another log is refitted here first, as compare and diagnose do:
    # its stored values shown on this log's residuals are neither model's fit
    model, _ = model_option.own(model, args.model, log, data, noise)
    if baseline is not None:
        baseline, _ = model_option.own(baseline, args.baseline, log, data, noise, say=False)
        if baseline.extra.get("refit_from"):
            print(f"the baseline {args.baseline} was fitted to another log: refitting its effects on this log first")
    truth = load_truth(args.truth, log) if args.truth else None
    if truth is not None:
        # in the frame the result's misalignments are estimated in (a system-level or positions
        # result works in the accelerometer-defined frame: the injected truth turned into it)
        from components.navigation.truth_frame import estimation_frame, truth_of_result

        frame = model.extra.get("truth_frame") or estimation_frame(list(model.values))
        truth = truth_of_result(truth, list(model.values), frame)
        if frame != "table":
            print("truth: turned into the accelerometer-defined frame the result's misalignments are estimated in")
    write(args.out, log, data, model, args.model, noise, diagnose_models=args.diagnose,
          identify=not args.no_noise, truth=truth, baseline=baseline, baseline_path=args.baseline,
          truth_complete=True, extra_provenance=_truth_provenance(args.truth))
    return 0


def register(sub) -> None:
    r = sub.add_parser("report", help="one self-contained HTML page: before/after, where each model fails, "
                                      "the diagnosis, the noise, the provenance")
    r.add_argument("log")
    r.add_argument("--model", required=True, help="calibration result (JSON); its ladder gives the before-model")
    r.add_argument("--out", default="report.html", help="the page (and its JSON twin beside it)")
    r.add_argument("--baseline", help="the before-model (default: the ladder's first rung refitted on this log)")
    r.add_argument("--diagnose", choices=("after", "both", "none"), default="after",
                   help="which models to diagnose (default: the result)")
    r.add_argument("--truth", help="STEM.truth.json of a simulated log: recovered values against it")
    r.add_argument("--no-noise", action="store_true", help="leave out the noise identification")
    noise_option.add(r)
    log_option.add(r)
    r.set_defaults(func=_cmd_report)
