"""Design of the turntable's discrete position loop with python-control.

Plant per axis (torque -> angle):   P(s) = 1 / (J s^2 + B s)
Controller (error -> torque):       C(s) = K (s + w_i)/s * (1 + s/w_z)/(1 + s/w_p)
an integrator (zero a decade below crossover) for zero steady-state error against Coulomb
friction, and a lead network centred on the crossover w_c for the phase margin. C is discretised
with Tustin at the controller rate (pre-warped at w_c); the loop is checked on the ZOH-discretised
plant, and the lead is iterated until the discrete loop has the requested phase margin exactly at
the requested crossover. Feed-forward (J * alpha_ref + B * omega_ref) is added in the FMU.

``python -m fmus.turntable.design_servo`` prints the margins for the default axes.
"""
from __future__ import annotations

import math

import control
import numpy as np

from fmus.turntable import CONTROL_RATE_HZ

# What the default gains are designed for (variables.py makes them the FMU's defaults): motor +
# load inertia [kg m2] and viscous friction [N m s/rad] of a mid-size three-axis test table, per
# axis, outer first; the controller rate and the loop's targets.
DEFAULT_INERTIA = {"outer": 12.0, "middle": 5.0, "inner": 1.5}
DEFAULT_VISCOUS = {"outer": 0.8, "middle": 0.4, "inner": 0.15}
BANDWIDTH_HZ = 20.0
PHASE_MARGIN_DEG = 50.0


def plant(inertia: float, viscous: float) -> control.TransferFunction:
    """Continuous torque-to-angle transfer function of one axis [rad/(N m)]."""
    return control.tf([1.0], [inertia, viscous, 0.0])


def _continuous_controller(k: float, w_c: float, lead_deg: float) -> control.TransferFunction:
    s = math.sin(math.radians(lead_deg))
    beta = (1 + s) / (1 - s)
    w_z, w_p, w_i = w_c / math.sqrt(beta), w_c * math.sqrt(beta), w_c / 10.0
    integ = control.tf([1.0, w_i], [1.0, 0.0])
    lead = control.tf([1.0 / w_z, 1.0], [1.0 / w_p, 1.0])
    return k * integ * lead


def design_axis(inertia: float, viscous: float, bandwidth_hz: float, phase_margin_deg: float,
                rate_hz: float) -> dict:
    """Discrete controller coefficients and the loop's achieved margins.

    Returns ``b0, b1, b2, a1, a2`` of D(z) = (b0 + b1 z^-1 + b2 z^-2)/(1 + a1 z^-1 + a2 z^-2)
    [N m/rad], and ``crossover_hz``, ``phase_margin_deg``, ``gain_margin_db``.
    """
    T = 1.0 / rate_hz
    w_c = 2 * math.pi * bandwidth_hz
    p_d = control.c2d(plant(inertia, viscous), T, "zoh")
    lead = phase_margin_deg + 15.0  # first guess; corrected below on the discrete loop
    for _ in range(30):
        c = _continuous_controller(1.0, w_c, lead)
        c_d = control.c2d(c, T, "tustin", prewarp_frequency=w_c)
        loop_at_wc = complex((c_d * p_d)(np.exp(1j * w_c * T)))
        k = 1.0 / abs(loop_at_wc)
        pm = 180.0 + math.degrees(np.angle(loop_at_wc))
        err = phase_margin_deg - pm
        if abs(err) < 1e-6:
            break
        lead = min(lead + err, 85.0)
    c_d = control.c2d(_continuous_controller(k, w_c, lead), T, "tustin", prewarp_frequency=w_c)
    num = np.asarray(c_d.num[0][0], float)
    den = np.asarray(c_d.den[0][0], float)
    num = np.concatenate([np.zeros(3 - len(num)), num]) / den[0]
    den = den / den[0]
    gm, pm, _, wc = _margins(c_d * p_d, T)
    return {
        "b0": float(num[0]), "b1": float(num[1]), "b2": float(num[2]),
        "a1": float(den[1]), "a2": float(den[2]),
        "crossover_hz": float(wc) / (2 * math.pi), "phase_margin_deg": float(pm),
        "gain_margin_db": 20 * math.log10(gm) if np.isfinite(gm) else math.inf,
    }


def _margins(loop, T: float):
    """Gain margin (ratio), phase margin [deg], phase crossover and gain crossover [rad/s] of a
    discrete loop, from python-control's frequency response on a dense grid up to Nyquist."""
    w = np.geomspace(1e-1, 0.999 * math.pi / T, 200000)
    resp = control.frequency_response(loop, w)
    mag, phase = np.abs(resp.complex.ravel()), np.unwrap(np.angle(resp.complex.ravel()))
    i = np.nonzero((mag[:-1] >= 1) & (mag[1:] < 1))[0][0]
    pm = 180.0 + math.degrees(np.angle(resp.complex.ravel()[i]))
    # phase crossover above the gain crossover (below it the integrator keeps the phase near
    # -180 deg: the loop is conditionally stable there, which gain reduction does not threaten)
    phase = phase - 2 * math.pi * np.round((phase[i] - np.angle(resp.complex.ravel()[i])) / (2 * math.pi))
    j = i + np.nonzero((phase[i:-1] > -math.pi) & (phase[i + 1:] <= -math.pi))[0]
    gm = 1.0 / mag[j[0]] if len(j) else math.inf
    return gm, pm, (w[j[0]] if len(j) else math.nan), w[i]


def bandwidth_hz(closed, T: float) -> float:
    """-3 dB bandwidth of a discrete closed loop [Hz]."""
    w = np.geomspace(1e-1, 0.999 * math.pi / T, 200000)
    mag = np.abs(control.frequency_response(closed, w).complex.ravel())
    return float(w[np.nonzero(mag < 1 / math.sqrt(2))[0][0]]) / (2 * math.pi)


def discrete_controller(gains: dict, rate_hz: float) -> control.TransferFunction:
    return control.tf([gains["b0"], gains["b1"], gains["b2"]], [1.0, gains["a1"], gains["a2"]],
                      1.0 / rate_hz)


def closed_loop(gains: dict, inertia: float, viscous: float, rate_hz: float):
    """Reference-to-angle closed loop of the discrete controller on the ZOH plant, without
    feed-forward (the loop as a pure feedback system)."""
    p_d = control.c2d(plant(inertia, viscous), 1.0 / rate_hz, "zoh")
    return control.feedback(discrete_controller(gains, rate_hz) * p_d, 1)


def main() -> None:
    print(f"controller rate {CONTROL_RATE_HZ:g} Hz, crossover target {BANDWIDTH_HZ:g} Hz, "
          f"phase margin target {PHASE_MARGIN_DEG:g} deg")
    print(f"{'axis':8s} {'J':>6s} {'B':>6s} {'w_c [Hz]':>9s} {'PM [deg]':>9s} {'GM [dB]':>8s} "
          f"{'-3dB [Hz]':>9s} {'overshoot':>9s} {'t_s2% [ms]':>10s}")
    for a, J in DEFAULT_INERTIA.items():
        B = DEFAULT_VISCOUS[a]
        g = design_axis(J, B, BANDWIDTH_HZ, PHASE_MARGIN_DEG, CONTROL_RATE_HZ)
        cl = closed_loop(g, J, B, CONTROL_RATE_HZ)
        info = control.step_info(cl, SettlingTimeThreshold=0.02)
        bw = bandwidth_hz(cl, 1.0 / CONTROL_RATE_HZ)
        print(f"{a:8s} {J:6.2f} {B:6.2f} {g['crossover_hz']:9.3f} {g['phase_margin_deg']:9.3f} "
              f"{g['gain_margin_db']:8.2f} {bw:9.2f} {info['Overshoot']:8.2f}% "
              f"{1e3 * info['SettlingTime']:10.1f}")


if __name__ == "__main__":
    main()
