"""How the vocabulary reaches an IMU FMU's parameters: the effect map, the noise map and the seed
parameter of a unit description (scenario ``[imu]``, campaign ``[systems.X]``; docs/supplier.md).

Our IMU's parameters are named after the vocabulary and are SI: the identity. A supplier's IMU
has its own names and units: the map says, per vocabulary parameter, the FMU's parameter
(``"gyro.bias.x" = "GyroBias_X"``), optionally with the unit the user expects it in
(``["GyroBias_X", "deg/s"]``). The value is converted with the unit the **FMU declares** (its unit
definition's factor to SI base units, whose exponents must be the vocabulary parameter's); a
unit the user states must agree with it — deg/s written against a parameter declared in deg/h
is an error, not a value 3600 times too small. Where the FMU declares no usable unit the stated
one is used, and where neither exists the map is refused.
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path

from components.errors import ScenarioError
from components.model.effects import effect_of
from components.model.quantities import NOISE_UNITS, effect_units

BUILTIN_SEED = "seed"


@dataclass
class ParameterMap:
    """Vocabulary parameter -> (FMU parameter, SI per FMU unit)."""

    entries: dict = field(default_factory=dict)
    identity: bool = False      # our IMU: the vocabulary names are its parameters, SI

    def fmu_value(self, name: str, si: float) -> tuple[str, float] | None:
        """(FMU parameter, its value) for the vocabulary parameter *name* = *si*, or None when the
        FMU has no parameter for it."""
        if self.identity:
            return name, si
        if name not in self.entries:
            return None
        fmu_name, scale = self.entries[name]
        return fmu_name, si / scale


def _si_exponents(unit: str):
    from orchestrator import si
    from orchestrator.errors import UnitParseError

    try:
        return si.parse(unit)[0]
    except UnitParseError:
        return None


def _readable_units(name: str, kind: str) -> dict:
    """The units a user may state for *name* (SI per unit)."""
    if kind == "noise":
        base = ".".join(name.split(".")[:3])
        return dict(NOISE_UNITS[base][1]) if base in NOISE_UNITS else {}
    return effect_units(name)


def _si_unit(name: str, kind: str) -> str:
    if kind == "noise":
        base = ".".join(name.split(".")[:3])
        return NOISE_UNITS[base][0]
    return effect_of(name).unit


def resolve_map(raw: dict | None, fmu_path: Path, kind: str, where: str) -> ParameterMap:
    """The map *raw* ({vocabulary parameter: FMU parameter | [FMU parameter, unit]}) checked
    against the FMU *fmu_path*'s declared parameters and units; ``kind`` "effect" or "noise"."""
    from orchestrator.fmu_units import read_fmu_variables

    if raw is None:
        return ParameterMap()
    variables = read_fmu_variables(fmu_path)
    params = {n: v for n, v in variables.items() if v.causality == "parameter"}
    out = ParameterMap()
    for name, spec in raw.items():
        w = f"{where}: {name!r}"
        try:
            units = _readable_units(name, kind)
            si_unit = _si_unit(name, kind)
        except KeyError:
            raise ScenarioError(f"{w}: not a parameter of the {'noise model' if kind == 'noise' else 'effect vocabulary'}"
                                ) from None
        if isinstance(spec, str):
            fmu_name, stated = spec, None
        elif isinstance(spec, list) and len(spec) == 2 and all(isinstance(x, str) for x in spec):
            fmu_name, stated = spec
        else:
            raise ScenarioError(f"{w} = {spec!r}: expected the FMU's parameter name, or [name, unit]")
        v = params.get(fmu_name)
        if v is None:
            near = difflib.get_close_matches(fmu_name, list(params), n=3)
            hint = f" (did you mean {', '.join(near)}?)" if near else f" (its parameters: {', '.join(list(params)[:12])})"
            raise ScenarioError(f"{w}: the FMU {fmu_path.name} has no parameter {fmu_name!r}{hint}")
        want = _si_exponents(si_unit)
        have = None if v.base_exponents is None else tuple(v.base_exponents)
        if have is not None and want is not None and si_unit == "1" and "arcsec" in units:
            # a misalignment is a small angle: SI calls it 1, FMI's base units call it rad
            have = tuple(0 if k == len(have) - 1 else e for k, e in enumerate(have))
        declared = None   # SI per unit of the FMU's own unit, when it can be read
        if v.unit and v.base_exponents is not None:
            if want is not None and have != tuple(want):
                raise ScenarioError(f"{w}: the FMU declares {fmu_name} in {v.unit!r}, which is not a unit of {si_unit} "
                                    f"(what {name} is in)")
            if v.unit_offset:
                raise ScenarioError(f"{w}: the FMU declares {fmu_name} in {v.unit!r}, an offset unit: expected a "
                                    "proportional one")
            declared = float(v.unit_factor)
        elif v.unit:
            if v.unit in units:
                declared = units[v.unit]
            else:
                exps = _si_exponents(v.unit)
                if exps is not None and want is not None and tuple(exps) == tuple(want):
                    from orchestrator import si

                    declared = si.parse(v.unit)[1]
        if stated is not None:
            if stated not in units:
                raise ScenarioError(f"{w}: unit {stated!r}: expected one of {', '.join(units)}")
            if declared is not None and abs(units[stated] / declared - 1) > 1e-9:
                raise ScenarioError(f"{w}: the map says {stated!r}, the FMU declares {fmu_name} in {v.unit!r}: the values "
                                    f"would be off by {declared / units[stated]:.6g}; state the FMU's unit or none")
            scale = units[stated]
        elif declared is not None:
            scale = declared
        else:
            raise ScenarioError(f"{w}: the FMU declares {fmu_name} in {v.unit or 'no unit'!r}, which calbench cannot "
                                f"convert from {si_unit}: state its unit, e.g. [{fmu_name!r}, {next(iter(units))!r}]")
        out.entries[name] = (fmu_name, scale)
    return out


def builtin_maps() -> tuple[ParameterMap, ParameterMap, str]:
    """Our IMU: the vocabulary is its parameter list."""
    return ParameterMap(identity=True), ParameterMap(identity=True), BUILTIN_SEED


def check_seed(seed_parameter: str | None, fmu_path: Path, where: str) -> str | None:
    """The FMU's seed parameter, checked; None when the unit description names none."""
    from orchestrator.fmu_units import read_fmu_variables

    if seed_parameter is None:
        return None
    variables = read_fmu_variables(fmu_path)
    v = variables.get(seed_parameter)
    if v is None or v.causality != "parameter":
        raise ScenarioError(f"{where}: seed_parameter = {seed_parameter!r}: the FMU {fmu_path.name} has no such "
                            "parameter")
    if v.type != "Integer":   # (the family: Int32, UInt64, ... too)
        # a Real parameter took the seed: a scale factor of +300 % with seed 3
        raise ScenarioError(f"{where}: seed_parameter = {seed_parameter!r}: the FMU {fmu_path.name}'s {seed_parameter} "
                            f"is a {v.fmi_type or v.type}; the noise seed is an Integer parameter")
    return seed_parameter


@dataclass
class Injection:
    """What a run gives an IMU FMU: its parameters, what of the scenario's effects and noise it
    then has (the truth), what it could not take, and where the seed goes."""

    parameters: dict = field(default_factory=dict)   # FMU parameter -> value in the FMU's unit
    effects: dict = field(default_factory=dict)      # vocabulary -> SI, injected
    noise: dict = field(default_factory=dict)        # noise vocabulary -> SI, injected
    not_injected: dict = field(default_factory=dict)  # {"effects": [...], "noise": [...]} (non-zero asked, no parameter)
    seed_parameter: str | None = None                # None: the FMU takes no seed

    @property
    def noise_free(self) -> bool:
        """No noise reaches the IMU (the scenario asked for none, or the FMU takes none)."""
        return not any(v for v in self.noise.values())


def maps_for(fmu_path: Path, effect_map: dict | None, noise_map: dict | None, seed_parameter: str | None,
             where: str) -> tuple[ParameterMap, ParameterMap, str | None]:
    """The maps of a unit description, resolved against its FMU. Without maps: the identity when
    the FMU's parameters are the vocabulary's (ours), else nothing (a supplier's FMU, none given)."""
    from orchestrator.fmu_units import read_fmu_variables

    names = set(read_fmu_variables(fmu_path))
    ours = "gyro.bias.x" in names and "acc.bias.x" in names
    em = resolve_map(effect_map, fmu_path, "effect", f"{where} effect_map") if effect_map is not None else \
        ParameterMap(identity=ours)
    nm = resolve_map(noise_map, fmu_path, "noise", f"{where} noise_map") if noise_map is not None else \
        ParameterMap(identity=ours and "gyro.noise.arw" in names)
    seed = check_seed(seed_parameter, fmu_path, where) if seed_parameter is not None else \
        (BUILTIN_SEED if BUILTIN_SEED in names else None)
    return em, nm, seed


def plan_injection(effects: dict, noise: dict, em: ParameterMap, nm: ParameterMap, seed: str | None) -> Injection:
    """The FMU parameters for the scenario's *effects* and *noise* (vocabulary, SI) through the
    maps; what has no parameter is not injected (listed when non-zero) and not in the truth."""
    inj = Injection(seed_parameter=seed, not_injected={"effects": [], "noise": []})
    for kind, values, m, truth in (("effects", effects, em, inj.effects), ("noise", noise, nm, inj.noise)):
        for name, si in values.items():
            mapped = m.fmu_value(name, si)
            if mapped is None:
                if si != 0.0:
                    inj.not_injected[kind].append(name)
                continue
            inj.parameters[mapped[0]] = mapped[1]
            truth[name] = si
    return inj


COUNT_UNITS = {"gyro": "arcsec", "acc": "mm/s"}  # a count's weight as a data sheet states it


def unknown_count_weight(kinds: dict, stated: dict, fmu_names: set, fmu: str) -> str | None:
    """Why a unit with count outputs cannot run, or None: a count's weight is stated in the
    unit description (``count_weight``) or is the FMU's own ``<sensor>.count_weight`` (ours);
    without either, a log of counts would calibrate to scale factors off by a guessed weight.
    ``kinds``: sensor -> output kind."""
    for sensor, unit in COUNT_UNITS.items():
        if kinds.get(sensor) == "counts" and sensor not in stated and f"{sensor}.count_weight" not in fmu_names:
            return (f"{sensor}_output = 'counts', but the weight of one count is not known (the FMU {fmu} has no "
                    f"{sensor}.count_weight parameter): state it from the supplier's data sheet, e.g. "
                    f'count_weight = {{{sensor} = "0.05 {unit}"}}')
    return None
