"""The turntable's step integrals (plate.omega_int, plate.f_int) and the IMU's quartic
interpolant that matches them (input_integrals 1): checked against an independent fine
integration of the servo ODE, closed forms, analytic profiles a cubic cannot follow, and the
turntable -> IMU system at a 10x finer step. Never against numbers captured from the FMUs."""
from __future__ import annotations

import math

import numpy as np

from fmus.turntable import variables as tv

from support import Slave

AXES = ("outer", "middle", "inner")
AX = "xyz"
DEG = math.pi / 180
OMEGA_E = 7.2921151467e-5
LAT = 39.9 * DEG
T_CTRL = 1.0 / tv.CONTROL_RATE_HZ
SIG_GYRO_5MS = 0.002 * DEG / 60 * math.sqrt(0.005)  # navigation-grade ARW per 5 ms sample [rad]


def normal_gravity(lat: float, h: float) -> float:
    a, f, m = 6378137.0, 1 / 298.257223563, 0.00344978650684
    s2 = math.sin(lat) ** 2
    g0 = 9.7803253359 * (1 + 0.00193185265241 * s2) / math.sqrt(1 - 0.00669437999013 * s2)
    return g0 * (1 - 2 / a * (1 + f + m - 2 * f * s2) * h + 3 * h * h / a ** 2)


def vec(s: Slave, name: str) -> np.ndarray:
    return s.get(*[f"{name}.{c}" for c in AX])


def _rzT(t, v):
    c, s = np.cos(t), np.sin(t)
    return np.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1], v[..., 2]], -1)


def _rxT(t, v):
    c, s = np.cos(t), np.sin(t)
    return np.stack([v[..., 0], c * v[..., 1] + s * v[..., 2], -s * v[..., 1] + c * v[..., 2]], -1)


def plate_rate_force(th: np.ndarray, thd: np.ndarray):
    """omega and f of the plate for the default geometry (outer z, middle x, inner z, level base,
    no errors): th, thd [..., 3] -> (omega [..., 3], f [..., 3])."""
    shape = th.shape[:-1] + (3,)
    w = np.broadcast_to([0.0, OMEGA_E * math.cos(LAT), OMEGA_E * math.sin(LAT)], shape).copy()
    f = np.broadcast_to([0.0, 0.0, normal_gravity(LAT, 50.0)], shape).copy()
    for k, (rT, ax) in enumerate([(_rzT, 2), (_rxT, 0), (_rzT, 2)]):
        w, f = rT(th[..., k], w), rT(th[..., k], f)
        w[..., ax] += thd[..., k]
    return w, f


# ------------------------------------------------------------------ turntable integrals

def test_integrals_match_fine_integration_of_the_servo_ode(turntable_fmu):
    """A 90 deg index of all three axes, stepped one controller tick at a time. For every tick,
    from the FMU's state at its start and the torque it held, the sliding axis ODE
    J th'' = u - B th' - Tc s (s the direction of motion: that of the rate, or of the torque when
    breaking away from rest) is integrated here with 64 RK4 substeps and the plate kinematics
    with composite Simpson over them; a stuck axis (rate 0 at both ends, angle unchanged) stays
    put. The FMU's per-tick integrals must agree. Ticks in which a rate reaches zero (friction
    switches inside the tick: the FMU splits the tick there) are checked against 4096 substeps
    with the switch located by linear interpolation."""
    s = Slave(turntable_fmu, {"outer.angle_cmd": 90 * DEG, "middle.angle_cmd": 90 * DEG,
                              "inner.angle_cmd": -90 * DEG})
    n = 3000
    ends = np.zeros((n + 1, 3, 2))
    torque, wint, fint = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    names = [f"{a}.{q}" for a in AXES for q in ("angle_true", "rate", "torque")]
    try:
        for j in range(n):
            s.step(T_CTRL)
            v = s.get(*names).reshape(3, 3)
            ends[j + 1], torque[j] = v[:, :2], v[:, 2]
            wint[j], fint[j] = vec(s, "plate.omega_int"), vec(s, "plate.f_int")
    finally:
        s.close()
    J = np.array([tv.DEFAULT_INERTIA[a] for a in AXES])
    B = np.array([tv.DEFAULT_VISCOUS[a] for a in AXES])
    Tc = np.array([tv.DEFAULT_COULOMB[a] for a in AXES])
    w0, w1 = ends[:-1, :, 1], ends[1:, :, 1]
    stuck = (w0 == 0) & (w1 == 0)
    # a rate reaching zero inside the tick (stop, or reversal)
    switch = ((w0 != 0) & (np.sign(w1) != np.sign(w0)))
    sgn = np.where(w0 != 0, np.sign(w0), np.sign(torque))

    def integrate(N, th, w, sgn_fixed):
        hs = T_CTRL / N
        traj = np.zeros((N + 1,) + th.shape + (2,))
        traj[0, ..., 0], traj[0, ..., 1] = th, w
        sg = sgn_fixed.copy()
        for i in range(N):
            acc = lambda w: np.where(stuck_now, 0.0, (tq - B * w - Tc * sg) / J)  # noqa: E731
            stuck_now = (w == 0) & (np.abs(tq) <= Tc)
            k1v = acc(w)
            k2p = w + 0.5 * hs * k1v
            k2v = acc(k2p)
            k3p = w + 0.5 * hs * k2v
            k3v = acc(k3p)
            k4p = w + hs * k3v
            k4v = acc(k4p)
            th_new = th + hs / 6 * (w + 2 * k2p + 2 * k3p + k4p)
            w_new = w + hs / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            if sgn_switch:  # crossing zero: stop there (linear interpolation) and re-decide
                cross = (w != 0) & (np.sign(w_new) != np.sign(w))
                f = np.where(cross, w / np.where(w == w_new, 1, w - w_new), 1.0)
                th_new = np.where(cross, th + f * (th_new - th), th_new)
                w_new = np.where(cross, 0.0, w_new)
                sg = np.where(cross, np.sign(tq), sg)
            th, w = th_new, w_new
            traj[i + 1, ..., 0], traj[i + 1, ..., 1] = th, w
        simpson = np.ones(N + 1)
        simpson[1:-1:2], simpson[2:-1:2] = 4, 2
        simpson *= hs / 3
        W, F = plate_rate_force(traj[..., 0], traj[..., 1])
        return np.einsum("i,ijk->jk", simpson, W), np.einsum("i,ijk->jk", simpson, F), traj[-1]

    tq = torque
    sgn_switch = False
    w_ref, f_ref, last = integrate(64, ends[:-1, :, 0], np.where(stuck, 0.0, w0), sgn)
    ew, ef = np.abs(wint - w_ref).max(1), np.abs(fint - f_ref).max(1)
    ev = switch.any(1)
    plain = ~ev
    print(f"\nomega_int per tick vs fine RK4 + Simpson: max {ew[plain].max():.2e} rad, median "
          f"{np.median(ew[plain]):.2e} over {plain.sum()} ticks without a friction switch; "
          f"f_int max {ef[plain].max():.2e} m/s; |omega_int| up to {np.abs(w_ref).max():.2e} rad; "
          f"{stuck.all(1).sum()} ticks with the whole table stuck")
    assert np.abs(w_ref).max() > 1e-3  # the table really moved
    assert stuck.all(1).sum() > 0.05 * n  # and came to rest (from 1.34 s)
    assert ev.sum() < 0.01 * n
    assert ew[plain].max() < 1e-13
    assert ef[plain].max() < 1e-11
    assert np.abs(last[plain, :, 0] - ends[1:][plain, :, 0]).max() < 1e-13
    if ev.any():
        tq = torque[ev]
        stuck = stuck[ev]
        sgn_switch = True
        w_e, _, _ = integrate(4096, ends[:-1][ev, :, 0], np.where(stuck, 0.0, w0[ev]), sgn[ev])
        err = np.abs(wint[ev] - w_e).max()
        print(f"{ev.sum()} ticks with a switch: max {err:.2e} rad")
        assert err < 1e-3 * SIG_GYRO_5MS


def test_integrals_sum_over_finer_steps(turntable_fmu):
    """The same index at 5 ms and at 0.5 ms: the fine steps' integrals add up to the coarse one."""
    cmd = {"outer.angle_cmd": 30 * DEG, "middle.angle_cmd": 90 * DEG}
    a, b = Slave(turntable_fmu, cmd), Slave(turntable_fmu, cmd)
    try:
        for _ in range(100):
            a.step(0.005)
            acc = np.zeros(6)
            for _ in range(10):
                b.step(0.0005)
                acc += np.concatenate([vec(b, "plate.omega_int"), vec(b, "plate.f_int")])
            coarse = np.concatenate([vec(a, "plate.omega_int"), vec(a, "plate.f_int")])
            assert np.abs(coarse - acc).max() <= 1e-15 * (1 + np.abs(coarse).max())
    finally:
        a.close()
        b.close()


def test_integrals_at_rest_are_rate_times_step(turntable_fmu):
    """At rest in a tilted attitude: integral = (C_n^p omega_ie^n) h, (C_n^p g) h (closed form)."""
    angles = (0.3, 1.1, -2.0)
    start = {f"{a}.{q}": th for a, th in zip(AXES, angles) for q in ("angle0", "angle_cmd")}
    start.update({f"{a}.encoder.bits": 0 for a in AXES})
    s = Slave(turntable_fmu, start)
    try:
        assert np.all(vec(s, "plate.omega_int") == 0.0)  # empty interval in Initialization Mode
        h = 0.005
        for _ in range(3):
            s.step(h)
        w, f = plate_rate_force(np.array(angles), np.zeros(3))
        np.testing.assert_allclose(vec(s, "plate.omega_int"), w * h, rtol=1e-12, atol=1e-22)
        np.testing.assert_allclose(vec(s, "plate.f_int"), f * h, rtol=1e-12, atol=1e-15)
    finally:
        s.close()


def test_integrals_at_constant_rate_closed_form(turntable_fmu):
    """One axis (z, level base) turning at a constant rate r: the plate rate is
    [W cos L sin th, W cos L cos th, W sin L + r], whose integral over a step with th linear is
    W cos L [cos th0 - cos th1, sin th1 - sin th0] / r and (W sin L + r) h; the z component is
    exactly (th1 - th0) + W sin L h for any motion."""
    r, h = 0.8, 0.005
    s = Slave(turntable_fmu, {"n_axes": 1, "outer.encoder.bits": 0})
    try:
        s.set({"outer.mode": 1, "outer.rate_cmd": r})
        for _ in range(500):  # 2.5 s: past the acceleration and the friction transient
            s.step(h)
        for _ in range(20):
            th0 = s.get("outer.angle_true")[0]
            s.step(h)
            th1 = s.get("outer.angle_true")[0]
            wc, ws = OMEGA_E * math.cos(LAT), OMEGA_E * math.sin(LAT)
            exp = np.array([wc * (math.cos(th0) - math.cos(th1)) / r,
                            wc * (math.sin(th1) - math.sin(th0)) / r, th1 - th0 + ws * h])
            got = vec(s, "plate.omega_int")
            # th0, th1 are rounded absolute angles (ulp 4.4e-16 at 2 rad), added to once per
            # tick; the integral is summed from the rates: a few ulps per tick apart
            assert abs(got[2] - exp[2]) < 1e-14
            assert abs(got[2] - (r + ws) * h) < 1e-12
            assert np.abs(got[:2] - exp[:2]).max() < 1e-19
    finally:
        s.close()


# ------------------------------------------------------------------ IMU with integrals

def _drive_imu(imu_fmu, params: dict, w, a, iw, f, fd, iff, h: float, n: int) -> np.ndarray:
    """Step the IMU n times (input_timing 0): before doStep(t, h) the values at t + h and the
    integrals over [t, t + h]; f's first derivative as an FMI input derivative. Returns the
    outputs [n, 6]."""
    s = Slave(imu_fmu, params, initialize=False)
    fvr = [s.vr(f"f.{c}") for c in AX]

    def knot(t1, t0):
        vals = {}
        for name, x in (("omega", w(t1)), ("alpha", a(t1)), ("f", f(t1)),
                        ("omega_int", iw(t1) - iw(t0)), ("f_int", iff(t1) - iff(t0))):
            vals.update({f"{name}.{c}": x[i] for i, c in enumerate(AX)})
        s.set(vals)
        s.fmu.setRealInputDerivatives(fvr, [1, 1, 1], list(fd(t1)))

    out = np.empty((n, 6))
    try:
        knot(0.0, 0.0)
        s.fmu.exitInitializationMode()
        for k in range(n):
            knot(s.time + h, s.time)
            s.step(h)
            out[k] = np.concatenate([vec(s, "gyro"), vec(s, "acc")])
    finally:
        s.close()
    return out


def _fast_profile():
    """Rates with a 30 Hz sinusoid and specific force with a 23 Hz one: over a 5 ms step a
    cubic through the end values and slopes misses them by ~1e-6."""
    A, Fw, ph = np.array([0.3, -0.2, 0.5]), 2 * np.pi * 30.0, np.array([0.1, 0.7, 1.3])
    B, Ff, g = np.array([0.5, 0.4, -0.3]), 2 * np.pi * 23.0, np.array([0.0, 0.0, 9.8])
    return dict(w=lambda t: 0.2 + A * np.sin(Fw * t + ph), a=lambda t: A * Fw * np.cos(Fw * t + ph),
                iw=lambda t: 0.2 * t - A / Fw * np.cos(Fw * t + ph),
                f=lambda t: g + B * np.sin(Ff * t), fd=lambda t: B * Ff * np.cos(Ff * t),
                iff=lambda t: g * t - B / Ff * np.cos(Ff * t))


LINEAR = {"gyro.bias.x": 1e-6, "gyro.sf.y": 2e-4, "gyro.mis.xz": 3e-4, "gyro.gsens.zx": 1e-5,
          "acc.bias.z": 5e-4, "acc.sf.x": -3e-5, "acc.mis.yx": 2e-4}


def _linear_model(x: np.ndarray, fint: np.ndarray, h: float) -> np.ndarray:
    """The increments of LINEAR's effects for the exact integrals x (gyro) and fint."""
    gy, ac = x.copy(), fint.copy()
    gy[:, 0] += LINEAR["gyro.bias.x"] * h
    gy[:, 1] += LINEAR["gyro.sf.y"] * x[:, 1]
    gy[:, 0] += LINEAR["gyro.mis.xz"] * x[:, 2]
    gy[:, 2] += LINEAR["gyro.gsens.zx"] * fint[:, 0]
    ac[:, 2] += LINEAR["acc.bias.z"] * h
    ac[:, 0] += LINEAR["acc.sf.x"] * fint[:, 0]
    ac[:, 1] += LINEAR["acc.mis.yx"] * fint[:, 0]
    return np.hstack([gy, ac])


def test_linear_effects_exact_for_motion_a_cubic_cannot_follow(imu_fmu):
    p, h, n = _fast_profile(), 0.005, 200
    grid = np.arange(n + 1) * h
    exact = _linear_model(np.diff(np.array([p["iw"](t) for t in grid]), axis=0),
                          np.diff(np.array([p["iff"](t) for t in grid]), axis=0), h)
    with_int = _drive_imu(imu_fmu, {**LINEAR, "input_integrals": 1}, **p, h=h, n=n)
    without = _drive_imu(imu_fmu, {**LINEAR, "input_integrals": 0}, **p, h=h, n=n)
    e1, e0 = np.abs(with_int - exact).max(0), np.abs(without - exact).max(0)
    print(f"\n30 Hz motion at 5 ms: max error with integrals gyro {e1[:3].max():.1e} rad, acc "
          f"{e1[3:].max():.1e} m/s; without: gyro {e0[:3].max():.1e}, acc {e0[3:].max():.1e}")
    assert e1[:3].max() < 1e-12 * np.abs(exact[:, :3]).max()
    assert e1[3:].max() < 1e-12 * np.abs(exact[:, 3:]).max()
    assert e0[:3].max() > 1e-7 and e0[3:].max() > 1e-7


def test_quartic_exact_with_time_offset_and_quadratic_effects(imu_fmu):
    """A motion that is one global quartic in time is reproduced exactly by the per-interval
    quartic, so windows shifted by imu.time_offset (split at the knots) integrate exactly, and
    quadratic effects (degree 8: the 5-point rule) too; the cubic interpolant is not exact."""
    cw = np.array([[0.1, 0.5, -2.0, 3.0, 40.0], [-0.2, 0.3, 1.0, -5.0, 60.0],
                   [0.05, -0.4, 2.5, 1.0, -30.0]])  # coefficients of t^0..t^4 per axis
    cf = np.array([[0.2, 1.0, -3.0, 4.0, 50.0], [-0.1, 0.5, 2.0, -6.0, 20.0],
                   [9.8, -0.3, 1.5, 2.0, -70.0]])
    P = [np.polynomial.Polynomial(c) for c in cw]
    Q = [np.polynomial.Polynomial(c) for c in cf]
    ev = lambda polys, t: np.array([q(t) for q in polys])  # noqa: E731
    prof = dict(w=lambda t: ev(P, t), a=lambda t: ev([q.deriv() for q in P], t),
                iw=lambda t: ev([q.integ() for q in P], t), f=lambda t: ev(Q, t),
                fd=lambda t: ev([q.deriv() for q in Q], t), iff=lambda t: ev([q.integ() for q in Q], t))
    h, n, dt = 0.005, 40, -0.4 * 0.005
    params = {"imu.time_offset": dt, "acc.k2.x": 1e-3, "gyro.g2sens.y.xz": 2e-4}
    exact = np.empty((n, 6))
    for k in range(n):
        a, b = k * h + dt, (k + 1) * h + dt
        gi = np.array([q.integ()(b) - q.integ()(a) for q in P])
        fi = np.array([q.integ()(b) - q.integ()(a) for q in Q])
        gi[1] += 2e-4 * ((Q[0] * Q[2]).integ()(b) - (Q[0] * Q[2]).integ()(a))
        fi[0] += 1e-3 * ((Q[0] ** 2).integ()(b) - (Q[0] ** 2).integ()(a))
        exact[k] = np.concatenate([gi, fi])
    with_int = _drive_imu(imu_fmu, {**params, "input_integrals": 1}, **prof, h=h, n=n)
    without = _drive_imu(imu_fmu, {**params, "input_integrals": 0}, **prof, h=h, n=n)
    # the first window starts before the first knot (extrapolated: cubic), so it is left out
    e1 = np.abs(with_int[1:] - exact[1:]).max()
    e0 = np.abs(without[1:] - exact[1:]).max()
    assert e1 < 1e-14, e1
    assert e0 > 1e3 * max(e1, 1e-16)


def test_late_imu_sums_stay_exact_where_the_motion_is_extrapolated(imu_fmu):
    """An IMU late on the table (imu.time_offset > 0) samples motion up to tau past the newest
    knot, which it can only extrapolate (the last cubic). The next step integrates that piece
    again on the knot that has arrived and adds the difference: each sample keeps a small error,
    but the sums of samples (the angle and velocity a navigation integrates) are the true
    motion's up to the last sample's extrapolated piece, instead of piling the errors up."""
    P = [np.polynomial.Polynomial(c) for c in ([0.1, 0.5, -2.0, 3.0, 400.0],
                                               [-0.2, 0.3, 1.0, -5.0, 600.0],
                                               [0.05, -0.4, 2.5, 1.0, -300.0])]
    Q = [np.polynomial.Polynomial(c) for c in ([0.2, 1.0, -3.0, 4.0, 500.0],
                                               [-0.1, 0.5, 2.0, -6.0, 200.0],
                                               [9.8, -0.3, 1.5, 2.0, -700.0])]
    ev = lambda polys, t: np.array([q(t) for q in polys])  # noqa: E731
    prof = dict(w=lambda t: ev(P, t), a=lambda t: ev([q.deriv() for q in P], t),
                iw=lambda t: ev([q.integ() for q in P], t), f=lambda t: ev(Q, t),
                fd=lambda t: ev([q.deriv() for q in Q], t), iff=lambda t: ev([q.integ() for q in Q], t))
    h, n, dt = 0.005, 60, 0.4 * 0.005
    out = _drive_imu(imu_fmu, {"imu.time_offset": dt, "input_integrals": 1}, **prof, h=h, n=n)
    edges = np.arange(n + 1) * h + dt
    exact = np.diff(np.array([np.concatenate([ev([q.integ() for q in P], t), ev([q.integ() for q in Q], t)])
                              for t in edges]), axis=0)
    per_sample = np.abs(out - exact).max()
    summed = np.abs(np.cumsum(out - exact, axis=0)).max()
    assert per_sample > 1e-12                     # the extrapolation is there (a cubic, not the quartic)
    assert summed <= 1.001 * per_sample, (summed, per_sample)   # without the re-integration: 60x


# ------------------------------------------------------------------ turntable -> IMU

def _index_system(turntable_fmu, imu_fmu, h: float, integrals: bool, T: float = 1.6) -> np.ndarray:
    """Turntable -> IMU (Gauss-Seidel, as the orchestrator), 90 deg index of the outer and middle
    axes from t = 0, noise off, the tumble example's linear errors. Gyro increments [n, 3]."""
    table = Slave(turntable_fmu, {"outer.angle_cmd": 90 * DEG, "middle.angle_cmd": 90 * DEG},
                  name="table")
    imu = Slave(imu_fmu, {"gyro.bias.x": 1e-7, "gyro.sf.y": 3e-5, "gyro.mis.xy": 2e-4,
                          "input_integrals": int(integrals)}, name="imu", initialize=False)
    src = ["plate.omega", "plate.f", "plate.alpha"] + (["plate.omega_int", "plate.f_int"] if integrals else [])
    dst = [n.split(".", 1)[1] for n in src]
    src_vr = [table.vr(f"{n}.{c}") for n in src for c in AX]
    dst_vr = [imu.vr(f"{n}.{c}") for n in dst for c in AX]
    gvr = [imu.vr(f"gyro.{c}") for c in AX]
    n = int(round(T / h))
    out = np.empty((n, 3))
    try:
        imu.fmu.setReal(dst_vr, table.fmu.getReal(src_vr))
        imu.fmu.exitInitializationMode()
        for k in range(n):
            table.step(h)
            imu.fmu.setReal(dst_vr, table.fmu.getReal(src_vr))
            imu.step(h)
            out[k] = imu.fmu.getReal(gvr)
    finally:
        table.close()
        imu.close()
    return out


def test_system_coupling_error_during_indexing(turntable_fmu, imu_fmu):
    """The 5 ms system against the same system at 0.5 ms (summed to the 5 ms grid)."""
    err = {}
    for integrals in (True, False):
        coarse = _index_system(turntable_fmu, imu_fmu, 0.005, integrals)
        fine = _index_system(turntable_fmu, imu_fmu, 0.0005, integrals).reshape(-1, 10, 3).sum(1)
        err[integrals] = float(np.sqrt(np.mean((coarse - fine) ** 2)))
        assert np.abs(coarse).max() > 1e-3  # it moved
    print(f"\nindexing, gyro increments 5 ms vs 0.5 ms: RMS {err[True]:.2e} rad with the integrals, "
          f"{err[False]:.2e} rad without (navigation-grade noise per sample {SIG_GYRO_5MS:.1e} rad)")
    assert err[True] < 0.01 * SIG_GYRO_5MS
    assert err[False] > 100 * err[True]
