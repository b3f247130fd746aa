"""How a run treats a direct feed-through loop (refused, or run with the one-step delay the
system asks for), and the CLI's run of a missing FMU and of an SSP archive (#20)."""
from __future__ import annotations

from pathlib import Path

import fmpy
import numpy as np
import pytest

from fmus.build import fmu_path
from orchestrator.component import Component, Var
from orchestrator.errors import AlgebraicLoopError
from orchestrator.fmu_units import FMU2Unit
from orchestrator.master import Simulation
from orchestrator.system import Connection, System, UnitSpec

HERE = Path(__file__).parent / "fmus"
H = 0.01
N = 20


class PlusOne(Component):
    """y = u + 1, instantaneously (declared feed-through)."""

    variables = [Var("u", "input"), Var("y", "output")]
    feedthrough = {"y": ["u"]}

    def initialize(self, t0: float) -> None:
        self["y"] = self["u"] + 1.0

    def do_step(self, t: float, h: float) -> None:
        self["y"] = self["u"] + 1.0


@pytest.fixture(scope="module")
def feedthrough() -> Path:
    return fmu_path(HERE / "feedthrough", 2)


def _loop(fmu: Path, **kw) -> System:
    """f (y = u, an FMU) and p (y = u + 1) in a loop of direct feed-through."""
    return System(step=H, stop=N * H, units=[UnitSpec("f", fmu=str(fmu)),
                                             UnitSpec("p", component=PlusOne("p"))],
                  connections=[Connection("f.y", "p.u"), Connection("p.y", "f.u")],
                  record=["f.y", "p.y"], **kw)


def test_loop_refused_with_advice_that_works(feedthrough):
    with pytest.raises(AlgebraicLoopError) as ei:
        Simulation(_loop(feedthrough)).load()
    msg = str(ei.value)
    assert "f.u -> f.y -> p.u -> p.y" in msg
    assert "system.order" in msg and 'system.algorithm = "jacobi"' in msg


def test_loop_broken_by_order(feedthrough):
    """order = [f, p]: f reads p's output one step late, p reads f's of the same step. At
    initialisation f reads p.y before p exists (0): f.y_k = k, p.y_k = k + 1."""
    sim = Simulation(_loop(feedthrough, order=["f", "p"]))
    rec = sim.run()
    k = np.arange(N + 1)
    np.testing.assert_array_equal(rec["f.y"], k)
    np.testing.assert_array_equal(rec["p.y"], k + 1)
    (note,) = sim.notes
    assert "algebraic loop f.u -> f.y -> p.u -> p.y broken by the explicit system.order" in note
    assert rec.provenance["notes"] == [note]
    # fmpy: f alone, stepping from t_k with p.y_k as input (the one-step delay: the step to
    # t_(k+1) uses p's output of t_k)
    inp = np.zeros(N + 1, dtype=[("time", float), ("u", float)])
    inp["time"], inp["u"] = k * H, rec["p.y"]
    ref = fmpy.simulate_fmu(str(feedthrough), stop_time=N * H, step_size=H, output_interval=H,
                            input=inp, output=["y"])
    np.testing.assert_array_equal(rec["f.y"][1:], ref["y"][1:])


def test_loop_broken_by_jacobi(feedthrough):
    """Jacobi: both read the other's output of the step before: f.y_k = p.y_{k-1},
    p.y_k = f.y_{k-1} + 1 (from f.y_0 = 0, p.y_0 = 1): f.y = 0 1 1 2 2 3 ..., p.y = 1 1 2 2 ..."""
    sim = Simulation(_loop(feedthrough, algorithm="jacobi"))
    rec = sim.run()
    k = np.arange(N + 1)
    np.testing.assert_array_equal(rec["f.y"], (k + 1) // 2)
    np.testing.assert_array_equal(rec["p.y"], k // 2 + 1)
    assert 'broken by algorithm = "jacobi"' in sim.notes[0]


def test_cli_missing_fmu_is_one_line(tmp_path, capsys):
    from components.cli import main

    p = tmp_path / "sys.toml"
    p.write_text('[system]\nstep = 0.1\nstop = 1.0\n[units.a]\nfmu = "nosuch.fmu"\n')
    assert main(["run", str(p)]) == 2
    err = capsys.readouterr().err
    assert f"unit a: FMU file {tmp_path / 'nosuch.fmu'} does not exist" in err
    assert "Traceback" not in err


def test_cli_ssp_run_named_after_the_file(feedthrough, tmp_path, capsys, monkeypatch):
    from components.cli import main
    from orchestrator.ssp_save import save_ssp

    sysm = System(name="root", step=H, stop=N * H, units=[UnitSpec("f", fmu=str(feedthrough))],
                  record=["f.y"])
    save_ssp(sysm, tmp_path / "bench.ssp")
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(tmp_path / "bench.ssp")]) == 0
    assert (tmp_path / "bench.parquet").exists() and not (tmp_path / "root.parquet").exists()


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("controller", [False, True])
def test_python_path_equals_native_loop(monkeypatch, algorithm, controller):
    """The turntable -> IMU system of test_cross_engine, its FMI 2 units forced onto the Python
    path (as a unit with a Boolean exchange would be), with the angular acceleration also given
    as omega's input derivative: the recording is bit-identical to the native loop's."""
    from test_cross_engine import system

    sysm = system(algorithm, controller=controller)
    sysm.stop = 1.0
    sysm.connections.append(Connection("table.plate.alpha", "imu.omega", 1))
    sysm.record = sysm.record + ["table.plate.alpha"]
    native = Simulation(sysm).run()
    monkeypatch.setattr(Simulation, "_native_ok", lambda self, name: False)
    given = []
    original = FMU2Unit.set_input_derivatives

    def spy(unit, items):
        given.append(items)
        original(unit, items)

    monkeypatch.setattr(FMU2Unit, "set_input_derivatives", spy)
    python = Simulation(sysm).run()
    assert native.signals == python.signals and native.rows == python.rows == 201
    assert np.ptp(native.data[:, 0]) > 0  # the IMU sees motion
    np.testing.assert_array_equal(python.data, native.data)
    # the derivatives reached the IMU before each of its steps: the table's alpha, Gauss-Seidel
    # of the step's end, Jacobi of its start
    assert len(given) == 200
    alpha = np.column_stack([python[f"table.plate.alpha.{c}"] for c in "xyz"])
    k = np.arange(1, 201) if algorithm == "gauss-seidel" else np.arange(200)
    np.testing.assert_array_equal([[x for _, _, x in items] for items in given], alpha[k])
    assert {(var, order) for var, order, _ in given[0]} == {(f"omega.{c}", 1) for c in "xyz"}
