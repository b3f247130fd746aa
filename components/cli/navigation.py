"""``calbench kf CONFIG LOG --out RESULT.json`` (or ``--simulate SCENARIO`` instead of LOG)."""
from __future__ import annotations

import argparse
import sys

from components.cli import json_option, log_option, noise_option
from components.cli.calibration import result_json


def _cmd_kf(args: argparse.Namespace) -> int:
    from components.cli.log_option import parse_exclude
    from components.errors import UserError
    from components.logs.logfile import read_log
    from components.navigation.configs import load_config, with_grade
    from components.navigation.system import calibrate_system

    try:
        cfg = with_grade(load_config(args.config), args.grade)
    except (ValueError, OSError) as e:
        raise UserError(f"kf: configuration {args.config}: {e}") from None
    if args.simulate and args.log:
        raise UserError("kf: give a LOG or --simulate SCENARIO, not both")
    if args.simulate:
        from components.simulation.run import run_scenario
        from components.simulation.scenario import load_scenario

        run = run_scenario(load_scenario(args.simulate), progress=False if args.quiet else None)
        log, truth = run.log, run.truth
        source = args.simulate
    elif args.log:
        log = read_log(args.log)
        source, truth = args.log, None
    else:
        raise UserError("kf: give a LOG or --simulate SCENARIO")
    for line in cfg.schedule_mismatch(log.segment, source):
        print(f"calbench: warning: {line}", file=sys.stderr)
    data, noise = _noise_of(args, log)
    bar = _progress_bar(cfg, args.quiet)
    try:
        res, _ = calibrate_system(log, cfg, parse_exclude(args.exclude),
                                  progress=None if bar is None else bar.step, noise=noise, data=data)
    except ValueError as e:  # a window no label matches, no rest to align on, ...
        raise UserError(f"kf: {source} with configuration {cfg.name}: {e}") from None
    finally:
        if bar is not None:
            bar.close()
    json_option.record(args, config=cfg.name, source=str(source), **result_json(res), out=args.out)
    if truth is not None:
        _print_truth(args, res, truth)
    else:
        res.save(args.out)
        undetermined = res.extra.get("determinability", {}).get("undetermined", {})
        for p, v in res.values.items():
            from components.model.effects import effect_of

            unit, k = effect_of(p).display
            if p in undetermined:
                print(f"{p:18s} {'not determined':>25s}  ({undetermined[p]['why']}; needs {undetermined[p]['needs']})")
                continue
            share = res.extra.get("determinability", {}).get("posterior_to_prior_sigma", {}).get(p)
            flag = f"  weakly determined (σ at {share:.0%} of its prior σ: the prior weighs in)" if share else ""
            print(f"{p:18s} {v / k:12.4f} ± {res.sigmas[p] / k:9.4f} {unit}{flag}")
    for note in res.fit.get("notes", []):
        print(f"note: {note}")
    print(f"wrote {args.out} ({res.method}, config {cfg.name})")
    problems = res.consistency_problems()
    if problems:
        print("the filter is not consistent with the data; do not use these estimates:")
        for p in problems:
            print(f"  {p}")
        json_option.record(args, problems=problems)
        return 1
    for st in res.fit.get("stages", []):
        c = st.get("consistency")
        if c and c.get("innovation_windows"):
            # what the checks found, said on success too: a user sees how close to the limits it ran
            wp = c.get("whiteness_p")
            print(f"consistent: stage {st['name']!r}: {c['innovation_windows'] - c['windows_out']} of "
                  f"{c['innovation_windows']} innovation windows within bounds, normalised innovation RMS "
                  f"{st.get('normalised_innovation_rms', float('nan')):.3g}"
                  + (f", whiteness p {wp:.2g} (lags 3-60)" if wp is not None else ""))
    return 0


def _noise_of(args, log):
    """(the log's LogData, the noise model --noise gives or None): the filters take the slow
    terms of a given model as states (components.navigation.kf); without --noise, white noise from
    the static data, as before."""
    from components.cli.log_option import parse_exclude
    from components.diagnosis.noise_choice import choose_noise
    from components.estimation.log_data import LogData

    data = LogData.from_log(log, parse_exclude(args.exclude))
    if not args.noise:
        return data, None
    noise, said, _ = choose_noise(args.noise, data)
    if noise is None:   # --noise white: the filters' default
        print(f"noise: {said}")
        return data, None
    print(f"noise: {said}; its bias instability and random walk are states of the filters")
    json_option.record(args, noise=said)
    return data, noise


def _print_truth(args, res, truth: dict) -> None:
    """Errors against the simulation's truth, in the frame the configuration estimates in
    (components.navigation.truth_frame), with the injected parameters it has no state for."""
    from components.navigation.truth_frame import estimation_frame, not_estimated, truth_of_result
    from components.procedures.common import errors_against_truth, print_errors

    frame = estimation_frame(list(res.values))
    injected = truth.get("effects", {})
    rows = errors_against_truth(res, {**truth, "effects": truth_of_result(injected, list(res.values), frame)})
    missing = not_estimated(injected, list(res.values), frame)
    res.extra["errors_against_truth"] = rows
    res.extra["truth_frame"] = frame
    res.save(args.out)
    print(f"errors against the truth of {args.simulate}, misalignments in the "
          + ("table frame (the frame the table-referenced gyros realise)" if frame == "table" else
             "accelerometer-defined frame (x along the x accelerometer, y in the x-y accelerometer plane; "
             "the truth turned into it)") + ":")
    print_errors(rows)
    if missing:
        print("injected but not estimated by this configuration (the estimates above may be biased by them): "
              + ", ".join(missing))
    json_option.record(args, errors_against_truth=rows, truth_frame=frame, not_estimated=missing)


class _Progress:
    """A tqdm bar on stderr over the configuration's stages and filter passes (the filter is
    silent for tens of seconds); none when stderr is not a terminal or with --quiet."""

    def __init__(self, total: int):
        from tqdm import tqdm

        self.bar = tqdm(total=total, unit="pass", file=sys.stderr, leave=False, dynamic_ncols=True)

    def step(self, what: str) -> None:
        self.bar.set_description(what)
        self.bar.update(1)

    def close(self) -> None:
        self.bar.close()


def _progress_bar(cfg, quiet: bool):
    if quiet or not sys.stderr.isatty():
        return None
    return _Progress(sum(int(st.settings.get("passes", 1)) if st.kind == "kf" else 1 for st in cfg.stages))


def register(sub) -> None:
    k = sub.add_parser("kf", help="system-level Kalman-filter calibration (navigation velocity "
                                  "error on a stationary base): seed_001, seed_001_single, "
                                  "seed_003, seed_003_joint, seed_003_external, psins19, psins19_tga "
                                  "or a configuration TOML; exit 1 when the filter is not consistent "
                                  "with the data")
    k.add_argument("config", help="ready-made configuration name or .toml")
    k.add_argument("log", nargs="?", help="the log (either file of the pair, or the stem)")
    k.add_argument("--simulate", help="simulate this scenario file instead of reading a log")
    k.add_argument("--out", required=True, help="result file (JSON)")
    k.add_argument("--grade", choices=("navigation", "mems"), default="navigation",
                   help="the IMU's grade: the filter's priors and initial attitude uncertainty "
                        "(default navigation; mems for consumer/industrial MEMS)")
    k.add_argument("--quiet", action="store_true", help="no progress bar (none either when stderr is not a terminal)")
    noise_option.add(k)
    log_option.add(k)
    k.set_defaults(func=_cmd_kf)
