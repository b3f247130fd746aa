"""Seed 001's claim: the grouped (hybrid) calibration -- CW/CCW closed forms for the gyro scale
factors / misalignments (and the coarse accelerometer scale factors), then the 18-position
filter on the corrected data -- converges in fewer filter steps and to a smaller error than a
single system-level filter estimating everything on the same data.

Same simulated log (seed_001 schedule, navigation-grade white noise, the effects below) for both
configurations (components.navigation.configs seed_001, seed_001_single), one filter pass each
(the convergence history is the first pass's). Reported per configuration:
- final error per state, and the RMS over the states both estimate of error / target;
- filter steps (velocity updates) until every state's error stays within K x its target
  (K = 1 and 3), from the filter's history.

    python benchmarks/seed001_hybrid_vs_single.py [--seeds 2] [--dwell 10]
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from components.model.effects import ARCSEC, DEG_H, UG, effect_of
from components.navigation.configs import load_config
from components.navigation.system import calibrate_system
from components.simulation.run import run_scenario
from components.simulation.scenario import scenario_from_dict

TRUTH = {
    "gyro.bias.x": 0.008 * DEG_H, "gyro.bias.y": -0.005 * DEG_H, "gyro.bias.z": 0.01 * DEG_H,
    "gyro.sf.x": 10e-6, "gyro.sf.y": -8e-6, "gyro.sf.z": 12e-6,
    "gyro.mis.yz": 20 * ARCSEC, "gyro.mis.zy": -15 * ARCSEC, "gyro.mis.zx": 10 * ARCSEC,
    "acc.bias.x": 60 * UG, "acc.bias.y": -50 * UG, "acc.bias.z": 40 * UG,
    "acc.sf.x": 40e-6, "acc.sf.y": -30e-6, "acc.sf.z": 20e-6,
    "acc.mis.yx": 15 * ARCSEC, "acc.mis.zy": -20 * ARCSEC,
}
TARGET = {"gyro.bias": 0.003 * DEG_H, "gyro.sf": 2e-6, "gyro.mis": 2 * ARCSEC,
          "acc.bias": 10 * UG, "acc.sf": 5e-6, "acc.mis": 2 * ARCSEC}


def simulate(seed: int, dwell: float, sys_dwell: float):
    sc = scenario_from_dict({
        "scenario": {"name": f"s001-{seed}", "step": 0.005, "seed": seed},
        "schedule": {"name": "seed_001", "overrides": {"dwell": dwell, "sys_dwell": sys_dwell}},
        "site": {"latitude_deg": 39.9, "height_m": 50.0},
        "turntable": {"fmu": "builtin:turntable"},
        "imu": {"fmu": "builtin:imu", "effects": dict(TRUTH),
                "noise": {"gyro.noise.arw": "0.002 deg/sqrt(h)", "acc.noise.vrw": "10 ug/sqrt(Hz)"}},
    }, source="seed001 comparison")
    return run_scenario(sc, progress=False)


def rms_history(hist_v, params, fixed, truth, common):
    """RMS over the *common* states of error / target after each update (the earlier stages'
    values added: the filter's θ is a correction on top of them; states the filter does not
    carry keep the earlier stage's value)."""
    cols = {p: i for i, p in enumerate(params)}
    tgt = np.array([TARGET[effect_of(p).name] for p in common])
    tru = np.array([truth.get(p, 0.0) for p in common])
    val = np.array([[fixed.get(p, 0.0) + (h[cols[p]] if p in cols else 0.0) for p in common]
                    for h in hist_v])
    return np.sqrt(np.mean(((val - tru) / tgt) ** 2, axis=1))


def steps_below(r, level):
    """First update after which the RMS stays at or below level (None: never)."""
    bad = np.nonzero(r > level)[0]
    if len(bad) == 0:
        return 0
    return int(bad[-1] + 1) if bad[-1] + 1 < len(r) else None


def run_config(name: str, log, truth, passes: int = 1):
    cfg = load_config(name)
    cfg.stages = [replace(s, settings={**s.settings, "passes": passes}) for s in cfg.stages]
    t = time.time()
    res, outs = calibrate_system(log, cfg)
    wall = time.time() - t
    kf = [o for o in outs if o.filter is not None][-1]
    fixed = {}
    for o in outs:
        if o.filter is None:
            fixed.update(dict(zip(o.parameters, o.values)))
    f = kf.filter
    err = {p: v - truth.get(p, 0.0) for p, v in res.values.items()}
    return {"err": err, "sigma": res.sigmas, "updates": f.updates, "predictions": f.predictions,
            "states": 9 + len(kf.parameters), "wall": wall, "filter": f, "params": kf.parameters,
            "fixed": fixed}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--dwell", type=float, default=10.0)
    ap.add_argument("--sys-dwell", type=float, default=10.0)
    ap.add_argument("--passes", type=int, default=1)
    a = ap.parse_args()
    for seed in range(a.seeds):
        run = simulate(50 + seed, a.dwell, a.sys_dwell)
        truth = run.truth["effects"]
        out = {n: run_config(n, run.log, truth, a.passes) for n in ("seed_001", "seed_001_single")}
        common = [p for p in out["seed_001"]["err"] if p in out["seed_001_single"]["err"]]
        print(f"\nseed {seed}: {len(run.log.time)} samples; states in common {len(common)}")
        print(f"{'parameter':14s} {'hybrid err':>11s} {'single err':>11s} {'target':>8s} unit")
        for p in common:
            unit, k = effect_of(p).display
            print(f"{p:14s} {out['seed_001']['err'][p] / k:11.4g} "
                  f"{out['seed_001_single']['err'][p] / k:11.4g} {TARGET[effect_of(p).name] / k:8.3g} {unit}")
        hist = {n: rms_history(o["filter"].history_values, o["params"], o["fixed"], truth, common)
                for n, o in out.items()}
        finals = [h[-1] for h in hist.values()]
        levels = [2.0 * max(finals), 4.0 * max(finals), 10.0 * max(finals)]
        for n, o in out.items():
            nr = np.array([o["err"][p] / TARGET[effect_of(p).name] for p in common])
            st = ", ".join(f"<= {lv:.2f}: {steps_below(hist[n], lv)}" for lv in levels)
            print(f"{n:16s}: {o['states']} filter states, {o['updates']} updates/pass; "
                  f"RMS err/target {np.sqrt(np.mean(nr ** 2)):.3f} (max {np.abs(nr).max():.3f}); "
                  f"updates until the RMS stays {st}; wall {o['wall']:.1f} s")


if __name__ == "__main__":
    main()
