"""What an IMU FMU's interface costs at a communication step: the coupling error of its outputs
while the table indexes, against the noise the outputs carry per sample.

An IMU gets the table's motion only at communication points. Between them it must reconstruct
it: ours takes the angular acceleration (``alpha``, the derivative of ``omega``) and the table's
exact step integrals (``omega_int``, ``f_int``) and is exact through the servo's transients; an
IMU without them interpolates, and its increments are wrong while the table accelerates. The
error is a property of the interface and the step, not of the sensor, so it is measured here
without noise:

* the candidate IMU, driven by our turntable through a three-axis index (Gauss–Seidel, the table
  first, every input the IMU takes connected), runs at each step tried and once at the table's
  servo period (the finest step the table has, the reference);
* each run's outputs, and the reference's aggregated onto its grid as the role declares (sums of
  increments, means of mean rates), differ by the coupling error of that step (the reference's
  own error is that of a step 4 or more times smaller: a quarter of the estimate at first order,
  a sixteenth at second);
* the worst sample's error per sensor is set against the white noise per sample of a stated
  grade (ARW·√h for an increment, ARW/√h for a mean rate), and the largest step tried that keeps
  it under the stated fraction is named;
* at rest (the last 0.5 s, the table settled) a deterministic IMU's outputs do not depend on the
  step. Where they do (noise on, or a pulse output whose quantisation remainder depends on the
  step) the differences are not coupling error alone, and no step is recommended: set the noise
  parameters to zero, or check the IMU in an increment or rate output mode.

A counts output is not set against the noise (its quantisation, not the white noise, is what a
sample carries).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from components.errors import UserError
from components.model.noise import grade as noise_grade
from fmus.turntable import CONTROL_RATE_HZ
from orchestrator.errors import OrchestratorError
from orchestrator.fmu_units import load_fmu_unit
from orchestrator.master import simulate
from orchestrator.roles import check_unit, get_role
from orchestrator.system import Connection, System, UnitSpec
from orchestrator.verify import on_grid

SERVO_PERIOD = 1.0 / CONTROL_RATE_HZ  # the builtin turntable's controller period [s]
STEPS_TRIED = (0.002, 0.005, 0.01, 0.02)
AT_REST = 0.5                    # the last 0.5 s: the table has settled
ROUNDING = 1e-10                 # a difference at rest below this share of the output is rounding
# the index: outer 60 deg, middle and inner 90 deg at once from rest, then settle
INDEX = {"outer.angle_cmd": math.pi / 3, "middle.angle_cmd": math.pi / 2, "inner.angle_cmd": math.pi / 2}
DURATION = 3.0
OPTIONAL_INPUTS = {"alpha": "angular acceleration (alpha)",
                   "omega_int": "step integral of the rate (omega_int)",
                   "f_int": "step integral of the specific force (f_int)"}


@dataclass
class StepCost:
    step: float
    gyro_error: float        # worst sample's coupling error, gyro outputs (role SI unit)
    acc_error: float
    gyro_ratio: float        # / the grade's white noise per sample (nan for counts)
    acc_ratio: float

    @property
    def worst_ratio(self) -> float:
        r = [x for x in (self.gyro_ratio, self.acc_ratio) if math.isfinite(x)]
        return max(r) if r else math.nan


@dataclass
class InterfaceCost:
    fmu: str
    grade: str
    fraction: float
    missing: list[str]
    gyro_unit: str
    acc_unit: str
    steps: list[StepCost] = field(default_factory=list)
    reference: StepCost | None = None       # our IMU, every input connected, at the chosen step
    same_inputs: StepCost | None = None     # our IMU given only the inputs this one takes
    chosen: float = 0.0
    converges: bool = True     # at rest, every step's outputs agree with the reference's

    @property
    def recommended(self) -> float | None:
        ok = [s.step for s in self.steps if s.worst_ratio <= self.fraction]
        return max(ok) if ok and self.converges else None

    def report(self) -> str:
        taken = "every input the role offers" if not self.missing else \
            "no " + ", ".join(OPTIONAL_INPUTS[m] for m in self.missing)
        lines = [f"interface cost: the coupling error of the outputs while the table indexes "
                 f"(outer 60 deg, middle and inner 90 deg at once), against {self.grade}-grade "
                 f"white noise per sample; the IMU takes {taken}",
                 f"  {'step [s]':>9s} {'gyro err':>10s} {'x noise':>8s} {'acc err':>10s} {'x noise':>8s}"]
        for s in self.steps:
            mark = "  <- chosen" if s.step == self.chosen else ""
            lines.append(f"  {s.step:9.4g} {s.gyro_error:10.2e} {_ratio(s.gyro_ratio):>8s} "
                         f"{s.acc_error:10.2e} {_ratio(s.acc_ratio):>8s}{mark}")
        lines.append(f"  (errors: worst sample, gyro in {self.gyro_unit}, accelerometer in {self.acc_unit}; "
                     f"against a run at the table's servo period {SERVO_PERIOD:g} s)")
        for label, r in (("our IMU (increments) with every input", self.reference),
                         ("our IMU (increments) with only the inputs this one takes", self.same_inputs)):
            if r is not None:
                lines.append(f"  {label} at {r.step:g} s: gyro {r.gyro_error:.2e} rad "
                             f"({_ratio(r.gyro_ratio)} x noise), accelerometer {r.acc_error:.2e} m/s "
                             f"({_ratio(r.acc_ratio)} x noise)")
        if not self.converges:
            lines.append("  the outputs change with the step while the table is at rest, so the "
                         "differences are not coupling error alone (noise on? set its parameters "
                         "to 0 with --parameter); no step recommended")
        elif self.recommended is None:
            lines.append(f"  no step tried keeps the error below {self.fraction:g} x the noise")
        else:
            lines.append(f"  largest step tried that keeps the worst sample below {self.fraction:g} x "
                         f"the noise per sample: {self.recommended:g} s")
        return "\n".join(lines)


def _ratio(x: float) -> str:
    return "n/a" if not math.isfinite(x) else f"{x:.3g}"


def _system(imu_fmu: str, mapping: dict, role_options: dict, parameters: dict, inputs: list[str],
            step: float) -> System:
    conns = [Connection(f"table.plate.{v}", f"imu.{v}") for v in ["omega", "f", *inputs]]
    params = dict(parameters)
    if {"omega_int", "f_int"} <= set(inputs):
        params.setdefault("input_integrals", 1)
    return System(
        name="interface_cost", step=step, start=0.0, stop=DURATION, algorithm="gauss-seidel",
        order=["table", "imu"],
        units=[UnitSpec("table", fmu="builtin:turntable", role="turntable", parameters=dict(INDEX)),
               UnitSpec("imu", fmu=imu_fmu, role="imu", role_options=dict(role_options),
                        parameters=params, mapping=dict(mapping))],
        connections=conns, record=["imu.gyro", "imu.acc"], base_dir=Path.cwd())


def _worst(rec_h, rec_ref, block: int, how: list[str]) -> tuple[np.ndarray, bool]:
    """The worst difference per output over the run, and whether the outputs agree at rest."""
    a = on_grid(rec_h, 1, how)
    b = on_grid(rec_ref, block, how)
    n = min(a.shape[0], b.shape[0])
    diff = np.abs(a[1:n] - b[1:n])
    rest = rec_h.time[1:n] >= DURATION - AT_REST
    scale = np.max(np.abs(a[1:n][rest]), axis=0)
    return np.max(diff, axis=0), bool(np.all(np.max(diff[rest], axis=0) <= ROUNDING * scale))


def check_cost_inputs(step: float, grade: str, fraction: float):
    """The interface cost's own options, refused before anything runs: the grade's noise model."""
    if not (0 < fraction):
        raise UserError(f"noise fraction {fraction}: expected a positive number")
    multiple = step / SERVO_PERIOD
    if step > AT_REST / 5:
        raise UserError(f"step {step} s: the interface cost compares the outputs over the last {AT_REST} s of a "
                        f"{DURATION} s index, which needs steps of at most {AT_REST / 5:g} s")
    if step <= 0 or abs(multiple - round(multiple)) > 1e-9 * multiple:
        raise UserError(f"step {step} s: the interface cost drives our turntable, whose steps are "
                        f"whole multiples of its servo period {SERVO_PERIOD} s")
    try:
        return noise_grade(grade)
    except KeyError:
        raise UserError(f"grade {grade!r}: expected navigation or tactical") from None


def interface_cost(imu_fmu: str | Path, mapping: dict | None = None, role_options: dict | None = None,
                   parameters: dict | None = None, step: float = 0.005, grade: str = "navigation",
                   fraction: float = 0.1) -> InterfaceCost:
    """The coupling error of *imu_fmu* (in role ``imu`` through *mapping* and *role_options*) at
    *step* and at :data:`STEPS_TRIED`, set against *grade*'s white noise per sample."""
    mapping, role_options, parameters = dict(mapping or {}), dict(role_options or {}), dict(parameters or {})
    noise = check_cost_inputs(step, grade, fraction)
    role = get_role("imu", **role_options)
    unit = load_fmu_unit("imu", Path(imu_fmu))
    bindings = check_unit(unit, role, mapping).bindings
    inputs = [v for v in OPTIONAL_INPUTS if f"{v}.x" in bindings]
    missing = [v for v in OPTIONAL_INPUTS if v not in inputs]
    gyro_var, acc_var = role.variable("gyro.x"), role.variable("acc.x")
    result = InterfaceCost(str(imu_fmu), grade, fraction, missing, gyro_var.unit, acc_var.unit,
                           chosen=step)

    def run(fmu, ins, h, params):
        try:
            return simulate(_system(str(fmu), mapping if fmu == imu_fmu else {},
                                    role_options if fmu == imu_fmu else {}, params, ins, h), progress=False)
        except OrchestratorError as e:
            raise UserError(f"interface cost of {imu_fmu} at step {h} s: {e}") from None

    def cost(rec, ref, h, kinds) -> StepCost:
        how = [get_role("imu", gyro_output=kinds[0]).variable("gyro.x").aggregate] * 3 \
            + [get_role("imu", acc_output=kinds[1]).variable("acc.x").aggregate] * 3
        worst, still = _worst(rec, ref, int(round(h / SERVO_PERIOD)), how)
        result.converges &= still
        g, a = float(worst[:3].max()), float(worst[3:].max())
        sg = _sample_noise(noise.channels[0].white, h, kinds[0])
        sa = _sample_noise(noise.channels[3].white, h, kinds[1])
        return StepCost(h, g, a, g / sg if sg else math.nan, a / sa if sa else math.nan)

    kinds = (role_options.get("gyro_output", "increment"), role_options.get("acc_output", "increment"))
    ref = run(imu_fmu, inputs, SERVO_PERIOD, parameters)
    for h in sorted({*STEPS_TRIED, step}):
        result.steps.append(cost(run(imu_fmu, inputs, h, parameters), ref, h, kinds))
    from fmus.build import fmu_path

    ours = fmu_path("imu", 2)
    ours_ref = run(ours, list(OPTIONAL_INPUTS), SERVO_PERIOD, {})
    result.reference = cost(run(ours, list(OPTIONAL_INPUTS), step, {}), ours_ref, step,
                            ("increment", "increment"))
    if missing:
        # what the interface alone costs: our integration, fed what this IMU is fed
        ours_same_ref = run(ours, inputs, SERVO_PERIOD, {})
        result.same_inputs = cost(run(ours, inputs, step, {}), ours_same_ref, step,
                                  ("increment", "increment"))
    return result


def _sample_noise(white: float, h: float, kind: str) -> float:
    """White noise per sample of an output kind at step *h* (0 where it is not comparable)."""
    if kind == "increment":
        return white * math.sqrt(h)
    if kind in ("rate", "specific_force"):
        return white / math.sqrt(h)
    return 0.0
