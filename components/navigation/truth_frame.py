"""The truth of a simulation in the frame a system-level configuration estimates in.

Without table angles nothing fixes the body frame's orientation but the sensors themselves. A
configuration that estimates all six gyro misalignments and only the lower triangle of the
accelerometers' (``acc.mis.yx, zx, zy``) works in the **accelerometer-defined frame**: x along the
x accelerometer, y in the plane of the x and y accelerometers. The simulation injects its
misalignments against the table's plate frame; the same IMU in the accelerometer-defined frame
has (to first order, the misalignments being small angles) the frame turned by the skew matrix
Θ with Θ_xy = −a_xy, Θ_xz = −a_xz, Θ_yz = −a_yz (a = the accelerometers' misalignments), which
adds Θ to both sensors' misalignment matrices (output_i += mis_ij · input_j):

    acc.mis.yx' = a_yx + a_xy      acc.mis.zx' = a_zx + a_xz      acc.mis.zy' = a_zy + a_yz
    gyro.mis.ij' = g_ij + Θ_ij     (Θ_yx = a_xy, Θ_zx = a_xz, Θ_zy = a_yz)

A configuration that holds the gyro misalignments from a table-referenced stage (seed_001's
CW/CCW closed forms) works in the table frame its gyros realise and estimates all six
accelerometer misalignments: its truth is the injected one.
"""
from __future__ import annotations

UPPER = ("xy", "xz", "yz")


def estimation_frame(parameters: list[str]) -> str:
    """"table" (the injected frame) or "accelerometer" (the lower-triangular gauge) for a result
    that estimated *parameters*."""
    acc = {p.rsplit(".", 1)[1] for p in parameters if p.startswith("acc.mis.")}
    gyro_mis = any(p.startswith("gyro.mis.") for p in parameters)
    lower_only = acc and not (acc & set(UPPER))
    return "accelerometer" if lower_only and gyro_mis else "table"


def truth_in_frame(injected: dict, frame: str) -> dict:
    """The injected effects (SI) as the configuration's frame sees them."""
    if frame == "table":
        return dict(injected)
    a = {ij: float(injected.get(f"acc.mis.{ij}", 0.0)) for ij in UPPER}
    theta = {"xy": -a["xy"], "xz": -a["xz"], "yz": -a["yz"], "yx": a["xy"], "zx": a["xz"], "zy": a["yz"]}
    out = {k: v for k, v in injected.items() if not (k.startswith("acc.mis.") and k.rsplit(".", 1)[1] in UPPER)}
    for ij, ji in (("yx", "xy"), ("zx", "xz"), ("zy", "yz")):
        out[f"acc.mis.{ij}"] = float(injected.get(f"acc.mis.{ij}", 0.0)) + a[ji]
    for ij, t in theta.items():
        out[f"gyro.mis.{ij}"] = float(injected.get(f"gyro.mis.{ij}", 0.0)) + t
    return out


def not_estimated(injected: dict, parameters: list[str], frame: str) -> list[str]:
    """Injected non-zero parameters the configuration has no state for (after the frame change,
    which moves the upper accelerometer terms into the lower ones): its estimates may be biased by
    them."""
    seen = truth_in_frame(injected, frame)
    return [p for p, v in seen.items() if v != 0.0 and p not in parameters]


def truth_of_result(injected: dict, parameters: list[str], frame: str) -> dict:
    """The truth a system-level result's *parameters* are judged against: the injected effects
    in *frame*; and the table stage's ``imu.time_offset`` as both offsets' sum, which is what its
    rows measure (the accelerometers at each index cannot tell a late IMU from a late
    accelerometer; docs/system-level.md)."""
    seen = truth_in_frame(injected, frame)
    if "imu.time_offset" in parameters:
        seen["imu.time_offset"] = float(injected.get("imu.time_offset", 0.0)) + float(injected.get("acc.time_offset", 0.0))
    return seen
