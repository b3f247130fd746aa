"""The effect vocabulary (architecture.md §5), defined once.

An effect has a name (``acc.k2``), parameter indices (``x y z``), the SI unit of its parameters,
a typical navigation-grade magnitude, the place it lives (the IMU sensor model or the table
geometry) and, for sensor effects, its regressor: the contribution of one unit of the parameter
to each sample's output increment given the motion. The IMU FMU's parameter names, the
estimators' state vectors, the diagnosis candidates and the report lines all come from here.

Sensor model on axis i (the same as the IMU FMU, fmus/imu/model.c): with x = omega (gyro) or the
specific force at accelerometer i (acc), dT = T - T0 and s the time since the start,

    y_i = (1 + sf_i + sf_temp_i dT) x_i + sf_asym_i |x_i| + sum_j mis_ij x_j + bias_i
          + temp_i dT + drift_i s   (+ gyro: gsens_ij f_j + g2sens_i,jk f_j f_k;
                                       acc: k2_i x_i^2 + k3_i x_i^3 + cross_ij x_i x_j)

with x seen at the sample's time shifted by imu.time_offset (both sensors) and, for the
accelerometers, by acc.time_offset more (the gyro-accelerometer asynchrony; first order: the
increment gains τ (x(t) − x(t − h))).

to first order in the parameters (the FMU's products of two small parameters are below 1e-9 of
the signal). Table effects change the motion itself and are fitted through the geometry.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from components.model.motion import lever_acceleration

AX = "xyz"
OFF_DIAG = ("xy", "xz", "yx", "yz", "zx", "zy")
PAIRS = ("xx", "yy", "zz", "xy", "xz", "yz")
G0 = 9.80665
DEG = math.pi / 180
ARCSEC = DEG / 3600
DEG_H = DEG / 3600
UG = 1e-6 * G0


@dataclass(frozen=True)
class Effect:
    name: str
    indices: tuple[str, ...]
    unit: str
    typical: float  # navigation-grade magnitude, SI
    target: str  # "gyro", "acc", "imu" (both sensors) or "table"
    description: str
    signature: str  # what it leaves in the residuals
    display: tuple[str, float] = ("", 1.0)  # (readable unit, SI per readable unit)
    regressor: Callable | None = field(default=None, compare=False, repr=False)

    @property
    def parameters(self) -> list[str]:
        return [f"{self.name}.{i}" if i else self.name for i in self.indices]


# ----------------------------------------------------------------- regressors
# Each takes the motion (components.model.motion.Motion) and an index and returns (gyro, acc): arrays
# (N, 3) of increments per unit parameter, or None for a sensor it does not touch.

def _e(i: str, col: np.ndarray) -> np.ndarray:
    out = np.zeros((col.shape[0], 3))
    out[:, AX.index(i)] = col
    return out


def _integral(m, values_q: np.ndarray) -> np.ndarray:
    """∫ over each sample interval from quadrature-node values (N, Q) -> (N,)."""
    return m.dt * (values_q @ m.weights)


def _bias(sensor):
    return lambda m, i: _place(sensor, _e(i, m.dt))


def _place(sensor, col):
    return (col, None) if sensor == "gyro" else (None, col)


def _signal(m, sensor, i):
    """Node values (N, Q) of the input of axis i of the sensor (omega_i, or f at accelerometer i)."""
    k = AX.index(i)
    return m.omega_q[:, :, k] if sensor == "gyro" else m.f_at(i)[:, :, k]


def _signal_j(m, sensor, i, j):
    """Component j of the input seen by axis i (for acc: at accelerometer i's location)."""
    k = AX.index(j)
    return m.omega_q[:, :, k] if sensor == "gyro" else m.f_at(i)[:, :, k]


def _sf(sensor):
    return lambda m, i: _place(sensor, _e(i, _integral(m, _signal(m, sensor, i))))


def _asym(sensor):
    return lambda m, i: _place(sensor, _e(i, _integral(m, np.abs(_signal(m, sensor, i)))))


def _mis(sensor):
    return lambda m, ij: _place(sensor, _e(ij[0], _integral(m, _signal_j(m, sensor, ij[0], ij[1]))))


def _temp(sensor):
    return lambda m, i: _place(sensor, _e(i, _integral(m, m.dtemp_q)))


def _sf_temp(sensor):
    return lambda m, i: _place(sensor, _e(i, _integral(m, m.dtemp_q * _signal(m, sensor, i))))


def _drift(sensor):
    return lambda m, i: _place(sensor, _e(i, _integral(m, m.elapsed_q)))


def _gsens(m, ij):
    return _e(ij[0], _integral(m, m.f_q[:, :, AX.index(ij[1])])), None


def _g2sens(m, idx):
    i, jk = idx.split(".")
    f = m.f_q
    return _e(i, _integral(m, f[:, :, AX.index(jk[0])] * f[:, :, AX.index(jk[1])])), None


def _k2(m, i):
    return None, _e(i, _integral(m, _signal(m, "acc", i) ** 2))


def _k3(m, i):
    f = _signal(m, "acc", i)
    return None, _e(i, _integral(m, f * f * f))


def _cross(m, ij):
    i, j = ij
    return None, _e(i, _integral(m, _signal(m, "acc", i) * _signal_j(m, "acc", i, j)))


def _lever(m, idx):
    # component i of lever_acceleration(ω, α, e_k) = α × e_k + ω (ω_k) − e_k |ω|², written out:
    # the other two components of the (N, Q, 3) product are never used
    i, k = (AX.index(x) for x in idx.split("."))
    om, al = m.omega_q, m.alpha_q
    extra = om[:, :, i] * om[:, :, k]
    if i == k:
        extra = extra - np.einsum("nqj,nqj->nq", om, om)
    elif k == (i + 2) % 3:
        extra = extra + al[:, :, (i + 1) % 3]
    else:
        extra = extra - al[:, :, (i + 2) % 3]
    return None, _e(AX[i], _integral(m, extra))


def _time_offset(m, _):
    # d/d(delta) of the increment over (t - h + delta, t + delta]: signal(t) - signal(t - h)
    return m.omega_end - m.omega_start, m.f_end - m.f_start


def _acc_time_offset(m, _):
    # the same for the accelerometers alone, shifted against the gyros
    return None, m.f_end - m.f_start


# the parameters that shift the accelerometers' samples in time: each multiplies the lever-arm
# terms too (time_offset_of_lever), a product the least squares linearises
TIME_OFFSETS = ("imu.time_offset", "acc.time_offset")


def time_offset_of_lever(m, idx: str) -> np.ndarray:
    """(N, 3) accelerometer column of the product time offset × ``acc.lever.idx``: the
    derivative by the time shift of that parameter's unit lever-arm term, its value at the
    interval's end minus at its start. The time-offset regressor alone shifts the specific force
    at the plate's reference point; 10 cm off the centre the tangential term α × r that starts
    and stops every index is as large as the gravity turning through the axes, and leaving its
    shift out biased the fitted offset by 27 µs per ms of offset (noise-free, seed 003's
    S201+S202). A model fitting both linearises the product (components.estimation.lsq)."""
    i, k = idx.split(".")
    r = np.zeros(3)
    r[AX.index(k)] = 1.0
    change = (lever_acceleration(m.omega_end, m.alpha_end, r)
              - lever_acceleration(m.omega_start, m.alpha_at_start(), r))
    return _e(i, change[:, AX.index(i)])


def _vec(name, unit, typical, target, description, signature, display, reg):
    return Effect(name, tuple(AX), unit, typical, target, description, signature, display, reg)


EFFECTS: dict[str, Effect] = {e.name: e for e in [
    _vec("gyro.bias", "rad/s", 0.005 * DEG_H, "gyro", "gyro bias",
         "constant offset, independent of attitude and rate", ("deg/h", DEG_H), _bias("gyro")),
    _vec("gyro.sf", "1", 5e-6, "gyro", "gyro scale-factor error", "∝ rate; cancels in ±rate sums",
         ("ppm", 1e-6), _sf("gyro")),
    _vec("gyro.sf_asym", "1", 2e-6, "gyro", "gyro scale-factor asymmetry", "∝ |rate|",
         ("ppm", 1e-6), _asym("gyro")),
    Effect("gyro.mis", OFF_DIAG, "1", 20 * ARCSEC, "gyro", "gyro misalignment (axis i to rate j)",
           "cross-axis output ∝ rate on another axis", ("arcsec", ARCSEC), _mis("gyro")),
    Effect("gyro.gsens", tuple(i + j for i in AX for j in AX), "rad.s/m", 0.001 * DEG_H / G0,
           "gyro", "gyro g-sensitivity (axis i per f_j)", "attitude-dependent offset ∝ f",
           ("deg/h/g", DEG_H / G0), _gsens),
    Effect("gyro.g2sens", tuple(f"{i}.{jk}" for i in AX for jk in PAIRS), "rad.s3/m2",
           1e-4 * DEG_H / G0**2, "gyro", "gyro g²-sensitivity (axis i per f_j f_k)", "∝ f²",
           ("deg/h/g2", DEG_H / G0**2), _g2sens),
    _vec("gyro.temp", "rad/s/K", 0.001 * DEG_H, "gyro", "gyro bias temperature coefficient",
         "offset following temperature", ("deg/h/K", DEG_H), _temp("gyro")),
    _vec("gyro.sf_temp", "1/K", 1e-6, "gyro", "gyro scale-factor temperature coefficient",
         "∝ rate × (T − T0)", ("ppm/K", 1e-6), _sf_temp("gyro")),
    _vec("gyro.drift", "rad/s/s", 0.001 * DEG_H / 3600, "gyro", "gyro linear bias drift",
         "slow trend over the run", ("deg/h/h", DEG_H / 3600), _drift("gyro")),
    _vec("acc.bias", "m/s2", 50 * UG, "acc", "accelerometer bias", "constant offset",
         ("ug", UG), _bias("acc")),
    _vec("acc.sf", "1", 30e-6, "acc", "accelerometer scale-factor error", "∝ f_i; ±1 g difference",
         ("ppm", 1e-6), _sf("acc")),
    _vec("acc.sf_asym", "1", 10e-6, "acc", "accelerometer scale-factor asymmetry", "∝ |f_i|",
         ("ppm", 1e-6), _asym("acc")),
    Effect("acc.mis", OFF_DIAG, "1", 20 * ARCSEC, "acc", "accelerometer misalignment (axis i to f_j)",
           "cross-axis output ∝ f_j", ("arcsec", ARCSEC), _mis("acc")),
    _vec("acc.k2", "s2/m", 20 * UG / G0**2, "acc", "accelerometer second-order nonlinearity",
         "∝ f_i², same sign at ±1 g", ("ug/g2", UG / G0**2), _k2),
    _vec("acc.k3", "s4/m2", 1 * UG / G0**3, "acc", "accelerometer third-order nonlinearity",
         "∝ f_i³", ("ug/g3", UG / G0**3), _k3),
    Effect("acc.cross", OFF_DIAG, "s2/m", 10 * UG / G0**2, "acc",
           "accelerometer cross-coupling (axis i per f_i f_j)", "∝ f_i f_j, at 45° attitudes",
           ("ug/g2", UG / G0**2), _cross),
    Effect("acc.lever", tuple(f"{i}.{k}" for i in AX for k in AX), "m", 0.02, "acc",
           "size effect: k component of accelerometer i's offset",
           "∝ ω² during constant-rate rotation, ∝ ω̇ at start/stop", ("mm", 1e-3), _lever),
    _vec("acc.temp", "m/s2/K", 5 * UG, "acc", "accelerometer bias temperature coefficient",
         "offset following temperature", ("ug/K", UG), _temp("acc")),
    _vec("acc.sf_temp", "1/K", 1e-6, "acc", "accelerometer scale-factor temperature coefficient",
         "∝ f_i × (T − T0)", ("ppm/K", 1e-6), _sf_temp("acc")),
    _vec("acc.drift", "m/s2/s", 1 * UG / 3600, "acc", "accelerometer linear bias drift",
         "slow trend over the run", ("ug/h", UG / 3600), _drift("acc")),
    Effect("imu.time_offset", ("",), "s", 1e-3, "imu", "IMU sample time late relative to the table",
           "∝ ω̇ (gyro), ∝ df/dt at indexing", ("ms", 1e-3), _time_offset),
    Effect("acc.time_offset", ("",), "s", 1e-4, "acc",
           "accelerometer samples late relative to the gyros (gyro-accelerometer asynchrony, PSINS's tGA)",
           "accelerometer residuals ∝ df/dt at the starts and ends of moves, none at rest, none in the gyros",
           ("ms", 1e-3), _acc_time_offset),
    Effect("table.base_tilt", ("x", "y"), "rad", 10 * ARCSEC, "table",
           "base rotation about east (x) / north (y) from level",
           "gravity leaks into horizontal axes; attitude-dependent offsets", ("arcsec", ARCSEC)),
    Effect("table.base_azimuth", ("",), "rad", 60 * ARCSEC, "table",
           "base rotation about up from the log's frame (x east): where the outer axis's zero points",
           "the Earth's rate turned in the horizontal: gyro residuals that turn with the outer angle, "
           "none in the accelerometers", ("arcmin", 60 * ARCSEC)),
    Effect("table.nonorth", tuple(f"{a}.{c}" for a in ("middle", "inner") for c in "uv"), "rad",
           5 * ARCSEC, "table", "non-orthogonality: rotation of a stage axis about its u / v",
           "cross terms a model attributes to IMU misalignment", ("arcsec", ARCSEC)),
    Effect("table.wobble", tuple(f"{a}.{c}" for a in ("outer", "middle", "inner") for c in "cs"),
           "rad", 3 * ARCSEC, "table", "first-harmonic axis tilt (A cos φ, A sin φ)",
           "error periodic in the axis angle", ("arcsec", ARCSEC)),
    Effect("table.encoder", tuple(f"{a}.{c}" for a in ("outer", "middle", "inner")
                                  for c in ("s1", "c1", "s2", "c2")),
           "rad", 2 * ARCSEC, "table", "encoder harmonic error (sin/cos of 1st and 2nd harmonic)",
           "error periodic in the axis angle", ("arcsec", ARCSEC)),
    Effect("table.reversal", ("outer", "middle", "inner"), "rad", 1 * ARCSEC, "table",
           "reversal error (ISO 230-2): at rest the plate is half of it past the reading, on the "
           "side the stage last moved to (backlash, a servo that stops past the count)",
           "gyro integral of a move that turns back off by the reversal, none when it goes on; "
           "rests apart by the side they were reached from", ("arcsec", ARCSEC)),
]}

DEFAULT_EFFECTS = ("gyro.bias", "gyro.sf", "gyro.mis", "acc.bias", "acc.sf", "acc.mis")


def effect_of(parameter: str) -> Effect:
    """The effect a parameter name belongs to (``acc.lever.x.y`` -> ``acc.lever``)."""
    parts = parameter.split(".")
    for n in range(len(parts), 0, -1):
        e = EFFECTS.get(".".join(parts[:n]))
        if e is not None and parameter in e.parameters:
            return e
    raise KeyError(f"{parameter!r} is not a parameter of any effect of the vocabulary")


def parse_effects(spec: str | list[str] | tuple) -> list[str]:
    """A comma list (or list) of effect names -> validated effect names, in the given order."""
    names = [s.strip() for s in (spec.split(",") if isinstance(spec, str) else spec) if s.strip()]
    unknown = [n for n in names if n not in EFFECTS]
    if unknown:
        raise ValueError(f"unknown effect(s) {unknown}; the vocabulary has: {', '.join(EFFECTS)}")
    return list(dict.fromkeys(names))


def regressor_of(motion, parameter: str):
    """(gyro, acc) increments (N, 3) per unit of a sensor-effect parameter (None where it does
    not act); table effects have none (they change the motion)."""
    e = effect_of(parameter)
    if e.regressor is None:
        return None, None
    return e.regressor(motion, parameter[len(e.name) + 1:] if len(parameter) > len(e.name) else "")


def parameters_of(effects: list[str]) -> list[str]:
    return [p for e in effects for p in EFFECTS[e].parameters]
