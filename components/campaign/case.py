"""One case, in this process: simulate the scenario, run the procedure, judge the criteria.

``python -m components.campaign.case TASK.json RESULT.json`` is how a worker runs it in a child
process of its own (components.campaign.isolate): a crash of an FMU takes down only that child.
The record holds no time and no path: the same task gives a byte-identical record."""
from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

FORMAT = "calbench-campaign-case/1"


def _f(x):
    """JSON-safe float (NaN/inf -> None)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _mark(task: dict) -> None:
    """A marker file per execution (how tests count that no finished case ran twice)."""
    d = task.get("marker_dir")
    if d and Path(d).is_dir():
        (Path(d) / f"{task['case']['id']}.{os.getpid()}.{os.urandom(4).hex()}").touch()


def _procedure(proc: dict, log):
    from components.estimation.log_data import LogData
    from components.estimation.lsq import calibrate
    from components.model.result import result_from_fit

    data = LogData.from_log(log)
    if proc["method"] == "lsq":
        opts = dict(proc.get("options", {}))
        if "noise" in opts or any(data.count_weight):
            # the procedure's noise model (--noise specifications: identify, a grade, NAME=VALUE ...);
            # pulse counts without one as calibrate does: their quantization from the count weight
            from components.diagnosis.noise_choice import choose_noise

            specs = opts.pop("noise", None)
            specs = None if specs is None else [specs] if isinstance(specs, str) else list(specs)
            opts["noise"] = choose_noise(specs, data, effects=list(proc["effects"]), bootstrap=10)[0]
        fit = calibrate(data, list(proc["effects"]), **opts)
        return data, result_from_fit(fit, list(proc["effects"]), data)
    from components import procedures

    opts = dict(proc.get("options", {}))
    if proc["method"] in ("tilt", "tilt_ignored") and proc.get("effects"):
        opts["effects"] = tuple(proc["effects"])
    return data, procedures.run(proc["method"], data, **opts)


def _crb(data, model, noise: dict) -> dict:
    import numpy as np

    from components.estimation.crb import cramer_rao
    from components.model.effects import EFFECTS
    from components.model.noise import from_fmu_parameters

    arw = noise.get("gyro.noise.arw") or float(np.mean(model.noise.get("gyro_arw_rad_per_sqrt_s", [0.0])))
    vrw = noise.get("acc.noise.vrw") or float(np.mean(model.noise.get("acc_vrw_mps_per_sqrt_s", [0.0])))
    effects = [e for e in model.effects if e in EFFECTS]
    if not effects or not (arw > 0 and vrw > 0):
        return {}
    # the bound under the noise injected (bias instability, random walk too), white levels
    # from the fit where the truth has none
    injected = from_fmu_parameters({**noise, "gyro.noise.arw": arw, "acc.noise.vrw": vrw})
    try:
        return cramer_rao(data, effects, injected, rest_angle_sigma=model.rest_angle_sigma())
    except Exception:  # noqa: BLE001  (a bound we cannot compute is reported as missing)
        return {}


def numbers_of(task: dict) -> tuple[dict, object, object, object]:
    """(numbers, data, model, comparison) of the case: the estimates against the truth and the
    CRB, chi2/dof of the model on its own log, the diagnosis verdict (when a criterion asks)."""
    from components.diagnosis.compare import compare
    from components.simulation.run import run_scenario
    from components.simulation.scenario import scenario_from_dict

    sc = scenario_from_dict(task["scenario"], task["source"], Path(task["base_dir"]))
    run = run_scenario(sc, progress=False)
    data, model = _procedure(task["procedure"], run.log)
    truth = task["truth"]
    crb = _crb(data, model, run.truth.get("noise", {}))
    est = {}
    for p, v in model.values.items():
        t = truth.get(p, 0.0)
        est[p] = {"value": _f(v), "sigma": _f(model.sigmas.get(p)), "truth": _f(t), "error": _f(v - t),
                  "crb": _f(crb.get(p))}
    comp = None
    chi2 = None
    try:
        comp = compare(data, model, fitted_parameters=len(model.values))
        chi2 = comp.chi2_per_dof
    except Exception:  # noqa: BLE001  (a result the comparison cannot replay: no chi2)
        pass
    diag = None
    if task.get("diagnose"):
        from components.diagnosis.diagnose import diagnose

        diag = diagnose(data, model, forward=False).verdict
    numbers = {"estimates": est, "chi2_per_dof": _f(chi2), "diagnosis": diag,
               "fmus": {"imu": run.truth["imu"]["sha256"], "turntable": run.truth["turntable"]["sha256"]},
               "samples": int(run.log.n)}
    return numbers, data, model, comp


def record(task: dict, numbers: dict | None, reason: str | None = None) -> dict:
    """The case record: verdict pass (every criterion passed), fail or error (with the reason)."""
    from components.campaign.criteria import evaluate

    lost = task.get("not_injected", {})
    rec = {"format": FORMAT, **task["case"], "truth": task["truth"], "not_injected": lost}
    if numbers is None:
        return {**rec, "verdict": "error", "reason": reason,
                "criteria": [{"id": c["id"], "requirement": c["requirement"], "kind": c["kind"], "passed": None,
                              "message": "not evaluated: the case errored"} for c in task["criteria"]]}
    results = []
    for c in task["criteria"]:
        why = not_applicable(c, lost)
        results.append({"id": c["id"], "requirement": c["requirement"], "kind": c["kind"], "passed": None,
                        "applicable": False, "message": f"not applicable: {why}"} if why else evaluate(c, numbers))
    failed = [r["id"] for r in results if r["passed"] is False]
    return {**rec, "verdict": "fail" if failed else "pass",
            "reason": f"failed: {', '.join(failed)}" if failed else None, "criteria": results, **numbers}


def needs_noise(criterion: dict) -> bool:
    """A criterion whose numbers mean something only with noise: σ, the Cramér–Rao bound, χ², a
    statistical test's verdict."""
    return criterion["kind"] in ("crb", "chi2", "diagnosis") or any(k in criterion for k in ("crb_sigmas", "sigmas"))


def not_applicable(criterion: dict, lost: dict) -> str | None:
    """Why the criterion cannot be judged on this case's IMU (None: it can): a noise-free IMU
    gives σ, bounds and χ² of nothing — never a pass on them."""
    if not needs_noise(criterion) or not lost.get("noise_free"):
        return None
    if lost.get("noise"):
        return (f"the IMU FMU takes none of the noise asked for ({', '.join(lost['noise'])}: no noise_map or no such "
                "parameter), so the run is noise-free and its σ, bounds and χ² say nothing")
    return "the case injects no noise, so the run is noise-free and its σ, bounds and χ² say nothing"


def run_case(task: dict) -> dict:
    _mark(task)
    try:
        numbers = numbers_of(task)[0]
    except Exception as e:  # noqa: BLE001  (any failure of the case is its own error, not the campaign's)
        return record(task, None, f"{type(e).__name__}: {e}")
    return record(task, numbers)


def dumps(rec: dict) -> str:
    return json.dumps(rec, indent=1, sort_keys=True, allow_nan=False) + "\n"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m components.campaign.case TASK.json RESULT.json", file=sys.stderr)
        return 2
    task = json.loads(Path(argv[0]).read_text())

    rec = run_case(task)
    out = Path(argv[1])
    tmp = out.with_suffix(".tmp")
    tmp.write_text(dumps(rec))
    os.replace(tmp, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
