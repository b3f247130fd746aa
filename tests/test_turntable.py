"""Turntable FMU against physics computed independently here (scipy rotations, the WGS-84
normal-gravity formula, python-control's closed loop), never against numbers taken from the FMU.

Conventions under test (documented at the top of fmus/turntable/gimbal.c):
C_p^n = R(x, tilt.x) R(y, tilt.y) R(z, azimuth) * prod_k Rot(w_k) R(a_k, theta_k),
a_k = Rot(nonorth_k) normalize(axis_k), w_k = A [cos(theta+phi) u + sin(theta+phi) v]."""
from __future__ import annotations

import itertools
import math

import control
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fmus.turntable import design_servo
from fmus.turntable import variables as tv

from support import Slave

AXES = ("outer", "middle", "inner")
DEG = math.pi / 180
ARCSEC = DEG / 3600
OMEGA_E = 7.2921151467e-5
T_CTRL = 1.0 / tv.CONTROL_RATE_HZ
H = 0.005  # communication step used by most tests (10 controller ticks)


# ------------------------------------------------------------------ independent reference

def normal_gravity(lat: float, h: float) -> float:
    """WGS-84 Somigliana normal gravity with the second-order free-air correction."""
    a, f, m = 6378137.0, 1 / 298.257223563, 0.00344978650684
    s2 = math.sin(lat) ** 2
    g0 = 9.7803253359 * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 0.00669437999013 * s2)
    return g0 * (1 - 2 / a * (1 + f + m - 2 * f * s2) * h + 3 * h * h / a ** 2)


def rot(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, float)
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()


def wobble_basis(a):
    j = int(np.argmin(np.abs(a)))  # argmin returns the first index on ties: x, then y, then z
    u = np.cross(np.eye(3)[j], a)
    u /= np.linalg.norm(u)
    return u, np.cross(a, u)


def stage(axis, theta, nonorth=(0, 0, 0), amp=0.0, phase=0.0) -> np.ndarray:
    """C_k^{k-1} of one stage, built from the documented convention."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    a = Rotation.from_rotvec(np.asarray(nonorth, float)).apply(a)
    u, v = wobble_basis(a)
    w = amp * (math.cos(theta + phase) * u + math.sin(theta + phase) * v)
    return Rotation.from_rotvec(w).as_matrix() @ rot(a, theta)


def c_pn(angles, axes=None, tilt=(0.0, 0.0), azimuth=0.0, errors=None) -> np.ndarray:
    axes = axes or [tv.DEFAULT_AXIS[a] for a in AXES]
    errors = errors or [{}] * len(angles)
    C = rot([1, 0, 0], tilt[0]) @ rot([0, 1, 0], tilt[1]) @ rot([0, 0, 1], azimuth)
    for ax, th, err in zip(axes, angles, errors):
        C = C @ stage(ax, th, **err)
    return C


def earth_rate_n(lat: float) -> np.ndarray:
    return np.array([0.0, OMEGA_E * math.cos(lat), OMEGA_E * math.sin(lat)])


def plate(s: Slave, name: str) -> np.ndarray:
    comps = "wxyz" if name == "q" else "xyz"
    return s.get(*[f"plate.{name}.{c}" for c in comps])


def rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


def quat_close(q_fmu, C, tol=1e-12):
    x, y, z, w = Rotation.from_matrix(C).as_quat()
    q = np.array([w, x, y, z])
    assert q_fmu[0] >= 0
    assert min(np.abs(q_fmu - q).max(), np.abs(q_fmu + q).max()) < tol


@pytest.fixture
def make(turntable_fmu):
    made = []

    def _make(start=None, **kw):
        s = Slave(turntable_fmu, start or {}, **kw)
        close = s.close

        def close_once():  # tests may close early; the fixture closes the rest exactly once
            if s in made:
                made.remove(s)
                close()

        s.close = close_once
        made.append(s)
        return s

    yield _make
    for s in list(made):
        try:
            s.close()
        except Exception:
            pass


def hold(angles, **extra) -> dict:
    """Start values: the table at rest at `angles`, commanded to stay there."""
    d = dict(extra)
    for a, th in zip(AXES, angles):
        d[f"{a}.angle0"] = th
        d[f"{a}.angle_cmd"] = th
    return d


def check_static(s: Slave, C: np.ndarray, lat: float, g: float) -> None:
    f_exp = C.T @ np.array([0.0, 0.0, g])
    w_exp = C.T @ earth_rate_n(lat)
    assert rel(plate(s, "f"), f_exp) < 1e-9
    assert rel(plate(s, "omega"), w_exp) < 1e-9
    assert np.all(plate(s, "alpha") == 0.0)
    quat_close(plate(s, "q"), C)


# ------------------------------------------------------------------ static attitudes

def _24_attitudes():
    seen, out = [], []
    for k in itertools.product(range(4), repeat=3):
        C = c_pn([i * math.pi / 2 for i in k])
        if not any(np.allclose(C, D, atol=1e-9) for D in seen):
            seen.append(C)
            out.append(k)
    return out


ATTITUDES = _24_attitudes()


def test_there_are_24_attitudes():
    assert len(ATTITUDES) == 24


def test_static_24_attitudes(make):
    lat = 39.9 * DEG
    g = normal_gravity(lat, 50.0)
    assert abs(g - 9.8015) < 1e-3  # the primer's Beijing value
    for k in ATTITUDES:
        angles = [i * math.pi / 2 for i in k]
        s = make(hold(angles))
        C = c_pn(angles)
        check_static(s, C, lat, g)  # initial outputs, before any step
        s.step(H)
        check_static(s, C, lat, g)
        # multiples of 90 deg sit on encoder counts: the table must not move at all
        assert list(s.get(*[f"{a}.angle_true" for a in AXES])) == angles
        assert np.all(s.get(*[f"{a}.torque" for a in AXES]) == 0.0)
        s.close()


def test_static_base_tilt_azimuth_site(make):
    lat, hgt = -33.9 * DEG, 1234.0
    tilt, az = (2e-3, -3.5e-3), 0.7
    g = normal_gravity(lat, hgt)
    for k in ATTITUDES[::5]:
        angles = [i * math.pi / 2 for i in k]
        s = make(hold(angles, **{"base.tilt.x": tilt[0], "base.tilt.y": tilt[1],
                                 "base.azimuth": az, "site.latitude": lat,
                                 "site.height": hgt}))
        s.step(H)
        check_static(s, c_pn(angles, tilt=tilt, azimuth=az), lat, g)
        s.close()


def test_gravity_override_and_earth_rate(make):
    s = make(hold([0.0, 0.0, 0.0], **{"site.gravity": 9.81, "site.earth_rate": 1e-4,
                                       "site.latitude": 0.3}))
    assert rel(plate(s, "f"), [0, 0, 9.81]) < 1e-15
    assert rel(plate(s, "omega"), [0, 1e-4 * math.cos(0.3), 1e-4 * math.sin(0.3)]) < 1e-15


def test_static_seed002_geometry(make):
    """Seed 002: outer along y, middle along x, inner along z; arbitrary angles (bits=0 so that
    an off-count angle is not re-positioned onto an encoder count)."""
    axes = [(0, 1, 0), (1, 0, 0), (0, 0, 1)]
    geo = {f"{a}.axis.{c}": axes[i][j] for i, a in enumerate(AXES) for j, c in enumerate("xyz")}
    lat = 39.9 * DEG
    g = normal_gravity(lat, 50.0)
    for angles in ([0.3, -1.2, 2.5], [math.pi / 2, math.pi, -math.pi / 2]):
        s = make(hold(angles, **geo, **{f"{a}.encoder.bits": 0 for a in AXES}))
        s.step(H)
        check_static(s, c_pn(angles, axes=axes), lat, g)
        s.close()


def test_fewer_axes(make):
    """n_axes = 2: the inner stage does not enter the chain, whatever its angle0."""
    angles = [0.4, -0.9]
    s = make(hold(angles, n_axes=2, **{"inner.angle0": 1.0, "inner.angle_cmd": 1.0},
                  **{f"{a}.encoder.bits": 0 for a in AXES}))
    s.step(H)
    check_static(s, c_pn(angles, axes=[(0, 0, 1), (1, 0, 0)]), 39.9 * DEG,
                 normal_gravity(39.9 * DEG, 50.0))
    assert s.get("inner.angle_true")[0] == 0.0


def test_rest_is_exact_off_count(make):
    """angle_cmd == angle0 with an exact encoder: nothing moves, no torque, ever."""
    s = make(hold([0.3, -0.2, 1.7], **{f"{a}.encoder.bits": 0 for a in AXES}))
    for _ in range(100):
        s.step(H)
    assert list(s.get(*[f"{a}.angle_true" for a in AXES])) == [0.3, -0.2, 1.7]
    assert np.all(s.get(*[f"{a}.torque" for a in AXES]) == 0.0)
    assert np.all(s.get(*[f"{a}.rate" for a in AXES]) == 0.0)


# ------------------------------------------------------------------ rate mode

def test_constant_rate(make):
    """Middle axis in rate mode (outer at 90 deg, inner at -90 deg): acceleration phase at
    acc_max, then exactly the commanded rate; plate rate and acceleration from the kinematics."""
    rate, lat = 0.8, 39.9 * DEG
    amax = 200 * DEG
    s = make(hold([math.pi / 2, 0.0, -math.pi / 2], **{f"{a}.encoder.bits": 0 for a in AXES}))
    s.set({"middle.mode": 1, "middle.rate_cmd": rate})
    axis_p = rot([0, 0, 1], -math.pi / 2).T @ np.array([1.0, 0, 0])  # middle axis in plate axes
    # acceleration phase: rate / amax = 0.23 s; sample it in the middle
    for _ in range(20):
        s.step(H)
    alpha = plate(s, "alpha")
    assert rel(alpha, amax * axis_p) < 2e-3, alpha
    for _ in range(400):  # 2 s: the integrator has taken up the Coulomb friction
        s.step(H)
    th1 = s.get("middle.angle_true")[0]
    for _ in range(100):
        s.step(H)
    th2 = s.get("middle.angle_true")[0]
    assert abs(s.get("middle.rate")[0] - rate) < 1e-10 * rate
    assert abs((th2 - th1) - rate * 100 * H) < 1e-10
    C = c_pn([math.pi / 2, th2, -math.pi / 2])
    w_earth = C.T @ earth_rate_n(lat)
    w_exp = w_earth + rate * axis_p
    assert rel(plate(s, "omega"), w_exp) < 1e-10
    # d/dt (C_n^p w_ie^n) = (C_n^p w_ie^n) x (gimbal rate in plate axes); the gimbal part is
    # constant in plate axes
    a_exp = np.cross(w_earth, rate * axis_p)
    assert np.linalg.norm(plate(s, "alpha") - a_exp) < 1e-9
    assert rel(plate(s, "f"), C.T @ [0, 0, normal_gravity(lat, 50.0)]) < 1e-9


def test_rate_limit_in_rate_mode(make):
    s = make(hold([0, 0, 0]))
    s.set({"inner.mode": 1, "inner.rate_cmd": 100.0})
    for _ in range(400):
        s.step(H)
    # the 2^24 encoder's quantisation makes the rate jitter by ~2e-6 rad/s at this speed
    assert abs(s.get("inner.rate")[0] - 300 * DEG) < 1e-5


# ------------------------------------------------------------------ servo vs python-control

def _loop_start(axis: str, **extra) -> dict:
    d = {"servo.feedforward": 0.0, f"{axis}.coulomb": 0.0, f"{axis}.encoder.bits": 0,
         f"{axis}.rate_max": 1e12, f"{axis}.acc_max": 1e12, f"{axis}.torque_max": 1e12}
    d.update(extra)
    return d


def _closed_loop(axis: str):
    J, B = tv.DEFAULT_INERTIA[axis], tv.DEFAULT_VISCOUS[axis]
    gains = design_servo.design_axis(J, B, tv.BANDWIDTH_HZ, tv.PHASE_MARGIN_DEG,
                                     tv.CONTROL_RATE_HZ)
    return design_servo.closed_loop(gains, J, B, tv.CONTROL_RATE_HZ)


def _run_ticks(s: Slave, axis: str, n: int) -> np.ndarray:
    out = [s.get(f"{axis}.angle_true")[0]]
    for _ in range(n):
        s.step(T_CTRL)
        out.append(s.get(f"{axis}.angle_true")[0])
    return np.array(out)


@pytest.mark.parametrize("axis", AXES)
def test_step_response_matches_python_control(make, axis):
    """Pure feedback loop (no feed-forward, no Coulomb friction, exact encoder, unlimited
    reference): the FMU's continuous plant under the held torque, integrated by RK4, against
    python-control's exact ZOH discretisation. RK4's truncation error on the viscous mode is
    (B T / J)^5 / 120 ~ 1e-25; what remains is rounding, amplified by the controller's nearly
    cancelling coefficients (b0 + b1 + b2 ~ 1e-5 b0) and python-control's polynomial form:
    measured 3e-10 to 9e-10 of the step, hence the bound 1e-8."""
    step, n = 1e-3, 600
    s = make(_loop_start(axis, **{f"{axis}.angle_cmd": step}))
    y_fmu = _run_ticks(s, axis, n)
    cl = _closed_loop(axis)
    t = np.arange(n + 1) * T_CTRL
    r = np.where(np.arange(n + 1) >= 1, step, 0.0)  # the step reaches th_ref one tick later
    y_pc = control.forced_response(cl, T=t, U=r).outputs
    assert np.max(np.abs(y_fmu - y_pc)) < 1e-8 * step
    info_pc = control.step_info(cl, SettlingTimeThreshold=0.02)
    over_fmu = 100 * (y_fmu.max() - step) / step
    assert abs(over_fmu - info_pc["Overshoot"]) < 1e-4
    assert 25 < over_fmu < 35  # the design: ~30.5 % overshoot at PM 50 deg
    outside = np.nonzero(np.abs(y_fmu - step) > 0.02 * step)[0]
    settle_fmu = (outside[-1] + 1 - 1) * T_CTRL  # minus the one-tick delay of the reference
    assert abs(settle_fmu - info_pc["SettlingTime"]) <= T_CTRL


def test_ramp_without_feedforward_matches_python_control(make):
    """Rate mode, unlimited acceleration: th_ref(t_k) = v T (k - 1/2) for k >= 1 (the reference
    rate jumps at the first tick and the angle integrates it by the trapezoid rule)."""
    v, n, axis = 0.2, 800, "middle"
    s = make(_loop_start(axis))
    s.set({f"{axis}.mode": 1, f"{axis}.rate_cmd": v})
    y_fmu = _run_ticks(s, axis, n)
    k = np.arange(n + 1)
    r = np.where(k >= 1, v * T_CTRL * (k - 0.5), 0.0)
    y_pc = control.forced_response(_closed_loop(axis), T=k * T_CTRL, U=r).outputs
    assert np.max(np.abs(y_fmu - y_pc)) < 1e-8 * v * n * T_CTRL  # measured 4.6e-10 (rounding)
    # type 2 (double integrator in the loop): the ramp error decays to zero, also without FF
    for _ in range(400):
        s.step(H)
    err = v * (s.time - T_CTRL / 2) - s.get(f"{axis}.angle_true")[0]
    assert abs(err) < 1e-9 * abs(y_fmu - r).max()


def test_ramp_with_feedforward_tracks(make):
    """Defaults (feed-forward on, Coulomb friction, acceleration limit), exact encoder: after the
    transient the true angle follows the reference with no steady error."""
    s = make({f"{a}.encoder.bits": 0 for a in AXES})
    s.set({"outer.mode": 1, "outer.rate_cmd": 0.5})
    worst = 0.0
    for i in range(600):
        s.step(H)
        worst = max(worst, abs(s.get("outer.angle_ref")[0] - s.get("outer.angle_true")[0]))
    err = s.get("outer.angle_ref")[0] - s.get("outer.angle_true")[0]
    assert abs(err) < 1e-11
    assert worst < 1e-4  # feed-forward keeps the transient error small (~Tc / stiffness)


# ------------------------------------------------------------------ indexing

def _index(make, axis, target, n, h=H, **extra):
    s = make({**extra, f"{axis}.angle_cmd": target})
    rows = []
    for _ in range(n):
        s.step(h)
        rows.append(s.get(f"{axis}.angle", f"{axis}.angle_true", f"{axis}.rate",
                          "plate.alpha.x", "plate.alpha.y", "plate.alpha.z"))
    return s, np.array(rows)


def test_index_90deg_default_limits(make):
    """Outer axis, 90 deg, default limits and encoder (2^24): bang-bang acceleration profile
    (t_min = 2 sqrt(pi/2 / acc_max) = 1.34 s), settled within one count. The acceleration
    limit is exceeded by the servo's transients at the profile's corners by < 1 %; the true
    angle overshoots by < 30 counts (measured 17.5 counts = 1.35 arcsec; settles 0.27 s after
    the reference arrives)."""
    q = 2 * math.pi / 2 ** 24
    amax, wmax = 200 * DEG, 300 * DEG
    s, rows = _index(make, "outer", math.pi / 2, 1000, h=0.002)
    assert abs(rows[-1, 0] - math.pi / 2) <= q
    assert np.all(np.abs(rows[-150:, 0] - math.pi / 2) <= q)  # held for the last 0.3 s
    assert np.abs(rows[:, 2]).max() <= wmax
    assert np.abs(rows[:, 2]).max() > 0.99 * math.sqrt(amax * math.pi / 2)  # near bang-bang
    alpha = np.linalg.norm(rows[:, 3:], axis=1)
    assert alpha.max() <= 1.01 * amax
    assert rows[:, 1].max() - math.pi / 2 < 30 * q
    settled = np.nonzero(np.abs(rows[:, 0] - math.pi / 2) > q)[0][-1] + 1
    assert settled * 0.002 < 1.34 + 0.4


def test_index_hits_rate_limit(make):
    wmax = 0.6
    s, rows = _index(make, "inner", math.pi / 2, 700, **{"inner.rate_max": wmax})
    assert np.abs(rows[:, 2]).max() <= wmax * (1 + 1e-3)
    assert np.abs(rows[:, 2]).max() > 0.999 * wmax
    assert abs(rows[-1, 0] - math.pi / 2) <= 2 * math.pi / 2 ** 24


def test_position_to_rate_mode_is_bumpless(make):
    s = make({f"{a}.encoder.bits": 0 for a in AXES})
    s.set({"inner.angle_cmd": 0.2})
    for _ in range(40):
        s.step(H)
    s.set({"inner.mode": 1, "inner.rate_cmd": -0.3})
    prev = s.get("inner.angle_ref")[0]
    for _ in range(10):
        s.step(H)
        th_ref = s.get("inner.angle_ref")[0]
        assert abs(th_ref - prev) < 300 * DEG * H  # no jump: at most rate_max * h per step
        prev = th_ref


def test_moving_command_with_rate_feedforward(make):
    """Position mode with a moving command (first-order hold by rate_cmd): tracks the line."""
    s = make({f"{a}.encoder.bits": 0 for a in AXES})
    v = 0.1
    for i in range(600):
        t = i * H
        s.set({"inner.angle_cmd": v * t, "inner.rate_cmd": v})
        s.step(H)
    assert abs(s.get("inner.angle_true")[0] - v * 600 * H) < 1e-9
    assert abs(s.get("inner.rate")[0] - v) < 1e-9


# ------------------------------------------------------------------ encoder

def test_encoder_quantisation_at_start(make):
    bits, th0 = 16, 0.123456
    q = 2 * math.pi / 2 ** bits
    s = make(hold([th0, 0, 0], **{"outer.encoder.bits": bits}), initialize=True)
    assert s.get("outer.angle")[0] == pytest.approx(round(th0 / q) * q, rel=1e-15)
    assert s.get("outer.angle_true")[0] == th0


def test_encoder_harmonics_positions_reading(make):
    """The loop nulls the encoder READING: true angle = command - harmonic error (to a count)."""
    bits, h1, p1, h2, p2 = 16, 1e-3, 0.4, 4e-4, -1.1
    q = 2 * math.pi / 2 ** bits
    cmd = 5000 * q  # on a count, so the loop can rest
    s = make({"inner.encoder.bits": bits, "inner.encoder.h1.amp": h1,
              "inner.encoder.h1.phase": p1, "inner.encoder.h2.amp": h2,
              "inner.encoder.h2.phase": p2, "inner.angle_cmd": cmd})
    for _ in range(200):
        s.step(H)
    for _ in range(50):
        s.step(H)
        th = s.get("inner.angle_true")[0]
        reading = th + h1 * math.sin(th + p1) + h2 * math.sin(2 * th + p2)
        assert s.get("inner.angle")[0] == pytest.approx(round(reading / q) * q, rel=1e-15)
        assert abs(reading - cmd) <= q
        assert abs(th - cmd) > 5 * q  # the harmonic error is visible in the true angle


# ------------------------------------------------------------------ non-orthogonality, wobble

ERRORS = [
    {"nonorth": (1e-3, -2e-3, 5e-4), "amp": 0.0, "phase": 0.0},
    {"nonorth": (-7e-4, 3e-4, 1.5e-3), "amp": 5e-4, "phase": -1.2},
    {"nonorth": (0.0, 0.0, 0.0), "amp": 1e-3, "phase": 0.7},
]


def _error_params():
    d = {}
    for a, e in zip(AXES, ERRORS):
        for c, x in zip("xyz", e["nonorth"]):
            d[f"{a}.nonorth.{c}"] = x
        d[f"{a}.wobble.amp"] = e["amp"]
        d[f"{a}.wobble.phase"] = e["phase"]
        d[f"{a}.encoder.bits"] = 0
    return d


def test_nonorthogonality_and_wobble_static(make):
    lat = 39.9 * DEG
    g = normal_gravity(lat, 50.0)
    for angles in ([0.4, -0.7, 1.1], [2.0, 0.3, -2.9]):
        s = make(hold(angles, **_error_params()))
        s.step(H)
        C = c_pn(angles, errors=ERRORS)
        check_static(s, C, lat, g)
        assert rel(C, c_pn(angles)) > 1e-4  # the errors do matter at this size
        s.close()


def test_wobble_rate_is_derivative_of_attitude(make):
    """Inner axis spinning with wobble and non-orthogonality everywhere: plate.omega minus the
    Earth part equals the rate obtained by differentiating the test's own chain numerically."""
    rate, lat = 1.3, 39.9 * DEG
    s = make(hold([0.5, -0.3, 0.0], **_error_params()))
    s.set({"inner.mode": 1, "inner.rate_cmd": rate})
    for _ in range(300):
        s.step(H)
    th = s.get("inner.angle_true")[0]
    eps = 1e-5
    Cm = c_pn([0.5, -0.3, th - eps], errors=ERRORS)
    Cp = c_pn([0.5, -0.3, th + eps], errors=ERRORS)
    C = c_pn([0.5, -0.3, th], errors=ERRORS)
    Om = C.T @ (Cp - Cm) / (2 * eps)  # skew(omega_np^p) per unit inner rate
    w_gimbal = rate * np.array([Om[2, 1], Om[0, 2], Om[1, 0]])
    w_exp = C.T @ earth_rate_n(lat) + w_gimbal
    assert np.linalg.norm(plate(s, "omega") - w_exp) < 1e-9 * rate
    quat_close(plate(s, "q"), C, tol=1e-12)
    assert rel(plate(s, "f"), C.T @ [0, 0, normal_gravity(lat, 50.0)]) < 1e-12


def test_wobble_acceleration_direction(make):
    """No Earth rate, only the wobbling inner stage accelerating: plate.alpha = theta'' * beta,
    beta = vee(C^T dC/dtheta) from the test's chain, which the convention makes constant."""
    s = make(hold([0.5, -0.3, 0.0], **_error_params(), **{"site.earth_rate": 0.0}))
    s.set({"inner.mode": 1, "inner.rate_cmd": 1.3})
    for _ in range(10):
        s.step(H)

    def beta(th, eps=1e-5):
        C = c_pn([0.5, -0.3, th], errors=ERRORS)
        D = (c_pn([0.5, -0.3, th + eps], errors=ERRORS)
             - c_pn([0.5, -0.3, th - eps], errors=ERRORS)) / (2 * eps)
        Om = C.T @ D
        return np.array([Om[2, 1], Om[0, 2], Om[1, 0]])

    th = s.get("inner.angle_true")[0]
    b = beta(th)
    assert np.linalg.norm(beta(th + 2.0) - b) < 1e-9  # constant in plate axes
    assert abs(np.linalg.norm(b) - 1) < 1e-9
    assert np.linalg.norm(b - np.array([0.0, 0.0, 1.0])) > 5e-4  # the wobble tilts it
    alpha = plate(s, "alpha")
    assert np.linalg.norm(np.cross(alpha, b)) < 1e-9 * np.linalg.norm(alpha)
    assert abs(np.linalg.norm(alpha) - 200 * DEG) < 2e-3 * 200 * DEG


def test_fmu_state_round_trip(make):
    """The private state is a plain struct: a saved state replays bit for bit."""
    s = make({"outer.angle_cmd": 0.4, "inner.mode": 1, "inner.rate_cmd": 0.7})
    for _ in range(20):
        s.step(H)
    state = s.fmu.getFMUState()
    t0 = s.time
    names = [f"{a}.{v}" for a in AXES for v in ("angle", "angle_true", "rate", "torque")]
    first = []
    for _ in range(30):
        s.step(H)
        first.append(s.get(*names))
    s.fmu.setFMUState(state)
    s.time = t0
    for row in first:
        s.step(H)
        assert np.array_equal(s.get(*names), row)
    s.fmu.freeFMUState(state)


# ------------------------------------------------------------------ instances

def test_instances_are_independent(make):
    a = make({"outer.angle_cmd": 0.5}, name="a")
    b = make({"outer.angle_cmd": -0.2}, name="b")
    c = make({"outer.angle_cmd": 0.5}, name="c")
    for _ in range(50):
        a.step(H)
        b.step(H)
    for _ in range(50):
        c.step(H)
    assert a.get("outer.angle_true")[0] == c.get("outer.angle_true")[0]
    assert b.get("outer.angle_true")[0] < 0


# ------------------------------------------------------------------ errors

@pytest.mark.parametrize("start,words", [
    ({"middle.axis.x": 0.0, "middle.axis.y": 0.0, "middle.axis.z": 0.0}, ["middle.axis"]),
    ({"inner.inertia": -1.0}, ["inner.inertia", "> 0"]),
    ({"site.latitude": float("nan")}, ["site.latitude", "nan"]),
    ({"outer.wobble.phase": float("inf")}, ["outer.wobble.phase"]),
    ({"outer.viscous": -0.1}, ["outer.viscous"]),
    ({"servo.rate": 0.0}, ["servo.rate"]),
    ({"inner.encoder.bits": 40}, ["inner.encoder.bits"]),
    ({"n_axes": 4}, ["n_axes"]),
    ({"site.latitude": 2.0}, ["site.latitude"]),
    ({"middle.mode": 7}, ["middle.mode"]),
    ({"servo.stick_velocity": -1.0}, ["servo.stick_velocity"]),
    ({"middle.static_friction": -0.1}, ["middle.static_friction"]),
])
def test_bad_parameters(turntable_fmu, start, words):
    s = Slave(turntable_fmu, start, initialize=False)
    try:
        with pytest.raises(Exception):
            s.fmu.exitInitializationMode()
        text = " ".join(m for _, m in s.log).lower()
        for w in words:
            assert w.lower() in text, s.log
    finally:
        s.fmu.freeInstance()


def test_bad_mode_at_step(make):
    s = make()
    s.step(H)
    s.set({"outer.mode": 7})
    with pytest.raises(Exception):
        s.step(H)
    assert any("outer.mode" in m for _, m in s.log)


def test_nonfinite_input(make):
    s = make()
    s.set({"inner.angle_cmd": float("nan")})
    with pytest.raises(Exception):
        s.step(H)
    assert any("inner.angle_cmd" in m for _, m in s.log)


def test_step_not_multiple_of_controller_period(make):
    s = make()
    with pytest.raises(Exception):
        s.step(0.0013)
    msg = " ".join(m for _, m in s.log)
    assert "0.0013" in msg and "0.0005" in msg


def test_step_multiple_within_rounding_is_accepted(make):
    s = make()
    for _ in range(30):
        s.step(0.1 / 3 * 0.15)  # 0.005 up to rounding
        s.step(0.0005 * 3)


@pytest.mark.parametrize("reversal_arcsec", [0.0, 2.0, -1.0])
def test_the_servo_rests_past_the_reading_on_the_side_it_came_from(make, reversal_arcsec):
    """A servo that compares counts (error 0 once the reading is the target count) stops inside
    that count and coasts past its centre in the direction of the move, and the same move stops
    in the same place. The encoder's backlash (``encoder.reversal`` r, a play operator) puts the
    plate r/2 further on the side it came from (short of it for r < 0). So at rest the true angle
    is the reading + r/2 × the side of approach + a repeatable fraction of a count on that side:
    a reversal error (ISO 230-2) of r + that fraction."""
    q = 2 * math.pi / 2**24
    r = reversal_arcsec * ARCSEC
    s = make({"middle.encoder.reversal": r})
    seen = {}
    for target in (90, 0, 90, 0, -90, 0):
        before = s.get("middle.angle")[0]
        cmd = round(math.radians(target) / q) * q
        s.set({"middle.angle_cmd": cmd})
        for _ in range(1600):
            s.step(H)
        reading, true = s.get("middle.angle", "middle.angle_true")
        assert reading == pytest.approx(cmd, abs=1e-12)
        side = np.sign(cmd - before)
        beyond = (true - reading - 0.5 * r * side) / q  # what the servo adds, in counts
        assert 0 < beyond * side < 0.5
        seen.setdefault((target, side), []).append(beyond)
    # the repeated 0 -> 90 and 90 -> 0 moves stop within a tenth of a count of each other
    assert any(len(v) > 1 for v in seen.values())
    for offsets in seen.values():
        assert max(offsets) - min(offsets) < 0.1
