"""A "supplier" IMU as a vendor would ship it: its own names, deg/s and g (unit definitions
with factors in the modelDescription), mean-rate outputs, no angular-acceleration input.

Per axis: out = (1 + SF) * mean + Bias, mean = the mean over [t, t+h] of the linear
interpolation between the previous input knot and the current one (inputs set before
doStep(t, h) are the values at t + h).

Fault injection for the campaign tests (default never): the doStep starting at SegfaultAt writes
through a NULL pointer (SIGSEGV); the one starting at HangAt loops for ever."""
from fmus.modeldef import ModelTable, real

AX = "XYZ"
VARIABLES = (
    [real("SegfaultAt", "parameter", 1e300, "s", "start time of the step that segfaults (test)"),
     real("HangAt", "parameter", 1e300, "s", "start time of the step that never returns (test)")]
    + [real(f"GyroBias_{c}", "parameter", 0.0, "deg/s", f"gyro bias, {c}") for c in AX]
    + [real(f"GyroSF_{c}", "parameter", 0.0, "1", f"gyro scale-factor error, {c}") for c in AX]
    + [real(f"AccBias_{c}", "parameter", 0.0, "g", f"accelerometer bias, {c}") for c in AX]
    + [real(f"AccSF_{c}", "parameter", 0.0, "1", f"accelerometer scale-factor error, {c}") for c in AX]
    + [real(f"AngularRate_{c}", "input", 0.0, "deg/s", f"angular rate, {c}") for c in AX]
    + [real(f"Accel_{c}", "input", 0.0, "g", f"specific force, {c}") for c in AX]
    + [real(f"GyroRate_{c}", "output", None, "deg/s", f"mean angular rate over the interval, {c}")
       for c in AX]
    + [real(f"Accel_Out_{c}", "output", None, "g", f"mean specific force over the interval, {c}")
       for c in AX]
)

TABLE = ModelTable(
    identifier="acme_imu",
    description="ACME tactical IMU (test stand-in for a supplier FMU)",
    variables=VARIABLES,
    sources=["model.c"],
    can_interpolate_inputs=False,
)
