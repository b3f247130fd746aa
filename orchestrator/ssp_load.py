"""Reading an SSP archive into the same :class:`~orchestrator.system.System` a TOML file gives
(the conventions, and calbench's annotation: :mod:`orchestrator.ssp_common`).

What is read from ``SystemStructure.ssd`` (namespaces of SSP 1.0):

* ``ssd:Component`` (type ``application/x-fmu-sharedlibrary``, the default) with
  ``source="resources/x.fmu"``: one unit per component. The archive's ``resources/`` are
  extracted once to ``<cache>/ssp/<sha256 of the archive>/`` (``<cache>`` is ``$CALBENCH_CACHE``
  or ``~/.cache/calbench``), so the FMU paths of the System stay valid after this call.
* ``ssd:Connector`` of each component: when a component declares connectors, connections and
  parameter bindings must name one of them.
* ``ssd:Connection startElement/startConnector/endElement/endConnector``: one scalar connection
  each (connections to the system's own connectors, and ``ssc:LinearTransformation`` or other
  transformations, are refused rather than ignored).
* ``ssd:ParameterBindings``: inline ``ssd:ParameterValues/ssv:ParameterSet`` or
  ``source="resources/x.ssv"``; values ``ssv:Real`` (xs:double), ``ssv:Integer`` (xs:int),
  ``ssv:Boolean``, ``ssv:String``. A binding's ``prefix`` is stripped from the names of the
  set's parameters (parameters without it do not apply to that component).
* ``ssd:DefaultExperiment startTime/stopTime``. A missing ``stopTime`` is an error unless the
  caller passes ``stop=``.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
import zipfile
from pathlib import Path, PurePosixPath
from xml.etree import ElementTree as ET

from orchestrator.errors import SystemError_
from orchestrator.ssp_common import (
    CONNECTION_ANNOTATION,
    FMU_TYPE,
    SSD_NAME,
    SSD_NS,
    SSV_NS,
    SYSTEM_ANNOTATION,
    ssc,
    ssd,
    ssv,
)
from orchestrator.system import ALGORITHMS, Connection, System, UnitSpec
from orchestrator.units import sha256_file

DEFAULT_STEP = 0.005
_DOUBLE = re.compile(r"^\s*([+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?|[+-]?INF|NaN)\s*$")
_INT = re.compile(r"^\s*[+-]?\d+\s*$")


def cache_root() -> Path:
    root = os.environ.get("CALBENCH_CACHE")
    return (Path(root) if root else Path.home() / ".cache" / "calbench") / "ssp"


def load_ssp(path: str | Path, stop: float | None = None) -> System:
    """Read an SSP archive into a :class:`System` (see the module docstring for what is read)."""
    p = Path(path)
    if not p.exists():
        raise SystemError_(f"SSP archive {p} does not exist")
    if not zipfile.is_zipfile(p):
        raise SystemError_(f"{p}: not an SSP archive (not a zip file)")
    with zipfile.ZipFile(p) as z:
        names = set(z.namelist())
        if SSD_NAME not in names:
            raise SystemError_(f"{p}: the archive has no {SSD_NAME} at its root "
                               f"(found: {', '.join(sorted(names)) or 'nothing'})")
        try:
            root = ET.fromstring(z.read(SSD_NAME))
        except ET.ParseError as e:
            raise SystemError_(f"{p}: {SSD_NAME} is not well-formed XML ({e})") from None
        ssv_texts = {n: z.read(n) for n in names if n.lower().endswith(".ssv")}
    where = f"{p}: {SSD_NAME}"
    if root.tag != ssd("SystemStructureDescription"):
        raise SystemError_(f"{where}: root element is {root.tag}; expected ssd:SystemStructureDescription "
                           f"in namespace {SSD_NS}")
    system_el = root.find(ssd("System"))
    if system_el is None:
        raise SystemError_(f"{where}: no ssd:System element")
    sys_name = system_el.get("name") or root.get("name") or p.stem
    ann = _system_annotation(root, where)
    unit_ann = {u.get("name"): u for u in ann.findall("unit")} if ann is not None else {}
    cache = _extract(p, names)

    units: list[UnitSpec] = []
    connectors: dict[str, set[str] | None] = {}
    inverse: dict[str, dict[str, str]] = {}
    elements = system_el.find(ssd("Elements"))
    for el in list(elements) if elements is not None else []:
        if el.tag == ssd("System"):
            raise SystemError_(f"{where}: ssd:System {el.get('name')!r} inside ssd:Elements: nested "
                               "systems are not supported")
        if el.tag == ssd("SignalDictionaryReference"):
            raise SystemError_(f"{where}: ssd:SignalDictionaryReference is not supported")
        if el.tag != ssd("Component"):
            continue
        name = el.get("name")
        if not name:
            raise SystemError_(f"{where}: ssd:Component without a name")
        ewhere = f"{where}: ssd:Component {name!r}"
        ctype = el.get("type", FMU_TYPE)
        if ctype != FMU_TYPE:
            raise SystemError_(f"{ewhere}: type {ctype!r}; only {FMU_TYPE} is supported")
        src = el.get("source")
        if not src:
            raise SystemError_(f"{ewhere}: no source attribute (expected source=\"resources/x.fmu\")")
        member = _member(src, names, ewhere)
        spec = UnitSpec(name=name, fmu=str(cache / member))
        a = unit_ann.pop(name, None)
        if a is not None:
            _apply_unit_annotation(spec, a, f"{where}: calbench annotation unit {name!r}")
        inverse[name] = {v: k for k, v in spec.mapping.items()}
        cons = el.find(ssd("Connectors"))
        connectors[name] = None if cons is None else {c.get("name") for c in cons.findall(ssd("Connector"))}
        for b in el.findall(f"{ssd('ParameterBindings')}/{ssd('ParameterBinding')}"):
            for pname, value in _binding(b, ssv_texts, names, ewhere):
                if connectors[name] is not None and pname not in connectors[name]:
                    raise SystemError_(f"{ewhere}: parameter {pname!r} is not one of its connectors")
                spec.parameters[inverse[name].get(pname, pname)] = value
        units.append(spec)
    if unit_ann:
        raise SystemError_(f"{where}: calbench annotation names unit(s) {sorted(unit_ann)} that are not "
                           "components of the system")
    if not units:
        raise SystemError_(f"{where}: the system has no ssd:Component")

    conns: list[Connection] = []
    cons_el = system_el.find(ssd("Connections"))
    for i, c in enumerate(cons_el.findall(ssd("Connection")) if cons_el is not None else []):
        cwhere = f"{where}: ssd:Connection #{i + 1}"
        ends = []
        for elem_attr, conn_attr in (("startElement", "startConnector"), ("endElement", "endConnector")):
            e, k = c.get(elem_attr), c.get(conn_attr)
            if not k:
                raise SystemError_(f"{cwhere}: missing {conn_attr}")
            if not e:
                raise SystemError_(f"{cwhere} ({conn_attr}={k!r}): no {elem_attr}; connections to the "
                                   "system's own connectors are not supported")
            if e not in connectors:
                raise SystemError_(f"{cwhere}: {elem_attr}={e!r} is not a component of the system "
                                   f"(components: {', '.join(connectors)})")
            if connectors[e] is not None and k not in connectors[e]:
                raise SystemError_(f"{cwhere}: component {e!r} has no connector {k!r}")
            ends.append(f"{e}.{inverse[e].get(k, k)}")
        for child in c:
            if child.tag not in (ssd("Annotations"), ssd("ConnectionGeometry")):
                raise SystemError_(f"{cwhere}: {child.tag.split('}')[-1]} is not supported "
                                   "(no transformations on connections)")
        order = 0
        ca = _find_annotation(c, CONNECTION_ANNOTATION, cwhere)
        if ca is not None:
            order = _int_attr(ca, "derivative_order", cwhere, 0)
        conns.append(Connection(ends[0], ends[1], order))

    de = root.find(ssd("DefaultExperiment"))
    start = _float_attr(de, "startTime", f"{where}: ssd:DefaultExperiment", 0.0) if de is not None else 0.0
    stop_v = _float_attr(de, "stopTime", f"{where}: ssd:DefaultExperiment", None) if de is not None else None
    if stop_v is None:
        if stop is None:
            raise SystemError_(f"{where}: no ssd:DefaultExperiment stopTime; give stop= to load_ssp")
        stop_v = float(stop)
    elif stop is not None:
        stop_v = float(stop)

    system = System(name=sys_name, start=start, stop=stop_v, units=units, connections=conns,
                    source=str(p), base_dir=cache)
    awhere = f"{where}: calbench annotation"
    if ann is not None:
        system.step = _float_attr(ann, "step", awhere, DEFAULT_STEP)
        system.algorithm = ann.get("algorithm", "gauss-seidel")
        if system.algorithm not in ALGORITHMS:
            raise SystemError_(f"{awhere}: algorithm={system.algorithm!r}; expected one of {ALGORITHMS}")
        rec = ann.get("record")
        system.record = rec.split() if rec is not None else _connected_outputs(conns)
        system.record_every = _int_attr(ann, "record_every", awhere, 1)
        order = ann.get("order")
        system.order = order.split() if order else None
        aggregate = {}
        for ag in ann.findall("aggregate"):
            if not ag.get("signal") or not ag.get("how"):
                raise SystemError_(f"{awhere}: <aggregate> needs signal= and how=")
            aggregate[ag.get("signal")] = ag.get("how")
        if aggregate:
            system.record_aggregate = aggregate
    else:
        system.record = _connected_outputs(conns)
    system.validate()
    return system


def _connected_outputs(conns: list[Connection]) -> list[str]:
    out: list[str] = []
    for c in conns:
        if c.derivative_order == 0 and c.source not in out:
            out.append(c.source)
    return out


def _member(src: str, names: set[str], where: str) -> str:
    if "://" in src or src.startswith("/"):
        raise SystemError_(f"{where}: source={src!r}: only files inside the archive are supported")
    member = str(PurePosixPath(src.removeprefix("./")))
    if member not in names:
        raise SystemError_(f"{where}: source={src!r} is not in the archive")
    return member


def _extract(p: Path, names: set[str]) -> Path:
    """Extract the archive's files (but the SSD) to a folder keyed by its SHA-256, once."""
    digest = sha256_file(p)
    dest = cache_root() / digest
    if (dest / ".complete").exists():
        return dest
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{digest[:12]}-", dir=dest.parent))
    try:
        with zipfile.ZipFile(p) as z:
            for n in names:
                target = (tmp / n).resolve()
                if not str(target).startswith(str(tmp.resolve()) + os.sep):
                    raise SystemError_(f"{p}: archive member {n!r} points outside the archive")
            z.extractall(tmp)
        (tmp / ".complete").write_text(str(p))
        try:
            tmp.rename(dest)
        except OSError:  # another process extracted it meanwhile
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return dest


def _find_annotation(el: ET.Element, type_: str, where: str) -> ET.Element | None:
    found = [a for a in el.iter(ssc("Annotation")) if a.get("type") == type_]
    if len(found) > 1:
        raise SystemError_(f"{where}: {len(found)} ssc:Annotation elements of type {type_!r}; expected one")
    if not found:
        return None
    inner = found[0].find("calbench")
    if inner is None:
        raise SystemError_(f"{where}: ssc:Annotation type={type_!r} has no <calbench> element")
    return inner


def _system_annotation(root: ET.Element, where: str) -> ET.Element | None:
    # connection annotations are a different type, so searching the whole tree is safe
    return _find_annotation(root, SYSTEM_ANNOTATION, where)


def _apply_unit_annotation(spec: UnitSpec, a: ET.Element, where: str) -> None:
    spec.role = a.get("role") or None
    spec.step_multiple = _int_attr(a, "step_multiple", where, 1)
    opts = a.get("role_options")
    if opts:
        try:
            spec.role_options = json.loads(opts)
        except json.JSONDecodeError as e:
            raise SystemError_(f"{where}: role_options is not JSON ({e})") from None
        if not isinstance(spec.role_options, dict):
            raise SystemError_(f"{where}: role_options must be a JSON object")
    for m in a.findall("map"):
        r, n = m.get("role"), m.get("name")
        if not r or not n:
            raise SystemError_(f"{where}: <map> needs role= and name=")
        spec.mapping[r] = n


def _float_attr(el: ET.Element, key: str, where: str, default):
    s = el.get(key)
    if s is None:
        return default
    if not _DOUBLE.match(s):
        raise SystemError_(f"{where}: {key}={s!r} is not a number")
    return float(s.replace("INF", "inf"))


def _int_attr(el: ET.Element, key: str, where: str, default: int) -> int:
    s = el.get(key)
    if s is None:
        return default
    if not _INT.match(s):
        raise SystemError_(f"{where}: {key}={s!r} is not an integer")
    return int(s)


def _binding(b: ET.Element, ssv_texts: dict, names: set[str], where: str):
    """(name, value) pairs of one ssd:ParameterBinding."""
    if b.get("type") not in (None, "application/x-ssp-parameter-set"):
        raise SystemError_(f"{where}: ssd:ParameterBinding type={b.get('type')!r} is not supported")
    if b.find(ssd("ParameterMapping")) is not None:
        raise SystemError_(f"{where}: ssd:ParameterMapping is not supported")
    src = b.get("source")
    if src:
        member = _member(src, names, where)
        bwhere = f"{where}: parameter source {member}"
        try:
            pset = ET.fromstring(ssv_texts[member]) if member in ssv_texts else None
        except ET.ParseError as e:
            raise SystemError_(f"{bwhere}: not well-formed XML ({e})") from None
        if pset is None or pset.tag != ssv("ParameterSet"):
            raise SystemError_(f"{bwhere}: expected an ssv:ParameterSet (namespace {SSV_NS})")
    else:
        bwhere = f"{where}: inline ssd:ParameterValues"
        pset = b.find(f"{ssd('ParameterValues')}/{ssv('ParameterSet')}")
        if pset is None:
            raise SystemError_(f"{where}: ssd:ParameterBinding has neither source= nor "
                               "ssd:ParameterValues/ssv:ParameterSet")
    prefix = b.get("prefix", "")
    for par in pset.findall(f"{ssv('Parameters')}/{ssv('Parameter')}"):
        pname = par.get("name")
        if not pname:
            raise SystemError_(f"{bwhere}: ssv:Parameter without a name")
        if prefix:
            if not pname.startswith(prefix):
                continue
            pname = pname[len(prefix):]
        yield pname, _parameter_value(par, f"{bwhere}: ssv:Parameter {par.get('name')!r}")


def _parameter_value(par: ET.Element, where: str):
    kids = [k for k in par if k.tag != ssv("Annotations") and k.tag != ssc("Annotations")]
    if len(kids) != 1:
        raise SystemError_(f"{where}: expected exactly one value element (ssv:Real, ssv:Integer, "
                           "ssv:Boolean or ssv:String)")
    k = kids[0]
    kind = k.tag.split("}")[-1]
    s = k.get("value")
    if s is None:
        raise SystemError_(f"{where}: ssv:{kind} has no value attribute")
    if k.tag == ssv("Real"):
        if not _DOUBLE.match(s):
            raise SystemError_(f"{where}: ssv:Real value={s!r} is not a number (xs:double)")
        return float(s.strip().replace("INF", "inf"))
    if k.tag == ssv("Integer"):
        if not _INT.match(s):
            raise SystemError_(f"{where}: ssv:Integer value={s!r} is not an integer (xs:int)")
        return int(s)
    if k.tag == ssv("Boolean"):
        t = s.strip()
        if t not in ("true", "false", "1", "0"):
            raise SystemError_(f"{where}: ssv:Boolean value={s!r}; expected true, false, 1 or 0")
        return t in ("true", "1")
    if k.tag == ssv("String"):
        return s
    raise SystemError_(f"{where}: value element {k.tag!r} is not supported (expected ssv:Real, "
                       "ssv:Integer, ssv:Boolean or ssv:String)")
