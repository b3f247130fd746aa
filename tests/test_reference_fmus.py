"""benchmarks/reference_fmus.py, the conformance script against fmpy, on a directory of the
project's own FMUs (the modelica Reference-FMUs are not in the repository): every model that runs
is "same", an FMU without co-simulation is listed as not run, and a difference is reported."""
from __future__ import annotations

import importlib.util
import shutil
import sys
import zipfile
from pathlib import Path

import pytest

from fmus.build import fmu_path

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).parent / "fmus"


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("reference_fmus", ROOT / "benchmarks" / "reference_fmus.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules["reference_fmus"] = mod  # its dataclass looks its module up while being built
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture
def folder(tmp_path) -> Path:
    for version in (2, 3):
        (tmp_path / f"{version}.0").mkdir()
        shutil.copy(fmu_path(HERE / "lag", version), tmp_path / f"{version}.0" / "Lag.fmu")
    shutil.copy(fmu_path(HERE / "counter", 2), tmp_path / "2.0" / "Counter.fmu")
    return tmp_path


def test_lines_say_same(script, folder, capsys):
    assert script.main([str(folder)]) == 0
    out = capsys.readouterr().out.splitlines()
    lines = [x for x in out if x.startswith(("2.0", "3.0"))]
    assert len(lines) == 3 and all(x.endswith("same") for x in lines), out
    counter = next(x for x in lines if "test_counter" in x)
    assert " 200   200/200  same" in counter  # 1 s at 5 ms: its integer output changes every step
    assert "3 of 3 models run are the same" in out[-1]


def test_not_run_and_differs_are_reported(script, folder, capsys, monkeypatch):
    src = folder / "3.0" / "Lag.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(folder / "3.0" / "LagME.fmu", "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.decode().replace("<CoSimulation ", "<ModelExchange ").encode()
            zout.writestr(item, data)
    real_fmpy = script._fmpy

    def shifted(path, start, stop, step, names):
        res = real_fmpy(path, start, stop, step, names)
        if "Counter" in str(path):
            res["y"] += 1e-6
        return res

    monkeypatch.setattr(script, "_fmpy", shifted)
    assert script.main([str(folder)]) == 1
    out = capsys.readouterr().out
    assert "not run: the FMU offers model exchange only" in out
    counter = next(x for x in out.splitlines() if "test_counter" in x)
    assert "1.000e-06" in counter and counter.endswith("differs")
