"""The model against the measurement: ``calbench compare`` (residuals, χ²/dof, where it fails),
``calbench diagnose`` (which effect is missing) and ``calbench add`` (add it, refit, the ladder)."""
from __future__ import annotations

import argparse

import numpy as np

from components.cli import json_option, log_option, model_option, noise_option
from components.cli import report as report_option
from components.cli.json_option import CHECK_FAILED, OK

_load_model = model_option.load


def _fail_above(args, chi2_per_dof: float) -> int:
    """Exit status of ``--fail-above CHI2``: 1 when the model's χ²/dof exceeds it (said)."""
    limit = getattr(args, "fail_above", None)
    if limit is not None and chi2_per_dof > limit:
        print(f"--fail-above {limit:g}: chi2/dof {chi2_per_dof:.3f} exceeds it: exit 1")
        return CHECK_FAILED
    return OK


def _print_comparison(c, coloured: bool = False) -> None:
    against = "whitened with the noise model" if coloured else "against the white-noise level"
    print(f"chi2/dof (block sums {against}) = {c.chi2_per_dof:.3f} "
          f"({c.dof} dof, 1 ± {(2 / max(c.dof, 1)) ** 0.5:.3f} for a correct model)")
    print(f"{'channel':8s} {'rms':>11s} {'noise':>11s} {'rms/noise':>9s} {'chi2/dof':>9s} "
          f"{'fit %':>9s} {'white p':>8s}")
    for k, v in c.channels.items():
        print(f"{k:8s} {v['rms']:11.4g} {v['noise_floor']:11.4g} {v['rms'] / v['noise_floor']:9.3f} "
              f"{v['chi2_per_dof']:9.3f} {v['fit_percent']:9.4f} {v['whiteness_p']:8.3f}")
    free = [k for k, v in c.channels.items() if v.get("noise_free")]
    if free:
        print(f"{', '.join(free)}: no noise in these data (the residual's sample differences are rounding): their χ² "
              "weighs rounding against a numerical floor, not a misfit against noise; read their rms")
    from components.diagnosis.misfit import chi2_band, chi2_band_note

    note = chi2_band_note(c.chi2_per_dof, c.dof)
    if note:
        # too good to be true: the noise model, not the model, is what is wrong
        print(note)
    if c.chi2_per_dof > chi2_band(c.dof)[1]:
        from components.cli.calibration import white_level_warnings

        for line in white_level_warnings(c.no_white_level, c.white_poorly_read):
            print(line)
    if c.misfits is not None:
        # only what is significant given how many cells were looked at (components.diagnosis.misfit)
        print("where it fails: " + "\n                ".join(c.misfits.lines()))


def _cmd_compare(args: argparse.Namespace) -> int:
    from components.diagnosis.compare import compare
    from components.diagnosis.noise_choice import choose_noise
    from components.diagnosis.residual_export import write_block_residuals, write_residuals
    from components.errors import UserError
    from components.model.result import fitted_on

    log, data = log_option.read(args, commands=args.servo is not None or args.model.endswith((".toml", ".ssp")))
    if args.report and (not data.has_table or args.model.endswith((".toml", ".ssp"))):
        # said before the comparison, not after printing it all
        raise UserError("compare --report: the page needs a calibration result and a log with table angles")
    if not data.has_table:
        from components.diagnosis.compare_positions import compare_positions

        if args.model.endswith((".toml", ".ssp")) or args.servo is not None:
            raise UserError("compare: a log without table angles cannot drive an IMU or turntable FMU (its motion "
                            "between rests is not known); give a calibration result")
        model = _load_model(args.model)
        noise, said, _ = choose_noise(args.noise, data, model)
        print(f"noise: {said}")
        model, refit = model_option.own(model, args.model, log, data, noise)
        json_option.record(args, refit=refit)
        c = compare_positions(data, model, fitted_parameters=len(model.values) if fitted_on(model, log) else 0,
                              noise=noise)
        print("model: the rests' attitudes fitted with the model's parameters held (no table angles)")
    elif args.model.endswith((".toml", ".ssp")):
        # a system: its IMU unit (ours or a supplier's FMU) replayed on the log's motion
        from components.diagnosis.compare import assess
        from components.estimation.chunks import PlateAtSamples
        from components.simulation.replay import replay_imu

        noise, said, _ = choose_noise(args.noise, data)
        print(f"noise: {said}")
        motion = data.motion(data.geometry)
        c = assess(data, data.geometry, PlateAtSamples.of(motion), replay_imu(data, args.model, motion), noise=noise)
        print(f"model: the IMU unit of {args.model}, replayed on the log's motion")
    else:
        model = _load_model(args.model)
        noise, said, _ = choose_noise(args.noise, data, model)
        print(f"noise: {said}")
        model, refit = model_option.own(model, args.model, log, data, noise)
        json_option.record(args, refit=refit)
        c = compare(data, model, fitted_parameters=len(model.values) if fitted_on(model, log) else 0,
                    noise=noise)
    _print_comparison(c, noise is not None and noise.coloured)
    if args.servo is not None:
        _print_servo(log, None if args.servo == "builtin" else args.servo)
    json_option.record(args, **c.summary())
    if args.residuals:
        write_residuals(args.residuals, log, c)
    if args.block_residuals:
        write_block_residuals(args.block_residuals, c)
    if args.report:
        report_option.write(args.report, log, data, model, args.model, noise, diagnose_models="none")
    return _fail_above(args, c.chi2_per_dof)


def _print_servo(log, system_file) -> None:
    from components.errors import UserError
    from components.simulation.replay import replay_servo

    try:
        res = replay_servo(log, system_file)
    except ValueError as e:
        raise UserError(str(e)) from None
    src = system_file or "the built-in turntable FMU"
    print(f"servo: commanded angles replayed through {src}; measured − simulated encoder angle [arcsec]:")
    print(f"{'axis':8s} {'rms':>10s} {'max':>10s} {'rms moving':>11s} {'rms rest':>10s}")
    k = 180 * 3600 / np.pi
    for a, v in res.items():
        print(f"{a:8s} {v['rms'] * k:10.4g} {v['max'] * k:10.4g} {v['rms_moving'] * k:11.4g} {v['rms_rest'] * k:10.4g}")


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from components.diagnosis.candidate_notes import (
        LEGEND,
        RANKING_HEADER,
        candidate_notes_lines,
        ranking_line,
        verdict_lines,
    )
    from components.diagnosis.diagnose import NOISE_CANDIDATES, diagnose
    from components.diagnosis.noise_choice import choose_noise
    from components.errors import UserError
    from components.model.effects import parse_effects

    # the model and the candidates are checked before the log is read (an 8-hour log: a minute)
    model = _load_model(args.model)
    cands = None
    if args.candidates:
        names = [c.strip() for c in args.candidates.split(",") if c.strip()]
        noise_names = [c for c in names if c in NOISE_CANDIDATES]
        try:
            cands = parse_effects(",".join(c for c in names if c not in NOISE_CANDIDATES)) + noise_names
        except ValueError as e:
            raise UserError(f"--candidates: {e} (noise terms: {', '.join(NOISE_CANDIDATES)})") from None
    log, data = log_option.read(args)
    if args.report and not data.has_table:  # said before the diagnosis, not after printing it all
        raise UserError("diagnose --report: the page needs a log with table angles")
    noise, said, _ = choose_noise(args.noise, data, model)
    print(f"noise: {said}")
    model, refit = model_option.own(model, args.model, log, data, noise)
    d = diagnose(data, model, candidates=cands, alpha=args.alpha, noise=noise)
    print(f"model: {', '.join(model.effects)}; chi2/dof = {d.base_chi2_per_dof:.3f} over {d.rows} block rows")
    print(RANKING_HEADER)
    for i, c in enumerate(d.ranking[: args.top], 1):
        print(ranking_line(i, c))
        for note in candidate_notes_lines(c):
            print("       " + note)
    rest = d.ranking[args.top:]
    if rest:
        quiet = "" if any(c.passes for c in rest) else "none significant; "
        print(f"  ... {len(rest)} more below ({quiet}--top {len(d.ranking)} shows them): "
              + ", ".join(c.effect for c in rest))
    print(LEGEND)
    if d.unseeable:
        print("not tested, this log cannot see them at any plausible magnitude: " + "; ".join(
            f"{e} (needs {why})" for e, why in d.unseeable.items()))
    if d.noise_candidates:
        print("noise terms the model lacks (maximum likelihood on the same rows):")
        for n in d.noise_candidates:
            print(f"     {n['term']:16s} log-likelihood gain {n['loglik_gain']:9.2f}  (Akaike {n['aic_gain']:+.1f})"
                  f"  {'significant' if n['significant'] else 'not significant'}")
    for line in verdict_lines(d):
        print(line)
    json_option.record(args, **d.to_json(), refit=refit)
    if args.report:
        report_option.write(args.report, log, data, model, args.model, noise,
                            diagnoses={_name(model): d})
    status = _fail_above(args, d.base_chi2_per_dof)
    if args.fail_on_verdict and d.verdict is not None:
        print(f"--fail-on-verdict: {d.verdict} is missing: exit 1")
        status = CHECK_FAILED
    return status


def _noise_terms_in(model, terms: list[str]) -> list[str]:
    """The noise *terms* (acc.noise.bi, ...) *model*'s own noise model already has on every axis."""
    from components.model.noise import TERM_OF_NAME

    own = model.noise_model()
    if own is None:
        return []
    out = []
    for t in terms:
        sensor, _, kind = t.split(".")
        off = 0 if sensor == "gyro" else 3
        if all(getattr(own.channels[off + a], TERM_OF_NAME[kind]) > 0 for a in range(3)):
            out.append(t)
    return out


def _cmd_add(args: argparse.Namespace) -> int:
    from components.diagnosis.compare import compare
    from components.diagnosis.diagnose import NOISE_CANDIDATES
    from components.diagnosis.ladder import ladder_entry, ladder_lines
    from components.diagnosis.noise_choice import IDENTIFIED, choose_noise
    from components.diagnosis.noise_id import add_noise_terms
    from components.errors import UserError
    from components.estimation.lsq import calibrate
    from components.model.effects import parse_effects
    from components.model.result import result_from_fit

    log, data = log_option.read(args)
    model = _load_model(args.model)
    names = [c.strip() for c in args.effect.split(",") if c.strip()]
    noise_terms = [c for c in names if c in NOISE_CANDIDATES]
    try:
        new = parse_effects(",".join(c for c in names if c not in NOISE_CANDIDATES)) if len(noise_terms) < len(names) else []
    except ValueError as e:
        raise UserError(f"--effect: {e} (noise terms: {', '.join(NOISE_CANDIDATES)})") from None
    already = [e for e in new if e in model.effects] + _noise_terms_in(model, noise_terms)
    if already:
        # refitting the same effects would add a rung "+ acc.k2" that changes nothing
        from components.model.noise import describe

        raise UserError(f"--effect {', '.join(already)}: already in the model {args.model} (its effects: "
                        f"{', '.join(model.effects)}; its noise: {describe(model.noise_model())}); diagnose names "
                        "what is missing")
    noise, said, _ = choose_noise(args.noise, data, model)
    print(f"noise: {said}")
    model, refit = model_option.own(model, args.model, log, data, noise)
    json_option.record(args, refit=refit)
    effects = list(dict.fromkeys(list(model.effects) + new))
    # a foreign model's ladder belongs to its own log: the ladder here starts from the refit
    ladder = list(model.extra.get("ladder", [])) if refit is None else []
    if not data.has_table:
        if args.report:  # said before the fit, as compare and diagnose say it
            raise UserError("add --report: the page needs a log with table angles; run add without --report")
        return _add_positions(args, log, data, model, effects, new, noise_terms, noise, ladder)
    if not ladder:
        ladder.append(ladder_entry(compare(data, model, fitted_parameters=len(model.values), noise=noise),
                                   model.effects))
    if noise_terms:
        noise, report = add_noise_terms(data, model, noise, noise_terms)
        for name, r in report.items():
            # a term whose likelihood is highest at zero has no σ there (the boundary): said so, not '± nan'
            value = f"{r['value']:.4g} ± {r['sigma']:.2g}" if r["sigma"] == r["sigma"] else \
                f"{r['value']:.4g} (its likelihood highest at zero: no σ)"
            print(f"{name:18s} {value} (SI; likelihood ratio {r['likelihood_ratio']:.1f}"
                  f"{', not significant' if not r['present'] else ''})")
    fit = calibrate(data, effects, temperature_ref=model.temperature_ref, noise=noise)
    # identified here (--noise identify) or by the model's own identification: identified again
    # with the effect in the model; a noise given as such (a file, a grade, terms) stays as given
    given = [x for x in (args.noise or []) if x.strip() != "identify"]
    if new and not given and noise is not None and IDENTIFIED in noise.source:
        # a noise identified on the residual of the model without the effect took the effect's
        # misfit in (its slow terms and white levels too large: χ²/dof 0.87 after adding a 2"
        # reversal under navigation-grade flicker noise, 0.99 with the noise identified again)
        noise, said, _ = choose_noise(["identify"], data, result_from_fit(fit, effects, data, log))
        print(f"noise: {said}, again with {', '.join(new)} in the model")
        fit = calibrate(data, effects, temperature_ref=model.temperature_ref, noise=noise)
    res = result_from_fit(fit, effects, data, log)
    ladder.append(ladder_entry(compare(data, res, fitted_parameters=len(res.values), noise=noise), effects,
                               f"+ {', '.join(new + noise_terms)}"))
    res.extra["ladder"] = ladder
    if refit is not None:
        res.extra["refit_from"] = refit
    res.save(args.out)
    print("\n".join(ladder_lines(ladder)))
    from components.model.effects import effect_of

    for p in res.values:   # what was added, as the result holds it
        if effect_of(p).name in new:
            unit, k = effect_of(p).display
            sigma = res.sigmas.get(p, float("nan"))
            print(f"{p:22s} {res.values[p] / k:+12.5g} ± {sigma / k:.3g} {unit}" if sigma == sigma else
                  f"{p:22s} not determined by this log (held at 0)")
    from components.cli.calibration import confounded_lines

    for line in confounded_lines(res.extra.get("determinability", {}),
                                 [p for p in res.values if effect_of(p).name in new]):
        print(line)
    print(f"-> {args.out}")
    if args.report:
        report_option.write(args.report, log, data, res, args.out, noise, baseline=model)
    json_option.record(args, ladder=ladder, out=args.out)
    return 0


def _name(model) -> str:
    from components.diagnosis.report_run import model_name

    return model_name(model)


def _add_positions(args, log, data, model, effects, new, noise_terms, noise, ladder) -> int:
    """``add`` on a log without table angles: the positions method with the effect added."""
    from components.diagnosis.compare_positions import compare_positions
    from components.diagnosis.ladder import ladder_entry, ladder_lines
    from components.errors import UserError
    from components.estimation.positions_effects import fit_positions

    if noise_terms:
        raise UserError(f"add {', '.join(noise_terms)}: noise terms are added on logs with table angles; on a log "
                        "without them give the noise with --noise (a grade, a noise file or NAME=VALUE terms)")
    if not ladder:
        ladder.append(ladder_entry(compare_positions(data, model, fitted_parameters=len(model.values), noise=noise),
                                   model.effects))
    fit = fit_positions(data, effects, noise=noise, temperature_ref=model.temperature_ref)
    res = fit.to_result(source=log.source)
    ladder.append(ladder_entry(compare_positions(data, res, fitted_parameters=len(res.values), noise=noise), effects,
                               f"+ {', '.join(new)}"))
    res.extra["ladder"] = ladder
    if "refit_from" in model.extra:
        res.extra["refit_from"] = model.extra["refit_from"]
    json_option.record(args, ladder=ladder, out=args.out)
    res.save(args.out)
    print("\n".join(fit.lines()))
    print("\n".join(ladder_lines(ladder)))
    print(f"-> {args.out}")
    return 0


def register(sub) -> None:
    c = sub.add_parser("compare", help="replay a log's motion through a model: residuals, "
                                       "chi2/dof, fit, whiteness, where it fails")
    c.add_argument("log")
    c.add_argument("--model", required=True,
                   help="calibration result (JSON), or a system (TOML/SSP) whose IMU unit is replayed")
    c.add_argument("--servo", nargs="?", const="builtin", metavar="SYSTEM",
                   help="also replay the logged commands through the turntable FMU (the built-in "
                        "one, or a system's turntable unit) and compare with the logged angles")
    json_option.add(c, "write χ²/dof and the per-channel figures as JSON to FILE, or stdout with '-'")
    c.add_argument("--fail-above", type=float, metavar="CHI2", help="exit 1 when chi2/dof exceeds CHI2 (for CI)")
    c.add_argument("--residuals", help="write per-sample residuals (CSV, the log's output units; column "
                                       "encoder_limited = 1 inside moves, where the gyro prediction is rebuilt "
                                       "from encoder counts)")
    c.add_argument("--block-residuals", metavar="F.csv", help="write the normalised block residuals the "
                                                              "statistics use (1 = noise), with the misfit flag")
    noise_option.add(c)
    log_option.add(c)
    report_option.add_option(c)
    c.set_defaults(func=_cmd_compare)

    d = sub.add_parser("diagnose", help="which effect of the vocabulary is missing from the model")
    d.add_argument("log")
    d.add_argument("--model", required=True)
    json_option.add(d, "write verdict and ranking as JSON to FILE, or stdout with '-'")
    d.add_argument("--fail-above", type=float, metavar="CHI2",
                   help="exit 1 when the model's chi2/dof (before any candidate) exceeds CHI2 (for CI)")
    d.add_argument("--fail-on-verdict", action="store_true",
                   help="exit 1 when the verdict names a missing effect or noise term (for CI)")
    d.add_argument("--alpha", type=float, default=0.01, help="family-wise error rate (Holm)")
    d.add_argument("--candidates", help="comma list of effects to test (default: all not in the model)")
    d.add_argument("--top", type=int, default=10, help="ranking lines to print (the rest are named in one line)")
    noise_option.add(d)
    log_option.add(d)
    report_option.add_option(d)
    d.set_defaults(func=_cmd_diagnose)

    a = sub.add_parser("add", help="add an effect to a model and refit all parameters")
    a.add_argument("log")
    a.add_argument("--model", required=True)
    a.add_argument("--effect", required=True, help="effect name (or comma list); a noise term (acc.noise.bi, "
                                                   "gyro.noise.rrw, ...) adds it to the noise model")
    a.add_argument("--out", required=True, help="the new model (JSON), with the ladder")
    noise_option.add(a)
    log_option.add(a)
    report_option.add_option(a)
    a.set_defaults(func=_cmd_add)
