"""Model against measurement: replay the measured motion through a model and measure the misfit.

The motion is the log's gimbal angles through the table geometry (with the model's table
effects), the model is a calibration result (components.model.result) — the IMU's predicted output is
ideal + Σ effect regressors × values.

What the numbers mean (docs/compare.md says the same for users):

- ``residual``: per sample and channel, measured − model, in SI increments (and in the log's
  output units in the ``--residuals`` file).
- ``noise_floor``: the per-sample noise σ of each channel: white, estimated from the residual's
  high-frequency content (consecutive differences within static runs, robust scale) or the
  noise model's; with a pulse output's quantization Q in the noise model, the two remainders of
  a sample's count with it, √(σ² + 2Q²) (a noise-free pulse output has no white level at all).
- ``rms``: RMS of the per-sample residual over the samples the model predicts sample by sample —
  every accelerometer sample and the static gyro samples; during moves the per-sample gyro
  prediction is limited by the encoder (domain.md §3) and is reported apart as ``rms_moving``.
  A correct model has rms ≈ noise_floor.
- ``chi2_per_dof``: the low-frequency content. Residuals are summed over the estimator's blocks
  (1 s static chunks and rest-to-rest moves for the gyros, 1 s chunks for the accelerometers);
  each block sum is divided by its white-noise σ (√n · noise_floor, plus the rest-angle
  uncertainty of a move); χ²/dof = mean of the squares over the blocks (minus the fitted
  parameters when the model was fitted to this log). White noise gives 1 ± √(2/dof); a missing
  systematic effect, which adds coherently within a block, gives clearly more — where a
  per-sample χ² would stay at 1.00.
- ``fit_percent``: 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) per channel over all samples (NRMSE fit).
- ``whiteness_p``: Ljung–Box p-value of the normalised block residuals in time order.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from components.diagnosis.misfit import CHANNELS, Misfits, misfits
from components.estimation import order_statistics
from components.estimation.blocks import observation_blocks, samples_per_block, white_noise_sigma
from components.estimation.chunks import CHUNK_SAMPLES, BlockLayout, PlateAtSamples, chunked_prediction
from components.estimation.count_phase import count_advance
from components.estimation.design import SIGNAL_SCALE, noise_floor
from components.estimation.distributions import ljung_box
from components.estimation.log_data import LogData
from components.estimation.rest_angles import rest_sigma, rest_variance
from components.estimation.whitening import whiten
from components.logs.labels import SegmentLabels
from components.logs.spill import both, empty_like_log, gathered, pieces, release
from components.model.effects import effect_of
from components.model.noise import NoiseModel, describe
from components.model.result import CalibrationResult
from components.model.table_parameters import apply_table_parameter

__all__ = ["CHANNELS", "Comparison", "assess", "compare", "locate", "model_geometry"]

def model_geometry(data: LogData, model: CalibrationResult):
    geo = data.geometry
    for p, v in model.values.items():
        if effect_of(p).target == "table":
            geo = apply_table_parameter(geo, p, v)
    return geo


@dataclass
class Comparison:
    time: np.ndarray
    segment: SegmentLabels | None  # the log's (LogData.segment)
    static: np.ndarray
    residual: np.ndarray           # (N, 6) SI increments
    predicted: np.ndarray          # (N, 6)
    noise_floor: np.ndarray        # (6,) per-sample σ
    channels: dict                 # channel -> metrics
    chi2: float
    dof: int
    rows: dict                     # block rows: z, sensor, axis, start, stop, moving
    per_segment: dict = field(default_factory=dict)
    conditions: dict = field(default_factory=dict)
    coloured: bool = False         # the block residuals are whitened with a coloured noise model
    # that model's terms (components.model.noise.describe), None under white noise: two χ²/dof of
    # one model under two identified noise models differ, and the reader must see which is which
    noise_terms: str | None = None
    misfits: Misfits | None = None  # which segments / conditions / channels misfit beyond noise
    # (N,) the samples that enter estimates (LogData.usable): the sample after a gap, a masked or
    # excluded one, has a residual here but enters no statistic (None: every sample)
    usable: np.ndarray | None = None
    # pulse channels without a white level (LogData.without_white_level)
    no_white_level: list = field(default_factory=list)
    # pulse channels whose identified white level is not measured (LogData.white_poorly_read)
    white_poorly_read: list = field(default_factory=list)

    def whitened_under(self, noise: NoiseModel | None) -> None:
        """Record the noise model the block residuals were whitened with (None: white noise)."""
        self.coloured = noise is not None and noise.coloured
        self.noise_terms = describe(noise) if self.coloured else None

    @property
    def static_usable(self) -> np.ndarray:
        """(N,) at rest and usable: the samples a per-sample noise statistic may read."""
        return both(self.static, self.usable)

    @property
    def chi2_per_dof(self) -> float:
        return self.chi2 / max(self.dof, 1)

    def summary(self) -> dict:
        return {"chi2_per_dof": self.chi2_per_dof, "dof": self.dof,
                "channels": self.channels, "segments": self.per_segment,
                "conditions": self.conditions,
                "misfits": self.misfits.to_json() if self.misfits is not None else None,
                "no_white_level": list(self.no_white_level), "white_poorly_read": list(self.white_poorly_read)}


def _blocks_rows(data: LogData, geo, blocks, residual, sigma, rest, chunk_s, noise: NoiseModel | None = None):
    dt = data.sample_interval
    gb, ab = blocks
    zs, vs, sens, axis, start, stop, moving = [], [], [], [], [], [], []
    for blocks, sl, name in ((gb, slice(0, 3), "gyro"), (ab, slice(3, 6), "acc")):
        s = blocks.sum(residual[:, sl])
        var = blocks.count[:, None] * sigma[sl][None, :] ** 2
        if name == "gyro":
            var = var + rest_variance(data, geo, blocks, rest)
        z = s / np.sqrt(var)
        zs.append(z.reshape(-1))
        vs.append((s.reshape(-1), var.reshape(-1)))
        sens += [name] * z.size
        axis.append(np.tile([0, 1, 2], len(blocks)) + (0 if name == "gyro" else 3))
        start.append(np.repeat(blocks.start, 3))
        stop.append(np.repeat(blocks.stop, 3))
        moving.append(np.repeat(blocks.moving, 3))
    rows = {"z": np.concatenate(zs), "sensor": np.array(sens), "channel": np.concatenate(axis),
            "start": np.concatenate(start), "stop": np.concatenate(stop),
            "moving": np.concatenate(moving)}
    if noise is not None and noise.coloured:
        # block sums whitened under the coloured model: z is then the normalised innovation
        rows["axis"] = rows["channel"] % 3
        rows.update(count_advance(data, rows))
        sums = np.concatenate([v[0] for v in vs])
        var = np.concatenate([v[1] for v in vs])
        span = float(data.time[-1] - data.time[0] + dt)
        z, _, _ = whiten(sums, np.zeros((len(sums), 0)), rows, var, noise, dt, span, chunk_s)
        rows["z"] = z
    return rows


def compare(data: LogData, model: CalibrationResult, *, fitted_parameters: int = 0,
            chunk_s: float = 1.0, rest_angle_sigma=None, noise: NoiseModel | None = None,
            chunk_samples: int = CHUNK_SAMPLES) -> Comparison:
    """Residual of *model* on *data*. ``fitted_parameters``: how many parameters were fitted to
    this same log (subtracted from the degrees of freedom). ``noise``: the composite noise model
    the block residuals are whitened with (default: the model's own, else white noise of the
    level estimated from the residual's high-frequency content). The prediction is made
    ``chunk_samples`` samples at a time (components.estimation.chunks)."""
    geo = model_geometry(data, model)
    sensor_params = [p for p in model.values if effect_of(p).target != "table"]
    values = np.array([model.values[p] for p in sensor_params])
    layout = BlockLayout.of(data, samples_per_block(data.sample_interval, chunk_s), chunk_samples)
    pred, plate = chunked_prediction(data, layout, sensor_params, values, geo, model.temperature_ref)
    if rest_angle_sigma is None:
        rest_angle_sigma = model.rest_angle_sigma()
    if noise is None:
        noise = model.noise_model()
    return assess(data, geo, plate, pred, fitted_parameters=fitted_parameters, chunk_s=chunk_s,
                  rest_angle_sigma=rest_angle_sigma, noise=noise, blocks=(layout.gyro, layout.acc))


def assess(data: LogData, geo, plate: PlateAtSamples, pred: np.ndarray, *, fitted_parameters: int = 0,
           chunk_s: float = 1.0, rest_angle_sigma=None, noise: NoiseModel | None = None,
           blocks=None) -> Comparison:
    """The misfit figures of a prediction (N, 6) of the log's IMU increments, whatever made it
    (a calibration result, or a supplier's IMU FMU replayed on the log's motion); *plate*: the
    plate at the samples (PlateAtSamples.of a Motion, or from chunked_prediction); *blocks*:
    the log's (gyro, accelerometer) observation blocks if already laid out."""
    if blocks is None:
        blocks = observation_blocks(plate.static, data.angles, samples_per_block(data.sample_interval, chunk_s), data.valid)
    # residual written in place, a piece at a time: a long log's (N, 6) arrays are 48 bytes a
    # sample each (and spilled to disk with a spilled log, components.logs.spill)
    resid = empty_like_log(pred.shape, pred)
    for s in pieces(len(resid), resid, pred, data.gyro, data.acc):
        np.subtract(data.gyro[s], pred[s, :3], out=resid[s, :3])
        np.subtract(data.acc[s], pred[s, 3:], out=resid[s, 3:])
    sigma = white_noise_sigma(resid, both(plate.static, data.valid), data.quantization_floor(noise))
    dt = order_statistics.median(plate.dt)
    release(plate.dt)  # a spilled log's: its pages back (the plate's columns, 56 bytes a sample)
    # a channel without noise (a simulation that injected none, a conformance vector): its
    # residual's differences are rounding, below a billionth of Earth's rate or gravity a sample
    # (the best IMU's noise is ~1e-4 of it), and its χ² weighs them against a numerical floor
    scale = SIGNAL_SCALE * dt
    noise_free = ~(np.isfinite(sigma) & (sigma > 1e-9 * scale))
    raw = np.nan_to_num(sigma)
    sigma = noise_floor(sigma, scale)
    rest = rest_sigma(data.angles, rest_angle_sigma, data.encoder_resolution)
    if noise is not None and noise.coloured:
        white = noise.white_sigma(dt)
        sigma = np.where(white > 0, white, sigma)
    rows = _blocks_rows(data, geo, blocks, resid, sigma, rest, chunk_s, noise)
    chi2 = float(np.sum(rows["z"] ** 2))
    dof = max(len(rows["z"]) - fitted_parameters, 1)
    channels = {}
    sums = _sample_sums(data, resid, plate.static, data.usable)
    floor = np.sqrt(sigma**2 + 2 * _model_quantization(noise) ** 2)
    for k, ch in enumerate(CHANNELS):
        sel = rows["channel"] == k
        zk = rows["z"][sel]
        order = np.argsort(rows["start"][sel], kind="stable")
        sq_ok, n_ok, sq_moving, n_moving, sq_all, sq_dev = sums[k]
        channels[ch] = {
            "rms": float(np.sqrt(sq_ok / n_ok)) if n_ok else float("nan"),
            "rms_moving": float(np.sqrt(sq_moving / n_moving)) if n_moving else None,
            "noise_floor": float(floor[k]),
            "chi2_per_dof": float(np.sum(zk**2) / max(len(zk) - fitted_parameters * len(zk) / max(len(rows["z"]), 1), 1)),
            "fit_percent": float(100 * (1 - np.sqrt(sq_all) / np.sqrt(sq_dev))) if sq_dev > 0 else float("nan"),
            "whiteness_p": ljung_box(zk[order]),
            "noise_free": bool(noise_free[k]) and not (noise is not None and noise.coloured),
        }
    # (the mask itself, None for every sample: static_usable is then the static mask, not a copy
    # of it made against a mask of all True, a file's worth on a spilled log)
    comp = Comparison(data.time, data.segment, plate.static, resid, pred, sigma, channels, chi2,
                      dof, rows, usable=data.valid)
    comp.whitened_under(noise)
    comp.no_white_level = data.without_white_level(raw, noise)
    comp.white_poorly_read = data.white_poorly_read(noise)
    locate(comp, data, plate, rows)
    return comp


def _model_quantization(noise: NoiseModel | None) -> np.ndarray:
    """(6,) the quantization Q the noise model carries per channel (0 without one)."""
    return np.zeros(6) if noise is None else np.array([c.quantization for c in noise.channels])


def _sample_sums(data: LogData, resid: np.ndarray, static: np.ndarray, usable: np.ndarray) -> list[tuple]:
    """Per channel, over the *usable* samples: Σ r² and count where the model predicts sample by
    sample (every accelerometer sample, the gyros at rest), the same for the rest, Σ r² over all,
    and Σ (y − ȳ)² of the measurement; a piece of the log at a time (two passes: ȳ first). A left-
    out sample never counts: the one after a gap spans it, a residual of the gap's length."""
    n = len(resid)
    mean = np.zeros(6)
    for s in pieces(n, data.gyro, data.acc):
        u = usable[s]
        mean[:3] += data.gyro[s][u].sum(axis=0)
        mean[3:] += data.acc[s][u].sum(axis=0)
    mean /= max(int(np.count_nonzero(usable)), 1)
    tot = np.zeros((6, 6))  # channel x (sq_ok, n_ok, sq_moving, n_moving, sq_all, sq_dev)
    for s in pieces(n, resid, data.gyro, data.acc):
        u = usable[s, None]
        r2 = np.where(u, resid[s] ** 2, 0.0)
        ok = np.ones(r2.shape, bool)
        ok[:, :3] = static[s, None]
        tot[:, 0] += np.where(ok, r2, 0.0).sum(axis=0)
        tot[:, 1] += (ok & u).sum(axis=0)
        tot[:, 2] += np.where(ok, 0.0, r2).sum(axis=0)
        tot[:, 3] += (~ok & u).sum(axis=0)
        tot[:, 4] += r2.sum(axis=0)
        dev = np.where(u, np.hstack([data.gyro[s], data.acc[s]]) - mean, 0.0)
        tot[:, 5] += (dev**2).sum(axis=0)
    return [tuple(row) for row in tot]


def locate(comp: Comparison, data: LogData, plate: PlateAtSamples, rows: dict) -> None:
    """Where the misfit is: per segment and per condition (RMS, 1 = noise) and the cells that
    misfit beyond noise given how many were looked at (components.diagnosis.misfit)."""
    comp.per_segment = _per_segment(data, rows)
    masks = _condition_masks(data, plate, rows)
    comp.conditions = _conditions(rows, masks)
    seg = data.segment[rows["start"]].astype(str) if data.segment is not None else None
    comp.misfits = misfits(rows, seg, masks)


def _per_segment(data: LogData, rows: dict) -> dict:
    """Per segment label and channel: RMS of the normalised block residuals (1 = noise)."""
    if data.segment is None:
        return {}
    label = data.segment[rows["start"]].astype(str)  # the blocks' labels, not every sample's
    out: dict = {}
    for s in dict.fromkeys(label):
        sel = label == s
        out[s] = [float(np.sqrt(np.mean(rows["z"][sel & (rows["channel"] == k)] ** 2)))
                  if np.any(sel & (rows["channel"] == k)) else None for k in range(6)]
    return out


def _condition_masks(data: LogData, plate: PlateAtSamples, rows: dict) -> dict:
    """Condition name -> which block rows it holds."""
    mid = (rows["start"] + rows["stop"] - 1) // 2
    # the blocks' middles touch every page of a spilled log's columns: a piece at a time
    f, w = gathered(plate.f, mid), gathered(plate.omega, mid)
    cond: dict[str, np.ndarray] = {}
    cond["static"] = ~rows["moving"]
    cond["rotating"] = rows["moving"]
    up = np.argmax(np.abs(f), axis=1)
    sign = np.sign(f[np.arange(len(f)), up])
    for k, c in enumerate("xyz"):
        for s, name in ((1, "up"), (-1, "down")):
            cond[f"static, {c} {name}"] = (~rows["moving"]) & (up == k) & (sign == s)
    rate = np.linalg.norm(w, axis=1)
    cond["rate < 5 deg/s"] = rows["moving"] & (rate < np.radians(5))
    cond["rate 5-20 deg/s"] = rows["moving"] & (rate >= np.radians(5)) & (rate < np.radians(20))
    cond["rate > 20 deg/s"] = rows["moving"] & (rate >= np.radians(20))
    dom = np.argmax(np.abs(w), axis=1)
    wsign = np.sign(w[np.arange(len(w)), dom])
    cond["rate sign +"] = rows["moving"] & (wsign > 0)
    cond["rate sign -"] = rows["moving"] & (wsign < 0)
    if data.temperature is not None:
        T = gathered(data.temperature, mid)
        # the thirds of the blocks' temperatures, the rows these conditions split (the thirds of
        # every sample's were a copy of the whole column, 8 bytes a sample)
        lo, hi = np.quantile(T, [1 / 3, 2 / 3]) if len(T) else (0.0, 0.0)
        if hi > lo:  # a temperature that hardly changes has no low and high thirds to set apart
            cond["temperature low"] = T <= lo
            cond["temperature mid"] = (T > lo) & (T <= hi)
            cond["temperature high"] = T > hi
    return cond


def _conditions(rows: dict, cond: dict) -> dict:
    """Normalised block-residual RMS split by condition."""
    z = rows["z"]
    out = {}
    for name, sel in cond.items():
        vals = []
        for k in range(6):
            m = sel & (rows["channel"] == k)
            vals.append(float(np.sqrt(np.mean(z[m] ** 2))) if m.any() else None)
        if any(v is not None for v in vals):
            out[name] = vals
    return out
