"""Campaign throughput: cases per second on a Dask local cluster with 1 and 2 worker processes,
and the per-case overhead of the Dask path (task -> child process -> record) over running the
case directly in this process.

The cases: examples/campaigns/smoke.toml's scenario (six-position, 5 s dwell by default, 100 Hz) with our
IMU only, least squares, N Monte-Carlo seeds.

    python benchmarks/campaign_throughput.py [--cases 16] [--dwell 5]
    python benchmarks/campaign_throughput.py --campaign examples/campaigns/smoke.toml --replicates 4

``--campaign FILE`` takes a campaign file instead (its replicates set by ``--replicates``, so the
smoke campaign's 8 cases become 16 at 4).

Reported:
  direct       run_case(task) in this process (imports warm), per case
  isolated     run_isolated(task): the child process alone (no Dask), per case
  dask N       cluster start (workers and their warm case servers), then cases/s
  speed-up     throughput(2) / throughput(1)   (goal: >= 1.7 on 2 cores)
  overhead     1-worker time per case - direct time per case (child start + imports + Dask)
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def campaign_text(n: int, dwell: float) -> str:
    return f"""
[campaign]
name = "throughput"
seed = 1
replicates = {n}
timeout_s = 300
[scenario]
file = "{ROOT / 'examples' / 'scenarios' / 'six_position.toml'}"
step = 0.01
[scenario.schedule_overrides]
dwell = {dwell}
[systems.ours]
imu = "builtin:imu"
[procedures.lsq]
method = "lsq"
[variations."acc.bias.x"]
distribution = "normal"
mean = "0 ug"
sigma = "100 ug"
[[criteria]]
requirement = "REQ-1"
kind = "estimate"
parameters = ["acc.bias.*"]
tolerance = "50 ug"
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=16)
    ap.add_argument("--dwell", type=float, default=5.0, help="dwell per attitude [s]")
    ap.add_argument("--campaign", type=Path, help="a campaign file to time instead of the built-in one")
    ap.add_argument("--replicates", type=int, help="with --campaign: its replicates (cases scale with them)")
    args = ap.parse_args()
    from components.campaign.case import run_case
    from components.campaign.execute import connect
    from components.campaign.isolate import run_isolated, warm
    from components.campaign.reader import load_campaign
    from components.campaign.spec import task_for

    with tempfile.TemporaryDirectory() as tmp:
        if args.campaign is not None:
            import tomllib

            from components.campaign.reader import campaign_from_dict

            data = tomllib.loads(args.campaign.read_text())
            if args.replicates:
                data["campaign"]["replicates"] = args.replicates
            camp = campaign_from_dict(data, args.campaign)
            what = f"{args.campaign} at {data['campaign'].get('replicates')} replicates"
        else:
            f = Path(tmp) / "c.toml"
            f.write_text(campaign_text(args.cases, args.dwell))
            camp = load_campaign(f)
            what = f"six-position, {args.dwell:g} s dwell, 100 Hz, least squares"
        tasks = [task_for(camp, c) for c in camp.cases]
        out = {"cases": len(tasks)}

        run_case(tasks[0])  # warm the imports and caches of this process
        t = time.perf_counter()
        direct = [run_case(tk) for tk in tasks]
        out["direct_s_per_case"] = (time.perf_counter() - t) / len(tasks)

        k = min(4, len(tasks))
        warm()  # this process's case server starts here, as a worker's does before its first case
        t = time.perf_counter()
        isolated = [run_isolated(tk) for tk in tasks[:k]]
        out["isolated_s_per_case"] = (time.perf_counter() - t) / k
        assert [json.dumps(r, sort_keys=True) for r in isolated] == \
               [json.dumps(r, sort_keys=True) for r in direct[:k]], "child and direct records differ"

        for w in (1, 2):
            t0 = time.perf_counter()
            client, cluster, _ = connect(w)
            t1 = time.perf_counter()
            futs = [client.submit(run_isolated, tk, key=f"bench-{w}-{i}", pure=False) for i, tk in enumerate(tasks)]
            recs = client.gather(futs)
            t2 = time.perf_counter()
            client.close()
            cluster.close()
            assert [r["verdict"] for r in recs] == [r["verdict"] for r in direct]
            out[f"dask{w}_start_s"] = t1 - t0
            out[f"dask{w}_s"] = t2 - t1
            out[f"dask{w}_cases_per_s"] = len(tasks) / (t2 - t1)
    out["speedup_2_over_1"] = out["dask2_cases_per_s"] / out["dask1_cases_per_s"]
    out["overhead_s_per_case"] = out["dask1_s"] / out["cases"] - out["direct_s_per_case"]
    out["cpus"] = os.cpu_count()
    out["load_average_1min"] = os.getloadavg()[0]  # other work on the machine skews the speed-up
    print(f"cases: {out['cases']} ({what})")
    print(f"direct in-process     {out['direct_s_per_case']:.3f} s/case")
    print(f"isolated child        {out['isolated_s_per_case']:.3f} s/case (no Dask)")
    for w in (1, 2):
        print(f"dask {w} worker(s)      start {out[f'dask{w}_start_s']:.2f} s, then {out[f'dask{w}_s']:.2f} s "
              f"= {out[f'dask{w}_cases_per_s']:.3f} cases/s")
    print(f"speed-up 2 / 1        {out['speedup_2_over_1']:.2f}x (goal >= 1.7x on 2 cores)")
    print(f"overhead of the Dask path over a direct run: {out['overhead_s_per_case']:.3f} s/case "
          f"({100 * out['overhead_s_per_case'] / out['direct_s_per_case']:.0f}%)")
    print(f"load average (1 min) at the end: {out['load_average_1min']:.2f} on {out['cpus']} cpus")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
