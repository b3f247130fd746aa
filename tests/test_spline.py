"""The moving runs' cubic spline (components.model.spline) against scipy.interpolate.CubicSpline
with the same end conditions, an independent implementation, and against curves it must
reproduce exactly."""
import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from components.model.spline import RunSpline, knot_slopes

ZERO = (1, np.zeros(2))


def _knots(rng, n, t0=1000.0):
    x = t0 + np.cumsum(rng.uniform(0.002, 0.008, n))  # jittered sample times
    y = np.cumsum(rng.normal(0, 0.01, (n, 2)), axis=0)
    return x, y


@pytest.mark.parametrize("n, clamp", [(n, c) for n in (2, 3, 4, 5, 12, 400)
                                      for c in ((True, True), (True, False), (False, True), (False, False))
                                      if n >= 4 or all(c)])  # not-a-knot needs four knots
def test_matches_scipy_cubic_spline(n, clamp):
    rng = np.random.default_rng(n)
    x, y = _knots(rng, n)
    ref = CubicSpline(x, y, axis=0, bc_type=tuple(ZERO if c else "not-a-knot" for c in clamp))
    spl = RunSpline(x, y, *clamp)
    k = np.repeat(np.arange(n - 1), 5)
    frac = np.tile([0.0, 0.1, 0.5, 0.9, 1.0], n - 1)
    u = frac * np.diff(x)[k]
    for d in range(3):
        want = ref(x[k] + u, d)
        scale = np.abs(want).max() + 1e-300
        # x + u in floating point is not x exactly u further on (scipy subtracts the knot again)
        np.testing.assert_allclose(spl(k, u, d), want, rtol=0, atol=1e-9 * scale)
    knots = np.arange(n)
    for d in (1, 2):
        np.testing.assert_allclose(spl.at_knots(knots)[d], ref(x, d), rtol=1e-12, atol=1e-12)


def test_reproduces_cubics_and_the_end_conditions():
    rng = np.random.default_rng(7)
    x, _ = _knots(rng, 30, t0=0.0)
    cubic = 0.3 - 1.2 * x + 0.8 * x**2 - 2.5 * x**3
    spl = RunSpline(x, cubic, False, False)  # not-a-knot at both ends: a cubic is its own spline
    np.testing.assert_allclose(knot_slopes(x, cubic, False, False)[:, 0], -1.2 + 1.6 * x - 7.5 * x**2, rtol=1e-9)
    mid = 0.37 * np.diff(x)
    k = np.arange(29)
    np.testing.assert_allclose(spl(k, mid)[:, 0], np.polyval([-2.5, 0.8, -1.2, 0.3], x[:-1] + mid), rtol=1e-10)
    clamped = RunSpline(x, cubic, True, True)
    np.testing.assert_array_equal(clamped.at_knots(np.array([0, 29]))[1][:, 0], [0.0, 0.0])
    # second derivative continuous at every inner knot: from the left as from the right
    left = clamped(k[:-1], np.diff(x)[:-1], 2)
    np.testing.assert_allclose(left, clamped.at_knots(k[1:])[2], rtol=1e-8)


@pytest.mark.parametrize("x, clamp, what", [([0.0, 1.0, 1.0, 2.0], (True, True), "strictly increasing"),
                                             ([0.0], (True, True), "at least two"),
                                             ([0.0, 1.0, 2.0], (True, False), "four knots")])
def test_bad_knots_are_one_clear_error(x, clamp, what):
    with pytest.raises(ValueError, match=what):
        knot_slopes(np.array(x), np.zeros((len(x), 1)), *clamp)
