"""The manifest: what an auditor needs to trust the record. SHA-256 of the campaign file, the
scenario and schedule files and every FMU; software and library versions (and the git commit of
calbench when it runs from a checkout); the seeds of every case; the host; and the start and end
of every session (a resumed campaign has several). Times live here only, never in a case record."""
from __future__ import annotations

import datetime as _dt
import os
import platform
import socket
import subprocess
from pathlib import Path

from components.control.schedule import schedules_dir
from components.model.result import file_sha256

LIBRARIES = ("numpy", "scipy", "fmpy", "dask", "distributed", "matplotlib", "tqdm", "pyarrow", "filterpy",
             "control")


def now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


def _version(name: str) -> str | None:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return None


def _git() -> dict | None:
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10)
        if head.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10)
        return {"commit": head.stdout.strip(), "modified_files": len(dirty.stdout.splitlines())}
    except (OSError, subprocess.SubprocessError):
        return None


def software() -> dict:
    return {"calbench": _version("calbench"), "calbench_git": _git(), "python": platform.python_version(),
            "python_implementation": platform.python_implementation(),
            "libraries": {n: _version(n) for n in LIBRARIES}}


def host() -> dict:
    return {"name": socket.gethostname(), "platform": platform.platform(), "machine": platform.machine(),
            "cpus": os.cpu_count()}


def input_files(camp) -> dict:
    """{role: {path, sha256}} for every file the cases read."""
    from components.campaign.spec import resolve_imu

    files = {"campaign": camp.source}
    if camp.scenario_file:
        files["scenario"] = camp.scenario_file
    sched = camp.scenario.get("schedule", {})
    if "path" in sched:
        p = Path(sched["path"])
        files["schedule"] = p if p.is_absolute() else camp.scenario_base_dir / p
    elif "name" in sched:
        p = Path(str(schedules_dir())) / f"{sched['name']}.toml"
        if p.exists():
            files["schedule"] = p
    tt = camp.scenario.get("turntable", {}).get("fmu", "builtin:turntable")
    files["fmu:turntable"] = resolve_imu(tt, camp.scenario_base_dir)
    for name, s in camp.systems.items():
        files[f"fmu:{name}"] = s.path
    return {k: {"path": str(Path(v).resolve()), "sha256": file_sha256(v)} for k, v in files.items()}


def new_manifest(camp) -> dict:
    return {"format": "calbench-campaign-manifest/1", "campaign": camp.name, "description": camp.description,
            "files": input_files(camp), "software": software(), "host": host(),
            "seeds": {"campaign": camp.seed, "cases": {c.id: c.seed for c in camp.cases}},
            "cases": len(camp.cases), "sessions": []}
