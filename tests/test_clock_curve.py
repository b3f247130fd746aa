"""The test that keeps a table clock's curve only where the stretches of the record show it
(components.logs.clock_curve): its size and power against the F distribution it claims."""
import numpy as np

from components.logs.clock_curve import CURVE_P, ClockCurve, _seen_in_stretches


def _stretches(rng, curve=None, amplitude=0.0):
    """Eight stretches over 36 minutes: a line (7.7 ms, 30 ppm), white scatter of their σ (1-2 µs),
    and *amplitude* times *curve*."""
    t = np.linspace(100.0, 2060.0, 8)
    sigma = rng.uniform(1e-6, 2e-6, 8)
    off = 7.7e-3 + 30e-6 * (t - t[0]) + rng.normal(0.0, sigma)
    if curve is not None:
        off = off + amplitude * curve(t)
    return t, off, sigma**2


def test_a_curve_the_stretches_do_not_show_is_refused_at_its_nominal_rate():
    """Under the null (the stretches a line and white scatter of their stated σ; the curve's shape
    fixed beforehand) the F-test refuses all but CURVE_P of the curves: of 4000 draws (4
    expected to pass), more than 16 has a binomial probability of 1.1e-6. A curve bowing 7 µs, a
    few σ of a stretch: the samples alone found one of 3.8 µs on a rig whose clocks share a
    crystal."""
    rng = np.random.default_rng(1)
    curve = ClockCurve(1080.0, 980.0, np.array([5e-6, -2e-6]))
    passed = sum(_seen_in_stretches(curve, _stretches(rng)) for _ in range(4000))
    assert CURVE_P == 1e-3
    assert passed <= 16, passed


def test_a_curve_the_stretches_follow_is_kept():
    """The same curve in the stretches at 20 times the scatter (a crystal's soak: 90 µs over 36
    minutes): kept in every draw; and not where the stretches are too few to tell."""
    rng = np.random.default_rng(2)
    curve = ClockCurve(1080.0, 980.0, np.array([5e-6, -2e-6]))
    assert all(_seen_in_stretches(curve, _stretches(rng, curve, 8.0)) for _ in range(200))
    t, off, var = _stretches(rng, curve, 8.0)
    assert not _seen_in_stretches(curve, (t[:4], off[:4], var[:4]))
    assert not _seen_in_stretches(curve, None)
