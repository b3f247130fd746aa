"""Test FMU meant for role imu but not conforming: no input f.z, and omega.x is a parameter."""
from fmus.modeldef import ModelTable, real

TABLE = ModelTable(
    identifier="test_badimu",
    description="an IMU lacking f.z, with omega.x as a parameter",
    variables=[real("omega.x", "parameter", 0.0, "rad/s", "wrongly a parameter")]
    + [real(f"omega.{c}", "input", 0.0, "rad/s") for c in "yz"]
    + [real(f"f.{c}", "input", 0.0, "m/s2") for c in "xy"]
    + [real(f"gyro.{c}", "output", None, "rad") for c in "xyz"]
    + [real(f"acc.{c}", "output", None, "m/s") for c in "xyz"],
    sources=["model.c"],
)
