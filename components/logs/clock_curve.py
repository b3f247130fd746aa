"""A table controller's clock against the line its offset is fitted as: a rate that changes over
the record (a curve), and a bow that shows which clock drifts.

An uncompensated crystal warming after power-on moves by ppm over the first hour. Against the
IMU's clock, the table's offset then bows away from any line (an offset and a rate): 1 ppm
soaking over 36 minutes bows it 0.26 ms, and the table's angles set against the gyros' turn
during each move's acceleration misfit by far more than a navigation-grade gyro's noise
(χ²/dof 1.10 on a 26-position log, out of its band). The offset is then a polynomial in time: the
line, and terms of degree 2 and up fitted with it by the same Gauss–Newton on every moving
sample (table_clock._refine), each degree kept while the term it adds is significant against the
residual of every moving sample (an F-test) and the curve it makes bows by more than the
offset's σ (a curve below that changes no angle the data could tell); the curve is then kept
only where the offsets of the record's stretches follow it beyond their scatter.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from components.errors import MappingError

MOST_DEGREE = 10  # a soak (an exponential approach over a quarter of the record) to ~1e-4 of its bow
CURVE_P = 1e-3    # the term added must be this unlikely from the residual alone
# the table's offsets must follow the other clock this many of their σ away from the one the
# mapping says, and nearer it than the mapping's, before the import says the mapping is wrong
WRONG_CLOCK_SIGMAS = 5.0


def legendre_tail(x, terms: int) -> np.ndarray:
    """(len(x), terms): the Legendre polynomials P_2(x) .. P_{terms+1}(x), the curve's basis beyond
    the line (the offset's value at x: these times its coefficients)."""
    return np.polynomial.legendre.legvander(np.atleast_1d(np.asarray(x, float)), terms + 1)[:, 2:]


@dataclass
class ClockCurve:
    """The table's offset beyond its line, on the IMU's clock: Σ_k c_k P_k(x) for k ≥ 2 (Legendre
    polynomials, orthogonal on the record: the degrees stay apart), x = (t − t_ref) / scale, less
    its value at *zero_at* (where the offset is said: the table's first sample)."""

    t_ref: float
    scale: float
    coefficients: np.ndarray  # c_2 .. c_degree [s]
    zero_at: float | None = None

    def __call__(self, t: np.ndarray) -> np.ndarray:
        c = self._raw(np.asarray(t, float))
        return c if self.zero_at is None else c - self._raw(np.asarray(self.zero_at, float))

    def _raw(self, t: np.ndarray) -> np.ndarray:
        x = (t - self.t_ref) / self.scale
        return (legendre_tail(x, len(self.coefficients)) @ self.coefficients).reshape(np.shape(x))

    @property
    def _grid(self) -> np.ndarray:
        return np.linspace(-1.0, 1.0, 401)

    @property
    def bow_s(self) -> float:
        """How far the offset bows away from its best line over the record."""
        x = self._grid
        c = self(self.t_ref + self.scale * x)
        return float(np.max(np.abs(c - np.polyval(np.polyfit(x, c, 1), x))))

    @property
    def rate_span_ppm(self) -> float:
        """How far the clocks' rate moves over the record."""
        leg = np.polynomial.legendre
        rate = leg.legval(self._grid, leg.legder(np.concatenate([[0.0, 0.0], self.coefficients]))) / self.scale
        return float(np.ptp(rate)) * 1e6

    def said(self) -> str:
        """What the import says of it."""
        return (f"the clocks' rate moving over {self.rate_span_ppm:.3g} ppm across the record, the offset bowing up "
                f"to {self.bow_s * 1e3:.3g} ms off its line (followed: degree {len(self.coefficients) + 1} in time; the rate "
                "above is at the record's middle)")


def curved(refine, moving: np.ndarray, line: np.ndarray, rss: float, t_ref: float, scale: float,
           offset_sigma: float, stretches):
    """(line with the curve's coefficients appended, covariance, ClockCurve or None): degrees 2..
    MOST_DEGREE added in turn to *line* (δ, rate, fitted on every moving sample with the residual
    sum of squares *rss*) while each is significant and bows by more than *offset_sigma*, and the
    curve kept only where it explains the *stretches*' offsets about their line
    (ClockOffset.stretches) beyond their scatter (:func:`_seen_in_stretches`). *refine* (samples,
    coefficients) -> (coefficients, covariance, residual sum of squares, samples used):
    table_clock._refine with the polynomial on x = (t − t_ref) / scale."""
    from scipy.special import fdtrc

    best, cov, curve = line, None, None
    for degree in range(2, MOST_DEGREE + 1):
        try:
            got, got_cov, got_rss, got_n = refine(moving, np.concatenate([best, [0.0]]))
        except (MappingError, np.linalg.LinAlgError):
            break  # too few samples overlap the table at a trial curve, or a singular step
        dof = got_n - len(got)
        if dof <= 0 or got_rss <= 0 or got_rss >= rss:
            break
        f = (rss - got_rss) / (got_rss / dof)
        candidate = ClockCurve(t_ref, scale, np.asarray(got[2:], float))
        if fdtrc(1, dof, f) > CURVE_P or candidate.bow_s <= offset_sigma:
            break
        best, cov, rss, curve = got, got_cov, got_rss, candidate
    if curve is not None and not _seen_in_stretches(curve, stretches):
        return line, None, None
    if curve is not None:
        # σ at least what the stretches' scatter about the line and the curve says, as the line's
        # is about the line (every moving sample's residual is not white: a 1 ppm soak's rate came
        # out 4 of its σ off its truth with the σ of the samples alone)
        fit = _line_and(stretches, curve(np.asarray(stretches[0], float)))
        if fit is not None and fit[4] > 0:
            cov = cov * max(1.0, fit[3] / fit[4])
    return best, cov, curve


def _seen_in_stretches(curve: ClockCurve, stretches) -> bool:
    """Whether the stretches' offsets follow *curve* beyond their scatter: an F-test of its amplitude
    fitted with a line to them (:func:`_line_and`), against what it leaves. Every moving sample's
    residual is not white: a 200 Hz table's interpolation errs with each move's profile, and on a
    rig whose clocks share a crystal the samples alone found a 3.8 µs curve (a 0.02 ppm rate
    change) that the stretches do not show. None (too few stretches move): not seen."""
    from scipy.special import fdtrc

    if stretches is None or len(stretches[0]) < 5:
        return False
    fit = _line_and(stretches, curve(np.asarray(stretches[0], float)))
    if fit is None:
        return False
    _, _, chi2_line, chi2, dof = fit
    if chi2 <= 0:
        return chi2_line > 0
    return bool(fdtrc(1, dof, (chi2_line - chi2) / (chi2 / dof)) < CURVE_P)


def bow_followed(stretches, at: np.ndarray, bow: np.ndarray) -> tuple[float, float] | None:
    """How much of the stamps' bow a table clock's offsets follow: *a* of offset = δ + r t + a·bow(t)
    fitted to the offsets of the record's stretches (:func:`_line_and`), its σ widened by their
    scatter about the fit; None with fewer than four stretches. *bow* (s) at the log's times *at*:
    the host's stamps less the sensor's grid.

    The stamps cannot tell which clock drifts; a table on a third clock can. Matched against the
    host's stamps, a table controller's clock that keeps the sensor's time shows the host's bow in
    its offsets (a = 1), one that keeps the host's shows none (a = 0); matched against the
    sensor's clock, a = 0 and −1."""
    if len(stretches[0]) < 4:
        return None
    fit = _line_and(stretches, np.interp(np.asarray(stretches[0], float), at, bow))
    if fit is None:
        return None
    a, var_a, _, chi2, dof = fit
    return a, math.sqrt(var_a * max(1.0, chi2 / max(dof, 1)))


def _line_and(stretches, shape: np.ndarray):
    """The stretches' offsets (times, offsets, variances) fitted, weighted by their σ, with a line
    and *shape* (its values at their times): (the shape's amplitude, its variance from their σ, χ²
    of the line alone, χ² with the shape, the degrees of freedom left), or None where the shape is
    a line over them (the offset and the rate take it)."""
    t, off, var = (np.asarray(v, float) for v in stretches)
    w = 1.0 / np.sqrt(var)
    A = np.column_stack([np.ones_like(t), t - t.mean(), shape]) * w[:, None]
    scale = np.linalg.norm(A, axis=0)
    if np.any(scale == 0):
        return None
    A = A / scale
    if np.linalg.cond(A) > 1e6:
        return None
    y = off * w
    chi2 = [float(np.sum((B @ np.linalg.lstsq(B, y, rcond=None)[0] - y) ** 2)) for B in (A[:, :2], A)]
    sol = np.linalg.lstsq(A, y, rcond=None)[0]
    var_a = float(np.linalg.inv(A.T @ A)[2, 2])
    return float(sol[2] / scale[2]), var_a / scale[2] ** 2, chi2[0], chi2[1], len(t) - 3
