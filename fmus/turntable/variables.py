"""Variable table of the turntable FMU (role ``turntable``): the single source of its
modelDescription.xml and C value references. Units SI; angles in rad."""
from __future__ import annotations

import math

from fmus.modeldef import ModelTable, integer, real
from fmus.turntable.design_servo import (
    BANDWIDTH_HZ,
    CONTROL_RATE_HZ,
    DEFAULT_INERTIA,
    DEFAULT_VISCOUS,
    PHASE_MARGIN_DEG,
    design_axis,
)

# The servo design's inputs (inertia, viscous friction, rates) are defined with the design, in
# design_servo.py, which must not import this module back; they are the defaults below and are
# read from here too.

AXES = ("outer", "middle", "inner")
DEFAULT_AXIS = {"outer": (0.0, 0.0, 1.0), "middle": (1.0, 0.0, 0.0), "inner": (0.0, 0.0, 1.0)}
# Coulomb friction of the same table as the design's inertia and viscous friction.
DEFAULT_COULOMB = {"outer": 0.6, "middle": 0.3, "inner": 0.1}
DEFAULT_TORQUE_MAX = {"outer": 300.0, "middle": 150.0, "inner": 60.0}
DEG = math.pi / 180.0


def _axis_variables(a: str) -> list:
    gains = design_axis(DEFAULT_INERTIA[a], DEFAULT_VISCOUS[a], BANDWIDTH_HZ, PHASE_MARGIN_DEG,
                        CONTROL_RATE_HZ)
    ax = DEFAULT_AXIS[a]
    v = [
        real(f"{a}.axis.{c}", "parameter", ax[k], "1",
             f"{a} stage rotation axis, {c} component, in the previous stage's frame at zero angle")
        for k, c in enumerate("xyz")
    ]
    v += [
        real(f"{a}.inertia", "parameter", DEFAULT_INERTIA[a], "kg.m2", "motor + load inertia"),
        real(f"{a}.viscous", "parameter", DEFAULT_VISCOUS[a], "N.m.s/rad", "viscous friction"),
        real(f"{a}.coulomb", "parameter", DEFAULT_COULOMB[a], "N.m",
             "Coulomb (sliding) friction torque"),
        real(f"{a}.static_friction", "parameter", 0.0, "N.m",
             "static friction (breakaway) torque; values below coulomb, e.g. the default 0, "
             "mean equal to coulomb"),
        real(f"{a}.torque_max", "parameter", DEFAULT_TORQUE_MAX[a], "N.m", "motor torque limit"),
        real(f"{a}.rate_max", "parameter", 300.0 * DEG, "rad/s", "rate limit of the reference"),
        real(f"{a}.acc_max", "parameter", 200.0 * DEG, "rad/s2",
             "acceleration limit of the reference"),
        real(f"{a}.angle0", "parameter", 0.0, "rad", "true angle at start"),
    ]
    # discrete position controller D(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2),
    # error [rad] -> torque [N.m], designed by design_servo.py for the default inertia
    for name in ("b0", "b1", "b2", "a1", "a2"):
        v.append(real(f"{a}.ctrl.{name}", "parameter", gains[name], None,
                      f"position controller coefficient {name} (design_servo.py)"))
    v += [
        integer(f"{a}.encoder.bits", "parameter", 24,
                "encoder resolution: 2^bits counts per revolution (0: no quantisation)"),
        real(f"{a}.encoder.h1.amp", "parameter", 0.0, "rad", "1st-harmonic encoder error"),
        real(f"{a}.encoder.h1.phase", "parameter", 0.0, "rad", "its phase"),
        real(f"{a}.encoder.h2.amp", "parameter", 0.0, "rad", "2nd-harmonic encoder error"),
        real(f"{a}.encoder.h2.phase", "parameter", 0.0, "rad", "its phase"),
        real(f"{a}.encoder.reversal", "parameter", 0.0, "rad",
             "reversal error (backlash between the plate and the encoder, a play of this width): "
             "after a move longer than it the plate rests half of it past the reading, on the side "
             "it came from"),
    ]
    v += [
        real(f"{a}.nonorth.{c}", "parameter", 0.0, "rad",
             f"small rotation of the {a} axis vector about {c} of the previous stage (non-orthogonality)")
        for c in "xyz"
    ]
    v += [
        real(f"{a}.wobble.amp", "parameter", 0.0, "rad", "first-harmonic tilt of the axis"),
        real(f"{a}.wobble.phase", "parameter", 0.0, "rad", "its phase"),
        integer(f"{a}.mode", "input", 0, "0: position (index to angle_cmd), 1: rate (rate_cmd)"),
        real(f"{a}.angle_cmd", "input", 0.0, "rad", "commanded angle (position mode)"),
        real(f"{a}.rate_cmd", "input", 0.0, "rad/s",
             "commanded rate (rate mode) or rate feed-forward of a moving angle command"),
        real(f"{a}.angle", "output", None, "rad", "measured (encoder) angle, multi-turn"),
        real(f"{a}.rate", "output", None, "rad/s", "axis rate"),
        real(f"{a}.angle_true", "output", None, "rad", "true angle (simulation truth)"),
        real(f"{a}.angle_ref", "output", None, "rad", "reference angle of the servo loop"),
        real(f"{a}.torque", "output", None, "N.m", "motor torque"),
    ]
    return v


VARIABLES = [
    integer("n_axes", "parameter", 3, "number of stages (1 to 3), outer first", min=1, max=3),
    real("servo.rate", "parameter", CONTROL_RATE_HZ, "Hz",
         "controller rate; the communication step must be a multiple of its period"),
    real("servo.feedforward", "parameter", 1.0, "1",
         "1: add J*alpha_ref + B*omega_ref + coulomb*sign(omega_ref) to the controller "
         "torque, 0: pure feedback"),
    real("servo.stick_velocity", "parameter", 1e-6, "rad/s",
         "Karnopp band: an axis slower than this whose applied torque is within the static "
         "friction sticks (rate set to exactly 0)"),
    real("site.latitude", "parameter", 39.9 * DEG, "rad", "geodetic latitude"),
    real("site.height", "parameter", 50.0, "m", "height above the ellipsoid"),
    real("site.gravity", "parameter", 0.0, "m/s2",
         "local gravity magnitude; 0 = WGS-84 normal gravity at latitude and height"),
    real("site.earth_rate", "parameter", 7.2921151467e-5, "rad/s", "Earth rotation rate"),
    real("base.tilt.x", "parameter", 0.0, "rad", "base rotation about east from level"),
    real("base.tilt.y", "parameter", 0.0, "rad", "base rotation about north from level"),
    real("base.azimuth", "parameter", 0.0, "rad", "base rotation about up (x axis from east toward north)"),
]
for _a in AXES:
    VARIABLES += _axis_variables(_a)
VARIABLES += [real(f"plate.omega.{c}", "output", None, "rad/s",
                   f"inertial angular rate of the plate, plate {c} axis (Earth rate included)")
              for c in "xyz"]
VARIABLES += [real(f"plate.alpha.{c}", "output", None, "rad/s2",
                   f"angular acceleration of the plate (d/dt of plate.omega in plate axes), {c}")
              for c in "xyz"]
VARIABLES += [real(f"plate.f.{c}", "output", None, "m/s2",
                   f"specific force at the plate reference point, plate {c} axis")
              for c in "xyz"]
VARIABLES += [real(f"plate.omega_int.{c}", "output", None, "rad",
                   f"integral of plate.omega.{c} over the communication step just ended "
                   "(closed-form axis motion, 2-point Gauss per smooth piece of each tick)")
              for c in "xyz"]
VARIABLES += [real(f"plate.f_int.{c}", "output", None, "m/s",
                   f"integral of plate.f.{c} over the communication step just ended")
              for c in "xyz"]
VARIABLES += [real(f"plate.q.{c}", "output", None, "1",
                   f"attitude quaternion of the plate w.r.t. ENU (C_p^n), {c} component")
              for c in "wxyz"]

TABLE = ModelTable(
    identifier="calbench_turntable",
    description="calbench three-axis turntable: servo loops, gimbal chain, base, Earth",
    variables=VARIABLES,
    sources=["model.c", "gimbal.c", "servo.c"],
    default_step=0.005,
)
