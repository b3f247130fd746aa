"""Generic behaviour of the orchestrator, with small FMUs built from tests/fmus/ and Python
components defined here: exactness of the exchange (closed forms, hand-derived sequences for
Gauss-Seidel and Jacobi), multi-rate stepping, recording, and every kind of fault with the
message it must give and the partial results it must keep."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fmus.build import fmu_path
from orchestrator.component import Component, Var
from orchestrator.errors import AlgebraicLoopError, RoleError, SimulationFault, SystemError_
from orchestrator.fmu_units import FMU2Unit
from orchestrator.loader import load_system
from orchestrator.master import Simulation, simulate
from orchestrator.recording import Recording
from orchestrator.system import Connection, System, UnitSpec

HERE = Path(__file__).parent / "fmus"
H = 0.01  # communication step of every system here


@pytest.fixture(scope="module")
def fmus() -> dict[str, Path]:
    return {name: fmu_path(HERE / name, 2)
            for name in ("feedthrough", "lag", "failing", "nanout", "badimu")}


# ------------------------------------------------------------------ Python components

class Sequence(Component):
    """y = values[k] at communication point k (k = 0 at the start)."""

    variables = [Var("y", "output")]

    def __init__(self, name: str, values=(0.0,)) -> None:
        super().__init__(name)
        self.values = list(values)
        self.k = 0

    def initialize(self, t0: float) -> None:
        self["y"] = self.values[0]

    def do_step(self, t: float, h: float) -> None:
        self.k += 1
        self["y"] = self.values[self.k]


class Constant(Component):
    variables = [Var("y", "output")]

    def __init__(self, name: str, value: float = 1.0) -> None:
        super().__init__(name)
        self.value = value

    def initialize(self, t0: float) -> None:
        self["y"] = self.value

    def do_step(self, t: float, h: float) -> None:
        self["y"] = self.value


class Counter(Component):
    """Counts its steps; reports the last step size."""

    variables = [Var("steps", "output"), Var("h_last", "output")]

    def do_step(self, t: float, h: float) -> None:
        self["steps"] += 1
        self["h_last"] = h


class Boom(Component):
    """y = t; raises in the step that starts at ``at``."""

    variables = [Var("y", "output")]

    def __init__(self, name: str, at: float = 0.03) -> None:
        super().__init__(name)
        self.at = at

    def do_step(self, t: float, h: float) -> None:
        if t >= self.at - 1e-9 * h:
            raise RuntimeError("sensor model diverged")
        self["y"] = t + h


class PyNaN(Component):
    """y = t at the end of the step, NaN from ``at`` on."""

    variables = [Var("y", "output")]

    def __init__(self, name: str, at: float = 0.05) -> None:
        super().__init__(name)
        self.at = at

    def do_step(self, t: float, h: float) -> None:
        self["y"] = math.nan if t + h >= self.at - 1e-9 * h else t + h


def _system(units, connections=(), record=(), stop=0.1, **kw) -> System:
    return System(name="t", step=H, start=0.0, stop=stop, units=list(units),
                  connections=[Connection(a, b) for a, b in connections], record=list(record), **kw)


def _t(rec: Recording) -> np.ndarray:
    return np.arange(rec.rows) * H


# ------------------------------------------------------------------ exactness

def test_lag_step_response_is_the_closed_form(fmus):
    tau = 0.037
    sysm = _system([UnitSpec("src", component=Constant, config={"value": 2.5}),
                    UnitSpec("lag", fmu=str(fmus["lag"]), parameters={"tau": tau})],
                   [("src.y", "lag.u")], ["lag.y"], stop=0.5)
    rec = simulate(sysm)
    assert rec.rows == 51 and rec.complete
    # the input is 2.5 from t = 0 and held: y(t) = 2.5 (1 - exp(-t/tau)) exactly at every step
    np.testing.assert_allclose(rec["lag.y"], 2.5 * (1 - np.exp(-_t(rec) / tau)), rtol=1e-13, atol=1e-15)


def test_system_file_in_toml(fmus, tmp_path):
    """The same lag from a TOML file: an FMU-only system (stepped in one native span) whose
    input is set as a start value, record.every = 3, output saved and reloaded."""
    tau = 0.05
    f = tmp_path / "lag.toml"
    f.write_text(f"""
[system]
name = "lagtoml"
step = {H}
stop = 0.1
[units.lag]
fmu = "{fmus['lag']}"
[units.lag.parameters]
tau = {tau}
u = 1.0
[record]
signals = ["lag.y", "lag.steps"]
every = 3
""")
    sysm = load_system(f)
    rec = simulate(sysm, output=tmp_path / "out.parquet")
    # 10 steps, a row every 3rd: t = 0, 0.03, 0.06, 0.09
    t = np.array([0.0, 0.03, 0.06, 0.09])
    assert rec.rows == 4
    np.testing.assert_allclose(rec.t, t, rtol=1e-15)
    np.testing.assert_allclose(rec["lag.y"], 1 - np.exp(-t / tau), rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(rec["lag.steps"], [0, 3, 6, 9])
    back = Recording.load(tmp_path / "out.parquet")
    assert back.complete and back.fault is None
    np.testing.assert_array_equal(back["lag.y"], rec["lag.y"])


SEQ = [float(k * k + 1) for k in range(11)]  # s_k, distinct at every step


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_feedthrough_chain(fmus, algorithm):
    """src -> f1 -> f2, both with direct feed-through. Gauss-Seidel (order from the graph:
    src, f1, f2) passes s_k through the chain within step k; Jacobi gives every unit the values
    of the start of the step, so each link adds one step of delay. The initial exchange runs in
    stepping order in both cases, so row 0 is s_0 everywhere."""
    sysm = _system([UnitSpec("f2", fmu=str(fmus["feedthrough"])),  # declared out of order
                    UnitSpec("src", component=Sequence, config={"values": SEQ}),
                    UnitSpec("f1", fmu=str(fmus["feedthrough"]))],
                   [("src.y", "f1.u"), ("f1.y", "f2.u")], ["src.y", "f1.y", "f2.y"],
                   algorithm=algorithm)
    sim = Simulation(sysm)
    sim.load()
    assert sim.order == ["src", "f1", "f2"]
    rec = sim.run()
    k = np.arange(11)
    s = np.array(SEQ)
    np.testing.assert_array_equal(rec["src.y"], s)
    if algorithm == "gauss-seidel":
        np.testing.assert_array_equal(rec["f1.y"], s)
        np.testing.assert_array_equal(rec["f2.y"], s)
    else:
        np.testing.assert_array_equal(rec["f1.y"], s[np.maximum(k - 1, 0)])
        np.testing.assert_array_equal(rec["f2.y"], s[np.maximum(k - 2, 0)])


@pytest.mark.parametrize("python_source", [True, False])
def test_multi_rate(fmus, python_source):
    """A lag with step_multiple 4 steps at base steps 0, 4, 8 over 4 h. Its outputs are
    published as soon as it has stepped and held until its next step: the row at base step k
    (k >= 1) shows the state after n = ceil(k/4) of its steps, at time 4 h n. A Python unit
    with step_multiple 4 (counter) follows the same rule."""
    tau = 0.07
    units = [UnitSpec("lag", fmu=str(fmus["lag"]), step_multiple=4,
                      parameters={"tau": tau} if python_source else {"tau": tau, "u": 1.0}),
             UnitSpec("cnt", component=Counter, step_multiple=4)]
    conns = []
    if python_source:
        units.append(UnitSpec("src", component=Constant, config={"value": 1.0}))
        conns = [("src.y", "lag.u")]
    rec = simulate(_system(units, conns, ["lag.y", "lag.steps", "lag.h_last", "cnt.steps",
                                          "cnt.h_last"], stop=0.12))
    k = np.arange(13)
    n = -(-k // 4)  # ceil
    assert rec.rows == 13
    np.testing.assert_array_equal(rec["lag.steps"], n)
    np.testing.assert_array_equal(rec["cnt.steps"], n)
    np.testing.assert_array_equal(rec["lag.h_last"], np.where(k > 0, 4 * H, 0.0))
    np.testing.assert_array_equal(rec["cnt.h_last"], np.where(k > 0, 4 * H, 0.0))
    np.testing.assert_allclose(rec["lag.y"], 1 - np.exp(-4 * H * n / tau), rtol=1e-13, atol=1e-15)


# ------------------------------------------------------------------ faults during the run

@pytest.mark.parametrize("with_python", [False, True])
def test_fmu_error_is_reported_with_partial_results(fmus, tmp_path, with_python):
    """fmi2Error from the step starting at 0.05 s. Without a Python unit the whole run is one
    native span; with one, the FMU is stepped one base step at a time."""
    units = [UnitSpec("bad", fmu=str(fmus["failing"]), parameters={"fail_time": 0.05})]
    if with_python:
        units.append(UnitSpec("cnt", component=Counter))
    out = tmp_path / "partial.parquet"
    with pytest.raises(SimulationFault) as ei:
        simulate(_system(units, record=["bad.y"]), output=out)
    msg = str(ei.value)
    assert "unit bad: fmi2DoStep returned Error at t = 0.05 s (step 5)" in msg
    assert "[Error] deliberate failure: step from t = 0.05 reached fail_time = 0.05" in msg
    rec = ei.value.recording
    # steps 0..4 completed: rows t = 0 .. 0.05, y = the time at the end of each step
    assert rec.rows == 6 and not rec.complete
    np.testing.assert_allclose(rec["bad.y"], _t(rec), rtol=1e-12, atol=0)
    assert ei.value.saved == out
    back = Recording.load(out)
    assert back.complete is False
    assert "fmi2DoStep returned Error" in back.fault and "deliberate failure" in back.fault
    assert back.rows == 6
    np.testing.assert_array_equal(back["bad.y"], rec["bad.y"])
    np.testing.assert_allclose(back.t, np.arange(6) * H, rtol=1e-15)


def test_fmu_nan_output(fmus, tmp_path):
    with pytest.raises(SimulationFault) as ei:
        simulate(_system([UnitSpec("nan", fmu=str(fmus["nanout"]), parameters={"nan_time": 0.05})],
                         record=["nan.y"]), output=tmp_path / "nan.parquet")
    msg = str(ei.value)
    # the NaN is the output for the end of the step 0.04 -> 0.05
    assert "unit nan: output y = nan at t = 0.05 s" in msg
    assert "[Warning] output y is NaN from t = 0.05" in msg
    rec = ei.value.recording
    assert rec.rows == 5  # t = 0 .. 0.04: nothing non-finite was recorded
    np.testing.assert_allclose(rec["nan.y"], _t(rec), rtol=1e-12, atol=0)
    back = Recording.load(tmp_path / "nan.parquet")
    assert not back.complete and "output y = nan" in back.fault and back.rows == 5


def test_python_component_exception(fmus, tmp_path):
    sysm = _system([UnitSpec("src", component=Constant),
                    UnitSpec("lag", fmu=str(fmus["lag"]), parameters={"tau": 0.1}),
                    UnitSpec("boom", component=Boom, config={"at": 0.03})],
                   [("src.y", "lag.u")], ["lag.y", "boom.y"])
    with pytest.raises(SimulationFault) as ei:
        simulate(sysm, output=tmp_path / "boom.parquet")
    msg = str(ei.value)
    assert "unit boom: do_step at t = 0.03 s raised RuntimeError: sensor model diverged" in msg
    rec = ei.value.recording
    assert rec.rows == 4  # t = 0 .. 0.03
    np.testing.assert_allclose(rec["boom.y"], _t(rec), rtol=1e-12, atol=0)
    np.testing.assert_allclose(rec["lag.y"], 1 - np.exp(-_t(rec) / 0.1), rtol=1e-13, atol=1e-15)
    assert not Recording.load(tmp_path / "boom.parquet").complete


def test_python_component_nan(fmus):
    sysm = _system([UnitSpec("pynan", component=PyNaN, config={"at": 0.05}),
                    UnitSpec("f", fmu=str(fmus["feedthrough"]))],
                   [("pynan.y", "f.u")], ["f.y"])
    with pytest.raises(SimulationFault) as ei:
        simulate(sysm)
    assert "unit pynan: output y = nan at t = 0.05 s" in str(ei.value)
    rec = ei.value.recording
    assert rec.rows == 5
    np.testing.assert_allclose(rec["f.y"], _t(rec), rtol=1e-12, atol=0)


# ------------------------------------------------------------------ refused before the run

def test_role_mismatch_refused_before_first_step(fmus):
    sysm = _system([UnitSpec("imu", fmu=str(fmus["badimu"]), role="imu")])
    sim = Simulation(sysm)
    with pytest.raises(RoleError) as ei:
        sim.load()
    (chk,) = ei.value.checks
    assert sorted(chk.problems) == sorted([
        "missing input f.z [m/s2, Real]",
        "omega.x: causality parameter, role imu needs input",
    ])
    msg = str(ei.value)
    assert "unit imu against role imu: 2 problem(s)" in msg
    assert "missing input f.z" in msg and "omega.x: causality parameter" in msg
    # nothing was instantiated
    assert isinstance(sim.units["imu"], FMU2Unit) and sim.units["imu"].fmu is None
    with pytest.raises(RoleError):
        simulate(sysm)


def test_algebraic_loop_detected(fmus):
    sysm = _system([UnitSpec("f1", fmu=str(fmus["feedthrough"])),
                    UnitSpec("f2", fmu=str(fmus["feedthrough"]))],
                   [("f1.y", "f2.u"), ("f2.y", "f1.u")])
    with pytest.raises(AlgebraicLoopError) as ei:
        Simulation(sysm).load()
    assert "algebraic loop" in str(ei.value)
    assert "f1.u -> f1.y -> f2.u -> f2.y" in str(ei.value)
    # the same cycle through a unit without feed-through (the lag) is an ordinary feedback
    ok = _system([UnitSpec("f1", fmu=str(fmus["feedthrough"])),
                  UnitSpec("lag", fmu=str(fmus["lag"]))],
                 [("f1.y", "lag.u"), ("lag.y", "f1.u")])
    Simulation(ok).load()


def _toml(tmp_path, body: str) -> Path:
    p = tmp_path / "sys.toml"
    p.write_text(body)
    return p


def _base(fmus) -> str:
    return f"""
[system]
step = {H}
stop = 0.1
[units.f1]
fmu = "{fmus['feedthrough']}"
[units.f2]
fmu = "{fmus['feedthrough']}"
[units.lag]
fmu = "{fmus['lag']}"
"""


@pytest.mark.parametrize("extra, where, key", [
    ("", "units.lag", "stepmultiple"),
    ("", "system", "stpe"),
    ("", "record", "evry"),
    ("", "connections[0]", "derivative"),
])
def test_unknown_keys(fmus, tmp_path, extra, where, key):
    body = _base(fmus)
    if where == "units.lag":
        body += "stepmultiple = 4\n"
    elif where == "system":
        body = body.replace("stop = 0.1", "stop = 0.1\nstpe = 0.02")
    elif where == "record":
        body += '[record]\nsignals = ["f1.y"]\nevry = 2\n'
    else:
        body += '[[connections]]\nfrom = "f1.y"\nto = "f2.u"\nderivative = 1\n'
    p = _toml(tmp_path, body)
    with pytest.raises(SystemError_) as ei:
        load_system(p)
    msg = str(ei.value)
    assert str(p) in msg and where in msg and repr(key) in msg and "unknown key" in msg
    assert "\n" not in msg


def test_connection_to_unknown_unit(fmus, tmp_path):
    p = _toml(tmp_path, _base(fmus) + '[[connections]]\nfrom = "nosuch.y"\nto = "f1.u"\n')
    with pytest.raises(SystemError_) as ei:
        load_system(p)
    assert "connections[0]" in str(ei.value) and "'nosuch.y'" in str(ei.value)
    assert "['f1', 'f2', 'lag']" in str(ei.value)


def test_connection_to_unknown_variable(fmus, tmp_path):
    p = _toml(tmp_path, _base(fmus) + '[[connections]]\nfrom = "f1.y"\nto = "lag.uu"\n')
    sysm = load_system(p)
    with pytest.raises(SystemError_) as ei:
        Simulation(sysm).load()
    msg = str(ei.value)
    assert "connections[0] (f1.y -> lag.uu)" in msg
    assert "unit lag has no variable 'uu'; did you mean u?" in msg


def test_input_driven_twice(fmus, tmp_path):
    p = _toml(tmp_path, _base(fmus) + '[[connections]]\nfrom = "f1.y"\nto = "f2.u"\n'
              '[[connections]]\nfrom = "lag.y"\nto = "f2.u"\n')
    with pytest.raises(SystemError_) as ei:
        Simulation(load_system(p)).load()
    msg = str(ei.value)
    assert "connections[1] (lag.y -> f2.u)" in msg
    assert "input f2.u is already driven by f1.y" in msg
