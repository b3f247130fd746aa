"""A log's segment labels as runs: which label each sample carries, without a string per sample.

Why: a log's labels change at the schedule's steps only (a few thousand runs on an 8-hour 1 kHz
log of 30 M samples), and a label per sample, as an object array, was 8 bytes a sample (240 MB on
that log) held by every command, plus tens of bytes a sample wherever it became a text array.
:class:`SegmentLabels` holds the runs: the first sample of each, its label's code and the labels.
Reading a sample's label, a stretch's labels, the samples of a label (a bool mask, 1 byte a
sample, made when asked) and the runs themselves are what the commands need of them.

It stands in for the object array where one is expected: ``len``, indexing (a slice gives runs,
an index array gives the labels as an object array), iteration, ``==`` a label and
``np.asarray`` (which makes the array a sample at a time: for short logs and tests).
"""
from __future__ import annotations

import numpy as np


class SegmentLabels:
    """Labels of *n* samples as runs: run r starts at sample ``starts[r]`` (``starts[0] == 0``,
    increasing) and carries label ``names[codes[r]]``."""

    __slots__ = ("starts", "codes", "names", "n")
    __hash__ = None  # type: ignore[assignment]  (== compares a sample at a time, as an array's)
    ndim = 1
    dtype = np.dtype(object)

    def __init__(self, starts: np.ndarray, codes: np.ndarray, names, n: int):
        self.starts = np.asarray(starts, np.int64)
        self.codes = np.asarray(codes, np.int32)
        self.names = np.array([str(x) for x in names], dtype=object)
        self.n = int(n)
        if len(self.starts) != len(self.codes) or (self.n > 0) != (len(self.starts) > 0):
            raise ValueError("segment labels: one code per run, and runs exactly when there are samples")

    # ------------------------------------------------------------------ making them
    @classmethod
    def of(cls, values) -> "SegmentLabels":
        """From SegmentLabels (as they are) or one label a sample (str; anything else is a
        ValueError naming the first sample that is not text)."""
        if isinstance(values, SegmentLabels):
            return values
        a = np.asarray(values, dtype=object)
        if a.ndim != 1:
            raise ValueError(f"segment labels: expected one label a sample, got shape {a.shape}")
        if len(a) == 0:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.int32), [], 0)
        # the runs first (compared as the objects they are), then their labels
        starts = np.concatenate([[0], np.flatnonzero(a[1:] != a[:-1]) + 1])
        first = a[starts]
        for i, x in enumerate(first):
            if not isinstance(x, str):
                raise ValueError(f"sample {starts[i] + 1}: {x!r}; expected text")
        names, codes = np.unique(np.array([str(x) for x in first], dtype=object), return_inverse=True)
        codes = codes.ravel()
        keep = np.concatenate([[True], codes[1:] != codes[:-1]])  # 1 and '1' are one label
        return cls(starts[keep], codes[keep], names, len(a))

    @classmethod
    def from_codes(cls, codes: np.ndarray, names) -> "SegmentLabels":
        """From a code a sample (indices into *names*)."""
        codes = np.asarray(codes)
        n = len(codes)
        if n == 0:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.int32), names, 0)
        starts = np.concatenate([[0], np.flatnonzero(codes[1:] != codes[:-1]) + 1])
        return cls(starts, codes[starts], names, n)

    @classmethod
    def concatenate(cls, parts) -> "SegmentLabels":
        """The labels of *parts* (SegmentLabels or label arrays) one after the other."""
        parts = [cls.of(p) for p in parts]
        names = sorted({str(x) for p in parts for x in p.names[np.unique(p.codes)]} if parts else set())
        index = {name: i for i, name in enumerate(names)}
        starts, codes, at = [], [], 0
        for p in parts:
            remap = np.array([index.get(str(x), -1) for x in p.names], np.int64)
            starts.append(p.starts + at)
            codes.append(remap[p.codes] if len(p.codes) else p.codes)
            at += p.n
        if at == 0:
            return cls(np.zeros(0, np.int64), np.zeros(0, np.int32), names, 0)
        starts, codes = np.concatenate(starts), np.concatenate(codes)
        # runs of one label across a seam are one run
        keep = np.concatenate([[True], codes[1:] != codes[:-1]])
        return cls(starts[keep], codes[keep], names, at)

    # ------------------------------------------------------------------ reading them
    def __len__(self) -> int:
        return self.n

    @property
    def shape(self) -> tuple[int]:
        return (self.n,)

    @property
    def stops(self) -> np.ndarray:
        """One past the last sample of each run."""
        return np.append(self.starts[1:], self.n)

    @property
    def lengths(self) -> np.ndarray:
        """The samples of each run."""
        return np.diff(np.append(self.starts, self.n))

    def runs(self):
        """(first sample, one past the last, label) of each run, in order."""
        for a, b, c in zip(self.starts.tolist(), self.stops.tolist(), self.codes.tolist()):
            yield a, b, self.names[c]

    def distinct(self) -> list[str]:
        """The labels some sample carries, sorted."""
        return sorted(self.names[np.unique(self.codes)].tolist())

    def isin(self, labels) -> np.ndarray:
        """(n,) bool: the sample's label is one of *labels*."""
        want = {str(x) for x in labels}
        run_hit = np.array([self.names[c] in want for c in self.codes.tolist()], bool)
        return np.repeat(run_hit, self.lengths)

    def __eq__(self, other):
        if isinstance(other, (str, np.str_)):
            return self.isin([other])
        return np.asarray(self) == (np.asarray(other, dtype=object) if isinstance(other, SegmentLabels) else other)

    def __ne__(self, other):
        return ~np.asarray(self.__eq__(other), bool)

    def _run_of(self, index: np.ndarray) -> np.ndarray:
        return np.searchsorted(self.starts, index, side="right") - 1

    def __getitem__(self, key):
        if isinstance(key, slice):
            a, b, step = key.indices(self.n)
            if step == 1:
                return self._stretch(a, max(a, b))
            key = np.arange(a, b, step)
        if isinstance(key, (int, np.integer)):
            i = int(key) + (self.n if key < 0 else 0)
            if not 0 <= i < self.n:
                raise IndexError(f"sample {key} of {self.n} segment labels")
            return self.names[self.codes[self._run_of(i)]]
        key = np.asarray(key)
        if key.dtype == bool:
            if key.shape != (self.n,):
                raise IndexError(f"a mask of {key.shape} for {self.n} segment labels")
            key = np.flatnonzero(key)
        idx = key.astype(np.int64) + np.where(key < 0, self.n, 0)
        if np.any((idx < 0) | (idx >= self.n)):
            raise IndexError(f"a sample outside the {self.n} segment labels")
        return self.names[self.codes[self._run_of(idx)]] if len(idx) else np.zeros(0, dtype=object)

    def _stretch(self, a: int, b: int) -> "SegmentLabels":
        if a >= b:
            return SegmentLabels(np.zeros(0, np.int64), np.zeros(0, np.int32), self.names, 0)
        r0, r1 = self._run_of(a), self._run_of(b - 1)
        starts = self.starts[r0:r1 + 1] - a
        starts[0] = 0
        return SegmentLabels(starts, self.codes[r0:r1 + 1], self.names, b - a)

    def __iter__(self):
        for a, b, label in self.runs():
            for _ in range(b - a):
                yield label

    def __array__(self, dtype=None, copy=None):
        out = self.names[np.repeat(self.codes, self.lengths)] if self.n else \
            np.zeros(0, dtype=object)
        return out if dtype is None else out.astype(dtype)

    def astype(self, dtype) -> np.ndarray:
        return np.asarray(self).astype(dtype)

    def tolist(self) -> list:
        return list(self)

    def __repr__(self) -> str:
        shown = ", ".join(f"{label!r} x{b - a}" for a, b, label in list(self.runs())[:4])
        return f"SegmentLabels({self.n} samples, {len(self.starts)} runs: {shown}{', ...' if len(self.starts) > 4 else ''})"
