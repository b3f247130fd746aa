"""Tests' way to put the chunk work (components.estimation.chunks) on forked workers."""
from __future__ import annotations


class _CountingPool:
    """ProcessPoolExecutor, counting the pools started (in the test's process)."""

    started = 0

    def __init__(self, *args, **kwargs):
        from concurrent.futures import ProcessPoolExecutor

        type(self).started += 1
        self._pool = ProcessPoolExecutor(*args, **kwargs)

    def __enter__(self):
        return self._pool.__enter__()

    def __exit__(self, *exc):
        return self._pool.__exit__(*exc)


def send_chunks_to_workers(mp) -> type:
    """Make the chunk work go to forked workers (CALBENCH_WORKERS=2) however few the chunks: a
    test's log is a dozen chunks, fewer than chunks.PARALLEL_CHUNKS, below which they are done in
    the calling process. Returns the pool class, whose ``started`` counts the worker pools, so a
    test can assert that workers ran rather than pass on one process. *mp*: a MonkeyPatch."""
    from components.estimation import chunks

    counting = type("CountingPool", (_CountingPool,), {"started": 0})
    mp.setenv("CALBENCH_WORKERS", "2")
    mp.setattr(chunks, "PARALLEL_CHUNKS", 2)
    mp.setattr(chunks, "ProcessPoolExecutor", counting)
    return counting
