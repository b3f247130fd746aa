"""Everything a report page shows, computed from a log and a calibration result: the one
function behind ``calbench report``, ``--report`` on compare / diagnose / add, and the demo.

Before and after: a result written by ``calbench add`` (or the demo) keeps its ladder; the page
shows the ladder's first rung refitted on this log ("before") beside the result ("after"), each
with where it fails and — for the models asked — its diagnosis."""
from __future__ import annotations

from pathlib import Path

from components.diagnosis.report import ModelView, build_report


def model_name(model) -> str:
    """The name the ladder gives *model* (its last rung), else its effects."""
    ladder = model.extra.get("ladder") or []
    return ladder[-1]["model"] if ladder else "+".join(model.effects)


def truth_values(truth_effects: dict, model, complete: bool = False) -> list[dict]:
    """Each effect of a known truth (parameter -> SI value), then, for a *complete* truth (a
    simulation's, all it injected), each other parameter of the model (its truth 0), against the model's estimate, as numbers (SI), for the
    page and for scripts reading its JSON twin: the truth, the model's value and σ (None when
    not in the model) and the error in σ."""
    out = []
    # a whole simulation's truth (*complete*): every parameter the model fitted too, what it did
    # not inject being 0 (a fitted acc.mis.xz 2.1 σ off was left off the page)
    rest = [q for q in model.values if q not in truth_effects] if complete else []
    for p in list(truth_effects) + rest:
        v = truth_effects.get(p, 0.0)
        val = model.values.get(p)
        s = model.sigmas.get(p, float("nan")) if val is not None else None
        z = (val - v) / s if val is not None and s and s > 0 else (float("nan") if val is not None else None)
        out.append({"parameter": p, "truth": float(v), "value": None if val is None else float(val),
                    "sigma": None if s is None else float(s), "error_sigmas": None if z is None else float(z)})
    return out


def truth_lines(values: list[dict]) -> list[str]:
    """The rows of :func:`truth_values` as the page's lines, in display units."""
    from components.model.effects import effect_of

    out = []
    for r in values:
        unit, scale = effect_of(r["parameter"]).display
        head = f"{r['parameter']}: truth {r['truth'] / scale:+.4g} {unit}"
        if r["value"] is None:
            out.append(f"{head}, not in the model")
        else:
            out.append(f"{head}, recovered {r['value'] / scale:+.4g} ± {r['sigma'] / scale:.2g} {unit} "
                       f"({r['error_sigmas']:+.1f} σ)")
    return out


def _provenance(log, models: dict) -> dict:
    from components.model.result import file_sha256

    out: dict = {"log": str(log.source) if log.source else None, "files": {}}
    if log.source:
        stem = Path(log.source).with_suffix("")
        for suffix in (".csv", ".parquet", ".json"):
            f = stem.with_suffix(suffix)
            if f.exists():
                out["files"][f.name] = file_sha256(f)
    out["models"] = {}
    for name, (m, path) in models.items():
        entry = {"effects": list(m.effects), "file": str(path) if path else "refitted on this log"}
        if path and Path(path).exists():
            entry["sha256"] = file_sha256(Path(path))
        if m.extra.get("refit_from"):   # the file's effects, refitted here: its values are not the file's
            entry["refitted_on_this_log"] = True
        out["models"][name] = entry
        out.setdefault("software", m.to_dict().get("software"))
    return out


def write_model_report(page: str | Path, log, data, model, *, model_path=None, noise=None, title: str | None = None,
                       diagnose_models: str = "after", identify: bool = True, truth: dict | None = None,
                       baseline=None, diagnoses: dict | None = None, extra_provenance: dict | None = None,
                       baseline_path=None, truth_complete: bool = False):
    """Write the page for *model* on *log* (*data* its LogData). ``noise``: the noise model the
    rows are whitened with; ``diagnose_models``: "after", "both" or "none"; ``identify``: add the
    noise identification of the after-model's residual; ``truth``: parameter -> SI value of a
    known truth (``truth_complete``: all of a simulation's, the rest 0); ``baseline``: the before-model (default: the ladder's first rung refitted),
    ``baseline_path`` its file;
    ``diagnoses``: name -> an already computed diagnosis (not run again)."""
    from components.diagnosis.compare import compare
    from components.diagnosis.diagnose import diagnose
    from components.diagnosis.ladder import ladder_entry
    from components.estimation.lsq import calibrate
    from components.model.result import fitted_on, result_from_fit

    diagnoses = dict(diagnoses or {})
    after_name = model_name(model)
    ladder = list(model.extra.get("ladder") or [])
    models: dict = {}
    refitted = None
    if baseline is not None:
        models[model_name(baseline)] = (baseline, baseline_path)
    elif len(ladder) > 1 and list(ladder[0]["effects"]) != list(model.effects):
        effects = list(ladder[0]["effects"])
        fit = calibrate(data, effects, temperature_ref=model.temperature_ref, noise=noise)
        refitted = result_from_fit(fit, effects, data, log)
        models[ladder[0]["model"]] = (refitted, None)
    models[after_name] = (model, model_path)
    views = []
    for k, (name, (m, _)) in enumerate(models.items()):
        fitted = m is refitted or fitted_on(m, log)
        comp = compare(data, m, fitted_parameters=len(m.values) if fitted else 0, noise=noise)
        role = ("before" if k == 0 else "after") if len(models) > 1 else ""
        diag = diagnoses.get(name)
        if diag is None and (diagnose_models == "both" or (diagnose_models == "after" and m is model)):
            diag = diagnose(data, m, forward=False, noise=noise)
        views.append(ModelView(name, comp, diag, role))
    if not ladder:
        ladder = [ladder_entry(views[-1].comparison, list(model.effects), after_name)]
    ident = None
    if identify and data.has_table:
        from components.diagnosis.noise_choice import quantization_known
        from components.diagnosis.noise_id import identify_noise

        try:
            # no bootstrap: the page shows the model and its fit (σ per term: `calbench noise`, 30 s more)
            ident = identify_noise(data, model, known=quantization_known(data), bootstrap=0)
        except ValueError:
            ident = None  # too few static runs to identify: the page says nothing about noise
    numbers = truth_values(truth, model, truth_complete) if truth else None
    prov = _provenance(log, models)
    prov.update(extra_provenance or {})
    return build_report(page, title=title or f"calbench report: {log.source or 'log'}", views=views,
                        ladder=ladder, provenance=prov, noise=ident, noise_model=after_name,
                        truth=truth_lines(numbers) if numbers else None, truth_model=after_name,
                        truth_values=numbers)
