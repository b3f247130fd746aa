"""What an IMU FMU's interface costs (components/simulation/interface_cost.py), against
computations that do not go through it.

* The supplier IMU (tests/fmus/supplier_imu: no alpha, no step integrals) outputs the mean of the
  straight line between two rate knots. Its coupling error at a step is therefore the difference
  between that trapezoid and the true mean rate, which the table alone gives: its exact step
  integral ``plate.omega_int`` divided by the step. Computed here from a run of the table by
  itself, it must match the reported worst-sample error.
* Our IMU with every input integrates the table's exact step integrals: no coupling error beyond
  rounding at any step, so the largest step tried is recommended.
* An IMU whose noise is on gives outputs that change with the step even at rest: no step is
  recommended, and the report says why; with its noise parameter set to zero they do not.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from components.cli import main
from components.simulation.interface_cost import INDEX, SERVO_PERIOD, interface_cost
from fmus.build import fmu_path
from orchestrator.master import simulate
from orchestrator.system import System, UnitSpec

AX = "XYZ"
MAPPING = {**{f"omega.{c.lower()}": f"AngularRate_{c}" for c in AX}, **{f"f.{c.lower()}": f"Accel_{c}" for c in AX},
           **{f"gyro.{c.lower()}": f"GyroRate_{c}" for c in AX}, **{f"acc.{c.lower()}": f"Accel_Out_{c}" for c in AX}}
MEAN_RATE = {"gyro_output": "rate", "acc_output": "specific_force"}
HERE = Path(__file__).parent


@pytest.fixture(scope="module")
def supplier() -> Path:
    return fmu_path(HERE / "fmus" / "supplier_imu", 2)


def _table_alone(stop: float) -> tuple[np.ndarray, np.ndarray]:
    system = System(name="table", step=SERVO_PERIOD, stop=stop,
                    units=[UnitSpec("table", fmu="builtin:turntable", role="turntable", parameters=dict(INDEX))],
                    record=["table.plate.omega", "table.plate.omega_int"])
    rec = simulate(system, progress=False)
    d = rec.data[: rec.rows]
    return d[:, :3], d[:, 3:6]


def test_supplier_error_is_its_trapezoid_against_the_tables_exact_mean(supplier):
    cost = interface_cost(supplier, MAPPING, MEAN_RATE, step=0.005)
    assert cost.missing == ["alpha", "omega_int", "f_int"]
    omega, omega_int = _table_alone(3.0)
    for s in cost.steps:
        block = int(round(s.step / SERVO_PERIOD))
        knots = omega[::block]
        n = knots.shape[0] - 1
        exact = omega_int[1: n * block + 1].reshape(n, block, 3).sum(axis=1) / s.step
        trapezoid = 0.5 * (knots[:-1] + knots[1:n + 1])
        expected = float(np.max(np.abs(trapezoid - exact)))
        # the reported error is taken against the supplier's own run at the servo period, which
        # carries its own (much smaller) trapezoid error
        assert s.gyro_error == pytest.approx(expected, rel=0.05), s.step
    errors = [s.gyro_error for s in cost.steps]
    assert errors == sorted(errors) and errors[0] < 0.7 * errors[1]   # it falls with the step
    # navigation-grade white noise of a mean rate per sample: ARW / sqrt(h)
    chosen = next(s for s in cost.steps if s.step == 0.005)
    arw = 0.002 * math.pi / 180 / 60
    assert chosen.gyro_ratio == pytest.approx(chosen.gyro_error / (arw / math.sqrt(0.005)), rel=1e-12)
    assert cost.recommended is None and "no step tried keeps" in cost.report()
    # our integration fed the same two inputs does no better on the gyro: it is the interface
    assert cost.same_inputs.gyro_ratio == pytest.approx(chosen.gyro_ratio, rel=0.2)
    assert cost.reference.gyro_error < 1e-12 and cost.reference.acc_error < 1e-12


def test_our_imu_with_every_input_costs_nothing(imu_fmu):
    cost = interface_cost(imu_fmu, step=0.01, grade="tactical")
    assert cost.missing == [] and cost.same_inputs is None
    assert all(s.gyro_error < 1e-12 and s.acc_error < 1e-12 for s in cost.steps)
    assert cost.converges and cost.recommended == max(s.step for s in cost.steps) == 0.02


def test_noise_on_does_not_converge_and_a_zeroed_noise_does():
    noisy = fmu_path(HERE / "fmus" / "supplier_noisy_imu", 2)
    on = interface_cost(noisy, MAPPING, MEAN_RATE, {"GyroARW": 0.05}, step=0.005)
    assert not on.converges and on.recommended is None
    assert "change with the step while the table is at rest" in on.report()
    off = interface_cost(noisy, MAPPING, MEAN_RATE, {"GyroARW": 0.0}, step=0.005)
    assert off.converges


def test_check_fmu_prints_the_cost_and_refuses_bad_options(supplier, capsys):
    maps = [a for k, v in MAPPING.items() for a in ("--map", f"{k}={v}")]
    opts = ["--option", "gyro_output=rate", "--option", "acc_output=specific_force"]
    assert main(["check-fmu", str(supplier), "--role", "imu", *maps, *opts, "--step", "0.01",
                 "--noise-fraction", "500"]) == 0
    out = capsys.readouterr().out
    assert "interface cost" in out and "no angular acceleration (alpha)" in out
    assert "0.01 " in out and "<- chosen" in out and "below 500 x the noise per sample: 0.005 s" in out
    assert main(["check-fmu", str(supplier), "--role", "imu", "--option", "gyro_output=degrees"]) == 2
    err = capsys.readouterr().err
    assert "gyro_output 'degrees': expected one of" in err and "Traceback" not in err
    assert main(["check-fmu", str(supplier), "--role", "imu", *maps, *opts, "--parameter", "GyroARW"]) == 2
    assert "--parameter 'GyroARW': expected NAME=NUMBER" in capsys.readouterr().err
    assert main(["check-fmu", str(supplier), "--role", "imu", *maps, *opts, "--step", "0.0013"]) == 2
    assert "whole multiples of its servo period" in capsys.readouterr().err
