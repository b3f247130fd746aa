"""CW/CCW rotations and ± static positions: the classical closed forms of seed 003 (S201 gyro
scale factor from ± rotations, S202 accelerometer scale factor from ± static positions) and
seed 001 (steps 2-4 and 7: CW/CCW turns at six attitudes, coarse accelerometer scale factors
with a chosen scale acceleration β).

**Gyro** (scale factors and all six misalignments). Rotation segments are found from the
logged angles, not from labels: a segment over which exactly one gimbal turns by a whole
number (>= 1) of turns and ends at rest (the ``rotate`` steps of seed_001, seed_003 and
rotations schedules: labels such as ``att01-cw``/``att01-ccw``, ``S201-y+``/``S201-y-``,
``rotZ+10``). The rotation axis in plate axes ``a`` follows from the geometry at the other
gimbals' angles, the signed angle ``Θ`` from the encoder (start = the sample before the
segment, end = its last sample). The Earth rate (nominal geometry, known latitude) is
subtracted from the sums first; its constant part would cancel anyway, but the horizontal
part seen by the turning plate over the start and stop differs between CW and CCW (a few
0.01" of misalignment otherwise). Rotations about the same plate axis are grouped by sign;
with S± the summed gyro increments and T± the durations,

    c = (S+ + S-) / (T+ + T-)            (bias, per axis)
    D = S+ - S- - c (T+ - T-)            (the bias cancels, also for unequal T±)
    D / (Θ+ - Θ-) = (I + K_g) a          (K_g: diag = gyro.sf, off-diagonal = gyro.mis)

and with three or more independent axes ``I + K_g = (Σ w d aᵀ)(Σ w a aᵀ)⁻¹`` (w = (Θ+ - Θ-)²
/ samples; exactly ``D A⁻¹`` for three axes).

**Accelerometer** (bias, scale factor, misalignment). Static segments (no angle moving; not
``move-*``) whose attitude puts a plate axis within 1° of the vertical (the six ± positions,
e.g. seed_003's ``S202-01..06`` and seed_001's ``attNN``/``attNN-after``; ``static_labels``
restricts them by a regular expression). Per (axis, sign) the mean specific force f̄ and the
reference u = C_n^p [0, 0, β]; per axis k the pair difference d_k = f̄_k+ - f̄_k-,
Δu_k = u_k+ - u_k-:

    I + K_a = [d_x d_y d_z] [Δu_x Δu_y Δu_z]⁻¹,   b = mean(f̄) - (I + K_a) mean(u)

σ: white noise per sample from the static data (consecutive differences), propagated through
these linear closed forms (gyro: (N+ + N-) σ² per difference plus the encoder's count at the
four rest ends; accelerometer: σ²/N per mean).
"""
from __future__ import annotations

import re

import numpy as np

from components.model.effects import AX
from components.model.geometry import TableGeometry
from components.model.result import CalibrationResult, schedule_of
from components.procedures.common import (
    angle_quantum,
    as_data,
    is_static,
    linear_covariance,
    noise_sigma,
    sample_interval,
    segments,
)

NAME = "cwccw"
TWO_PI = 2 * np.pi


def find_rotations(data, min_turns: int = 1) -> list[dict]:
    """Whole-turn rest-to-rest rotations of one gimbal: label, samples, axis (plate), angle."""
    geo0 = TableGeometry(data.geometry.stages, data.geometry.latitude, data.geometry.height,
                         data.geometry.gravity, earth_rate=0.0)
    q = angle_quantum(data)
    out = []
    for seg in segments(data):
        if seg.start == 0 or seg.n < 3:
            continue
        a0, a1 = data.angles[seg.start - 1], data.angles[seg.stop - 1]
        d = a1 - a0
        moved = np.abs(d) > 4 * q
        if moved.sum() != 1:
            continue
        k = int(np.argmax(moved))
        turns = d[k] / TWO_PI
        if abs(turns) < min_turns - 1e-6 or abs(turns - round(turns)) * TWO_PI > 8 * q:
            continue
        if not np.all(data.angles[seg.stop - 2] == a1):  # not at rest at its end
            continue
        rate = np.zeros((1, data.angles.shape[1]))
        rate[0, k] = 1.0
        _, om, _, _ = geo0.kinematics(a0[None, :], rate)
        out.append({"label": seg.label, "segment": seg, "gimbal": data.geometry.names[k],
                    "axis": om[0] / np.linalg.norm(om[0]), "angle": float(d[k])})
    return out


def find_static_positions(data, static_labels: str | None = None, min_samples: int = 10,
                          tol_deg: float = 1.0) -> list[dict]:
    """Static segments with a plate axis within tol of the vertical: label, samples, axis, sign."""
    pat = re.compile(static_labels) if static_labels else None
    out = []
    for seg in segments(data):
        if seg.label.startswith("move-") or seg.n < min_samples:
            continue
        if pat is not None and not pat.search(seg.label):
            continue
        if not is_static(data, seg):
            continue
        C, *_ = data.geometry.kinematics(data.angles[seg.stop - 1][None, :])
        up_p = C[0].T @ np.array([0.0, 0.0, 1.0])  # the vertical in plate axes
        k = int(np.argmax(np.abs(up_p)))
        if abs(up_p[k]) < np.cos(np.radians(tol_deg)):
            continue
        out.append({"label": seg.label, "segment": seg, "axis": k, "sign": int(np.sign(up_p[k])),
                    "up_plate": up_p})
    return out


# --------------------------------------------------------------------------- gyro
def _gyro_groups(data, rotations, dt):
    """Per plate axis (rounded): sums S+, S-, T+, T-, N+, N-, angles Θ+, Θ-."""
    groups: dict[tuple, dict] = {}
    for r in rotations:
        key = tuple(np.round(r["axis"], 3))
        g = groups.setdefault(key, {"axis": r["axis"], "labels": [], "S+": np.zeros(3),
                                    "S-": np.zeros(3), **{f"{x}{s}": 0.0 for x in "TNA" for s in "+-"}})
        s = "+" if r["angle"] > 0 else "-"
        seg = r["segment"]
        g[f"S{s}"] = g[f"S{s}"] + data.gyro[seg.slice].sum(axis=0) - _earth_sum(data, seg, dt)
        g[f"T{s}"] += seg.n * dt
        g[f"N{s}"] += seg.n
        g[f"A{s}"] += r["angle"]
        g["labels"].append(r["label"])
    return [g for g in groups.values() if g["N+"] > 0 and g["N-"] > 0]


def _earth_sum(data, seg, dt) -> np.ndarray:
    """The Earth rate's integral in plate axes over a segment (nominal geometry, from the
    logged angles at the interval midpoints). Its constant part cancels in D anyway; what this
    removes is the horizontal Earth rate seen by the turning axes over the accelerating and
    settling parts, which differs between CW and CCW (~1e-6 rad per turn pair)."""
    a = data.angles[max(seg.start - 1, 0):seg.stop]
    mid = 0.5 * (a[1:] + a[:-1]) if seg.start > 0 else a
    _, om, _, _ = data.geometry.kinematics(mid)
    return om.sum(axis=0) * dt


def _gyro_solve(D: np.ndarray, dA: np.ndarray, axes: np.ndarray, w: np.ndarray) -> np.ndarray:
    """I + K_g from differences D (G, 3), angle differences dA (G,), plate axes (G, 3)."""
    d = D / dA[:, None]
    M = (w[:, None, None] * d[:, :, None] * axes[:, None, :]).sum(0)
    W = (w[:, None, None] * axes[:, :, None] * axes[:, None, :]).sum(0)
    return M @ np.linalg.inv(W)


def gyro_cwccw(data, rotations, sigma_g, q):
    dt = sample_interval(data)
    groups = _gyro_groups(data, rotations, dt)
    if not groups:
        if rotations:
            # turns in one direction only: the bias and Earth rate do not cancel, so the closed
            # form cannot be used; a silent skip would look like a calibration without gyro errors
            seen = ", ".join(f"{r['label']} ({'+' if r['angle'] > 0 else '-'}{abs(r['angle']) / TWO_PI:g} turn{'s' if abs(r['angle']) > 1.5 * TWO_PI else ''} "
                             f"about plate {np.round(r['axis'], 3).tolist()})" for r in rotations[:6])
            raise ValueError(f"the log's whole-turn rotations are one-directional ({seen}): the CW/CCW gyro part "
                             "needs turns in both directions about each axis; the general least squares "
                             "(calbench calibrate) uses one-directional turns")
        return None
    axes = np.array([g["axis"] for g in groups])
    if np.linalg.matrix_rank(axes, tol=0.1) < 3:
        raise ValueError(f"CW/CCW rotations about {len(groups)} plate axis direction(s) "
                         f"({', '.join(str(np.round(a, 3)) for a in axes)}) do not span three "
                         "dimensions: the gyro scale factors and misalignments need rotations about "
                         "three independent plate axes")
    D = np.zeros((len(groups), 3))
    nvar = np.zeros((len(groups), 3))
    dA = np.zeros(len(groups))
    for i, g in enumerate(groups):
        c = (g["S+"] + g["S-"]) / (g["T+"] + g["T-"])
        D[i] = g["S+"] - g["S-"] - c * (g["T+"] - g["T-"])
        dA[i] = g["A+"] - g["A-"]
        nvar[i] = (g["N+"] + g["N-"]) * np.nan_to_num(sigma_g) ** 2 + 4 * q**2 / 12
    w = dA**2 / nvar.sum(1).clip(1e-300)
    w = w / w.max()

    def params(Dflat):
        K = _gyro_solve(Dflat.reshape(D.shape), dA, axes, w) - np.eye(3)
        return _sf_mis_vector(K)

    value = params(D.ravel())
    cov = linear_covariance(params, D.ravel(), nvar.ravel())
    return value, cov, [l for g in groups for l in g["labels"]]


def _sf_mis_vector(K: np.ndarray) -> np.ndarray:
    return np.array([K[i, i] for i in range(3)] + [K[AX.index(ij[0]), AX.index(ij[1])]
                                                   for ij in ("xy", "xz", "yx", "yz", "zx", "zy")])


def _sf_mis_names(sensor: str) -> list[str]:
    return [f"{sensor}.sf.{i}" for i in AX] + [f"{sensor}.mis.{ij}" for ij in
                                               ("xy", "xz", "yx", "yz", "zx", "zy")]


# --------------------------------------------------------------------------- accelerometer
def acc_plus_minus(data, positions, sigma_a, beta: float):
    dt = sample_interval(data)
    groups: dict[tuple, dict] = {}
    for p in positions:
        g = groups.setdefault((p["axis"], p["sign"]), {"sum": np.zeros(3), "n": 0, "u": np.zeros(3),
                                                       "labels": []})
        seg = p["segment"]
        g["sum"] += data.acc[seg.slice].sum(axis=0)
        g["u"] += seg.n * beta * p["up_plate"]
        g["n"] += seg.n
        g["labels"].append(p["label"])
    missing = [f"{'+' if s > 0 else '-'}{AX[k]}" for k in range(3) for s in (1, -1) if (k, s) not in groups]
    if missing:
        raise ValueError(f"the ± static positions lack {', '.join(missing)} up (found static segments "
                         f"{', '.join(sorted({str(lab) for g in groups.values() for lab in g['labels']}))})")
    keys = [(k, s) for k in range(3) for s in (1, -1)]
    fbar = np.array([groups[k]["sum"] / (groups[k]["n"] * dt) for k in keys])   # (6, 3)
    u = np.array([groups[k]["u"] / groups[k]["n"] for k in keys])                # (6, 3)
    var = np.array([np.nan_to_num(sigma_a) ** 2 / (groups[k]["n"] * dt**2) for k in keys])

    def solve(f):
        """(b, K) of the closed form from the six groups' mean specific forces f (6, 3)."""
        d = np.array([f[2 * k] - f[2 * k + 1] for k in range(3)]).T      # columns d_k
        du = np.array([u[2 * k] - u[2 * k + 1] for k in range(3)]).T
        Kp = d @ np.linalg.inv(du)
        return f.mean(0) - Kp @ u.mean(0), Kp

    def params(fflat):
        b, Kp = solve(fflat.reshape(6, 3))
        return np.concatenate([b, _sf_mis_vector(Kp - np.eye(3))])

    value = params(fbar.ravel())
    cov = linear_covariance(params, fbar.ravel(), var.ravel())
    # the check of the closed form: each ± pair's mean is b + K ū_pair, and b is taken from the
    # three together, so 6 numbers are left to test it (a tilted base or a table error the closed
    # form does not model shows here, not in its σ)
    b, Kp = solve(fbar)
    r = np.array([(fbar[2 * k] + fbar[2 * k + 1]) / 2 - Kp @ ((u[2 * k] + u[2 * k + 1]) / 2) - b for k in range(3)])
    v = np.array([(var[2 * k] + var[2 * k + 1]) / 4 for k in range(3)])
    pairs = (float(np.sum(r**2 / np.where(v > 0, v, np.inf))), 6)
    return value, cov, [l for k in keys for l in groups[k]["labels"]], pairs


# --------------------------------------------------------------------------- procedure
def run(log_or_data, *, beta: float | None = None, static_labels: str | None = None,
        gyro: bool = True, acc: bool = True) -> CalibrationResult:
    """Gyro scale factors + misalignments from CW/CCW whole turns, accelerometer bias, scale
    factors + misalignments from ± static positions. ``beta``: the scale acceleration [m/s²]
    (default: the log's gravity); ``static_labels``: a regular expression the static segments'
    labels must match (default: every axis-aligned static segment)."""
    data, log = as_data(log_or_data)
    sigma_g, sigma_a = noise_sigma(data)
    beta = float(beta) if beta else data.geometry.g
    names, values, blocks, used = [], [], [], {}
    effects = []
    notes = []
    if gyro:
        rot = find_rotations(data)
        out = gyro_cwccw(data, rot, sigma_g, angle_quantum(data))
        if out is None:
            notes.append("gyro part not run: the log has no whole-turn rotation from rest to rest")
        if out is not None:
            v, c, labels = out
            names += _sf_mis_names("gyro")
            values.append(v)
            blocks.append(c)
            effects += ["gyro.sf", "gyro.mis"]
            used["rotations"] = labels
    if acc:
        pos = find_static_positions(data, static_labels)
        v, c, labels, (chi2_pairs, dof_pairs) = acc_plus_minus(data, pos, sigma_a, beta)
        from components.estimation.distributions import chi2_sf

        if chi2_sf(chi2_pairs, dof_pairs) < 1e-6:
            notes.append(f"the ± static pairs do not agree on one accelerometer bias (χ² {chi2_pairs:.3g} on "
                         f"{dof_pairs} dof, p < 1e-6): the table is not level or not the closed form's (a base tilt, "
                         "a table error), and the accelerometer estimates are off by it, far beyond their σ: run "
                         "procedure tilt, or calbench calibrate with table.base_tilt")
        names += [f"acc.bias.{i}" for i in AX] + _sf_mis_names("acc")
        values.append(v)
        blocks.append(c)
        effects += ["acc.bias", "acc.sf", "acc.mis"]
        used["static"] = labels
    if not names:
        raise ValueError("no CW/CCW rotation pair and no static position found in the log")
    value = np.concatenate(values)
    cov = np.zeros((len(names), len(names)))
    i = 0
    for c in blocks:
        cov[i:i + len(c), i:i + len(c)] = c
        i += len(c)
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sig, sig)
    dt = sample_interval(data)
    res = CalibrationResult(
        effects=effects, values=dict(zip(names, map(float, value))),
        sigmas=dict(zip(names, map(float, sig))), correlation=corr,
        noise={"model": "white noise per sample (estimated from static data)", "sample_interval_s": dt,
               "gyro_sigma_rad": [float(x) for x in sigma_g], "acc_sigma_mps": [float(x) for x in sigma_a]},
        fit={"estimator": "closed form: CW/CCW difference over the commanded angle; ± static pair "
                          "differences", "scale_acceleration_mps2": beta},
        schedule=schedule_of(data.time, data.segment),
        data={"samples": int(len(data.time)), **({"log": str(log.source)} if log is not None and log.source else {})},
        method="procedure:cwccw (seed 003 S201/S202, seed 001 steps 2-4, 7)",
        extra={"segments_used": used, **({"notes": notes} if notes else {})})
    return res
