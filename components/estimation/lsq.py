"""General least-squares calibration on any log: predict the IMU output from the measured gimbal
angles through the table geometry and a chosen effect set, fit all their parameters jointly.

Model per observation block (components.estimation.blocks): measured sum − ideal sum = H θ + v, with the
columns of H the effects' regressors (components.model.effects) summed over the block, and for table
effects the derivative of the ideal prediction with respect to the geometry parameter (central
differences; Gauss–Newton iterations re-linearise). Weighted least squares with the per-sample
white-noise σ estimated from the log's static data (block variance n σ², plus the encoder's
count variance at the ends of a moving gyro block). With white noise this is the efficient
estimator and its covariance (Hᵀ R⁻¹ H)⁻¹ the Cramér–Rao bound (domain.md §7).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from components.errors import EstimationError
from components.estimation.blocks import samples_per_block
from components.estimation.chunks import CHUNK_SAMPLES, BlockLayout, chunked_design
from components.estimation.design import ACC_SCALE, GYRO_SCALE, noise_floor
from components.estimation.determinability import Determinability, assess
from components.estimation.log_data import LogData
from components.estimation.rest_angles import encoder_quantum, rest_sigma, rest_variance
from components.estimation.stacked_qr import scaled_lstsq
from components.estimation.whitening import whitened_r
from components.logs.spill import product
from components.model.effects import TIME_OFFSETS, effect_of, parameters_of
from components.model.excitation import needs
from components.model.geometry import TableGeometry
from components.model.noise import NoiseModel
from components.model.plausibility import bias_floors, grade_factor, implausible, weakly_determined
from components.model.table_parameters import apply_table_parameter, table_parameter_value

RCOND = 1e-7  # relative singular value below which a design direction is not resolved
TIME_OFFSET_STEP_TOL = 1e-9  # s: the time offset × lever-arm linearisation has converged


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
    dt: float  # median sample interval [s]
    temperature_ref: float  # the temperature the temperature coefficients count from [°C]
    iterations: int
    rows: dict = field(default_factory=dict)  # design of the last iteration, for diagnostics
    rest_sigma: np.ndarray | None = None  # σ of the rest angles used (estimated or given) [rad]
    noise: NoiseModel | None = None  # the noise model the rows were whitened with (None: white)
    # requested parameters this log does not determine (held at 0 or their fixed value, not in
    # `parameters`), those it determines weakly, and estimates no real IMU has, with the likely cause
    determinability: Determinability | None = None
    weak: list = field(default_factory=list)
    implausible: dict = field(default_factory=dict)
    hidden_white: list = field(default_factory=list)  # LogData.without_white_level
    white_poorly_read: list = field(default_factory=list)  # LogData.white_poorly_read

    @property
    def sigma(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))

    def correlation(self) -> np.ndarray:
        s = self.sigma
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.covariance / np.outer(s, s)

    def values(self) -> dict[str, float]:
        return dict(zip(self.parameters, self.value))


def calibrate(data: LogData, effects: list[str], *, chunk_s: float = 1.0, quadrature: int = 3,
              iterations: int = 3, sigma_gyro=None, sigma_acc=None,
              temperature_ref: float | None = None, fixed: dict | None = None,
              rest_angle_sigma=None, noise: NoiseModel | None = None, undetermined: str = "hold",
              chunk_samples: int = CHUNK_SAMPLES) -> Fit:
    """Fit the parameters of *effects* jointly to *data*.

    ``fixed``: parameter values held (not fitted), e.g. a geometry known from elsewhere.
    ``noise``: the composite noise model (components.model.noise) the rows are whitened with
    (generalised least squares); its white part is the per-sample σ unless ``sigma_gyro`` /
    ``sigma_acc`` are given. Without one, white noise of the σ estimated from the static data.
    ``rest_angle_sigma`` [rad, per axis]: uncertainty of the true angle at rest around the
    encoder reading, which bounds a rest-to-rest gyro block; default: one count uniform
    (q/√12, q the count the logged angles' steps show: rest_angles.encoder_quantum), 0 for logs
    whose rest angles are exact.
    ``undetermined``: what to do with requested parameters the log does not determine
    (components.estimation.determinability): "hold" them (at 0, or their fixed value, and name
    them in ``Fit.determinability``) or "refuse" the fit (EstimationError naming them).
    ``chunk_samples``: the rows are built that many samples at a time (components.estimation.chunks)."""
    params = parameters_of(effects)
    if not params:
        raise ValueError("no effect to fit")
    table_params = [p for p in params if effect_of(p).target == "table"]
    geo = data.geometry
    for name, v in (fixed or {}).items():
        if effect_of(name).target == "table":
            geo = apply_table_parameter(geo, name, v)
    dt_mean = data.sample_interval if len(data.time) > 1 else 1.0

    if temperature_ref is None and data.temperature is not None:
        temperature_ref = float(data.temperature[0])
    static = data.static
    # refused before any pass over the log's sensors
    if data.has_table and len(static) > 1 and not np.any(static[1:]):
        step = encoder_quantum(data.angles)
        raise EstimationError(
            "the table angles of this log change at every sample, so it has no rest (calbench takes the table "
            "at rest where the logged angles repeat exactly); their finest step is "
            + ", ".join(f"{np.degrees(x) * 3600:.3g}\"" for x in step) + ": if the angles carry noise finer than "
            "the encoder's count, import the log with 'round_to_count = true' and 'encoder_resolution' in the "
            "mapping's [table] (docs/import.md)")
    layout = BlockLayout.of(data, samples_per_block(data.sample_interval, chunk_s), chunk_samples)
    gb = layout.gyro

    def rows_at(g: TableGeometry, lin=None):
        return chunked_design(data, layout, params, sg, sa, q, g, table_params, temperature_ref, quadrature, lin)
    white = noise.white_sigma(dt_mean) if noise is not None else np.zeros(6)
    span = float(data.time[-1] - data.time[0] + dt_mean) if len(data.time) else 0.0

    def compressed(y, H, w, rows):
        """R of the whitened [H | y]: every solve, χ² and covariance below is on its few rows."""
        return whitened_r(y, H, rows, 1.0 / w**2, noise, dt_mean, span, chunk_s)

    quant = data.quantization_floor(noise)
    # each channel's white level from the noise model where it has one, else from the data (a
    # channel without one took all three sensors' axes to the data's: with gyro_x's white level
    # not found beside its floor, gyro_y's read one was dropped too, and χ²/dof went to 1.14); the
    # data's level is a pass over the whole log, so only for a sensor with a channel lacking one
    def own_or_data(given, levels, sensor, floor):
        if given is not None:
            return np.asarray(given, float)
        if np.all(levels > 0):
            return levels
        return np.where(levels > 0, levels, np.maximum(data.white_sigma_at_rest(sensor), floor))

    raw_g = own_or_data(sigma_gyro, white[:3], "gyro", quant[:3])
    raw_a = own_or_data(sigma_acc, white[3:], "acc", quant[3:])
    if np.any(np.isnan(raw_g)) or np.any(np.isnan(raw_a)):
        # no two usable static samples in a row: no σ can be given without being told the noise
        where = f"{data.source['log']}: " if (data.source or {}).get("log") else ""
        raise EstimationError(f"{where}the white-noise level cannot be estimated from this log (it has no two usable "
                              "samples in a row at rest): give the noise (--noise: a grade, a noise file or "
                              "NAME=VALUE terms such as gyro.noise.arw='0.002 deg/sqrt(h)')")
    no_white = data.without_white_level(np.concatenate([raw_g, raw_a]), noise)
    sg = noise_floor(raw_g, GYRO_SCALE * dt_mean)
    sa = noise_floor(raw_a, ACC_SCALE * dt_mean)
    q = rest_sigma(data.angles, rest_angle_sigma, data.encoder_resolution)
    if rest_angle_sigma is None and np.any(q):
        q = _estimate_rest_sigma(data, gb, params, sg, sa, q, geo, rows_at(geo))
    value = np.array([(fixed or {}).get(p, 0.0) if effect_of(p).target == "table"
                      else 0.0 for p in params])
    for p in table_params:
        value[params.index(p)] = table_parameter_value(geo, p)
    # the model's one product of two fitted parameters: the time offset shifts the lever-arm
    # terms too (effects.time_offset_of_lever); linearised at the last solution (Gauss–Newton)
    bilinear = any(p in params for p in TIME_OFFSETS) and any(effect_of(p).name == "acc.lever" for p in params)
    lin = None
    it = 0
    det = None
    for it in range(1, iterations + 1):
        # residual relative to the current table values (Gauss–Newton on the geometry)
        R = compressed(*rows_at(geo, lin))
        if det is None:
            det = assess(R[:, :-1], params)
            if det.undetermined:
                if undetermined == "refuse":
                    raise EstimationError("this log does not determine " + "; ".join(
                        f"{p} ({det.describe(p)}; needs {needs(p)})" for p in det.undetermined))
                keep = [k for k, p in enumerate(params) if p not in det.undetermined]
                params = [params[k] for k in keep]
                if not params:
                    raise EstimationError("this log determines none of the requested parameters: " + "; ".join(
                        f"{p} needs {needs(p)}" for p in det.undetermined))
                R, value = R[:, keep + [R.shape[1] - 1]], value[keep]
                table_params = [p for p in table_params if p in params]
                bilinear = any(p in params for p in TIME_OFFSETS) and any(effect_of(p).name == "acc.lever" for p in params)
        # rcond: a direction of the column-normalised design below 1e-7 of the largest is a
        # parameter combination the data cannot see (e.g. a wobble of an inner stage, which is a
        # constant rotation of the plate = IMU misalignment, left only with the forward-
        # difference error of its column); resolving it would amplify noise into a huge step
        # of the geometry and wreck the next linearisation
        step = scaled_lstsq(R[:, :-1], R[:, -1], RCOND)[0]
        sensor_idx = [k for k, p in enumerate(params) if p not in table_params]
        value[sensor_idx] = step[sensor_idx]
        moved = False
        if bilinear:
            kts = [params.index(p) for p in TIME_OFFSETS if p in params]
            moved = lin is None or max(abs(value[k] - lin[k]) for k in kts) > TIME_OFFSET_STEP_TOL
            lin = value.copy()
        if table_params:
            delta = np.array([step[params.index(p)] for p in table_params])
            for p, d in zip(table_params, delta):
                value[params.index(p)] += d
                geo = apply_table_parameter(geo, p, value[params.index(p)])
            moved = moved or np.max(np.abs(delta)) >= 1e-12
        if not moved:
            break
    # final linearisation at the solution: sensor values and the last (tiny) table correction
    y, H, w, rows = rows_at(geo, lin)
    R = compressed(y, H, w, rows)
    sol, chi2, cov, _ = scaled_lstsq(R[:, :-1], R[:, -1], RCOND)
    for k, p in enumerate(params):
        value[k] = value[k] + sol[k] if p in table_params else sol[k]
    rows["residual"] = y - product(H, sol)
    # the median interval as the motion has them (the first one from dt0)
    dt_median = data.interval_median(first=float(data.time[0] - data.start_time))
    fit = Fit(params, value, cov, chi2, len(y) - len(params), sg, sa, geo, dt_median,
              float(temperature_ref or 0.0), it, rows)
    fit.rest_sigma = q
    fit.hidden_white = no_white
    fit.white_poorly_read = data.white_poorly_read(noise)
    fit.noise = noise if noise is not None and noise.coloured else None
    fit.determinability = det
    factor = grade_factor({"gyro": float(np.median(sg)) / np.sqrt(dt_mean), "acc": float(np.median(sa)) / np.sqrt(dt_mean)})
    fit.weak = weakly_determined(dict(zip(params, fit.sigma)), factor, bias_floors(noise))
    fit.implausible = implausible(dict(zip(params, value)), dt_mean)
    return fit


def _estimate_rest_sigma(data, gb, params, sg, sa, q, geo, design_rows):
    """How far the table really rests from its encoder readings, from the data: the moving gyro
    blocks' residual variance beyond their white noise, against the geometric factor of the
    rest angles (a method-of-moments variance component). Starts from one count uniform (the
    prior q/√12) and stays within [0, 2 q/√12]; the estimator's σ then matches its spread."""
    y, H, w, rows = design_rows
    # (white noise: the weights alone; no interval or span enters)
    R = whitened_r(y, H, rows, 1.0 / w**2, None, data.sample_interval, 0.0)
    sol = scaled_lstsq(R[:, :-1], R[:, -1], None)[0]
    r = y - product(H, sol)
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
