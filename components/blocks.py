"""Observation blocks: sums of consecutive samples that the estimators fit instead of single
samples.

Why: per-sample gyro predictions during a move are dominated by encoder quantisation (the
interpolated angle is only exact at the logged counts), while the integral of the gimbal rate
between two rest samples is exact. So gyro rows are whole rest-to-rest moves plus static chunks;
accelerometer predictions depend only on the attitude, which the encoder gives to a count, so
accelerometer rows are short chunks everywhere. Static chunks keep time resolution for trends
(drift, temperature) and for locating residuals.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from components.motion import moving_runs


@dataclass
class Blocks:
    """Index ranges [start, stop) of samples that are summed into one observation row."""

    start: np.ndarray
    stop: np.ndarray
    moving: np.ndarray  # bool per block

    def __len__(self) -> int:
        return len(self.start)

    def sum(self, per_sample: np.ndarray) -> np.ndarray:
        """Block sums of a per-sample array (N, ...) -> (B, ...)."""
        c = np.concatenate([np.zeros((1,) + per_sample.shape[1:]), np.cumsum(per_sample, axis=0)])
        return c[self.stop] - c[self.start]

    @property
    def count(self) -> np.ndarray:
        return self.stop - self.start


def _chunks(a: int, b: int, n: int) -> list[tuple[int, int]]:
    k = max(1, int(np.ceil((b - a) / n)))
    edges = np.linspace(a, b, k + 1).round().astype(int)
    return list(zip(edges[:-1], edges[1:]))


def observation_blocks(static: np.ndarray, angles: np.ndarray,
                       samples_per_chunk: int) -> tuple[Blocks, Blocks]:
    """(gyro blocks, accelerometer blocks) of a log. A log whose table already moves at its first
    sample has no angle for the start of that sample's interval (the interpolation would take it
    at rest): that sample is left out."""
    first = 1 if len(angles) > 1 and np.any(angles[1] != angles[0]) else 0
    return (make_blocks(static, samples_per_chunk, whole_moves=True, start=first),
            make_blocks(static, samples_per_chunk, whole_moves=False, start=first))


def make_blocks(static: np.ndarray, samples_per_chunk: int, whole_moves: bool,
                start: int = 0) -> Blocks:
    """Static runs in chunks of at most *samples_per_chunk*; moving runs whole (gyro) or in
    chunks too (accelerometers); samples before *start* left out."""
    n = len(static)
    runs = [(max(a, start), b) for a, b in moving_runs(static) if b > start]
    spans: list[tuple[int, int, bool]] = []
    pos = start
    for a, b in runs:
        spans += [(s, e, False) for s, e in _chunks(pos, a, samples_per_chunk)] if a > pos else []
        spans += [(a, b, True)] if whole_moves else [(s, e, True) for s, e in _chunks(a, b, samples_per_chunk)]
        pos = b
    if pos < n:
        spans += [(s, e, False) for s, e in _chunks(pos, n, samples_per_chunk)]
    arr = np.array(spans, dtype=object) if spans else np.zeros((0, 3), dtype=object)
    return Blocks(arr[:, 0].astype(int), arr[:, 1].astype(int), arr[:, 2].astype(bool))


def white_noise_sigma(increments: np.ndarray, static: np.ndarray) -> np.ndarray:
    """Per-sample white-noise σ of each channel from static data: consecutive differences within
    static runs remove any constant (bias, gravity, Earth rate), var(x_k - x_{k-1}) = 2 σ².
    Returns (channels,). Falls back to NaN where there is no static pair."""
    both = static[1:] & static[:-1]
    d = np.diff(increments, axis=0)[both]
    if len(d) < 2:
        return np.full(increments.shape[1], np.nan)
    # a robust scale (median absolute deviation) so that a few steps at a run edge do not count
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(2)
