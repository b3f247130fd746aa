"""Orchestrator speed on the standard system: turntable FMU + IMU FMU + Python controller at 10 Hz
(AttitudeSequence, step_multiple 20), 5 ms step, one hour simulated by default.

Three engines, each pinned to one core (os.sched_setaffinity), each run in a fresh process:
  orchestrator  Simulation.run (native span loop between controller steps), Gauss–Seidel
  fmpy          a plain FMU2Slave loop: the same Gauss–Seidel algorithm and the same controller
                in Python, values exchanged with setReal/getReal on value-reference lists
  libcosim      libcosimpy on the two FMUs only. libcosim cannot host a Python component, so
                the controller's outputs are fixed initial values of the table's angle_cmd (the
                table holds one attitude); libcosim's algorithm is Jacobi, not Gauss–Seidel.
All three record the same 9 signals (IMU gyro/acc, table angles) every step.

    python benchmarks/orchestrator_speed.py [--hours 1.0]

Goal (issue): orchestrator >= 3x faster than the plain fmpy loop, and no slower than libcosim.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time

H = 0.005
D = math.pi / 180
RECORD = ["imu.gyro", "imu.acc", "table.outer.angle", "table.middle.angle", "table.inner.angle"]


def sequence(hours: float) -> list:
    """A new attitude every 60 s, cycling through the six axis-up attitudes."""
    att = [(0, 0, 0), (0, 180, 0), (0, 90, 0), (0, -90, 0), (0, 90, 90), (0, 90, -90)]
    n = max(1, int(hours * 3600 / 60))
    return [[60.0 * i, *(a * D for a in att[i % 6])] for i in range(n)]


def _system(hours: float, controller: bool):
    from components.simulation.tumble import IMU_ERRORS, IMU_NOISE
    from orchestrator.system import Connection, System, UnitSpec

    units = [UnitSpec("table", fmu="builtin:turntable", role="turntable",
                      parameters={} if controller else {"middle.angle_cmd": 90 * D}),
             UnitSpec("imu", fmu="builtin:imu", role="imu",
                      parameters={**IMU_ERRORS, **IMU_NOISE, "seed": 1, "input_integrals": 1})]
    conns = [Connection("table.plate.omega", "imu.omega"), Connection("table.plate.f", "imu.f"),
             Connection("table.plate.alpha", "imu.alpha"),
             Connection("table.plate.omega_int", "imu.omega_int"),
             Connection("table.plate.f_int", "imu.f_int")]
    if controller:
        units.insert(0, UnitSpec("ctrl", component="components.control.sequencer:AttitudeSequence",
                                 step_multiple=20, config={"sequence": sequence(hours)}))
        conns += [Connection(f"ctrl.{a}.angle_cmd", f"table.{a}.angle_cmd") for a in ("outer", "middle", "inner")]
    return System(name="bench", step=H, stop=hours * 3600, units=units, connections=conns,
                  record=RECORD, algorithm="gauss-seidel" if controller else "jacobi")


def run_orchestrator(hours: float) -> float:
    from orchestrator.master import Simulation

    sim = Simulation(_system(hours, True), progress=False)
    sim.load()
    t = time.perf_counter()
    sim.run()
    return time.perf_counter() - t


def run_libcosim(hours: float) -> float:
    from orchestrator.libcosim import run_libcosim as run

    rec = run(_system(hours, False))
    return rec.provenance["wall_time_s"]


def run_fmpy(hours: float) -> float:
    import shutil
    import tempfile

    import numpy as np
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    from components.control.sequencer import AttitudeSequence
    from components.simulation.tumble import IMU_ERRORS, IMU_NOISE
    from fmus.build import fmu_path

    def load(model, name):
        path = fmu_path(model, 2)
        md = read_model_description(str(path))
        d = extract(str(path), unzipdir=tempfile.mkdtemp(prefix="bench-"))
        f = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=name)
        f.instantiate()
        f.setupExperiment(startTime=0.0)
        f.enterInitializationMode()
        return f, {v.name: v.valueReference for v in md.modelVariables}, d

    table, tvr, td = load("turntable", "table")
    imu, ivr, idir = load("imu", "imu")
    for k, v in {**IMU_ERRORS, **IMU_NOISE}.items():
        imu.setReal([ivr[k]], [v])
    imu.setInteger([ivr["seed"]], [1])
    imu.setInteger([ivr["input_integrals"]], [1])
    ctrl = AttitudeSequence("ctrl", sequence(hours))
    axes = ("outer", "middle", "inner")
    cmd_vr = [tvr[f"{a}.angle_cmd"] for a in axes]
    src = [tvr[f"plate.{v}.{c}"] for v in ("omega", "f", "alpha", "omega_int", "f_int") for c in "xyz"]
    dst = [ivr[f"{v}.{c}"] for v in ("omega", "f", "alpha", "omega_int", "f_int") for c in "xyz"]
    rec_imu = [ivr[f"{s}.{c}"] for s in ("gyro", "acc") for c in "xyz"]
    rec_tab = [tvr[f"{a}.angle"] for a in axes]
    n = int(round(hours * 3600 / H))
    out = np.empty((n + 1, 9))
    t0 = time.perf_counter()
    ctrl.initialize(0.0)
    table.setReal(cmd_vr, [ctrl[f"{a}.angle_cmd"] for a in axes])
    table.exitInitializationMode()
    imu.setReal(dst, table.getReal(src))
    imu.exitInitializationMode()
    out[0] = imu.getReal(rec_imu) + table.getReal(rec_tab)
    for k in range(n):
        t = k * H
        if k % 20 == 0:
            ctrl.do_step(t, 20 * H)
            table.setReal(cmd_vr, [ctrl[f"{a}.angle_cmd"] for a in axes])
        table.doStep(t, H)
        imu.setReal(dst, table.getReal(src))
        imu.doStep(t, H)
        out[k + 1] = imu.getReal(rec_imu) + table.getReal(rec_tab)
    wall = time.perf_counter() - t0
    for f, d in ((table, td), (imu, idir)):
        f.terminate()
        f.freeInstance()
        shutil.rmtree(d, ignore_errors=True)
    return wall


ENGINES = {"orchestrator": run_orchestrator, "fmpy": run_fmpy, "libcosim": run_libcosim}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hours", type=float, default=1.0, help="simulated time [h] (default 1)")
    ap.add_argument("--core", type=int, default=0, help="CPU core to pin each run to")
    ap.add_argument("--engine", choices=sorted(ENGINES), help=argparse.SUPPRESS)  # child process
    args = ap.parse_args()
    if args.engine:
        os.sched_setaffinity(0, {args.core})
        print(json.dumps({"wall": ENGINES[args.engine](args.hours)}))
        return 0
    from fmus.build import fmu_path

    fmu_path("turntable", 2), fmu_path("imu", 2)  # build outside the timed runs
    n = int(round(args.hours * 3600 / H))
    print(f"standard system: turntable + IMU FMUs, AttitudeSequence at 10 Hz; h = {H} s, "
          f"{args.hours:g} h simulated = {n} steps; each engine alone on core {args.core}")
    walls = {}
    for name in ENGINES:
        r = subprocess.run([sys.executable, __file__, "--engine", name, "--hours", str(args.hours),
                            "--core", str(args.core)], capture_output=True, text=True)
        if r.returncode:
            print(f"{name}: failed\n{r.stderr}")
            continue
        walls[name] = json.loads(r.stdout.strip().splitlines()[-1])["wall"]
        note = " (two FMUs only: controller outputs fixed, Jacobi)" if name == "libcosim" else ""
        print(f"{name:13s} wall {walls[name]:8.2f} s   {walls[name] / n * 1e6:7.2f} us/step{note}")
    if "orchestrator" in walls:
        o = walls["orchestrator"]
        if "fmpy" in walls:
            print(f"fmpy / orchestrator     = {walls['fmpy'] / o:5.2f}x  (goal >= 3)")
        if "libcosim" in walls:
            print(f"libcosim / orchestrator = {walls['libcosim'] / o:5.2f}x  (goal >= 1)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
