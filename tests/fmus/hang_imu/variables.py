"""A badly behaved supplier IMU for campaign tests: the supplier_imu model (own names, deg/s
and g, mean-rate outputs) whose doStep HANGS (loops forever) in the step that starts at
FailAt (default never)."""
from fmus.modeldef import ModelTable, real

AX = "XYZ"
VARIABLES = (
    [real("FailAt", "parameter", 1e300, "s", "start time of the step that misbehaves")]
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
    identifier="acme_hang_imu",
    description="ACME IMU that HANGS (loops forever) at FailAt (test stand-in for a broken supplier FMU)",
    variables=VARIABLES,
    sources=["model.c"],
    can_interpolate_inputs=False,
)
