"""A short, checkable co-simulation: the turntable FMU tumbles the IMU FMU through the six
axis-up attitudes; at each one the IMU's mean outputs are compared with the table's truth and
with what the injected errors predict.

Runs the two FMUs with fmpy in Gauss–Seidel order (table first, then the IMU fed with the
table's outputs at the end of the step), as the orchestrator does.
"""
from __future__ import annotations

import math
import shutil
import tempfile

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from fmus.build import fmu_path

DEG = math.pi / 180
DEG_PER_H = DEG / 3600
G0 = 9.80665
UG = 1e-6 * G0

# (label, outer, middle, inner) for the default geometry outer z, middle x, inner z
ATTITUDES = [
    ("z up", 0.0, 0.0, 0.0),
    ("z down", 0.0, 180.0, 0.0),
    ("y up", 0.0, 90.0, 0.0),
    ("y down", 0.0, -90.0, 0.0),
    ("x up", 0.0, 90.0, 90.0),
    ("x down", 0.0, 90.0, -90.0),
]

# A navigation-grade IMU with a few visible errors (SI units).
IMU_ERRORS = {
    "gyro.bias.x": 0.02 * DEG_PER_H, "gyro.bias.y": -0.01 * DEG_PER_H, "gyro.bias.z": 0.015 * DEG_PER_H,
    "acc.bias.x": 50 * UG, "acc.bias.y": -30 * UG, "acc.bias.z": 80 * UG,
    "acc.sf.x": 30e-6, "acc.sf.y": -20e-6, "acc.sf.z": 40e-6,
}
IMU_NOISE = {"gyro.noise.arw": 0.002 * DEG / 60, "acc.noise.vrw": 10 * UG}


class _Unit:
    """Minimal by-name access to one FMI 2 co-simulation FMU."""

    def __init__(self, path, name: str, start: dict):
        md = read_model_description(str(path))
        self._dir = extract(str(path), unzipdir=tempfile.mkdtemp(prefix="calbench-"))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.types = {v.name: v.type for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=self._dir,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        self.set(start)

    def set(self, values: dict) -> None:
        for k, v in values.items():
            if self.types[k] == "Integer":
                self.fmu.setInteger([self.vr[k]], [int(v)])
            else:
                self.fmu.setReal([self.vr[k]], [float(v)])

    def get(self, names: list[str]) -> np.ndarray:
        return np.array(self.fmu.getReal([self.vr[n] for n in names]))

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()
        shutil.rmtree(self._dir, ignore_errors=True)


PLATE = [f"plate.omega.{c}" for c in "xyz"] + [f"plate.f.{c}" for c in "xyz"] + \
        [f"plate.alpha.{c}" for c in "xyz"] + \
        [f"plate.omega_int.{c}" for c in "xyz"] + [f"plate.f_int.{c}" for c in "xyz"]
IMU_IN = [f"omega.{c}" for c in "xyz"] + [f"f.{c}" for c in "xyz"] + [f"alpha.{c}" for c in "xyz"] + \
    [f"omega_int.{c}" for c in "xyz"] + [f"f_int.{c}" for c in "xyz"]
IMU_OUT = [f"gyro.{c}" for c in "xyz"] + [f"acc.{c}" for c in "xyz"]


def run_tumble(seed: int = 1, dwell: float = 10.0, step: float = 0.005,
               settle_timeout: float = 10.0, summary: dict | None = None) -> int:
    """Exit status 0 when every attitude's IMU output matches truth + injected errors within 5 σ of
    the dwell mean's noise; *summary* (when given) receives the per-attitude figures for --json."""
    from components.errors import UserError
    from fmus.turntable import CONTROL_RATE_HZ

    SERVO_PERIOD = 1.0 / CONTROL_RATE_HZ
    multiple = step / SERVO_PERIOD
    if abs(multiple - round(multiple)) > 1e-9 * multiple or round(multiple) < 1:
        raise UserError(f"--step {step:g}: the turntable's servo runs every {SERVO_PERIOD * 1e3:g} ms, so the step "
                        "must be a whole multiple of it (e.g. 0.005)")
    if step > min(dwell, settle_timeout) / 20:
        raise UserError(f"--step {step:g}: the check needs at least 20 steps in a dwell ({dwell:g} s) and in the "
                        f"settling time ({settle_timeout:g} s): at most {min(dwell, settle_timeout) / 20:g} s")
    table = _Unit(fmu_path("turntable"), "table", {})
    # the table's integrals over each step make the IMU's increments exact through the servo
    # transients (input_integrals 1: see fmus/imu/model.c)
    imu = _Unit(fmu_path("imu"), "imu", {**IMU_ERRORS, **IMU_NOISE, "seed": seed, "input_integrals": 1})
    table.fmu.exitInitializationMode()
    imu.set(dict(zip(IMU_IN, table.get(PLATE))))
    imu.fmu.exitInitializationMode()
    t = 0.0

    def advance() -> tuple[np.ndarray, np.ndarray]:
        nonlocal t
        table.fmu.doStep(t, step)
        plate = table.get(PLATE)
        imu.set(dict(zip(IMU_IN, plate)))
        imu.fmu.doStep(t, step)
        t += step
        return plate, imu.get(IMU_OUT)

    n_dwell = int(round(dwell / step))
    sigma_f = IMU_NOISE["acc.noise.vrw"] / math.sqrt(dwell)  # σ of a dwell mean [m/s²]
    sigma_w = IMU_NOISE["gyro.noise.arw"] / math.sqrt(dwell)
    print("calbench tumble: turntable FMU -> IMU FMU, six attitudes, "
          f"{dwell:g} s dwell each, {step * 1e3:g} ms step, seed {seed}")
    print(f"{'attitude':8s} {'settle':>7s}  {'acc mean [m/s2]':>32s}  {'acc - truth - model [ug]':>26s}"
          f"  {'gyro - truth - bias [deg/h]':>28s}")
    worst = 0.0
    for label, o, m, i in ATTITUDES:
        table.set({"outer.angle_cmd": o * DEG, "middle.angle_cmd": m * DEG, "inner.angle_cmd": i * DEG})
        t_start, settled_for = t, 0.0
        while settled_for < 0.5:
            advance()
            err = max(abs(table.get([f"{a}.angle"])[0] - c * DEG)
                      for a, c in (("outer", o), ("middle", m), ("inner", i)))
            rate = max(abs(table.get([f"{a}.rate"])[0]) for a in ("outer", "middle", "inner"))
            settled_for = settled_for + step if (err < 2e-6 and rate < 1e-5) else 0.0
            if t - t_start > settle_timeout:
                print(f"{label}: table did not settle within {settle_timeout:g} s")
                return 1
        settle = t - t_start - 0.5
        sums = np.zeros(6)
        truth = np.zeros(6)
        for _ in range(n_dwell):
            plate, out = advance()
            sums += out
            truth += plate[9:15]  # the table's own integrals over the step
        T = n_dwell * step
        acc, f_true = sums[3:] / T, truth[3:] / T
        gyro, w_true = sums[:3] / T, truth[:3] / T
        ax = "xyz"
        acc_model = f_true * (1 + np.array([IMU_ERRORS[f"acc.sf.{c}"] for c in ax])) + \
            np.array([IMU_ERRORS[f"acc.bias.{c}"] for c in ax])
        gyro_model = w_true + np.array([IMU_ERRORS[f"gyro.bias.{c}"] for c in ax])
        ra, rg = (acc - acc_model) / UG, (gyro - gyro_model) / DEG_PER_H
        worst = max(worst, np.max(np.abs(acc - acc_model)) / sigma_f,
                    np.max(np.abs(gyro - gyro_model)) / sigma_w)
        if summary is not None:
            summary.setdefault("attitudes", {})[label] = {
                "settle_s": float(settle), "acc_mean_mps2": acc.tolist(), "acc_residual_ug": ra.tolist(),
                "gyro_residual_deg_per_h": rg.tolist()}
        print(f"{label:8s} {settle:6.2f}s  "
              f"{acc[0]:+10.6f} {acc[1]:+10.6f} {acc[2]:+10.6f}  "
              f"{ra[0]:+8.2f} {ra[1]:+8.2f} {ra[2]:+8.2f}  {rg[0]:+9.5f} {rg[1]:+9.5f} {rg[2]:+9.5f}")
    table.close()
    imu.close()
    print(f"noise sigma of a dwell mean: acc {sigma_f / UG:.2f} ug, gyro {sigma_w / DEG_PER_H:.5f} deg/h")
    verdict = "PASS" if worst < 5.0 else "FAIL"
    if summary is not None:
        summary.update(largest_residual_sigma=float(worst), verdict=verdict,
                       noise_sigma_acc_ug=float(sigma_f / UG), noise_sigma_gyro_deg_per_h=float(sigma_w / DEG_PER_H))
    print(f"largest residual {worst:.2f} sigma -> {verdict} (IMU output = truth + injected errors + noise)")
    return 0 if verdict == "PASS" else 1
