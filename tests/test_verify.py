"""`calbench verify` on a system whose coupling error has a closed form.

A source x(t) = sin(t) (Python component, exact at its communication points) drives an
integrator y' = x that holds its input over the step (zero-order hold). Under Jacobi the
integrator steps over [t_k, t_k+1] with x(t_k), so y(t_j) = h * sum_{k<j} sin(k h)
= h sin(j h / 2) sin((j - 1) h / 2) / sin(h / 2), while the exact y(t) = 1 - cos(t): a first-order
coupling error, known in closed form at every grid point.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from components.cli import main
from orchestrator.component import Component, Var
from orchestrator.loader import load_system
from orchestrator.system import Connection, System, UnitSpec
from orchestrator.verify import aggregation_of, on_grid, verify


class Sine(Component):
    variables = [Var("x", "output")]

    def initialize(self, t0):
        self["x"] = math.sin(t0)

    def do_step(self, t, h):
        self["x"] = math.sin(t + h)


class HoldIntegrator(Component):
    variables = [Var("u", "input"), Var("y", "output"), Var("dy", "output")]

    def do_step(self, t, h):
        self["dy"] = h * self["u"]  # the increment over the step (a per-interval quantity)
        self["y"] += self["dy"]


H, STOP = 0.01, 4.0


def lag_system(every: int = 1) -> System:
    return System(name="hold", step=H, stop=STOP, algorithm="jacobi",
                  units=[UnitSpec("src", component=Sine), UnitSpec("int", component=HoldIntegrator)],
                  connections=[Connection("src.x", "int.u")],
                  record=["int.y", "int.dy", "src.x"], record_every=every,
                  record_aggregate={"int.dy": "sum"})


def closed_form_y(t: np.ndarray, h: float) -> np.ndarray:
    j = np.round(t / h)
    return h * np.sin(j * h / 2) * np.sin((j - 1) * h / 2) / math.sin(h / 2)


@pytest.mark.parametrize("every", [1, 5])
def test_order_and_error_estimate_against_closed_form(every):
    rep = verify(lag_system(every), rel_tol=1e-2, engine=False)
    by = {s.name: s for s in rep.signals}
    t = np.arange(1, int(round(STOP / (H * every))) + 1) * H * every
    true_y = closed_form_y(t, H) - (1 - np.cos(t))
    true_err = math.sqrt(np.mean(true_y ** 2))
    y = by["int.y"]
    assert abs(y.order - 1.0) < 0.05, y.order
    assert true_err / 2 <= y.error <= 2 * true_err, (y.error, true_err)
    # the per-interval increment, summed onto the coarse grid: its sum over a grid interval
    # is y(t_j) - y(t_j-1); its exact value is cos(t_j-1) - cos(t_j)
    dy = by["int.dy"]
    assert dy.aggregate == "sum"
    y_h = closed_form_y(np.concatenate([[0.0], t]), H)
    true_dy = np.diff(y_h) - (np.cos(t - H * every) - np.cos(t))
    assert abs(dy.order - 1.0) < 0.1, dy.order
    assert math.sqrt(np.mean(true_dy ** 2)) / 2 <= dy.error <= 2 * math.sqrt(np.mean(true_dy ** 2))
    # the source is exact at its communication points: no coupling error at all
    assert by["src.x"].error < 1e-14 and by["src.x"].coupling_ok  # rounding of t + h only
    assert "skipped" in rep.table() or "not requested" in rep.engine_note


def test_pass_fail_flips_with_tolerance():
    rel = {s.name: s.rel_error for s in verify(lag_system(), rel_tol=1.0, engine=False).signals}
    assert rel["int.y"] > 0 and rel["int.dy"] > 0
    assert verify(lag_system(), rel_tol=2 * max(rel.values()), engine=False).ok
    bad = verify(lag_system(), rel_tol=rel["int.y"] / 2, engine=False)
    assert not bad.ok
    failed = {s.name for s in bad.signals if not s.coupling_ok}
    assert "int.y" in failed and "src.x" not in failed


def test_on_grid_sample_and_sum():
    from orchestrator.recording import Recording

    data = np.arange(9, dtype=float).reshape(9, 1).repeat(2, axis=1)
    rec = Recording(["a", "b"], np.arange(9.0), data, rows=9)
    g = on_grid(rec, 4, ["sample", "sum"])
    np.testing.assert_array_equal(g[:, 0], [0, 4, 8])
    np.testing.assert_array_equal(g[:, 1], [0, 1 + 2 + 3 + 4, 5 + 6 + 7 + 8])


def test_aggregate_from_toml_and_prefix(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('[system]\nstop = 1.0\n[units.a]\nfmu = "x.fmu"\n'
                 '[record]\nsignals = ["a.gyro"]\naggregate = {"a.gyro" = "sum"}\n')
    s = load_system(p)
    assert aggregation_of(s, "a.gyro.x") == "sum"
    assert aggregation_of(s, "a.gyroscope") == "sample"
    assert aggregation_of(s, "a.gyro.x", {"a.gyro.x": "sample"}) == "sample"
    p.write_text('[system]\nstop = 1.0\n[units.a]\nfmu = "x.fmu"\n'
                 '[record]\nsignals = ["a.gyro"]\naggregate = {"a.gyro" = "mean"}\n')
    with pytest.raises(Exception, match="aggregate"):
        load_system(p)


def test_cli_verify_exit_codes(tmp_path, capsys):

    toml = tmp_path / "fmus.toml"
    toml.write_text("""
[system]
name = "pair"
step = 0.004
stop = 1.0
algorithm = "jacobi"
[units.table]
fmu = "builtin:turntable"
role = "turntable"
[units.table.parameters]
"middle.angle_cmd" = 1.0
[units.imu]
fmu = "builtin:imu"
role = "imu"
[units.imu.parameters]
input_timing = 1
"acc.bias.x" = 1e-3
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
signals = ["imu.acc", "table.middle.angle"]
aggregate = {"imu.acc" = "sum"}
""")
    assert main(["verify", str(toml), "--rel-tol", "1e3"]) == 0
    out = capsys.readouterr().out
    assert "PASS" in out and "skipped" not in out  # the libcosim comparison ran
    assert main(["verify", str(toml), "--rel-tol", "1e-15"]) == 1
    assert "FAIL" in capsys.readouterr().out
