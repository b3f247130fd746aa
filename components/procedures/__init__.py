"""Classical calibration procedures (one module each), each one call on a log:

- ``cwccw``: gyro scale factors / misalignments from CW/CCW whole turns, accelerometer bias,
  scale factors / misalignments from ± static positions (seeds 003 S201/S202, 001 steps 2-4, 7)
- ``tilt`` / ``tilt_ignored``: seed 000, base tilt from four outer positions then the
  multi-position accelerometer calibration with / without the tilt in the geometry
- ``latitude``: seed 002, vertical, east, attitude and latitude with one accelerometer and one
  gyro on a three-gimbal device (drives the co-simulation adaptively: ``latitude.drive``)

``run(name, log_or_data, **options)`` -> components.model.result.CalibrationResult.
"""
from __future__ import annotations

from importlib import import_module

PROCEDURES = {
    "cwccw": ("components.procedures.cwccw", "run"),
    "tilt": ("components.procedures.tilt", "run"),
    "tilt_ignored": ("components.procedures.tilt", "run_ignored"),
    "latitude": ("components.procedures.latitude", "run"),
}


def get(name: str):
    if name not in PROCEDURES:
        raise KeyError(f"unknown procedure {name!r}; expected one of {', '.join(PROCEDURES)}")
    mod, fn = PROCEDURES[name]
    return getattr(import_module(mod), fn)


def run(name: str, log_or_data, **options):
    return get(name)(log_or_data, **options)
