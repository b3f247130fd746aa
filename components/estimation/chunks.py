"""The log a stretch at a time: the estimators' block rows built chunk by chunk, so the per-sample
work arrays (the interpolated angles, the plate motion at every quadrature node, the effects'
regressors: ~2 KB per sample) are held for one chunk, never for the whole log.

Every row is one observation block (components.estimation.blocks) and a block's sums need only
its own samples, the motion over them and, for a move, its rests on both sides. So the log is cut
only where two consecutive samples rest at the same angles and both the gyro and the
accelerometer blocks have a boundary: every move, its spline and its rests lie inside one chunk,
and each chunk (LogData.stretch, one rest sample leading) computes exactly the rows the whole log
computes for it. The blocks themselves are laid out once on the whole log (they depend on whole
static runs); the rows of the chunks are put back in the whole log's order (gyro blocks, then
accelerometer blocks), so what follows — whitening, the fit, the tests — cannot tell the
difference (tests/test_chunks.py: equal to 1e-9 relative)."""
from __future__ import annotations

import multiprocessing as mp
import os
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from components import progress
from components.errors import UserError, whole_number_from_environment
from components.estimation.block_motion import BlockMotion
from components.estimation.blocks import Blocks, observation_blocks
from components.estimation.count_phase import count_advance
from components.estimation.design import design, predict
from components.estimation.log_data import LogData
from components.estimation.table_columns import (
    geometry_column_keys,
    geometry_columns_since,
    remember_geometry_columns,
)
from components.logs.spill import empty_like_log, is_spilled, release, spilled_array, write_rows

# samples per chunk: ~0.1 GB of work arrays at 3 quadrature nodes and 3 axes, whatever the log (2^16 was
# faster than 2^18 too, on a 2.5 M-sample log: 7.9 against 8.4 s, the arrays staying in cache)
CHUNK_SAMPLES = 1 << 16


@dataclass
class BlockLayout:
    """The observation blocks of a whole log and where it can be cut into chunks."""

    gyro: Blocks
    acc: Blocks
    cuts: np.ndarray  # sample indices the chunks start at (the first is 0), increasing

    @classmethod
    def of(cls, data: LogData, samples_per_block: int, chunk_samples: int = CHUNK_SAMPLES) -> "BlockLayout":
        static = data.static
        gb, ab = observation_blocks(static, data.angles, samples_per_block, data.valid)
        return cls(gb, ab, _cuts(static, gb, ab, len(static), chunk_samples))

    def chunks(self, data: LogData):
        """The chunks in order (Chunk): each chunk's samples as a log of their own
        (LogData.stretch; the whole log when there is one chunk) and the blocks that lie in it,
        indexed into that stretch."""
        for i in range(len(self.cuts)):
            yield self.chunk(data, i)

    def chunk(self, data: LogData, i: int) -> "Chunk":
        """The *i*-th chunk (made where it is needed: a stretch holds copies of the log's light
        columns, so the whole list of them is the log's light columns once more)."""
        if len(self.cuts) == 1:
            return Chunk(data, self.gyro, self.acc, 0, 0)
        a = int(self.cuts[i])
        b = int(self.cuts[i + 1]) if i + 1 < len(self.cuts) else len(data.time)
        lead = max(a - 1, 0)
        return Chunk(data.stretch(a, b), _within(self.gyro, a, b, lead), _within(self.acc, a, b, lead), lead, a)


@dataclass
class Chunk:
    data: LogData  # samples lead..stop-1 of the log
    gyro: Blocks   # the chunk's blocks, indices into `data`
    acc: Blocks
    lead: int      # the log's index of data's first sample
    start: int     # the log's index of the chunk's first own sample (lead + 1, or 0)

    @property
    def own(self) -> slice:
        """The chunk's own samples within `data` (without the leading rest sample)."""
        return slice(self.start - self.lead, None)


def _within(blocks: Blocks, a: int, b: int, shift: int) -> Blocks:
    keep = (blocks.start >= a) & (blocks.stop <= b)
    return Blocks(blocks.start[keep] - shift, blocks.stop[keep] - shift, blocks.moving[keep], blocks.whole_moves)


def cut_candidates(static: np.ndarray, gb: Blocks, ab: Blocks, n: int) -> np.ndarray:
    """The sample indices p in [1, n) the log can be cut at, increasing: samples p - 1 and p
    both at rest, p a boundary (start or stop) of a block of each set, and no block of either
    set spanning it (start < p < stop). From the blocks' boundaries alone: dense per-sample
    masks and a running count were five arrays of the log's length (0.6 s and ~1 GB of fresh
    pages on an 8-hour log)."""
    p = np.intersect1d(np.concatenate([gb.start, gb.stop]), np.concatenate([ab.start, ab.stop]))
    p = p[(p >= 1) & (p < n)]
    p = p[static[p - 1] & static[p]]
    for blocks in (gb, ab):
        if len(blocks.start) == 0:
            continue
        order = np.argsort(blocks.start, kind="stable")
        start, reach = blocks.start[order], np.maximum.accumulate(blocks.stop[order])
        # the blocks that start before p reach past it at most as far as the furthest of them
        last = np.searchsorted(start, p, side="left") - 1
        spanned = (last >= 0) & (reach[np.maximum(last, 0)] > p)
        p = p[~spanned]
    return p


def _cuts(static: np.ndarray, gb: Blocks, ab: Blocks, n: int, target: int) -> np.ndarray:
    """Chunk starts about *target* samples apart where the log can be cut (module docstring)."""
    if n <= target:
        return np.array([0])
    candidates = cut_candidates(static, gb, ab, n)
    cuts = [0]
    for c in candidates:
        if c - cuts[-1] >= target:
            cuts.append(int(c))
    return np.array(cuts)


def chunk_workers() -> int:
    """Processes the chunk work of a long log runs on: ``CALBENCH_WORKERS``, else every CPU."""
    if "fork" not in mp.get_all_start_methods():
        return 1  # the workers inherit the log by fork (not on Windows)
    return whole_number_from_environment("CALBENCH_WORKERS", os.cpu_count() or 1, least=1)


def chunk_scheduler() -> str | None:
    """The Dask scheduler the chunk work goes to when one machine is not enough:
    ``CALBENCH_SCHEDULER`` (the address a campaign's ``--scheduler`` takes), else none."""
    return os.environ.get("CALBENCH_SCHEDULER") or None


# the work a forked worker runs (inherited at the fork: a closure over the log cannot be pickled,
# and the log's arrays are shared, not copied)
_FORKED = None
# fewer chunks than this are done in this process: starting the workers and sending each chunk's
# rows back cost more than halving the chunk work saves (on 2 cores, one worker against two: a
# 42-minute 200 Hz log, 8 chunks, diagnose 0.89x the CPU and 0.96-1.1x the wall time, calibrate
# 0.77x the CPU and 0.90x the wall; a 2.1-hour one, 23 chunks, diagnose and calibrate 0.81-0.89x
# the CPU at 1.07-1.10x the wall; on an 8-hour 1 kHz log, 460 chunks, the three commands took
# 161 s of CPU in 117 s: benchmarks/long_log_8h.txt)
PARALLEL_CHUNKS = 32
IN_FLIGHT = 2  # chunks sent to a cluster per worker thread before the first result is back
SCHEDULER_TIMEOUT = "30s"  # connecting to CALBENCH_SCHEDULER


def _with_columns(work, chunk):
    """work(chunk) and the geometry columns it computed, for the caller's cache (a later call
    with the same geometry then finds them, as it would without workers)."""
    known = geometry_column_keys()
    progress.enable(False)  # the caller's bar counts the chunks
    return work(chunk), geometry_columns_since(known)


def _each_chunk(work, layout: BlockLayout, data: LogData, desc: str, parallel: str | None = None,
                sink=None) -> list:
    """[work(chunk) for each chunk] in order, with a bar over the chunks on a terminal; given a
    *sink*, each result goes to sink(result) as it comes instead (none is kept: the list is empty).
    ``parallel``: ``"fork"``: the chunks may run on :func:`chunk_workers` forked processes (what
    *work* writes into shared mappings the caller sees); ``"anywhere"``: *work* only returns its
    result, so the chunks may also go to the Dask cluster at :func:`chunk_scheduler`. The
    results, and so every estimate, are the same bits in the same order. (Threads gained 1.09x on
    2 cores: the chunk work is mostly short numpy calls that hold the interpreter.)"""
    out: list = []
    keep = sink or out.append
    if len(layout.cuts) == 1:
        for c in layout.chunks(data):
            keep(work(c))
        return out
    address = chunk_scheduler() if parallel == "anywhere" else None
    workers = min(chunk_workers(), len(layout.cuts)) if parallel else 1
    with progress.steps(desc, len(layout.cuts)) as bar:
        if address and len(layout.cuts) >= PARALLEL_CHUNKS:
            for result, columns in _on_cluster(address, work, layout.chunks(data), data):
                keep(result)
                remember_geometry_columns(columns)
                bar.update()
            return out
        if workers > 1 and len(layout.cuts) >= PARALLEL_CHUNKS:
            def in_worker(i: int):
                chunk = layout.chunk(data, i)  # made in the worker, not kept: it caches its angle profile
                result = _with_columns(work, chunk)
                chunk.data.release()
                return result

            for result, columns in forked_results(in_worker, len(layout.cuts), bar):
                keep(result)
                remember_geometry_columns(columns)
            return out
        for chunk in layout.chunks(data):
            keep(work(chunk))
            data.release()  # a spilled log's pages of this chunk (components.logs.spill)
            bar.update()
    return out


def forked_map(work, count: int, bar=None) -> list:
    """[work(i) for i in range(count)], the pieces on :func:`chunk_workers` forked processes
    (each inherits what *work* reads at the fork), results in order: the same bits as one
    process, where each piece depends on nothing another piece changes (a noise identification's
    channels, each from its own seed). ``bar``: a progress bar advanced as each result comes."""
    return list(forked_results(work, count, bar))


def forked_results(work, count: int, bar=None):
    """:func:`forked_map`'s results one at a time as they come, in order, none kept: a long log's
    chunks give their rows to the caller, which puts them in place (a list of them all was every
    candidate's rows of the log once more: 0.35 GB on an 8-hour log)."""
    global _FORKED
    workers = min(chunk_workers(), count)
    if workers <= 1:
        for i in range(count):
            yield work(i)
            if bar is not None:
                bar.update()
        return
    _FORKED = work
    try:
        with ProcessPoolExecutor(workers, mp_context=mp.get_context("fork")) as pool:
            for result in pool.map(_piece_in_worker, range(count)):
                yield result
                if bar is not None:
                    bar.update()
    finally:
        _FORKED = None


def _piece_in_worker(i: int):
    progress.enable(False)  # the caller's bar counts the pieces
    return _FORKED(i)


def _on_cluster(address: str, work, chunks, data: LogData):
    """(result, geometry columns) of each chunk in order, computed on the Dask cluster at
    *address*: each chunk's samples are sent with its task (a worker need not see the log's
    file), and only :data:`IN_FLIGHT` per worker thread are out at once, so the caller holds a
    few chunks, never the whole log's worth of pickled arrays."""
    from distributed import Client

    try:
        client = Client(address, timeout=SCHEDULER_TIMEOUT)
    except (OSError, TimeoutError) as e:
        raise UserError(f"CALBENCH_SCHEDULER={address}: no Dask scheduler answers there ({e}); "
                        "start one (`dask scheduler`, `dask worker ADDR`) or unset CALBENCH_SCHEDULER "
                        "to use this machine's processes") from None
    with client:
        threads = sum(w.get("nthreads", 1) for w in client.scheduler_info().get("workers", {}).values())
        pending: deque = deque()

        def send():
            chunk = next(chunks, None)
            if chunk is not None:
                pending.append(client.submit(_with_columns, work, chunk, pure=False))
                data.release()

        for _ in range(IN_FLIGHT * max(threads, 1)):
            send()
        while pending:
            got = pending.popleft().result()
            send()
            yield got


def chunked_design(data: LogData, layout: BlockLayout, params, sg, sa, rest, geo, table_params,
                   t0_temperature, quadrature: int = 3, lin=None, spill: bool | None = None):
    """components.estimation.design.design on the whole log, built a chunk at a time: the same
    y, H, weights and row information (indices into the whole log). Each chunk's rows go into
    their place as they come (the whole log's order: every gyro row, then every accelerometer
    row), so only one chunk's rows are held beside the whole; ``spill``: H is a spilled array
    (components.logs.spill), written through its file, so not even the whole is in memory; by
    default when the log's samples are spilled (a long log: every estimator's rows alike)."""
    if t0_temperature is None and data.temperature is not None:
        t0_temperature = float(data.temperature[0])  # the whole log's, not each chunk's
    def rows_of(chunk: Chunk):
        d = chunk.data
        motion = BlockMotion(d.angle_profile(quadrature), geo, d.temperature, t0_temperature, d.time_origin)
        y, H, w, rows = design(d, motion, params, chunk.gyro, chunk.acc, sg, sa, rest, geo, table_params, lin)
        return len(chunk.gyro) * 3, dict(rows, start=rows["start"] + chunk.lead, stop=rows["stop"] + chunk.lead)

    n_gyro = 3 * len(layout.gyro)
    n = n_gyro + 3 * len(layout.acc)
    if spill is None:
        spill = is_spilled(data.gyro)
    H = spilled_array((n, len(params))) if spill else np.empty((n, len(params)))
    rows: dict = {}
    at = [0, n_gyro]  # where the next chunk's gyro and accelerometer rows go

    def put(part):
        g, r = part
        if not rows:
            # (the sensor's name at its longest: a first chunk of accelerometer rows alone has "<U3")
            rows.update({k: np.empty(n, dtype="<U4" if k == "sensor" else r[k].dtype) for k in ROW_KEYS})
        for first, sl in ((at[0], slice(0, g)), (at[1], slice(g, None))):
            k = len(r["y"][sl])
            for key in ROW_KEYS:
                rows[key][first:first + k] = r[key][sl]
            write_rows(H, first, r["H"][sl])
        at[0], at[1] = at[0] + g, at[1] + len(r["y"]) - g

    _each_chunk(rows_of, layout, data, "block rows, chunk by chunk", parallel="anywhere", sink=put)
    if at != [n_gyro, n]:
        raise AssertionError(f"the chunks gave {at[0]} gyro and {at[1] - n_gyro} accelerometer rows for "
                             f"{n_gyro} and {n - n_gyro} blocks x 3 axes")
    release(H)
    rows["H"] = H
    # a pulse output's count phase through the whole log's rests (a rest may span chunks)
    rows.update(count_advance(data, rows))
    return rows["y"], rows["H"], rows["weight"], rows


# the row information every chunk's design gives beside H (components.estimation.design.design)
ROW_KEYS = ("sensor", "axis", "start", "stop", "moving", "y", "weight")


@dataclass
class PlateAtSamples:
    """What the comparison keeps of the plate motion per sample (the full Motion holds every
    quadrature node): rest or not, the interval, and the specific force and inertial rate at the
    start of the interval (the first node), which sort blocks by attitude and rate."""

    static: np.ndarray  # (N,) bool
    dt: np.ndarray      # (N,)
    f: np.ndarray       # (N, 3) m/s²
    omega: np.ndarray   # (N, 3) rad/s

    @classmethod
    def of(cls, motion) -> "PlateAtSamples":
        return cls(motion.static, motion.dt, motion.f_q[:, 0, :], motion.omega_q[:, 0, :])


def chunked_prediction(data: LogData, layout: BlockLayout, params, values, geo, t0_temperature,
                       quadrature: int = 3) -> tuple[np.ndarray, PlateAtSamples]:
    """The model's increments (N, 6) for sensor-effect *values* on the log's motion at *geo*
    (components.estimation.design.predict), and the plate at the samples, a chunk at a time."""
    if t0_temperature is None and data.temperature is not None:
        t0_temperature = float(data.temperature[0])
    n = len(data.time)
    # a spilled log gets a spilled prediction (components.logs.spill), which forked workers can
    # fill: the file is mapped shared, so what they write is what the parent reads
    pred = empty_like_log((n, 6), data.gyro)
    plate = PlateAtSamples(empty_like_log(n, data.gyro, bool), empty_like_log(n, data.gyro),
                           empty_like_log((n, 3), data.gyro), empty_like_log((n, 3), data.gyro))

    def fill(chunk: Chunk):
        motion = chunk.data.motion(geo, t0_temperature, quadrature)
        own = chunk.own
        at = slice(chunk.start, chunk.lead + len(chunk.data.time))
        gyro, acc = predict(motion, params, values)
        p = PlateAtSamples.of(motion)
        # whole rows, through a spilled array's file (components.logs.spill.write_rows): written
        # through the mapping, the 8-hour log's 3 GB of prediction faulted in a page at a time
        for target, rows in ((pred, np.hstack([gyro[own], acc[own]])), (plate.static, p.static[own]),
                             (plate.dt, p.dt[own]), (plate.f, p.f[own]), (plate.omega, p.omega[own])):
            write_rows(target, at.start, rows)
        release(pred, plate.static, plate.dt, plate.f, plate.omega)

    _each_chunk(fill, layout, data, "prediction, chunk by chunk", parallel="fork" if is_spilled(pred) else None)
    return pred, plate
