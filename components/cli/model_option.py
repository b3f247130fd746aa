"""The ``--model RESULT.json`` of compare, diagnose and add, and the rule that a result belongs to
its log: a result that records another log (its path and SHA-256 under ``data``) is not compared
as if it had been fitted here — its effects are refitted on this log first, said in one line and
recorded, so the ladder starts from the refit and an added effect is not credited with what the
refit alone explains."""
from __future__ import annotations

from pathlib import Path


def load(path: str):
    from components.model.result import CalibrationResult

    return CalibrationResult.load(path)


def fitted_elsewhere(model, log) -> str | None:
    """The log *model* was fitted to, as "PATH (sha XXXXXXXX)", when it records one that is not
    *log* (other contents); None when it was fitted to *log* or records no log at all (a model
    written by hand, or a datasheet's: then it is taken as given)."""
    from components.model.result import fitted_on

    shas = {k: v for k, v in model.data.items() if k.endswith("_sha256") and k != "json_sha256"}
    if not shas or fitted_on(model, log):
        return None
    sha = next(iter(shas.values()))
    return f"{model.data.get('log', 'another log')} (sha {sha[:12]})"


def own(model, model_path: str, log, data, noise, *, say: bool = True):
    """(the model to use on *log*, the provenance of a refit or None). A result fitted to another
    log is refitted here with the same effects and temperature reference under *noise*; the
    returned result records where it came from in ``extra["refit_from"]``."""
    from components.model.result import result_from_fit

    other = fitted_elsewhere(model, log)
    if other is None:
        return model, None
    if say:
        print(f"the model was fitted to {other}, not to this log: refitting its effects on this log first")
    if data.has_table:
        from components.estimation.lsq import calibrate

        fit = calibrate(data, list(model.effects), temperature_ref=model.temperature_ref, noise=noise)
        res = result_from_fit(fit, list(model.effects), data, log)
    else:
        from components.estimation.positions_effects import fit_positions

        fit = fit_positions(data, list(model.effects), noise=noise, temperature_ref=model.temperature_ref)
        res = fit.to_result(source=log.source)
    provenance = {"model": str(Path(model_path)), "fitted_to": model.data.get("log"),
                  "fitted_to_sha256": {k: v for k, v in model.data.items() if k.endswith("_sha256")},
                  "refitted_on": str(log.source) if log.source else None, "effects": list(model.effects)}
    res.extra["refit_from"] = provenance
    return res, provenance
