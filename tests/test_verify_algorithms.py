"""verify sees the coupling error step refinement cannot: units that act on their own fixed grid.

A source samples sin on its own grid of period T (its output changes only at multiples of T); a
consumer accumulates y += T * u, also only at multiples of T, and counts the ticks with u > 0.
Under Gauss–Seidel the consumer's tick at t_i sees sin(t_i); under Jacobi it sees the source's
output one communication step earlier, which is sin(t_(i-1)) for every h that divides T: the run
is a whole internal period late, and h, h/2, h/4 give identical recordings. The closed form of the
difference: y_GS(t_i) - y_J(t_i) = T * sin(t_i).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from components.cli import main
from orchestrator.component import Component, Var
from orchestrator.system import Connection, System, UnitSpec
from orchestrator.verify import verify

T, H, STOP = 0.05, 0.01, 2.0


def _tick(t: float) -> int | None:
    """The internal grid index reached at t, or None between grid points."""
    i = round(t / T)
    return i if abs(t - i * T) < 1e-9 else None


class GridSine(Component):
    variables = [Var("x", "output")]

    def do_step(self, t, h):
        i = _tick(t + h)
        if i is not None:
            self["x"] = math.sin(i * T)


class GridSum(Component):
    variables = [Var("u", "input"), Var("y", "output"), Var("positive", "output", type="Integer", start=0)]

    def do_step(self, t, h):
        if _tick(t + h) is not None:
            self["y"] += T * self["u"]
            self["positive"] += int(self["u"] > 0)


def grid_system(algorithm: str) -> System:
    return System(name="grid", step=H, stop=STOP, algorithm=algorithm,
                  units=[UnitSpec("src", component=GridSine), UnitSpec("sum", component=GridSum)],
                  connections=[Connection("src.x", "sum.u")],
                  record=["sum.y", "sum.positive", "src.x"])


def test_jacobi_one_step_late_is_flagged_by_the_algorithm_comparison():
    rep = verify(grid_system("jacobi"), rel_tol=1e-3, engine=False)
    by = {s.name: s for s in rep.signals}
    y = by["sum.y"]
    # refinement is blind: identical h, h/2, h/4 runs
    assert y.d1 == 0.0 and y.d2 == 0.0 and y.error == 0.0
    # the algorithm difference against its closed form T sin(t_i), RMS over the grid rows
    t = np.arange(1, int(round(STOP / H)) + 1) * H
    held = T * np.sin(np.floor(t / T + 1e-9) * T)
    assert abs(y.alg_diff - math.sqrt(np.mean(held ** 2))) < 1e-12
    assert y.alg_bound == y.alg_diff / 2 and not y.coupling_ok
    # the integer counter is compared exactly: rows that differ
    pos = by["sum.positive"]
    assert pos.kind == "exact" and pos.alg_diff > 0 and not pos.coupling_ok
    assert by["src.x"].coupling_ok and by["src.x"].alg_diff == 0.0
    assert not rep.ok
    assert "step refinement shows no change: the units integrate on their own grid; the algorithm " \
           "comparison does" in rep.table()


def test_gauss_seidel_feed_forward_passes():
    rep = verify(grid_system("gauss-seidel"), rel_tol=1e-3, engine=False)
    assert rep.ok, rep.table()
    assert "not judged" in rep.algorithm_note


def test_gauss_seidel_against_the_order_is_judged():
    s = grid_system("gauss-seidel")
    s.order = ["sum", "src"]  # the consumer steps first: its input is a step late, as in Jacobi
    rep = verify(s, rel_tol=1e-3, engine=False)
    assert not rep.ok and "src.x -> sum.u" in rep.algorithm_note


TOML = """
[system]
name = "grid"
step = {h}
stop = {stop}
algorithm = "{algorithm}"
[units.src]
component = "test_verify_algorithms:GridSine"
[units.sum]
component = "test_verify_algorithms:GridSum"
[[connections]]
from = "src.x"
to = "sum.u"
[record]
signals = ["sum.y", "sum.positive"]
"""


def test_cli_exit_codes(tmp_path, capsys, monkeypatch):
    monkeypatch.syspath_prepend(str(Path(__file__).parent))
    for algorithm, code in (("jacobi", 1), ("gauss-seidel", 0)):
        p = tmp_path / f"{algorithm}.toml"
        p.write_text(TOML.format(h=H, stop=STOP, algorithm=algorithm))
        assert main(["verify", str(p), "--rel-tol", "1e-3"]) == code
        out = capsys.readouterr().out
        assert ("FAIL" if code else "PASS") in out
        assert ("the algorithm comparison does" in out) == (code == 1)


def test_through_an_fmu(tmp_path):
    """The same blind spot with an FMU in the path: the grid source drives tests/fmus/feedthrough
    (y = u), recorded at the FMU's output; Jacobi hands it x one communication step late."""
    from fmus.build import fmu_path

    fmu = fmu_path(Path(__file__).parent / "fmus" / "feedthrough", 2)

    def system(algorithm):
        return System(name="grid_fmu", step=H, stop=STOP, algorithm=algorithm,
                      units=[UnitSpec("src", component=GridSine), UnitSpec("plant", fmu=str(fmu))],
                      connections=[Connection("src.x", "plant.u")], record=["plant.y"])

    late = verify(system("jacobi"), rel_tol=1e-3, engine=False)
    (y,) = late.signals
    assert y.d1 == 0.0 and y.d2 == 0.0 and not late.ok
    # GS gives y(t_k) = x(t_k), Jacobi x(t_k-1): differences where the source changed
    t = np.arange(0, int(round(STOP / H)) + 1) * H
    x = np.sin(np.floor(t / T + 1e-9) * T)
    assert abs(y.alg_diff - math.sqrt(np.mean(np.diff(x) ** 2))) < 1e-12
    assert verify(system("gauss-seidel"), rel_tol=1e-3, engine=False).ok


def test_columns_of_every_type_are_put_on_the_grid_and_compared():
    """What verify does with a typed recording's columns (strings by equality, integers and
    Booleans exactly, arrays not compared), told by the column when no variable type is known."""
    from orchestrator.verify import _column_on_grid, _differ, _kind

    words = np.array(["idle", "run", "run", "stop", "stop"], dtype=object)
    np.testing.assert_array_equal(_column_on_grid(words, 2, "sample"), ["idle", "run", "stop"])
    assert _differ(words, np.array(["idle", "run", "x", "stop", "y"], dtype=object)) == 2
    assert _kind(None, "u.mode", words) == ("equal", "")
    assert _kind(None, "u.flag", np.array([True, False]))[0] == "exact"
    assert _kind(None, "u.n", np.array([1, 2], dtype=np.int64))[0] == "exact"
    assert _kind(None, "u.x", np.array([1.0, 2.0]))[0] == "real"
    kind, why = _kind(None, "u.v", np.zeros((3, 2)))
    assert kind == "skip" and "array" in why
    counts = np.array([0, 1, 1, 2, 3], dtype=np.int64)
    np.testing.assert_array_equal(_column_on_grid(counts, 2, "sum"), [0, 2, 5])
