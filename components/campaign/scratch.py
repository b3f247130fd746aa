"""A campaign's temporary directory, and the sweep of those whose campaign was killed.

Every case's temporary files (its unpacked FMUs, its task and result files) live in the
directory of the campaign that runs it, removed when the campaign ends, however it ends — except
when its process is killed outright (SIGKILL, the kernel's out-of-memory killer, a power cut):
then nothing of it runs to clean up. So each such directory names its owner (process id and
start time), and the next campaign on the machine removes those whose owner is gone.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

PREFIX = "calbench-campaign-"
OWNER = "owner"  # the file in the directory: "<pid> <start time>"


def process_identity(pid: int) -> str | None:
    """"<pid> <start time>" of a running process, None when there is none of that id. The start
    time (clock ticks since boot, Linux's /proc/PID/stat) tells a process from a later one given
    the same id; elsewhere only the id is known, and it is taken as alive while any process has it."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat = f.read()
        # (fields after the command name, which is in parentheses and may hold spaces)
        return f"{pid} {int(stat[stat.rindex(b')') + 2:].split()[19])}"
    except FileNotFoundError:
        return None
    except (OSError, ValueError, IndexError):
        pass
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:
        pass
    return f"{pid} ?"


def campaign_scratch() -> str:
    """A new temporary directory for this process's campaign, naming this process its owner."""
    path = tempfile.mkdtemp(prefix=PREFIX)
    (Path(path) / OWNER).write_text(process_identity(os.getpid()) or f"{os.getpid()} ?")
    return path


def sweep_stale(within: str | None = None) -> list[str]:
    """Remove the campaign directories (in *within*, default the temporary directory) whose owner
    is gone; returns them. A directory without an owner file (another version's, or one being
    made) and one whose owner runs are left alone."""
    removed = []
    for d in sorted(Path(within or tempfile.gettempdir()).glob(PREFIX + "*")):
        try:
            owner = (d / OWNER).read_text().split()
            pid, started = int(owner[0]), (owner[1] if len(owner) > 1 else "?")
        except (OSError, ValueError, IndexError):
            continue
        now = process_identity(pid)
        running = now is not None and (now.split()[1] == started or "?" in (started, now.split()[1]))
        if not running:
            shutil.rmtree(d, ignore_errors=True)
            removed.append(str(d))
    return removed
