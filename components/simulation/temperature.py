"""The IMU's environment temperature in a simulated run: a Python unit whose output
``temperature_env`` [degC] an IMU in temperature mode 2 follows (ours interpolates it linearly
between steps), and the scenario file's ``[temperature] profile``, a piecewise-linear heat, soak
and cool: the changes of temperature that a temperature coefficient needs, which a constant or a
single ramp does not give (on a ramp a temperature term and a linear drift are one column)."""
from __future__ import annotations

from bisect import bisect_right
from typing import Callable

from components.errors import ScenarioError
from orchestrator.component import Component, Var

# beyond any thermal chamber or IMU's operating range: a typo or the wrong unit (K for °C)
LOWEST, HIGHEST = -100.0, 200.0  # degC


class TemperatureSource(Component):
    """Output ``temperature_env`` [degC] = profile(t) at the end of each step."""

    variables = [Var("temperature_env", "output", "Real", 25.0, "degC")]

    def __init__(self, name: str, profile: Callable[[float], float] | None = None) -> None:
        super().__init__(name)
        self.profile = profile or (lambda t: 25.0)

    def initialize(self, t0: float) -> None:
        self["temperature_env"] = float(self.profile(t0))

    def do_step(self, t: float, h: float) -> None:
        self["temperature_env"] = float(self.profile(t + h))


def piecewise_linear(knots: tuple) -> Callable[[float], float]:
    """T(t) through the (time [s], temperature [degC]) *knots*, held before the first and after
    the last; numpy's interpolation formula in plain Python: it runs at every co-simulation step,
    where np.interp on one number cost 1 µs of a ~14 µs step."""
    t = [float(k[0]) for k in knots]
    T = [float(k[1]) for k in knots]
    slope = [(T[j + 1] - T[j]) / (t[j + 1] - t[j]) for j in range(len(t) - 1)]

    def at(s: float) -> float:
        if s <= t[0]:
            return T[0]
        if s >= t[-1]:
            return T[-1]
        j = bisect_right(t, s) - 1
        return slope[j] * (s - t[j]) + T[j]
    return at


def profile_from_table(table, where: str) -> tuple | None:
    """The knots of a scenario's ``[temperature]`` table (``profile = [[t_s, T_degC], ...]``,
    from t = 0, times increasing), checked; None without the table."""
    if table is None:
        return None
    if not isinstance(table, dict) or set(table) != {"profile"}:
        raise ScenarioError(f"{where}: expected one key, profile = [[time_s, temperature_degC], ...]; got "
                            f"{sorted(table) if isinstance(table, dict) else table!r}")
    knots = table["profile"]
    if not isinstance(knots, list) or len(knots) < 2:
        raise ScenarioError(f"{where}: profile = {knots!r}: expected at least two [time_s, temperature_degC] knots")
    out = []
    for i, k in enumerate(knots):
        if not (isinstance(k, list) and len(k) == 2
                and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in k)):
            raise ScenarioError(f"{where}: profile knot {i + 1} = {k!r}: expected [time_s, temperature_degC]")
        t, T = float(k[0]), float(k[1])
        if not LOWEST <= T <= HIGHEST:
            raise ScenarioError(f"{where}: profile knot {i + 1}: {T:g} degC is outside {LOWEST:g} to {HIGHEST:g} degC "
                                "(temperatures are in degrees Celsius)")
        if i == 0 and t != 0:
            raise ScenarioError(f"{where}: profile knot 1: time {t:g} s: expected the profile to start at 0 s")
        if out and not t > out[-1][0]:
            raise ScenarioError(f"{where}: profile knot {i + 1}: time {t:g} s is not after the knot before it "
                                f"({out[-1][0]:g} s)")
        out.append((t, T))
    return tuple(out)
