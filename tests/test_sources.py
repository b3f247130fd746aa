"""Built-in signal sources through real simulate() runs driving an FMU input, against their
closed forms; their config mistakes; and a Python component found beside its system file.

The sources drive tests/fmus/feedthrough (y = u at once) under Gauss–Seidel, so the FMU's
recorded output at t_k is the source's value at t_k."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from fmus.build import fmu_path
from orchestrator.errors import SystemError_
from orchestrator.loader import load_system
from orchestrator.master import simulate

HERE = Path(__file__).parent / "fmus"
H, STOP = 0.01, 1.0


@pytest.fixture(scope="module")
def feedthrough() -> Path:
    return fmu_path(HERE / "feedthrough", 2)


def system_file(tmp_path: Path, fmu: Path, component: str, config: str, name: str = "s.toml") -> Path:
    p = tmp_path / name
    p.write_text(f"""
[system]
step = {H}
stop = {STOP}
[units.src]
component = "{component}"
[units.src.config]
{config}
[units.plant]
fmu = "{fmu}"
[[connections]]
from = "src.y"
to = "plant.u"
[record]
signals = ["plant.y"]
""")
    return p


def run(tmp_path, fmu, component, config) -> tuple[np.ndarray, np.ndarray]:
    rec = simulate(load_system(system_file(tmp_path, fmu, component, config)), progress=False)
    return rec.t, rec["plant.y"]


def test_sine_at_the_sample_times(tmp_path, feedthrough):
    t, y = run(tmp_path, feedthrough, "orchestrator.sources:Sine",
               "amplitude = 0.5\nfrequency = 2.0\nphase = 0.3\noffset = 0.1")
    assert len(t) == int(round(STOP / H)) + 1
    np.testing.assert_allclose(y, 0.1 + 0.5 * np.sin(2 * math.pi * 2.0 * t + 0.3), rtol=0, atol=1e-14)


def test_ramp_slope_and_start(tmp_path, feedthrough):
    t, y = run(tmp_path, feedthrough, "orchestrator.sources:Ramp", "slope = -3.0\nstart_time = 0.2\noffset = 1.0")
    before = t < 0.2 - 1e-12
    assert np.all(y[before] == 1.0)
    np.testing.assert_allclose(np.diff(y[~before]), -3.0 * H, rtol=1e-9)
    np.testing.assert_allclose(y, 1.0 - 3.0 * np.maximum(0.0, t - 0.2), atol=1e-14)


def test_step_time(tmp_path, feedthrough):
    t, y = run(tmp_path, feedthrough, "orchestrator.sources:Step", "time = 0.25\nbefore = -1.0\nafter = 2.0")
    first = int(np.argmax(y == 2.0))
    assert abs(t[first] - 0.25) < 1e-12 and np.all(y[:first] == -1.0) and np.all(y[first:] == 2.0)


def test_constant(tmp_path, feedthrough):
    _, y = run(tmp_path, feedthrough, "orchestrator.sources:Constant", "value = 4.5")
    assert np.all(y == 4.5)


CSV = "t_s,cmd,other\n0.0,0.0,9\n0.1,1.0,9\n0.35,-0.5,9\n0.6,2.0,9\n"


@pytest.mark.parametrize("interpolation", ["linear", "hold"])
def test_table_from_csv_relative_to_the_system_file(tmp_path, feedthrough, interpolation):
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "cmd.csv").write_text(CSV)
    t, y = run(tmp_path, feedthrough, "orchestrator.sources:Table",
               f'file = "data/cmd.csv"\ntime = "t_s"\nvalue = "cmd"\ninterpolation = "{interpolation}"')
    ts, ys = np.array([0.0, 0.1, 0.35, 0.6]), np.array([0.0, 1.0, -0.5, 2.0])
    if interpolation == "linear":
        expected = np.interp(t, ts, ys)
    else:
        expected = ys[np.searchsorted(ts, t + 1e-12, side="right") - 1]
    np.testing.assert_allclose(y, expected, atol=1e-12)
    # after the last row the last value is held
    assert np.all(y[t > 0.6] == 2.0)


@pytest.mark.parametrize("component, config, match", [
    ("Sine", 'amplitude = "big"', r"units\.src\.config\.amplitude = 'big': expected a finite number"),
    ("Sine", "frequency = -1.0", r"units\.src\.config\.frequency = -1\.0: expected a number >= 0"),
    ("Sine", "amplitud = 1.0", r"units\.src\.config: Sine does not take \['amplitud'\]; expected some of"),
    ("Step", "time = true", r"units\.src\.config\.time = True: expected a finite number"),
    ("Table", 'file = "nope.csv"', r"units\.src\.config\.file = '.*nope\.csv': no such file"),
    ("Table", 'file = "c.csv"\ninterpolation = "cubic"', r"units\.src\.config\.interpolation = 'cubic'"),
    ("Table", 'file = "c.csv"\nvalue = "missing"', r"units\.src\.config\.value = 'missing': .*c\.csv has no such column"),
    ("Table", 'file = "bad.csv"', r"bad\.csv, line 3: time = 0\.0 after 0\.5: expected strictly increasing"),
])
def test_bad_config_names_unit_and_key(tmp_path, feedthrough, component, config, match):
    (tmp_path / "c.csv").write_text("time,value\n0,1\n1,2\n")
    (tmp_path / "bad.csv").write_text("time,value\n0.5,1\n0.0,2\n")
    with pytest.raises(SystemError_, match=match):
        run(tmp_path, feedthrough, f"orchestrator.sources:{component}", config)


COMPONENT = '''
from orchestrator.component import Component, Var


class Twice(Component):
    variables = [Var("y", "output")]

    def __init__(self, name, gain=2.0):
        super().__init__(name)
        self.gain = gain

    def initialize(self, t0):
        self["y"] = self.gain * t0

    def do_step(self, t, h):
        self["y"] = self.gain * (t + h)
'''


def test_component_beside_the_system_file_without_pythonpath(tmp_path, feedthrough, monkeypatch):
    monkeypatch.chdir(Path(__file__).parent)  # neither the working folder nor the path has it
    name = "calbench_test_beside_system"
    assert not any(Path(p).resolve() == tmp_path.resolve() for p in sys.path if p)
    (tmp_path / f"{name}.py").write_text(COMPONENT)
    t, y = run(tmp_path, feedthrough, f"{name}:Twice", "gain = 3.0")
    np.testing.assert_allclose(y, 3.0 * t, atol=1e-14)
    assert str(tmp_path) not in sys.path  # the folder is not left on the path
    # a module the folder does not have is still reported as one line naming where it looked
    with pytest.raises(SystemError_, match=r"units\.src\.component = 'no_such_module_x:A': cannot import"):
        run(tmp_path, feedthrough, "no_such_module_x:A", "")


def test_two_modules_of_one_name_are_refused_with_both_paths(tmp_path, feedthrough):
    name = "calbench_test_twice_named"
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / f"{name}.py").write_text(COMPONENT)
    t, y = run(tmp_path / "a", feedthrough, f"{name}:Twice", "")
    np.testing.assert_allclose(y, 2.0 * t, atol=1e-14)
    with pytest.raises(SystemError_, match=rf"a module '{name}' is already imported from .*a/{name}\.py, not "
                                           rf".*b/{name}\.py; rename one"):
        run(tmp_path / "b", feedthrough, f"{name}:Twice", "")
    sys.modules.pop(name, None)


def test_short_names_of_the_builtin_sources(tmp_path, feedthrough):
    t, y = run(tmp_path, feedthrough, "sine", "amplitude = 2.0\nfrequency = 0.5")
    np.testing.assert_allclose(y, 2.0 * np.sin(math.pi * t), atol=1e-14)
    with pytest.raises(SystemError_, match=r"units\.src\.component = 'cosine': expected 'module:Class' or a "
                                           r"built-in source \(constant, step, ramp, sine, table\)"):
        run(tmp_path, feedthrough, "cosine", "")
