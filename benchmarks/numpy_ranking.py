"""The baseline of issue #18 item 2: a plain vectorised numpy ranking of missing effects, written
here without calbench's code, to time calbench's diagnose against on the same file.

What it does — the static part of calbench's test, nothing more:
- reads the Parquet log with pyarrow (time, gimbal angles, gyro, accelerometer, temperature);
- the rests: samples whose gimbal angles equal the previous sample's; 1 s block sums within
  each rest (np.add.reduceat);
- the ideal output per block from the log's table axes (C_plate^base = R(a1,θ1) R(a2,θ2)
  R(a3,θ3), base ENU), WGS-84 normal gravity and Earth rate at the log's latitude;
- the baseline per sensor axis: bias + the 3x3 scale-factor/misalignment matrix for the
  accelerometers (12 parameters, as calbench's default model), bias alone for the gyros (at
  rest they see only Earth rate: their scale factors need the rotations, which this baseline
  does not model);
- each candidate effect (per axis: acc k2, k3, scale-factor asymmetry, temperature, scale factor
  × temperature, linear drift; gyro temperature and drift) added in turn: the likelihood-ratio
  statistic Σ_axes ΔRSS / σ² against χ²(3), σ² from the baseline's residual; Holm at family
  α = 0.01; the verdict the first that passes.

    python benchmarks/numpy_ranking.py LOG.parquet        (prints the ranking and the verdict)
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


def gravity(lat: float, h: float) -> float:
    """Somigliana's normal gravity with the second-order free-air correction."""
    b = A_WGS84 * (1 - F_WGS84)
    e2 = 1 - (b / A_WGS84) ** 2
    k = (b * GP) / (A_WGS84 * GE) - 1
    s2 = np.sin(lat) ** 2
    g0 = GE * (1 + k * s2) / np.sqrt(1 - e2 * s2)
    m = OMEGA**2 * A_WGS84**2 * b / 3.986004418e14
    return g0 * (1 - 2 / A_WGS84 * (1 + F_WGS84 + m - 2 * F_WGS84 * s2) * h + 3 * h**2 / A_WGS84**2)


def rotation(axis, theta: np.ndarray) -> np.ndarray:
    """(n, 3, 3) active right-handed rotations by *theta* about the unit *axis* (Rodrigues)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def rank(path: str | Path) -> dict:
    import pyarrow.parquet as pq

    path = Path(path)
    meta = json.loads(path.with_suffix(".json").read_text())
    axes = [(a["name"], a["axis"]) for a in meta["table"]["axes"]]
    cols = ["time"] + [f"gimbal_{n}" for n, _ in axes] + [f"{s}_{c}" for s in ("gyro", "acc") for c in "xyz"]
    table = pq.read_table(path, columns=cols + ["temperature"])
    t = table.column("time").to_numpy()
    ang = np.column_stack([table.column(f"gimbal_{n}").to_numpy() for n, _ in axes])
    gyro = np.column_stack([table.column(f"gyro_{c}").to_numpy() for c in "xyz"])
    acc = np.column_stack([table.column(f"acc_{c}").to_numpy() for c in "xyz"])
    temp = table.column("temperature").to_numpy()
    del table
    dt = float(np.median(np.diff(t)))
    spb = max(1, int(round(1.0 / dt)))

    # rests and 1 s blocks within them
    static = np.concatenate([[False], np.all(ang[1:] == ang[:-1], axis=1)])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], static.astype(np.int8), [0]])))
    starts, stops = [], []
    for a, b in zip(edges[0::2], edges[1::2]):
        k = (b - a) // spb
        starts.append(a + spb * np.arange(k))
    starts = np.concatenate(starts)
    stops = starts + spb
    idx = np.empty(2 * len(starts), int)
    idx[0::2], idx[1::2] = starts, stops
    padded = lambda x: np.concatenate([x, np.zeros((1,) + x.shape[1:])])  # noqa: E731
    yg = np.add.reduceat(padded(gyro), idx, axis=0)[0::2]
    ya = np.add.reduceat(padded(acc), idx, axis=0)[0::2]
    T = np.add.reduceat(padded(temp), idx)[0::2] / spb
    tm = t[starts + spb // 2]
    n_dt = spb * dt

    # ideal output per block
    C = np.broadcast_to(np.eye(3), (len(starts), 3, 3))
    for j, (_, axis) in enumerate(axes):
        C = C @ rotation(axis, ang[starts, j])
    lat, h = np.radians(meta["site"]["latitude_deg"]), meta["site"]["height_m"]
    g = meta["site"].get("gravity_mps2") or gravity(lat, h)
    f = np.einsum("nji,j->ni", C, np.array([0.0, 0.0, g]))            # C^T f_base
    w = np.einsum("nji,j->ni", C, OMEGA * np.array([0.0, np.cos(lat), np.sin(lat)]))

    T0, t0 = T[0], tm[0]
    one = np.ones(len(starts))
    base = {"acc": lambda i: np.column_stack([one, f]), "gyro": lambda i: one[:, None]}
    ideal = {"acc": f, "gyro": w}
    meas = {"acc": ya / n_dt, "gyro": yg / n_dt}
    candidates = {
        "acc.k2": ("acc", lambda i: f[:, i] ** 2), "acc.k3": ("acc", lambda i: f[:, i] ** 3),
        "acc.sf_asym": ("acc", lambda i: np.abs(f[:, i])), "acc.temp": ("acc", lambda i: T - T0),
        "acc.sf_temp": ("acc", lambda i: f[:, i] * (T - T0)), "acc.drift": ("acc", lambda i: tm - t0),
        "gyro.temp": ("gyro", lambda i: T - T0), "gyro.drift": ("gyro", lambda i: tm - t0),
    }

    def rss(y, X):
        beta, *_ = np.linalg.lstsq(X, y, rcond=None)
        r = y - X @ beta
        return float(r @ r)

    from scipy import stats

    sigma2, rss0 = {}, {}
    for s in ("acc", "gyro"):
        for i in range(3):
            y = meas[s][:, i] - ideal[s][:, i]
            X = base[s](i)
            rss0[s, i] = rss(y, X)
            sigma2[s, i] = rss0[s, i] / (len(y) - X.shape[1])
    out = []
    for name, (s, col) in candidates.items():
        stat = sum((rss0[s, i] - rss(meas[s][:, i] - ideal[s][:, i], np.column_stack([base[s](i), col(i)])))
                   / sigma2[s, i] for i in range(3))
        out.append((name, float(stat), float(stats.chi2.sf(stat, 3))))
    out.sort(key=lambda r: r[2])
    m = len(out)
    verdict = None
    for k, (name, _, p) in enumerate(out):  # Holm
        if p * (m - k) >= ALPHA:
            break
        verdict = verdict or name
    return {"blocks": int(len(starts)), "ranking": out, "verdict": verdict}


if __name__ == "__main__":
    r = rank(sys.argv[1])
    print(f"{r['blocks']} static blocks")
    for name, stat, p in r["ranking"]:
        print(f"  {name:12s} LR {stat:12.1f}  p {p:.3g}")
    print(f"verdict: {r['verdict']}")
