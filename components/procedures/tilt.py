"""Seed 000: calibration on a non-level base.

Stage 1, base tilt from four outer-frame positions. With the plate level (middle and inner at
0) and the outer axis at 0°, 90°, 180°, 270° (static segments found from the logged angles;
the seed_000 schedule labels them ``az000``, ``az090``, ``az180``, ``az270``), the base tilt
puts a horizontal specific force ``g [-sin t_y cos t_x, sin t_x]`` (base axes) into the
accelerometers, which the outer angle θ rotates into plate axes. With f̄(θ) the mean specific
force of accelerometers x, y at θ, differences of opposite positions cancel bias and
misalignment (and the scale factor enters only as (1+s) times the tilt):

    sin t_x = [(f̄_y(0) - f̄_y(180)) + (f̄_x(90) - f̄_x(270))] / 4g
    sin t_y = -[(f̄_x(0) - f̄_x(180)) - (f̄_y(90) - f̄_y(270))] / (4 g cos t_x)

(the seed's extra small middle-frame rotation at 0°, ``az000-sign``, fixes the sign on a
platform without encoders; with the encoder angles logged it is not needed and not used).

Stage 2, frame-angle compensation and multi-position estimation. The seed turns the frames so
that the triad is locally level; here the equivalent: the geometry carries the estimated tilt,
so every attitude of the multi-position set is computed with the base as it is, and the
accelerometer scale factor, bias, K2 and misalignment follow from the static time means by
least squares (components.estimation.lsq.calibrate with the tilt fixed). ``tilt_ignored`` runs the same
second stage on the nominal, level geometry, for comparison.
"""
from __future__ import annotations

import numpy as np

from components.estimation.lsq import calibrate
from components.model.result import CalibrationResult, result_from_fit
from components.procedures.common import as_data, is_static, sample_interval, segments

NAME = "tilt"
DEFAULT_EFFECTS = ("acc.bias", "acc.sf", "acc.mis", "acc.k2")
TWO_PI = 2 * np.pi


def four_positions(data, tol_deg: float = 0.01) -> dict[int, list]:
    """Static segments with every gimbal but the outer at 0 and the outer at 0/90/180/270°:
    {0: [segments], 90: [...], ...}."""
    out: dict[int, list] = {0: [], 90: [], 180: [], 270: []}
    tol = np.radians(tol_deg)
    for seg in segments(data):
        if seg.label.startswith("move-") or seg.n < 2 or not is_static(data, seg):
            continue
        a = data.angles[seg.stop - 1]
        others = np.angle(np.exp(1j * a[1:]))
        if np.any(np.abs(others) > tol):
            continue
        deg = np.degrees(np.mod(a[0], TWO_PI))
        for target in out:
            if abs((deg - target + 180) % 360 - 180) < tol_deg:
                out[target].append(seg)
    return out


def estimate_tilt(data) -> dict:
    """Base tilt (x, y) [rad] from the four outer-frame positions, with σ from the noise."""
    geo = data.geometry
    outer = geo.stages[0].nominal_axis()
    if abs(abs(outer[2]) - 1) > 1e-9:
        raise ValueError(f"the tilt procedure needs a vertical outer axis; this table's is {outer}")
    pos = four_positions(data)
    missing = [k for k, v in pos.items() if not v]
    if missing:
        raise ValueError(f"no static segment with the plate level at outer angle(s) {missing} deg "
                         "(seed_000 schedule: az000, az090, az180, az270)")
    dt = sample_interval(data)
    from components.procedures.common import noise_sigma

    _, sig_a = noise_sigma(data)
    f, var = {}, {}
    for k, segs in pos.items():
        n = sum(s.n for s in segs)
        f[k] = sum(data.acc[s.slice].sum(0) for s in segs) / (n * dt)
        var[k] = np.nan_to_num(sig_a) ** 2 / (n * dt**2)
    g = geo.g
    sgn = np.sign(outer[2])  # an outer axis pointing down turns the plate the other way
    sx = ((f[0][1] - f[180][1]) + sgn * (f[90][0] - f[270][0])) / (4 * g)
    tx = float(np.arcsin(sx))
    sy = -((f[0][0] - f[180][0]) - sgn * (f[90][1] - f[270][1])) / (4 * g * np.cos(tx))
    ty = float(np.arcsin(sy))
    # σ: each is a sum of four means with weights ±1/4g
    s_tx = float(np.sqrt(var[0][1] + var[180][1] + var[90][0] + var[270][0]) / (4 * g))
    s_ty = float(np.sqrt(var[0][0] + var[180][0] + var[90][1] + var[270][1]) / (4 * g))
    return {"table.base_tilt.x": tx, "table.base_tilt.y": ty,
            "sigma": {"table.base_tilt.x": s_tx, "table.base_tilt.y": s_ty},
            "segments": {k: [s.label for s in v] for k, v in pos.items()}}


def _second_stage(data, log, effects, fixed, method):
    fit = calibrate(data, list(effects), fixed=fixed)
    res = result_from_fit(fit, list(effects), data, log)
    res.method = method
    return res


def run(log_or_data, *, effects=DEFAULT_EFFECTS) -> CalibrationResult:
    """Seed 000: base tilt from the four outer positions, then the multi-position accelerometer
    calibration with the geometry carrying that tilt. The result holds the tilt
    (table.base_tilt.x/.y, σ from stage 1) and the accelerometer parameters."""
    data, log = as_data(log_or_data)
    t = estimate_tilt(data)
    fixed = {k: t[k] for k in ("table.base_tilt.x", "table.base_tilt.y")}
    res = _second_stage(data, log, effects, fixed,
                        "procedure:tilt (seed 000: tilt from outer 0/90/180/270, then multi-position "
                        "least squares on the tilt-compensated geometry)")
    # the tilt's own uncertainty carried into the stage-2 parameters: J = ∂θ/∂tilt by central
    # differences of the (linear) stage 2 at ± one σ of each tilt, cov += J Σ_tilt Jᵀ (without it
    # the stage-2 σ were too small: error RMS 1.17 σ over 6 seeds, acc.bias.z 1.71)
    names = list(res.values)
    tilt_names = ["table.base_tilt.x", "table.base_tilt.y"]
    s_tilt = np.array([t["sigma"][k] for k in tilt_names])
    J = np.zeros((len(names), 2))
    for j, k in enumerate(tilt_names):
        if not s_tilt[j] > 0:
            continue
        side = [_second_stage(data, log, effects, {**fixed, k: fixed[k] + sgn * s_tilt[j]}, res.method).values
                for sgn in (1.0, -1.0)]
        J[:, j] = [(side[0][p] - side[1][p]) / (2 * s_tilt[j]) for p in names]
    s2 = np.array([res.sigmas[p] for p in names])
    corr2 = res.correlation if res.correlation is not None else np.eye(len(names))
    cov2 = corr2 * np.outer(s2, s2) + J @ np.diag(s_tilt**2) @ J.T
    cov = np.zeros((len(names) + 2, len(names) + 2))
    cov[:2, :2] = np.diag(s_tilt**2)
    cov[2:, 2:] = cov2
    cov[2:, :2] = J @ np.diag(s_tilt**2)
    cov[:2, 2:] = cov[2:, :2].T
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sig, sig)
    res.values = {**fixed, **res.values}
    res.sigmas = dict(zip(tilt_names + names, map(float, sig)))
    res.correlation = corr
    res.effects = ["table.base_tilt"] + list(res.effects)
    res.extra["tilt_stage"] = {"segments": {str(k): v for k, v in t["segments"].items()},
                               "note": "tilt sigma from stage 1; the stage-2 sigmas include the tilt's uncertainty "
                                       "(carried by the stage's derivatives; the two stages' shared rests are taken "
                                       "as independent)"}
    return res


def run_ignored(log_or_data, *, effects=DEFAULT_EFFECTS):
    """The same multi-position estimation on the nominal (level) geometry."""
    data, log = as_data(log_or_data)
    return _second_stage(data, log, effects, {"table.base_tilt.x": 0.0, "table.base_tilt.y": 0.0},
                         "procedure:tilt_ignored (multi-position least squares on the level "
                         "nominal geometry)")
