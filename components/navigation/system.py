"""System-level calibration of a log: stages of a configuration (components.navigation.configs)
run in order on the log; each stage's estimates correct the data of the next ones and the merged
estimates form one CalibrationResult (method "system-level KF"), with the same vocabulary and
file as the least-squares procedures (compare / diagnose / add work on it).

A ``kf`` stage: the samples of a window (segment labels matching a regular expression, from the
first to the last match), corrected by the earlier stages' estimates; per pass: coarse and fine
alignment on the window's first static run (data corrected by the current estimates), then the
closed-loop filter (components.navigation.kf) from the start of that run to the window's end.
The alignment run is the window's first rest of at least ``align_min_s`` (a table settling after
an index creeps; data before that rest are not used).
A ``cwccw`` stage: the CW/CCW closed forms (components.procedures.cwccw) for the listed
parameters (seed 001's gyro stage).
A ``table`` stage: the least squares (components.estimation.lsq) with the table angles on a window, the
model's ``effects`` fitted jointly and only ``parameters`` kept (seed 003's table-referenced
steps S201/S202). It is where the IMU/table time offset comes from: the navigation velocity on
a stationary base cannot see it (a delayed IMU record is an equally valid trajectory), the
table angles can (the accelerometers lead or lag the gravity turning through them at each
index by ``time_offset · df/dt``).

Deterministic: no random numbers, a fixed order of operations, so a raw log re-solved later
gives bit-identical values (seed 003's offline re-solve).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field, replace

import numpy as np

from components.estimation.blocks import white_noise_sigma
from components.estimation.log_data import LogData
from components.logs.labels import SegmentLabels
from components.model.effects import effect_of, parameters_of
from components.model.excitation import needs
from components.model.result import CalibrationResult, schedule_of
from components.navigation.alignment import alignment_run, coarse_align, fine_align
from components.navigation.consistency import check_stage
from components.navigation.earth import Site
from components.navigation.kf import (
    SIGMA_ACC_FLOOR,
    SIGMA_GYRO_FLOOR,
    FilterOutput,
    FilterSettings,
    noise_states,
    prior_sigmas,
    run_filter,
)
from components.navigation.sensor import Regressors

METHOD = "system-level KF"
STATIC_TOL = 1e-9  # rad: an angle change per sample below this is "at rest"
UNINFORMED = 0.9  # a filter state whose posterior σ is above this share of its prior σ: not determined
PRIOR_WEIGHTED = 0.5  # above this share the prior holds a quarter or more of its information: weak


@dataclass
class Stage:
    kind: str = "kf"                      # "kf", "table" or "cwccw"
    name: str = ""
    effects: list = field(default_factory=list)
    parameters: list | None = None        # explicit parameter list (default: all of effects)
    window: str | None = None             # regex on segment labels
    settings: dict = field(default_factory=dict)  # FilterSettings fields
    align_max_s: float = 60.0
    align_min_s: float = 10.0             # the filter starts at the first rest this long
    consider_earlier: bool = False        # keep what earlier stages estimated as consider states


@dataclass
class Config:
    name: str
    description: str
    stages: list
    schedule: str | None = None           # the ready-made schedule it is meant for

    def schedule_mismatch(self, segment: np.ndarray | None, source) -> list[str]:
        """The configuration is built for a schedule whose positions excite its states; a log
        (its *segment* labels) with far fewer segments than it (a six-position log under psins19's
        19 positions) leaves states at their prior with σ that look like estimates: said before
        the run."""
        if not self.schedule or segment is None:
            return []
        from components.control.schedule import load_schedule

        try:
            want = [lab for lab in load_schedule(self.schedule).labels if not lab.startswith("move-")]
        except (ValueError, OSError):
            return []
        have = {x for x in SegmentLabels.of(segment).distinct() if not x.startswith("move-")}  # (any labels)
        if len(have) >= 0.8 * len(want):
            return []
        return [f"{source}: {len(have)} segment label(s) beside the moves, where configuration {self.name}'s "
                f"schedule {self.schedule!r} has {len(want)}: its filter's states are excited by that schedule's "
                "positions, and on this log some will stay near their prior (their σ then the prior's, not the "
                "data's); run the schedule, or a configuration made for this log's"]


def static_mask(angles: np.ndarray) -> np.ndarray:
    d = np.abs(np.diff(angles, axis=0, prepend=angles[:1]))
    return np.all(d <= STATIC_TOL, axis=1)


def window_of(segment, pattern: str | None, n: int) -> tuple[int, int]:
    if pattern is None or segment is None:
        return 0, n
    rx = re.compile(pattern)
    hit = [(a, b) for a, b, label in SegmentLabels.of(segment).runs() if rx.search(label)]
    if not hit:
        raise ValueError(f"no segment label matches {pattern!r}")
    return hit[0][0], hit[-1][1]


@dataclass
class StageOutput:
    stage: Stage
    parameters: list
    values: np.ndarray
    covariance: np.ndarray
    filter: FilterOutput | None = None
    window: tuple = (0, 0)
    passes: list = field(default_factory=list)
    joint_parameters: list = field(default_factory=list)   # estimated + consider
    joint_covariance: np.ndarray | None = None
    totals: np.ndarray | None = None      # the parameters' values after this stage: ``values``
    #                                       are the increments on the earlier stages' estimates
    prior_values: np.ndarray | None = None  # a kf stage: where its filter started, and the σ of
    prior_sigma: np.ndarray | None = None   # its prior (components.navigation.consistency)
    kf_interval: float | None = None
    noise_free: bool = False              # its data carry no noise (the innovation check does not apply)


def joint_prior(outputs: list, names: list[str]) -> np.ndarray:
    """Covariance of ``names`` from earlier stages: each pair from the latest stage that had
    both in its joint state (cross-stage pairs 0)."""
    P = np.zeros((len(names), len(names)))
    for i, p in enumerate(names):
        for j, q in enumerate(names):
            for so in reversed(outputs):
                jp = so.joint_parameters or so.parameters
                jc = so.joint_covariance if so.joint_covariance is not None else so.covariance
                if p in jp and q in jp:
                    P[i, j] = jc[jp.index(p), jp.index(q)]
                    break
                if p in jp or q in jp:
                    break
    return P


def _noise_settings(settings: FilterSettings, noise, dt: float, span: float) -> None:
    """A composite noise model into a filter's settings: its white level where it gives one
    (else the data's, already set), plus the power of the terms too fast for states; its slow
    terms as states (components.navigation.kf.noise_states)."""
    states, fast = noise_states(noise, settings.kf_interval, span)
    white = noise.white_sigma(dt)   # per-sample σ [rad, m/s]
    for key, ch in (("sigma_gyro", slice(0, 3)), ("sigma_acc", slice(3, 6))):
        own = np.broadcast_to(np.asarray(getattr(settings, key), float), (3,))
        level = np.where(white[ch] > 0, white[ch], own)
        setattr(settings, key, np.sqrt(level**2 + fast[ch] * dt))
    settings.noise_states = tuple(states)


def run_kf_stage(data: LogData, stage: Stage, fixed: dict, static: np.ndarray,
                 dt: float, earlier_sigma: dict | None = None, earlier: list | None = None,
                 progress=None, noise=None) -> StageOutput:
    params = stage.parameters or parameters_of(stage.effects)
    consider = []
    if stage.consider_earlier and earlier:
        # the earlier filters' states; a table stage's parameters (the time offset) do not enter
        # the navigation velocity, so they are not states of a filter
        consider = [q for so in earlier if so.stage.kind == "kf"
                    for q in so.parameters if q not in params]
        consider = list(dict.fromkeys(consider))
    a, b = window_of(data.segment, stage.window, len(data.time))
    site = Site.of_geometry(data.geometry)
    # the earlier stages' estimates, applied once to the window's raw data; not the time offset:
    # a navigation solution does not depend on when the IMU's clock says its samples were taken
    # (the table's time enters only through the rests), and shifting increments by a first-
    # order correction errs where a move starts or stops within a sample (noise-free seed_003
    # with 0.2 ms: gyro biases 0.003-0.007 deg/h off, against 2-6e-4 uncorrected)
    fixed_p = [p for p, v in fixed.items() if v != 0.0 and p != "imu.time_offset"]
    g, ac = data.gyro[a:b], data.acc[a:b]
    temp = None if data.temperature is None else data.temperature[a:b]
    st = static[a:b]
    if fixed_p:
        values = np.array([fixed[p] for p in fixed_p])
        g, ac = Regressors.on_estimated_motion(fixed_p, values, g, ac, dt, temp, st).correct(values)
    s0, s1 = alignment_run(st, max(2, int(round(stage.align_min_s / dt))))
    s1 = min(s1, s0 + max(2, int(round(stage.align_max_s / dt))))
    settings = FilterSettings(parameters=params, **stage.settings)
    if consider:
        # the earlier stages' joint covariance is this stage's prior, as is (no inflation):
        # continuing their filter on new data, with the consider states held
        settings.consider = consider
        settings.prior_cov = joint_prior(earlier, params + consider)
        earlier_sigma = {}    # a parameter an earlier stage estimated starts from that estimate with its σ (×3) as the
    # prior: a later filter refines it where its data are informative and keeps it elsewhere
    for p in params:
        s_prev = (earlier_sigma or {}).get(p)
        if s_prev is not None and np.isfinite(s_prev) and p not in settings.prior_sigma:
            settings.prior_sigma = {**settings.prior_sigma, p: 3.0 * s_prev}
    if settings.sigma_gyro is None:
        settings.sigma_gyro = white_noise_sigma(g, st)
    if settings.sigma_acc is None:
        settings.sigma_acc = white_noise_sigma(ac, st)
    for key in ("sigma_gyro", "sigma_acc"):
        v = np.asarray(getattr(settings, key), float)
        setattr(settings, key, np.where(np.isfinite(v), v, 0.0))
    if noise is not None:
        _noise_settings(settings, noise, dt, (len(g) - s0) * dt)
    g, ac, st = g[s0:], ac[s0:], st[s0:]
    temp = None if temp is None else temp[s0:]
    theta = np.array([settings.initial.get(p, 0.0) for p in params], float)
    # every pass keeps the prior where it was (a Gauss–Newton iteration, components.navigation.kf);
    # only the closed-loop mode (effect_feedback, the smoother) re-centres a vague prior
    closed = settings.effect_feedback or settings.smoother
    prior_mean = None if closed and not consider else theta.copy()
    passes = []
    out = None
    n_passes = settings.passes
    for i_pass in range(n_passes):
        if progress is not None:
            progress(f"{stage.name} pass {i_pass + 1}/{n_passes}")
        # the regressors on the motion corrected by this pass's linearisation point
        regs = Regressors.on_estimated_motion(params + consider, np.concatenate(
            [theta, np.zeros(len(consider))]), g, ac, dt, temp, static=st)
        n_al = s1 - s0
        if params:
            G, A = regs.block(0, n_al)
            th = np.concatenate([theta, np.zeros(len(consider))])
            ga, aa = g[:n_al] - G @ th, ac[:n_al] - A @ th
        else:
            ga, aa = g[:n_al], ac[:n_al]
        C0 = coarse_align(ga, aa, site)
        C0, sphi = fine_align(ga, aa, dt, site, C0, settings.sigma_gyro, settings.sigma_acc)
        phi0 = np.maximum(np.asarray(settings.phi0, float), 3 * sphi)
        run_settings = replace(settings, phi0=tuple(phi0))
        out = run_filter(g, ac, dt, site, C0, st, run_settings, regs, theta,
                         time0=float(data.time[a + s0] - dt), prior_mean=prior_mean)
        theta = out.values
        passes.append(theta.copy())
    out.pass_values = passes
    joint = slice(9, 9 + len(params) + len(consider))   # not the slow-noise states after them
    so = StageOutput(stage, params, theta, out.covariance, out, (a + s0, b), passes,
                     params + consider, out.P[joint, joint].copy())
    so.prior_values = np.array([settings.initial.get(p, 0.0) for p in params], float)
    so.prior_sigma = prior_sigmas(params, settings)
    so.kf_interval = settings.kf_interval
    # noise-free data (a simulation's check of the model): the filter runs on its numerical floors,
    # where the innovations measure the linearisation, not the data's noise
    so.noise_free = bool(np.all(np.asarray(settings.sigma_gyro, float) <= 1.01 * SIGMA_GYRO_FLOOR)
                         and np.all(np.asarray(settings.sigma_acc, float) <= 1.01 * SIGMA_ACC_FLOOR))
    return so


def run_table_stage(data: LogData, stage: Stage, fixed: dict, dt: float) -> StageOutput:
    from components.estimation.lsq import calibrate

    a, b = window_of(data.segment, stage.window, len(data.time))
    # from the sample before the first match: a window's first match is often the start of a
    # move, whose first interval needs the rest angle before it
    a = max(a - 1, 0)
    window = data.window(a, b)
    rests = static_mask(window.angles)
    fixed_p = [p for p, v in fixed.items() if v != 0.0 and effect_of(p).target != "table"]
    if fixed_p:
        values = np.array([fixed[p] for p in fixed_p])
        g, ac = Regressors.on_estimated_motion(fixed_p, values, window.gyro, window.acc, dt,
                                               window.temperature, rests).correct(values)
        window = replace(window, gyro=g, acc=ac)
    # per-sample σ from the rests, with the filter's floors: a noise-free log (a check of the
    # model) would otherwise weigh its rows by 1e-13 of a sample and let model error decide
    sg = np.fmax(np.nan_to_num(white_noise_sigma(window.gyro, rests)), SIGMA_GYRO_FLOOR)
    sa = np.fmax(np.nan_to_num(white_noise_sigma(window.acc, rests)), SIGMA_ACC_FLOOR)
    fit = calibrate(window, stage.effects, sigma_gyro=sg, sigma_acc=sa)
    params = stage.parameters or fit.parameters
    missing = [p for p in params if p not in fit.parameters]
    if missing:
        raise ValueError(f"table stage {stage.name!r}: {', '.join(missing)} not among the "
                         f"parameters of its effects ({', '.join(stage.effects)})")
    idx = [fit.parameters.index(p) for p in params]
    return StageOutput(stage, params, fit.value[idx].copy(), fit.covariance[np.ix_(idx, idx)].copy(),
                       window=(a, b))


def run_cwccw_stage(log, stage: Stage) -> StageOutput:
    from components.procedures import cwccw

    res = cwccw.run(log)
    params = stage.parameters or [p for p in res.values if effect_of(p).name in stage.effects]
    vals = np.array([res.values[p] for p in params])
    cov = np.diag([res.sigmas.get(p, np.nan) ** 2 for p in params])
    return StageOutput(stage, params, vals, cov)


def rests_of(data: LogData) -> np.ndarray:
    """(N,) bool: the samples the IMU rests through — from the table angles, or in a log without
    them from the segments described as static — and that are usable."""
    if data.has_table:
        return static_mask(data.angles) & data.usable
    kinds = data.segment_kinds or {}
    labels = [lab for lab, d in kinds.items() if d["kind"] == "static"]
    if data.segment is None or not labels:
        raise ValueError("a log without table angles needs segments described as static (the rests the "
                         "filter aligns on and observes zero velocity in)")
    return data.segment.isin(labels) & data.usable


def calibrate_system(log, config: Config, exclude: list | None = None,
                     progress=None, noise=None, data: LogData | None = None) -> tuple[CalibrationResult, list[StageOutput]]:
    """Run a configuration's stages on a MeasurementLog (``exclude``: more to leave out, as
    components.estimation.log_data.LogData.from_log takes it; *data*: that LogData when the
    caller has it). ``progress(text)``, when given, is called before each table or CW/CCW stage
    and each filter pass. ``noise``: the sensors' composite noise model
    (components.model.noise.NoiseModel); its slow terms become states of every filter stage
    (components.navigation.kf); None: white noise, its level from the static data."""
    data = LogData.from_log(log, exclude) if data is None else data
    dt = float(log.dt)
    static = rests_of(data)
    fixed: dict[str, float] = {}
    sigmas: dict[str, float] = {}
    outputs = []
    notes: list[str] = []
    for stage in config.stages:
        if stage.kind in ("cwccw", "table") and not data.has_table:
            if stage.kind == "cwccw":
                raise ValueError(f"stage {stage.name!r} (CW/CCW closed forms) needs the table angles, which this "
                                 "log does not have; use a configuration of kf stages")
            notes.append(f"stage {stage.name!r} skipped: it fits {', '.join(stage.parameters or stage.effects)} "
                         "against the table angles, which this log does not have (left at 0)")
            continue
        if progress is not None and stage.kind in ("cwccw", "table"):
            progress(stage.name)
        if stage.kind == "cwccw":
            so = run_cwccw_stage(log, stage)
        elif stage.kind == "table":
            so = run_table_stage(data, stage, fixed, dt)
        elif stage.kind != "kf":
            raise ValueError(f"stage {stage.name!r}: kind {stage.kind!r}, expected kf, table or cwccw")
        else:
            so = run_kf_stage(data, stage, fixed, static, dt, dict(sigmas), outputs, progress, noise)
        for p, v, s in zip(so.parameters, so.values, np.sqrt(np.diag(so.covariance))):
            fixed[p] = fixed.get(p, 0.0) + float(v)
            sigmas[p] = float(s)
        so.totals = np.array([fixed[p] for p in so.parameters])
        outputs.append(so)
    res = _result(log, data, config, fixed, sigmas, outputs, noise)
    if notes:
        res.fit["notes"] = notes
    # a filter state whose σ stays at its prior's: the log did not inform it
    undetermined, prior_weighted = {}, {}
    for so in outputs:
        if so.filter is None or so.prior_sigma is None:
            continue
        for p, s, s0 in zip(so.parameters, np.sqrt(np.abs(np.diag(so.covariance))), so.prior_sigma):
            if s0 > 0 and s > UNINFORMED * s0:
                undetermined[p] = {"why": f"stage {so.stage.name!r}: its σ stays at {s / s0:.0%} of its prior σ: "
                                          "this log does not inform it", "needs": needs(p)}
            elif s0 > 0 and s > PRIOR_WEIGHTED * s0:
                # the prior still holds a quarter or more of what is known of it: its estimate
                # leans towards where the filter started, its σ partly the prior's
                prior_weighted[p] = float(s / s0)
    if undetermined or prior_weighted:
        res.extra["determinability"] = {"undetermined": undetermined,
                                        "weakly_determined": sorted(prior_weighted),
                                        "posterior_to_prior_sigma": prior_weighted}
    return res, outputs


def _result(log, data, config, values, sigmas, outputs, noise_model=None) -> CalibrationResult:
    effects = list(dict.fromkeys(effect_of(p).name for p in values))
    params = list(values)
    # correlations within each stage's filter; across stages 0
    corr = np.eye(len(params))
    for so in outputs:
        if so.filter is None:
            continue
        s = np.sqrt(np.diag(so.covariance))
        with np.errstate(invalid="ignore", divide="ignore"):
            c = so.covariance / np.outer(s, s)
        for i, p in enumerate(so.parameters):
            for j, q in enumerate(so.parameters):
                corr[params.index(p), params.index(q)] = c[i, j]
    stages = []
    for so in outputs:
        d = {"name": so.stage.name, "kind": so.stage.kind, "parameters": so.parameters}
        if so.stage.kind == "table":
            d.update({"window_samples": [int(so.window[0]), int(so.window[1])],
                      "effects_fitted": list(so.stage.effects), "observations": "table angles"})
        if so.filter is not None:
            f = so.filter
            nu = f.innovations / np.sqrt(np.maximum(f.innovation_var, 1e-300))
            c = check_stage(so, so.kf_interval or 0.1, so.prior_values, so.prior_sigma)
            d.update({"window_samples": [int(so.window[0]), int(so.window[1])],
                      "passes": len(so.passes), "updates_per_pass": f.updates,
                      "predictions_per_pass": f.predictions,
                      "final_nav_sigma": [float(x) for x in f.sigma_nav],
                      "normalised_innovation_rms": float(np.sqrt(np.mean(nu ** 2))) if len(nu) else None,
                      "consistency": {"ok": c.ok, "problems": c.problems, "innovation_windows": c.windows,
                                      "windows_out": c.windows_out, "whiteness_p": c.whiteness_p}})
        stages.append(d)
    dt = float(log.dt)
    noise = {"model": "white noise per sample (estimated from static data)", "sample_interval_s": dt}
    if noise_model is not None:
        slow = max((len(so.filter.P) - 9 - len(so.joint_parameters) for so in outputs if so.filter is not None),
                   default=0)
        noise = {"model": f"composite ({noise_model.source}); its slow terms states of the filters ({slow} per "
                          "filter)", "sample_interval_s": dt, "composite": noise_model.to_dict()}
    fit = {"config": config.name, "stages": stages,
           "observations": "navigation velocity (zero truth) in static filter intervals"}
    data_d = {"samples": int(len(data.time)), "duration_s": float(data.time[-1] - data.time[0] + dt)}
    if log.source:
        data_d["log"] = str(log.source)
    return CalibrationResult(effects=effects, values={p: float(values[p]) for p in params},
                             sigmas={p: float(sigmas.get(p, np.nan)) for p in params},
                             correlation=corr, noise=noise, fit=fit,
                             temperature_ref=None, schedule=schedule_of(data.time, data.segment),
                             data=data_d, method=METHOD)
