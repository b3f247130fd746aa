"""`calbench verify` on a system whose coupling error has a closed form.

A source x(t) = sin(t) (Python component, exact at its communication points) drives an
integrator y' = x that holds its input over the step (zero-order hold). Under Jacobi the
integrator steps over [t_k, t_k+1] with x(t_k), so y(t_j) = h * sum_{k<j} sin(k h)
= h sin(j h / 2) sin((j - 1) h / 2) / sin(h / 2), while the exact y(t) = 1 - cos(t): a first-order
coupling error, known in closed form at every grid point.
"""
from __future__ import annotations

import math
from pathlib import Path

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
    g = on_grid(rec, 4, ["mean", "sample"])
    np.testing.assert_array_equal(g[:, 0], [0, (1 + 2 + 3 + 4) / 4, (5 + 6 + 7 + 8) / 4])


def test_aggregate_from_toml_and_prefix(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('[system]\nstop = 1.0\n[units.a]\nfmu = "x.fmu"\n'
                 '[record]\nsignals = ["a.gyro"]\naggregate = {"a.gyro" = "sum"}\n')
    s = load_system(p)
    assert aggregation_of(s, "a.gyro.x") == "sum"
    assert aggregation_of(s, "a.gyroscope") == "sample"
    assert aggregation_of(s, "a.gyro.x", {"a.gyro.x": "sample"}) == "sample"
    p.write_text('[system]\nstop = 1.0\n[units.a]\nfmu = "x.fmu"\n'
                 '[record]\nsignals = ["a.gyro"]\naggregate = {"a.gyro" = "median"}\n')
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


# Our IMU FMU between a slewing table (1 rad on the middle axis) and nothing to smooth it over a
# step (no integrals, Jacobi): a real first-order coupling error on every sensed channel.
PAIR = """
[system]
name = "pair"
step = 0.004
stop = {stop}
algorithm = "jacobi"
[units.table]
fmu = "builtin:turntable"
role = "turntable"
[units.table.parameters]
"middle.angle_cmd" = 1.0
[units.imu]
fmu = "builtin:imu"
role = "imu"
{options}
[units.imu.parameters]
"acc.bias.x" = 1e-3
{parameters}
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
signals = ["imu.acc", "imu.gyro", "table.middle.angle"]
"""


def pair(tmp_path, name="pair.toml", stop=1.0, options="", parameters=""):
    p = tmp_path / name
    p.write_text(PAIR.format(stop=stop, options=options, parameters=parameters))
    return p


MEAN_RATE = 'role_options = {gyro_output = "rate", acc_output = "specific_force"}'


def test_mean_rate_outputs_are_averaged_like_increments_are_summed(tmp_path):
    """A mean rate over an interval is its increment divided by the interval, so averaged onto the
    coarse grid it is the summed increment / h: the same IMU in rate mode and in increment mode
    must show the same relative coupling error, each aggregated as its role declares (nothing in
    the system file says how). Sampling the mean rate instead (the old behaviour that failed every
    mean-rate IMU) compares intervals of different lengths and overstates it."""
    inc = verify(load_system(pair(tmp_path)), rel_tol=1.0, engine=False)
    rate_system = load_system(pair(tmp_path, "rate.toml", options=MEAN_RATE))
    rate = verify(rate_system, rel_tol=1.0, engine=False)
    sampled = verify(rate_system, rel_tol=1.0, engine=False, aggregate={"imu": "sample"})
    # the interface it leaves out is said: the pair connects no step integrals
    assert "unit imu (role imu) takes omega_int, f_int, temperature_env, but nothing drives them" \
        in inc.table()
    by_inc = {s.name: s for s in inc.signals}
    by_sampled = {s.name: s for s in sampled.signals}
    for s in rate.signals:
        if not s.name.startswith("imu."):
            continue
        i = by_inc[s.name]
        assert (s.aggregate, i.aggregate) == ("mean", "sum"), s.name
        # the outputs really are rates: increment / h (the role option reached our FMU)
        assert s.rms == pytest.approx(i.rms / 0.004, rel=1e-9), s.name
        if s.name == "imu.acc.x":
            continue  # a constant bias: no coupling error in either mode
        assert s.rel_error == pytest.approx(i.rel_error, rel=1e-6), s.name
        assert by_sampled[s.name].rel_error > 1.3 * s.rel_error, s.name


def test_role_options_and_parameters_must_agree(tmp_path, capsys):
    p = pair(tmp_path, options=MEAN_RATE, parameters='"gyro.output" = 2')
    assert main(["verify", str(p), "--no-engine"]) == 2
    err = capsys.readouterr().err
    assert "gyro.output = 2 contradicts" in err and "Traceback" not in err
    p = pair(tmp_path, options='role_options = {gyro_output = "degrees"}')
    assert main(["verify", str(p), "--no-engine"]) == 2
    assert "gyro_output 'degrees': expected one of" in capsys.readouterr().err


def test_turntable_axes_option_as_one_string():
    from components.simulation.roles import turntable_role

    names = {v.name.split(".")[0] for v in turntable_role("outer, inner").variables}
    assert names == {"outer", "inner", "plate"}
    with pytest.raises(ValueError, match="expected distinct axis names"):
        turntable_role("outer, outer")


class Failing(Component):
    variables = [Var("x", "output")]

    def do_step(self, t, h):
        if t > 0.5:
            raise RuntimeError("sensor saturated")


def test_verify_exit_codes_bad_input_could_not_run_engine_missing(tmp_path, capsys, monkeypatch):
    assert main(["verify", str(pair(tmp_path)), "--aggregate", "imu=median"]) == 2
    assert "expected SIGNAL=sample|sum|mean" in capsys.readouterr().err
    # a unit fails during the run: "could not run", the unit and time named
    failing = tmp_path / "failing.toml"
    failing.write_text('[system]\nname = "f"\nstep = 0.1\nstop = 1.0\n[units.f]\n'
                       'component = "test_verify:Failing"\n[record]\nsignals = ["f.x"]\n')
    monkeypatch.syspath_prepend(str(__import__("pathlib").Path(__file__).parent))
    assert main(["verify", str(failing), "--no-engine"]) == 3
    err = capsys.readouterr().err
    assert "could not run" in err and "sensor saturated" in err
    # the engine is not installed: said in the report, exit 3 even though the coupling passed
    monkeypatch.setitem(__import__("sys").modules, "libcosimpy", None)
    monkeypatch.setitem(__import__("sys").modules, "libcosimpy._internal", None)
    assert main(["verify", str(pair(tmp_path)), "--rel-tol", "1e3"]) == 3
    cap = capsys.readouterr()
    assert "libcosimpy is not installed" in cap.out and "PASS" in cap.out
    assert "engine comparison could not run" in cap.err and "Traceback" not in cap.err
    # a system libcosim cannot run (a Python component) is told why without the engine: the
    # comparison does not apply, so it is no failure to run
    sine = tmp_path / "sine.toml"
    sine.write_text('[system]\nname = "s"\nstep = 0.1\nstop = 1.0\n[units.s]\n'
                    'component = "test_verify:Sine"\n[record]\nsignals = ["s.x"]\n')
    assert main(["verify", str(sine)]) == 0
    out = capsys.readouterr().out
    assert "skipped" in out and "Python component" in out and "not installed" not in out


def test_shipped_all_fmu_example_runs_in_libcosim(capsys):
    """examples/libcosim_pair.toml, as the README runs it: every signal is compared with libcosim
    (none skipped) and agrees to 1e-12; Jacobi's coupling error is second order, as its comment
    says."""
    example = Path(__file__).parent.parent / "examples" / "libcosim_pair.toml"
    assert main(["verify", str(example), "--rel-tol", "1e-3"]) == 0
    out = capsys.readouterr().out
    assert "skipped" not in out and "libcosim (fixed-step, Jacobi)" in out
    report = verify(load_system(example), rel_tol=1e-3)
    gyro = [s for s in report.signals if s.name.startswith("imu.gyro")]
    assert all(s.engine_ok and 1.5 < s.order < 2.5 and 1e-4 < s.rel_error < 1e-3 for s in gyro)
