"""Seed 002: vertical, east (attitude) and latitude from ONE accelerometer and ONE gyro on a
three-gimbal device (outer axis along base y, middle along x, inner along z: the turntable
FMU's ``<axis>.axis.{x,y,z}`` parameters, see examples/scenarios/seed002_latitude.toml).

Sensors: the seed mounts the accelerometer and the gyro with parallel sensitive axes,
perpendicular to the inner axis, along x at inner angle 0: here accelerometer x and gyro x of
the IMU (plate x; the inner axis is plate z). Only these two channels are used.

Every measurement is a *spin*: the inner axis turns whole turns at constant rate and the
sensor output is fitted against the inner angle k (least squares on 1, cos k, sin k with the
regressors averaged over each sample interval, constant-rate samples only):
``y = c + A cos k + B sin k``; the constant c takes bias (and the sensor's misalignment times
the spin rate), the amplitude R = hypot(A, B) carries the scale factor, and only the phase
``k_p = atan2(B, A)`` (the inner angle at the positive peak) and amplitude *ratios* are used:
the method is immune to bias and scale factor. Directions follow from the phase through the
geometry: s(k) = C_p^b0(θ, ψ, k) e_x is the sensor direction in base axes.

Steps (seed 002 steps 4-9; labels of the rotate segments ``spinNN-<kind>``):

1. ``spin01-level``: inner axis as it is (θ = ψ = 0). The sensor direction half way between
   the peaks, s(k_p + 90°), is horizontal: n.
2. ``spin02-horizontal``: outer/middle turned so that the inner axis lies along n; spin. The
   peak direction g1 = s(k_p) is the approximate vertical (up), G = R the amplitude.
   (The seed's accelerometer reads gravity, so its *negative* peak points up; ours reads
   specific force, f = +g up, so the *positive* peak does.)
3. ``spin03-vertical``, ``spin04-vertical``, ...: inner axis along the current vertical; spin.
   A remaining sinusoid of amplitude R1 gives the vertical error γ = R1 / G (the seed's
   ±G1/G, peak-to-peak ratios) towards s(k_p); correction (seed's formula in this frame
   and sign convention, with k_p the positive peak):  δθ = γ cos k_p / cos ψ,
   δψ = -γ sin k_p (the seed's δθ = γ sin k / cos ψ, δψ = γ cos k with k the zero crossing
   before the peak and the opposite accelerometer sign). Iterated until γ is below the
   tolerance, its noise (3σ) or one encoder count (commands are whole counts): the number of
   corrections is reported as iterations. (With the builtin table's 2^24 counts/rev the first
   vertical g1 is usually within a count already: 0 corrections.)
4. ``spinNN-north``: the same (flat) attitude, a long spin; the gyro's sinusoid peaks at the
   horizontal Earth rate (north); east = s(k_N - 90°). Its accelerometer fit refines the
   vertical once more: up = normalize(d + γ s(k_p)) with d the inner axis.
5. Attitude: C_n^b0 = [east, north, up] (columns, base axes); reported as the table's base
   tilt (table.base_tilt.x/.y, the vocabulary's names) and azimuth.
6. ``spinNN-east``: inner axis along east; long spin. The accelerometer peak is up, the gyro
   peak the Earth-rate direction, both in the meridian plane; the angle between them is the
   colatitude (the seed says "the latitude"; it is 90° minus it):
   L = atan2(cos(k_ω - k_u), sin(k_u - k_ω)).

:func:`drive` runs this adaptively on the co-simulation (one short scenario run per spin
through components.simulation.scenario, each starting where the last ended: ``<axis>.angle0``), and
returns the concatenated log; :func:`run` applies the estimators to a log holding the spins
(the labels above), so the log alone reproduces the result.
"""
from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np

from components.logs.labels import SegmentLabels
from components.model.result import CalibrationResult, schedule_of
from components.procedures.common import angle_quantum, as_data, noise_sigma, sample_interval, segments

NAME = "latitude"
SENSOR = 0  # plate x
ARCSEC = math.pi / 180 / 3600
SPIN = re.compile(r"^spin(\d+)-(level|horizontal|vertical|north|east)$")


# --------------------------------------------------------------------------- geometry helpers
def _geo0(geo):
    return replace(geo, tilt_x=0.0, tilt_y=0.0, azimuth=0.0)


def sensor_dir(geo, angles, k=None) -> np.ndarray:
    """The sensor axis (plate x) in base axes at gimbal angles (inner replaced by k if given)."""
    a = np.array(angles, float)
    if k is not None:
        a[-1] = k
    C, *_ = _geo0(geo).kinematics(a[None, :])
    return C[0][:, SENSOR]


def inner_dir(geo, angles) -> np.ndarray:
    """The inner axis in base axes."""
    C, *_ = _geo0(geo).kinematics(np.array(angles, float)[None, :])
    return C[0] @ geo.stages[-1].nominal_axis()


def point_inner(geo, d, guess=(0.0, 0.0)) -> tuple[float, float]:
    """Outer and middle angles that put the inner axis along unit vector d (base axes)."""
    from scipy.optimize import least_squares

    d = np.asarray(d, float) / np.linalg.norm(d)
    best = None
    starts = [guess] + [(a, b) for a in np.radians([0, 90, 180, 270]) for b in np.radians([-60, 0, 60])]
    for x0 in starts:
        r = least_squares(lambda x: inner_dir(geo, [x[0], x[1], 0.0]) - d, x0, xtol=1e-15, ftol=1e-15,
                          gtol=1e-15)
        if best is None or r.cost < best.cost:
            best = r
        if best.cost < 1e-26:
            break
    th, ps = best.x
    return float(np.angle(np.exp(1j * th))), float(np.angle(np.exp(1j * ps)))


def is_seed_geometry(geo) -> bool:
    ax = [tuple(np.round(s.nominal_axis(), 12)) for s in geo.stages]
    return ax == [(0, 1, 0), (1, 0, 0), (0, 0, 1)]


# --------------------------------------------------------------------------- spin fit
def fit_spin(data, seg, channel: str) -> dict:
    """Sinusoid of one sensor channel ('acc' or 'gyro', plate x) against the inner angle over
    the constant-rate part of a spin segment."""
    i0 = max(seg.start, 1)
    k1 = data.angles[i0:seg.stop, -1]
    k0 = data.angles[i0 - 1:seg.stop - 1, -1]
    dk = k1 - k0
    med = np.median(dk[dk != 0]) if np.any(dk != 0) else 0.0
    others_still = np.all(data.angles[i0:seg.stop, :-1] == data.angles[i0 - 1:seg.stop - 1, :-1], axis=1)
    use = (np.abs(dk - med) <= 0.02 * abs(med)) & others_still & (med != 0)
    if use.sum() < 20:
        raise ValueError(f"segment {seg.label}: fewer than 20 constant-rate samples of the inner axis")
    dt = sample_interval(data)
    y = (data.acc if channel == "acc" else data.gyro)[i0:seg.stop, SENSOR][use] / dt
    a, b, d = k0[use], k1[use], dk[use]
    cbar = (np.sin(b) - np.sin(a)) / d
    sbar = -(np.cos(b) - np.cos(a)) / d
    H = np.column_stack([np.ones_like(cbar), cbar, sbar])
    sol, *_ = np.linalg.lstsq(H, y, rcond=None)
    res = y - H @ sol
    n = len(y)
    std = float(np.sqrt(res @ res / max(n - 3, 1)))
    cov = std**2 * np.linalg.inv(H.T @ H)
    A, B = sol[1], sol[2]
    R = float(math.hypot(A, B))
    kp = float(math.atan2(B, A))
    # σ of amplitude (along the peak) and of the phase (across)
    u = np.array([0, math.cos(kp), math.sin(kp)])
    v = np.array([0, -math.sin(kp), math.cos(kp)])
    s_R = float(np.sqrt(u @ cov @ u))
    s_k = float(np.sqrt(v @ cov @ v)) / R if R > 0 else float("inf")
    angles = data.angles[seg.stop - 1].copy()
    return {"label": seg.label, "channel": channel, "offset": float(sol[0]), "amplitude": R,
            "peak": kp, "sigma_amplitude": s_R, "sigma_peak": s_k, "samples": int(n), "residual_std": std,
            "angles": angles}


# --------------------------------------------------------------------------- the steps
def horizontal_from_level(geo, f) -> np.ndarray:
    return sensor_dir(geo, f["angles"], f["peak"] + math.pi / 2)


def vertical_from_horizontal(geo, f) -> np.ndarray:
    return sensor_dir(geo, f["angles"], f["peak"])


def vertical_error(f, G: float) -> tuple[float, float]:
    """γ (radians, towards the peak direction) and its σ, from a spin with the axis near vertical."""
    return f["amplitude"] / G, f["sigma_amplitude"] / G


def correction(geo, f, G: float) -> tuple[float, float]:
    """(δθ, δψ): the seed's first-order correction of outer and middle angles."""
    g, _ = vertical_error(f, G)
    th, ps = f["angles"][0], f["angles"][1]
    if is_seed_geometry(geo):
        return g * math.cos(f["peak"]) / math.cos(ps), -g * math.sin(f["peak"])
    d = inner_dir(geo, f["angles"]) + g * sensor_dir(geo, f["angles"], f["peak"])
    t2, p2 = point_inner(geo, d, (th, ps))
    return t2 - th, p2 - ps


def refined_up(geo, f, G: float) -> np.ndarray:
    g, _ = vertical_error(f, G)
    d = inner_dir(geo, f["angles"]) + g * sensor_dir(geo, f["angles"], f["peak"])
    return d / np.linalg.norm(d)


def east_from_north_spin(geo, fg, up) -> np.ndarray:
    e = sensor_dir(geo, fg["angles"], fg["peak"] - math.pi / 2)
    e = e - (e @ up) * up
    return e / np.linalg.norm(e)


def latitude_from_east_spin(fa, fg) -> tuple[float, float]:
    ku, kw = fa["peak"], fg["peak"]
    L = math.atan2(math.cos(kw - ku), math.sin(ku - kw))
    return L, math.hypot(fa["sigma_peak"], fg["sigma_peak"])


def attitude_angles(up, east) -> dict:
    """Base tilt x/y and azimuth of C_b0^n = R_x(t_x) R_y(t_y) R_z(az) from up and east in base
    axes (azimuth from east, tilts from up)."""
    from components.model.geometry import rodrigues

    north = np.cross(up, east)
    east = np.cross(north, up)
    # row 0 of C_b0^n = east^T = [cos ty cos az, -cos ty sin az, sin ty]
    az = math.atan2(-east[1], east[0])
    w = rodrigues([0, 0, 1], az) @ up   # = R_y(-ty) R_x(-tx) e_z
    tx = math.asin(np.clip(w[1], -1, 1))
    ty = math.atan2(-w[0], w[2])
    return {"table.base_tilt.x": tx, "table.base_tilt.y": ty, "azimuth": az}


# --------------------------------------------------------------------------- estimation on a log
def spin_segments(data) -> list:
    out = []
    for seg in segments(data):
        m = SPIN.match(seg.label)
        if m:
            out.append((int(m.group(1)), m.group(2), seg))
    return sorted(out, key=lambda x: x[0])


def estimate(data, tol_arcsec: float = 1.0) -> dict:
    """All steps' estimates from the spins in a log (labels spinNN-<kind>)."""
    geo = data.geometry
    spins = spin_segments(data)
    kinds = [k for _, k, _ in spins]
    for need in ("horizontal", "vertical", "north", "east"):
        if need not in kinds:
            raise ValueError(f"the log has no spin segment of kind {need!r} (labels spinNN-{need}; "
                             f"found: {[s.label for _, _, s in spins]})")
    out: dict = {"spins": []}
    G = None
    vertical_fits = []
    for num, kind, seg in spins:
        fa = fit_spin(data, seg, "acc")
        rec = {"label": seg.label, "kind": kind, "angles_deg": [float(np.degrees(x)) for x in fa["angles"]],
               "acc_amplitude": fa["amplitude"], "acc_peak_deg": math.degrees(fa["peak"])}
        if kind == "level":
            rec["horizontal"] = horizontal_from_level(geo, fa).tolist()
        elif kind == "horizontal":
            G = fa["amplitude"]
            rec["vertical_g1"] = vertical_from_horizontal(geo, fa).tolist()
        elif kind in ("vertical", "north"):
            if G is None:
                raise ValueError(f"{seg.label}: a vertical spin before the horizontal one")
            g, sg = vertical_error(fa, G)
            rec["gamma_arcsec"], rec["sigma_gamma_arcsec"] = g / ARCSEC, sg / ARCSEC
            dth, dps = correction(geo, fa, G)
            rec["correction_deg"] = [math.degrees(dth), math.degrees(dps)]
            if kind == "vertical":
                vertical_fits.append(fa)
            else:
                out["up"] = refined_up(geo, fa, G)
                out["sigma_up"] = sg
                fg = fit_spin(data, seg, "gyro")
                out["east"] = east_from_north_spin(geo, fg, out["up"])
                out["sigma_east"] = fg["sigma_peak"]
                rec.update(gyro_amplitude_dph=fg["amplitude"] / (math.pi / 180 / 3600),
                           gyro_peak_deg=math.degrees(fg["peak"]))
        elif kind == "east":
            fg = fit_spin(data, seg, "gyro")
            L, sL = latitude_from_east_spin(fa, fg)
            out["latitude"], out["sigma_latitude"] = L, sL
            rec.update(gyro_amplitude_dph=fg["amplitude"] / (math.pi / 180 / 3600),
                       gyro_peak_deg=math.degrees(fg["peak"]))
        out["spins"].append(rec)
    out["iterations"] = max(len(vertical_fits) - 1, 0)
    out["G"] = G
    return out


def run(log_or_data, *, tol_arcsec: float = 1.0) -> CalibrationResult:
    """The seed-002 estimators on a log that holds the spins (labels ``spinNN-level``,
    ``-horizontal``, ``-vertical`` (one or more), ``-north``, ``-east``). The result: the base
    attitude as table.base_tilt.x/.y (σ from the vertical's noise), with up, east, azimuth,
    latitude and the per-spin record under ``latitude_procedure``."""
    data, log = as_data(log_or_data)
    est = estimate(data, tol_arcsec)
    att = attitude_angles(est["up"], est["east"])
    values = {"table.base_tilt.x": att["table.base_tilt.x"], "table.base_tilt.y": att["table.base_tilt.y"]}
    sigmas = {k: est["sigma_up"] for k in values}
    sg, sa = noise_sigma(data)
    return CalibrationResult(
        effects=["table.base_tilt"], values=values, sigmas=sigmas, correlation=np.eye(2),
        noise={"model": "white noise per sample (from static data)", "gyro_sigma_rad": [float(x) for x in sg],
               "acc_sigma_mps": [float(x) for x in sa], "sample_interval_s": sample_interval(data)},
        fit={"estimator": "sinusoid phase fits per spin (seed 002)", "iterations": est["iterations"]},
        schedule=schedule_of(data.time, data.segment),
        data={"samples": int(len(data.time)), **({"log": str(log.source)} if log is not None and log.source else {})},
        method="procedure:latitude (seed 002: one accelerometer + one gyro, three-gimbal device)",
        extra={"latitude_procedure": {
            "latitude_rad": est["latitude"], "sigma_latitude_rad": est["sigma_latitude"],
            "up_base": [float(x) for x in est["up"]], "east_base": [float(x) for x in est["east"]],
            "azimuth_rad": att["azimuth"], "sigma_azimuth_rad": est["sigma_east"],
            "sigma_vertical_rad": est["sigma_up"], "iterations": est["iterations"],
            "amplitude_G_mps2": est["G"], "spins": est["spins"]}})


# --------------------------------------------------------------------------- driving the co-simulation
def _spin_schedule(num: int, kind: str, angles, rate_dps: float, turns: int, hold: float):
    from components.control.schedule import schedule_from_dict

    lab = f"spin{num:02d}-{kind}"
    d = {"schedule": {"name": lab},
         "steps": [{"kind": "index", "angles_deg": [math.degrees(a) for a in angles], "label": lab + "-set"},
                   {"kind": "dwell", "duration": hold, "label": lab + "-hold"},
                   {"kind": "rotate", "axis": "inner", "rate_dps": rate_dps, "turns": turns, "label": lab}]}
    return schedule_from_dict(d, lab)


def _concat(logs):
    from dataclasses import replace as drep

    t_off, times = 0.0, []
    for lg in logs:
        times.append(lg.time + t_off)
        t_off = times[-1][-1]
    first = logs[0]
    cat = lambda f: np.concatenate([getattr(lg, f) for lg in logs])  # noqa: E731
    return drep(first, time=np.concatenate(times),
                gimbal={a: np.concatenate([lg.gimbal[a] for lg in logs]) for a in first.axis_names},
                gyro=cat("gyro"), acc=cat("acc"),
                command={k: np.concatenate([lg.command[k] for lg in logs]) for k in first.command},
                temperature=None if first.temperature is None else cat("temperature"),
                segment=SegmentLabels.concatenate([lg.segment for lg in logs]),
                extra={k: np.concatenate([lg.extra[k] for lg in logs]) for k in first.extra},
                description="seed 002 latitude/attitude procedure: adaptive spins", source=None)


def truth_of(sc) -> dict:
    """Truth of a scenario: base tilt, azimuth, latitude, up and east in base axes."""
    from components.model.geometry import Stage, TableGeometry

    tx = sc.table_effects.get("table.base_tilt.x", sc.table_parameters.get("base.tilt.x", 0.0))
    ty = sc.table_effects.get("table.base_tilt.y", sc.table_parameters.get("base.tilt.y", 0.0))
    az = sc.table_parameters.get("base.azimuth", 0.0)
    g = TableGeometry((Stage("outer", (0, 0, 1)),), math.radians(sc.site["latitude_deg"]),
                      tilt_x=tx, tilt_y=ty, azimuth=az)
    Cn_b0 = g.base_to_nav().T
    return {"table.base_tilt.x": tx, "table.base_tilt.y": ty, "azimuth": az,
            "latitude": math.radians(sc.site["latitude_deg"]),
            "up": Cn_b0 @ np.array([0, 0, 1.0]), "east": Cn_b0 @ np.array([1.0, 0, 0])}


def drive(scenario, *, rate_dps: float = 10.0, acc_turns: int = 1, north_turns: int = 17,
          east_turns: int = 100, hold: float = 2.0, tol_arcsec: float = 1.0, max_iterations: int = 8,
          progress=None, verbose: bool = False):
    """Run seed 002 adaptively on the co-simulation described by *scenario* (a Scenario or a
    path: its site, turntable (seed-002 axes), IMU and step; its schedule is replaced spin by
    spin). Returns (MeasurementLog of all spins, list of per-run truths, the decisions)."""
    from components.estimation.log_data import LogData
    from components.simulation.run import run_scenario
    from components.simulation.scenario import Scenario, load_scenario

    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    logs, truths, decisions = [], [], []
    cur = [0.0, 0.0, 0.0]  # true angles where the table is (angle0 of the next run)
    num = 0

    def spin(kind, outer_middle, turns):
        nonlocal num, cur
        num += 1
        target = [outer_middle[0], outer_middle[1], 0.0]
        params = dict(sc.table_parameters)
        for a, v in zip(sc.table_axes, cur):
            params[f"{a}.angle0"] = float(v)
        run_sc = replace(sc, schedule=_spin_schedule(num, kind, target, rate_dps, turns, hold),
                         table_parameters=params, seed=sc.seed + num - 1)
        r = run_scenario(run_sc, progress=progress)
        logs.append(r.log)
        truths.append(r.truth)
        cur = [float(x) for x in r.log.angles[-1]]
        data = LogData.from_log(r.log)
        seg = [s for s in segments(data) if s.label == f"spin{num:02d}-{kind}"][0]
        return data, fit_spin(data, seg, "acc"), seg

    data, f1, _ = spin("level", (0.0, 0.0), acc_turns)
    geo = data.geometry
    n_h = horizontal_from_level(geo, f1)
    th, ps = point_inner(geo, n_h)
    decisions.append({"step": "horizontal", "direction": n_h.tolist(), "outer_middle_deg": [math.degrees(th), math.degrees(ps)]})
    data, f2, _ = spin("horizontal", (th, ps), acc_turns)
    G = f2["amplitude"]
    g1 = vertical_from_horizontal(geo, f2)
    th, ps = point_inner(geo, g1, (th, ps))
    decisions.append({"step": "vertical g1", "direction": g1.tolist(), "outer_middle_deg": [math.degrees(th), math.degrees(ps)]})
    for it in range(max_iterations + 1):
        data, f3, _ = spin("vertical", (th, ps), acc_turns)
        g, sg = vertical_error(f3, G)
        # flat: below the tolerance, the noise (3σ) or one encoder count (the commanded
        # angles are whole counts: a smaller correction cannot be made)
        flat = g < max(tol_arcsec * ARCSEC, 3 * sg, angle_quantum(data))
        decisions.append({"step": f"vertical spin {it + 1}", "gamma_arcsec": g / ARCSEC,
                          "sigma_gamma_arcsec": sg / ARCSEC, "flat": bool(flat)})
        if verbose:
            print(f"  vertical spin {it + 1}: gamma = {g / ARCSEC:.3f} arcsec (sigma {sg / ARCSEC:.3f})"
                  + (" flat" if flat else ""))
        if flat or it == max_iterations:
            break
        dth, dps = correction(geo, f3, G)
        th, ps = th + dth, ps + dps
    # the north spin at the flat attitude (its accelerometer fit refines the vertical)
    data, f4, seg4 = spin("north", (th, ps), north_turns)
    up = refined_up(geo, f4, G)
    east = east_from_north_spin(geo, fit_spin(data, seg4, "gyro"), up)
    te, pe = point_inner(geo, east, (th, ps))
    decisions.append({"step": "east", "direction": east.tolist(), "outer_middle_deg": [math.degrees(te), math.degrees(pe)]})
    spin("east", (te, pe), east_turns)
    return _concat(logs), truths, decisions


def errors(result: CalibrationResult, truth: dict) -> dict:
    lp = result.extra["latitude_procedure"]
    up = np.array(lp["up_base"])
    east = np.array(lp["east_base"])
    ang = lambda a, b: math.atan2(np.linalg.norm(np.cross(a, b)), a @ b)  # noqa: E731
    return {"vertical_arcsec": ang(up, truth["up"]) / ARCSEC,
            "east_arcmin": ang(east, truth["east"]) / ARCSEC / 60,
            "latitude_arcmin": (lp["latitude_rad"] - truth["latitude"]) / ARCSEC / 60,
            "tilt_x_arcsec": (result.values["table.base_tilt.x"] - truth["table.base_tilt.x"]) / ARCSEC,
            "tilt_y_arcsec": (result.values["table.base_tilt.y"] - truth["table.base_tilt.y"]) / ARCSEC,
            "iterations": lp["iterations"]}
