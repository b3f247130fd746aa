"""Declarative variable tables for the plant FMUs, and the generators that turn one table into
``modelDescription.xml`` (FMI 2.0 and FMI 3.0) and the C header with value references.

One table per FMU is the single source of truth: the XML and the C definitions are generated
from it on every build, so they cannot drift apart.

Value references: Real variables are numbered 0..N_REAL-1 in table order, Integer variables
continue from N_REAL. They are unique across types, as FMI 3.0 requires.
"""
from __future__ import annotations

import hashlib
import math
import re
import uuid
from dataclasses import dataclass, field
from xml.sax.saxutils import quoteattr

CAUSALITIES = ("parameter", "input", "output", "local")
VARIABILITIES = ("fixed", "tunable", "discrete", "continuous")

# SI base-unit exponents for the unit definitions the FMUs declare: (kg, m, s, A, K, mol, cd, rad)
_BASE_UNITS = {
    "1": {},
    "s": {"s": 1},
    "m": {"m": 1},
    "rad": {"rad": 1},
    "rad/s": {"rad": 1, "s": -1},
    "rad/s2": {"rad": 1, "s": -2},
    "m/s": {"m": 1, "s": -1},
    "m/s2": {"m": 1, "s": -2},
    "kg.m2": {"kg": 1, "m": 2},
    "N.m": {"kg": 1, "m": 2, "s": -2},
    "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
    "N.m.s2/rad": {"kg": 1, "m": 2, "rad": -1},
    "N.m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1},
    "Hz": {"s": -1},
    "degC": {"K": 1},
    "1/K": {"K": -1},
    "1/s": {"s": -1},
    "K/s": {"K": 1, "s": -1},
    "s/rad": {"s": 1, "rad": -1},
    "s2/m": {"s": 2, "m": -1},
    "s4/m2": {"s": 4, "m": -2},
    "rad/m": {"rad": 1, "m": -1},
    "rad.s/m": {"rad": 1, "s": 1, "m": -1},
    "rad.s3/m2": {"rad": 1, "s": 3, "m": -2},
    "rad/s/K": {"rad": 1, "s": -1, "K": -1},
    "m/s2/K": {"m": 1, "s": -2, "K": -1},
    "rad/s/s": {"rad": 1, "s": -2},
    "m/s2/s": {"m": 1, "s": -3},
    "rad/s/sqrt(s)": {"rad": 1, "s": -1},  # density: exponent of sqrt(s) not expressible; informative
    "m/s2/sqrt(s)": {"m": 1, "s": -2},
    "rad/sqrt(s)": {"rad": 1},
    "m/s/sqrt(s)": {"m": 1, "s": -1},
    "rad/s/s/sqrt(s)": {"rad": 1, "s": -2},
    "m/s2/s/sqrt(s)": {"m": 1, "s": -3},
    # non-SI units a supplier's FMU may declare (SI value = factor * value + offset)
    "deg": {"rad": 1},
    "deg/s": {"rad": 1, "s": -1},
    "deg/s2": {"rad": 1, "s": -2},
    "g": {"m": 1, "s": -2},
    "deg/h": {"rad": 1, "s": -1},
    "mg": {"m": 1, "s": -2},
    "urad": {"rad": 1},
    "arcsec": {"rad": 1},
    "mm/s": {"m": 1, "s": -1},
    "deg/sqrt(h)": {"rad": 1},   # density: the sqrt is not expressible; the factor is deg/sqrt(h) in rad/sqrt(s)
}
_BASE_UNIT_OFFSET = {"degC": 273.15}
_BASE_UNIT_FACTOR = {"deg": 0.017453292519943295, "deg/s": 0.017453292519943295,
                     "deg/s2": 0.017453292519943295, "g": 9.80665, "deg/h": 0.017453292519943295 / 3600,
                     "mg": 9.80665e-3, "urad": 1e-6, "arcsec": 0.017453292519943295 / 3600, "mm/s": 1e-3, "deg/sqrt(h)": 0.017453292519943295 / 60}


@dataclass(frozen=True)
class Variable:
    name: str
    type: str  # "Real" or "Integer"
    causality: str
    variability: str
    start: float | int | None
    unit: str | None = None
    description: str = ""
    min: float | None = None
    max: float | None = None
    # FMI 2 co-simulation: may the master pass time derivatives of this input?
    derivative_of: str | None = None
    # outputs: names of the inputs this output depends on directly (feed-through within a step);
    # None or empty: no direct dependency (dependencies="" in the ModelStructure)
    depends_on: tuple | list | None = None

    def __post_init__(self) -> None:
        if self.causality not in CAUSALITIES:
            raise ValueError(f"{self.name}: causality {self.causality!r} not in {CAUSALITIES}")
        if self.variability not in VARIABILITIES:
            raise ValueError(f"{self.name}: variability {self.variability!r}")
        if self.unit is not None and self.unit not in _BASE_UNITS:
            raise ValueError(f"{self.name}: unit {self.unit!r} has no definition in modeldef")
        if self.causality in ("parameter", "input") and self.start is None:
            raise ValueError(f"{self.name}: {self.causality} needs a start value")
        if self.causality == "output" and self.start is not None and self.variability == "continuous":
            # FMI 2: outputs with initial="calculated" must not declare start; keep it simple.
            object.__setattr__(self, "start", None)
        if self.depends_on and self.causality != "output":
            raise ValueError(f"{self.name}: depends_on is for outputs only")

    @property
    def c_name(self) -> str:
        return "VR_" + re.sub(r"[^A-Za-z0-9]", "_", self.name)


def real(name, causality, start=None, unit=None, description="", variability=None, **kw) -> Variable:
    if variability is None:
        variability = {"parameter": "fixed", "input": "continuous", "output": "continuous",
                       "local": "continuous"}[causality]
    return Variable(name, "Real", causality, variability, start, unit, description, **kw)


def integer(name, causality, start=None, description="", variability=None, **kw) -> Variable:
    if variability is None:
        variability = {"parameter": "fixed", "input": "discrete", "output": "discrete",
                       "local": "discrete"}[causality]
    return Variable(name, "Integer", causality, variability, start, None, description, **kw)


@dataclass
class ModelTable:
    """Everything the generators need to know about one FMU."""

    identifier: str
    description: str
    variables: list[Variable]
    sources: list[str]  # C files of the model, relative to the model's folder
    default_step: float = 0.005
    can_interpolate_inputs: bool = True
    max_output_derivative_order: int = 0
    version: str = "1.0"
    _by_name: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        names = [v.name for v in self.variables]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"{self.identifier}: duplicate variable names {sorted(dup)}")
        self._by_name = {v.name: v for v in self.variables}
        for v in self.variables:
            for d in v.depends_on or ():
                if d not in self._by_name or self._by_name[d].causality != "input":
                    raise ValueError(f"{self.identifier}: {v.name} depends_on {d!r}, which is not an input")

    @property
    def reals(self) -> list[Variable]:
        return [v for v in self.variables if v.type == "Real"]

    @property
    def integers(self) -> list[Variable]:
        return [v for v in self.variables if v.type == "Integer"]

    def value_reference(self, name: str) -> int:
        v = self._by_name[name]
        if v.type == "Real":
            return self.reals.index(v)
        return len(self.reals) + self.integers.index(v)

    def ordered(self) -> list[tuple[int, Variable]]:
        """(value reference, variable) in value-reference order."""
        return list(enumerate(self.reals)) + [
            (len(self.reals) + j, v) for j, v in enumerate(self.integers)
        ]

    def token(self, source_key: str) -> str:
        """Instantiation token / GUID, derived from the sources so that a rebuilt FMU is new."""
        return "{" + str(uuid.UUID(hashlib.sha256(source_key.encode()).hexdigest()[:32])) + "}"


# ---------------------------------------------------------------------------- C header

def _c_double(x: float) -> str:
    if math.isnan(x) or math.isinf(x):
        raise ValueError("start values must be finite")
    return repr(float(x))


def c_header(table: ModelTable, token: str) -> str:
    lines = [
        "/* Generated from the variable table by fmus/modeldef.py. Do not edit. */",
        "#ifndef CALBENCH_CONFIG_H",
        "#define CALBENCH_CONFIG_H",
        f"#define MODEL_IDENTIFIER {table.identifier}",
        f'#define MODEL_IDENTIFIER_STRING "{table.identifier}"',
        f'#define INSTANTIATION_TOKEN "{token}"',
        f"#define N_REAL {len(table.reals)}",
        f"#define N_INTEGER {max(len(table.integers), 1)}",
        f"#define N_INTEGER_USED {len(table.integers)}",
        f"#define INTEGER_VR_BASE {len(table.reals)}",
        "#define TIME_VR 999999",
        "",
    ]
    for vr, v in table.ordered():
        lines.append(f"#define {v.c_name} {vr}  /* {v.name} [{v.unit or '-'}] {v.causality} */")
    lines.append("")
    cz = {"parameter": 0, "input": 1, "output": 2, "local": 3}
    vz = {"fixed": 0, "tunable": 1, "discrete": 2, "continuous": 3}
    rs = [v.start if v.start is not None else 0.0 for v in table.reals]
    lines.append("static const double REAL_START[N_REAL] = {" + ", ".join(_c_double(x) for x in rs) + "};")
    ints = [int(v.start or 0) for v in table.integers] or [0]
    lines.append("static const int INTEGER_START[N_INTEGER] = {" + ", ".join(map(str, ints)) + "};")
    for kind, vs in (("REAL", table.reals), ("INTEGER", table.integers)):
        n = "N_REAL" if kind == "REAL" else "N_INTEGER"
        caus = [cz[v.causality] for v in vs] or [3]
        var = [vz[v.variability] for v in vs] or [0]
        names = [f'"{v.name}"' for v in vs] or ['""']
        lines.append(f"static const unsigned char {kind}_CAUSALITY[{n}] = {{{', '.join(map(str, caus))}}};")
        lines.append(f"static const unsigned char {kind}_VARIABILITY[{n}] = {{{', '.join(map(str, var))}}};")
        lines.append(f"static const char *const {kind}_NAME[{n}] = {{{', '.join(names)}}};")
    lines += [
        "enum { CAUS_PARAMETER = 0, CAUS_INPUT = 1, CAUS_OUTPUT = 2, CAUS_LOCAL = 3 };",
        "enum { VAR_FIXED = 0, VAR_TUNABLE = 1, VAR_DISCRETE = 2, VAR_CONTINUOUS = 3 };",
        "#endif",
        "",
    ]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- XML

def _units_used(table: ModelTable) -> list[str]:
    return sorted({v.unit for v in table.variables if v.unit})


def _base_unit_xml(unit: str) -> str:
    exps = _BASE_UNITS[unit]
    attrs = "".join(f' {k}="{e}"' for k, e in exps.items())
    if unit in _BASE_UNIT_FACTOR:
        attrs += f' factor="{_fmt(_BASE_UNIT_FACTOR[unit])}"'
    if unit in _BASE_UNIT_OFFSET:
        attrs += f' offset="{_BASE_UNIT_OFFSET[unit]}"'
    return f"<BaseUnit{attrs}/>"


def _fmt(x) -> str:
    if isinstance(x, int) and not isinstance(x, bool):
        return str(x)
    return repr(float(x))


def model_description_fmi2(table: ModelTable, token: str, source_files: list[str]) -> str:
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<fmiModelDescription fmiVersion="2.0"',
        f'  modelName={quoteattr(table.identifier)}',
        f'  guid="{token}"',
        f'  description={quoteattr(table.description)}',
        f'  version="{table.version}"',
        '  generationTool="calbench fmus/modeldef.py"',
        '  variableNamingConvention="structured"',
        '  numberOfEventIndicators="0">',
        f'  <CoSimulation modelIdentifier="{table.identifier}"',
        '    canHandleVariableCommunicationStepSize="true"',
        f'    canInterpolateInputs="{str(table.can_interpolate_inputs).lower()}"',
        f'    maxOutputDerivativeOrder="{table.max_output_derivative_order}"',
        '    canGetAndSetFMUstate="true" canSerializeFMUstate="true"',
        '    canNotUseMemoryManagementFunctions="true">',
        "    <SourceFiles>",
    ]
    out += [f'      <File name="{s}"/>' for s in source_files]
    out += ["    </SourceFiles>", "  </CoSimulation>", "  <UnitDefinitions>"]
    for u in _units_used(table):
        out.append(f'    <Unit name="{u}">{_base_unit_xml(u)}</Unit>')
    out += ["  </UnitDefinitions>",
            f'  <DefaultExperiment startTime="0" stopTime="1" stepSize="{_fmt(table.default_step)}"/>',
            "  <ModelVariables>"]
    outputs: list[int] = []
    index = {v.name: idx for idx, (_, v) in enumerate(table.ordered(), start=1)}
    deps: dict[int, str] = {}
    for idx, (vr, v) in enumerate(table.ordered(), start=1):
        initial = ""
        if v.causality == "output":
            initial = ' initial="exact"' if v.start is not None else ""
            outputs.append(idx)
            deps[idx] = " ".join(str(index[d]) for d in v.depends_on or ())
        attrs = (f'    <ScalarVariable name={quoteattr(v.name)} valueReference="{vr}" '
                 f'causality="{v.causality}" variability="{v.variability}"{initial} '
                 f'description={quoteattr(v.description)}>')
        type_attrs = ""
        if v.unit:
            type_attrs += f' unit="{v.unit}"'
        if v.min is not None:
            type_attrs += f' min="{_fmt(v.min)}"'
        if v.max is not None:
            type_attrs += f' max="{_fmt(v.max)}"'
        if v.start is not None:
            type_attrs += f' start="{_fmt(v.start)}"'
        out += [attrs, f"      <{v.type}{type_attrs}/>", "    </ScalarVariable>"]
    out += ["  </ModelVariables>", "  <ModelStructure>", "    <Outputs>"]
    # Outputs of a co-simulation slave after doStep depend on the inputs only through the step,
    # never instantaneously, unless the table declares a direct feed-through (depends_on).
    out += [f'      <Unknown index="{i}" dependencies="{deps[i]}"/>' for i in outputs]
    out += ["    </Outputs>", "    <InitialUnknowns>"]
    out += [f'      <Unknown index="{i}" dependencies=""/>' for i in outputs]
    out += ["    </InitialUnknowns>", "  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(out)


def model_description_fmi3(table: ModelTable, token: str) -> str:
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<fmiModelDescription fmiVersion="3.0"',
        f'  modelName={quoteattr(table.identifier)}',
        f'  instantiationToken="{token}"',
        f'  description={quoteattr(table.description)}',
        f'  version="{table.version}"',
        '  generationTool="calbench fmus/modeldef.py"',
        '  variableNamingConvention="structured">',
        f'  <CoSimulation modelIdentifier="{table.identifier}"',
        '    canHandleVariableCommunicationStepSize="true"',
        '    canGetAndSetFMUState="true" canSerializeFMUState="true"',
        f'    maxOutputDerivativeOrder="{table.max_output_derivative_order}"/>',
        "  <UnitDefinitions>",
    ]
    for u in _units_used(table):
        out.append(f'    <Unit name="{u}">{_base_unit_xml(u)}</Unit>')
    out += ["  </UnitDefinitions>",
            f'  <DefaultExperiment startTime="0" stopTime="1" stepSize="{_fmt(table.default_step)}"/>',
            "  <ModelVariables>"]
    out.append('    <Float64 name="time" valueReference="999999" causality="independent" '
               'variability="continuous" description="Simulation time"/>')
    outputs: list[int] = []
    deps3: dict[int, str] = {}
    for vr, v in table.ordered():
        tag = "Float64" if v.type == "Real" else "Int32"
        attrs = (f'    <{tag} name={quoteattr(v.name)} valueReference="{vr}" '
                 f'causality="{v.causality}" variability="{v.variability}" '
                 f'description={quoteattr(v.description)}')
        if v.causality == "output":
            outputs.append(vr)
            deps3[vr] = " ".join(str(table.value_reference(d)) for d in v.depends_on or ())
            if v.start is not None:
                attrs += ' initial="exact"'
        if v.unit:
            attrs += f' unit="{v.unit}"'
        if v.min is not None:
            attrs += f' min="{_fmt(v.min)}"'
        if v.max is not None:
            attrs += f' max="{_fmt(v.max)}"'
        if v.start is not None:
            attrs += f' start="{_fmt(v.start)}"'
        out.append(attrs + "/>")
    out += ["  </ModelVariables>", "  <ModelStructure>"]
    out += [f'    <Output valueReference="{vr}" dependencies="{deps3[vr]}"/>' for vr in outputs]
    out += [f'    <InitialUnknown valueReference="{vr}" dependencies=""/>' for vr in outputs]
    out += ["  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(out)
