"""Tests' way to put the chunk work (components.estimation.chunks) on forked workers."""
from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from types import SimpleNamespace


def send_chunks_to_workers(mp) -> SimpleNamespace:
    """Make the chunk work go to forked workers (CALBENCH_WORKERS=2) however few the chunks: a
    test's log is a dozen chunks, fewer than chunks.PARALLEL_CHUNKS, below which they are done in
    the calling process. Returns a counter whose ``started`` counts the worker pools started, so a
    test can assert that workers ran rather than pass on one process. *mp*: a MonkeyPatch."""
    from components.estimation import chunks

    pools = SimpleNamespace(started=0)

    def counted_pool(*args, **kwargs) -> ProcessPoolExecutor:
        pools.started += 1
        return ProcessPoolExecutor(*args, **kwargs)

    mp.setenv("CALBENCH_WORKERS", "2")
    mp.setattr(chunks, "PARALLEL_CHUNKS", 2)
    mp.setattr(chunks, "ProcessPoolExecutor", counted_pool)
    return pools
