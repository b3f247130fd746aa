"""The plate motion as the block sums of the design need it: the moving samples one by one, each
rest block as one row.

Why: at rest the attitude is fixed, so every sensor effect's regressor over a rest sample is its
attitude's rate or force (times a coefficient) times the interval, plus terms linear in the
temperature and in the time (components.model.effects: temp, sf_temp, drift). A rest block's sum
is then the same regressor evaluated once, on a row whose interval is the block's Σ dt and whose
temperature and time are the dt-weighted means over the block (the linear interpolation between
samples integrates to the interval's mid value). Logs are mostly rests: on a 42-minute 200 Hz
log 95 % of the samples, and on a thermal soak nearly all, whose per-node rows were most of the
design's time and memory. The interval-boundary terms (time offsets) telescope over a rest: only
the block's first sample, whose start may be the end of a move, contributes, and the row takes
that sample's start values.

tests/test_block_motion.py holds every effect of the vocabulary to the per-sample sums.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from components.estimation.blocks import Blocks, block_sums
from components.model.motion import AngleProfile, Motion, motion_from_profile


class BlockMotion:
    """The motion of one log (its angle profile, geometry and temperature) for block sums."""

    def __init__(self, profile: AngleProfile, geometry, temperature: np.ndarray | None,
                 t0_temperature: float | None, time_origin: float | None):
        self.profile = profile
        self.geometry = geometry
        self.temperature = None if temperature is None else np.asarray(temperature, float)
        self.t0_temperature = t0_temperature
        self.time_origin = profile.t_prev[0] if time_origin is None else time_origin
        self.moving_index = profile.moving_index
        self.moving = motion_from_profile(profile, geometry, temperature, t0_temperature,
                                          time_origin=self.time_origin, samples=self.moving_index)

    def rests(self, blocks: Blocks) -> Motion:
        """One row per rest block of *blocks* (in their order), one node at weight 1: a
        regressor on it is the block's sum of that regressor over its samples."""
        p = self.profile
        r = ~blocks.moving
        start, stop = blocks.start[r], blocks.stop[r]
        first = motion_from_profile(p, self.geometry, self.temperature, self.t0_temperature,
                                    time_origin=self.time_origin, samples=start)
        total = block_sums(p.dt, start, stop)
        # Σ dt·(T at the interval's middle − T0) and Σ dt·(time at the middle − origin)
        elapsed = block_sums(p.dt * ((p.t_prev - self.time_origin) + 0.5 * p.dt), start, stop)
        if self.temperature is not None:
            T = self.temperature
            mid = np.empty_like(T)
            mid[0] = T[0]
            np.add(T[1:], T[:-1], out=mid[1:])
            mid[1:] *= 0.5
            dtemp = block_sums(p.dt * (mid - first.t0_temperature), start, stop)
        else:
            dtemp = np.zeros(len(start))
        safe = np.where(total > 0, total, 1.0)
        return replace(first, time=p.time[np.maximum(stop - 1, start)], dt=total, nodes=np.array([0.5]),
                       weights=np.array([1.0]), omega_q=first.omega_q[:, :1], alpha_q=first.alpha_q[:, :1],
                       f_q=first.f_q[:, :1], dtemp_q=(dtemp / safe)[:, None], elapsed_q=(elapsed / safe)[:, None])

    def sums(self, blocks: Blocks, per_moving: np.ndarray, per_rest: np.ndarray) -> np.ndarray:
        """Block sums (B, ...) from a per-sample array over the moving samples (rows of
        :attr:`moving`) and one over the rest rows of *blocks* (rows of :meth:`rests`)."""
        out = np.empty((len(blocks),) + per_moving.shape[1:])
        r = ~blocks.moving
        out[r] = per_rest
        if (~r).any():
            start, stop = self.moving_rows(blocks)
            out[~r] = block_sums(per_moving, start, stop)
        return out

    def moving_rows(self, blocks: Blocks) -> tuple[np.ndarray, np.ndarray]:
        """[start, stop) of each moving block of *blocks* in the rows of :attr:`moving`."""
        m = blocks.moving
        start = np.searchsorted(self.moving_index, blocks.start[m])
        stop = np.searchsorted(self.moving_index, blocks.stop[m])
        if np.any(stop - start != blocks.stop[m] - blocks.start[m]):
            raise ValueError("block motion: a moving block holds a rest sample")
        return start, stop
