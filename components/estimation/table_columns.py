"""The table effects' columns of the design: the derivative of the ideal block sums with respect
to each geometry parameter (base tilt, axis non-orthogonality, wobble, encoder errors), by
forward differences. The prediction is smooth in these small angles: the truncation error is
~1e-6 of the column, far below what the fit can resolve.

Why a module of its own: a log's 24 table parameters cost one kinematics pass each over every
moving sample, the largest part of diagnose's time. What makes them cheap:
- only block sums are needed, so a rest's increments are never formed per sample: a block's sum
  over its rests is Σ_attitudes (Σ dt of its samples at that attitude) × (rate or force there),
  a sparse (blocks × attitudes) matrix built once per profile;
- the moving samples' rate and force come from :meth:`TableGeometry.rate_and_force` (vectors
  rotated, no matrices);
- the difference perturbed − unperturbed is taken per attitude and per moving sample before it
  is summed, so no column loses digits to a block sum of gravity × seconds;
- geometry columns depend only on the angle profile, the blocks and the geometry: logs that
  share the motion (Monte-Carlo seeds, effects hidden in the IMU only) reuse them (a cache).
"""
from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

from components import progress
from components.estimation.blocks import Blocks
from components.model.geometry import TableGeometry
from components.model.motion import AngleProfile, IdealIncrements
from components.model.table_parameters import apply_table_parameter, table_parameter_value

TABLE_STEP = 1e-6  # rad, forward-difference step of the geometry parameters
_GEOMETRY_COLUMNS: "OrderedDict[tuple, tuple]" = OrderedDict()
GEOMETRY_CACHE = 256  # entries kept


def remember_geometry_columns(columns: dict) -> None:
    """Keep *columns* (key -> (gyro, accelerometer) block columns), the oldest dropped beyond
    :data:`GEOMETRY_CACHE` (also how a chunk worker's columns reach its parent's cache)."""
    _GEOMETRY_COLUMNS.update(columns)
    while len(_GEOMETRY_COLUMNS) > GEOMETRY_CACHE:
        _GEOMETRY_COLUMNS.popitem(last=False)


def geometry_columns_since(known: set) -> dict:
    """The cached geometry columns whose keys are not in *known*."""
    return {k: v for k, v in _GEOMETRY_COLUMNS.items() if k not in known}


def geometry_column_keys() -> set:
    return set(_GEOMETRY_COLUMNS)


class _BlockMap:
    """Where the samples of a profile fall in one set of blocks (sorted, not overlapping, as
    blocks.make_blocks makes them): the rests as a sparse (blocks × attitudes) matrix of summed
    intervals, the moving samples as their block's row (-1: in none)."""

    def __init__(self, profile: AngleProfile, blocks: Blocks, moving_index: np.ndarray):
        start, stop = blocks.start, blocks.stop
        if np.any(start[1:] < stop[:-1]):
            raise ValueError("table columns: blocks overlap or are not sorted")
        self.n = len(blocks)
        st = np.flatnonzero(profile.static)
        row = _row_of(st, start, stop)
        inside = row >= 0
        n_att = 0 if profile.attitudes is None else len(profile.attitudes)
        # imported at use: scipy.sparse was ~0.1 s of every diagnose, calibrate and compare, and
        # only table effects' columns need it
        from scipy import sparse

        self.rests = (sparse.csr_matrix((profile.dt[st][inside], (row[inside], profile.attitude_of[inside])),
                                        shape=(self.n, n_att)) if n_att else sparse.csr_matrix((self.n, 0)))
        self.moving_row = _row_of(moving_index, start, stop)

    def sums(self, per_attitude: np.ndarray, per_moving: np.ndarray) -> np.ndarray:
        """(blocks, 3): Σ over each block of rests (attitude values × time) and moving samples."""
        out = np.asarray(self.rests @ per_attitude) if self.rests.shape[1] else np.zeros((self.n, 3))
        keep = self.moving_row >= 0
        for k in range(3):
            out[:, k] += np.bincount(self.moving_row[keep], per_moving[keep, k], minlength=self.n)
        return out


def _row_of(samples: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
    row = np.searchsorted(start, samples, side="right") - 1
    ok = row >= 0
    ok[ok] = samples[ok] < stop[row[ok]]
    return np.where(ok, row, -1)


def table_columns(profile: AngleProfile, gb: Blocks, ab: Blocks, geo: TableGeometry,
                  table_params: list[str]) -> dict:
    """parameter -> (gyro block columns (B_g, 3), accelerometer block columns (B_a, 3)): d(ideal
    block sums)/d(parameter) by a forward step of :data:`TABLE_STEP`, from the cache where the
    profile (its digest), blocks and geometry were seen before."""
    if not table_params:
        return {}
    blocks_key = hashlib.sha256(gb.start.tobytes() + gb.stop.tobytes() + ab.start.tobytes()
                                + ab.stop.tobytes()).hexdigest()
    keys = {p: (profile.key, blocks_key, geo, p) for p in table_params}
    # taken out of the cache first: adding the missing ones may drop the oldest, which can be ours
    columns = {p: _GEOMETRY_COLUMNS[key] for p, key in keys.items() if key in _GEOMETRY_COLUMNS}
    missing = [p for p in keys if p not in columns]
    if not missing:
        return columns
    ideal = IdealIncrements(profile)
    gmap, amap = _BlockMap(profile, gb, ideal.moving_index), _BlockMap(profile, ab, ideal.moving_index)
    base = ideal.of(geo)
    with progress.steps("table effects' columns", len(missing)) as bar:
        for p in missing:
            v = table_parameter_value(geo, p)
            rg, ra, mg, ma = (x - x0 for x, x0 in zip(ideal.of(apply_table_parameter(geo, p, v + TABLE_STEP)), base))
            columns[p] = (gmap.sums(rg, mg) / TABLE_STEP, amap.sums(ra, ma) / TABLE_STEP)
            remember_geometry_columns({keys[p]: columns[p]})
            bar.update()
    return columns
