"""The calibration result file (JSON): parameters with σ and unit, correlations, noise model,
fit statistics, the schedule and the data it came from. SI units; ratios as plain numbers.

No wall-clock time is written: the same log and options give a byte-identical file."""
from __future__ import annotations

import json
import platform
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from components.errors import ResultFormatError
from components.model.effects import EFFECTS, effect_of
from orchestrator.units import sha256_file as file_sha256  # noqa: F401  (one implementation; re-exported)

FORMAT = "calbench-result/1"


@dataclass
class CalibrationResult:
    effects: list[str]
    values: dict[str, float]
    sigmas: dict[str, float]
    correlation: np.ndarray | None = None  # in the order of `values`
    noise: dict = field(default_factory=dict)
    fit: dict = field(default_factory=dict)
    temperature_ref: float | None = None
    schedule: list = field(default_factory=list)
    data: dict = field(default_factory=dict)
    method: str = "least-squares"
    extra: dict = field(default_factory=dict)

    @property
    def parameters(self) -> list[str]:
        return list(self.values)

    def value(self, name: str, default: float = 0.0) -> float:
        return self.values.get(name, default)

    def rest_angle_sigma(self):
        """σ of the table's true angle at rest around its reading per axis [rad], as the fit
        estimated it from the moves, or None (not estimated: one count uniform is taken)."""
        return self.noise.get("rest_angle_sigma_rad")

    def consistency_problems(self) -> list[str]:
        """What the checks of a system-level result's filter stages found (empty: consistent, or
        not a filter's result): the filter's own word that its estimates are not to be used."""
        return [p for st in (self.fit or {}).get("stages", []) if isinstance(st, dict)
                for p in (st.get("consistency") or {}).get("problems", [])]

    def noise_model(self):
        """The composite noise model the fit was whitened with (components.model.noise), or None
        (white noise)."""
        if "composite" not in self.noise:
            return None
        from components.model.noise import NoiseModel

        return NoiseModel.from_dict(self.noise["composite"])

    def to_dict(self) -> dict:
        out = {
            "format": FORMAT,
            "method": self.method,
            "effects": list(self.effects),
            "parameters": {p: {"value": float(v), "sigma": float(self.sigmas.get(p, float("nan"))),
                               "unit": effect_of(p).unit} for p, v in self.values.items()},
        }
        if self.correlation is not None:
            c = np.where(np.isfinite(self.correlation), self.correlation, 0.0)
            out["correlations"] = {"parameters": list(self.values),
                                   "matrix": [[round(float(x), 12) for x in row] for row in c]}
        out["noise"] = self.noise
        out["fit"] = self.fit
        out["temperature_ref_degC"] = self.temperature_ref
        out["schedule"] = self.schedule
        out["data"] = self.data
        out["software"] = _software()
        out.update(self.extra)
        return out

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=True) + "\n")
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> "CalibrationResult":
        p = Path(path)
        try:
            d = json.loads(p.read_text())
        except FileNotFoundError:
            raise ResultFormatError(f"result file {p} does not exist") from None
        except json.JSONDecodeError as e:
            raise ResultFormatError(f"{p}: not JSON ({e})") from None
        if d.get("format") != FORMAT:
            raise ResultFormatError(f"{p}: key 'format' = {d.get('format')!r}, expected {FORMAT!r}")
        params = d.get("parameters")
        if not isinstance(params, dict):
            raise ResultFormatError(f"{p}: key 'parameters' missing or not an object")
        values, sigmas = {}, {}
        for name, entry in params.items():
            try:
                e = effect_of(name)
            except KeyError as err:
                raise ResultFormatError(f"{p}: parameters.{name}: {err}") from None
            if not isinstance(entry, dict) or "value" not in entry:
                raise ResultFormatError(f"{p}: parameters.{name}: expected {{'value', 'sigma', 'unit'}}")
            if entry.get("unit", e.unit) != e.unit:
                raise ResultFormatError(f"{p}: parameters.{name}.unit = {entry.get('unit')!r}, "
                                        f"expected {e.unit!r} (SI)")
            values[name] = float(entry["value"])
            sigmas[name] = float(entry.get("sigma", float("nan")))
        effects = d.get("effects", [])
        unknown = [x for x in effects if x not in EFFECTS]
        if unknown:
            raise ResultFormatError(f"{p}: effects {unknown} are not in the vocabulary")
        corr = None
        if "correlations" in d:
            corr = np.array(d["correlations"]["matrix"], float)
        known = {"format", "method", "effects", "parameters", "correlations", "noise", "fit",
                 "temperature_ref_degC", "schedule", "data", "software"}
        return cls(effects, values, sigmas, corr, d.get("noise", {}), d.get("fit", {}),
                   d.get("temperature_ref_degC"), d.get("schedule", []), d.get("data", {}),
                   d.get("method", "least-squares"), {k: v for k, v in d.items() if k not in known})


def _software() -> dict:
    import numpy
    import scipy

    try:
        from importlib.metadata import version

        cb = version("calbench")
    except Exception:
        cb = "unknown"
    return {"calbench": cb, "python": platform.python_version(), "numpy": numpy.__version__,
            "scipy": scipy.__version__}


def schedule_of(time: np.ndarray, segment, take=None) -> list:
    """[(label, t_start, t_end)] runs of equal segment labels (t_start = start of the first
    sample's interval); *segment*: the log's labels as runs (components.logs.labels.SegmentLabels)
    or None. ``take(index)``: time[index], read another way (a spilled log's times a piece at a
    time: components.estimation.log_data.LogData.times_at)."""
    if segment is None or len(segment) == 0:
        return []
    runs = list(segment.runs())
    a = np.array([r[0] for r in runs], np.int64)
    b = np.array([r[1] for r in runs], np.int64)
    take = take or (lambda i: np.asarray(time)[i])
    first, before, last = take(a), take(np.maximum(a - 1, 0)), take(b - 1)
    dt0 = np.diff(take(np.arange(2)))[0] if len(time) > 1 else 0.0
    return [[str(label), float(first[i] - (first[i] - before[i] if a[i] else dt0)), float(last[i])]
            for i, (_, _, label) in enumerate(runs)]


def result_from_fit(fit, effects: list[str], data, log=None) -> CalibrationResult:
    """Package an lsq.Fit as a result."""
    dt = fit.dt
    noise = {
        "model": "white noise per sample (estimated from static data)",
        "sample_interval_s": dt,
        "gyro_sigma_rad": [float(x) for x in fit.sigma_gyro],
        "acc_sigma_mps": [float(x) for x in fit.sigma_acc],
        "gyro_arw_rad_per_sqrt_s": [float(x / np.sqrt(dt)) for x in fit.sigma_gyro],
        "acc_vrw_mps_per_sqrt_s": [float(x / np.sqrt(dt)) for x in fit.sigma_acc],
    }
    if getattr(fit, "rest_sigma", None) is not None:
        # how far the table rests from its encoder readings (estimated from the moves)
        noise["rest_angle_sigma_rad"] = [float(x) for x in fit.rest_sigma]
    if getattr(fit, "hidden_white", None):
        # pulse channels without a white level: a numerical floor stood in (LogData.without_white_level)
        noise["no_white_level"] = list(fit.hidden_white)
    if getattr(fit, "white_poorly_read", None):
        # pulse channels whose identified white level is not measured (LogData.white_poorly_read)
        noise["white_poorly_read"] = list(fit.white_poorly_read)
    if getattr(fit, "noise", None) is not None:
        noise["model"] = f"composite noise model ({fit.noise.source}): rows whitened with it"
        noise["composite"] = fit.noise.to_dict()
    fitd = {"chi2": fit.chi2, "dof": fit.dof, "chi2_per_dof": fit.chi2 / fit.dof if fit.dof > 0 else None,
            "iterations": fit.iterations,
            "observations": "block sums: rest-to-rest gyro moves and static chunks, accelerometer chunks"}
    if fit.dof <= 0:
        fitd["note"] = "no degrees of freedom left: the fit cannot be checked by its chi2"
    data_d = {"samples": int(len(data.time)), "duration_s": float(data.time[-1] - data.time[0] + dt)}
    # what was assumed or left out, so that a result says what produced it
    if getattr(data, "left_out", None):
        data_d["left_out_samples"] = dict(data.left_out)
    res = getattr(data, "encoder_resolution", None)
    data_d["encoder_resolution_rad"] = ("exact" if isinstance(res, str) else [float(x) for x in res]) \
        if res is not None else "not stated: one count taken from the logged angles' steps"
    if log is not None and log.source:
        src = Path(log.source)
        stem = src.with_suffix("")
        data_d["log"] = str(stem)
        for suffix in (".csv", ".parquet", ".json"):
            f = stem.with_suffix(suffix)
            if f.exists():
                data_d[f"{suffix[1:]}_sha256"] = file_sha256(f)
    # (a spilled log's times read a piece at a time: each read of a mapped file brings the pages
    # around it along, 768 runs of the 8-hour log 220 MB resident)
    schedule = schedule_of(data.time, data.segment, take=getattr(data, "times_at", None))
    return CalibrationResult(
        effects=list(effects), values=dict(zip(fit.parameters, map(float, fit.value))),
        sigmas=dict(zip(fit.parameters, map(float, fit.sigma))), correlation=fit.correlation(),
        noise=noise, fit=fitd, temperature_ref=fit.temperature_ref
        if data.temperature is not None else None,
        schedule=schedule, data=data_d,
        extra=determinability_block(fit))


def determinability_block(fit) -> dict:
    """What the log did not determine, determined weakly, or gave beyond any real IMU (see
    components.estimation.determinability and components.model.plausibility); empty when all is well."""
    from components.model.excitation import needs

    out: dict = {}
    det = getattr(fit, "determinability", None)
    if det is not None and det.undetermined:
        out["undetermined"] = {p: {"held_at": 0.0, "why": det.describe(p), "needs": needs(p)}
                               for p in det.undetermined}
    if det is not None and det.confounded:
        out["confounded"] = {p: {"sigma_ratio": r, "moves_with": [[q, c] for q, c in like],
                                 "why": det.describe_confounded(p), "needs": needs(p)}
                             for p, (r, like) in det.confounded.items()}
    if getattr(fit, "weak", None):
        out["weakly_determined"] = list(fit.weak)
    if getattr(fit, "implausible", None):
        out["implausible"] = dict(fit.implausible)
    return {"determinability": out} if out else {}


def fitted_on(model: CalibrationResult, log) -> bool:
    """Was *model* fitted to this very log (same file contents)? Then its parameters count
    against the degrees of freedom of a comparison on it."""
    if not log.source:
        return False
    stem = Path(log.source).with_suffix("")
    for suffix in ("csv", "parquet"):
        f = stem.with_suffix("." + suffix)
        if f.exists() and model.data.get(f"{suffix}_sha256") == file_sha256(f):
            return True
    return False
