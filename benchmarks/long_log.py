"""Long logs: calibrate, compare, diagnose (then noise and report, without a baseline) on a
41.6-minute 200 Hz log (502,420 samples), each command in a child process of its own, timed
(CPU: user + system of the child) with its peak resident memory; and the report page's size.

The log: the demo's navigation-grade scenario (hidden K2 on z) on the twenty-six-position
schedule with 88 s dwells (the length of the log issue #18 measured), written as Parquet.

Baselines: measured here, on the same file in the same run, benchmarks/numpy_ranking.py — a
plain vectorised numpy ranking of diagnose's test on eight IMU candidates (rest blocks and
rest-to-rest moves, bias + scale-factor/misalignment baseline; see its docstring), timed the same
way (twice: its BLAS thread pools at their default size and at one thread, as calbench runs; the
faster is the baseline) against diagnose with all its candidates and against diagnose told those eight
(``--candidates``: the same test); and quoted (issue #18, same machine class, 200 Hz only):
calbench's diagnose before this work, 64 s CPU and 1.58 GB per call on a 41.5-minute 200 Hz log,
and the issue's own numpy solver, 12 s CPU and 0.94 GB.

An 8-hour thermal run (``--hours 8 --rate 1000``, the issue's 28.8 M samples): the
twenty-six-position schedule repeated back to back (each repetition returns the table to its
zero angles, so the angles run on without a jump), the IMU temperature following a ramp and soak
(25 °C for an eighth of the run, up to 60 °C over a quarter, 60 °C for a quarter, down to 25 °C
over a quarter, 25 °C), an accelerometer bias temperature coefficient (acc.temp.y, 5 ug/K) beside
the hidden K2. Each repetition is simulated on its own (the simulator holds a run in memory:
~0.7 KB a sample) with its own noise seed, the temperature profile taken up where the last one
ended, and appended to one Parquet file a row group at a time; so the noise state starts afresh
at each repetition's first sample (every ~42 minutes), the one way this file differs from a
single run.

The table times each command once. A single figure is the machine's as much as the command's:
the system time of touching fresh memory varies two- to three-fold from run to run on these
virtual machines (the numpy ranking's on the 8-hour log: 5-17 s of its CPU), so diagnose told
the ranking's eight candidates and the ranking are then run in alternating pairs (``--pairs``,
3 by default) and compared by their medians, user and system time apart.

    python benchmarks/long_log.py [--dir DIR] [--dwell 88] [--rate 200] [--hours 8] [--pairs 3]
    python benchmarks/long_log.py --growth SHORT.parquet LONG.parquet   (the peak's growth per sample)
"""
from __future__ import annotations

import argparse
import copy
import os
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import NamedTuple

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

BASELINES = {"diagnose": {"calbench before (issue #18)": (64.0, 1.58), "numpy solver (issue #18)": (12.0, 0.94)}}


def make_log(stem: Path, dwell: float, step: float = 0.005) -> Path:
    from components.cli.demo import SCENARIO
    from components.simulation.run import run_scenario, write_outputs
    from components.simulation.scenario import scenario_from_dict

    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["schedule"] = {"name": "twentysix_position", "overrides": {"dwell": dwell}}
    d["scenario"]["step"] = step
    run = run_scenario(scenario_from_dict(d, source="long_log"), progress=False)
    write_outputs(run, stem, fmt="parquet")
    return stem.with_suffix(".parquet")


RAMP_AND_SOAK = ([0.0, 0.125, 0.375, 0.625, 0.875, 1.0], [25.0, 25.0, 60.0, 60.0, 25.0, 25.0])  # run fraction, °C


def make_thermal_log(stem: Path, hours: float, step: float, dwell: float) -> Path:
    """The thermal run of the module docstring, as <stem>.parquet + <stem>.json."""
    import json

    import numpy as np
    import pyarrow.parquet as pq

    from components.cli.demo import SCENARIO
    from components.logs.labels import SegmentLabels
    from components.logs.logfile import write_log
    from components.simulation.multi_imu import Variant, run_variants
    from components.simulation.scenario import scenario_from_dict

    sched = (ROOT / "components" / "control" / "schedules" / "twentysix_position.toml").read_text()
    sched += ('\n[[steps]]\nkind = "index"\nangles_deg = [0, 0, 0]\nabsolute = true\nlabel = "home"\n'
              '[[steps]]\nkind = "dwell"\nduration = 2.0\nlabel = "home"\n')
    (stem.parent / "thermal_schedule.toml").write_text(sched)
    d = copy.deepcopy(tomllib.loads(SCENARIO.read_text()))
    d["schedule"] = {"path": "thermal_schedule.toml", "overrides": {"dwell": dwell}}
    d["scenario"]["step"] = step
    d["imu"]["effects"]["acc.temp.y"] = "5 ug/K"
    total = hours * 3600.0
    fr, temp = RAMP_AND_SOAK
    writer, t_end, k, n = None, 0.0, 0, 0
    piece = stem.parent / "piece"
    try:
        while t_end < total:
            d["scenario"]["seed"] = 1000 + k
            sc = scenario_from_dict(d, source=f"long_log thermal {k}", base_dir=stem.parent)
            offset = t_end
            profile = lambda t, o=offset: float(np.interp((t + o) / total, fr, temp))  # noqa: E731
            log, _ = run_variants(sc, [Variant("imu", parameters={"temperature.mode": 2}, temperature_env=True)],
                                  profile)["imu"]
            log.time = log.time + offset
            seg = log.segment
            log.segment = SegmentLabels(seg.starts, seg.codes, [f"r{k:02d}-{s}" for s in seg.names], seg.n)
            log.description = f"thermal run: twenty-six positions repeated, ramp and soak 25-60 degC ({hours:g} h)"
            write_log(piece, log, fmt="parquet")
            table = pq.read_table(piece.with_suffix(".parquet"))
            if writer is None:
                writer = pq.ParquetWriter(stem.with_suffix(".parquet"), table.schema)
                meta = json.loads(piece.with_suffix(".json").read_text())
            writer.write_table(table, row_group_size=1 << 20)
            t_end, n, k = float(log.time[-1]), n + log.n, k + 1
            print(f"  repetition {k}: {n} samples, {t_end / 3600:.2f} h", flush=True)
            del log, table
    finally:
        if writer is not None:
            writer.close()
        for suffix in (".parquet", ".json", ".truth.json"):
            piece.with_suffix(suffix).unlink(missing_ok=True)
    stem.with_suffix(".json").write_text(json.dumps(meta, indent=1))
    return stem.with_suffix(".parquet")


def as_pulse_counts(log: Path, stem: Path, gyro_count_rad: float, acc_count_mps: float) -> Path:
    """*log* (Parquet, increments) rewritten as <stem>.parquet + .json with the gyro and
    accelerometer columns as the whole pulse counts of a logger with those count weights (int64,
    each axis's remainder started at a random fraction of a count), a row group at a time: the
    running totals are carried from one row group to the next, so the counts are those of the
    whole log's sums. What a laser-gyro or pulse-output IMU's logger writes."""
    import json

    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq
    from pulse_counts import PulseLogger

    weights = {"gyro": gyro_count_rad, "acc": acc_count_mps}
    rng = np.random.default_rng(7)
    loggers = {f"{s}_{c}": PulseLogger(weights[s], rng.random() * weights[s]) for s in weights for c in "xyz"}
    pf = pq.ParquetFile(log)
    writer = None
    try:
        for i in range(pf.num_row_groups):
            table = pf.read_row_group(i)
            for name, logger in loggers.items():
                counts = pa.array(logger.counts(table.column(name).to_numpy()))
                table = table.set_column(table.schema.get_field_index(name), name, counts)
            if writer is None:
                writer = pq.ParquetWriter(stem.with_suffix(".parquet"), table.schema)
            writer.write_table(table, row_group_size=1 << 20)
    finally:
        if writer is not None:
            writer.close()
    meta = json.loads(log.with_suffix(".json").read_text())
    meta["imu"].update(gyro_output="counts", acc_output="counts", gyro_count_rad=gyro_count_rad,
                       acc_count_mps=acc_count_mps)
    meta["description"] = meta.get("description", "") + f"; pulse counts of {gyro_count_rad:g} rad and {acc_count_mps:g} m/s"
    stem.with_suffix(".json").write_text(json.dumps(meta, indent=1))
    return stem.with_suffix(".parquet")


def _tree_pss(pid: int) -> int:
    """Proportional set size [bytes] of *pid* and its descendants (shared pages split among the
    processes that map them: the sum is what the job holds, a forked worker's shared pages
    counted once)."""
    total, todo = 0, [pid]
    while todo:
        p = todo.pop()
        try:
            with open(f"/proc/{p}/smaps_rollup") as f:
                for line in f:
                    if line.startswith("Pss:"):
                        total += int(line.split()[1]) * 1024
                        break
            for t in os.listdir(f"/proc/{p}/task"):
                with open(f"/proc/{p}/task/{t}/children") as f:
                    todo += [int(c) for c in f.read().split()]
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            continue
    return total


def _cached_bytecode() -> dict:
    """The environment the commands run in: Python's bytecode cache on, as on a user's machine
    (an installed package's modules are compiled at install; PYTHONDONTWRITEBYTECODE, set on
    some build machines, made every command compile calbench's ~100 modules again, ~0.15 s of
    CPU that neither a user nor the numpy baseline, whose libraries come compiled, pays)."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _one_blas_thread(env: dict) -> dict:
    """*env* with the BLAS thread pools at one thread, as calbench sets them for itself
    (components/__init__.py). The numpy ranking runs both ways: with the pools at their default
    size (one thread per CPU) their idle threads spin after each call and at start, ~0.15 s of CPU
    on the 41.9-minute log, which a baseline timed only that way would be charged and calbench
    not; the faster of the two is the baseline."""
    from components import ONE_BLAS_THREAD

    return {**env, **ONE_BLAS_THREAD}


class Run(NamedTuple):
    cpu: float  # s, user + system
    wall: float  # s
    peak: float  # GB, the command's resident set
    tree: float  # GB, the peak of the proportional set size summed over the process tree
    user: float  # s
    system: float  # s


def measure(args: list[str], env: dict | None = None) -> Run:
    """The figures of ``calbench ARGS`` (or, when ARGS starts with a .py file, that script) in
    a child process: CPU from its rusage (its worker processes' included), the tree's PSS sampled
    every 0.2 s."""
    import threading

    t = time.perf_counter()
    argv = [sys.executable, *args] if args[0].endswith(".py") else [sys.executable, "-m", "components.cli", *args]
    p = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         env=env or _cached_bytecode())
    peak_pss = [0]
    done = threading.Event()

    def sample():
        while not done.wait(0.2):
            peak_pss[0] = max(peak_pss[0], _tree_pss(p.pid))

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    _, status, usage = os.wait4(p.pid, 0)
    done.set()
    sampler.join()
    p.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t
    # 1 is a calbench command's "a check failed" (a verdict named); a script's 1 is an exception
    if p.returncode not in ((0,) if args[0].endswith(".py") else (0, 1)):
        raise SystemExit(f"{' '.join(args)} exited {p.returncode}")
    return Run(usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss / 1024**2, peak_pss[0] / 1024**3,
               usage.ru_utime, usage.ru_stime)


def environment(name: str) -> dict:
    """The child's environment for the table's command *name*: the numpy ranking's "numpy1" with one
    BLAS thread, as calbench runs; every command with its bytecode compiled (_cached_bytecode)."""
    return _one_blas_thread(_cached_bytecode()) if name == "numpy1" else _cached_bytecode()


def paired(steps: dict, pairs: int, n: int) -> None:
    """diagnose8 and the one-thread numpy ranking run in turn *pairs* times; each pair's CPU
    (user + system) and ratio, then the medians."""
    import statistics

    print(f"paired runs, in turn ({pairs}): diagnose8 against numpy1, CPU s as user + system")
    runs: dict = {"diagnose8": [], "numpy1": []}
    for i in range(pairs):
        for name in runs:
            runs[name].append(measure(steps[name], environment(name)))
        d, r = runs["diagnose8"][-1], runs["numpy1"][-1]
        print(f"  pair {i + 1}: diagnose8 {d.user:.1f} + {d.system:.1f} = {d.cpu:.1f}, numpy1 {r.user:.1f} + "
              f"{r.system:.1f} = {r.cpu:.1f}: {d.cpu / r.cpu:.2f}x", flush=True)
    med = {k: Run(*(statistics.median(getattr(x, f) for x in v) for f in Run._fields)) for k, v in runs.items()}
    d, r = med["diagnose8"], med["numpy1"]
    print(f"median of {pairs}: diagnose8 {d.cpu:.1f} s CPU ({d.user:.1f} user), numpy1 {r.cpu:.1f} s CPU "
          f"({r.user:.1f} user): {d.cpu / r.cpu:.2f}x CPU ({d.user / r.user:.2f}x user), "
          f"{max(d.peak, d.tree) / r.peak:.2f}x memory; per sample {d.cpu / n * 1e6:.2f} against "
          f"{r.cpu / n * 1e6:.2f} us")


def growth(short: Path, long: Path, out: Path, repeat: int = 3) -> int:
    """Issue #18 item 1, memory bounded by the chunk and the parameters, not by the log: the peak
    resident set of calibrate, compare and diagnose on two logs of the same kind and different
    lengths (e.g. 2 and 4 hours of the thermal run), each command on one worker (a forked worker's
    pages are its parent's: one process is the whole figure), and what the peak grows by per
    sample of the longer log, against the log's own float64 sensor columns (time, gyro, acc: 56
    bytes a sample), which is what a command holding the log in memory would grow by at least.
    Each command runs *repeat* times on each log, the two logs in turn: one run's peak moves by a
    few MB from run to run (the C heap's and Arrow's pools), as much as 4 hours of samples add, so
    the growth is taken between the medians and printed beside the runs' spread."""
    import pyarrow.parquet as pq

    env = {**_cached_bytecode(), "CALBENCH_WORKERS": "1"}
    n = {log: pq.ParquetFile(log).metadata.num_rows for log in (short, long)}
    print(f"logs: {short} ({n[short]} samples), {long} ({n[long]} samples); one worker; each command "
          f"{repeat} times on each log, in turn")
    models = {}
    for log in (short, long):
        models[log] = out / f"{log.stem}-{n[log]}.json"
        subprocess.run([sys.executable, "-m", "components.cli", "calibrate", str(log), "--out", str(models[log])],
                       cwd=ROOT, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    peaks: dict = {}
    for _ in range(repeat):
        for log in (short, long):
            for name, args in (("calibrate", ["calibrate", str(log), "--out", str(out / "again.json")]),
                               ("compare", ["compare", str(log), "--model", str(models[log])]),
                               ("diagnose", ["diagnose", str(log), "--model", str(models[log])])):
                peaks.setdefault((name, log), []).append(measure(args, env)[2])
    per_sample = 1024**3 / (n[long] - n[short])
    print(f"{'command':10s} {'peak GB':>9s} {'peak GB':>9s} {'B/sample':>9s}   against the log's float64 columns "
          f"(56 B/sample); the runs' spread (max - min) on each log, in B/sample of the difference")
    for name in ("calibrate", "compare", "diagnose"):
        a, b = (statistics.median(peaks[name, log]) for log in (short, long))
        spread = [(max(peaks[name, log]) - min(peaks[name, log])) * per_sample for log in (short, long)]
        print(f"{name:10s} {a:9.3f} {b:9.3f} {(b - a) * per_sample:9.2f}   {(b - a) * per_sample / 56:.3f}x   "
              f"spread {spread[0]:.2f} and {spread[1]:.2f}")
    print(f"cpus {os.cpu_count()}, load average (1 min) {os.getloadavg()[0]:.2f}")
    return 0


def summary(got: dict, candidates: int) -> None:
    """The table's ratios against the numpy ranking, and the issue's bound for the three commands."""
    from components.estimation.chunks import chunk_workers

    # the stricter baseline: the ranking with the fewer CPU seconds (numpy1: one BLAS thread)
    base = min(("numpy", "numpy1"), key=lambda k: got[k].cpu)
    b = got[base]
    print(f"numpy ranking baseline: {base} ({'one BLAS thread, as calbench runs' if base == 'numpy1' else 'BLAS threads at their default'}; "
          f"the other {got['numpy1' if base == 'numpy' else 'numpy'].cpu:.1f} s CPU)")
    for name, what in (("diagnose", "all its candidates"),
                       ("diagnose8", f"the numpy ranking's {candidates} candidates: the same test")):
        d = got[name]
        print(f"diagnose ({what}) against the numpy ranking, side by side: {d.cpu / b.cpu:.2f}x CPU, "
              f"{max(d.peak, d.tree) / b.peak:.2f}x memory")
    three = [got[k] for k in ("calibrate", "compare", "diagnose")]
    print(f"calibrate + compare + diagnose: {sum(g.cpu for g in three):.0f} s CPU, {sum(g.wall for g in three):.0f} s "
          f"wall on {chunk_workers()} worker(s), peak {max(max(g.peak, g.tree) for g in three):.2f} GB "
          "(issue #18 for an 8-hour 1 kHz log: <= 10 minutes on 2 cores, <= 4 GB)")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", type=Path, help="where the log is written (default: a temporary directory)")
    ap.add_argument("--dwell", type=float, default=88.0)
    ap.add_argument("--rate", type=float, default=200.0, help="sample rate [Hz] (1000: the issue's 1 kHz; "
                    "the baselines are for 200 Hz)")
    ap.add_argument("--hours", type=float, help="a thermal run of this many hours instead (module docstring)")
    ap.add_argument("--log", type=Path, help="time the commands on this Parquet log instead of simulating one")
    ap.add_argument("--only-make", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--only-counts", nargs=4, help=argparse.SUPPRESS)
    ap.add_argument("--counts", help="GYRO_RAD,ACC_MPS: time the commands on the log rewritten as pulse counts of "
                    "these weights (e.g. 1e-6,1e-5; as_pulse_counts)")
    ap.add_argument("--growth", nargs=2, type=Path, metavar=("SHORT", "LONG"),
                    help="the peak memory's growth per sample between two Parquet logs of the same kind (growth())")
    ap.add_argument("--repeat", type=int, default=3, help="--growth: runs of each command on each log (medians)")
    ap.add_argument("--steps", help="the table's commands to time, comma-separated (default: all; the ratios "
                    "that need the others are left out)")
    ap.add_argument("--pairs", type=int, default=3, help="diagnose8 and numpy1 run in turn this many times after "
                    "the table (module docstring; 0: none)")
    a = ap.parse_args()
    if a.growth:
        with tempfile.TemporaryDirectory() as d:
            return growth(*a.growth, Path(d), a.repeat)
    from numpy_ranking import CANDIDATES

    if a.only_counts:
        src, stem, g, f = a.only_counts
        as_pulse_counts(Path(src), Path(stem), float(g), float(f))
        return 0
    if a.only_make:
        if a.hours:
            make_thermal_log(a.only_make, a.hours, 1.0 / a.rate, a.dwell)
        else:
            make_log(a.only_make, a.dwell, 1.0 / a.rate)
        return 0
    tmp = None
    if a.dir is None:
        tmp = tempfile.TemporaryDirectory()
        a.dir = Path(tmp.name)
    a.dir.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    if a.log:
        log = a.log
    else:
        # simulated in a child: a forked child's peak memory starts from its parent's (the figures
        # below were the simulation's 1.7 GB for every command of a 1 kHz log)
        subprocess.run([sys.executable, __file__, "--only-make", str(a.dir / "long"), "--dwell", str(a.dwell),
                        "--rate", str(a.rate)] + (["--hours", str(a.hours)] if a.hours else []), check=True)
        log = (a.dir / "long").with_suffix(".parquet")
    if a.counts:
        t = time.perf_counter()
        g, f = (float(v) for v in a.counts.split(","))
        # in a child, as the simulation: the commands' children are forked from this process, and
        # a forked child's peak resident set starts from its parent's (Arrow's pool after the
        # rewrite put 2.95 GB under every command of the 8-hour log)
        subprocess.run([sys.executable, __file__, "--only-counts", str(log), str(a.dir / "counts"), str(g), str(f)],
                       check=True)
        log = (a.dir / "counts").with_suffix(".parquet")
        print(f"pulse counts of {g:g} rad and {f:g} m/s written in {time.perf_counter() - t:.1f} s -> {log.name}")
    import pyarrow.parquet as pq

    n = pq.ParquetFile(log).metadata.num_rows
    print(f"log: {n} samples at {a.rate:g} Hz ({n / a.rate / 60:.1f} min), "
          + (f"given: {log}" if a.log else f"simulated and written in {time.perf_counter() - t:.1f} s -> {log.name}"))
    model = a.dir / "base.json"
    subprocess.run([sys.executable, "-m", "compileall", "-q", "components"], cwd=ROOT, check=True,
                   env=_cached_bytecode(), stdout=subprocess.DEVNULL)
    print("bytecode: compiled before the timings (as an installed package has it; _cached_bytecode)")
    steps = [("calibrate", ["calibrate", str(log), "--out", str(model)]),
             ("compare", ["compare", str(log), "--model", str(model)]),
             ("diagnose", ["diagnose", str(log), "--model", str(model)]),
             ("diagnose8", ["diagnose", str(log), "--model", str(model), "--candidates", ",".join(CANDIDATES)]),
             ("numpy", [str(ROOT / "benchmarks" / "numpy_ranking.py"), str(log)]),
             ("numpy1", [str(ROOT / "benchmarks" / "numpy_ranking.py"), str(log)]),
             # the other commands of issue #18 item 1 on the same log (no baseline)
             ("noise", ["noise", str(log), "--model", str(model)]),
             ("report", ["report", str(log), "--model", str(model), "--out", str(a.dir / "report.html")])]
    print(f"{'command':10s} {'CPU s':>7s} {'wall s':>7s} {'peak GB':>8s} {'tree GB':>8s} {'us/sample':>9s} "
          f"{'B/sample':>8s}   against the baselines (CPU ratio, memory ratio)\n"
          "  (CPU: the command's and its worker processes'; peak: the command's resident set; tree: the peak of "
          "the proportional set size summed over the command and its workers)")
    got = {}
    chosen = a.steps.split(",") if a.steps else [name for name, _ in steps]
    unknown = set(chosen) - {name for name, _ in steps}
    if unknown:
        raise SystemExit(f"--steps: no such command {sorted(unknown)}; the table has {[name for name, _ in steps]}")
    for name, args in ((k, v) for k, v in steps if k in chosen):
        cpu, wall, peak, tree, _, _ = got[name] = measure(args, environment(name))
        ratios = "; ".join(f"{b}: {cpu / c:.2f}x CPU, {peak / m:.2f}x memory"
                           for b, (c, m) in (BASELINES.get(name, {}) if a.rate == 200 else {}).items())
        if name.startswith("diagnose"):
            ratios = "; ".join(x for x in (ratios, "numpy ranking: below") if x)
        print(f"{name:10s} {cpu:7.1f} {wall:7.1f} {peak:8.2f} {tree:8.2f} {cpu / n * 1e6:9.1f} "
              f"{max(peak, tree) * 1024**3 / n:8.0f}   {ratios}", flush=True)
    page = a.dir / "report.html"
    if "report" in got and page.exists():
        print(f"report page: {page.stat().st_size / 1e6:.2f} MB (its JSON twin {page.with_suffix('.json').stat().st_size / 1e6:.2f} MB)")
    if {"numpy", "numpy1", "diagnose", "diagnose8", "calibrate", "compare"} <= set(got):
        summary(got, len(CANDIDATES))
    if a.pairs > 0:
        paired(dict(steps), a.pairs, n)
    print(f"cpus {os.cpu_count()}, load average (1 min) {os.getloadavg()[0]:.2f}")
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
