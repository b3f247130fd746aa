"""A supplier's IMU with a noise model and a seed, in units a vendor would choose: gyro bias in
deg/h, accelerometer bias in mg, one misalignment in urad, angle random walk in deg/sqrt(h), an
integer seed. Inputs deg/s and g, outputs mean rates in deg/s and g (as tests/fmus/supplier_imu).

Per axis: gyro = mean(ω) + bias + (axis x: mis_xy · mean(ω_y)) + white noise of density ARW;
accelerometer = mean(f) + bias; mean = the mean over [t, t+h] of the linear interpolation between
the previous input knot and the current one."""
from fmus.modeldef import ModelTable, integer, real

AX = "XYZ"
VARIABLES = (
    [real(f"GyroBias_{c}", "parameter", 0.0, "deg/h", f"gyro bias, {c}") for c in AX]
    + [real(f"AccBias_{c}", "parameter", 0.0, "mg", f"accelerometer bias, {c}") for c in AX]
    + [real("GyroMis_XY", "parameter", 0.0, "urad", "gyro x sensitivity to the rate about y")]
    + [real("GyroARW", "parameter", 0.0, "deg/sqrt(h)", "gyro angle random walk")]
    + [real(f"AngularRate_{c}", "input", 0.0, "deg/s", f"angular rate, {c}") for c in AX]
    + [real(f"Accel_{c}", "input", 0.0, "g", f"specific force, {c}") for c in AX]
    + [real(f"GyroRate_{c}", "output", None, "deg/s", f"mean angular rate over the interval, {c}") for c in AX]
    + [real(f"Accel_Out_{c}", "output", None, "g", f"mean specific force over the interval, {c}") for c in AX]
    + [integer("RandomSeed", "parameter", 1, "seed of the gyro noise")]
)

TABLE = ModelTable(
    identifier="acme_noisy_imu",
    description="ACME IMU with noise and a seed (test stand-in for a supplier FMU)",
    variables=VARIABLES,
    sources=["model.c"],
    can_interpolate_inputs=False,
)
