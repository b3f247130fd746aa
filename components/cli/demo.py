"""``calbench demo``: the product in one command.

Simulate a calibration run on the built-in FMUs with an effect the baseline model lacks, calibrate
the baseline (bias, scale factor, misalignment), compare it with the measurement, diagnose which
effect is missing, add the winner and refit, compare again, and write the report. Prints the
ladder and the recovered value of the hidden effect against its truth.
"""
from __future__ import annotations

import json
from pathlib import Path

from components.model.effects import DEFAULT_EFFECTS, EFFECTS, effect_of

SCENARIO = Path(__file__).resolve().parents[1] / "simulation" / "scenarios" / "demo_hidden_k2.toml"


def _scenario_path() -> Path:
    return SCENARIO


def run_demo(out_dir: str | Path = "calbench-demo", seed: int | None = None, dwell: float | None = None,
             max_added: int = 3) -> int:
    from components.diagnosis.compare import compare
    from components.diagnosis.diagnose import diagnose
    from components.diagnosis.ladder import ladder_entry, ladder_lines
    from components.diagnosis.report_run import write_model_report
    from components.estimation.log_data import LogData
    from components.estimation.lsq import calibrate
    from components.logs.logfile import read_log
    from components.model.result import result_from_fit
    from components.simulation.run import run_scenario, write_outputs
    from components.simulation.scenario import load_scenario

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    overrides = {"dwell": dwell} if dwell else None
    sc = load_scenario(_scenario_path(), overrides)
    if seed is not None:
        sc.seed = seed
    print(f"1. simulate: scenario {sc.name} (schedule {sc.schedule.name}) on the built-in FMUs")
    run = run_scenario(sc, progress=False)
    paths = write_outputs(run, out / "run")
    hidden = {p: v for p, v in run.truth.get("effects", {}).items()
              if effect_of(p).name not in DEFAULT_EFFECTS}
    print(f"   {run.log.n} samples, {run.log.time[-1]:.0f} s -> {paths[0].parent}/run.*"
          f" (hidden from the baseline: {', '.join(hidden) or 'nothing'})")

    log = read_log(out / "run")
    data = LogData.from_log(log)
    effects = list(DEFAULT_EFFECTS)
    print(f"2. calibrate the baseline model: {', '.join(effects)}")
    fit = calibrate(data, effects)
    model = result_from_fit(fit, effects, data, log)
    comp = compare(data, model, fitted_parameters=len(model.values))
    ladder = [ladder_entry(comp, effects, "baseline")]
    model.extra["ladder"] = list(ladder)
    model.save(out / "model0.json")
    baseline = model
    print(f"3. compare: chi2/dof = {comp.chi2_per_dof:.3f} (a correct model scores 1 ± "
          f"{(2 / comp.dof) ** 0.5:.3f})")
    diag = None
    diagnosed: dict = {}  # model name (its ladder rung) -> its diagnosis
    for step in range(1, max_added + 1):
        diag = diagnose(data, model, forward=False)
        diagnosed[ladder[-1]["model"]] = diag
        if diag.verdict is None:
            print(f"4.{step} diagnose: no significant effect is missing")
            break
        if diag.verdict_kind == "noise":
            print(f"4.{step} diagnose: the noise model is too simple ({diag.verdict} explains the residual better "
                  "than any effect): identify it with `calbench noise`")
            break
        win = diag.ranking[0]
        unit, scale = EFFECTS[win.effect].display
        mags = ", ".join(f"{p} = {v / scale:+.3g} ± {s / scale:.2g} {unit}" for p, (v, s) in win.parameters.items()
                         if abs(v) > 3 * s)
        print(f"4.{step} diagnose: {win.effect} is missing (F = {win.statistic:.3g}, p = {win.p_adjusted:.2g}, "
              f"explains {100 * win.explained_fraction:.1f}% of the residual): {mags}")
        for other, rho, advice in win.indistinguishable:
            print(f"     cannot be told apart from {other} here (correlation {rho:.3f}); {advice}")
        effects = effects + [win.effect]
        fit = calibrate(data, effects)
        model = result_from_fit(fit, effects, data, log)
        comp = compare(data, model, fitted_parameters=len(model.values))
        ladder.append(ladder_entry(comp, effects, f"+ {win.effect}"))
        model.extra["ladder"] = list(ladder)
        model.save(out / f"model{step}.json")
        print(f"5.{step} add {win.effect} and refit: chi2/dof = {comp.chi2_per_dof:.3f}")
    print("6. the ladder:")
    print("\n".join(ladder_lines(ladder)))
    for p, v in hidden.items():
        e = effect_of(p)
        unit, scale = e.display
        if p in model.values:
            print(f"   hidden {p}: truth {v / scale:+.4g} {unit}, recovered "
                  f"{model.values[p] / scale:+.4g} ± {model.sigmas[p] / scale:.2g} {unit}")
        else:
            print(f"   hidden {p}: truth {v / scale:+.4g} {unit}, not recovered")
    prov = {"scenario": str(_scenario_path()), "truth_file": str(out / "run.truth.json"),
            "fmus": {u: {"fmu": run.truth[u]["fmu"], "sha256": run.truth[u]["sha256"]}
                     for u in ("turntable", "imu")}}
    # the page calbench report writes: before (the baseline, with the diagnosis that found the
    # effect) and after (the final model, its own diagnosis), the hidden effect against its truth
    html, js = write_model_report(out / "report", log, data, model, model_path=out / f"model{len(ladder) - 1}.json",
                                  title=f"calbench demo: {sc.name}", truth=hidden, diagnoses=diagnosed,
                                  baseline=baseline if len(ladder) > 1 else None, diagnose_models="none",
                                  extra_provenance=prov)
    print(f"7. report: {html} (and {js.name})")
    (out / "ladder.json").write_text(json.dumps(ladder, indent=1))
    return 0


def _cmd_demo(args) -> int:
    code = run_demo(args.out, seed=args.seed, dwell=args.dwell)
    from components.cli import json_option

    # the demo keeps its ladder beside the report; --json gives it with where the files are
    ladder = Path(args.out) / "ladder.json"
    json_option.record(args, out=str(args.out), ladder=json.loads(ladder.read_text()) if ladder.exists() else None)
    return code


def register(sub) -> None:
    dm = sub.add_parser("demo", help="simulate a run with a hidden effect, calibrate, compare, "
                                     "diagnose, add the winner, compare again, write the report")
    dm.add_argument("--out", default="calbench-demo", help="output folder")
    dm.add_argument("--seed", type=int, help="IMU noise seed (default: the scenario's)")
    dm.add_argument("--dwell", type=float, help="dwell per attitude [s] (default 8)")
    dm.set_defaults(func=_cmd_demo)
