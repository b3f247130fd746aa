"""The Dask task: run one case in a child process of its own, with a timeout.

A segfault (or any signal) of the child, a hang past the timeout or a non-zero exit becomes an
errored record with the reason (signal name / timeout / last line of stderr); the worker, and
so the campaign, go on."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

# one BLAS thread per case: the workers are the parallelism, and results do not depend on it
_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _die_with_parent() -> None:  # pragma: no cover  (runs in the child before exec)
    """Linux: the child gets SIGKILL when the worker that started it dies (no orphans)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except Exception:  # noqa: BLE001
        pass


def signal_name(returncode: int) -> str:
    try:
        return signal.Signals(-returncode).name
    except ValueError:
        return f"signal {-returncode}"


def run_isolated(task: dict, timeout_s: float | None = None) -> dict:
    """The case record (components.campaign.case.record), whatever happens to the child."""
    from components.campaign.case import record

    timeout = float(timeout_s if timeout_s is not None else task.get("timeout_s") or 300.0)
    env = {**os.environ, **_ENV}
    with tempfile.TemporaryDirectory(prefix="calbench-case-") as tmp:
        tin, tout = Path(tmp) / "task.json", Path(tmp) / "result.json"
        tin.write_text(json.dumps(task))
        cmd = [sys.executable, "-m", "components.campaign.case", str(tin), str(tout)]
        try:
            p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=timeout,
                               preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
        except subprocess.TimeoutExpired:
            return record(task, None, f"timeout: no result after {timeout:g} s (the case was killed)")
        if p.returncode < 0:
            return record(task, None, f"crashed: the case process died of {signal_name(p.returncode)}")
        if p.returncode != 0 or not tout.exists():
            lines = [ln for ln in p.stderr.decode(errors="replace").splitlines() if ln.strip()]
            return record(task, None, f"exit code {p.returncode}: {lines[-1] if lines else 'no message'}")
        return json.loads(tout.read_text())
