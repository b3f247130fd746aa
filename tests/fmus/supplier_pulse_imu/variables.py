"""A supplier's pulse-output IMU, as ring-laser and many navigation IMUs deliver their data: the
number of whole pulses (angle and velocity quanta) in each interval, as Integer outputs, with the
pulse weights as the supplier's own parameters in arcsec and mm/s. Inputs deg/s and g, no
angular-acceleration input, no noise parameter and no seed: quantisation is its only noise.

Per axis: S(t) = the integral of (input + bias), the input the linear interpolation between the
previous input knot and the current one; the interval's pulses are floor(S(t+h)/w) - floor(S(t)/w),
so the pulses of a run sum to the integral within one pulse (no quantisation error accumulates)."""
from fmus.modeldef import ModelTable, integer, real

AX = "XYZ"
VARIABLES = (
    [real(f"GyroBias_{c}", "parameter", 0.0, "deg/h", f"gyro bias, {c}") for c in AX]
    + [real(f"AccBias_{c}", "parameter", 0.0, "mg", f"accelerometer bias, {c}") for c in AX]
    + [real("GyroPulseWeight", "parameter", 0.05, "arcsec", "angle of one gyro pulse")]
    + [real("AccPulseWeight", "parameter", 0.1, "mm/s", "velocity of one accelerometer pulse")]
    + [real(f"AngularRate_{c}", "input", 0.0, "deg/s", f"angular rate, {c}") for c in AX]
    + [real(f"Accel_{c}", "input", 0.0, "g", f"specific force, {c}") for c in AX]
    + [integer(f"GyroPulses_{c}", "output", 0, f"gyro pulses in the interval, {c}") for c in AX]
    + [integer(f"AccPulses_{c}", "output", 0, f"accelerometer pulses in the interval, {c}") for c in AX]
)

TABLE = ModelTable(
    identifier="acme_pulse_imu",
    description="ACME pulse-output IMU (test stand-in for a supplier FMU with count outputs)",
    variables=VARIABLES,
    sources=["model.c"],
    can_interpolate_inputs=False,
)
