"""General least-squares calibration on any log: predict the IMU output from the measured gimbal
angles through the table geometry and a chosen effect set, fit all their parameters jointly.

Model per observation block (components.blocks): measured sum − ideal sum = H θ + v, with the
columns of H the effects' regressors (components.effects) summed over the block, and for table
effects the derivative of the ideal prediction with respect to the geometry parameter (central
differences; Gauss–Newton iterations re-linearise). Weighted least squares with the per-sample
white-noise σ estimated from the log's static data (block variance n σ², plus the encoder's
count variance at the ends of a moving gyro block). With white noise this is the efficient
estimator and its covariance (Hᵀ R⁻¹ H)⁻¹ the Cramér–Rao bound (domain.md §7).
"""
from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field, replace

import numpy as np

from components.blocks import Blocks, observation_blocks, white_noise_sigma
from components.effects import effect_of, parameters_of, regressor_of, time_offset_of_lever
from components.geometry import TableGeometry
from components.motion import Motion, interpolate_angles, motion_from_profile

TABLE_STEP = 1e-6  # rad, forward-difference step of the geometry parameters
RCOND = 1e-7  # relative singular value below which a design direction is not resolved
TIME_OFFSET_STEP_TOL = 1e-9  # s: the time offset × lever-arm linearisation has converged
# Geometry columns depend only on the angle profile, the blocks and the geometry: logs that
# share the motion (Monte-Carlo seeds, effects hidden in the IMU only) reuse them.
_GEOMETRY_COLUMNS: "OrderedDict[tuple, tuple]" = OrderedDict()


@dataclass
class LogData:
    """What the estimators need from a measurement log, in SI (increments per interval)."""

    time: np.ndarray
    angles: np.ndarray  # (N, n_axes) measured
    gyro: np.ndarray    # (N, 3) increments [rad]
    acc: np.ndarray     # (N, 3) increments [m/s]
    geometry: TableGeometry
    temperature: np.ndarray | None = None
    segment: np.ndarray | None = None
    dt0: float | None = None
    source: dict = field(default_factory=dict)
    _profiles: dict = field(default_factory=dict, repr=False, compare=False)

    def angle_profile(self, quadrature: int = 3):
        """The interpolated gimbal angles (cached: they do not depend on the geometry)."""
        if quadrature not in self._profiles:
            self._profiles[quadrature] = interpolate_angles(self.time, self.angles, quadrature, self.dt0)
        return self._profiles[quadrature]

    def motion(self, geometry: TableGeometry, t0_temperature: float | None = None,
               quadrature: int = 3) -> Motion:
        return motion_from_profile(self.angle_profile(quadrature), geometry, self.temperature,
                                   t0_temperature)

    def window(self, a: int, b: int) -> "LogData":
        """Samples a..b-1 (a stage of a schedule), the same site, table and sample interval."""
        cut = lambda x: None if x is None else x[a:b]  # noqa: E731
        return replace(self, time=self.time[a:b], angles=self.angles[a:b], gyro=self.gyro[a:b],
                       acc=self.acc[a:b], temperature=cut(self.temperature),
                       segment=cut(self.segment), _profiles={})

    @classmethod
    def from_log(cls, log) -> "LogData":
        """From a components.logfile.MeasurementLog."""
        from components.geometry import Stage, TableGeometry

        geo = TableGeometry(tuple(Stage(n, tuple(float(x) for x in v))
                                  for n, v in zip(log.axis_names, log.axis_vectors)),
                            latitude=log.latitude, height=log.height_m, gravity=log.gravity)
        return cls(time=log.time, angles=log.angles, gyro=log.gyro_increment(),
                   acc=log.acc_increment(), geometry=geo, temperature=log.temperature,
                   segment=log.segment, dt0=log.dt, source={"log": log.source})


def apply_table_parameter(geo: TableGeometry, name: str, value: float) -> TableGeometry:
    """Geometry with one table-effect parameter set (names of components.effects)."""
    parts = name.split(".")
    if name.startswith("table.base_tilt."):
        return replace(geo, **{f"tilt_{parts[2]}": value})
    axis, comp = parts[2], parts[3]
    if axis not in geo.names:
        return geo  # a stage this table does not have: the parameter has no effect
    field_name = {"table.nonorth": f"nonorth_{comp}", "table.wobble": f"wobble_{comp}",
                  "table.encoder": f"enc_{comp}"}[".".join(parts[:2])]
    return geo.with_stage(axis, **{field_name: value})


def table_parameter_value(geo: TableGeometry, name: str) -> float:
    parts = name.split(".")
    if name.startswith("table.base_tilt."):
        return getattr(geo, f"tilt_{parts[2]}")
    axis, comp = parts[2], parts[3]
    if axis not in geo.names:
        return 0.0
    stage = next(s for s in geo.stages if s.name == axis)
    attr = {"table.nonorth": f"nonorth_{comp}", "table.wobble": f"wobble_{comp}",
            "table.encoder": f"enc_{comp}"}[".".join(parts[:2])]
    return getattr(stage, attr)


@dataclass
class Fit:
    parameters: list[str]
    value: np.ndarray
    covariance: np.ndarray
    chi2: float
    dof: int
    sigma_gyro: np.ndarray  # per-sample white-noise σ used [rad]
    sigma_acc: np.ndarray   # [m/s]
    geometry: TableGeometry
    motion: Motion
    iterations: int
    rows: dict = field(default_factory=dict)  # design of the last iteration, for diagnostics
    rest_sigma: np.ndarray | None = None  # σ of the rest angles used (estimated or given) [rad]

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))

    def correlation(self) -> np.ndarray:
        s = self.sigma
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.covariance / np.outer(s, s)

    def values(self) -> dict[str, float]:
        return dict(zip(self.parameters, self.value))


def sensor_columns(motion: Motion, params: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample regressors: gyro (N, 3, P) and acc (N, 3, P) increments per unit parameter."""
    n = len(motion.dt)
    G = np.zeros((n, 3, len(params)))
    A = np.zeros((n, 3, len(params)))
    for k, p in enumerate(params):
        g, a = regressor_of(motion, p)
        if g is not None:
            G[:, :, k] = g
        if a is not None:
            A[:, :, k] = a
    return G, A


def predict(motion: Motion, params: list[str], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Model output increments (N, 3) gyro and acc for sensor-effect values on this motion."""
    G, A = sensor_columns(motion, params)
    return motion.ideal_gyro + G @ values, motion.ideal_acc + A @ values


def _noise_floor(sig: np.ndarray, scale: float) -> np.ndarray:
    # a noise-free log (a conformance vector) still needs finite weights
    return np.where(np.isfinite(sig) & (sig > 0), sig, 0.0) + 1e-13 * scale


def calibrate(data: LogData, effects: list[str], *, chunk_s: float = 1.0, quadrature: int = 3,
              iterations: int = 3, sigma_gyro=None, sigma_acc=None,
              temperature_ref: float | None = None, fixed: dict | None = None,
              rest_angle_sigma=None) -> Fit:
    """Fit the parameters of *effects* jointly to *data*.

    ``fixed``: parameter values held (not fitted), e.g. a geometry known from elsewhere.
    ``rest_angle_sigma`` [rad, per axis]: uncertainty of the true angle at rest around the
    encoder reading, which bounds a rest-to-rest gyro block; default: one count uniform
    (q/√12, q = the smallest logged angle step), 0 for logs whose rest angles are exact."""
    params = parameters_of(effects)
    if not params:
        raise ValueError("no effect to fit")
    table_params = [p for p in params if effect_of(p).target == "table"]
    geo = data.geometry
    for name, v in (fixed or {}).items():
        if effect_of(name).target == "table":
            geo = apply_table_parameter(geo, name, v)
    dt_mean = float(np.median(np.diff(data.time))) if len(data.time) > 1 else 1.0
    n_chunk = max(1, int(round(chunk_s / dt_mean)))

    def motion_for(g: TableGeometry) -> Motion:
        return data.motion(g, temperature_ref, quadrature)

    motion = motion_for(geo)
    gb, ab = observation_blocks(motion.static, data.angles, n_chunk)
    sg = _noise_floor(np.asarray(sigma_gyro if sigma_gyro is not None
                                 else white_noise_sigma(data.gyro, motion.static), float),
                      7.3e-5 * dt_mean)
    sa = _noise_floor(np.asarray(sigma_acc if sigma_acc is not None
                                 else white_noise_sigma(data.acc, motion.static), float),
                      9.8 * dt_mean)
    q = rest_sigma(data.angles, rest_angle_sigma)
    if rest_angle_sigma is None and np.any(q):
        q = _estimate_rest_sigma(data, motion, params, gb, ab, sg, sa, q, geo, table_params, motion_for)
    value = np.array([(fixed or {}).get(p, 0.0) if effect_of(p).target == "table"
                      else 0.0 for p in params])
    for p in table_params:
        value[params.index(p)] = table_parameter_value(geo, p)
    # the model's one product of two fitted parameters: the time offset shifts the lever-arm
    # terms too (effects.time_offset_of_lever); linearised at the last solution (Gauss–Newton)
    bilinear = "imu.time_offset" in params and any(effect_of(p).name == "acc.lever" for p in params)
    lin = None
    it = 0
    for it in range(1, iterations + 1):
        y, H, w, rows = _design(data, motion, params, gb, ab, sg, sa, q, geo, table_params, motion_for, lin)
        # residual relative to the current table values (Gauss–Newton on the geometry)
        Hw = H * w[:, None]
        scale = np.linalg.norm(Hw, axis=0)
        scale[scale == 0] = 1.0
        # rcond: a direction of the column-normalised design below 1e-7 of the largest is a
        # parameter combination the data cannot see (e.g. a wobble of an inner stage, which is a
        # constant rotation of the plate = IMU misalignment, left only with the forward-
        # difference error of its column); resolving it would amplify noise into a huge step
        # of the geometry and wreck the next linearisation
        sol, *_ = np.linalg.lstsq(Hw / scale, y * w, rcond=RCOND)
        step = sol / scale
        sensor_idx = [k for k, p in enumerate(params) if p not in table_params]
        value[sensor_idx] = step[sensor_idx]
        moved = False
        if bilinear:
            tau = value[params.index("imu.time_offset")]
            moved = lin is None or abs(tau - lin[params.index("imu.time_offset")]) > TIME_OFFSET_STEP_TOL
            lin = value.copy()
        if table_params:
            delta = np.array([step[params.index(p)] for p in table_params])
            for p, d in zip(table_params, delta):
                value[params.index(p)] += d
                geo = apply_table_parameter(geo, p, value[params.index(p)])
            motion = motion_for(geo)
            moved = moved or np.max(np.abs(delta)) >= 1e-12
        if not moved:
            break
    # final linearisation at the solution: sensor values and the last (tiny) table correction
    y, H, w, rows = _design(data, motion, params, gb, ab, sg, sa, q, geo, table_params, motion_for, lin)
    Hw = H * w[:, None]
    scale = np.linalg.norm(Hw, axis=0)
    scale[scale == 0] = 1.0
    sol = np.linalg.lstsq(Hw / scale, y * w, rcond=RCOND)[0] / scale
    for k, p in enumerate(params):
        value[k] = value[k] + sol[k] if p in table_params else sol[k]
    resid_vec = y - H @ sol
    chi2 = float(np.sum((resid_vec * w) ** 2))
    info = (Hw / scale).T @ (Hw / scale)
    cov = np.linalg.pinv(info, rcond=1e-12) / np.outer(scale, scale)
    rows["residual"] = resid_vec
    fit = Fit(params, value, cov, chi2, max(len(y) - len(params), 1), sg, sa, geo, motion, it, rows)
    fit.rest_sigma = q
    return fit


def _estimate_rest_sigma(data, motion, params, gb, ab, sg, sa, q, geo, table_params, motion_for):
    """How far the table really rests from its encoder readings, from the data: the moving gyro
    blocks' residual variance beyond their white noise, against the geometric factor of the
    rest angles (a method-of-moments variance component). Starts from one count uniform (the
    prior q/√12) and stays within [0, 2 q/√12]; the estimator's σ then matches its spread."""
    y, H, w, rows = _design(data, motion, params, gb, ab, sg, sa, q, geo, table_params, motion_for)
    Hw = H * w[:, None]
    scale = np.linalg.norm(Hw, axis=0)
    scale[scale == 0] = 1.0
    sol = np.linalg.lstsq(Hw / scale, y * w, rcond=None)[0] / scale
    r = y - H @ sol
    n_g = 3 * len(gb)
    mv = np.repeat(gb.moving, 3)
    unit = rest_variance(data, geo, gb, np.ones_like(q)).reshape(-1)[mv]
    white = (gb.count[:, None] * sg[None, :] ** 2).reshape(-1)[mv]
    if unit.sum() <= 0:
        return q
    # residuals shrink by the fitted parameters' share (leverage ~ p / rows on average)
    shrink = max(1.0 - len(params) / max(len(y), 1), 0.5)
    s2 = float(np.sum(r[:n_g][mv] ** 2 / shrink - white) / np.sum(unit))
    s = np.sqrt(min(max(s2, 0.0), (2 * q.max()) ** 2))
    return np.full_like(q, s)


def rest_directions(angles: np.ndarray, geo: TableGeometry, at: np.ndarray) -> np.ndarray:
    """Plate-frame rotation direction of each stage (B, n_axes, 3) at the logged angles of the
    samples *at*: how a small error of that stage's rest angle shows in the gyro triad."""
    th = np.atleast_2d(angles[at])
    _, w0, _, _ = geo.kinematics(th)
    out = np.empty((len(th), th.shape[1], 3))
    for k in range(th.shape[1]):
        e = np.zeros_like(th)
        e[:, k] = 1.0
        out[:, k, :] = geo.kinematics(th, e)[1] - w0
    return out


def rest_variance(data, geo: TableGeometry, gb: Blocks, rest: np.ndarray) -> np.ndarray:
    """(B, 3) variance a moving gyro block gets from the rest angles at its two ends: a rest
    angle error δ_k of stage k shifts the integral of the gyro by b_k δ_k (b_k its rotation
    direction in plate axes), independently at the start and at the end of the move."""
    var = np.zeros((len(gb), 3))
    mv = np.nonzero(gb.moving)[0]
    if len(mv) == 0 or not np.any(rest):
        return var
    b = rest_directions(data.angles, geo, np.maximum(gb.stop[mv] - 1, 0))
    var[mv] = 2 * np.einsum("bki,k->bi", b**2, np.asarray(rest, float) ** 2)
    return var


def rest_sigma(angles: np.ndarray, given=None) -> np.ndarray:
    """Per-axis σ of the true angle at rest: *given*, or a uniform count q/√12."""
    if given is not None:
        return np.broadcast_to(np.asarray(given, float), (angles.shape[1],)).copy()
    return _encoder_quantum(angles) / np.sqrt(12.0)


def _encoder_quantum(angles: np.ndarray) -> np.ndarray:
    """Per axis, the smallest step between distinct logged angles (the count), or 0."""
    out = []
    for k in range(angles.shape[1]):
        u = np.unique(angles[:, k])
        d = np.diff(u)
        d = d[d > 0]
        out.append(float(d.min()) if len(d) else 0.0)
    return np.array(out)


def _design(data, motion, params, gb: Blocks, ab: Blocks, sg, sa, rest, geo, table_params, motion_for,
            lin=None):
    """Stacked rows (gyro blocks x 3 axes, then acc blocks x 3 axes): y, H, weights, row info.
    ``lin``: the values (per parameter) the time offset × lever-arm product is linearised at."""
    yg = gb.sum(data.gyro - motion.ideal_gyro)
    ya = ab.sum(data.acc - motion.ideal_acc)
    # block sums column by column: never hold (N, 3, P) regressors for long logs
    Hg = np.zeros((len(gb), 3, len(params)))
    Ha = np.zeros((len(ab), 3, len(params)))
    for k, p in enumerate(params):
        g, a = regressor_of(motion, p)
        if g is not None:
            Hg[:, :, k] = gb.sum(g)
        if a is not None:
            Ha[:, :, k] = ab.sum(a)
    if lin is not None:
        # τ D(r) ≈ τ D(r0) + τ0 D(r) − τ0 D(r0), D linear in r: the time-offset column gains
        # D(r0), each lever column τ0 D(e_k), and τ0 D(r0) moves to the observed side
        kt = params.index("imu.time_offset")
        tau0 = lin[kt]
        for k, p in enumerate(params):
            if effect_of(p).name == "acc.lever":
                d = ab.sum(time_offset_of_lever(motion, p.split(".", 2)[2]))
                Ha[:, :, kt] += lin[k] * d
                Ha[:, :, k] += tau0 * d
                ya = ya + tau0 * lin[k] * d
    # geometry columns by forward differences (the prediction is smooth in these small angles:
    # the truncation error is ~1e-6 of the column, far below what the fit can resolve)
    base_g, base_a = (gb.sum(motion.ideal_gyro), ab.sum(motion.ideal_acc)) if table_params else (0, 0)
    blocks_key = hashlib.sha256(gb.start.tobytes() + gb.stop.tobytes() + ab.start.tobytes()
                                + ab.stop.tobytes()).hexdigest() if table_params else ""
    for p in table_params:
        k = params.index(p)
        key = (motion.profile_key, blocks_key, geo, p)
        if key not in _GEOMETRY_COLUMNS:
            v = table_parameter_value(geo, p)
            mp = motion_for(apply_table_parameter(geo, p, v + TABLE_STEP))
            _GEOMETRY_COLUMNS[key] = ((gb.sum(mp.ideal_gyro) - base_g) / TABLE_STEP,
                                      (ab.sum(mp.ideal_acc) - base_a) / TABLE_STEP)
            while len(_GEOMETRY_COLUMNS) > 256:
                _GEOMETRY_COLUMNS.popitem(last=False)
        Hg[:, :, k], Ha[:, :, k] = _GEOMETRY_COLUMNS[key]
    var_g = gb.count[:, None] * sg[None, :] ** 2 + rest_variance(data, geo, gb, rest)
    var_a = ab.count[:, None] * sa[None, :] ** 2
    y = np.concatenate([yg.reshape(-1), ya.reshape(-1)])
    H = np.concatenate([Hg.reshape(-1, len(params)), Ha.reshape(-1, len(params))])
    w = 1.0 / np.sqrt(np.concatenate([var_g.reshape(-1), var_a.reshape(-1)]))
    rows = {"sensor": np.array(["gyro"] * yg.size + ["acc"] * ya.size),
            "axis": np.concatenate([np.tile([0, 1, 2], len(gb)), np.tile([0, 1, 2], len(ab))]),
            "start": np.concatenate([np.repeat(gb.start, 3), np.repeat(ab.start, 3)]),
            "stop": np.concatenate([np.repeat(gb.stop, 3), np.repeat(ab.stop, 3)]),
            "moving": np.concatenate([np.repeat(gb.moving, 3), np.repeat(ab.moving, 3)]),
            "y": y, "H": H, "weight": w}
    return y, H, w, rows
