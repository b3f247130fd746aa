"""Model against measurement on a log without table angles (docs/positions.md).

Without angles the attitudes of the rests are not known: with the model's parameters held,
they are estimated (2 tilts per rest, and the heading when the Earth rate is modelled) from this
log, and what is left — the block rows of components.estimation.positions_design whitened by
the noise model — is the misfit: χ² with dof = rows − attitude angles (− the model's parameters
when it was fitted to this log). The per-sample residual is measured − predicted on the rests'
samples and the turns'; samples no row uses (hand moves, excluded) have none (NaN).
"""
from __future__ import annotations

import numpy as np

from components.diagnosis.compare import CHANNELS, Comparison, locate
from components.estimation.blocks import white_noise_sigma
from components.estimation.chunks import PlateAtSamples
from components.estimation.design import SIGNAL_SCALE, noise_floor
from components.estimation.distributions import ljung_box
from components.estimation.log_data import LogData
from components.estimation.positions import SUPPORTED, calibrate_positions
from components.estimation.positions_design import PositionsDesign
from components.model.effects import effect_of
from components.model.noise import NoiseModel
from components.model.result import CalibrationResult

STEP_TOL = 1e-4     # attitude iterations stop below this fraction of an angle's σ
MAX_ITERATIONS = 20


def model_attitudes(design: PositionsDesign, data: LogData, params: list[str], theta: np.ndarray,
                    noise: NoiseModel | None = None, chunk_s: float = 1.0):
    """The rests' attitudes (P, 3, 3) that fit *data* best with the sensor parameters held at
    *theta*, and the rows there."""
    start = calibrate_positions(data.time, data.gyro, data.acc, data.segment, data.segments, effects=SUPPORTED,
                                valid=data.usable, latitude=data.geometry.latitude, gravity=data.geometry.gravity,
                                noise=noise, chunk_s=chunk_s)
    C = start.attitudes.copy()
    for _ in range(MAX_ITERATIONS):
        r = design.rows(C, params, theta)
        resid = r.y - r.H @ theta
        sc = np.linalg.norm(r.A, axis=0)
        sc[sc == 0] = 1.0
        An = r.A / sc
        delta = np.linalg.lstsq(An, resid, rcond=None)[0]
        sig = np.sqrt(np.clip(np.diag(np.linalg.pinv(An.T @ An)), 0, None))
        C = design.turn_rest(C, delta / sc)
        if np.max(np.abs(delta) / np.where(sig > 0, sig, 1.0)) < STEP_TOL:
            break
    return C, design.rows(C, params, theta)


def compare_positions(data: LogData, model: CalibrationResult, *, fitted_parameters: int = 0,
                      chunk_s: float = 1.0, noise: NoiseModel | None = None) -> Comparison:
    """The misfit of *model* on a log without table angles (see the module docstring)."""
    if noise is None:
        noise = model.noise_model()
    params = [p for p in model.values if effect_of(p).target != "table"]
    theta = np.array([model.values[p] for p in params])
    design = PositionsDesign(data, chunk_s=chunk_s, noise=noise, temperature_ref=model.temperature_ref)
    C, r = model_attitudes(design, data, params, theta, noise, chunk_s)
    z = r.y - r.H @ theta
    # the attitudes were fitted: what is left is the part of the rows they cannot explain
    z = z - r.A @ np.linalg.lstsq(r.A, z, rcond=None)[0]
    info = r.info
    rows = {"z": z, "sensor": info["sensor"], "channel": info["axis"] + np.where(info["sensor"] == "acc", 3, 0),
            "start": info["start"], "stop": info["stop"], "moving": info["moving"]}
    n_att = r.A.shape[1]
    chi2 = float(z @ z)
    dof = max(len(z) - n_att - fitted_parameters, 1)
    # the per-sample prediction on the rests' and the turns' samples
    per = PositionsDesign(data, chunk_s=chunk_s, noise=None, temperature_ref=model.temperature_ref, per_sample=True)
    g, a = per.predict_units(C, params, theta)
    pred = np.hstack([g, a])
    modelled = np.zeros(len(data.time), bool)
    for _, s, e in design.segs.chunks:
        modelled[s:e] = True
    for t in design.turns:
        modelled[t.lo:t.hi] = True
    pred[~modelled] = np.nan
    resid = np.hstack([data.gyro, data.acc]) - pred
    motion = per.motion(C)
    rest = motion.static & modelled
    sigma = white_noise_sigma(np.nan_to_num(resid), rest)
    sigma = noise_floor(sigma, SIGNAL_SCALE)
    # a pulse output's sample differences collapse where its counts are coarser than the noise:
    # a sample's residual still carries the two remainders of its count
    sigma = np.maximum(sigma, np.sqrt(2.0) * data.quantization_floor())
    meas = np.hstack([data.gyro, data.acc])
    channels = {}
    for k, ch in enumerate(CHANNELS):
        sel = rows["channel"] == k
        zk = rows["z"][sel]
        order = np.argsort(rows["start"][sel], kind="stable")
        ok = rest
        moving = modelled & ~rest if k < 3 else np.zeros_like(rest)
        dev = meas[modelled, k] - meas[modelled, k].mean()
        channels[ch] = {
            "rms": float(np.sqrt(np.mean(resid[ok, k] ** 2))) if ok.any() else float("nan"),
            "rms_moving": float(np.sqrt(np.mean(resid[moving, k] ** 2))) if moving.any() else None,
            "noise_floor": float(sigma[k]),
            "chi2_per_dof": float(np.sum(zk ** 2) / max(len(zk) * dof / max(len(z), 1), 1)),
            "fit_percent": float(100 * (1 - np.linalg.norm(resid[modelled, k]) / np.linalg.norm(dev)))
            if np.linalg.norm(dev) > 0 else float("nan"),
            "whiteness_p": ljung_box(zk[order]),
        }
    comp = Comparison(data.time, data.segment, rest, resid, pred, sigma, channels, chi2, dof, rows)
    comp.whitened_under(noise)
    locate(comp, data, PlateAtSamples.of(motion), rows)
    comp.attitudes = C  # type: ignore[attr-defined]
    return comp
