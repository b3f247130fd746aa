"""What the closed-form procedures share: log access, segments, noise, attitudes, truth errors."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from components.estimation.blocks import white_noise_sigma
from components.estimation.log_data import LogData
from components.estimation.rest_angles import encoder_quantum
from components.model.effects import effect_of


def as_data(log_or_data) -> tuple[LogData, object]:
    """(LogData, the MeasurementLog or None) from either."""
    if isinstance(log_or_data, LogData):
        return log_or_data, None
    return LogData.from_log(log_or_data), log_or_data


@dataclass
class Segment:
    label: str
    start: int   # first sample
    stop: int    # one past the last sample

    @property
    def slice(self) -> slice:
        return slice(self.start, self.stop)

    @property
    def n(self) -> int:
        return self.stop - self.start


def segments(data: LogData) -> list[Segment]:
    """Runs of equal segment labels, in log order."""
    if data.segment is None or len(data.segment) == 0:
        return []
    return [Segment(label, a, b) for a, b, label in data.segment.runs()]


def angle_quantum(data: LogData) -> float:
    """The encoder count [rad], the smallest over the axes that move, at least 1e-12: the log's
    stated resolution, else the count every logged step is a whole number of (the estimators'
    :func:`~components.estimation.rest_angles.encoder_quantum`: a table that moves 13 counts a
    sample logs no one-count step, and the smallest step then overstated a reading's
    quantization 13-fold); for angles stated exact, the smallest logged step."""
    res = data.encoder_resolution
    if isinstance(res, str) or data.angles.shape[1] == 0:
        steps = [np.diff(np.unique(data.angles[:, k])) for k in range(data.angles.shape[1])]
        q = [float(d[d > 0].min()) for d in steps if np.any(d > 0)]
    else:
        counts = np.broadcast_to(np.asarray(res, float), (data.angles.shape[1],)) if res is not None \
            else encoder_quantum(data.angles)
        q = [float(c) for c in counts if c > 0]
    return max(min(q) if q else 0.0, 1e-12)


def is_static(data: LogData, seg: Segment, tol_counts: float = 2.0) -> bool:
    """No gimbal angle moved by more than a few counts over the segment (and the samples before
    its first one: the interval of the first sample starts at the previous sample)."""
    a = data.angles[max(seg.start - 1, 0):seg.stop]
    return bool(np.all(np.ptp(a, axis=0) <= tol_counts * angle_quantum(data) + 1e-15))


def static_mask(data: LogData) -> np.ndarray:
    """Per sample: no angle changed over its interval."""
    d = np.abs(np.diff(data.angles, axis=0, prepend=data.angles[:1]))
    return np.all(d == 0.0, axis=1)


def noise_sigma(data: LogData) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample white-noise σ of the gyro [rad] and accelerometer [m/s] increments, from the
    static data (consecutive differences; NaN where the log has no static pairs)."""
    st = static_mask(data)
    return white_noise_sigma(data.gyro, st), white_noise_sigma(data.acc, st)


def plate_attitude(data: LogData, angles, geometry=None) -> np.ndarray:
    """C_p^n (3, 3) at one set of (measured) gimbal angles through the geometry."""
    geo = geometry or data.geometry
    C, *_ = geo.kinematics(np.atleast_2d(np.asarray(angles, float)))
    return C[0]


def sample_interval(data: LogData) -> float:
    return float(data.dt0) if data.dt0 else data.sample_interval


def linear_covariance(func, x: np.ndarray, var_x: np.ndarray) -> np.ndarray:
    """Covariance of func(x) for a func linear (or nearly) in x with independent inputs of
    variances var_x: J diag(var_x) J^T with J by central differences at the σ scale."""
    x = np.asarray(x, float)
    y0 = np.asarray(func(x), float)
    J = np.zeros((y0.size, x.size))
    for k in range(x.size):
        h = np.sqrt(var_x.flat[k]) if var_x.flat[k] > 0 else 0.0
        if h == 0.0:
            continue
        xp, xm = x.copy(), x.copy()
        xp.flat[k] += h
        xm.flat[k] -= h
        J[:, k] = (np.asarray(func(xp), float).ravel() - np.asarray(func(xm), float).ravel()) / (2 * h)
    return J @ np.diag(var_x.ravel()) @ J.T


def errors_against_truth(result, truth: dict) -> list[dict]:
    """Per estimated parameter: value, truth (0 if not injected), error, σ, in display units;
    ``noise_free``: the truth injected no noise into the parameter's sensor, whose σ is then the
    numerical floor's and the error against it says nothing."""
    injected = dict(truth.get("effects", {}))
    noisy = {k.split(".")[0] for k, v in (truth.get("noise") or {}).items() if v}
    rows = []
    for p, v in result.values.items():
        e = effect_of(p)
        unit, scale = e.display
        t = injected.get(p, 0.0)
        rows.append({"parameter": p, "value": v / scale, "truth": t / scale, "error": (v - t) / scale,
                     "sigma": result.sigmas.get(p, float("nan")) / scale, "unit": unit,
                     "noise_free": "noise" in truth and e.target in ("gyro", "acc") and e.target not in noisy})
    return rows


def print_errors(rows: list[dict]) -> None:
    """The rows of :func:`errors_against_truth` with the error in σ (|error/σ| > 3 marked: more
    than noise explains, one time in 370 for a consistent estimate)."""
    print(f"{'parameter':22s} {'estimate':>13s} {'truth':>13s} {'error':>12s} {'sigma':>10s} {'err/sigma':>9s}  unit")
    for r in rows:
        z = r["error"] / r["sigma"] if r["sigma"] and r["sigma"] == r["sigma"] else float("nan")
        flag = ("  noise-free sensor: no noise was injected, σ is the numerical floor's" if r.get("noise_free")
                else "  OFF BY MORE THAN 3 SIGMA" if abs(z) > 3 else "")
        print(f"{r['parameter']:22s} {r['value']:+13.6g} {r['truth']:+13.6g} {r['error']:+12.4g} "
              f"{r['sigma']:10.3g} {z:+9.2f}  {r['unit']}" + flag)
