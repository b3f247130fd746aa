"""A warm case server: ``python -m components.campaign.forkserver`` imports the case code once,
then for each request (one JSON line on stdin) forks a child that runs the case and exits; it
waits for the child up to the timeout (then SIGKILLs it) and answers one JSON line on stdout:
{"status": "exit", "code": n} | {"status": "signal", "signal": n} | {"status": "timeout"}.

Every case still runs in a process of its own (a segfault or a hang takes down only that child),
but starts from the same warm, never-used state in milliseconds instead of a fresh interpreter's
~1.7 s of imports: the same task gives the same record as a fresh process."""
from __future__ import annotations

import json
import os
import select
import signal
import sys
import time


def die_with_parent(parent: int | None = None) -> None:  # pragma: no cover  (runs in a child)
    """Linux: this process gets SIGKILL when its parent dies. Needed in every generation: the
    setting is not inherited across fork, and a case child orphaned by a killed worker (a hanging
    supplier FMU, say) would otherwise spin on for ever. With ``parent``: exit at once if it has
    already gone (the race between fork and prctl)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except Exception:  # noqa: BLE001
        return
    if parent is not None and os.getppid() != parent:
        os._exit(1)


def _child(req: dict, server: int) -> None:  # pragma: no cover  (runs in the forked child)
    code = 1
    try:
        die_with_parent(server)
        fd = os.open(req["stderr"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        os.close(fd)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        if req.get("tmpdir"):
            import tempfile

            os.environ["TMPDIR"] = tempfile.tempdir = req["tmpdir"]
        from components.campaign.case import main

        code = main([req["task"], req["result"]])
    except BaseException:  # noqa: BLE001
        import traceback

        traceback.print_exc()
        code = 1
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def _status(status: int) -> dict:
    if os.WIFSIGNALED(status):
        return {"status": "signal", "signal": os.WTERMSIG(status)}
    return {"status": "exit", "code": os.WEXITSTATUS(status)}


def _wait(pid: int, timeout: float) -> dict:
    """The child's end, or a timeout (the child is then SIGKILLed). A pidfd wakes us the moment
    the child ends; polling (where there is no pidfd) loses up to 50 ms per case."""
    if hasattr(os, "pidfd_open"):
        try:
            fd = os.pidfd_open(pid)
        except OSError:
            fd = None
        if fd is not None:
            try:
                ready, _, _ = select.select([fd], [], [], timeout)
            finally:
                os.close(fd)
            if not ready:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                return {"status": "timeout"}
            return _status(os.waitpid(pid, 0)[1])
    deadline = time.monotonic() + timeout
    delay = 0.002
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return _status(status)
        if time.monotonic() >= deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return {"status": "timeout"}
        time.sleep(delay)
        delay = min(delay * 2, 0.05)


def serve() -> int:
    # the imports every case needs, once (children inherit them)
    import fmpy  # noqa: F401

    import components.campaign.case  # noqa: F401
    import components.diagnosis.compare  # noqa: F401
    import components.diagnosis.diagnose  # noqa: F401
    import components.estimation.crb  # noqa: F401
    import components.estimation.lsq  # noqa: F401
    import components.logs.recording  # noqa: F401  (imports python-control, matplotlib: ~1.2 s)
    import components.simulation.scenario  # noqa: F401
    import fmus.turntable.variables  # noqa: F401
    import orchestrator.master  # noqa: F401

    server = os.getpid()
    out = sys.stdout
    out.write(json.dumps({"status": "ready"}) + "\n")
    out.flush()
    for line in sys.stdin:
        if not line.strip():
            continue
        req = json.loads(line)
        pid = os.fork()
        if pid == 0:
            _child(req, server)
        out.write(json.dumps(_wait(pid, float(req["timeout"]))) + "\n")
        out.flush()
    return 0


if __name__ == "__main__":
    sys.exit(serve())
