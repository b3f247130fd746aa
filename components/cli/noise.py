"""``calbench noise LOG [--model RESULT.json]``: the residual's Allan deviation per channel in the
static runs, with confidence intervals, and the composite noise model identified from it and
from the whole log; ``--out NOISE.json`` writes the model for ``--noise NOISE.json``."""
from __future__ import annotations

import argparse
import json

import numpy as np


def _cmd_noise(args: argparse.Namespace) -> int:
    from components.diagnosis.noise_choice import held_terms, identification_known, white_fit
    from components.diagnosis.noise_id import identify_noise
    from components.errors import UserError
    from components.estimation.log_data import LogData
    from components.logs.logfile import read_log
    from components.model.effects import parse_effects
    from components.model.noise import CHANNELS, TERM_OF_NAME, TERMS, sensor_of
    from components.model.result import CalibrationResult

    bad = [spec for spec in args.noise or [] if "=" not in spec]
    if bad:
        raise UserError(f"noise: --noise {bad[0]!r}: expected a term given as NAME=VALUE (held while the rest is "
                        "identified), e.g. gyro.noise.arw='0.002 deg/sqrt(h)'")
    held = held_terms(args.noise)   # (a term's name, unit or value wrong: its UserError before the log is read)
    log = read_log(args.log, lean=True)
    if not log.has_table:
        raise UserError(f"noise: {args.log} has no table angles: noise identification works on the residual of a "
                        "fit over the whole log, which needs them; identify the IMU's noise on a table log (or give "
                        "it with --noise / the log's imu.noise)")
    data = LogData.from_log(log)
    try:
        effects = parse_effects(args.effects) if args.effects else None
    except ValueError as e:
        raise UserError(f"--effects: {e}") from None
    terms = None
    if args.terms:
        terms = []
        for t in args.terms.split(","):
            if t.strip() not in TERM_OF_NAME:
                raise UserError(f"--terms {t.strip()!r}: expected some of {', '.join(TERM_OF_NAME)}")
            terms.append(TERM_OF_NAME[t.strip()])
        terms = tuple(dict.fromkeys(terms))
    if args.model:
        model = CalibrationResult.load(args.model)
        print(f"residual of the model {args.model} ({', '.join(model.effects)})")
    else:
        model = white_fit(data, effects)
        print(f"residual of a white-noise fit of {', '.join(model.effects)} on this log")
    known = identification_known(data, held)
    if args.noise:
        print(f"held as given: {', '.join(args.noise)}")
    try:
        ident = identify_noise(data, model, known=known, bootstrap=args.bootstrap,
                               **({"terms": terms} if terms else {}))
    except ValueError as e:
        raise UserError(f"noise: {args.log}: {e}") from None
    print(f"{ident.static_runs} static runs")
    allan = {}
    for k, c in enumerate(ident.channels):
        av = c.fast.allan
        lo, hi = av.interval()
        model_adev = np.sqrt(c.noise.avar_realised(av.tau))
        unit, scale = TERMS[sensor_of(k)]["bias_instability"][2:]
        print(f"{CHANNELS[k]}: Allan deviation [{unit}] (68 % interval from the equivalent degrees of freedom) "
              "and the identified model")
        print(f"  {'tau [s]':>9s} {'adev':>11s} {'low':>11s} {'high':>11s} {'model':>11s}")
        for i in range(len(av.tau)):
            print(f"  {av.tau[i]:9.4g} {av.adev[i] / scale:11.4g} {lo[i] / scale:11.4g} {hi[i] / scale:11.4g} "
                  f"{model_adev[i] / scale:11.4g}")
        allan[CHANNELS[k]] = {"tau_s": av.tau.tolist(), "adev": av.adev.tolist(), "low": lo.tolist(),
                              "high": hi.tolist(), "edf": av.edf.tolist(), "model_adev": model_adev.tolist(),
                              "unit": "rad/s" if k < 3 else "m/s2"}
    print("\n".join(ident.table()))
    for note in ident.notes:
        print(f"note: {note}")
    out = ident.model.to_dict()
    out["presence_tests"] = ident.presence_tests()
    out["allan"] = allan
    out["log"] = str(args.log)
    if args.out:
        with open(args.out, "w") as f:
            json.dump(out, f, indent=1)
        print(f"-> {args.out} (use it with --noise {args.out})")
    from components.cli import json_option

    json_option.record(args, **out)
    if args.report:
        from components.diagnosis.compare import compare
        from components.diagnosis.report import build_report

        comp = compare(data, model, fitted_parameters=0, noise=ident.model)
        html_path, _ = build_report(args.report, title=f"calbench noise: {args.log}", comparison=comp,
                                    noise=ident, provenance={"log": str(args.log), "model": args.model or
                                                             "white-noise fit of " + ", ".join(model.effects)})
        print(f"report: {html_path}")
    return 0


def register(sub) -> None:
    n = sub.add_parser("noise", help="identify the noise: Allan deviation of the residual in the static runs "
                                     "and a composite model (quantization, white, bias instability, random walk)")
    n.add_argument("log", help="the log (either file of the pair, or the stem)")
    n.add_argument("--model", help="calibration result whose residual is analysed (default: a white-noise fit of "
                                   "--effects on this log)")
    n.add_argument("--effects", help="effects of that default fit (default: bias, scale factor, misalignment)")
    n.add_argument("--terms", help="terms to look for, comma list of q, arw (vrw), bi, rrw (default: all)")
    n.add_argument("--noise", action="append", metavar="NAME=VALUE",
                   help="a term given (e.g. gyro.noise.arw='0.002 deg/sqrt(h)', a datasheet's ARW where pulse counts "
                        "hide the white level), held at its value while the rest is identified; repeatable")
    n.add_argument("--bootstrap", type=int, default=30, help="parametric bootstrap replicates for the σ (30)")
    n.add_argument("--out", help="write the noise model (JSON) for --noise")
    from components.cli import json_option

    json_option.add(n, "write the Allan deviations and the model as JSON to FILE, or stdout with '-'")
    n.add_argument("--report", metavar="PAGE.html", help="write the HTML page: the model against the log under the "
                                                         "identified noise, the Allan deviations with the model")
    n.set_defaults(func=_cmd_noise)
