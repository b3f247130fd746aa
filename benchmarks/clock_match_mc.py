"""Is the clock match's σ honest? The foreign rig's files (benchmarks/foreign_rig.py: pulse
counts, jittered host stamps, lost packets, the table controller 7.7 ms behind on a clock of its
own) over many seeds, imported only (no calibration loop): the offset the import says at the
table's first sample and the rate between the clocks, each against its truth on the log's own
time, in units of the σ the import says. Over N seeds the z-scores of an honest σ have mean 0
and RMS 1: printed with the RMS's χ²(N) band (two-sided, 1 %), and the offsets' RMS error beside
the σ said.

    python benchmarks/clock_match_mc.py [--seeds 20] [--table-ppm 30] [--jitter-ms 0.3] [--counter]
                                        [--gyro-count 1e-5]
"""
from __future__ import annotations

import argparse
import math
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import foreign_rig  # noqa: E402
from foreign_rig import _grid_error, calbench, scenario_text, write_rig  # noqa: E402

from components.logs.logfile import read_log  # noqa: E402


def one_seed(seed: int, d: Path, table_ppm: float, jitter_s: float, counter: bool) -> dict:
    d.mkdir(parents=True, exist_ok=True)
    (d / "scenario.toml").write_text(scenario_text(seed))
    calbench("simulate", "scenario.toml", "--out", "sim", cwd=d)
    (d / "rig").mkdir(exist_ok=True)
    true_offset, true_times = write_rig(d / "sim", d / "rig", np.random.default_rng(seed), table_ppm=table_ppm,
                                        jitter_s=jitter_s, counter=counter)
    said = calbench("import", "rig/map.toml", "--out", "imp", cwd=d)
    grid_s, grid_ppm = _grid_error(read_log(d / "imp").time, true_times)
    off = re.search(r"clock offset table -> IMU ([+-][\d.]+) ± ([\d.e-]+) ms", said)
    rate = re.search(r"the IMU's clock ([+-][\d.e+-]+) ± ([\d.e-]+) ppm against the table's[:,]", said)
    true_rate = (1 / (1 + table_ppm * 1e-6) - 1) * 1e6 + grid_ppm
    out = {"seed": seed, "offset_err": float(off.group(1)) * 1e-3 - (true_offset + grid_s),
           "offset_sigma": float(off.group(2)) * 1e-3}
    if rate:
        out.update(rate_err=float(rate.group(1)) - true_rate, rate_sigma=float(rate.group(2)))
    return out


def _band(n: int) -> tuple[float, float]:
    from scipy.stats import chi2

    return math.sqrt(chi2.ppf(0.005, n) / n), math.sqrt(chi2.ppf(0.995, n) / n)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=101)
    ap.add_argument("--table-ppm", type=float, default=30.0)
    ap.add_argument("--jitter-ms", type=float, default=0.3)
    ap.add_argument("--counter", action="store_true")
    ap.add_argument("--gyro-count", type=float, help="the gyro pulse's weight [rad] instead of 1e-6")
    a = ap.parse_args()
    if a.gyro_count:
        foreign_rig.use_gyro_count(a.gyro_count)
    print(f"clock match over {a.seeds} seeds from {a.first_seed}: the foreign rig's files, the table's clock "
          f"{a.table_ppm:g} ppm fast, stamps ±{a.jitter_ms:g} ms, gyro pulses of {foreign_rig.COUNTS['gyro']:g} rad"
          + (", a packet counter" if a.counter else ""))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(a.seeds):
            t = time.perf_counter()
            r = one_seed(a.first_seed + k, Path(tmp) / f"s{k}", a.table_ppm, a.jitter_ms * 1e-3, a.counter)
            rows.append(r)
            rate = (f"; rate {r['rate_err']:+.4f} ± {r['rate_sigma']:.2g} ppm ({r['rate_err'] / r['rate_sigma']:+.2f} σ)"
                    if "rate_err" in r else "; no rate said")
            print(f"  seed {r['seed']}: offset {r['offset_err'] * 1e6:+.2f} ± {r['offset_sigma'] * 1e6:.2f} us "
                  f"({r['offset_err'] / r['offset_sigma']:+.2f} σ){rate}  ({time.perf_counter() - t:.0f} s)", flush=True)
    lo, hi = _band(len(rows))
    for name in ("offset", "rate"):
        z = np.array([r[f"{name}_err"] / r[f"{name}_sigma"] for r in rows if f"{name}_err" in r])
        if not len(z):
            continue
        lo, hi = _band(len(z))
        rms = float(np.sqrt(np.mean(z**2)))
        print(f"{name}: z mean {z.mean():+.2f} (SE {1 / math.sqrt(len(z)):.2f}), RMS {rms:.2f} over {len(z)} seeds "
              f"(an honest σ: in {lo:.2f}-{hi:.2f} at 99 %), largest |z| {np.max(np.abs(z)):.2f}")
    err = np.array([r["offset_err"] for r in rows])
    sig = np.array([r["offset_sigma"] for r in rows])
    print(f"offset: RMS error {np.sqrt(np.mean(err**2)) * 1e6:.2f} us, RMS σ said {np.sqrt(np.mean(sig**2)) * 1e6:.2f} us")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
