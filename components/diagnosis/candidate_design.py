"""The whitened block design every candidate of a diagnosis is refitted on: the rows of the
model's and every candidate's parameters (components.estimation.chunks), whitened with the noise
model, and their compressed form — R of the QR of [H | y] — on which each refit is a solve of a
few dozen rows whatever the log's length.

Only the raw rows are kept (on a long log in a spilled array: components.logs.spill); the
whitened ones are made a piece at a time, each channel's filter carrying its state from piece to
piece (components.estimation.whitening.whitened_pieces), and go straight into R
(components.estimation.stacked_qr), so no whitened copy of the rows — nor, on a spilled log, the
raw rows themselves — is ever in memory whole. What the diagnosis needs per row (a residual, a
signature's column) is whitened the same way, a column or a few at a time."""
from __future__ import annotations

import math

import numpy as np

from components.estimation.blocks import samples_per_block
from components.estimation.chunks import CHUNK_SAMPLES, BlockLayout, chunked_design
from components.estimation.design import ACC_SCALE, GYRO_SCALE, noise_floor
from components.estimation.log_data import LogData
from components.estimation.rest_angles import rest_sigma
from components.estimation.stacked_qr import scaled_lstsq
from components.estimation.whitening import whitened_pieces, whitened_r
from components.logs.spill import product
from components.model.effects import effect_of
from components.model.noise import NoiseModel
from components.model.plausibility import grade_factor
from components.model.result import CalibrationResult


class CandidateDesign:
    """Block design of all parameters of the model and of every candidate (and, on a log without
    table angles, of the rests' attitudes, always in the base): the raw rows ``raw`` = (y, H,
    weights, row information), whitened under ``noise`` on demand."""

    def __init__(self, params: list[str], raw: tuple, noise: NoiseModel | None, dt: float, span: float,
                 t_lo: float, white_sigma: np.ndarray, nuisance: list[str] | None = None):
        self.params = params
        self.index = {p: k for k, p in enumerate(params)}
        self.raw, self.noise = raw, noise
        self.dt, self.span, self.t_lo = dt, span, t_lo
        self.white_sigma = white_sigma
        # how many times noisier than navigation grade (per sensor; plausibility.grade_factor)
        self.grade = grade_factor({"gyro": float(np.median(white_sigma[:3])) / math.sqrt(dt),
                                   "acc": float(np.median(white_sigma[3:])) / math.sqrt(dt)})
        self.n = len(raw[0])
        self.nuisance = list(nuisance or [])
        self._bases: dict = {}  # base parameters -> orthonormal basis of their columns
        self._compressed: np.ndarray | None = None
        self._before: tuple | None = None  # the whitening rewhiten replaced, to go back to it

    @classmethod
    def on_table_log(cls, data: LogData, model: CalibrationResult, params: list[str],
                     chunk_s: float, rest_angle_sigma, noise: NoiseModel | None = None,
                     chunk_samples: int = CHUNK_SAMPLES) -> "CandidateDesign":
        """The block rows of a log with table angles at the model's geometry."""
        from components.diagnosis.compare import model_geometry

        geo = model_geometry(data, model)
        table_params = [p for p in params if effect_of(p).target == "table"]
        T0 = model.temperature_ref
        dt = data.sample_interval
        layout = BlockLayout.of(data, samples_per_block(dt, chunk_s), chunk_samples)
        # noise from the high-frequency content of the data (differences remove the model)
        q = data.quantization_floor(noise)
        sg = np.maximum(data.white_sigma_at_rest("gyro"), q[:3])
        sa = np.maximum(data.white_sigma_at_rest("acc"), q[3:])
        if noise is not None and noise.coloured:
            white = noise.white_sigma(dt)
            sg, sa = np.where(white[:3] > 0, white[:3], sg), np.where(white[3:] > 0, white[3:], sa)
        sg, sa = noise_floor(sg, GYRO_SCALE * dt), noise_floor(sa, ACC_SCALE * dt)
        rest = rest_sigma(data.angles, rest_angle_sigma, data.encoder_resolution)
        # (a long log's rows are spilled, as its samples are: every candidate's columns, ~0.4 GB
        # on an 8-hour log)
        y, H, w, rows = chunked_design(data, layout, params, sg, sa, rest, geo, table_params, T0)
        span = float(data.time[-1] - data.time[0] + dt)
        # table columns are derivatives at the model's geometry: the model's table values are
        # already in the motion, so their unknowns here are corrections (start at 0)
        return cls(params, (y, H, w, rows), noise, dt, span, chunk_s, np.concatenate([sg, sa]))

    @classmethod
    def on_positions_log(cls, data: LogData, model: CalibrationResult, params: list[str], chunk_s: float,
                         noise: NoiseModel | None = None) -> "CandidateDesign":
        """The rows of a log without table angles (components.estimation.positions_design),
        linearised at the attitudes that fit it best with the model's parameters refitted on it;
        the attitudes' columns join the parameters as nuisances."""
        from components.estimation.positions_design import PositionsDesign
        from components.estimation.positions_effects import fit_positions

        base = [p for p in params if p in model.values or effect_of(p).name in model.effects]
        refit = fit_positions(data, list(model.effects), noise=noise, chunk_s=chunk_s,
                              temperature_ref=model.temperature_ref)
        values = refit.values()
        theta = np.array([values.get(p, 0.0) if p in base else 0.0 for p in params])
        pd = PositionsDesign(data, chunk_s=chunk_s, noise=noise, temperature_ref=model.temperature_ref)
        r = pd.rows(refit.attitudes, params, theta)
        names = pd.attitude_names
        info = dict(r.info)
        dt = pd.dt_med
        span = float(data.time[-1] - data.time[0] + dt)
        # (rows already weighted: unit weights, and no noise model to whiten them with again)
        return cls(params + names, (r.y, np.hstack([r.H, r.A]), np.ones(len(r.y)), info), None, dt, span, chunk_s,
                   np.concatenate([pd.sg, pd.sa]), nuisance=names)

    def rewhiten(self, noise: NoiseModel | None) -> None:
        """Whiten the same rows with another noise model (a noise term added); back to the
        whitening before it without whitening again (a noise term tried and dropped); the model
        it is whitened with already: nothing to do."""
        if noise is self.noise:
            return
        state = (self.noise, self._compressed)
        if self._before is not None and self._before[0] is noise:
            self.noise, self._compressed = self._before
        else:
            self.noise, self._compressed = noise, None
        self._before = state
        self._bases = {}

    def _whitened(self, y: np.ndarray, columns: list[int] | None):
        """(slice of rows, whitened [H[:, columns] | y] of them; None: every column), a piece at a time."""
        _, H, w, rows = self.raw
        return whitened_pieces(y, H, rows, 1.0 / w**2, self.noise, self.dt, self.span, self.t_lo,
                               piece=QR_ROWS, columns=columns)

    @property
    def compressed(self) -> np.ndarray:
        """R of the QR of the whitened [H | y], (min(n, p+1), p+1): H = Q R[:, :p] and y = Q R[:, p]
        + what lies outside every column's span, whose length is R[p, p]. Any least squares on a
        subset of the columns has on these few rows the same solution, χ² and singular values as
        on the n whitened rows (Q is orthonormal), so every candidate's refit, projection and rank
        is a solve of p+1 rows, not of the log's block rows (on an 8-hour log 180 000, each refit
        ~0.1 s: most of a diagnose's ranking)."""
        if self._compressed is None:
            y, H, w, rows = self.raw
            self._compressed = whitened_r(y, H, rows, 1.0 / w**2, self.noise, self.dt, self.span, self.t_lo,
                                          piece=QR_ROWS)
        return self._compressed

    def whitened_columns(self, names: list[str]) -> np.ndarray:
        """The whitened rows' columns of *names*, (n, len(names))."""
        out = np.empty((self.n, len(names)))
        for at, M in self._whitened(np.zeros(self.n), [self.index[p] for p in names]):
            out[at] = M[:, :-1]
        return out

    def _columns(self, names: list[str]) -> np.ndarray:
        """The compressed rows of the columns of *names*."""
        return self.compressed[:, [self.index[p] for p in names]]

    @property
    def _rows_y(self) -> np.ndarray:
        return self.compressed[:, -1]

    def fit(self, subset: list[str]) -> tuple[float, np.ndarray, np.ndarray, int]:
        """χ², values, covariance and rank of the WLS fit on *subset* of the parameters."""
        y = self._rows_y
        if not subset:
            return float(y @ y), np.zeros(0), np.zeros((0, 0)), 0
        sol, chi2, cov, rank = scaled_lstsq(self._columns(subset), y, 1e-10)
        return chi2, sol, cov, rank

    def residual(self, subset: list[str]) -> np.ndarray:
        """The whitened rows' residual of the fit on *subset* (the filter is linear: the whitened
        raw residual)."""
        y, H, _, _ = self.raw
        r = np.array(y, dtype=float)
        if subset:
            idx = [self.index[p] for p in subset]
            sol = np.linalg.lstsq(self.compressed[:, idx], self._rows_y, rcond=1e-10)[0]
            r -= product(H, sol, idx, step=QR_ROWS)
        out = np.empty(self.n)
        for at, M in self._whitened(r, []):
            out[at] = M[:, 0]
        return out

    def projected_column(self, base: list[str], p: str) -> np.ndarray:
        """Column of *p* with the span of *base* projected out, in the compressed rows (its
        inner products with other such columns, and with :meth:`projected`'s, are the whitened
        rows')."""
        c = self.compressed[:, self.index[p]].copy()
        if base:
            Q = self._basis_of(base)
            c = c - Q @ (Q.T @ c)
        return c

    def _basis_of(self, base: list[str]) -> np.ndarray:
        """Q of the QR of *base*'s scaled columns (compressed rows), once per base (every
        candidate of a ranking projects out the same base)."""
        key = tuple(base)
        if key not in self._bases:
            B = self._columns(base)
            self._bases = {key: np.linalg.qr(B / np.maximum(np.linalg.norm(B, axis=0), 1e-300))[0]}
        return self._bases[key]

    def projected(self, base: list[str], extra: list[str]) -> np.ndarray:
        """Columns of *extra* with the span of *base* projected out (orthonormal basis, in the
        compressed rows)."""
        C = self._columns(extra)
        if base:
            Q = self._basis_of(base)
            C = C - Q @ (Q.T @ C)
        norms = np.linalg.norm(C, axis=0)
        C = C[:, norms > 1e-9 * max(norms.max(initial=0.0), 1e-300)]
        if C.shape[1] == 0:
            return C
        U, s, _ = np.linalg.svd(C, full_matrices=False)
        return U[:, s > 1e-8 * s[0]]


# rows whitened and factored at a time (with the R so far on top: ~20 MB at 150 columns)
QR_ROWS = 1 << 14
