"""What a multi-position calibration (:mod:`.positions`) returns: per rest, per turn and the fit
as a whole, printable and convertible to a components.model.result.CalibrationResult."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from components.model.effects import effect_of

# stated in every result, so that a reader of the file knows what the accelerometer
# misalignments are relative to (docs/positions.md, "the gauge")
GAUGE = ("body frame B = the frame the rotations' axes and 'up' hints are given in; the accelerometer "
         "triad is lower-triangular in B (acc x along B x, acc y in the B x-y plane): acc.mis.xy = "
         "acc.mis.xz = acc.mis.yz = 0 by convention; gyro parameters relative to B")


@dataclass
class PositionResult:
    """One static position: its estimated attitude and what is left of its rows."""

    name: str                 # the label, or label#k for the k-th run of a label used twice
    label: str
    start: int                # sample range [start, stop) of the run
    stop: int
    samples: int              # samples used
    duration: float           # s used
    up: np.ndarray            # body-frame unit vector pointing up (gravity's reaction), in B
    up_covariance: np.ndarray  # (3, 3) [rad²]
    up_hint: np.ndarray | None
    hint_angle_deg: float | None  # angle between the stated and the estimated up
    north: np.ndarray | None  # body-frame north (latitude given)
    heading_sigma_deg: float | None
    acc_residual: np.ndarray  # mean specific-force residual [m/s²]
    gyro_residual: np.ndarray  # mean rate residual [rad/s]
    chi2: float
    rows: int

    @property
    def up_sigma_deg(self) -> float:
        return math.degrees(math.sqrt(max(float(np.trace(self.up_covariance)), 0.0)))


@dataclass
class RotationResult:
    """One rotation segment and its fit."""

    name: str
    label: str
    start: int                # summed samples [start, stop) (with the rest sample on each side)
    stop: int
    axis: np.ndarray          # unit, body frame B
    angle: float              # rad, stated
    duration: float
    before: str               # position names on either side
    after: str
    measured: np.ndarray      # Σ gyro increments [rad]
    earth: np.ndarray         # M_r C_qᵀ Ω_n [rad] (0 without latitude)
    residual: np.ndarray      # measured − model [rad]
    normalized: np.ndarray    # residual / σ
    end_mismatch_deg: float   # angle between R(a, θ)ᵀ u_before and u_after

    @property
    def chi2(self) -> float:
        return float(self.normalized @ self.normalized)


@dataclass
class PositionsFit:
    """A multi-position calibration (see components.estimation.positions for the model and the gauge)."""

    effects: list[str]
    parameters: list[str]          # estimated, vocabulary names
    value: np.ndarray
    covariance: np.ndarray
    held: dict[str, str]           # parameter -> why it is held at 0 (the gauge)
    undetermined: list[str]        # requested but not determined by these data: held at 0, no σ
    chi2: float
    dof: int
    positions: list[PositionResult]
    rotations: list[RotationResult]
    sigma_gyro: np.ndarray         # per-sample white σ [rad]
    sigma_acc: np.ndarray          # [m/s]
    sample_interval: float
    noise_source: str
    latitude: float | None
    gravity: float
    iterations: int
    excluded: dict = field(default_factory=dict)   # label -> samples left out ('(valid = False)': masked)
    notes: list[str] = field(default_factory=list)
    schedule: list = field(default_factory=list)   # [(label, t_start, t_end)]
    samples: int = 0
    duration: float = 0.0
    gauge: str = GAUGE
    attitudes: np.ndarray | None = None  # (P, 3, 3) body -> ENU per rest, in the order of `positions`
    temperature_ref: float | None = None  # °C, T0 of temperature effects (None: no temperature effect)
    noise: object = None  # the composite NoiseModel the rows were whitened with (None: white only)

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))

    @property
    def chi2_per_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")

    def chi2_band(self, level: float = 0.999) -> tuple[float, float]:
        """The two-sided band of χ²/dof that a correct model and noise model fall in with
        probability *level*."""
        from scipy.stats import chi2

        a = (1 - level) / 2
        return float(chi2.ppf(a, self.dof) / self.dof), float(chi2.ppf(1 - a, self.dof) / self.dof)

    def values(self) -> dict[str, float]:
        return dict(zip(self.parameters, map(float, self.value)))

    def sigmas(self) -> dict[str, float]:
        return dict(zip(self.parameters, map(float, self.sigma)))

    def correlation(self) -> np.ndarray:
        s = self.sigma
        return self.covariance / np.outer(s, s)

    def lines(self) -> list[str]:
        """A printable summary: estimated parameters with σ; held and undetermined ones named,
        never with a σ."""
        out = [f"{'parameter':18s} {'value':>12s} {'sigma':>10s}  unit"]
        for p, v, s in zip(self.parameters, self.value, self.sigma):
            unit, k = effect_of(p).display
            out.append(f"{p:18s} {v / k:+12.5g} {s / k:10.3g}  {unit}")
        if self.held:
            out.append(f"held by the gauge (not estimated): {', '.join(self.held)}")
        if self.undetermined:
            out.append(f"not determined by these data (not estimated): {', '.join(self.undetermined)}")
        lo, hi = self.chi2_band()
        out.append(f"chi2/dof = {self.chi2_per_dof:.3f} ({self.dof} dof; 99.9 % band {lo:.3f}-{hi:.3f}), "
                   f"{len(self.positions)} positions, {len(self.rotations)} rotations")
        for p, why in self.implausible().items():
            out.append(f"IMPLAUSIBLE {p}: {why}")
        out += [f"note: {n}" for n in self.notes]
        return out

    def implausible(self) -> dict[str, str]:
        """Estimates no real IMU has, with the likely cause (components.model.plausibility)."""
        from components.model.plausibility import implausible

        return implausible(self.values(), self.sample_interval)

    def to_result(self, source: str | Path | None = None):
        """A components.model.result.CalibrationResult (method "positions"). Held and
        undetermined parameters are not among its values (a model reads them as 0) and are
        listed in its ``positions`` block. ``source``: the log the data came from (its files'
        SHA-256 are recorded)."""
        from components.model.result import CalibrationResult, file_sha256

        dt = self.sample_interval
        noise = {
            "model": f"white noise per sample ({self.noise_source})",
            "sample_interval_s": dt,
            "gyro_sigma_rad": [float(x) for x in self.sigma_gyro],
            "acc_sigma_mps": [float(x) for x in self.sigma_acc],
            "gyro_arw_rad_per_sqrt_s": [float(x / math.sqrt(dt)) for x in self.sigma_gyro],
            "acc_vrw_mps_per_sqrt_s": [float(x / math.sqrt(dt)) for x in self.sigma_acc],
        }
        if self.noise is not None:
            # as a table log's result: compare, diagnose and add read the model's noise from here
            noise["model"] = f"composite noise model ({self.noise.source}): rows whitened with it"
            noise["composite"] = self.noise.to_dict()
        lo, hi = self.chi2_band()
        fit = {"chi2": float(self.chi2), "dof": int(self.dof), "chi2_per_dof": float(self.chi2_per_dof),
               "chi2_per_dof_band_999": [lo, hi], "iterations": int(self.iterations),
               "observations": "static chunks (accelerometer and gyro) per position, one summed row "
                               "per rotation; attitudes estimated (2 tilt angles per position, "
                               "+ heading with the latitude)"}
        data = {"samples": int(self.samples), "duration_s": float(self.duration)}
        if source is not None:
            stem = Path(source).with_suffix("")
            data["log"] = str(stem)
            for suffix in (".csv", ".parquet", ".json"):
                f = stem.with_suffix(suffix)
                if f.exists():
                    data[f"{suffix[1:]}_sha256"] = file_sha256(f)
        block = {
            "gauge": self.gauge,
            "held": dict(self.held),
            "undetermined": list(self.undetermined),
            "latitude_deg": None if self.latitude is None else math.degrees(self.latitude),
            "gravity_mps2": self.gravity,
            "attitudes": [{"name": p.name, "label": p.label, "samples": p.samples,
                           "up": [float(x) for x in p.up], "up_sigma_deg": p.up_sigma_deg,
                           "hint_angle_deg": p.hint_angle_deg,
                           "north": None if p.north is None else [float(x) for x in p.north],
                           "heading_sigma_deg": p.heading_sigma_deg,
                           "acc_residual_mps2": [float(x) for x in p.acc_residual],
                           "gyro_residual_rps": [float(x) for x in p.gyro_residual],
                           "chi2": p.chi2, "rows": p.rows} for p in self.positions],
            "rotations": [{"name": r.name, "label": r.label, "axis": [float(x) for x in r.axis],
                           "angle_deg": math.degrees(r.angle), "duration_s": r.duration,
                           "before": r.before, "after": r.after,
                           "residual_rad": [float(x) for x in r.residual],
                           "normalized": [float(x) for x in r.normalized],
                           "earth_rad": [float(x) for x in r.earth],
                           "end_mismatch_deg": r.end_mismatch_deg} for r in self.rotations],
            "excluded_samples": dict(self.excluded),
            "notes": list(self.notes),
        }
        bad = self.implausible()
        extra = {"positions": block}
        if bad or self.undetermined:
            extra["determinability"] = {k: v for k, v in (
                ("implausible", bad),
                ("undetermined", {p: {"held_at": 0.0, "why": "not determined by these data"} for p in self.undetermined}),
            ) if v}
        return CalibrationResult(
            effects=list(self.effects), values=self.values(), sigmas=self.sigmas(),
            correlation=self.correlation() if len(self.parameters) else None, noise=noise, fit=fit,
            temperature_ref=self.temperature_ref, schedule=[list(s) for s in self.schedule], data=data,
            method="positions", extra=extra)
