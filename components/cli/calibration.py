"""``calbench calibrate`` (general least squares on a log) and ``calbench apply`` (correct a raw
log with a result)."""
from __future__ import annotations

import argparse

from components.cli import json_option, log_option, noise_option


def _print_result(res) -> None:
    from components.model.effects import effect_of

    det = res.extra.get("determinability", {})
    weak = set(det.get("weakly_determined", []))
    bad = det.get("implausible", {})
    print(f"{'parameter':22s} {'value':>14s} {'sigma':>12s}  unit")
    for p in res.parameters:
        e = effect_of(p)
        unit, scale = e.display
        v, s = res.values[p] / scale, res.sigmas[p] / scale
        flag = "  IMPLAUSIBLE" if p in bad else ("  weakly determined" if p in weak else "")
        print(f"{p:22s} {v:+14.6g} {s:12.3g}  {unit}{flag}")
    for p, d in det.get("undetermined", {}).items():
        print(f"{p:22s} {'not determined':>27s}  (held at 0: {d['why']}; needs {d['needs']})")
    f = res.fit
    if f:
        if f.get("chi2_per_dof") is None:
            print(f"chi2/dof: none ({f['dof']} dof: {f.get('note', 'no degrees of freedom left')})")
        else:
            print(f"chi2/dof = {f['chi2_per_dof']:.3f} ({f['dof']} dof), {f['iterations']} iteration(s)")
            from components.diagnosis.misfit import chi2_band, chi2_band_note

            note = chi2_band_note(f["chi2_per_dof"], f["dof"], above=True)
            if note:
                print(f"note: {note}")
            if f["chi2_per_dof"] > chi2_band(f["dof"])[1]:
                for line in white_level_warnings(res.noise.get("no_white_level"), res.noise.get("white_poorly_read")):
                    print(line)
    if weak:
        print(f"weakly determined (sigma above 10 x the magnitude expected of an IMU of this noise grade): "
              f"{', '.join(sorted(weak))}")
    for p, why in bad.items():
        print(f"IMPLAUSIBLE {p}: {why}")
    for line in confounded_lines(det, res.parameters):
        print(line)


def give_the_noise(channels: list[str]) -> str:
    """What to give for *channels* whose white level the counts hide: the datasheet's level, held
    while the rest is identified (given after the identification alone, the slow terms stay those
    read beside the level that was too low)."""
    example = " --noise ".join(term for sensor, term in (("gyro", "gyro.noise.arw='0.005 deg/sqrt(h)'"),
                                                         ("acc", "acc.noise.vrw='20 ug/sqrt(Hz)'"))
                               if any(ch.startswith(sensor) for ch in channels))
    return (f"give the datasheet's level, the rest identified beside it: --noise identify --noise {example} (or "
            "calbench noise LOG --noise ... --out NOISE.json, then --noise NOISE.json), or a noise file from a longer "
            "log of this IMU")


def white_level_warnings(hidden: list[str] | None, poorly_read: list[str] | None) -> list[str]:
    """The lines for pulse channels whose white level the counts hide, when χ²/dof is above its
    band: none found (a floor stood in for it), or one identified but not measured (below three
    of its σ: read low, it weighs the channel too much). Either may be why."""
    lines = []
    if hidden:
        lines.append(f"WARNING: no white-noise level on {', '.join(hidden)}: the pulse counts are too coarse for "
                     "this log to show it, and none was taken, so the sigma are too small (by as much as chi2/dof "
                     f"says); {give_the_noise(hidden)}")
    if poorly_read:
        lines.append(f"WARNING: white-noise level poorly read on {', '.join(poorly_read)}: the pulse counts are too "
                     "coarse for this log to measure it (identified within three of its sigma of 0), and a level "
                     f"read low leaves the sigma too small (by as much as chi2/dof says); {give_the_noise(poorly_read)}")
    return lines


def confounded_lines(det: dict, parameters) -> list[str]:
    """A line for each of *parameters* the log hardly tells from others (result determinability
    block's 'confounded'): its σ is large because of them, not because the log does not see it."""
    got = det.get("confounded", {})
    return [f"confounded {p}: {got[p]['why']} (needs {got[p]['needs']})" for p in parameters if p in got]


# a σ that would grow by more than this were the unseen slow terms at their bounds is named
SENSITIVE = 1.2


def _print_sensitivity(res) -> None:
    sens = res.extra.get("noise_sensitivity")
    if not sens:
        return
    hit = {p: r for p, r in sens["ratio"].items() if r > SENSITIVE}
    terms = ", ".join(sens["terms_at_upper_bound"])
    if not hit:
        print(f"sigma holds whatever the noise terms this log cannot pin down ({terms}): at their upper bounds "
              f"no sigma grows beyond {SENSITIVE}x")
        return
    print(f"sigma rests on noise terms this log cannot pin down ({terms}): at their upper bounds these sigma "
          "grow (a longer log, or the terms given with --noise, settles it):")
    for p, r in sorted(hit.items(), key=lambda x: -x[1]):
        print(f"  {p:22s} x{r:.2f}")


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from components.diagnosis.noise_choice import choose_noise
    from components.errors import UserError
    from components.estimation.lsq import calibrate
    from components.estimation.noise_sensitivity import sensitivity
    from components.model.effects import DEFAULT_EFFECTS, parse_effects
    from components.model.result import result_from_fit

    try:
        effects = parse_effects(args.effects) if args.effects else list(DEFAULT_EFFECTS)
    except ValueError as e:
        raise UserError(f"--effects: {e}") from None
    log, data = log_option.read(args)
    noise, said, ident = choose_noise(args.noise, data, effects=effects)
    print(f"noise: {said}")
    if not data.has_table:
        return _calibrate_positions(args, log, data, effects, noise)
    fit = calibrate(data, effects, chunk_s=args.chunk, noise=noise, undetermined=args.undetermined)
    res = result_from_fit(fit, effects, data, log)
    if ident is not None:
        span = float(data.time[-1] - data.start_time)
        sens = sensitivity(fit, ident, span, args.chunk)
        if sens is not None:
            res.extra["noise_sensitivity"] = sens
    res.save(args.out)
    _print_result(res)
    _print_sensitivity(res)
    print(f"-> {args.out}")
    json_option.record(args, **result_json(res), out=args.out)
    return strict_status(args, res)


def strict_status(args, res) -> int:
    """Exit status: 1 with --strict when an estimate is implausible (the result is written all the same)."""
    if getattr(args, "strict", False) and res.extra.get("determinability", {}).get("implausible"):
        print("--strict: implausible estimates (see above): exit 1")
        return 1
    return 0


def _calibrate_positions(args, log, data, effects, noise) -> int:
    """A log without table angles: rests of unknown attitude and turns of known angle
    (docs/positions.md)."""
    from components.estimation.positions_effects import fit_positions

    print("no table angles: the positions method (rests of unknown attitude, turns of known angle; "
          "docs/positions.md)")
    fit = fit_positions(data, effects, noise=noise, chunk_s=args.chunk)
    res = fit.to_result(source=log.source)
    res.save(args.out)
    print("\n".join(fit.lines()))
    print(f"-> {args.out}")
    json_option.record(args, **result_json(res), out=args.out)
    return strict_status(args, res)


def _cmd_apply(args: argparse.Namespace) -> int:
    from components.errors import UserError
    from components.logs.logfile import read_log, rewrite_parquet, sample_file, write_log
    from components.logs.spill import empty_like_log, release, write_rows
    from components.model.correct import correct_log
    from components.model.result import CalibrationResult

    res = CalibrationResult.load(args.result)
    # a system-level result whose filter found itself inconsistent said "do not use these
    # estimates": a correction with them is refused unless asked for
    failed = res.consistency_problems()
    if failed and not args.accept_inconsistent:
        raise UserError(f"{args.result}: the filter that made it found itself inconsistent ({failed[0]}"
                        + (f"; and {len(failed) - 1} more" if len(failed) > 1 else "") + "); its estimates are not "
                        "to be used: mend the run, or apply it anyway with --accept-inconsistent")
    _corrected_format(args, None)  # a contradiction in the options, before the log is read
    data_file = sample_file(args.log)
    if data_file.suffix.lower() == ".parquet" and _corrected_format(args, str(data_file)) == "parquet":
        # Parquet to Parquet: the columns the correction needs (a long log's on disk), the IMU
        # columns corrected a piece at a time, and the file rewritten a row group at a time with
        # every other column as it is (an 8-hour log read whole was 5.6 GB)
        log = read_log(args.log, lean=True)
        into = (empty_like_log(log.gyro.shape, log.gyro), empty_like_log(log.acc.shape, log.acc))
        out = correct_log(log, res, into=into, after_piece=lambda: release(log.gyro, log.acc, *into),
                          put_rows=write_rows)
        paths = rewrite_parquet(data_file, args.out, out, [f"{s}_{c}" for s in ("gyro", "acc") for c in "xyz"])
    else:
        log = read_log(args.log)
        out = correct_log(log, res)
        paths = write_log(args.out, out, fmt=_corrected_format(args, log.source))
    print(f"corrected {log.n} samples with {args.result} -> {', '.join(map(str, paths))}")
    json_option.record(args, samples=int(log.n), result=args.result, out=[str(p) for p in paths])
    return 0


def _corrected_format(args, raw_source: str | None) -> str:
    """The corrected log's sample format: ``--format``, else the suffix of ``--out`` (.csv or
    .parquet), else the raw log's own (an hours-long Parquet log written back as CSV is ten times
    the file and a slower read)."""
    from pathlib import Path

    from components.errors import UserError

    suffix = Path(args.out).suffix.lower()
    if args.format:
        if suffix in (".csv", ".parquet") and suffix[1:] != args.format:
            raise UserError(f"--out {args.out}: a {suffix} file, but --format {args.format}; give one of them")
        return args.format
    if suffix in (".csv", ".parquet"):
        return suffix[1:]
    return "parquet" if raw_source and raw_source.lower().endswith(".parquet") else "csv"


def result_json(res) -> dict:
    """What --json gives of a result: each parameter's value and σ in SI and in its display unit,
    the fit, and the flags (weak, implausible, not determined)."""
    from components.model.effects import effect_of

    params = {}
    for p in res.parameters if hasattr(res, "parameters") else res.values:
        unit, scale = effect_of(p).display
        v, s = res.values[p], res.sigmas.get(p, float("nan"))
        params[p] = {"value": v, "sigma": s, "display_value": v / scale, "display_sigma": s / scale,
                     "display_unit": unit}
    out = {"effects": list(res.effects), "parameters": params, "fit": res.fit,
           "determinability": res.extra.get("determinability", {})}
    if res.extra.get("noise_sensitivity"):
        out["noise_sensitivity"] = res.extra["noise_sensitivity"]
    return out


def register(sub) -> None:
    c = sub.add_parser("calibrate", help="least-squares calibration of a calbench-log/1 log "
                                         "(any effects of the vocabulary, with covariance)")
    c.add_argument("log", help="the log: either file of the pair, or the stem")
    c.add_argument("--out", required=True, help="result file (JSON)")
    c.add_argument("--effects", help="comma list of effects (default: bias, scale factor and "
                                     "misalignment of gyro and accelerometer)")
    c.add_argument("--chunk", type=float, default=1.0, help="static block length [s]")
    c.add_argument("--undetermined", choices=("hold", "refuse"), default="hold",
                   help="parameters the log does not determine: hold them at 0 and name them (default), "
                        "or refuse the fit")
    c.add_argument("--strict", action="store_true", help="exit 1 when an estimate is beyond any real IMU")
    noise_option.add(c)
    log_option.add(c)
    c.set_defaults(func=_cmd_calibrate)

    a = sub.add_parser("apply", help="correct a raw log with a calibration result")
    a.add_argument("log", help="the raw log (either file or the stem)")
    a.add_argument("--result", required=True, help="calibration result (JSON)")
    a.add_argument("--out", required=True, help="stem of the corrected log pair (STEM.json and STEM.csv or "
                                                "STEM.parquet)")
    a.add_argument("--format", choices=("csv", "parquet", "both"),
                   help="the samples' file (default: the suffix of --out, else the raw log's own format)")
    a.add_argument("--accept-inconsistent", action="store_true",
                   help="apply a system-level result whose filter failed its consistency checks")
    a.set_defaults(func=_cmd_apply)
