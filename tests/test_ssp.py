"""SSP archives: a TOML system and the SSP written from it are the same system and give the
same recording bit for bit; malformed archives are refused with the specific error."""
from __future__ import annotations

import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

import components  # noqa: F401  (registers builtin: and the roles)
from fmus.build import fmu_path
from orchestrator.errors import SystemError_
from orchestrator.loader import load_system
from orchestrator.master import simulate
from orchestrator.ssp_common import SSD_NS, SSV_NS
from orchestrator.ssp_load import load_ssp
from orchestrator.ssp_save import save_ssp

TOML = """
[system]
name = "tt_imu"
step = 0.005
stop = 2.0

[units.table]
fmu = "builtin:turntable"
role = "turntable"
[units.table.parameters]
"site.latitude" = 0.7
"outer.encoder.bits" = 20
"outer.angle0" = 0.3
"middle.angle0" = -1.1

[units.imu]
fmu = "builtin:imu"
role = "imu"
[units.imu.parameters]
"gyro.bias.x" = 1e-6
"acc.sf.z" = 3e-5
"gyro.noise.arw" = 1e-4
"acc.noise.vrw" = 1e-4
seed = 7

[[connections]]
from = "table.plate.omega"
to = "imu.omega"
[[connections]]
from = "table.plate.f"
to = "imu.f"
[[connections]]
from = "table.plate.alpha"
to = "imu.alpha"

[record]
signals = ["imu.gyro", "imu.acc", "table.outer.angle", "table.middle.angle"]
"""

# what the three vector connections above mean, written out by hand
EXPECTED_SCALAR = {(f"table.plate.{v}.{c}", f"imu.{v}.{c}") for v in ("omega", "f", "alpha") for c in "xyz"}


@pytest.fixture(scope="module")
def pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("ssp")
    (d / "sys.toml").write_text(TOML)
    toml_sys = load_system(d / "sys.toml")
    save_ssp(toml_sys, d / "sys.ssp")
    return toml_sys, load_ssp(d / "sys.ssp"), d


def test_archive_layout_and_namespaces(pair):
    _, _, d = pair
    with zipfile.ZipFile(d / "sys.ssp") as z:
        names = set(z.namelist())
        assert {"SystemStructure.ssd", "resources/table.fmu", "resources/imu.fmu"} <= names
        assert z.read("resources/imu.fmu") == fmu_path("imu").read_bytes()
        root = ET.fromstring(z.read("SystemStructure.ssd"))
    assert root.tag == f"{{{SSD_NS}}}SystemStructureDescription"
    conns = root.findall(f".//{{{SSD_NS}}}Connection")
    assert {(f"{c.get('startElement')}.{c.get('startConnector')}", f"{c.get('endElement')}.{c.get('endConnector')}")
            for c in conns} == EXPECTED_SCALAR
    ints = root.findall(f".//{{{SSV_NS}}}Parameter[@name='outer.encoder.bits']/{{{SSV_NS}}}Integer")
    assert [i.get("value") for i in ints] == ["20"]
    de = root.find(f"{{{SSD_NS}}}DefaultExperiment")
    assert float(de.get("startTime")) == 0.0 and float(de.get("stopTime")) == 2.0


def test_equivalent_systems(pair):
    a, b, _ = pair
    for k in ("name", "step", "start", "stop", "algorithm", "order", "record", "record_every"):
        assert getattr(a, k) == getattr(b, k), k
    assert [u.name for u in a.units] == [u.name for u in b.units]
    for ua, ub in zip(a.units, b.units):
        assert ua.role == ub.role and ua.mapping == ub.mapping and ua.step_multiple == ub.step_multiple
        assert ua.parameters == ub.parameters
        assert {k: type(v) for k, v in ua.parameters.items()} == {k: type(v) for k, v in ub.parameters.items()}
        assert Path(ub.fmu).read_bytes() == fmu_path(ua.fmu.split(":")[1]).read_bytes()
    assert {(c.source, c.target) for c in b.connections} == EXPECTED_SCALAR
    assert all(c.derivative_order == 0 for c in b.connections)
    assert isinstance(b.unit("imu").parameters["seed"], int)


def test_identical_recordings(pair):
    a, b, _ = pair
    ra, rb = simulate(a), simulate(b)
    assert ra.signals == rb.signals and ra.rows == rb.rows == 401
    assert np.array_equal(ra.time, rb.time)
    assert ra.data.tobytes() == rb.data.tobytes()
    # the run is not trivial: noise, and the servo moves the middle axis from -1.1 rad to 0
    assert np.std(ra["imu.gyro.x"][1:]) > 0
    assert np.ptp(ra["table.middle.angle"]) > 1.0


def test_reload_uses_cache_keyed_by_content(pair):
    _, b, d = pair
    again = load_ssp(d / "sys.ssp")
    assert again.unit("imu").fmu == b.unit("imu").fmu
    import hashlib
    assert hashlib.sha256((d / "sys.ssp").read_bytes()).hexdigest() in b.unit("imu").fmu


def test_default_step_and_record_without_annotation(pair, tmp_path):
    _, _, d = pair
    ssd = _ssd(d / "sys.ssp")
    for parent in ssd.iter():
        for ch in list(parent):
            if ch.tag == f"{{{SSD_NS}}}Annotations":
                parent.remove(ch)
    p = _rewrite(d / "sys.ssp", tmp_path / "plain.ssp", ssd)
    s = load_ssp(p)
    assert s.step == 0.005 and s.algorithm == "gauss-seidel"
    assert s.record == [f"table.plate.{v}.{c}" for v in ("omega", "f", "alpha") for c in "xyz"]
    assert all(u.role is None for u in s.units)


def test_parameter_set_from_ssv_file(pair, tmp_path):
    _, b, d = pair
    ssd = _ssd(d / "sys.ssp")
    comp = ssd.find(f".//{{{SSD_NS}}}Component[@name='imu']")
    pb = comp.find(f"{{{SSD_NS}}}ParameterBindings/{{{SSD_NS}}}ParameterBinding")
    pv = pb.find(f"{{{SSD_NS}}}ParameterValues")
    pset = pv.find(f"{{{SSV_NS}}}ParameterSet")
    pb.remove(pv)
    pb.set("source", "resources/imu.ssv")
    p = _rewrite(d / "sys.ssp", tmp_path / "ssv.ssp", ssd,
                 {"resources/imu.ssv": ET.tostring(pset, xml_declaration=True, encoding="UTF-8")})
    assert load_ssp(p).unit("imu").parameters == b.unit("imu").parameters


# ------------------------------------------------------------------ malformed archives
def _ssd(path: Path) -> ET.Element:
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("SystemStructure.ssd"))


def _rewrite(src: Path, dst: Path, ssd: ET.Element | None, extra: dict | None = None,
             drop: tuple = ()) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for n in zin.namelist():
            if n in drop or (n == "SystemStructure.ssd" and ssd is not None):
                continue
            zout.writestr(n, zin.read(n))
        if ssd is not None:
            zout.writestr("SystemStructure.ssd", ET.tostring(ssd, xml_declaration=True, encoding="UTF-8"))
        for n, data in (extra or {}).items():
            zout.writestr(n, data)
    return dst


def test_missing_ssd(pair, tmp_path):
    _, _, d = pair
    p = _rewrite(d / "sys.ssp", tmp_path / "nossd.ssp", None, drop=("SystemStructure.ssd",))
    with pytest.raises(SystemError_, match=r"nossd\.ssp.*no SystemStructure\.ssd"):
        load_ssp(p)


def test_not_a_zip(tmp_path):
    p = tmp_path / "junk.ssp"
    p.write_text("hello")
    with pytest.raises(SystemError_, match=r"junk\.ssp.*not a zip"):
        load_system(p)  # dispatch through load_system


def test_connection_to_unknown_component(pair, tmp_path):
    _, _, d = pair
    ssd = _ssd(d / "sys.ssp")
    c = ssd.findall(f".//{{{SSD_NS}}}Connection")[4]
    c.set("endElement", "gyro_box")
    p = _rewrite(d / "sys.ssp", tmp_path / "badconn.ssp", ssd)
    with pytest.raises(SystemError_, match=r"badconn\.ssp.*ssd:Connection #5.*endElement='gyro_box' is not a "
                                           r"component"):
        load_ssp(p)


def test_connection_to_undeclared_connector(pair, tmp_path):
    _, _, d = pair
    ssd = _ssd(d / "sys.ssp")
    ssd.findall(f".//{{{SSD_NS}}}Connection")[0].set("startConnector", "plate.omega.q")
    p = _rewrite(d / "sys.ssp", tmp_path / "badcon.ssp", ssd)
    with pytest.raises(SystemError_, match=r"ssd:Connection #1: component 'table' has no connector 'plate.omega.q'"):
        load_ssp(p)


@pytest.mark.parametrize("kind,value,msg", [
    ("Real", "fast", r"ssv:Real value='fast' is not a number"),
    ("Real", "1_000", r"ssv:Real value='1_000' is not a number"),
    ("Integer", "7.5", r"ssv:Integer value='7.5' is not an integer"),
])
def test_parameter_not_a_number(pair, tmp_path, kind, value, msg):
    _, _, d = pair
    ssd = _ssd(d / "sys.ssp")
    name = "gyro.bias.x" if kind == "Real" else "seed"
    el = ssd.find(f".//{{{SSV_NS}}}Parameter[@name='{name}']/{{{SSV_NS}}}{kind}")
    el.set("value", value)
    p = _rewrite(d / "sys.ssp", tmp_path / "badpar.ssp", ssd)
    with pytest.raises(SystemError_, match=rf"badpar\.ssp.*ssd:Component 'imu'.*ssv:Parameter '{name}'.*{msg}"):
        load_ssp(p)


def test_missing_fmu_resource(pair, tmp_path):
    _, _, d = pair
    p = _rewrite(d / "sys.ssp", tmp_path / "nofmu.ssp", None, drop=("resources/imu.fmu",))
    with pytest.raises(SystemError_, match=r"ssd:Component 'imu'.*source='resources/imu.fmu' is not in the archive"):
        load_ssp(p)


def test_missing_stop_time(pair, tmp_path):
    _, _, d = pair
    ssd = _ssd(d / "sys.ssp")
    del ssd.find(f"{{{SSD_NS}}}DefaultExperiment").attrib["stopTime"]
    p = _rewrite(d / "sys.ssp", tmp_path / "nostop.ssp", ssd)
    with pytest.raises(SystemError_, match=r"nostop\.ssp.*stopTime"):
        load_ssp(p)
    assert load_ssp(p, stop=3.0).stop == 3.0


def test_python_component_cannot_be_saved(tmp_path):
    from orchestrator.system import System, UnitSpec

    s = System(units=[UnitSpec("ctrl", component="components.control.sequencer:AttitudeSequence")], stop=1.0)
    with pytest.raises(SystemError_, match="ctrl is a Python component"):
        save_ssp(s, tmp_path / "x.ssp")
