"""The Dask task: run one case in a child process of its own, with a timeout.

On Linux the child is forked from a warm case server (components.campaign.forkserver; one per
worker thread, started on first use or by warm()); elsewhere, or with CALBENCH_CASE_ISOLATION=spawn, it is a
fresh ``python -m components.campaign.case``. Either way a segfault (or any signal) of the child,
a hang past the timeout or a non-zero exit becomes an errored record with the reason (signal
name / timeout / last line of stderr); the worker, and so the campaign, go on."""
from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from components import ONE_BLAS_THREAD
from components.campaign.forkserver import die_with_parent

# a case's process: one BLAS thread, and a long log's chunk work (components.estimation.chunks) on
# the case's own process, whatever the caller's environment: the campaign's workers are the
# parallelism, and a case forking a worker per CPU beside them oversubscribes the machine
CASE_ENVIRONMENT = {**ONE_BLAS_THREAD, "CALBENCH_WORKERS": "1"}


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def _use_server() -> bool:
    return hasattr(os, "fork") and sys.platform.startswith("linux") and \
        os.environ.get("CALBENCH_CASE_ISOLATION", "fork") != "spawn"


class _Server:
    def __init__(self):
        self.p = subprocess.Popen([sys.executable, "-m", "components.campaign.forkserver"],
                                  env={**os.environ, **CASE_ENVIRONMENT}, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                  preexec_fn=die_with_parent)
        if json.loads(self._read(120.0) or "{}").get("status") != "ready":
            self.close()
            raise RuntimeError("the case server did not start")

    def _read(self, timeout: float) -> str | None:
        r, _, _ = select.select([self.p.stdout], [], [], timeout)
        return self.p.stdout.readline().decode() if r else None

    def run(self, req: dict, timeout: float) -> dict:
        self.p.stdin.write((json.dumps(req) + "\n").encode())
        self.p.stdin.flush()
        line = self._read(timeout + 60.0)
        if not line:
            raise RuntimeError("the case server did not answer")
        return json.loads(line)

    def alive(self) -> bool:
        return self.p.poll() is None

    def close(self) -> None:
        try:
            self.p.kill()
            self.p.wait(5)
        except Exception:  # noqa: BLE001
            pass


_pool: list = []            # idle case servers of this (worker) process
_pool_lock = threading.Lock()


def _take() -> _Server:
    with _pool_lock:
        while _pool:
            s = _pool.pop()
            if s.alive():
                return s
    return _Server()


def _give(s: _Server) -> None:
    with _pool_lock:
        _pool.append(s)


def warm() -> int:
    """Start an idle case server in this process now (a cluster's workers, before the cases)."""
    if _use_server():
        _give(_take())
    return os.getpid()


def _spawn(tin: Path, tout: Path, terr: Path, scratch: Path, timeout: float) -> dict:
    cmd = [sys.executable, "-m", "components.campaign.case", str(tin), str(tout)]
    with open(terr, "wb") as err:
        try:
            p = subprocess.run(cmd, env={**os.environ, **CASE_ENVIRONMENT, "TMPDIR": str(scratch)},
                               stdout=err, stderr=err, timeout=timeout,
                               preexec_fn=die_with_parent if sys.platform.startswith("linux") else None)
        except subprocess.TimeoutExpired:
            return {"status": "timeout"}
    return {"status": "signal", "signal": -p.returncode} if p.returncode < 0 else {"status": "exit",
                                                                                  "code": p.returncode}


def run_isolated(task: dict, timeout_s: float | None = None) -> dict:
    """The case record (components.campaign.case.record), whatever happens to the child."""
    from components.campaign.case import record

    timeout = float(timeout_s if timeout_s is not None else task.get("timeout_s") or 300.0)
    # inside the campaign's own temporary directory where this machine has it (a worker of a
    # remote cluster uses its own machine's)
    within = task.get("scratch_dir")
    with tempfile.TemporaryDirectory(prefix="calbench-case-", dir=within if within and os.path.isdir(within) else None) \
            as tmp:
        tin, tout, terr = Path(tmp) / "task.json", Path(tmp) / "result.json", Path(tmp) / "stderr.txt"
        tin.write_text(json.dumps(task))
        # the case's own temporary files (its unpacked FMUs) live in the case's directory: a case
        # killed at its timeout, or dying of a signal, cleans up nothing itself (found: two
        # unpacked FMUs left in /tmp by every killed case)
        scratch = Path(tmp) / "tmp"
        scratch.mkdir()
        if _use_server():
            try:
                server = _take()
                st = server.run({"task": str(tin), "result": str(tout), "stderr": str(terr),
                                 "tmpdir": str(scratch), "timeout": timeout}, timeout)
                _give(server)
            except (RuntimeError, OSError, ValueError):
                st = _spawn(tin, tout, terr, scratch, timeout)
        else:
            st = _spawn(tin, tout, terr, scratch, timeout)
        if st["status"] == "timeout":
            return record(task, None, f"timeout: no result after {timeout:g} s (the case was killed)")
        if st["status"] == "signal":
            return record(task, None, f"crashed: the case process died of {signal_name(st['signal'])}")
        if st["code"] != 0 or not tout.exists():
            lines = [ln for ln in terr.read_text(errors="replace").splitlines() if ln.strip()] if terr.exists() else []
            return record(task, None, f"exit code {st['code']}: {lines[-1] if lines else 'no message'}")
        return json.loads(tout.read_text())
