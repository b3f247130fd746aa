"""The user's loop at MEMS grade, as a user runs it: an industrial MEMS IMU (errors a thousand
times navigation grade: gyro biases of 25-40 deg/h, scale factors of 1000-2000 ppm) with its
coloured noise (gyro ARW 0.3 deg/sqrt(h), bias instability 8 deg/h as a flicker floor from 10 s
to an hour, rate random walk 3 deg/h/sqrt(h); accelerometer VRW 60 ug/sqrt(Hz), bias instability
20 ug, random walk 10 ug/sqrt(h)) and a hidden K2 of 300 ug/g2 on z, on the twenty-six-position
schedule (36 minutes at 200 Hz); with ``--thermal``, a heat, soak and cool (25 -> 45 -> 25 degC,
the scenario's [temperature] profile) and a hidden 20 ug/K on acc_z besides; with ``--ramp``, the
same 20 ug/K under a single ramp of 0.01 K/s from 25 degC instead (on a ramp acc.temp and
acc.drift are one column: either may be named, and a drift's truth is then the coefficient times
the ramp's rate, 720 ug/h). With ``--counts "1 arcsec,0.1 mm/s"`` the IMU gives pulse counts of
those weights instead of increments (the accelerometer's count coarser than a sample's noise,
4.2e-5 m/s at 200 Hz: most of its sample differences are 0), the loop's noise identified with
the counts' quantization as a term of its own.

    calbench simulate; calbench calibrate (the default model);
    then, until diagnose names nothing: calbench diagnose --noise identify, calbench add --effect VERDICT --noise identify

Printed: each step's verdict and chi2/dof, the identified noise against the injected, and each
parameter of the last model against the truth: z = (estimate - truth) / sigma, their RMS (1 for
honest sigma; the baseline named: a standard normal's, with its 99 % band for this many
parameters from the chi-square distribution) and the largest |z|.

    python benchmarks/mems_grade.py [--seed 19] [--thermal | --ramp] [--counts GYRO,ACC]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]

SCENARIO = """
[scenario]
name = "mems-26"
description = "industrial MEMS IMU, coloured noise, hidden K2 on z"
step = 0.005
seed = {seed}

[schedule]
name = "twentysix_position"

[site]
latitude_deg = 45.0
height_m = 100.0

[turntable]
fmu = "builtin:turntable"

[imu]
fmu = "builtin:imu"
{outputs}
[imu.effects]
"gyro.bias.x" = "40 deg/h"
"gyro.bias.y" = "-25 deg/h"
"gyro.bias.z" = "30 deg/h"
"gyro.sf.x" = "2000 ppm"
"gyro.sf.y" = "-1500 ppm"
"gyro.sf.z" = "1000 ppm"
"gyro.mis.xy" = "600 arcsec"
"gyro.mis.xz" = "-400 arcsec"
"gyro.mis.yx" = "300 arcsec"
"gyro.mis.yz" = "-500 arcsec"
"gyro.mis.zx" = "450 arcsec"
"gyro.mis.zy" = "-350 arcsec"
"acc.bias.x" = "3 mg"
"acc.bias.y" = "-2 mg"
"acc.bias.z" = "4 mg"
"acc.sf.x" = "2000 ppm"
"acc.sf.y" = "-1500 ppm"
"acc.sf.z" = "1200 ppm"
"acc.mis.yx" = "500 arcsec"
"acc.mis.zx" = "-400 arcsec"
"acc.mis.zy" = "300 arcsec"
"acc.k2.z" = "300 ug/g2"
{thermal_effect}
[imu.noise]
"gyro.noise.arw" = "0.3 deg/sqrt(h)"
"gyro.noise.bi" = "8 deg/h"
"gyro.noise.bi_tau" = 10.0
"gyro.noise.bi_tau_max" = 3600.0
"gyro.noise.rrw" = "3 deg/h/sqrt(h)"
"acc.noise.vrw" = "60 ug/sqrt(Hz)"
"acc.noise.bi" = "20 ug"
"acc.noise.bi_tau" = 10.0
"acc.noise.bi_tau_max" = 3600.0
"acc.noise.rrw" = "10 ug/sqrt(h)"
{thermal_profile}
"""
THERMAL_EFFECT = '"acc.temp.z" = "20 ug/K"'
THERMAL_PROFILE = "[temperature]\nprofile = [[0, 25], [600, 45], [1200, 45], [1800, 25]]"
RAMP_RATE = 0.01  # K/s
RAMP_PROFILE = f"[temperature]\nprofile = [[0, 25], [3600, {25 + 3600 * RAMP_RATE}]]"


def calbench(*args: str, json_out: Path | None = None) -> dict | None:
    cmd = [sys.executable, "-m", "components.cli", *args] + (["--json", str(json_out)] if json_out else [])
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if p.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(args)} exited {p.returncode}:\n{p.stderr[-2000:]}")
    return json.loads(json_out.read_text()) if json_out else None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=19)
    kind = ap.add_mutually_exclusive_group()
    kind.add_argument("--thermal", action="store_true", help="a heat, soak and cool with 20 ug/K on acc_z besides")
    kind.add_argument("--ramp", action="store_true", help="a single 0.01 K/s ramp with 20 ug/K on acc_z besides")
    ap.add_argument("--counts", help="pulse outputs of these count weights, with units: GYRO,ACC (e.g. "
                    "'1 arcsec,0.1 mm/s')")
    a = ap.parse_args()
    outputs = ""
    if a.counts:
        weights = [w.strip() for w in a.counts.split(",")]
        if len(weights) != 2:
            ap.error("--counts takes two weights, GYRO,ACC")
        outputs = (f'gyro_output = "counts"\nacc_output = "counts"\n'
                   f'count_weight = {{gyro = "{weights[0]}", acc = "{weights[1]}"}}')
    profile = THERMAL_PROFILE if a.thermal else RAMP_PROFILE if a.ramp else ""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "mems.toml").write_text(SCENARIO.format(seed=a.seed, thermal_effect=THERMAL_EFFECT if profile else "",
                                                     thermal_profile=profile, outputs=outputs))
        calbench("simulate", str(d / "mems.toml"), "--out", str(d / "log"))
        log = str(d / "log.json")
        calbench("calibrate", log, "--out", str(d / "m0.json"))
        model, added = d / "m0.json", []
        what = ", heat/soak/cool" if a.thermal else f", a {RAMP_RATE} K/s ramp" if a.ramp else ""
        print(f"MEMS grade, seed {a.seed}{what + ' with acc.temp.z 20 ug/K' if profile else ''}; "
              f"hidden acc.k2.z 300 ug/g2{'; pulse counts of ' + a.counts if a.counts else ''}")
        for k in range(4):
            diag = calbench("diagnose", log, "--model", str(model), "--noise", "identify", json_out=d / f"d{k}.json")
            taken = (diag["steps"][0].get("taken_for_noise") if diag["steps"] else None)
            how = (f"; named by the test of effects taken for noise, likelihood ratio {taken['likelihood_ratio']:.1f} "
                   f"against {taken['critical']:.1f}" if taken else "")
            print(f"  diagnose ({', '.join(['default'] + added)}): verdict {diag['verdict'] or 'none'} "
                  f"({diag['verdict_kind'] or '-'}), chi2/dof of the base {diag['base_chi2_per_dof']:.3f}{how}")
            if not diag["verdict"]:
                break
            added.append(diag["verdict"])
            calbench("add", log, "--model", str(model), "--effect", diag["verdict"], "--noise", "identify",
                     "--out", str(d / f"m{k + 1}.json"))
            model = d / f"m{k + 1}.json"
        result = json.loads(model.read_text())
        truth = json.loads((d / "log.truth.json").read_text())["effects"]
        if a.ramp:
            # on a ramp from the coefficient's reference temperature a drift is the same column
            truth["acc.drift.z"] = truth["acc.temp.z"] * RAMP_RATE
        z = {p: (v["value"] - truth.get(p, 0.0)) / v["sigma"] for p, v in result["parameters"].items()}
        n = len(z)
        rms = float(np.sqrt(np.mean(np.square(list(z.values())))))
        lo, hi = (np.sqrt(stats.chi2.ppf(q, n) / n) for q in (0.005, 0.995))
        worst = max(z, key=lambda p: abs(z[p]))
        print(f"  last model: {', '.join(['default'] + added)}; chi2/dof {result['fit']['chi2_per_dof']:.3f}")
        print(f"  {n} parameters against the truth: RMS z {rms:.2f} (a standard normal's: 1, 99 % band for {n}: "
              f"{lo:.2f}-{hi:.2f}); largest {worst} {z[worst]:+.2f}")
        # display units: ug/g2 (SI 1/(m/s2): x g0 / 1e-6) and ug/K (SI m/s2/K: / (1e-6 g0))
        for p, unit, per_si in (("acc.k2.z", "ug/g2", 9.80665 / 1e-6), ("acc.temp.z", "ug/K", 1 / 9.80665e-6),
                                ("acc.drift.z", "ug/h", 3600 / 9.80665e-6)):
            if p in result["parameters"]:
                v = result["parameters"][p]
                print(f"  {p}: {v['value'] * per_si:.1f} ± {v['sigma'] * per_si:.1f} {unit} "
                      f"(truth {truth[p] * per_si:.1f})")
    print(f"total {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
