"""Writing a :class:`~orchestrator.system.System` whose units are FMUs as an SSP archive that
:func:`~orchestrator.ssp_load.load_ssp` reads back as the same system (the conventions, and
calbench's annotation: :mod:`orchestrator.ssp_common`).
"""
from __future__ import annotations

import json
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from orchestrator.errors import SystemError_
from orchestrator.fmu_resolver import resolve_fmu
from orchestrator.ssp_common import (
    CONNECTION_ANNOTATION,
    FMU_TYPE,
    SSC_NS,
    SSD_NAME,
    SSD_NS,
    SSV_NS,
    SYSTEM_ANNOTATION,
    ssc,
    ssd,
    ssv,
)
from orchestrator.system import System, UnitSpec

_VECTOR_SUFFIXES = (("x", "y", "z"), ("w", "x", "y", "z"))


def _fmu_variables(system: System, spec: UnitSpec) -> tuple[Path, dict]:
    from fmpy import read_model_description

    path = resolve_fmu(spec.fmu, system.base_dir)
    if not Path(path).exists():
        raise SystemError_(f"units.{spec.name}.fmu = {spec.fmu!r}: {path} does not exist")
    md = read_model_description(str(path))
    return Path(path), {v.name: v for v in md.modelVariables}


def _scalar_names(spec: UnitSpec, variables: dict, name: str, where: str) -> list[str]:
    """The FMU's own names for *name* (a role or FMU name, or a vector prefix of either)."""
    def own(n: str) -> str | None:
        m = spec.mapping.get(n, n)
        return m if m in variables else None

    o = own(name)
    if o is not None:
        return [o]
    for suffixes in _VECTOR_SUFFIXES:
        parts = [own(f"{name}.{s}") for s in suffixes]
        if all(parts):
            return parts  # type: ignore[return-value]
    raise SystemError_(f"{where}: unit {spec.name} has no variable {name!r}")


def _fmt(x: float) -> str:
    r = repr(float(x))
    return {"inf": "INF", "-inf": "-INF", "nan": "NaN"}.get(r, r)


def save_ssp(system: System, path: str | Path) -> Path:
    """Write *system* as an SSP archive: the FMUs copied into ``resources/<unit>.fmu``, vector
    connections expanded to scalars, parameters typed by the FMU's variables, the calbench
    annotation carrying step, algorithm, recording, order, roles and mappings."""
    system.validate()
    where = system.source or "system"
    ET.register_namespace("ssd", SSD_NS)
    ET.register_namespace("ssv", SSV_NS)
    ET.register_namespace("ssc", SSC_NS)
    root = ET.Element(ssd("SystemStructureDescription"), {"version": "1.0", "name": system.name})
    sys_el = ET.SubElement(root, ssd("System"), {"name": system.name})
    elements = ET.SubElement(sys_el, ssd("Elements"))
    files: dict[str, Path] = {}
    variables: dict[str, dict] = {}
    for spec in system.units:
        if spec.fmu is None:
            raise SystemError_(f"{where}: units.{spec.name} is a Python component; an SSP archive "
                               "holds FMUs only")
        fpath, variables[spec.name] = _fmu_variables(system, spec)
        files[f"resources/{spec.name}.fmu"] = fpath

    # scalar connections in the FMUs' own names
    scalar: list[tuple[str, str, str, str, int]] = []
    used: dict[str, list[str]] = {u.name: [] for u in system.units}
    for i, c in enumerate(system.connections):
        cw = f"{where}: connections[{i}] ({c.source} -> {c.target})"
        su, sn = c.source.split(".", 1)
        tu, tn = c.target.split(".", 1)
        src = _scalar_names(system.unit(su), variables[su], sn, cw)
        dst = _scalar_names(system.unit(tu), variables[tu], tn, cw)
        if len(src) != len(dst):
            raise SystemError_(f"{cw}: {len(src)} source value(s) but {len(dst)} target value(s)")
        for s, d in zip(src, dst):
            scalar.append((su, s, tu, d, c.derivative_order))
            for u, n in ((su, s), (tu, d)):
                if n not in used[u]:
                    used[u].append(n)

    for spec in system.units:
        comp = ET.SubElement(elements, ssd("Component"), {
            "name": spec.name, "type": FMU_TYPE, "source": f"resources/{spec.name}.fmu"})
        vars_ = variables[spec.name]
        params = []
        for pname, value in spec.parameters.items():
            (own,) = _scalar_names(spec, vars_, pname, f"{where}: units.{spec.name}.parameters")
            params.append((own, value))
        cons = ET.SubElement(comp, ssd("Connectors"))
        for n in used[spec.name] + [p for p, _ in params if p not in used[spec.name]]:
            v = vars_[n]
            kind = v.causality if v.causality in ("input", "output", "parameter", "calculatedParameter") \
                else "parameter"
            con = ET.SubElement(cons, ssd("Connector"), {"name": n, "kind": kind})
            ET.SubElement(con, ssc(_ssc_type(v.type)))
        if params:
            pb = ET.SubElement(ET.SubElement(comp, ssd("ParameterBindings")), ssd("ParameterBinding"))
            pset = ET.SubElement(ET.SubElement(pb, ssd("ParameterValues")), ssv("ParameterSet"),
                                 {"version": "1.0", "name": f"{spec.name}.parameters"})
            plist = ET.SubElement(pset, ssv("Parameters"))
            for own, value in params:
                par = ET.SubElement(plist, ssv("Parameter"), {"name": own})
                ET.SubElement(par, ssv(_ssc_type(vars_[own].type)), {"value": _ssv_value(value, vars_[own].type)})

    conns_el = ET.SubElement(sys_el, ssd("Connections"))
    for su, s, tu, d, order in scalar:
        c = ET.SubElement(conns_el, ssd("Connection"), {"startElement": su, "startConnector": s,
                                                        "endElement": tu, "endConnector": d})
        if order:
            a = ET.SubElement(ET.SubElement(c, ssd("Annotations")), ssc("Annotation"),
                              {"type": CONNECTION_ANNOTATION})
            ET.SubElement(a, "calbench", {"derivative_order": str(order)})

    de = ET.SubElement(root, ssd("DefaultExperiment"), {"startTime": _fmt(system.start),
                                                        "stopTime": _fmt(system.stop)})
    ann = ET.SubElement(ET.SubElement(de, ssd("Annotations")), ssc("Annotation"), {"type": SYSTEM_ANNOTATION})
    attrs = {"step": _fmt(system.step), "algorithm": system.algorithm, "record": " ".join(system.record),
             "record_every": str(system.record_every)}
    if system.order:
        attrs["order"] = " ".join(system.order)
    cb = ET.SubElement(ann, "calbench", attrs)
    for sig, how in (getattr(system, "record_aggregate", None) or {}).items():
        ET.SubElement(cb, "aggregate", {"signal": sig, "how": how})
    for spec in system.units:
        ua = {"name": spec.name, "step_multiple": str(spec.step_multiple)}
        if spec.role:
            ua["role"] = spec.role
        if spec.role_options:
            ua["role_options"] = json.dumps(spec.role_options)
        u = ET.SubElement(cb, "unit", ua)
        for r, n in spec.mapping.items():
            ET.SubElement(u, "map", {"role": r, "name": n})

    ET.indent(root)
    xml = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr(SSD_NAME, xml)
        for arc, f in files.items():
            z.write(f, arc)
    tmp.replace(out)
    return out


def _ssc_type(fmi_type: str) -> str:
    return {"Real": "Real", "Float64": "Real", "Float32": "Real", "Integer": "Integer", "Int32": "Integer",
            "Boolean": "Boolean", "String": "String", "Enumeration": "Integer"}.get(fmi_type, "Real")


def _ssv_value(value, fmi_type: str) -> str:
    t = _ssc_type(fmi_type)
    if t == "Real":
        return _fmt(value)
    if t == "Integer":
        if isinstance(value, float) and not value.is_integer():
            raise SystemError_(f"parameter value {value!r} for an Integer variable is not whole")
        return str(int(value))
    if t == "Boolean":
        return "true" if value else "false"
    return str(value)
