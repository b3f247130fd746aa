"""What libcosim (through libcosimpy 0.0.6) cannot run is named before libcosimpy is called, and
verify reports "engine check skipped: <reason>" instead of libcosimpy's traceback: an Integer
connection (its connect_integer_variables calls a method it never defines) and an FMI 2
Enumeration start value."""
from __future__ import annotations

import zipfile
from pathlib import Path

import pytest

from components.cli import main
from fmus.build import fmu_path
from orchestrator.errors import LibcosimUnsupported
from orchestrator.libcosim import check_supported
from orchestrator.system import Connection, System, UnitSpec
from orchestrator.verify import verify

HERE = Path(__file__).parent / "fmus"


@pytest.fixture(scope="module")
def counter() -> Path:
    return fmu_path(HERE / "counter", 2)


@pytest.fixture(scope="module")
def enum_counter(counter, tmp_path_factory) -> Path:
    """The counter with its Integer parameter 'mode' declared as an Enumeration (FMI 2 sets and
    gets enumerations through the Integer functions, so the binary is unchanged)."""
    out = tmp_path_factory.mktemp("enum") / "enum_counter.fmu"
    with zipfile.ZipFile(counter) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                text = text.replace("  <DefaultExperiment", '  <TypeDefinitions>\n    <SimpleType name="Mode">'
                                    '<Enumeration><Item name="one" value="1"/><Item name="two" value="2"/>'
                                    '</Enumeration></SimpleType>\n  </TypeDefinitions>\n  <DefaultExperiment', 1)
                old = '<Integer start="1"/>'
                assert old in text
                text = text.replace(old, '<Enumeration declaredType="Mode" start="1"/>', 1)
                data = text.encode()
            zout.writestr(item, data)
    return out


def test_integer_connection_is_named_not_a_traceback(counter):
    s = System(step=0.1, stop=1.0, units=[UnitSpec("a", fmu=str(counter)), UnitSpec("b", fmu=str(counter))],
               connections=[Connection("a.n", "b.n_in")], record=["b.n", "b.y"])
    with pytest.raises(LibcosimUnsupported, match=r"a.n -> b.n_in is an Integer connection"):
        check_supported(s)
    rep = verify(s, rel_tol=1e3)
    assert rep.engine_note.startswith("engine check skipped: connection a.n -> b.n_in is an Integer")
    # the integer output is compared exactly; the orchestrator's own run is right: n = 2 * steps
    assert {x.name: x.kind for x in rep.signals} == {"b.n": "exact", "b.y": "real"}


def test_enumeration_start_value_is_named_through_the_cli(enum_counter, tmp_path, capsys):
    toml = tmp_path / "enum.toml"
    toml.write_text(f'[system]\nstep = 0.1\nstop = 1.0\n[units.a]\nfmu = "{enum_counter}"\n'
                    '[units.a.parameters]\nmode = 2\n[record]\nsignals = ["a.y"]\n')
    rc = main(["verify", str(toml), "--rel-tol", "1e3"])
    cap = capsys.readouterr()
    assert "Traceback" not in cap.out + cap.err
    assert "engine check skipped: units.a.parameters: mode is an FMI 2 Enumeration" in cap.out
    assert rc == 0
