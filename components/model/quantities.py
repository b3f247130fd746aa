"""Quantities with units as users write them in files (``"40 ug/g2"``, ``"0.002 deg/sqrt(h)"``,
or a bare number in SI), converted to SI at the boundary.

Each effect of the vocabulary has one SI unit (``components.model.effects``); the readable units
of that dimension are listed here once, for scenario, campaign and any other file that names a
value of an effect or of the noise model.
"""
from __future__ import annotations

from components.errors import CalbenchError
from components.model.effects import ARCSEC, DEG, DEG_H, EFFECTS, G0, UG, effect_of

# SI unit -> readable units of that dimension (SI per unit)
UNITS = {
    "rad": {"rad": 1.0, "deg": DEG, "arcmin": 60 * ARCSEC, "arcsec": ARCSEC, "urad": 1e-6, "mrad": 1e-3},
    "rad/s": {"rad/s": 1.0, "deg/h": DEG_H, "deg/s": DEG},
    "m/s2": {"m/s2": 1.0, "ug": UG, "mg": 1e-3 * G0, "g": G0},
    "1": {"1": 1.0, "ppm": 1e-6},
    "m": {"m": 1.0, "mm": 1e-3, "cm": 1e-2},
    "s": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0},
}
# noise parameter -> (SI unit, readable units)
NOISE_UNITS = {
    "gyro.noise.arw": ("rad/sqrt(s)", {"deg/sqrt(h)": DEG / 60.0, "rad/sqrt(s)": 1.0}),
    "gyro.noise.bi": ("rad/s", UNITS["rad/s"]),
    "gyro.noise.bi_tau": ("s", UNITS["s"]),
    "gyro.noise.bi_tau_max": ("s", UNITS["s"]),
    "gyro.noise.rrw": ("rad/s/sqrt(s)", {"rad/s/sqrt(s)": 1.0, "deg/h/sqrt(h)": DEG_H / 60.0}),
    "acc.noise.vrw": ("m/s/sqrt(s)", {"m/s/sqrt(s)": 1.0, "ug/sqrt(Hz)": UG, "m/s/sqrt(h)": 1 / 60.0}),
    "acc.noise.bi": ("m/s2", UNITS["m/s2"]),
    "acc.noise.bi_tau": ("s", UNITS["s"]),
    "acc.noise.bi_tau_max": ("s", UNITS["s"]),
    "acc.noise.rrw": ("m/s2/sqrt(s)", {"m/s2/sqrt(s)": 1.0, "ug/sqrt(s)": UG, "ug/sqrt(h)": UG / 60.0}),
}
# the terms of a noise model given by hand (calbench --noise): the FMU's densities without their
# correlation times, plus the quantization of a pulse output
NOISE_TERM_UNITS = {k: v for k, v in NOISE_UNITS.items() if not k.endswith("_tau")}
NOISE_TERM_UNITS.update({"gyro.noise.bi_tau_min": ("s", UNITS["s"]), "acc.noise.bi_tau_min": ("s", UNITS["s"]),
                         "gyro.noise.q": ("rad", UNITS["rad"]),
                         "acc.noise.q": ("m/s", {"m/s": 1.0, "mm/s": 1e-3, "um/s": 1e-6})})


class QuantityError(CalbenchError, ValueError):
    """A value is neither a number nor '<number> <unit>' with a unit of its dimension."""


def quantity(v, key: str, where: str, units: dict, si: str) -> float:
    """SI value of *v*: a number (already SI) or ``"<number> <unit>"`` with *unit* in *units*."""
    if isinstance(v, bool):
        raise QuantityError(f"{where}: {key} = {v!r}: expected a number [{si}] or '<number> <unit>'")
    if isinstance(v, (int, float)):
        return float(v)
    if isinstance(v, str):
        parts = v.split(None, 1)
        try:
            x = float(parts[0])
        except (ValueError, IndexError):
            x = None
        if x is not None and len(parts) == 2 and parts[1].strip() in units:
            return x * units[parts[1].strip()]
    raise QuantityError(f"{where}: {key} = {v!r}: expected a number [{si}] or '<number> <unit>' with unit one of "
                        f"{', '.join(units)}")


def effect_units(name: str) -> dict:
    """Readable units of the effect parameter *name* (SI per unit); KeyError if not one."""
    e = effect_of(name)
    units = dict(UNITS.get(e.unit, {e.unit: 1.0}))
    if e.display[0]:
        units[e.display[0]] = e.display[1]
    return units


def effect_value(name: str, v, where: str) -> float:
    """SI value of the effect parameter *name* (``acc.k2.z``) written as *v*."""
    try:
        units = effect_units(name)
    except KeyError:
        raise QuantityError(f"{where}: {name!r} is not a parameter of the effect vocabulary "
                            f"(components.model.effects; effects: {', '.join(EFFECTS)})") from None
    return quantity(v, name, where, units, effect_of(name).unit)


def refuse_bare_number(name: str, v, where: str) -> None:
    """A value a person wrote in a file without its unit, for an effect parameter: taken as SI it
    is refused when the effect's unit is not 1 (``"acc.bias.x" = 60`` would be 60 m/s²: ask for
    "60 ug") or when it is beyond what any real IMU has (``"acc.sf.z" = 35`` would be 3500 %:
    ask for "35 ppm"). Programs that build scenarios in SI do not come through here."""
    from components.model.plausibility import plausible_limit

    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return
    try:
        e = effect_of(name)
    except KeyError:
        return  # effect_value names the unknown parameter
    units = ", ".join(f'"{v:g} {u}"' for u in [u for u in effect_units(name) if u != "1"][:3])
    if e.unit != "1":
        raise QuantityError(f"{where}: {name} = {v!r}: a bare number for an effect in {e.unit}; write it with its "
                            f"unit, e.g. {units}")
    limit = plausible_limit(name)
    if abs(v) > limit:
        raise QuantityError(f"{where}: {name} = {v!r} is {abs(v) * 100:g} % as a bare number (SI ratio), beyond any "
                            f"real IMU's {limit * 100:g} %; write it with its unit, e.g. {units}")


def noise_value(name: str, v, where: str) -> float:
    """SI value of the noise parameter *name* (``gyro.noise.arw``) written as *v*."""
    if name not in NOISE_UNITS:
        raise QuantityError(f"{where}: {name!r}: expected one of {', '.join(NOISE_UNITS)}")
    si, units = NOISE_UNITS[name]
    return quantity(v, name, where, units, si)
