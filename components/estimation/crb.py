"""Cramér–Rao bound of a calibration schedule for a noise model.

The observations are the least-squares engine's block sums (components.estimation.design), so the
bound is the one the estimator can reach. The noise is the composite model of
components.model.noise (quantization, white noise, bias instability, random walk, Gauss–Markov
terms) in its exact discrete form on the blocks: the rows whitened by the Kalman filter of
components.estimation.whitening give the Fisher information F = H̃ᵀ H̃ and CRB = F⁻¹. The bias
instability and the random walk enter as the correlated noise they are, not as extra parameters.
"""
from __future__ import annotations

import numpy as np

from components.estimation.blocks import samples_per_block
from components.estimation.chunks import BlockLayout, chunked_design
from components.estimation.determinability import assess
from components.estimation.log_data import LogData
from components.estimation.rest_angles import rest_sigma
from components.estimation.whitening import whitened_r
from components.model.effects import effect_of, parameters_of
from components.model.noise import NoiseModel


def cramer_rao(data: LogData, effects: list[str], noise: NoiseModel, chunk_s: float = 1.0,
               rest_angle_sigma=None) -> dict[str, float]:
    """σ bound per parameter of *effects* on the motion of *data* (its IMU values are unused),
    for the IMU noise *noise*. ``rest_angle_sigma``: as for components.estimation.lsq.calibrate."""
    params = parameters_of(effects)
    table_params = [p for p in params if effect_of(p).target == "table"]
    geo = data.geometry
    dt = data.sample_interval
    white = noise.white_sigma(dt)
    sg, sa = np.maximum(white[:3], 1e-30), np.maximum(white[3:], 1e-30)
    q = rest_sigma(data.angles, rest_angle_sigma, data.encoder_resolution)
    # the bound needs the design's columns only (the rows' measured side is not used), built a
    # chunk of the schedule at a time like the estimators' (components.estimation.chunks)
    y, H, w, rows = chunked_design(data, BlockLayout.of(data, samples_per_block(data.sample_interval, chunk_s)), params, sg, sa, q, geo, table_params, None)
    span = data.time[-1] - data.time[0] + dt
    # the whitened rows' R (their Gram matrix, a piece of rows at a time: whitening.whitened_r)
    Hw = whitened_r(y, H, rows, 1.0 / w**2, noise, dt, span, chunk_s)[:, :-1]
    # a parameter the schedule does not determine has no bound: inf, never the min-norm σ of a
    # pseudo-inverse (which reads as a confident number)
    det = assess(Hw, params)
    keep = [k for k, p in enumerate(params) if p not in det.undetermined]
    Hk = Hw[:, keep]
    F = Hk.T @ Hk
    scale = np.sqrt(np.clip(np.diag(F), 1e-300, None))
    cov = np.linalg.pinv(F / np.outer(scale, scale), rcond=1e-12) / np.outer(scale, scale)
    out = dict.fromkeys(params, float("inf"))
    out.update(zip([params[k] for k in keep], np.sqrt(np.clip(np.diag(cov), 0, None))))
    return out


def positions_cramer_rao(data: LogData, effects: list[str], noise: NoiseModel) -> tuple[dict[str, float], dict]:
    """σ bound per parameter of *effects* on a log without table angles (the positions method:
    each rest's attitude a nuisance, components.estimation.positions_effects), for *noise*,
    at the attitudes the log's own fit finds (the information depends on them, not on what the
    sensors read); and the parameters the method holds, with why (its gauge, or not determined)."""
    from components.estimation.positions_effects import fit_positions

    fit = fit_positions(data, effects, noise=noise)
    sig = np.sqrt(np.clip(np.diag(fit.covariance), 0, None))
    out = dict.fromkeys(parameters_of(effects), float("inf"))
    out.update(zip(fit.parameters, sig.tolist()))
    held = dict(fit.held)
    held.update({p: "not determined by this log" for p in fit.undetermined if p not in held})
    for p in held:
        out.pop(p, None)
    return out, held
