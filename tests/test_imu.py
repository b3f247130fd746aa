"""IMU FMU physics against independent computations: closed forms, a Python restatement of each
effect's formula (domain.md §4), an Allan deviation computed here, an attitude integrated with
scipy. Never against numbers captured from the FMU."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from scipy.integrate import solve_ivp

from support import Slave

G = 9.80665
OMEGA_IE = 7.2921151467e-5
AX = "xyz"
OUT = [f"gyro.{c}" for c in AX] + [f"acc.{c}" for c in AX]
IN = [f"omega.{c}" for c in AX] + [f"f.{c}" for c in AX] + [f"alpha.{c}" for c in AX]
OFF = ("xy", "xz", "yx", "yz", "zx", "zy")
PAIRS = ("xx", "yy", "zz", "xy", "xz", "yz")


# ------------------------------------------------------------------------------ drivers

def motion(w, f, a=(0.0, 0.0, 0.0)) -> dict:
    return dict(zip(IN, [*map(float, w), *map(float, f), *map(float, a)]))


def run(fmu, params: dict, profile, h: float, n: int, timing: int = 0, extra_out=()):
    """Step an IMU n times. profile(t) -> dict of input values at t (or None: constant inputs
    from params). timing 0 sets the inputs at t+h before doStep(t, h), timing 1 those at t.
    Returns (times at the end of each step, outputs[n, 6 + len(extra_out)])."""
    start = dict(params, input_timing=timing)
    if profile is not None:
        start.update(profile(0.0))
    s = Slave(fmu, start)
    names = OUT + list(extra_out)
    vout = [s.vr(v) for v in names]
    out = np.empty((n, len(names)))
    ts = np.empty(n)
    try:
        for k in range(n):
            if profile is not None:
                u = profile(s.time + h if timing == 0 else s.time)
                s.fmu.setReal([s.vr(v) for v in u], list(u.values()))
            s.step(h)
            ts[k] = s.time
            out[k] = s.fmu.getReal(vout)
    finally:
        s.close()
    return ts, out


def rot(axis, angle) -> np.ndarray:
    """Rodrigues matrix, active rotation about unit axis."""
    n = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def cube_attitudes() -> list[np.ndarray]:
    """The 24 proper rotations mapping axes onto axes."""
    mats = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1, -1), repeat=3):
            C = np.zeros((3, 3))
            for r, (c, sg) in enumerate(zip(perm, signs)):
                C[r, c] = sg
            if np.linalg.det(C) > 0:
                mats.append(C)
    assert len(mats) == 24
    return mats


# ------------------------------------------------------------------------------ ideal outputs

@pytest.mark.parametrize("k", range(24))
def test_static_attitudes_ideal(imu_fmu, k):
    lat = np.radians(39.9)
    C = cube_attitudes()[k] @ rot([0.3, -0.2, 1.0], 0.7)  # C_n^b: cube attitude off a generic one
    w = C @ [0.0, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)]
    f = C @ [0.0, 0.0, G]
    h = 0.005
    _, y = run(imu_fmu, {}, lambda t: motion(w, f), h, 5)
    np.testing.assert_allclose(y[:, :3], np.tile(w * h, (5, 1)), rtol=0, atol=1e-12 * OMEGA_IE * h)
    np.testing.assert_allclose(y[:, 3:], np.tile(f * h, (5, 1)), rtol=0, atol=1e-12 * G * h)


def test_constant_rate_rotation_ideal(imu_fmu):
    """Rotation at constant rate about a body-fixed axis n: f_b(t) = R(n, Wt)^T f0 (Rodrigues),
    integrated in closed form."""
    n = np.array([0.2, -0.5, 0.84])
    n /= np.linalg.norm(n)
    W, h, N = 0.8, 0.01, 200
    f0 = np.array([1.0, 2.0, G])
    w = W * n

    def f_of(t):
        th = W * t
        return f0 * np.cos(th) - np.cross(n, f0) * np.sin(th) + n * (n @ f0) * (1 - np.cos(th))

    def int_f(ta, tb):  # closed-form integral of f_of
        a, b = W * ta, W * tb
        return (f0 * (np.sin(b) - np.sin(a)) + np.cross(n, f0) * (np.cos(b) - np.cos(a))
                + n * (n @ f0) * ((b - a) - (np.sin(b) - np.sin(a)))) / W

    ts, y = run(imu_fmu, {}, lambda t: motion(w, f_of(t)), h, N)
    np.testing.assert_allclose(y[:, :3].sum(0), w * ts[-1], rtol=1e-13, atol=1e-14)
    exact = np.array([int_f(t - h, t) for t in ts])
    assert np.max(np.abs(y[:, 3:] - exact)) < 1e-11  # Hermite: h^5/720 g W^4 ~ 6e-12
    np.testing.assert_allclose(y[:, 3:].sum(0), int_f(0, ts[-1]), rtol=0, atol=1e-10)


# ------------------------------------------------------------------------------ effects

def ref_rates(p: dict, w, f, s: float, t0: float = 0.0) -> np.ndarray:
    """domain.md §4 restated: instantaneous [gyro xyz, acc xyz] for constant omega, f, alpha = 0
    at sensor time s (temperature modes 0/1 only)."""
    P = lambda k: p.get(k, 0.0)  # noqa: E731
    T = P("temperature.start") if "temperature.start" in p else 25.0
    if p.get("temperature.mode", 0) == 1:
        T += P("temperature.rate") * (s - t0)
    dT = T - p.get("temperature.ref", 25.0)
    out = np.zeros(6)
    idx = {c: k for k, c in enumerate(AX)}
    for sensor, base in (("gyro", 0), ("acc", 3)):
        for i, c in enumerate(AX):
            if sensor == "gyro":
                x = np.asarray(w, float)
            else:
                r = np.array([P(f"acc.lever.{c}.{k}") for k in AX])
                x = np.asarray(f, float) + np.cross(w, np.cross(w, r))
            y = (1 + P(f"{sensor}.sf.{c}") + P(f"{sensor}.sf_temp.{c}") * dT) * x[i]
            y += P(f"{sensor}.sf_asym.{c}") * abs(x[i])
            y += sum(P(f"{sensor}.mis.{c}{d}") * x[idx[d]] for d in AX if d != c)
            y += P(f"{sensor}.bias.{c}") + P(f"{sensor}.temp.{c}") * dT + P(f"{sensor}.drift.{c}") * (s - t0)
            if sensor == "gyro":
                y += sum(P(f"gyro.gsens.{c}{d}") * f[idx[d]] for d in AX)
                y += sum(P(f"gyro.g2sens.{c}.{jk}") * f[idx[jk[0]]] * f[idx[jk[1]]] for jk in PAIRS)
            else:
                y += P(f"acc.k2.{c}") * x[i] ** 2 + P(f"acc.k3.{c}") * x[i] ** 3
                y += sum(P(f"acc.cross.{c}{d}") * x[i] * x[idx[d]] for d in AX if d != c)
            out[base + i] = y
    return out


def _vec(name, v):
    return {f"{name}.{c}": v[k] for k, c in enumerate(AX)}


_rng = np.random.default_rng(12345)
_r = lambda n, s: (_rng.standard_normal(n) * s).tolist()  # noqa: E731

EFFECTS = {
    "gyro.bias": _vec("gyro.bias", _r(3, 1e-4)),
    "gyro.sf": _vec("gyro.sf", _r(3, 1e-3)),
    "gyro.sf_asym": _vec("gyro.sf_asym", _r(3, 1e-3)),
    "gyro.mis": {f"gyro.mis.{ij}": v for ij, v in zip(OFF, _r(6, 1e-3))},
    "gyro.gsens": {f"gyro.gsens.{i}{j}": v for (i, j), v in zip(itertools.product(AX, AX), _r(9, 1e-5))},
    "gyro.g2sens": {f"gyro.g2sens.{i}.{jk}": v
                    for (i, jk), v in zip(itertools.product(AX, PAIRS), _r(18, 1e-6))},
    "gyro.temp": {**_vec("gyro.temp", _r(3, 1e-6)), "temperature.start": 31.0},
    "gyro.sf_temp": {**_vec("gyro.sf_temp", _r(3, 1e-5)), "temperature.start": 18.0},
    "gyro.drift": _vec("gyro.drift", _r(3, 1e-5)),
    "acc.bias": _vec("acc.bias", _r(3, 1e-3)),
    "acc.sf": _vec("acc.sf", _r(3, 1e-3)),
    "acc.sf_asym": _vec("acc.sf_asym", _r(3, 1e-3)),
    "acc.mis": {f"acc.mis.{ij}": v for ij, v in zip(OFF, _r(6, 1e-3))},
    "acc.k2": _vec("acc.k2", _r(3, 1e-4)),
    "acc.k3": _vec("acc.k3", _r(3, 1e-5)),
    "acc.cross": {f"acc.cross.{ij}": v for ij, v in zip(OFF, _r(6, 1e-4))},
    "acc.lever (centripetal)": {f"acc.lever.{i}.{k}": v
                                for (i, k), v in zip(itertools.product(AX, AX), _r(9, 0.05))},
    "acc.temp": {**_vec("acc.temp", _r(3, 1e-5)), "temperature.start": 40.0},
    "acc.sf_temp": {**_vec("acc.sf_temp", _r(3, 1e-5)), "temperature.start": 10.0},
    "acc.drift": _vec("acc.drift", _r(3, 1e-4)),
    "temperature ramp": {**_vec("gyro.temp", _r(3, 1e-6)), **_vec("acc.temp", _r(3, 1e-5)),
                         **_vec("gyro.sf_temp", _r(3, 1e-5)), **_vec("acc.sf_temp", _r(3, 1e-5)),
                         "temperature.mode": 1, "temperature.start": 20.0,
                         "temperature.rate": 0.5, "temperature.ref": 22.0},
}


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("effect", list(EFFECTS))
def test_effect_adds_its_formula(imu_fmu, effect, sign):
    """Constant rate about n with f parallel to n (so f stays constant in the body): every term
    is affine in time and its integral is the formula at mid-step times h."""
    n = np.array([0.3, -0.5, 0.81])
    n /= np.linalg.norm(n)
    w, f = sign * 1.3 * n, -sign * G * n  # both signs: every component changes sign
    p = EFFECTS[effect]
    h, N = 0.01, 6
    ts, y = run(imu_fmu, p, lambda t: motion(w, f), h, N, extra_out=["temperature"])
    ideal = np.concatenate([w, f]) * h
    for k, t in enumerate(ts):
        expect = ref_rates(p, w, f, t - h / 2) * h
        contribution = expect - ideal
        assert np.max(np.abs(contribution)) > 1e-12  # the effect is visible
        np.testing.assert_allclose(y[k, :6] - ideal, contribution, rtol=1e-9, atol=1e-15)
    if p.get("temperature.mode") == 1:
        np.testing.assert_allclose(y[:, 6], p["temperature.start"] + p["temperature.rate"] * ts,
                                   rtol=1e-14)


def test_sf_asym_is_proportional_to_abs_rate(imu_fmu):
    p = {"gyro.sf_asym.x": 1e-3, "acc.sf_asym.y": 2e-3}
    h = 0.01
    for sign in (1, -1):
        w, f = [sign * 0.5, 0, 0], [0, sign * 3.0, 0]
        _, y = run(imu_fmu, p, lambda t: motion(w, f), h, 2)
        assert y[-1, 0] - sign * 0.5 * h == pytest.approx(1e-3 * 0.5 * h, rel=1e-9)
        assert y[-1, 4] - sign * 3.0 * h == pytest.approx(2e-3 * 3.0 * h, rel=1e-9)


def test_lever_arm_tangential(imu_fmu):
    """Constant alpha from rest, omega = alpha t, f parallel (constant): f'(i) = f + alpha x r_i
    + t^2 alpha x (alpha x r_i); integral closed form."""
    a = np.array([0.4, -1.1, 0.7])
    f = 2.0 * a
    lever = np.array(_r(9, 0.05)).reshape(3, 3)
    p = {f"acc.lever.{i}.{k}": lever[ii, kk] for ii, i in enumerate(AX) for kk, k in enumerate(AX)}
    h, N = 0.01, 20
    ts, y = run(imu_fmu, p, lambda t: motion(a * t, f, a), h, N)
    for k, tb in enumerate(ts):
        ta = tb - h
        for i in range(3):
            r = lever[i]
            exact = (f + np.cross(a, r)) * h + np.cross(a, np.cross(a, r)) * (tb**3 - ta**3) / 3
            assert y[k, 3 + i] == pytest.approx(exact[i], rel=1e-11, abs=1e-15)
        np.testing.assert_allclose(y[k, :3], a * (tb**2 - ta**2) / 2, rtol=1e-11, atol=1e-16)


@pytest.mark.parametrize("timing", [0, 1])
@pytest.mark.parametrize("frac", [0.3, -0.45])
def test_time_offset_linear_ramp(imu_fmu, timing, frac):
    """omega = a t: the sample labelled t holds int_{t-h+dt}^{t+dt} a s ds = a h (t - h/2 + dt)."""
    a = np.array([0.5, -0.2, 0.9])
    h, N = 0.01, 10
    dt = frac * h
    ts, y = run(imu_fmu, {"imu.time_offset": dt}, lambda t: motion(a * t, [0, 0, 0], a), h, N,
                timing=timing)
    exact = np.outer(ts - h / 2 + dt, a) * h
    np.testing.assert_allclose(y[:, :3], exact, rtol=1e-11, atol=1e-17)


@pytest.mark.parametrize("timing", [0, 1])
@pytest.mark.parametrize("dt_frac, dta_frac", [(0.0, 0.34), (0.2, -0.45), (-0.3, 0.5)])
def test_accelerometer_time_offset_on_a_turn_with_gravity(imu_fmu, timing, dt_frac, dta_frac):
    """A constant-rate turn about x with gravity in the y-z plane: f(t) = g (0, sin wt, cos wt),
    omega = (w, 0, 0). The gyro sample labelled t integrates omega over (t - h + dt, t + dt], the
    accelerometer sample f over (t - h + dt + dta, t + dt + dta] (closed form): the
    accelerometers late by dta against the gyros, the vocabulary's acc.time_offset."""
    g, w = 9.8, 0.7
    h, N = 0.005, 40
    dt, dta = dt_frac * h, dta_frac * h
    prof = lambda t: motion([w, 0, 0], [0, g * math.sin(w * t), g * math.cos(w * t)])  # noqa: E731
    ts, y = run(imu_fmu, {"imu.time_offset": dt, "acc.time_offset": dta}, prof, h, N, timing=timing)
    lo, hi = ts - h + dt + dta, ts + dt + dta
    exact_y = g * (np.cos(w * lo) - np.cos(w * hi)) / w
    exact_z = g * (np.sin(w * hi) - np.sin(w * lo)) / w
    # the input is interpolated between communication points (cubic Hermite, f' = -omega x f),
    # (timing 1: its Taylor extrapolation) so the tolerance is the interpolant's error on a sine
    # over one step; a shift error of 1 % of dta would be ~6e-7 (w g h dta / 100)
    k = slice(2, None)   # the first samples see the motion before the start (held there)
    np.testing.assert_allclose(y[k, 4], exact_y[k], rtol=0, atol=1e-9)
    np.testing.assert_allclose(y[k, 5], exact_z[k], rtol=0, atol=1e-9)
    np.testing.assert_allclose(y[:, 0], w * h, rtol=1e-12)


def test_accelerometer_time_offset_bounded_by_the_step(imu_fmu):
    s = Slave(imu_fmu, {"imu.time_offset": 0.003, "acc.time_offset": 0.003})
    try:
        with pytest.raises(FMICallException):
            s.step(0.005)
        assert any("imu.time_offset + acc.time_offset" in msg for _, msg in s.log)
    finally:
        s.fmu.freeInstance()


def test_temperature_input_mode(imu_fmu):
    """Mode 2: temperature_env linear in time; the output follows it and the bias term integrates
    the (linearly interpolated) temperature."""
    p = {"temperature.mode": 2, "gyro.temp.z": 1e-5, "acc.temp.x": 2e-4, "temperature.ref": 20.0}
    env = lambda t: 25.0 + 3.0 * t  # noqa: E731
    h = 0.02
    ts, y = run(imu_fmu, p, lambda t: {**motion([0, 0, 0], [0, 0, 0]), "temperature_env": env(t)},
                h, 5, extra_out=["temperature"])
    np.testing.assert_allclose(y[:, 6], env(ts), rtol=1e-14)
    np.testing.assert_allclose(y[:, 2], 1e-5 * (env(ts - h / 2) - 20.0) * h, rtol=1e-12)
    np.testing.assert_allclose(y[:, 3], 2e-4 * (env(ts - h / 2) - 20.0) * h, rtol=1e-12)


# ------------------------------------------------------------------------------ noise

def allan(increments: np.ndarray, h: float, m: int) -> np.ndarray:
    """Overlapping Allan deviation at tau = m h from per-sample increments (columns = axes)."""
    theta = np.vstack([np.zeros((1, increments.shape[1])), np.cumsum(increments, axis=0)])
    d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
    tau = m * h
    return np.sqrt(np.mean(d**2, axis=0) / (2 * tau**2))


def test_allan_white_noise(imu_fmu):
    N_g, N_a, h, n = 2e-4, 3e-4, 0.01, 40000
    _, y = run(imu_fmu, {"gyro.noise.arw": N_g, "acc.noise.vrw": N_a, "seed": 11}, None, h, n)
    dens = np.array([N_g] * 3 + [N_a] * 3)
    for m in (1, 10, 100):
        est = allan(y, h, m) * np.sqrt(m * h)
        err = np.max(np.abs(est / dens - 1))
        print(f"ARW/VRW at tau={m * h:g}s: worst axis error {err:.3%}")
        assert err < 0.10


def test_allan_bias_instability(imu_fmu):
    """Gauss-Markov with T = bi_tau: the Allan deviation peaks at 0.664 B near tau = 1.89 T."""
    B_g, B_a, T, h, n = 1e-5, 2e-4, 1.0, 0.05, 60000
    p = {"gyro.noise.bi": B_g, "gyro.noise.bi_tau": T, "acc.noise.bi": B_a, "acc.noise.bi_tau": T,
         "seed": 5}
    _, y = run(imu_fmu, p, None, h, n)
    ms = np.unique(np.round(np.geomspace(4, 200, 40)).astype(int))
    ad = np.array([allan(y, h, m) for m in ms])  # [tau, axis]
    peak = ad.max(0) / np.array([B_g] * 3 + [B_a] * 3)
    tau_peak = ms[ad.argmax(0)] * h
    err = np.abs(peak / 0.664 - 1)
    print(f"BI peak / (0.664 B) per axis: {np.round(peak / 0.664, 3)}, tau_peak {tau_peak} s "
          f"(theory 1.89 s); worst error {err.max():.3%}")
    assert err.max() < 0.10
    assert np.all((tau_peak > 1.0) & (tau_peak < 4.0))


def test_allan_rate_random_walk(imu_fmu):
    K_g, K_a, h, n = 1e-6, 1e-5, 0.1, 60000
    _, y = run(imu_fmu, {"gyro.noise.rrw": K_g, "acc.noise.rrw": K_a, "seed": 3}, None, h, n)
    dens = np.array([K_g] * 3 + [K_a] * 3)
    ms = (50, 100, 200)
    est = np.array([allan(y, h, m) / np.sqrt(m * h / 3) for m in ms]).mean(0) / dens
    # each axis is noisy (few independent long clusters); the mean over the six axes is the check
    print(f"RRW estimate / K per axis {np.round(est, 3)}, mean {est.mean():.4f}")
    assert abs(est.mean() - 1) < 0.10
    assert np.all(np.abs(est - 1) < 0.20)


NOISY = {"gyro.noise.arw": 1e-4, "gyro.noise.bi": 1e-5, "gyro.noise.rrw": 1e-6,
         "acc.noise.vrw": 1e-4, "acc.noise.bi": 1e-4, "acc.noise.rrw": 1e-5,
         "gyro.noise.bi_tau": 5.0, "acc.noise.bi_tau": 3.0}


def test_seed_reproducible_and_distinct(imu_fmu):
    prof = lambda t: motion([0.1, 0.2, -0.3], [0.0, 0.0, G])  # noqa: E731
    _, a = run(imu_fmu, {**NOISY, "seed": 42}, prof, 0.01, 100)
    _, b = run(imu_fmu, {**NOISY, "seed": 42}, prof, 0.01, 100)
    _, c = run(imu_fmu, {**NOISY, "seed": 43}, prof, 0.01, 100)
    assert np.array_equal(a, b)  # bit-identical
    assert not np.any(a == c)


def test_instances_independent(imu_fmu):
    n, h = 50, 0.01
    separate = [run(imu_fmu, {**NOISY, "seed": s}, None, h, n)[1] for s in (1, 2)]
    slaves = [Slave(imu_fmu, {**NOISY, "seed": s}, name=f"imu{s}") for s in (1, 2)]
    got = [np.empty((n, 6)) for _ in slaves]
    try:
        for k in range(n):
            for s, g in zip(slaves, got):
                s.step(h)
                g[k] = s.get(*OUT)
    finally:
        for s in slaves:
            s.close()
    assert np.array_equal(got[0], separate[0]) and np.array_equal(got[1], separate[1])


def test_zero_density_keeps_other_realisation(imu_fmu):
    """All draws are made whatever the densities: switching one on leaves the others' bits."""
    _, a = run(imu_fmu, {"gyro.noise.arw": 1e-4, "seed": 9}, None, 0.01, 50)
    _, b = run(imu_fmu, {"gyro.noise.arw": 1e-4, "acc.noise.vrw": 1e-3, "seed": 9}, None, 0.01, 50)
    assert np.array_equal(a[:, :3], b[:, :3])


# ------------------------------------------------------------------------------ coupling error

def _profile():
    """Rates: sums of sinusoids about all three axes; attitude integrated by scipy (DOP853 at
    tolerance 1e-13), f_b = C_n^b [0, 0, g] and its integral as extra states."""
    amp = np.array([[0.4, 0.15], [0.3, 0.2], [0.5, 0.1]])
    frq = 2 * np.pi * np.array([[0.7, 2.3], [1.1, 1.7], [0.5, 2.9]])
    ph = np.array([[0.0, 1.0], [0.5, 2.0], [1.5, 0.3]])
    w = lambda t: (amp * np.sin(frq * t + ph)).sum(1)  # noqa: E731
    a = lambda t: (amp * frq * np.cos(frq * t + ph)).sum(1)  # noqa: E731
    int_w = lambda t: (-amp / frq * np.cos(frq * t + ph)).sum(1)  # noqa: E731
    gn = np.array([0.0, 0.0, G])

    def rhs(t, x):
        C = x[:9].reshape(3, 3)  # C_b^n
        wt = w(t)
        K = np.array([[0, -wt[2], wt[1]], [wt[2], 0, -wt[0]], [-wt[1], wt[0], 0]])
        return np.concatenate([(C @ K).ravel(), C.T @ gn])

    return w, a, int_w, rhs


def _coupling(imu_fmu, timing, h=0.005, T=2.0):
    w, a, int_w, rhs = _profile()
    n = int(round(T / h))
    grid = np.arange(n + 1) * h
    sol = solve_ivp(rhs, (0, T), np.concatenate([np.eye(3).ravel(), np.zeros(3)]),
                    method="DOP853", rtol=1e-13, atol=1e-14, t_eval=grid)
    C = sol.y[:9].T.reshape(-1, 3, 3)
    f = np.einsum("kji,j->ki", C, [0.0, 0.0, G])
    int_f = np.diff(sol.y[9:].T, axis=0)
    table = {round(t / h): k for k, t in enumerate(grid)}
    prof = lambda t: motion(w(t), f[table[round(t / h)]], a(t))  # noqa: E731
    _, y = run(imu_fmu, {}, prof, h, n, timing=timing)
    int_wk = np.array([int_w(grid[k + 1]) - int_w(grid[k]) for k in range(n)])
    sig_g = np.radians(0.002) / 60 * np.sqrt(h)  # ARW 0.002 deg/sqrt(h)
    sig_a = 10e-6 * G * np.sqrt(h)  # VRW 10 ug/sqrt(Hz)
    return (np.max(np.abs(y[:, :3] - int_wk)) / sig_g, np.max(np.abs(y[:, 3:] - int_f)) / sig_a)


def test_coupling_error_below_noise(imu_fmu):
    rg, ra = _coupling(imu_fmu, timing=0)
    print(f"coupling error / per-sample noise, input_timing 0: gyro {rg:.2e}, acc {ra:.2e}")
    assert rg < 0.01 and ra < 0.01
    rg1, ra1 = _coupling(imu_fmu, timing=1)
    print(f"coupling error / per-sample noise, input_timing 1: gyro {rg1:.2e}, acc {ra1:.2e}")
    assert rg1 > rg and ra1 > ra


# ------------------------------------------------------------------------------ counts

def test_counts_track_increments(imu_fmu):
    p = {**NOISY, "seed": 4, "gyro.count_weight": 1e-6, "acc.count_weight": 1e-5}
    prof = lambda t: motion([0.3, -0.1, 0.05], [0.1, 0.2, G])  # noqa: E731
    _, inc = run(imu_fmu, p, prof, 0.005, 300)
    _, cnt = run(imu_fmu, {**p, "gyro.output": 2, "acc.output": 2}, prof, 0.005, 300)
    assert np.array_equal(cnt, np.round(cnt))
    wts = np.array([1e-6] * 3 + [1e-5] * 3)
    diff = np.abs(np.cumsum(cnt, 0) * wts - np.cumsum(inc, 0)) / wts
    assert diff.max() <= 0.5 + 1e-6  # remainder carried: never more than half a count


def test_rate_output_is_increment_over_h(imu_fmu):
    prof = lambda t: motion([0.3, -0.1, 0.05], [0.1, 0.2, G])  # noqa: E731
    _, inc = run(imu_fmu, {**NOISY, "seed": 4}, prof, 0.005, 20)
    _, rate = run(imu_fmu, {**NOISY, "seed": 4, "gyro.output": 1, "acc.output": 1}, prof, 0.005, 20)
    np.testing.assert_allclose(rate, inc / 0.005, rtol=1e-14)


# ------------------------------------------------------------------------------ bad input

@pytest.mark.parametrize("name,value", [
    ("gyro.bias.x", float("nan")),
    ("acc.lever.y.z", float("inf")),
    ("gyro.noise.arw", -1e-6),
    ("acc.noise.rrw", -1.0),
    ("gyro.noise.bi_tau", 0.0),
    ("gyro.output", 5),
    ("acc.output", -1),
    ("input_timing", 2),
    ("temperature.mode", 3),
])
def test_bad_parameter_named(imu_fmu, name, value):
    s = Slave(imu_fmu, {name: value}, initialize=False)
    try:
        with pytest.raises(FMICallException):
            s.fmu.exitInitializationMode()
        assert any(st >= 3 and f"parameter {name} =" in msg for st, msg in s.log), s.log
    finally:
        s.fmu.freeInstance()


def test_count_weight_zero_in_counts_mode(imu_fmu):
    s = Slave(imu_fmu, {"acc.output": 2, "acc.count_weight": 0.0}, initialize=False)
    try:
        with pytest.raises(FMICallException):
            s.fmu.exitInitializationMode()
        assert any("acc.count_weight" in msg for _, msg in s.log)
    finally:
        s.fmu.freeInstance()
    Slave(imu_fmu, {"acc.count_weight": 0.0}).close()  # fine when counts are not output


def test_time_offset_not_below_step(imu_fmu):
    s = Slave(imu_fmu, {"imu.time_offset": 0.01})
    try:
        with pytest.raises(FMICallException):
            s.step(0.005)
        assert any("imu.time_offset" in msg for _, msg in s.log)
    finally:
        s.fmu.freeInstance()


def test_nonfinite_input_named(imu_fmu):
    s = Slave(imu_fmu, {})
    try:
        s.step(0.01)
        s.set({"omega.y": float("nan")})
        with pytest.raises(FMICallException):
            s.step(0.01)
        assert any("input omega.y" in msg for _, msg in s.log)
    finally:
        s.fmu.freeInstance()


# ------------------------------------------------------------------------------ portable generator

M64 = (1 << 64) - 1


class PyXoshiro:
    """The documented generator restated in Python (Python floats are IEEE doubles with
    correctly rounded + - * / sqrt, so the same algorithm gives the same bits as the C)."""

    def __init__(self, state):
        self.s = list(state)

    @classmethod
    def seeded(cls, seed):
        x, st = seed & M64, []
        for _ in range(4):
            x = (x + 0x9E3779B97F4A7C15) & M64
            z = x
            z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M64
            z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & M64
            st.append(z ^ (z >> 31))
        return cls(st)

    @staticmethod
    def _rotl(x, k):
        return ((x << k) | (x >> (64 - k))) & M64

    def next(self):
        s = self.s
        result = (self._rotl((s[1] * 5) & M64, 7) * 9) & M64
        t = (s[1] << 17) & M64
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = self._rotl(s[3], 45)
        return result

    def jumped(self):
        j = PyXoshiro(self.s)
        acc = [0, 0, 0, 0]
        for word in (0x180EC6D33CFD0ABA, 0xD5A61266F0C9392C, 0xA9582618E03FC9AA, 0x39ABDC4529B1661C):
            for b in range(64):
                if word >> b & 1:
                    acc = [a ^ v for a, v in zip(acc, j.s)]
                j.next()
        return PyXoshiro(acc)

    def gauss(self):
        while True:
            u = (self.next() >> 11) * 2.0**-52 - 1.0
            v = (self.next() >> 11) * 2.0**-52 - 1.0
            q = u * u + v * v
            if 0.0 < q < 1.0:
                return u * math.sqrt(-2.0 * py_log(q) / q)


LN2_HI, LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10


def py_log(x):
    m, e = math.frexp(x)
    if m < 0.70710678118654752440:
        m, e = m * 2.0, e - 1
    z = (m - 1.0) / (m + 1.0)
    z2, s = z * z, 0.0
    for k in range(25, 2, -2):
        s = (s + 1.0 / k) * z2
    return e * LN2_HI + (e * LN2_LO + 2.0 * (z + z * s))


def test_portable_log_accuracy():
    x = np.random.default_rng(0).uniform(1e-300, 1.0, 20000) ** np.random.default_rng(1).uniform(0, 30, 20000)
    x = x[(x > 0) & (x < 1)]
    err = max(abs(py_log(v) - math.log(v)) / abs(math.log(v)) for v in x if v != 1.0)
    assert err < 4e-16


def test_white_noise_bits_match_documented_generator(imu_fmu):
    """White noise alone: output = (N sqrt(h)) w1, w1 the first of the four normals per axis and
    step after the three Gauss-Markov start draws of initialisation, from the documented streams."""
    N_g, N_a, h, seed, n = 3e-4, 7e-4, 0.01, -12345, 5
    _, y = run(imu_fmu, {"gyro.noise.arw": N_g, "acc.noise.vrw": N_a, "seed": seed}, None, h, n)
    gy = PyXoshiro.seeded(seed)
    streams = [gy, gy.jumped()]
    expect = np.empty((n, 6))
    for s, dens in zip(streams, (N_g, N_a)):
        for _ in range(3):
            s.gauss()
    for k in range(n):
        for si, (s, dens) in enumerate(zip(streams, (N_g, N_a))):
            for i in range(3):
                w = [s.gauss() for _ in range(4)]
                expect[k, 3 * si + i] = dens * math.sqrt(h) * w[0]
    assert np.array_equal(y, expect)


def test_flicker_draws_match_documented_streams(imu_fmu):
    """White noise plus the flicker bias instability: the white part as above from the gyro and
    accelerometer streams, the flicker terms (components/model/flicker.py) from their own
    streams, the gyro stream after two and three jumps: per axis per term one start draw, then
    per step per axis per term one normal; each term x1 = phi x0 + s sqrt(1 - phi^2) v,
    contribution (x0 + x1)/2 h. Equal to rounding: the FMU's exp and log are its own."""
    from components.model.flicker import flicker_terms

    N_g, N_a, h, seed, n = 3e-6, 7e-5, 0.05, 2024, 40  # white and flicker of like size
    flick = {"gyro": (2e-5, 10.0, 3600.0), "acc": (3e-4, 1.0, 100.0)}  # B, bi_tau, bi_tau_max
    p = {"gyro.noise.arw": N_g, "acc.noise.vrw": N_a, "seed": seed}
    for sensor, (B, lo, hi) in flick.items():
        p.update({f"{sensor}.noise.bi": B, f"{sensor}.noise.bi_tau": lo, f"{sensor}.noise.bi_tau_max": hi})
    _, y = run(imu_fmu, p, None, h, n)
    gy = PyXoshiro.seeded(seed)
    acc = gy.jumped()
    fgy = acc.jumped()
    streams, fstreams = [gy, acc], [fgy, fgy.jumped()]
    terms = [flicker_terms(*flick["gyro"]), flicker_terms(*flick["acc"])]
    for s in streams:
        for _ in range(3):
            s.gauss()
    x = [[[sg * f.gauss() for sg, _ in tm] for _ in range(3)] for f, tm in zip(fstreams, terms)]
    expect = np.empty((n, 6))
    for k in range(n):
        for si, dens in enumerate((N_g, N_a)):
            for i in range(3):
                w = [streams[si].gauss() for _ in range(4)]
                fl = 0.0
                for j, (sg, T) in enumerate(terms[si]):
                    phi = math.exp(-h / T)
                    x1 = phi * x[si][i][j] + sg * math.sqrt(1 - phi * phi) * fstreams[si].gauss()
                    fl += 0.5 * (x[si][i][j] + x1) * h
                    x[si][i][j] = x1
                expect[k, 3 * si + i] = dens * math.sqrt(h) * w[0] + fl
    scale = np.abs(expect).max(0)
    np.testing.assert_allclose(y / scale, expect / scale, rtol=0, atol=1e-12)


@pytest.mark.parametrize("timing", [0, 1])
def test_master_input_derivatives_used(imu_fmu, timing):
    """fmi2SetRealInputDerivatives: omega = b t^2/2 (alpha = b t, omega'' = b from the master)
    and f = c t^2 (f' = 2 c t from the master) are reproduced exactly, in both timings
    (timing 1: Taylor to order 2; timing 0: the Hermite cubic through exact slopes)."""
    b = np.array([0.3, -0.7, 0.2])
    c = np.array([1.5, 0.4, -2.0])
    h, n = 0.01, 8
    s = Slave(imu_fmu, {"input_timing": timing})
    vr_w = [s.vr(f"omega.{k}") for k in AX]
    vr_f = [s.vr(f"f.{k}") for k in AX]
    vr_a = [s.vr(f"alpha.{k}") for k in AX]
    try:
        y = []
        for _ in range(n):
            t = s.time + h if timing == 0 else s.time
            s.fmu.setReal(vr_w + vr_f + vr_a, [*(b * t**2 / 2), *(c * t**2), *(b * t)])
            s.fmu.setRealInputDerivatives(vr_f, [1, 1, 1], list(2 * c * t))
            if timing == 1:
                s.fmu.setRealInputDerivatives(vr_w, [2, 2, 2], list(b))
                s.fmu.setRealInputDerivatives(vr_f, [2, 2, 2], list(2 * c))
            s.step(h)
            y.append(s.fmu.getReal([s.vr(v) for v in OUT]))
    finally:
        s.close()
    ts = h * np.arange(1, n + 1)
    ta = ts - h
    exact_w = np.outer((ts**3 - ta**3) / 6, b)
    exact_f = np.outer((ts**3 - ta**3) / 3, c)
    y = np.array(y)
    np.testing.assert_allclose(y[:, :3], exact_w, rtol=1e-11, atol=1e-18)
    np.testing.assert_allclose(y[:, 3:], exact_f, rtol=1e-11, atol=1e-16)
