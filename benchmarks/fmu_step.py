"""Cost of one co-simulation step of each plant FMU (FMI 2.0), through fmpy and through raw ctypes.

For each FMU: microseconds per fmi2DoStep at a 5 ms communication step (the turntable runs its
servo at its default internal rate, servo.rate = 2 kHz, i.e. 10 controller ticks per step),

* via fmpy's ``FMU2Slave.doStep`` and via a raw ctypes call of ``fmi2DoStep`` on the same loaded
  library (the wrapper's overhead is the difference), and
* the same with the per-step coupling traffic of a real run: set the inputs another FMU would
  drive (turntable: the three angle commands; IMU: omega, f, alpha) and get the outputs another
  FMU would read (turntable: plate omega/alpha/f; IMU: gyro and accelerometer triads).

Run: ``python benchmarks/fmu_step.py [--steps N]``. Informative only; nothing asserts on speed.
"""
from __future__ import annotations

import argparse
import ctypes
import math
import shutil
import tempfile
import time

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from fmus.build import fmu_path, load_table

H = 0.005

# (inputs set per step, outputs read per step) of each FMU, in a table-driven form
COUPLING = {
    "turntable": ([f"{a}.angle_cmd" for a in ("outer", "middle", "inner")],
                  [f"plate.{q}.{c}" for q in ("omega", "alpha", "f") for c in "xyz"]),
    "imu": ([f"{q}.{c}" for q in ("omega", "f", "alpha") for c in "xyz"],
            [f"{s}.{c}" for s in ("gyro", "acc") for c in "xyz"]),
}


def input_values(model: str, t: float) -> list[float]:
    """Plausible, slowly varying inputs at time t."""
    if model == "turntable":
        return [0.2 * math.sin(0.5 * t), 0.1 * math.sin(0.3 * t), 0.5 * t]
    w = [0.1 * math.sin(t), 0.05, 0.2]
    return w + [0.01, -0.02, 9.81] + [0.1 * math.cos(t), 0.0, 0.0]


def _best_of(fn, repeats: int) -> float:
    best = math.inf
    for _ in range(repeats):
        best = min(best, fn())
    return best


def bench(model: str, steps: int, repeats: int) -> dict:
    path = fmu_path(model, 2)
    md = read_model_description(str(path))
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    in_names, out_names = COUPLING[model]
    in_vrs = [vrs[n] for n in in_names]
    out_vrs = [vrs[n] for n in out_names]
    unzip = extract(str(path), unzipdir=tempfile.mkdtemp(prefix="calbench-bench-"))
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzip,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=model)
    try:
        fmu.instantiate()
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        # precompute the input trajectory so both variants pay the same (nothing) for it
        inputs = [input_values(model, k * H) for k in range(steps)]
        state = {"t": 0.0}

        # ---- fmpy
        def fmpy_step_only() -> float:
            t = state["t"]
            t0 = time.perf_counter()
            for _ in range(steps):
                fmu.doStep(t, H)
                t += H
            dt = time.perf_counter() - t0
            state["t"] = t
            return dt

        def fmpy_coupled() -> float:
            t = state["t"]
            t0 = time.perf_counter()
            for k in range(steps):
                fmu.setReal(in_vrs, inputs[k])
                fmu.doStep(t, H)
                fmu.getReal(out_vrs)
                t += H
            dt = time.perf_counter() - t0
            state["t"] = t
            return dt

        # ---- raw ctypes on the same library and instance
        dll = fmu.dll
        c = ctypes.c_void_p(fmu.component)
        # own function objects (prototypes bound by name): fmpy's bindings stay untouched
        vr_p, dbl_p = ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(ctypes.c_double)
        do_step = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double,
                                   ctypes.c_double, ctypes.c_int)(("fmi2DoStep", dll))
        io_type = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, vr_p, ctypes.c_size_t, dbl_p)
        set_real = io_type(("fmi2SetReal", dll))
        get_real = io_type(("fmi2GetReal", dll))
        in_vr_arr = (ctypes.c_uint * len(in_vrs))(*in_vrs)
        out_vr_arr = (ctypes.c_uint * len(out_vrs))(*out_vrs)
        in_buf = (ctypes.c_double * len(in_vrs))()
        out_buf = (ctypes.c_double * len(out_vrs))()
        n_in, n_out = len(in_vrs), len(out_vrs)

        def ctypes_step_only() -> float:
            t = state["t"]
            t0 = time.perf_counter()
            for _ in range(steps):
                if do_step(c, t, H, 1) != 0:
                    raise RuntimeError("fmi2DoStep failed")
                t += H
            dt = time.perf_counter() - t0
            state["t"] = t
            return dt

        def ctypes_coupled() -> float:
            t = state["t"]
            t0 = time.perf_counter()
            for k in range(steps):
                in_buf[:] = inputs[k]
                if set_real(c, in_vr_arr, n_in, in_buf) != 0:
                    raise RuntimeError("fmi2SetReal failed")
                if do_step(c, t, H, 1) != 0:
                    raise RuntimeError("fmi2DoStep failed")
                if get_real(c, out_vr_arr, n_out, out_buf) != 0:
                    raise RuntimeError("fmi2GetReal failed")
                list(out_buf)  # the values as Python floats, like fmpy's getReal returns
                t += H
            dt = time.perf_counter() - t0
            state["t"] = t
            return dt

        fmpy_step_only()  # warm-up
        us = lambda s: s / steps * 1e6  # noqa: E731
        res = {
            "fmpy": us(_best_of(fmpy_step_only, repeats)),
            "ctypes": us(_best_of(ctypes_step_only, repeats)),
            "fmpy+io": us(_best_of(fmpy_coupled, repeats)),
            "ctypes+io": us(_best_of(ctypes_coupled, repeats)),
            "n_in": n_in, "n_out": n_out,
        }
        fmu.terminate()
        fmu.freeInstance()
        return res
    finally:
        shutil.rmtree(unzip, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=2000, help="steps per timed run (default 2000)")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs, best kept (default 5)")
    args = ap.parse_args()
    rate = next(v.start for v in load_table("turntable").variables if v.name == "servo.rate")
    print(f"communication step {H * 1e3:g} ms, turntable servo.rate {rate:g} Hz "
          f"({round(H * rate)} controller ticks per step); best of {args.repeats} x "
          f"{args.steps} steps; FMI 2.0")
    print(f"{'FMU':<10} {'variant':<28} {'fmpy us':>9} {'ctypes us':>10} {'fmpy/ctypes':>12}")
    for model in ("turntable", "imu"):
        r = bench(model, args.steps, args.repeats)
        rows = (("doStep", r["fmpy"], r["ctypes"]),
                (f"set {r['n_in']} + doStep + get {r['n_out']}", r["fmpy+io"], r["ctypes+io"]))
        for label, f, cc in rows:
            print(f"{model:<10} {label:<28} {f:9.2f} {cc:10.2f} {f / cc:12.2f}")


if __name__ == "__main__":
    main()
