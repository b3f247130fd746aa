"""Stick-slip (Karnopp) friction of the turntable FMU: after an index the axes stick (rate
exactly 0, true angle constant to the bit), the encoder reads the command, the table breaks away
again when commanded, and a dwell is a pure Earth-rate input for the gyro. References are
computed here (scipy rotations), never taken from the FMU."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from support import Slave

AXES = ("outer", "middle", "inner")
AXIS_VEC = {"outer": (0, 0, 1), "middle": (1, 0, 0), "inner": (0, 0, 1)}
DEG = math.pi / 180
OMEGA_E = 7.2921151467e-5
LAT = 39.9 * DEG
H = 0.005
Q = 2 * math.pi / 2 ** 24
TRUTH = [f"{a}.{v}" for a in AXES for v in ("angle_true", "rate", "angle")]


def c_pn(angles) -> np.ndarray:
    C = np.eye(3)
    for a, th in zip(AXES, angles):
        C = C @ Rotation.from_rotvec(np.array(AXIS_VEC[a], float) * th).as_matrix()
    return C


def w_ie_p(angles) -> np.ndarray:
    return c_pn(angles).T @ np.array([0.0, OMEGA_E * math.cos(LAT), OMEGA_E * math.sin(LAT)])


def _settle_time(rows: np.ndarray, target: float) -> float:
    off = np.nonzero(np.abs(rows - target) > Q)[0]
    return (off[-1] + 1) * H if len(off) else 0.0


def _dwell(s: Slave, seconds: float):
    """Step through a dwell; return the truth rows [n, 9] and plate.omega rows [n, 3]."""
    rows, omega = [], []
    for _ in range(int(round(seconds / H))):
        s.step(H)
        rows.append(s.get(*TRUTH))
        omega.append(s.get("plate.omega.x", "plate.omega.y", "plate.omega.z"))
    return np.array(rows), np.array(omega)


@pytest.mark.parametrize("axis,target", [("outer", 90 * DEG), ("middle", -90 * DEG),
                                         ("inner", 180 * DEG)])
def test_index_then_dwell_is_exactly_static(turntable_fmu, axis, target):
    """Position mode: index, 2 s later a 10 s dwell. Every axis: rate exactly 0 and the true
    angle bit-identical over the whole dwell; the encoder reads the command exactly;
    plate.omega is C_n^p omega_ie of the (true) angles to 1e-15 relative."""
    s = Slave(turntable_fmu, {f"{axis}.angle_cmd": target})
    try:
        enc = []
        for _ in range(400):
            s.step(H)
            enc.append(s.get(f"{axis}.angle")[0])
        assert _settle_time(np.array(enc), target) <= 1.9  # 90 deg: 1.34 s; 180 deg: 1.85 s
        rows, omega = _dwell(s, 10.0)
        assert np.all(rows[:, 1::3] == 0.0)                  # rates
        assert np.all(rows[:, 0::3] == rows[0, 0::3])        # true angles, to the bit
        k = AXES.index(axis)
        assert np.all(rows[:, 3 * k + 2] == target)          # encoder == command
        assert abs(rows[0, 3 * k] - target) <= 0.5 * Q
        want = w_ie_p(rows[0, 0::3])
        assert np.all(np.abs(omega - want).max(axis=1) <= 1e-15 * np.linalg.norm(want))
    finally:
        s.close()


def test_rate_mode_stop_then_dwell_is_exactly_static(turntable_fmu):
    """Rate mode: spin the inner axis at 30 deg/s for 2 s, command rate 0; after 2 s the axis
    holds its reference (on the count nearest it) with rate exactly 0 for a 10 s dwell."""
    s = Slave(turntable_fmu, {})
    try:
        s.set({"inner.mode": 1, "inner.rate_cmd": 30 * DEG})
        for _ in range(400):
            s.step(H)
        s.set({"inner.rate_cmd": 0.0})
        for _ in range(400):
            s.step(H)
        ref = s.get("inner.angle_ref")[0]
        rows, _ = _dwell(s, 10.0)
        assert np.all(rows[:, 1::3] == 0.0)
        assert np.all(rows[:, 0::3] == rows[0, 0::3])
        assert np.all(np.abs(rows[:, 8] - ref) <= 0.5 * Q)   # the count nearest the reference
        assert abs(rows[0, 6] - 60 * DEG) < 1 * DEG          # it did turn (2 s at 30 deg/s)
    finally:
        s.close()


@pytest.mark.parametrize("stiction", [0.0, 0.45])
def test_breaks_away_and_indexes_as_before(turntable_fmu, stiction):
    """From a stuck dwell the middle axis breaks away when commanded (static friction exceeded)
    and settles to within a count in the bang-bang time 2 sqrt(pi/2 / acc_max) = 1.34 s + 10 ms
    (before stick-slip friction: 1.34 s), also with a static friction 1.5x the Coulomb torque."""
    s = Slave(turntable_fmu, {"middle.static_friction": stiction})
    try:
        rows, _ = _dwell(s, 1.0)
        assert np.all(rows[:, 1::3] == 0.0)
        s.set({"middle.angle_cmd": 90 * DEG})
        enc, rate = [], []
        for _ in range(600):
            s.step(H)
            enc.append(s.get("middle.angle")[0])
            rate.append(s.get("middle.rate")[0])
        assert rate[0] != 0.0                                # broke away at once
        t = _settle_time(np.array(enc), 90 * DEG)
        assert abs(t - 1.34) <= 0.01, t
        assert np.all(np.array(rate[-100:]) == 0.0)          # and sticks again
    finally:
        s.close()


def test_imu_in_a_dwell_sees_only_earth_rate(turntable_fmu, imu_fmu):
    """Turntable -> builtin IMU (ideal, noise off, integrals coupled), a 10 s dwell after an
    index of the outer and middle axes: the gyro increments sum to omega_ie^p * 10 s."""
    table = Slave(turntable_fmu, {"outer.angle_cmd": 90 * DEG, "middle.angle_cmd": 90 * DEG},
                  name="table")
    imu = Slave(imu_fmu, {"input_integrals": 1}, name="imu", initialize=False)
    src = [f"plate.{n}.{c}" for n in ("omega", "f", "alpha", "omega_int", "f_int") for c in "xyz"]
    src_vr = [table.vr(n) for n in src]
    dst_vr = [imu.vr(n.split(".", 1)[1]) for n in src]
    gvr = [imu.vr(f"gyro.{c}") for c in "xyz"]
    try:
        imu.fmu.setReal(dst_vr, table.fmu.getReal(src_vr))
        imu.fmu.exitInitializationMode()
        total, angles = np.zeros(3), None
        for k in range(600 + 2000):
            table.step(H)
            imu.fmu.setReal(dst_vr, table.fmu.getReal(src_vr))
            imu.step(H)
            if k == 600:  # 3 s: the dwell starts
                angles = table.get(*[f"{a}.angle_true" for a in AXES])
            if k >= 600:
                total += np.array(imu.fmu.getReal(gvr))
        assert np.all(table.get(*[f"{a}.angle_true" for a in AXES]) == angles)
        want = w_ie_p(angles) * 2000 * H
        assert np.linalg.norm(total - want) <= 1e-12 * np.linalg.norm(want), total - want
    finally:
        table.close()
        imu.close()
