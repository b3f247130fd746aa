"""Command-line entries of the calibration procedures: calibrate, apply."""
from __future__ import annotations

import argparse

import numpy as np




def _print_result(res) -> None:
    from components.effects import effect_of

    print(f"{'parameter':22s} {'value':>14s} {'sigma':>12s}  unit")
    for p in res.parameters:
        e = effect_of(p)
        unit, scale = e.display
        v, s = res.values[p] / scale, res.sigmas[p] / scale
        print(f"{p:22s} {v:+14.6g} {s:12.3g}  {unit}")
    f = res.fit
    if f:
        print(f"chi2/dof = {f['chi2_per_dof']:.3f} ({f['dof']} dof), {f['iterations']} iteration(s)")


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from components.effects import DEFAULT_EFFECTS, parse_effects
    from components.logfile import read_log
    from components.lsq import LogData, calibrate
    from components.result import result_from_fit

    from components.cli import UserError

    try:
        effects = parse_effects(args.effects) if args.effects else list(DEFAULT_EFFECTS)
    except ValueError as e:
        raise UserError(f"--effects: {e}") from None
    log = read_log(args.log)
    data = LogData.from_log(log)
    fit = calibrate(data, effects, chunk_s=args.chunk)
    res = result_from_fit(fit, effects, data, log)
    res.save(args.out)
    _print_result(res)
    print(f"-> {args.out}")
    return 0


def _cmd_apply(args: argparse.Namespace) -> int:
    from components.correct import correct_log
    from components.logfile import read_log, write_log
    from components.result import CalibrationResult

    res = CalibrationResult.load(args.result)
    log = read_log(args.log)
    out = correct_log(log, res)
    paths = write_log(args.out, out)
    print(f"corrected {log.n} samples with {args.result} -> {', '.join(map(str, paths))}")
    return 0


def add_commands(sub) -> None:
    c = sub.add_parser("calibrate", help="least-squares calibration of a calbench-log/1 log "
                                         "(any effects of the vocabulary, with covariance)")
    c.add_argument("log", help="the log: either file of the pair, or the stem")
    c.add_argument("--out", required=True, help="result file (JSON)")
    c.add_argument("--effects", help="comma list of effects (default: bias, scale factor and "
                                     "misalignment of gyro and accelerometer)")
    c.add_argument("--chunk", type=float, default=1.0, help="static block length [s]")
    c.set_defaults(func=_cmd_calibrate)
    add_model_commands(sub)
    add_plan_command(sub)

    a = sub.add_parser("apply", help="correct a raw log with a calibration result")
    a.add_argument("log", help="the raw log (either file or the stem)")
    a.add_argument("--result", required=True, help="calibration result (JSON)")
    a.add_argument("--out", required=True, help="stem of the corrected log pair")
    a.set_defaults(func=_cmd_apply)





# ------------------------------------------------------------------ model against measurement

def _load_model(path: str):
    from components.result import CalibrationResult

    return CalibrationResult.load(path)


def fitted_on(model, log) -> bool:
    """Was *model* fitted to this very log (same file contents)? Then its parameters count
    against the degrees of freedom."""
    from pathlib import Path

    from components.result import file_sha256

    if not log.source:
        return False
    stem = Path(log.source).with_suffix("")
    for suffix in ("csv", "parquet"):
        f = stem.with_suffix("." + suffix)
        if f.exists() and model.data.get(f"{suffix}_sha256") == file_sha256(f):
            return True
    return False


def ladder_entry(comparison, effects: list[str], label: str | None = None) -> dict:
    ch = comparison.channels
    return {"model": label or "+".join(effects), "effects": list(effects),
            "chi2_per_dof": comparison.chi2_per_dof,
            "rms": {k: v["rms"] for k, v in ch.items()},
            "noise_floor": {k: v["noise_floor"] for k, v in ch.items()}}


def print_ladder(ladder: list[dict]) -> None:
    print(f"{'model':48s} {'chi2/dof':>9s}  rms/noise: gyro x y z, acc x y z")
    for e in ladder:
        ratios = " ".join(f"{e['rms'][k] / e['noise_floor'][k]:5.2f}" for k in e["rms"])
        print(f"{e['model'][:48]:48s} {e['chi2_per_dof']:9.3f}  {ratios}")


def _print_comparison(c) -> None:
    print(f"chi2/dof (block sums against the white-noise level) = {c.chi2_per_dof:.3f} "
          f"({c.dof} dof, 1 ± {(2 / max(c.dof, 1)) ** 0.5:.3f} for a correct model)")
    print(f"{'channel':8s} {'rms':>11s} {'noise':>11s} {'rms/noise':>9s} {'chi2/dof':>9s} "
          f"{'fit %':>9s} {'white p':>8s}")
    for k, v in c.channels.items():
        print(f"{k:8s} {v['rms']:11.4g} {v['noise_floor']:11.4g} {v['rms'] / v['noise_floor']:9.3f} "
              f"{v['chi2_per_dof']:9.3f} {v['fit_percent']:9.4f} {v['whiteness_p']:8.3f}")
    worst = sorted(((max((x for x in vals if x is not None), default=0), s)
                    for s, vals in c.per_segment.items()), reverse=True)[:5]
    if worst:
        print("segments with the largest normalised residual (block RMS, 1 = noise): "
              + ", ".join(f"{s} {v:.2f}" for v, s in worst))


def _cmd_compare(args: argparse.Namespace) -> int:
    import json

    from components.compare import compare
    from components.logfile import read_log
    from components.lsq import LogData

    log = read_log(args.log)
    data = LogData.from_log(log)
    if args.model.endswith((".toml", ".ssp")):
        # a system: its IMU unit (ours or a supplier's FMU) replayed on the log's motion
        from components.compare import assess
        from components.replay import replay_imu

        motion = data.motion(data.geometry)
        c = assess(data, data.geometry, motion, replay_imu(data, args.model, motion))
        print(f"model: the IMU unit of {args.model}, replayed on the log's motion")
    else:
        model = _load_model(args.model)
        c = compare(data, model, fitted_parameters=len(model.values) if fitted_on(model, log) else 0)
    _print_comparison(c)
    if args.servo is not None:
        _print_servo(log, None if args.servo == "builtin" else args.servo)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(c.summary(), f, indent=1)
    if args.residuals:
        write_residuals(args.residuals, log, c)
    return 0


def _print_servo(log, system_file) -> None:
    from components.replay import replay_servo

    from components.cli import UserError

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


def write_residuals(path: str, log, c) -> None:
    """Per-sample residuals in the log's output units (CSV)."""
    import numpy as np

    r = c.residual.copy()
    for s, (kind, w) in ((slice(0, 3), (log.gyro_output, log.gyro_count_rad)),
                         (slice(3, 6), (log.acc_output, log.acc_count_mps))):
        if kind in ("rate", "specific_force"):
            r[:, s] /= log.dt
        elif kind == "counts":
            r[:, s] /= w
    seg = np.asarray(log.segment).astype(str) if log.segment is not None else np.full(log.n, "")
    with open(path, "w") as f:
        f.write("time,segment,gyro_x,gyro_y,gyro_z,acc_x,acc_y,acc_z\n")
        for k in range(log.n):
            f.write(f"{log.time[k]!r},{seg[k]}," + ",".join(repr(float(x)) for x in r[k]) + "\n")


def _cmd_diagnose(args: argparse.Namespace) -> int:
    import json

    from components.diagnose import diagnose
    from components.effects import EFFECTS, parse_effects
    from components.logfile import read_log
    from components.lsq import LogData

    log = read_log(args.log)
    data = LogData.from_log(log)
    model = _load_model(args.model)
    cands = parse_effects(args.candidates) if args.candidates else None
    d = diagnose(data, model, candidates=cands, alpha=args.alpha)
    print(f"model: {', '.join(model.effects)}; chi2/dof = {d.base_chi2_per_dof:.3f} over {d.rows} block rows")
    print(f"{'rank':4s} {'effect':16s} {'F':>10s} {'p (Holm)':>10s} {'dBIC':>10s} {'explains':>8s}  magnitude")
    for i, c in enumerate(d.ranking[: args.top], 1):
        e = EFFECTS[c.effect]
        unit, scale = e.display
        best = max(c.parameters.items(), key=lambda kv: abs(kv[1][0]) / (kv[1][1] or float("inf")))
        mag = f"{best[0]} = {best[1][0] / scale:+.4g} ± {best[1][1] / scale:.2g} {unit}"
        mark = "*" if c.passes else " "
        print(f"{i:3d}{mark} {c.effect:16s} {c.statistic:10.3g} {c.p_adjusted:10.2g} {c.bic_delta:10.4g} "
              f"{100 * c.explained_fraction:7.1f}%  {mag}")
        for other, rho, advice in c.indistinguishable:
            print(f"       cannot be told apart from {other} on this schedule (correlation {rho:.3f}): {advice}")
    if d.verdict is None:
        print("verdict: no significant effect is missing")
    else:
        print(f"verdict: {d.verdict} is missing" + (f"; in turn: {', '.join(d.found)}" if len(d.found) > 1 else ""))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(d.to_json(), f, indent=1)
    return 0


def _cmd_add(args: argparse.Namespace) -> int:
    from components.compare import compare
    from components.effects import parse_effects
    from components.logfile import read_log
    from components.lsq import LogData, calibrate
    from components.result import result_from_fit

    from components.cli import UserError

    log = read_log(args.log)
    data = LogData.from_log(log)
    model = _load_model(args.model)
    try:
        new = parse_effects(args.effect)
    except ValueError as e:
        raise UserError(f"--effect: {e}") from None
    effects = list(dict.fromkeys(list(model.effects) + new))
    ladder = list(model.extra.get("ladder", []))
    if not ladder:
        ladder.append(ladder_entry(compare(data, model, fitted_parameters=len(model.values)), model.effects))
    fit = calibrate(data, effects, temperature_ref=model.temperature_ref)
    res = result_from_fit(fit, effects, data, log)
    ladder.append(ladder_entry(compare(data, res, fitted_parameters=len(res.values)), effects,
                               f"+ {', '.join(new)}"))
    res.extra["ladder"] = ladder
    res.save(args.out)
    print_ladder(ladder)
    print(f"-> {args.out}")
    return 0


def add_model_commands(sub) -> None:
    c = sub.add_parser("compare", help="replay a log's motion through a model: residuals, "
                                       "chi2/dof, fit, whiteness, where it fails")
    c.add_argument("log")
    c.add_argument("--model", required=True,
                   help="calibration result (JSON), or a system (TOML/SSP) whose IMU unit is replayed")
    c.add_argument("--servo", nargs="?", const="builtin", metavar="SYSTEM",
                   help="also replay the logged commands through the turntable FMU (the built-in "
                        "one, or a system's turntable unit) and compare with the logged angles")
    c.add_argument("--json", help="write the per-channel figures as JSON")
    c.add_argument("--residuals", help="write per-sample residuals (CSV, the log's output units)")
    c.set_defaults(func=_cmd_compare)

    d = sub.add_parser("diagnose", help="which effect of the vocabulary is missing from the model")
    d.add_argument("log")
    d.add_argument("--model", required=True)
    d.add_argument("--json", help="write verdict and ranking as JSON")
    d.add_argument("--alpha", type=float, default=0.01, help="family-wise error rate (Holm)")
    d.add_argument("--candidates", help="comma list of effects to test (default: all not in the model)")
    d.add_argument("--top", type=int, default=10, help="ranking lines to print")
    d.set_defaults(func=_cmd_diagnose)

    a = sub.add_parser("add", help="add an effect to a model and refit all parameters")
    a.add_argument("log")
    a.add_argument("--model", required=True)
    a.add_argument("--effect", required=True, help="effect name (or comma list)")
    a.add_argument("--out", required=True, help="the new model (JSON), with the ladder")
    a.set_defaults(func=_cmd_add)


# ------------------------------------------------------------------ planning

def schedule_motion_log(schedule: str, dwell: float | None = None, step: float = 0.005):
    """Noise- and error-free simulated log of a schedule (name or path) on the built-in FMUs:
    the motion a plan is judged on."""
    from pathlib import Path

    from components.scenario import run_scenario, scenario_from_dict

    sched = {"path": str(Path(schedule).resolve())} if schedule.endswith(".toml") else {"name": schedule}
    if dwell is not None:
        sched["overrides"] = {"dwell": dwell}
    sc = scenario_from_dict({"scenario": {"name": f"plan-{Path(schedule).stem}", "step": step},
                             "schedule": sched, "site": {"latitude_deg": 39.9, "height_m": 50.0},
                             "turntable": {"fmu": "builtin:turntable"}, "imu": {"fmu": "builtin:imu"}},
                            source=f"plan {schedule}")
    return run_scenario(sc, progress=False).log


def _cmd_plan(args: argparse.Namespace) -> int:
    from pathlib import Path

    from components.crb import NoiseModel, cramer_rao
    from components.effects import DEFAULT_EFFECTS, DEG, UG, effect_of, parse_effects
    from components.logfile import read_log
    from components.lsq import LogData

    from components.cli import UserError

    try:
        effects = parse_effects(args.effects) if args.effects else list(DEFAULT_EFFECTS)
    except ValueError as e:
        raise UserError(f"--effects: {e}") from None
    noise = NoiseModel.navigation_grade() if args.grade == "navigation" else NoiseModel(
        gyro_arw=0.1 * DEG / 60, acc_vrw=50 * UG, gyro_bi=1 * DEG / 3600 * 0.3, acc_bi=50 * UG)
    noise = NoiseModel(
        gyro_arw=args.arw * DEG / 60 if args.arw is not None else noise.gyro_arw,
        acc_vrw=args.vrw * UG if args.vrw is not None else noise.acc_vrw,
        gyro_bi=args.gyro_bi * DEG / 3600 if args.gyro_bi is not None else noise.gyro_bi,
        acc_bi=args.acc_bi * UG if args.acc_bi is not None else noise.acc_bi,
        bi_tau=args.bi_tau)
    target = args.schedule
    is_log = Path(target).with_suffix(".json").exists() and (
        Path(target).with_suffix(".csv").exists() or Path(target).with_suffix(".parquet").exists())
    if is_log:
        log = read_log(target)
    else:
        print(f"simulating schedule {target} (noise- and error-free) for its motion ...")
        log = schedule_motion_log(target, args.dwell)
    data = LogData.from_log(log)
    crb = cramer_rao(data, effects, noise)
    hours = (log.time[-1] - log.time[0] + log.dt) / 3600
    print(f"Cramér–Rao bound for {target}: {hours * 60:.1f} min, noise: ARW {noise.gyro_arw / (DEG / 60):.4g} deg/sqrt(h), "
          f"VRW {noise.acc_vrw / UG:.3g} ug/sqrt(Hz), bias instability {noise.gyro_bi / (DEG / 3600):.3g} deg/h "
          f"and {noise.acc_bi / UG:.3g} ug (tau {noise.bi_tau:g} s)")
    print(f"{'parameter':22s} {'sigma':>12s}  unit       {'sigma x sqrt(hours)':>20s}")
    for p, s in crb.items():
        unit, scale = effect_of(p).display
        print(f"{p:22s} {s / scale:12.4g}  {unit:10s} {s / scale * hours ** 0.5:20.4g}")
    if args.observability:
        from components.navigation.observability import plan_observability

        print(plan_observability(log, args.observability, noise.gyro_arw, noise.acc_vrw, effects))
    return 0


def add_plan_command(sub) -> None:
    p = sub.add_parser("plan", help="Cramér–Rao bound per parameter of a schedule (or a log's motion) "
                                    "for a noise model, before running it")
    p.add_argument("schedule", help="ready-made schedule name, schedule .toml, or a log stem")
    p.add_argument("--effects", help="comma list of effects (default: bias, scale factor, misalignment)")
    p.add_argument("--grade", choices=("navigation", "tactical"), default="navigation")
    p.add_argument("--arw", type=float, help="gyro ARW [deg/sqrt(h)]")
    p.add_argument("--vrw", type=float, help="accelerometer VRW [ug/sqrt(Hz)]")
    p.add_argument("--gyro-bi", type=float, help="gyro bias instability [deg/h]")
    p.add_argument("--acc-bi", type=float, help="accelerometer bias instability [ug]")
    p.add_argument("--bi-tau", type=float, default=100.0, help="bias-instability correlation time [s]")
    p.add_argument("--dwell", type=float, help="override the schedule's dwell [s]")
    p.add_argument("--observability", metavar="CONFIG",
                   help="also the system-level filter's PWCS/SVD observability and its covariance "
                        "(white noise of the grade): a kf configuration (seed_003, ...: each stage on "
                        "its window) or 'effects' (the --effects on the whole run)")
    p.set_defaults(func=_cmd_plan)
