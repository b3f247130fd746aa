"""Algebraic loops solved at every step by fixed-point iteration (system.algorithm =
"iterative", orchestrator/loop_solver.py; #20 item 4), against closed forms and fmpy: the loop's
values at each step end are the solution of its equations, the units' states are restored
between iterations (a lag in the cycle and a component's own counter step once per step), a loop
with no fixed point fails naming it, and a unit that cannot get and set its state is refused."""
from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest

from fmus.build import fmu_path
from orchestrator.component import Component, Var
from orchestrator.errors import AlgebraicLoopError, SimulationFault, SystemError_
from orchestrator.master import Simulation
from orchestrator.system import Connection, System, UnitSpec

HERE = Path(__file__).parent / "fmus"
H = 0.01
N = 50


class HalfPlusClock(Component):
    """y = u / 2 + v + c, c its own clock (advanced by h in each do_step: state the iteration
    must restore); direct feed-through from u and v."""

    variables = [Var("u", "input"), Var("v", "input"), Var("y", "output")]
    feedthrough = {"y": ["u", "v"]}

    def __init__(self, name: str, clock: bool = True) -> None:
        super().__init__(name)
        self.c = 0.0
        self.clock = clock

    def initialize(self, t0: float) -> None:
        self["y"] = 0.5 * self["u"] + self["v"]

    def do_step(self, t: float, h: float) -> None:
        if self.clock:
            self.c += h
        self["y"] = 0.5 * self["u"] + self["v"] + self.c


class PlusOne(Component):
    variables = [Var("u", "input"), Var("y", "output")]
    feedthrough = {"y": ["u"]}

    def do_step(self, t: float, h: float) -> None:
        self["y"] = self["u"] + 1.0


def _pair(fmi: int, **kw) -> System:
    """f (y = u, an FMU) and p (y = u/2 + t) in a loop: y = y/2 + t, so y = 2 t at every step end."""
    return System(step=H, stop=N * H, units=[UnitSpec("f", fmu=str(fmu_path(HERE / "feedthrough", fmi))),
                                             UnitSpec("p", component=HalfPlusClock("p"))],
                  connections=[Connection("f.y", "p.u"), Connection("p.y", "f.u")],
                  record=["f.y", "p.y"], **kw)


@pytest.mark.parametrize("fmi", [2, 3])
def test_the_loop_is_solved_at_every_step(fmi):
    sim = Simulation(_pair(fmi, algorithm="iterative", loop_tolerance=1e-13))
    rec = sim.run()
    t = np.arange(N + 1) * H
    # a contraction by q = 1/2 stops within q / (1 - q) x the last change <= 1e-13 max(1, |y|)
    np.testing.assert_allclose(rec["p.y"][1:], 2 * t[1:], rtol=0, atol=1.01e-13)
    np.testing.assert_allclose(rec["f.y"][1:], 2 * t[1:], rtol=0, atol=1.01e-13)
    assert any("solved by fixed-point iteration at every step" in n for n in sim.notes)
    (stats,) = [n for n in rec.provenance["notes"] if n.startswith("algebraic loop of ['f', 'p'] solved")]
    # the map y -> y/2 + t contracts by 1/2: from the delayed guess (an error of ~2h) to 1e-13
    # takes about log2(2h / 1e-13) + 1 ~ 39 iterations
    assert f"at each of {N} steps" in stats
    iters = float(stats.split("(")[1].split(" iterations")[0])
    assert 30 <= iters <= 45


def test_the_advice_of_the_loop_error_names_the_iteration_and_it_works():
    with pytest.raises(AlgebraicLoopError, match=r'system.algorithm = "iterative"'):
        Simulation(_pair(2)).load()


def test_states_are_restored_between_iterations():
    """A lag L in the cycle of units (p.y -> L.u, L.y -> p.v; no feed-through in L) is stepped
    again with each iterate. With p's clock off, converged p.y = 2 v (v = L.y), and L's exact
    step with that input held, v_(k+1) = u + (v_k - u) a with u = 2 v_(k+1), a = exp(-h/tau),
    gives v_(k+1) = v_k a / (2a - 1). L counts its doStep calls: one per step, so its state was
    restored before every repeat."""
    lag = fmu_path(HERE / "lag", 2)
    sysm = System(step=H, stop=N * H, algorithm="iterative", loop_tolerance=1e-13,
                  units=[UnitSpec("f", fmu=str(fmu_path(HERE / "feedthrough", 2))),
                         UnitSpec("p", component=HalfPlusClock("p", clock=False)),
                         UnitSpec("L", fmu=str(lag), parameters={"tau": 1.0, "y0": 1.0})],
                  connections=[Connection("f.y", "p.u"), Connection("p.y", "f.u"),
                               Connection("p.y", "L.u"), Connection("L.y", "p.v")],
                  record=["f.y", "p.y", "L.y", "L.steps"])
    rec = Simulation(sysm).run()
    a = np.exp(-H / 1.0)
    v = (a / (2 * a - 1)) ** np.arange(N + 1)
    np.testing.assert_allclose(rec["L.y"], v, rtol=1e-11)
    np.testing.assert_allclose(rec["p.y"][1:], 2 * v[1:], rtol=1e-11)
    np.testing.assert_array_equal(rec["L.steps"], np.arange(N + 1))
    # fmpy drives the same lag with the converged input held over each step (the value at the
    # step's end, which the iteration found): the same outputs
    inp = np.zeros(N, dtype=[("time", float), ("u", float)])
    inp["time"], inp["u"] = np.arange(N) * H, rec["p.y"][1:]
    ref = fmpy.simulate_fmu(str(lag), stop_time=N * H, step_size=H, output_interval=H, input=inp,
                            start_values={"tau": 1.0, "y0": 1.0}, output=["y"])
    np.testing.assert_allclose(rec["L.y"], ref["y"], rtol=1e-13)


def test_a_loop_without_a_fixed_point_fails_naming_it():
    sysm = System(step=H, stop=N * H, algorithm="iterative", loop_max_iterations=20,
                  units=[UnitSpec("f", fmu=str(fmu_path(HERE / "feedthrough", 2))), UnitSpec("p", component=PlusOne("p"))],
                  connections=[Connection("f.y", "p.u"), Connection("p.y", "f.u")], record=["f.y"])
    with pytest.raises(SimulationFault, match=r"algebraic loop of \['f', 'p'\]: no fixed point reached at "
                                              r"t = 0 s after 20 iterations"):
        Simulation(sysm).run()


def test_a_unit_that_cannot_get_its_state_is_refused(tmp_path):
    src = fmu_path(HERE / "feedthrough", 2)
    dst = tmp_path / "nostate.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'canGetAndSetFMUstate="true"', b'canGetAndSetFMUstate="false"')
            zout.writestr(item, data)
    sysm = System(step=H, stop=N * H, algorithm="iterative",
                  units=[UnitSpec("f", fmu=str(dst)), UnitSpec("p", component=HalfPlusClock("p"))],
                  connections=[Connection("f.y", "p.u"), Connection("p.y", "f.u")], record=["f.y"])
    with pytest.raises(SystemError_, match=r"the units \['f'\] in the loop of \['f', 'p'\] cannot get and set their "
                                           r"state"):
        Simulation(sysm).load()
    shutil.rmtree(tmp_path, ignore_errors=True)


def test_a_system_file_takes_the_iteration_settings(tmp_path):
    from orchestrator.loader import load_system

    p = tmp_path / "loop.toml"
    p.write_text(f'''[system]
step = {H}
stop = {N * H}
algorithm = "iterative"
loop_tolerance = 1e-12
loop_max_iterations = 0
[units.f]
fmu = "{fmu_path(HERE / 'feedthrough', 2).as_posix()}"
''')
    with pytest.raises(SystemError_, match=r"system.loop_max_iterations = 0: expected an integer >= 1"):
        Simulation(load_system(p))


def test_verify_of_a_solved_loop_converges_with_the_step_and_says_why_no_algorithm_is_compared():
    """y = 2 t at every step end whatever the step: the runs at h, h/2, h/4 agree (the loop
    adds no coupling error), no other algorithm is run against it, and libcosim is not asked."""
    from orchestrator.verify import verify

    report = verify(_pair(2, algorithm="iterative", loop_tolerance=1e-13), rel_tol=1e-9)
    assert "solved at every step (iterative)" in report.algorithm_note
    assert report.ok
