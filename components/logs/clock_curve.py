"""A table controller's clock whose rate changes over the record.

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

from dataclasses import dataclass

import numpy as np

from components.errors import MappingError

MOST_DEGREE = 10  # a soak (an exponential approach over a quarter of the record) to ~1e-4 of its bow
CURVE_P = 1e-3    # the term added must be this unlikely from the residual alone


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
        return np.polynomial.legendre.legval(x, np.concatenate([[0.0, 0.0], self.coefficients]))

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


def curved(refine, moving: np.ndarray, line: np.ndarray, t_ref: float, scale: float, offset_sigma: float,
           stretches):
    """(line with the curve's coefficients appended, covariance, ClockCurve or None): degrees 2..
    MOST_DEGREE added in turn to *line* (δ, rate) while each is significant and bows by more than
    *offset_sigma*, and the curve kept only where it explains the *stretches*' offsets about their
    line (ClockOffset.stretches) beyond their scatter (:func:`_seen_in_stretches`). *refine*
    (samples, coefficients) -> (coefficients, covariance, residual sum of squares, samples used):
    table_clock._refine with the polynomial on x = (t − t_ref) / scale."""
    from scipy.special import fdtrc

    best, cov, rss, n = refine(moving, line)
    curve = None
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
    return best, cov, curve


def _seen_in_stretches(curve: ClockCurve, stretches) -> bool:
    """Whether the stretches' offsets follow *curve* beyond their scatter: an F-test of its amplitude
    fitted with a line to them (weighted by their σ), against what it leaves. Every moving sample's
    residual is not white: a 200 Hz table's interpolation errs with each move's profile, and on a
    rig whose clocks share a crystal the samples alone found a 3.8 µs curve (a 0.02 ppm rate
    change) that the stretches do not show. None (too few stretches move): not seen."""
    from scipy.special import fdtrc

    if stretches is None:
        return False
    t, off, var = (np.asarray(v, float) for v in stretches)
    if len(t) < 5:
        return False
    w = 1.0 / np.sqrt(var)
    x = (t - t.mean()) / max(float(np.ptp(t)), 1.0)
    line = np.column_stack([np.ones_like(x), x]) * w[:, None]
    both = np.column_stack([line, curve(t) * w])
    chi2 = [float(np.sum((A @ np.linalg.lstsq(A, off * w, rcond=None)[0] - off * w) ** 2)) for A in (line, both)]
    dof = len(t) - 3
    if chi2[1] <= 0:
        return chi2[0] > 0
    return bool(fdtrc(1, dof, (chi2[0] - chi2[1]) / (chi2[1] / dof)) < CURVE_P)
