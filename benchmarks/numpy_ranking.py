"""The baseline of issue #18 item 2: a plain vectorised numpy ranking of missing effects, written
here without calbench's code, to time calbench's diagnose against on the same file.

What it does — calbench's test on the candidates below, nothing more:
- reads the Parquet log with pyarrow (time, gimbal angles, gyro, accelerometer, temperature;
  increments, or pulse counts times their weight);
- the rows: 1 s block sums within each rest (np.add.reduceat) and, with ``moves=True`` (the
  default), one row per move from rest to rest; each row divided by the square root of its
  sample count (white noise per sample);
- the ideal increments: at rest from the log's table axes (C_plate^base = R(a1,θ1) R(a2,θ2)
  R(a3,θ3), base ENU), WGS-84 normal gravity and Earth rate at the log's latitude; while moving,
  per sample, the rotation vector of C_{k-1}^T C_k plus Earth rate and gravity at the interval's
  mid attitude (a midpoint rule: ~1e-7 of g at the schedules' rates);
- the baseline per sensor axis, as calbench's default model: bias + the 3x3 scale-factor /
  misalignment matrix (12 parameters per sensor; with ``moves=False`` the gyros get a bias
  alone: at rest they see only Earth rate);
- each candidate effect (per axis: acc k2, k3, scale-factor asymmetry, temperature, scale factor
  × temperature, linear drift; gyro temperature and drift) added in turn: the likelihood-ratio
  statistic Σ_axes ΔRSS / σ² against χ²(3), σ² from the baseline's residual; Holm at family
  α = 0.01; the verdict the first that passes.

    python benchmarks/numpy_ranking.py LOG.parquet [--rests-only]   (prints the ranking and the verdict)
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

A_WGS84, F_WGS84 = 6378137.0, 1 / 298.257223563
GE, GP = 9.7803253359, 9.8321849378
OMEGA = 7.2921151467e-5
ALPHA = 0.01
CANDIDATES = ("acc.k2", "acc.k3", "acc.sf_asym", "acc.temp", "acc.sf_temp", "acc.drift", "gyro.temp", "gyro.drift")


def gravity(lat: float, h: float) -> float:
    """Somigliana's normal gravity with the second-order free-air correction."""
    b = A_WGS84 * (1 - F_WGS84)
    e2 = 1 - (b / A_WGS84) ** 2
    k = (b * GP) / (A_WGS84 * GE) - 1
    s2 = np.sin(lat) ** 2
    g0 = GE * (1 + k * s2) / np.sqrt(1 - e2 * s2)
    m = OMEGA**2 * A_WGS84**2 * b / 3.986004418e14
    return g0 * (1 - 2 / A_WGS84 * (1 + F_WGS84 + m - 2 * F_WGS84 * s2) * h + 3 * h**2 / A_WGS84**2)


def skew(a: np.ndarray) -> np.ndarray:
    z = np.zeros(a.shape[:-1])
    return np.stack([np.stack([z, -a[..., 2], a[..., 1]], -1), np.stack([a[..., 2], z, -a[..., 0]], -1),
                     np.stack([-a[..., 1], a[..., 0], z], -1)], -2)


def rotation(axis, theta: np.ndarray) -> np.ndarray:
    """(n, 3, 3) active right-handed rotations by *theta* about the unit *axis* (Rodrigues)."""
    a = np.broadcast_to(np.asarray(axis, float), np.shape(theta) + (3,))
    K = skew(a / np.linalg.norm(a, axis=-1, keepdims=True))
    s, c = np.sin(theta)[..., None, None], np.cos(theta)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def attitude(axes, ang: np.ndarray) -> np.ndarray:
    C = np.broadcast_to(np.eye(3), (len(ang), 3, 3))
    for j, (_, axis) in enumerate(axes):
        C = C @ rotation(axis, ang[:, j])
    return C


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """log(R) as a rotation vector (n, 3), for rotations well below π (one sample's turn)."""
    v = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1) / 2
    s = np.linalg.norm(v, axis=1)
    th = np.arctan2(s, (np.trace(R, axis1=1, axis2=2) - 1) / 2)
    return v * np.where(s > 1e-12, th / np.where(s > 1e-12, s, 1.0), 1.0)[:, None]


def rank(path: str | Path, moves: bool = True) -> dict:
    import pyarrow.parquet as pq
    from scipy.special import chdtrc

    path = Path(path)
    meta = json.loads(path.with_suffix(".json").read_text())
    axes = [(a["name"], a["axis"]) for a in meta["table"]["axes"]]
    cols = ["time"] + [f"gimbal_{n}" for n, _ in axes] + [f"{s}_{c}" for s in ("gyro", "acc") for c in "xyz"]
    table = pq.read_table(path, columns=cols + ["temperature"])
    t = table.column("time").to_numpy()
    ang = np.column_stack([table.column(f"gimbal_{n}").to_numpy() for n, _ in axes])
    meas = {"gyro": np.column_stack([table.column(f"gyro_{c}").to_numpy() for c in "xyz"]),
            "acc": np.column_stack([table.column(f"acc_{c}").to_numpy() for c in "xyz"])}
    for s, key in (("gyro", "gyro_count_rad"), ("acc", "acc_count_mps")):
        if meta["imu"][f"{s}_output"] == "counts":  # a pulse output: whole counts of a weight
            meas[s] = meas[s] * meta["imu"][key]
    temp = table.column("temperature").to_numpy()
    del table
    dt = float(np.median(np.diff(t)))
    spb = max(1, int(round(1.0 / dt)))
    lat, h = np.radians(meta["site"]["latitude_deg"]), meta["site"]["height_m"]
    g_up = np.array([0.0, 0.0, meta["site"].get("gravity_mps2") or gravity(lat, h)])
    w_ie = OMEGA * np.array([0.0, np.cos(lat), np.sin(lat)])

    # sample k's increment spans (t[k-1], t[k]]: a rest sample when the angles did not change
    static = np.concatenate([[False], np.all(ang[1:] == ang[:-1], axis=1)])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], static.astype(np.int8), [0]])))
    starts = np.concatenate([a + spb * np.arange((b - a) // spb) for a, b in zip(edges[0::2], edges[1::2])])
    n_rest = np.full(len(starts), spb)
    idx = np.empty(2 * len(starts), int)
    idx[0::2], idx[1::2] = starts, starts + spb

    def rest_sums(x):
        return np.add.reduceat(np.concatenate([x, np.zeros((1,) + x.shape[1:])]), idx, axis=0)[0::2]

    C = attitude(axes, ang[starts])
    f_rest, w_rest = C.transpose(0, 2, 1) @ g_up, C.transpose(0, 2, 1) @ w_ie
    rows = {  # per row: sums over its samples of the ideal increments and of the candidates' regressors
        "n": n_rest.astype(float), "dt": n_rest * dt,
        "meas_gyro": rest_sums(meas["gyro"]), "meas_acc": rest_sums(meas["acc"]),
        "ideal_gyro": w_rest * spb * dt, "ideal_acc": f_rest * spb * dt,
        "f2": f_rest**2 * spb * dt, "f3": f_rest**3 * spb * dt, "fabs": np.abs(f_rest) * spb * dt,
        "T": rest_sums(temp) * dt, "fT": f_rest * rest_sums(temp)[:, None] * dt,
        "t": rest_sums(t) * dt,
    }
    if moves:
        mv = ~static
        mv[0] = False
        k = np.flatnonzero(mv)
        run = np.flatnonzero(np.diff(np.concatenate([[0], mv.astype(np.int8), [0]])))
        run_len = run[1::2] - run[0::2]
        first = np.concatenate([[0], np.cumsum(run_len)[:-1]])
        C0, C1 = attitude(axes, ang[k - 1]), attitude(axes, ang[k])
        phi = rotation_vector(C0.transpose(0, 2, 1) @ C1)
        Cm_t = (C0 @ rotation(phi, np.linalg.norm(phi, axis=1) / 2)).transpose(0, 2, 1)
        dtk = (t[k] - t[k - 1])[:, None]
        f_k = Cm_t @ g_up
        T_k, t_k = temp[k][:, None], t[k][:, None]

        def move_sums(x):
            return np.add.reduceat(x, first, axis=0)

        add = {"n": run_len.astype(float), "dt": move_sums(dtk[:, 0]),
               "meas_gyro": move_sums(meas["gyro"][k]), "meas_acc": move_sums(meas["acc"][k]),
               "ideal_gyro": move_sums(phi + Cm_t @ w_ie * dtk), "ideal_acc": move_sums(f_k * dtk),
               "f2": move_sums(f_k**2 * dtk), "f3": move_sums(f_k**3 * dtk), "fabs": move_sums(np.abs(f_k) * dtk),
               "T": move_sums(T_k[:, 0] * dtk[:, 0]), "fT": move_sums(f_k * T_k * dtk), "t": move_sums(t_k[:, 0] * dtk[:, 0])}
        rows = {key: np.concatenate([rows[key], add[key]]) for key in rows}
    w = 1 / np.sqrt(rows["n"])
    T0, t0 = temp[starts[0]], t[starts[0]]
    dT, dtime = rows["T"] - T0 * rows["dt"], rows["t"] - t0 * rows["dt"]
    base = {"acc": np.column_stack([rows["dt"], rows["ideal_acc"]]),
            "gyro": np.column_stack([rows["dt"], rows["ideal_gyro"]]) if moves else rows["dt"][:, None]}
    fT = rows["fT"] - T0 * rows["ideal_acc"]
    candidates = {
        "acc.k2": ("acc", lambda i: rows["f2"][:, i]), "acc.k3": ("acc", lambda i: rows["f3"][:, i]),
        "acc.sf_asym": ("acc", lambda i: rows["fabs"][:, i]), "acc.temp": ("acc", lambda i: dT),
        "acc.sf_temp": ("acc", lambda i: fT[:, i]), "acc.drift": ("acc", lambda i: dtime),
        "gyro.temp": ("gyro", lambda i: dT), "gyro.drift": ("gyro", lambda i: dtime),
    }

    def rss(y, X):
        beta, *_ = np.linalg.lstsq(X * w[:, None], y * w, rcond=None)
        r = (y - X @ beta) * w
        return float(r @ r)

    sigma2, rss0 = {}, {}
    for s in ("acc", "gyro"):
        for i in range(3):
            y = rows[f"meas_{s}"][:, i] - rows[f"ideal_{s}"][:, i]
            rss0[s, i] = rss(y, base[s])
            sigma2[s, i] = rss0[s, i] / (len(y) - base[s].shape[1])
    out = []
    for name, (s, col) in candidates.items():
        stat = sum((rss0[s, i] - rss(rows[f"meas_{s}"][:, i] - rows[f"ideal_{s}"][:, i],
                                     np.column_stack([base[s], col(i)]))) / sigma2[s, i] for i in range(3))
        stat = max(stat, 0.0)  # a column the log cannot see (a constant temperature) gains nothing: -0
        out.append((name, float(stat), float(chdtrc(3, stat))))
    out.sort(key=lambda r: r[2])
    m = len(out)
    verdict = None
    for j, (name, _, p) in enumerate(out):  # Holm
        if p * (m - j) >= ALPHA:
            break
        verdict = verdict or name
    return {"rows": int(len(w)), "ranking": out, "verdict": verdict}


if __name__ == "__main__":
    r = rank(sys.argv[1], moves="--rests-only" not in sys.argv[2:])
    print(f"{r['rows']} block rows")
    for name, stat, p in r["ranking"]:
        print(f"  {name:12s} LR {stat:12.1f}  p {p:.3g}")
    print(f"verdict: {r['verdict']}")
