"""A long log's sensor columns on disk instead of in memory.

An 8-hour log at 1 kHz is 28.8 M samples: its gyro, accelerometer and temperature columns alone
are 1.6 GB as float64, and the estimators read them a chunk at a time
(components.estimation.chunks). Above :data:`SPILL_SAMPLES` the reader therefore decodes those
columns, a Parquet row group at a time, into memory-mapped arrays in an unlinked temporary file
(the disk space goes when the arrays do), and the passes over them give the pages they touched
back to the page cache (:func:`release`). The numbers are the same float64 values bit for bit;
what changes is that the process's resident memory holds one chunk of them, not the log.

The light whole-log columns the block layout needs (time, gimbal angles, segment labels) stay in
memory.
"""
from __future__ import annotations

import errno
import mmap
import os
import tempfile

import numpy as np

from components.errors import SpillError, whole_number_from_environment

# logs with more samples than this have their sensor columns spilled when read for the
# estimators (70 minutes at 1 kHz; CALBENCH_SPILL_SAMPLES overrides, e.g. 0 for always)
SPILL_SAMPLES = 1 << 22
PIECE = 1 << 18  # samples per piece of a pass over a spilled column (a (PIECE, 6) array: 12.6 MB)
NO_ROOM = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)  # reserving failed for want of space


def spill_threshold() -> int:
    return whole_number_from_environment("CALBENCH_SPILL_SAMPLES", SPILL_SAMPLES)


def spilled_array(shape, dtype=np.float64) -> np.memmap:
    """A writable array of *shape* backed by an unlinked temporary file (write whole rows of it
    with :func:`write_rows`)."""
    shape = tuple(int(k) for k in np.atleast_1d(shape))
    file = tempfile.TemporaryFile(prefix="calbench-spill-", suffix=".npy")
    # (an empty mapping is no mapping: a zero-row array still gets a byte of file)
    _reserve(file, max(int(np.prod(shape)) * np.dtype(dtype).itemsize, 1))
    arr = np.memmap(file, dtype=dtype, mode="r+", shape=shape)
    arr._spill_file = file  # the views numpy makes of it have none: they are written through the mapping
    return arr


def _reserve(file, size: int) -> None:
    """Give *file* *size* bytes with its disk blocks allocated, not a sparse hole. A sparse file
    allocates at every page written, which on ext4 made writing the 8-hour log's 1.7 GB of
    columns cost 1.1-2.4 s of system time, against 0.25 s into reserved blocks; and a full disk
    then shows as a crash (SIGBUS) at a write through the mapping, not as this one error. Where
    the system or its file system cannot reserve blocks, a sparse file as before."""
    if hasattr(os, "posix_fallocate"):
        try:
            os.posix_fallocate(file.fileno(), 0, size)
            return
        except OSError as e:
            if e.errno in NO_ROOM:
                file.close()
                raise SpillError(f"the temporary directory {tempfile.gettempdir()} cannot hold {size / 1e9:.2f} GB "
                                 f"of a long log's columns ({e.strerror}); free space there or point TMPDIR at a "
                                 f"disk that has it") from None
    # (no reserving on this system or this file system: a sparse file)
    file.truncate(size)


def write_rows(array: np.ndarray, start: int, values) -> None:
    """array[start:start + len(values)] = values. A whole spilled *array* is written through its
    file, not its mapping: a write through the mapping faults each page of the file in, and the
    8-hour 1 kHz log's sensor columns are 0.65 M pages (4 s of system time of its 5.7 s read)."""
    file = getattr(array, "_spill_file", None)
    if file is None or not array.flags.c_contiguous:
        array[start:start + len(values)] = values
        return
    if not 0 <= start <= start + len(values) <= len(array):
        raise IndexError(f"rows {start}..{start + len(values)} of a spilled array of {len(array)}")
    block = np.ascontiguousarray(np.broadcast_to(values, (len(values),) + array.shape[1:]), dtype=array.dtype)
    data = memoryview(block).cast("B")
    at = array.offset + start * (array.itemsize * int(np.prod(array.shape[1:], dtype=np.int64)))
    while data:
        done = os.pwrite(file.fileno(), data, at)
        data, at = data[done:], at + done


def is_spilled(a) -> bool:
    return isinstance(a, np.memmap) and getattr(a, "_mmap", None) is not None


def release(*arrays) -> None:
    """Give the pages of spilled *arrays* (or of the mappings their views are of) back: they stay
    on disk and in the page cache, out of this process's resident memory. Anything else: nothing."""
    for a in arrays:
        m = getattr(a, "_mmap", None) if isinstance(a, np.memmap) else None
        if m is not None and not m.closed:
            m.madvise(mmap.MADV_DONTNEED)


def scaled(x: np.ndarray, factor) -> np.ndarray:
    """x * factor (factor broadcast over rows: a scalar or (N, 1)); a spilled *x* gives a spilled
    result, computed a piece at a time."""
    if not is_spilled(x):
        return x * factor
    out = spilled_array(x.shape, np.result_type(x, np.float64))
    f = np.asarray(factor)
    for s in pieces(len(x), x, out):
        np.multiply(x[s], f[s] if f.ndim and len(f) == len(x) else f, out=out[s])
    return out


def piece_rows(array: np.ndarray) -> int:
    """Rows of *array* a pass over it takes at a time: :data:`PIECE`, fewer for rows wider than a
    sample's six values (a design's hundreds of columns) or rows of a strided view, so a piece
    spans ~12.6 MB of the array's memory."""
    # (a row's stride, not its size: a view of every 28th row spans 28 rows of the file a row)
    row = abs(array.strides[0]) if array.ndim and array.strides[0] else \
        array.itemsize * int(np.prod(array.shape[1:], dtype=np.int64))
    return max(1, min(PIECE, PIECE * 48 // max(row, 1)))


def pieces(n: int, *arrays, step: int | None = None):
    """Slices of [0, n) of *step* rows (default :data:`PIECE` samples); after each, the pages of
    the spilled *arrays* it touched are given back."""
    step = step or PIECE
    for a in range(0, n, step):
        yield slice(a, min(a + step, n))
        release(*arrays)


def product(array: np.ndarray, x: np.ndarray, columns=None, step: int | None = None) -> np.ndarray:
    """array @ x, or array[:, columns] @ x, a piece of rows at a time (a spilled *array*'s pages
    given back after each): a wide spilled array times a vector without its pages, or a copy
    of its columns, resident at once."""
    out = np.empty((len(array),) + np.shape(x)[1:])
    for at in pieces(len(array), array, step=step or piece_rows(array)):
        out[at] = (array[at] if columns is None else array[at][:, columns]) @ x
    return out


def gathered(array: np.ndarray, index: np.ndarray, columns=None) -> np.ndarray:
    """array[index] (rows at *index*, in its order), or array[index][:, columns]; for a spilled
    *array*, a piece of it at a time with each piece's pages given back: indices spread over the
    whole log (a block's middle each second) otherwise fault every page of it in at once."""
    index = np.asarray(index)
    if not is_spilled(array) or index.size == 0:
        return array[index] if columns is None else array[np.ix_(index, columns)]
    order = np.argsort(index, kind="stable")
    at = index[order]
    shape = array.shape[1:] if columns is None else (len(columns),)
    out = np.empty((len(index),) + shape, dtype=array.dtype)
    step = piece_rows(array)
    bounds = np.searchsorted(at, np.arange(0, len(array) + step, step))
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b > a:
            out[order[a:b]] = array[at[a:b]] if columns is None else array[at[a:b]][:, columns]
            release(array)
    return out


def empty_like_log(shape, like, dtype=np.float64) -> np.ndarray:
    """An empty array of *shape*: spilled when *like* (a column of the log) is."""
    return spilled_array(shape, dtype) if is_spilled(like) else np.empty(shape, dtype)


def both(mask: np.ndarray, other: np.ndarray | None) -> np.ndarray:
    """mask & other (*other* None: *mask* itself); for a spilled *mask*, a spilled result made a
    piece at a time, so neither it nor its operands are resident whole."""
    if other is None:
        return mask
    if not is_spilled(mask):
        return mask & other
    out = spilled_array(len(mask), bool)
    for s in pieces(len(mask), mask, other, out):
        np.logical_and(mask[s], other[s], out=out[s])
    out.setflags(write=False)
    return out
