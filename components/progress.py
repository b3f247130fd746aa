"""Progress of long computations, on stderr, for the command line.

Library calls show nothing: the CLI switches progress on (stderr a terminal) and the loops that
can take more than a few seconds on a long log (the table effects' columns, the diagnosis's
candidates, the noise likelihood per channel) report through :func:`steps`. A bar appears only
after two seconds (``CALBENCH_PROGRESS_DELAY``), so short runs print nothing.
"""
from __future__ import annotations

import os
import sys
from contextlib import contextmanager

_ENABLED = False


def enable(on: bool) -> None:
    global _ENABLED
    _ENABLED = bool(on)


class _Silent:
    def update(self, n: int = 1) -> None:
        pass


@contextmanager
def steps(desc: str, total: int):
    """A bar over *total* steps (``bar.update()`` after each), or a silent stand-in."""
    if not _ENABLED or total < 2:
        yield _Silent()
        return
    from tqdm import tqdm

    delay = float(os.environ.get("CALBENCH_PROGRESS_DELAY", "2.0"))
    bar = tqdm(total=total, desc=desc, unit="step", file=sys.stderr, leave=False, delay=delay, dynamic_ncols=True)
    try:
        yield bar
    finally:
        bar.close()
