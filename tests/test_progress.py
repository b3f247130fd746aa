"""Progress on the command line (components/progress.py): a bar on stderr when stderr is a
terminal, none in a pipe and none from library calls; the command's output is the same."""
from __future__ import annotations

import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LOG, MODEL = ROOT / "examples" / "formats" / "log.csv", ROOT / "examples" / "formats" / "result.json"
ARGS = [sys.executable, "-m", "components.cli", "diagnose", str(LOG), "--model", str(MODEL)]


def _run(tty: bool, tmp_path: Path) -> tuple[str, str]:
    env = {**os.environ, "CALBENCH_PROGRESS_DELAY": "0"}
    out = tmp_path / f"out-{tty}.txt"
    if not tty:
        p = subprocess.run(ARGS, stdout=open(out, "w"), stderr=subprocess.PIPE, env=env, cwd=ROOT, check=True)
        return out.read_text(), p.stderr.decode(errors="replace")
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
    p = subprocess.Popen(ARGS, stdout=open(out, "w"), stderr=slave, env=env, cwd=ROOT, close_fds=True)
    os.close(slave)
    buf = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:
            break
        if not chunk:
            break
        buf += chunk
    assert p.wait() == 0
    os.close(master)
    return out.read_text(), buf.decode(errors="replace")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="pty window size set the Linux way")
def test_a_bar_on_a_terminal_none_in_a_pipe(tmp_path):
    out_tty, err_tty = _run(True, tmp_path)
    out_pipe, err_pipe = _run(False, tmp_path)
    assert "table effects' columns" in err_tty and "step/s" in err_tty
    assert "table effects' columns" not in err_pipe and "step/s" not in err_pipe
    assert out_tty == out_pipe  # the bar never reaches the command's output


def test_library_calls_show_nothing(capsys):
    from components import progress

    assert not progress._ENABLED
    with progress.steps("anything", 100) as bar:
        bar.update()
    assert capsys.readouterr().err == ""
