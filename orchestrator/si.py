"""SI unit strings as exponent vectors, and conversion of an FMU's declared unit to SI.

Unit strings follow the FMI convention used in modelDescription files: symbols joined by ``.``
(product) and ``/`` (quotient), a trailing integer is an exponent: ``rad/s2``, ``N.m``,
``m/s/sqrt(s)`` is not parsed (noise densities are not exchanged between units).
"""
from __future__ import annotations

import re

from orchestrator.errors import UnitParseError

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_SYMBOLS: dict[str, tuple[dict, float, float]] = {
    # symbol: (exponents, factor to SI, offset to SI)
    "1": ({}, 1.0, 0.0),
    "kg": ({"kg": 1}, 1.0, 0.0),
    "m": ({"m": 1}, 1.0, 0.0),
    "s": ({"s": 1}, 1.0, 0.0),
    "A": ({"A": 1}, 1.0, 0.0),
    "K": ({"K": 1}, 1.0, 0.0),
    "mol": ({"mol": 1}, 1.0, 0.0),
    "cd": ({"cd": 1}, 1.0, 0.0),
    "rad": ({"rad": 1}, 1.0, 0.0),
    "degC": ({"K": 1}, 1.0, 273.15),
    "N": ({"kg": 1, "m": 1, "s": -2}, 1.0, 0.0),
    "Hz": ({"s": -1}, 1.0, 0.0),
}


def parse(unit: str) -> tuple[tuple[int, ...], float, float]:
    """(exponents over BASE, factor, offset) with SI value = factor * value + offset."""
    if unit is None or unit == "":
        return (0,) * len(BASE), 1.0, 0.0
    exps = dict.fromkeys(BASE, 0)
    factor, offset = 1.0, 0.0
    parts = re.split(r"([./])", unit)
    sign = 1
    for tok in parts:
        if tok == ".":
            continue
        if tok == "/":
            sign = -1
            continue
        m = re.fullmatch(r"([A-Za-z]+|1)(-?\d+)?", tok)
        if not m or m.group(1) not in _SYMBOLS:
            raise UnitParseError(f"unit {unit!r}: cannot read {tok!r}")
        sym, p = m.group(1), int(m.group(2) or 1)
        e, f, off = _SYMBOLS[sym]
        if off and (len(parts) > 1 or p != 1):
            raise UnitParseError(f"unit {unit!r}: an offset unit cannot be combined")
        offset = off
        for k, v in e.items():
            exps[k] += sign * p * v
        factor *= f ** (sign * p)
    return tuple(exps[k] for k in BASE), factor, offset
