"""The system-level filter's innovation whiteness check (components.navigation.consistency):
beyond the filter's own first two lags a consistent filter's normalised innovations are white,
and a slow noise it has no state for is not. Checked on processes whose autocorrelation is known:
white noise and a moving average of order 2 (correlated at lags 1-2 only, as the filter's own
structure) pass; the same with a slow AR(1) wander of 5 % of the variance (φ = 0.98, as a bias
instability the filter does not model) is named, with the component."""
from __future__ import annotations

import numpy as np

from components.navigation.consistency import Consistency, _whiteness

N = 4000


def _problems(z: np.ndarray) -> list[str]:
    c = Consistency("S202")
    _whiteness(c, "S202", z)
    return c.problems


def test_white_and_short_memory_innovations_pass():
    rng = np.random.default_rng(7)
    assert _problems(rng.normal(size=(N, 3))) == []
    e = rng.normal(size=(N + 2, 3))
    ma2 = (e[2:] + 0.3 * e[1:-1] + 0.1 * e[:-2]) / np.sqrt(1 + 0.09 + 0.01)
    assert _problems(ma2) == []


def test_a_slow_wander_the_filter_lacks_is_named():
    rng = np.random.default_rng(8)
    z = rng.normal(size=(N, 3))
    w = np.zeros(N)
    e = rng.normal(size=N) * np.sqrt(1 - 0.98**2)
    for k in range(1, N):
        w[k] = 0.98 * w[k - 1] + e[k]
    z[:, 2] = np.sqrt(0.95) * z[:, 2] + np.sqrt(0.05) * w
    found = _problems(z)
    assert len(found) == 1 and "correlated in time" in found[0] and "component z" in found[0], found


def test_a_long_runs_slight_correlation_is_not_named():
    """60 000 updates with a 2 % wander: its autocorrelation (~0.02 at lags 3-10) is significant by
    the run's length alone, far below what a missing noise does (0.07-0.16): not named, and the
    p-value still reported."""
    rng = np.random.default_rng(9)
    n = 60_000
    w = np.zeros(n)
    e = rng.normal(size=n) * np.sqrt(1 - 0.98**2)
    for k in range(1, n):
        w[k] = 0.98 * w[k - 1] + e[k]
    z = rng.normal(size=(n, 3))
    z[:, 0] = np.sqrt(0.98) * z[:, 0] + np.sqrt(0.02) * w
    c = Consistency("S202")
    _whiteness(c, "S202", z)
    assert c.problems == [] and c.whiteness_p < 1e-6


def test_a_log_of_fewer_positions_than_the_configurations_schedule_is_said():
    """kf psins19 on a six-position log: the configuration's states are excited by its schedule's
    19 positions, and on six some stay near their prior; said before the run. A log with the
    schedule's own labels is not."""
    from components.control.schedule import load_schedule
    from components.navigation.configs import load_config

    cfg = load_config("psins19")
    six = np.array([f"pos0{k}" for k in range(1, 7)] + ["move-pos01"])
    said = cfg.schedule_mismatch(six, "six")
    assert len(said) == 1 and "6 segment label(s)" in said[0] and "has 19" in said[0], said
    own = np.array(load_schedule("psins19").labels)
    assert cfg.schedule_mismatch(own, "psins19") == []
