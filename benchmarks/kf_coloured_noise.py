"""The system-level filter under coloured noise: seed 003 (examples/scenarios/seed003.toml,
~12 minutes) with a navigation-grade flicker bias instability (gyro 0.005 deg/h, accelerometer
10 ug, Gauss–Markov sum over 10 s - 1 h) beside the white noise, Monte-Carlo over seeds.

Two runs of `calbench kf seed_003 --simulate` per seed:
- white: the filters' default (white noise from the static data): the whiteness check should
  refuse the run (exit 1), since its σ are too small;
- given: `--noise gyro.noise.bi=... --noise acc.noise.bi=...` (the datasheet's values; the
  flicker's range left to the filter: [5 filter intervals, the stage's length]): the slow terms
  are states of the filters, the run should pass and err/σ over every state and seed should be
  N(0, 1): pooled RMS within 1 ± 3/sqrt(2 n) and none beyond 3.5.

Prints per mode: exit codes, the pooled RMS of err/σ (and its band), the count beyond 3σ, the
largest, the CPU time per run.

    python benchmarks/kf_coloured_noise.py [--seeds 8] [--first 1]
"""
from __future__ import annotations

import argparse
import json
import re
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
NOISE = {"gyro.noise.bi": "0.005 deg/h", "acc.noise.bi": "10 ug"}
FLICKER = ('"gyro.noise.bi" = "0.005 deg/h"\n"gyro.noise.bi_tau" = 10.0\n"gyro.noise.bi_tau_max" = 3600.0\n'
           '"acc.noise.bi" = "10 ug"\n"acc.noise.bi_tau" = 10.0\n"acc.noise.bi_tau_max" = 3600.0\n')


def scenario(seed: int, where: Path) -> Path:
    text = (ROOT / "examples" / "scenarios" / "seed003.toml").read_text()
    text = re.sub(r"^seed = \d+", f"seed = {seed}", text, flags=re.M)
    text = text.replace("[imu.noise]\n", "[imu.noise]\n" + FLICKER)
    if FLICKER not in text:
        raise SystemExit("examples/scenarios/seed003.toml has no [imu.noise] table to add the flicker to")
    path = where / f"seed{seed}.toml"
    path.write_text(text)
    return path


def run(scn: Path, mode: str, out: Path) -> tuple[int, list[float], float]:
    extra = [a for k, v in NOISE.items() for a in ("--noise", f"{k}={v}")] if mode == "given" else []
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run([sys.executable, "-m", "components.cli", "kf", "seed_003", "--simulate", str(scn), "--out",
                        str(out), "--quiet"] + extra, cwd=ROOT, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode not in (0, 1):
        raise SystemExit(f"kf failed ({r.returncode}): {r.stderr[-2000:]}")
    rows = json.loads(out.read_text())["errors_against_truth"]
    z = [row["error"] / row["sigma"] for row in rows if row["sigma"]]
    return r.returncode, z, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--first", type=int, default=1)
    a = ap.parse_args()
    got = {"white": ([], [], []), "given": ([], [], [])}
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(tmp)
        for seed in range(a.first, a.first + a.seeds):
            scn = scenario(seed, where)
            for mode, (codes, zs, cpu) in got.items():
                rc, z, t = run(scn, mode, where / f"{mode}{seed}.json")
                codes.append(rc)
                zs.extend(z)
                cpu.append(t)
                print(f"seed {seed} {mode:5s}: exit {rc}, RMS err/σ {np.sqrt(np.mean(np.square(z))):.2f}, "
                      f"largest {np.max(np.abs(z)):.2f}", flush=True)
    print(f"\nseed 003 (~12 min) with a flicker bias instability (gyro 0.005 deg/h, acc 10 ug), {a.seeds} seeds:")
    for mode, (codes, zs, cpu) in got.items():
        z = np.asarray(zs)
        band = 3 / np.sqrt(2 * len(z))
        print(f"  {mode:5s}: exit 0 in {codes.count(0)}/{len(codes)}, exit 1 (refused) in {codes.count(1)}; err/σ over "
              f"{len(z)} estimates: RMS {np.sqrt(np.mean(z * z)):.3f} (N(0,1): 1 ± {band:.3f}), beyond 3σ "
              f"{int(np.sum(np.abs(z) > 3))}, largest {np.max(np.abs(z)):.2f}; {np.mean(cpu):.1f} s CPU a run")
    w, g = (np.sqrt(np.mean(np.square(got[m][1]))) for m in ("white", "given"))
    print(f"  RMS err/σ white / given: {w / g:.2f}x (the white filters' σ too small by this much)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
