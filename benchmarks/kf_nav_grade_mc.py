"""Monte-Carlo of the seed-003 system-level filter with navigation-grade white noise
(ARW 0.002 deg/sqrt(h), VRW 10 ug/sqrt(Hz)) on the seed_003 schedule: error per state against
the issue's accuracy targets, normalised errors e/σ, and the NEES of the 39-state stage's 30
effect states against its 95 % band.

    /work/venv/bin/python benchmarks/kf_nav_grade_mc.py --runs 6 [--dwell 30 --exc-dwell 10]
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy.stats import chi2

from components.effects import ARCSEC, DEG_H, G0, UG, effect_of
from components.navigation.configs import load_config
from components.navigation.system import calibrate_system
from components.scenario import run_scenario, scenario_from_dict

TRUTH = {
    "gyro.bias.x": 0.01 * DEG_H, "gyro.bias.y": -0.02 * DEG_H, "gyro.bias.z": 0.015 * DEG_H,
    "acc.bias.x": 60 * UG, "acc.bias.y": -40 * UG, "acc.bias.z": 80 * UG,
    "gyro.sf.x": 20e-6, "gyro.sf.y": -15e-6, "gyro.sf.z": 25e-6,
    "gyro.mis.xy": 20 * ARCSEC, "gyro.mis.xz": -15 * ARCSEC, "gyro.mis.yx": 10 * ARCSEC,
    "gyro.mis.yz": 25 * ARCSEC, "gyro.mis.zx": -30 * ARCSEC, "gyro.mis.zy": 12 * ARCSEC,
    "acc.sf.x": 50e-6, "acc.sf.y": -30e-6, "acc.sf.z": 40e-6,
    "acc.mis.yx": 15 * ARCSEC, "acc.mis.zx": 30 * ARCSEC, "acc.mis.zy": -20 * ARCSEC,
    "acc.lever.x.y": 0.020, "acc.lever.x.z": -0.015, "acc.lever.y.x": 0.010,
    "acc.lever.y.z": 0.012, "acc.lever.z.x": -0.008, "acc.lever.z.y": 0.018,
    "acc.k2.x": 30 * UG / G0**2, "acc.k2.y": -20 * UG / G0**2, "acc.k2.z": 40 * UG / G0**2,
}
TARGET = {"gyro.bias": 0.003 * DEG_H, "gyro.sf": 2e-6, "gyro.mis": 2 * ARCSEC,
          "acc.bias": 10 * UG, "acc.sf": 5e-6, "acc.mis": 2 * ARCSEC, "acc.k2": 2 * UG / G0**2,
          "acc.lever": 2e-3, "imu.time_offset": 1e-4}


def one_run(seed: int, dwell: float, exc_dwell: float, cycles: int, config: str = "seed_003"):
    sc = scenario_from_dict({
        "scenario": {"name": f"mc{seed}", "step": 0.005, "seed": seed},
        "schedule": {"name": "seed_003", "overrides": {"dwell": dwell, "exc_dwell": exc_dwell,
                                                       "cycles": cycles}},
        "site": {"latitude_deg": 39.9, "height_m": 50.0},
        "turntable": {"fmu": "builtin:turntable",
                      "parameters": {f"{a}.encoder.bits": 0 for a in ("outer", "middle", "inner")}},
        "imu": {"fmu": "builtin:imu", "effects": dict(TRUTH),
                "noise": {"gyro.noise.arw": "0.002 deg/sqrt(h)", "acc.noise.vrw": "10 ug/sqrt(Hz)"}},
    }, source="mc")
    run = run_scenario(sc, progress=False)
    t = time.time()
    res, outs = calibrate_system(run.log, load_config(config))
    wall = time.time() - t
    truth = run.truth["effects"]
    err = {p: v - truth.get(p, 0.0) for p, v in res.values.items()}
    # NEES of the first (39-state) stage's effect states, with its full covariance; the values
    # of that stage (before the S204 bias filter replaced the gyro biases)
    so = outs[0]
    e1 = np.array([so.totals[i] - truth.get(p, 0.0) for i, p in enumerate(so.parameters)])
    nees1 = float(e1 @ np.linalg.solve(so.covariance, e1))
    so2 = outs[-1]
    e2 = np.array([so2.totals[i] - truth.get(p, 0.0) for i, p in enumerate(so2.parameters)])
    nees2 = float(e2 @ np.linalg.solve(so2.covariance, e2))
    return {"seed": seed, "err": err, "sigma": dict(res.sigmas), "nees_stage1": nees1,
            "dof_stage1": len(e1), "nees_stage2": nees2, "dof_stage2": len(e2),
            "wall_s": wall, "samples": len(run.log.time)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=6)
    ap.add_argument("--dwell", type=float, default=30.0)
    ap.add_argument("--exc-dwell", type=float, default=10.0)
    ap.add_argument("--cycles", type=int, default=2)
    ap.add_argument("--out", default="benchmarks/kf_nav_grade_mc.json")
    a = ap.parse_args()
    runs = []
    for s in range(a.runs):
        r = one_run(100 + s, a.dwell, a.exc_dwell, a.cycles)
        runs.append(r)
        print(f"run {s}: NEES stage1 {r['nees_stage1']:.1f}/{r['dof_stage1']}, stage2 "
              f"{r['nees_stage2']:.1f}/{r['dof_stage2']}, {r['wall_s']:.1f} s", flush=True)
        json.dump({"args": vars(a), "runs": runs}, open(a.out, "w"), indent=1)
    params = list(runs[0]["err"])
    N = len(runs)
    print(f"\n{'parameter':18s} {'rms err':>10s} {'mean sigma':>10s} {'rms e/s':>8s} {'target':>8s} unit")
    for p in params:
        e = np.array([r["err"][p] for r in runs])
        s = np.array([r["sigma"][p] for r in runs])
        unit, k = effect_of(p).display
        tgt = TARGET.get(effect_of(p).name, np.nan)
        rms = np.sqrt(np.mean(e ** 2))
        flag = "" if rms <= tgt else "  > target"
        print(f"{p:18s} {rms / k:10.4g} {s.mean() / k:10.4g} {np.sqrt(np.mean((e / s) ** 2)):8.2f} "
              f"{tgt / k:8.4g} {unit}{flag}")
    for st in ("stage1", "stage2"):
        d = runs[0][f"dof_{st}"]
        m = np.mean([r[f"nees_{st}"] for r in runs])
        lo, hi = chi2.ppf([0.025, 0.975], N * d) / N
        print(f"mean NEES {st}: {m:.2f} (dof {d}), 95 % band [{lo:.2f}, {hi:.2f}] over {N} runs")


if __name__ == "__main__":
    main()
