"""The observation model of the least squares, the Cramér–Rao bound and the diagnosis, built
once: per observation block (components.estimation.blocks), measured sum − ideal sum = H θ + v,
the columns of H the effects' regressors (components.model.effects) summed over the block, and
for table effects the derivative of the ideal prediction with respect to the geometry parameter
(components.estimation.table_columns). Rows are weighted by the block's white-noise variance
(n σ², plus the encoder's count variance at the ends of a moving gyro block)."""
from __future__ import annotations

import numpy as np

from components.estimation.block_motion import BlockMotion
from components.estimation.blocks import Blocks
from components.estimation.rest_angles import rest_variance
from components.estimation.table_columns import table_columns
from components.model.effects import TIME_OFFSETS, effect_of, regressor_of, time_offset_of_lever
from components.model.motion import Motion


def predict(motion: Motion, params: list[str], values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Model output increments (N, 3) gyro and acc for sensor-effect values on this motion,
    summed one regressor at a time (all of them at once, as (N, 3, P) arrays, held 0.4 GB for
    18 parameters on a 42-minute 200 Hz log)."""
    gyro, acc = motion.ideal_gyro.copy(), motion.ideal_acc.copy()
    for p, v in zip(params, np.asarray(values, float)):
        g, a = regressor_of(motion, p)
        if g is not None:
            gyro += v * g
        if a is not None:
            acc += v * a
    return gyro, acc


# the size of what each channel measures, per second, gyro x y z then accelerometer x y z: the
# Earth's rate [rad/s] and gravity [m/s²]. Numerical floors are fractions of it (a noise-free
# channel's σ, rounding), never fractions of a noise that may be zero.
SIGNAL_SCALE = np.array([7.3e-5] * 3 + [9.8] * 3)
GYRO_SCALE, ACC_SCALE = SIGNAL_SCALE[0], SIGNAL_SCALE[3]


def noise_floor(sig: np.ndarray, scale: float) -> np.ndarray:
    # a noise-free log (a conformance vector) still needs finite weights
    return np.where(np.isfinite(sig) & (sig > 0), sig, 0.0) + 1e-13 * scale


def design(data, motion: BlockMotion, params, gb: Blocks, ab: Blocks, sg, sa, rest, geo, table_params,
           lin=None):
    """Stacked rows (gyro blocks x 3 axes, then acc blocks x 3 axes): y, H, weights, row info.
    ``lin``: the values (per parameter) the time offset × lever-arm product is linearised at."""
    # block sums column by column, the moving samples one by one and each rest block at once
    # (components.estimation.block_motion): never (N, 3, P) regressors, nor a row per rest sample.
    # A rest block's measured sum minus its ideal sum (~10 m/s for 1 s of gravity) leaves ~1e-15
    # m/s of rounding, 1e-11 of a navigation-grade accelerometer's noise over that second
    rg, ra = motion.rests(gb), motion.rests(ab)
    mi, mv = motion.moving_index, motion.moving
    yg = motion.sums(gb, data.gyro[mi] - mv.ideal_gyro, gb.subset(~gb.moving).sum(data.gyro) - rg.ideal_gyro)
    ya = motion.sums(ab, data.acc[mi] - mv.ideal_acc, ab.subset(~ab.moving).sum(data.acc) - ra.ideal_acc)
    Hg = np.zeros((len(gb), 3, len(params)))
    Ha = np.zeros((len(ab), 3, len(params)))
    for k, p in enumerate(params):
        g, a = regressor_of(motion.moving, p)
        if g is not None:
            Hg[:, :, k] = motion.sums(gb, g, regressor_of(rg, p)[0])
        if a is not None:
            Ha[:, :, k] = motion.sums(ab, a, regressor_of(ra, p)[1])
    if lin is not None:
        # τ D(r) ≈ τ D(r0) + τ0 D(r) − τ0 D(r0), D linear in r, τ the accelerometers' whole shift
        # (imu.time_offset + acc.time_offset): each time-offset column gains D(r0), each lever
        # column τ0 D(e_k), and τ0 D(r0) moves to the observed side
        kts = [params.index(p) for p in TIME_OFFSETS if p in params]
        tau0 = sum(lin[kt] for kt in kts)
        for k, p in enumerate(params):
            if effect_of(p).name == "acc.lever":
                idx = p.split(".", 2)[2]
                d = motion.sums(ab, time_offset_of_lever(motion.moving, idx), time_offset_of_lever(ra, idx))
                for kt in kts:
                    Ha[:, :, kt] += lin[k] * d
                Ha[:, :, k] += tau0 * d
                ya = ya + tau0 * lin[k] * d
    columns = table_columns(motion.profile, gb, ab, geo, table_params)
    for p, (cg, ca) in columns.items():
        Hg[:, :, params.index(p)], Ha[:, :, params.index(p)] = cg, ca
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
