"""Run a campaign on Dask: a LocalCluster of N single-threaded worker processes by default, or
the cluster at ``scheduler`` (no other change). Every finished case is written by this (the
client) process at once, so a remote cluster needs no shared folder; ``resume`` runs only the
cases without a record. Ctrl-C or SIGTERM stops cleanly: finished records stay, the cluster is
closed, and the manifest tells the session was interrupted."""
from __future__ import annotations

import logging
import shutil
import signal
import threading
import time
from pathlib import Path

from components.campaign.case import dumps, record
from components.campaign.isolate import run_isolated
from components.campaign.manifest import new_manifest, now
from components.campaign.progress import Progress
from components.campaign.scratch import campaign_scratch, sweep_stale
from components.campaign.spec import Campaign, task_for
from components.campaign.store import Store
from components.errors import CampaignError


class _Terminated(KeyboardInterrupt):
    pass


def _raise_terminated(signum, frame):  # noqa: ARG001
    raise _Terminated()


def connect(workers: int | None = None, scheduler: str | None = None):
    """(client, cluster or None, slots)."""
    from distributed import Client, LocalCluster

    if scheduler:
        client = Client(scheduler, timeout="30s")
        cluster = None
    else:
        # the scheduler's HTTP server starts whatever is asked (None is its default port, 8787,
        # for which two campaigns started at once contend, with a warning): any free port
        cluster = LocalCluster(n_workers=max(1, int(workers or 1)), threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
        client = Client(cluster)
    from components.campaign.isolate import warm

    try:
        client.run(warm)  # each worker's case server imports now, not inside the first case
    except Exception:  # noqa: BLE001  (a worker that cannot warm starts its server on first use)
        pass
    info = client.scheduler_info() if hasattr(client, "scheduler_info") else {}
    slots = sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()) or (workers or 1)
    return client, cluster, slots


def run_campaign(camp: Campaign, out: str | Path, *, workers: int | None = None, scheduler: str | None = None,
                 resume: bool = False, timeout: float | None = None, stream=None) -> dict:
    """Run what is missing; returns the manifest's session entry."""
    store = Store(out)
    done = store.done()
    manifest = store.read_manifest()
    sha = None
    if done and not resume:
        raise CampaignError(f"{store.out}: already holds {len(done)} case result(s): give --resume to run only "
                            "what is missing, or another --out")
    fresh = new_manifest(camp)
    if manifest is not None and resume:
        sha = manifest.get("files", {}).get("campaign", {}).get("sha256")
        if sha != fresh["files"]["campaign"]["sha256"]:
            raise CampaignError(f"{store.out}: was started with another campaign file (sha256 {sha}); "
                                "resume needs the same file")
        old_sessions = manifest.get("sessions", [])
        manifest = fresh
        manifest["sessions"] = old_sessions
    else:
        manifest = fresh
    store.prepare()
    known = {c.id for c in camp.cases}
    todo = [c for c in camp.cases if c.id not in done]
    session = {"start": now(), "end": None, "workers": None if scheduler else (workers or 1),
               "scheduler": scheduler, "resume": resume, "skipped_done": len(done & known), "ran": [],
               "interrupted": False, "case_wall_s": {}}
    manifest["sessions"].append(session)
    store.write_manifest(manifest)
    old_handler = None
    if threading.current_thread() is threading.main_thread():
        old_handler = signal.signal(signal.SIGTERM, _raise_terminated)
    client = cluster = None
    progress = None
    # every case's temporary directory inside one of the campaign's, removed below once the
    # cluster is closed: a worker stopped with the campaign dies before its case can clean up
    # (found: the running case's directory, its FMUs unpacked, left at a SIGTERM under load)
    # (and those of campaigns killed outright before, which could not clean up: scratch.py)
    session["swept_stale_scratch"] = len(sweep_stale())
    scratch = campaign_scratch()
    try:
        if todo:
            client, cluster, slots = connect(workers, scheduler)
            progress = Progress(len(camp.cases), already=len(camp.cases) - len(todo), slots=slots, stream=stream)
            from distributed import as_completed

            futures = {}
            t_submit = {}
            for c in todo:
                task = task_for(camp, c, marker_dir=str(store.runs_dir.resolve()))
                task["scratch_dir"] = scratch
                f = client.submit(run_isolated, task, timeout, key=f"calbench-case-{c.id}-{time.time_ns()}",
                                  pure=False)
                futures[f] = task
                t_submit[c.id] = time.monotonic()
            for f in as_completed(futures):
                task = futures[f]
                cid = task["case"]["id"]
                try:
                    rec = f.result()
                except Exception as e:  # noqa: BLE001  (a worker lost: the case errored, the campaign goes on)
                    rec = record(task, None, f"worker failure: {type(e).__name__}: {e}")
                store.write_case(rec, dumps(rec))
                session["ran"].append(cid)
                session["case_wall_s"][cid] = round(time.monotonic() - t_submit[cid], 3)
                progress.update(rec["verdict"], cid)
    except KeyboardInterrupt:
        session["interrupted"] = True
        raise
    finally:
        if progress is not None:
            progress.close()
        for obj in (client, cluster):
            if obj is not None:
                try:
                    obj.close()
                except Exception:  # noqa: BLE001
                    pass
        shutil.rmtree(scratch, ignore_errors=True)
        if old_handler is not None:
            signal.signal(signal.SIGTERM, old_handler)
        session["ran"] = sorted(session["ran"])
        session["end"] = now()
        store.write_manifest(manifest)
    return session
