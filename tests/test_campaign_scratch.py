"""A campaign killed outright leaves its temporary directory; the next one removes it, and only
it (components.campaign.scratch)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from components.campaign import scratch

CHILD = """
import time
from components.campaign.scratch import campaign_scratch
print(campaign_scratch(), flush=True)
time.sleep(60)
"""


def _campaign_process(tmp_path: Path) -> tuple[subprocess.Popen, Path]:
    """A process that made its campaign directory in *tmp_path* and waits."""
    env = dict(os.environ, TMPDIR=str(tmp_path), PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    p = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE, text=True, env=env)
    return p, Path(p.stdout.readline().strip())


def test_a_killed_campaigns_directory_is_swept_and_a_running_ones_kept(tmp_path):
    p, made = _campaign_process(tmp_path)
    try:
        assert made.parent == tmp_path and made.name.startswith(scratch.PREFIX)
        (made / "case" / "tmp").mkdir(parents=True)  # a case's unpacked FMUs, say
        assert scratch.sweep_stale(str(tmp_path)) == []  # its campaign runs
        assert made.is_dir()
    finally:
        p.send_signal(signal.SIGKILL)  # nothing of it can clean up
        p.wait()
        p.stdout.close()
    assert made.is_dir()
    assert scratch.sweep_stale(str(tmp_path)) == [str(made)]
    assert not made.exists()


def test_only_directories_whose_owner_is_gone_are_swept(tmp_path):
    mine = Path(scratch.campaign_scratch())
    try:
        def owned(name: str, text: str | None) -> Path:
            d = tmp_path / (scratch.PREFIX + name)
            d.mkdir()
            if text is not None:
                (d / scratch.OWNER).write_text(text)
            return d

        me = scratch.process_identity(os.getpid())
        assert me is not None and me.split()[0] == str(os.getpid())
        alive = owned("alive", me)
        unknown = owned("no-owner", None)  # another version's, or one being made: not ours to judge
        garbled = owned("garbled", "not a pid")
        # this process's id with another start time: the id given again to a later process
        reused = owned("reused", f"{os.getpid()} 1") if me.split()[1] != "1" else None
        p = subprocess.Popen([sys.executable, "-c", "pass"])
        p.wait()
        gone = owned("gone", f"{p.pid} ?")
        other = tmp_path / "calbench-case-x"  # not a campaign's
        other.mkdir()
        swept = scratch.sweep_stale(str(tmp_path))
        assert sorted(swept) == sorted(str(d) for d in (gone, reused) if d is not None)
        for d in (alive, unknown, garbled, other):
            assert d.is_dir()
        assert mine.is_dir() and (mine / scratch.OWNER).read_text() == me
    finally:
        import shutil

        shutil.rmtree(mine, ignore_errors=True)
