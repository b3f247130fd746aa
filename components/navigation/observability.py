"""Observability of the system-level filter for a schedule and a state set: piece-wise constant
system (PWCS) analysis with SVD (Goshen-Meskin & Bar-Itzhack 1992), matched against the
filter's own covariance.

The error model is the filter's (components.navigation.kf) without the position errors: they
feed nothing back (gravity and Earth rate are those of the fixed site) and are never observed,
so they are unobservable by construction and left out. State ``x = [φ (3), δv (3), θ (m)]``,
observation ``z = δv = H x``.

- **Segments.** The log is cut into static runs (the table at rest: the system is constant,
  ``F_j`` from the attitude C_j, the specific force and the effects' regressors averaged over the
  run) and moves (time-varying, not observed).
- **Transitions.** A static run's transition is ``expm(F_j τ_j)``; a move's is the product of
  the filter's own per-sample discretisation ``[[I + F T + (F T)²/2, B_k], [0, I]]`` over the
  measured motion (this is where the rotations carry gyro scale-factor / misalignment and
  lever-arm errors into the attitude and velocity errors).
- **Total observability matrix (TOM).** For each static run j: the time-scaled Krylov block
  ``O_j = [H; H (F_j τ_j); H (F_j τ_j)²/2!; …; H (F_j τ_j)^K/K!]`` (the Taylor terms of
  ``H Φ_j(t)`` over the run: the same row space as the usual ``[H; H F; H F²; …]`` but in m/s
  per unit state, so blocks of different runs are commensurate), times the transition from the
  start of the analysis to the start of run j. Stacked over the runs. (The stripped matrix that
  leaves the transitions out is not valid here: the moves' B terms are not in the null space of
  the static F_j, the condition for stripping.)
- **SVD.** Columns scaled by reference σ (the filter's initial σ: φ0, v0, the priors of the
  effects), so a singular value is the velocity signature [m/s] of a unit-prior-σ combination;
  ``rank`` counts singular values above ``rel_tol`` × the largest; the right singular vectors of
  the small ones are the unobservable (or weakly observable) combinations; each state's
  *degree* is the singular value of the direction it dominates (the largest |v_i| component).
- **Filter covariance.** :func:`filter_covariance` runs the filter itself on the same data with a
  noise model (one pass, no feedback effect on noise-free data): its σ / prior σ per state is the
  quantitative "how well"; along a PWCS null direction v (its effect-state part, normalised) the
  filter must keep ``vᵀ D⁻¹ P D⁻¹ v ≈ 1`` (it cannot learn it), observable ones shrink.
  :func:`analyse` returns both. The normalised singular values depend on the priors (the largest
  is usually a lever arm with a 0.2 m prior): "weak" (below 1e-4 of the largest) is a pointer, the
  filter's σ / prior is the measure.

The IMU/table time offset: a shifted IMU record on a stationary base is a shifted, equally valid
trajectory, so from velocity alone its gyro and accelerometer signatures cancel (to ~1 %); the
linear transitions here reproduce the cancellation only to ~0.5 % of the gyro part, so the
offset shows as "weakly observable" through discretisation residuals that the real data do not
carry: treat it as unobservable without table angles (tests/test_observability.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from components.estimation.log_data import LogData
from components.model.effects import effect_of
from components.model.geometry import skew
from components.navigation.earth import Site
from components.navigation.kf import FilterSettings, prior_sigmas
from components.navigation.sensor import Regressors
from components.navigation.strapdown import rot

NAV6 = ["phi.E", "phi.N", "phi.U", "dv.E", "dv.N", "dv.U"]


@dataclass
class Observability:
    states: list[str]                 # NAV6 + parameters
    ref_sigma: np.ndarray             # column scaling (the filter's initial σ)
    singular_values: np.ndarray       # of the scaled TOM, descending [m/s per unit prior σ]
    vt: np.ndarray                    # right singular vectors (rows), scaled coordinates
    rank: int
    rel_tol: float
    segments: int                     # static runs stacked
    degree: dict = field(default_factory=dict)       # state -> singular value it dominates
    unobservable: list = field(default_factory=list)  # [(σ_i, {state: component})] below tol
    filter_sigma: dict | None = None  # state -> filter σ (noise model), if computed
    filter_ratio: dict | None = None  # state -> filter σ / prior σ
    null_filter_ratio: list | None = None  # per unobservable direction: sqrt(vᵀ D⁻¹PD⁻¹ v)
    transition: np.ndarray | None = None   # start -> end of the analysed data (unscaled)
    weak_from: int = 0                # index of the first singular value below weak_tol

    @property
    def normalised(self) -> np.ndarray:
        s = self.singular_values
        return s / s[0] if len(s) and s[0] > 0 else s

    def combination(self, i: int, top: int = 4, min_weight: float = 0.1) -> dict:
        v = self.vt[i]
        order = np.argsort(-np.abs(v))[:top]
        return {self.states[j]: float(v[j]) for j in order if abs(v[j]) >= min_weight}

    def report(self) -> str:
        lines = [f"PWCS observability: {len(self.states)} states (6 navigation + "
                 f"{len(self.states) - 6} effects), {self.segments} static runs; rank {self.rank} "
                 f"(singular values above {self.rel_tol:g} x the largest)"]
        hdr = f"{'state':18s} {'degree':>10s}"
        if self.filter_sigma is not None:
            hdr += f" {'filter sigma':>14s} {'unit':6s} {'sigma/prior':>11s}"
        lines.append(hdr)
        for st in self.states:
            row = f"{st:18s} {self.degree[st] / self.singular_values[0]:10.2e}"
            if self.filter_sigma is not None:
                unit, k = _display(st)
                row += (f" {self.filter_sigma[st] / k:14.4g} {unit:6s}"
                        f" {self.filter_ratio[st]:11.3g}")
            lines.append(row)
        if self.unobservable:
            lines.append("unobservable (below rel_tol) and weak (below 1e-4) combinations "
                         "(normalised singular value: components in prior-sigma units):")
            for i, (s, comb) in enumerate(self.unobservable):
                c = ", ".join(f"{v:+.2f} {k}" for k, v in comb.items())
                extra = ""
                if self.null_filter_ratio is not None and self.null_filter_ratio[i] is not None:
                    extra = f"   [filter sigma/prior along it {self.null_filter_ratio[i]:.3f}]"
                kind = "unobservable" if s <= self.rel_tol * self.singular_values[0] else "weak"
                lines.append(f"  {kind:12s} {s / self.singular_values[0]:9.2e}: {c}{extra}")
        else:
            lines.append("every state and combination is observable")
        return "\n".join(lines)


def _display(state: str) -> tuple[str, float]:
    if state.startswith("phi."):
        return "arcsec", math.pi / 180 / 3600
    if state.startswith("dv."):
        return "m/s", 1.0
    return effect_of(state).display


def static_runs(static: np.ndarray, min_len: int = 2) -> list[tuple[int, int, bool]]:
    """[(a, b, is_static)] covering all samples in order."""
    out = []
    n = len(static)
    a = 0
    while a < n:
        b = a + 1
        while b < n and static[b] == static[a]:
            b += 1
        out.append((a, b, bool(static[a]) and b - a >= min_len))
        a = b
    return out


def _ref_sigma(params, settings: FilterSettings) -> np.ndarray:
    return np.concatenate([np.asarray(settings.phi0, float), np.full(3, settings.v0),
                           prior_sigmas(params, settings) if params else np.zeros(0)])


def total_observability(data: LogData, parameters: list[str], settings: FilterSettings | None = None,
                        window: tuple[int, int] | None = None, krylov: int = 4,
                        min_static_s: float = 1.0):
    """The scaled TOM of a log (error-free motion of a schedule, or any log) for a state set.
    Returns (TOM (rows, 6 + m), reference σ (6 + m,), number of static runs, the transition
    from the start to the end (6 + m, 6 + m), unscaled)."""
    from components.navigation.system import static_mask

    params = list(parameters)
    settings = settings or FilterSettings(parameters=params)
    m = len(params)
    n = 6 + m
    a0, b0 = window or (0, len(data.time))
    dt = float(data.time[1] - data.time[0])
    gyro, acc, angles = data.gyro[a0:b0], data.acc[a0:b0], data.angles[a0:b0]
    static = static_mask(angles)
    site = Site.of_geometry(data.geometry)
    w = site.w_ie
    C_all = data.geometry.kinematics(angles)[0]
    temp = None if data.temperature is None else data.temperature[a0:b0]
    regs = Regressors(params, gyro, acc, dt, temp, static=static) if m else None
    Wx = -skew(w)
    rows = []
    Psi = np.eye(n)
    runs = 0
    min_len = max(2, int(round(min_static_s / dt)))
    for a, b, is_static in static_runs(static, min_len):
        G, A = regs.block(a, b) if m else (np.zeros((b - a, 3, 0)), np.zeros((b - a, 3, 0)))
        if is_static:
            tau = (b - a) * dt
            C = C_all[a]
            F = np.zeros((n, n))
            F[0:3, 0:3] = Wx
            F[3:6, 3:6] = 2.0 * Wx
            F[3:6, 0:3] = skew(C @ acc[a:b].mean(0) / dt)
            if m:
                F[0:3, 6:] = -C @ G.mean(0) / dt
                F[3:6, 6:] = C @ A.mean(0) / dt
            Ft = F * tau
            blk = np.zeros((3, n))
            blk[:, 3:6] = np.eye(3)  # H
            O = [blk]
            for k in range(1, krylov + 1):
                blk = blk @ Ft / k
                O.append(blk)
            rows.append(np.vstack(O) @ Psi)
            Psi = expm(Ft) @ Psi
            runs += 1
        else:
            for k in range(a, b):
                # attitude at the sample's midpoint (the increment k ends at time k)
                C = C_all[max(k - 1, 0)] @ rot(0.5 * gyro[k])
                Fk = np.zeros((6, 6))
                Fk[0:3, 0:3] = Wx
                Fk[3:6, 3:6] = 2.0 * Wx
                Fk[3:6, 0:3] = skew(C @ acc[k] / dt)
                FT = Fk * dt
                Ak = np.eye(6) + FT + 0.5 * FT @ FT
                top = Ak @ Psi[:6]
                if m:
                    Bk = np.vstack([-C @ G[k - a], C @ A[k - a]])
                    top = top + Bk @ Psi[6:]
                Psi = np.vstack([top, Psi[6:]])
    if not rows:
        raise ValueError("no static run: nothing is observed")
    ref = _ref_sigma(params, settings)
    return np.vstack(rows) * ref[None, :], ref, runs, Psi


def pwcs(data: LogData, parameters: list[str], settings: FilterSettings | None = None,
         window=None, rel_tol: float = 1e-6, krylov: int = 4,
         weak_tol: float = 1e-4) -> Observability:
    """SVD of the scaled TOM: rank, degree per state, unobservable combinations."""
    params = list(parameters)
    tom, ref, runs, Psi = total_observability(data, params, settings, window, krylov)
    states = NAV6 + params
    # equilibrate rows by block-free scaling is not needed: all rows are m/s
    _, s, vt = np.linalg.svd(tom, full_matrices=False)
    n = len(states)
    if len(s) < n:  # fewer rows than states
        s = np.concatenate([s, np.zeros(n - len(s))])
        _, _, vt = np.linalg.svd(np.vstack([tom, np.zeros((n - tom.shape[0], n))]))
    tol = rel_tol * s[0]
    rank = int(np.sum(s > tol))
    # degree of each state: the singular value of the direction where it has its largest weight
    degree = {}
    for j, st in enumerate(states):
        i = int(np.argmax(np.abs(vt[:, j]) * (1 + 1e-12 * np.arange(n))))
        degree[st] = float(s[i])
    ob = Observability(states, ref, s, vt, rank, rel_tol, runs, degree)
    ob.transition = Psi
    weak = int(np.sum(s > weak_tol * s[0]))
    ob.weak_from = weak
    ob.unobservable = [(float(s[i]), ob.combination(i)) for i in range(min(weak, rank), n)]
    return ob


def filter_covariance(data: LogData, parameters: list[str], sigma_gyro: float, sigma_acc: float,
                      settings: dict | None = None, window=None):
    """The filter's final covariance (one pass) on the data with per-sample white noise σ
    (rad, m/s): the σ the filter will report. Returns (FilterOutput, reference σ of the states)."""
    from components.navigation.kf import run_filter
    from components.navigation.system import static_mask

    params = list(parameters)
    a0, b0 = window or (0, len(data.time))
    dt = float(data.time[1] - data.time[0])
    gyro, acc, angles = data.gyro[a0:b0], data.acc[a0:b0], data.angles[a0:b0]
    static = static_mask(angles)
    site = Site.of_geometry(data.geometry)
    C0 = data.geometry.kinematics(angles[:1])[0][0]
    st = FilterSettings(parameters=params, passes=1, sigma_gyro=sigma_gyro, sigma_acc=sigma_acc,
                        **(settings or {}))
    regs = Regressors(params, gyro, acc, dt, static=static) if params else None
    out = run_filter(gyro, acc, dt, site, C0, static, st, regs)
    return out, _ref_sigma(params, st)


def analyse(data: LogData, parameters: list[str], sigma_gyro: float | None = None,
            sigma_acc: float | None = None, settings: dict | None = None, window=None,
            rel_tol: float = 1e-6) -> Observability:
    """PWCS SVD, and (with a noise model) the filter's covariance matched against it."""
    fs = FilterSettings(parameters=list(parameters), **(settings or {}))
    ob = pwcs(data, parameters, fs, window, rel_tol)
    if sigma_gyro is not None and sigma_acc is not None:
        out, ref = filter_covariance(data, parameters, sigma_gyro, sigma_acc, settings, window)
        P = out.P[np.r_[0:6, 9:9 + len(parameters)]][:, np.r_[0:6, 9:9 + len(parameters)]]
        sig = np.sqrt(np.diag(P))
        ob.filter_sigma = dict(zip(ob.states, sig))
        ob.filter_ratio = dict(zip(ob.states, sig / ref))
        # along a weak direction: its effect-state part (constants: the final covariance is
        # theirs at every time; the navigation part is not comparable, the filter's P being of
        # the errors at the end), normalised; None when the direction is mostly navigation
        Pn = P[6:, 6:] / np.outer(ref[6:], ref[6:])
        ratios = []
        for i in range(min(ob.weak_from, ob.rank), len(ob.states)):
            v = ob.vt[i, 6:]
            nv = float(np.linalg.norm(v))
            ratios.append(float(np.sqrt(v @ Pn @ v)) / nv if nv > 0.7 else None)
        ob.null_filter_ratio = ratios
    return ob


def plan_observability(log, spec: str, gyro_arw: float, acc_vrw: float,
                       effects: list[str] | None = None) -> str:
    """``calbench plan --observability SPEC``: SPEC a system-level configuration (each ``kf``
    stage analysed on its window with its states) or ``effects`` (the plan's --effects over the
    whole log). Noise: ARW [rad/√s] and VRW [m/s/√s] as white noise per sample."""
    from components.model.effects import parameters_of
    from components.navigation.configs import READY, load_config
    from components.navigation.system import window_of

    data = LogData.from_log(log)
    dt = float(log.dt)
    sg, sa = gyro_arw * math.sqrt(dt), acc_vrw * math.sqrt(dt)
    if spec in ("effects", "") or (spec not in READY and not spec.endswith(".toml")):
        jobs = [("all samples", parameters_of(effects or []), None, {})]
    else:
        cfg = load_config(spec)
        jobs = []
        for s in cfg.stages:
            if s.kind != "kf":
                continue
            a, b = window_of(data.segment, s.window, len(data.time))
            params = s.parameters or parameters_of(s.effects)
            keep = {k: v for k, v in s.settings.items() if k in ("kf_interval", "phi0", "v0",
                                                                  "prior_sigma", "prior_scale")}
            jobs.append((f"stage {s.name!r} (window {s.window or 'all'})", params, (a, b), keep))
    out = []
    for name, params, window, settings in jobs:
        ob = analyse(data, params, sg, sa, settings, window)
        out.append(f"== {name}: {len(params) + 9} filter states\n{ob.report()}")
    return "\n".join(out)
