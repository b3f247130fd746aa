"""A supplier's IMU FMU (tests/fmus/supplier_imu: own names, deg/s and g, mean-rate outputs, no
angular-acceleration input) plugs into role ``imu`` through a name mapping in the system file,
and the orchestrator's unit conversion makes its recorded outputs those of our builtin IMU
configured alike.

The motion: angular rate piecewise linear in time (constant angular acceleration within each
communication step, changing every few steps), constant specific force. Both sensors are
compared with the closed form of their sensor model, (1 + sf) * mean + bias, where the mean over
a step of a linear rate is the mean of its end values.

The convention both follow (inputs set before doStep(t, h) are the values at t + h) is the
same, with one known difference: our IMU interpolates omega between knots as a cubic Hermite
with alpha as the derivative at each knot. Its mean over [t_j, t_j+1] is
(w_j + w_j+1)/2 + h (alpha_j - alpha_j+1)/12, so where alpha changes between two knots it differs
from the linear mean by that term (a knot holds one alpha, the profile has a kink there). With
alpha connected that difference is asserted exactly; without, the two agree to 1e-12.
For the same reason the acceleration is kept parallel to the specific force: our IMU takes
f' = -omega x f at a knot (a constant vector seen from the rotating frame), which is then the
same at every knot and drops out of the mean."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from components.cli import main as cli_main
from fmus.build import fmu_path
from orchestrator.component import Component, Var
from orchestrator.errors import OrchestratorError
from orchestrator.loader import load_system
from orchestrator.master import simulate

H = 0.005
N = 40
DEG = math.pi / 180
G0 = 9.80665
W0 = np.array([0.3, -0.2, 0.5])                       # rad/s at t = 0
F = G0 * np.array([0.21, -0.32, 0.93])                # specific force, m/s2, constant
FHAT = F / np.linalg.norm(F)
BLOCK = 4                                             # steps per acceleration segment
S = [0.8, 0.8, -1.5, 0.0, 2.0, -0.6, -0.6, 1.1, 0.0, 3.0]   # rad/s2 along FHAT, per segment

GYRO_BIAS_DEG = np.array([0.5, -0.25, 1.0])           # deg/s
GYRO_SF = np.array([1e-3, -2e-3, 5e-4])
ACC_BIAS_G = np.array([2e-3, -1e-3, 5e-3])            # g
ACC_SF = np.array([3e-4, -1e-4, 2e-4])
AX = "xyz"


def accel(j: int) -> np.ndarray:
    """Angular acceleration over step j, [t_j, t_j+1]."""
    return S[(j // BLOCK) % len(S)] * FHAT


class MotionSource(Component):
    """omega(t) piecewise linear (acceleration accel(j) over step j), alpha(t_j) = accel(j)
    (the acceleration of the step that starts there), f constant. Outputs at t + h after
    do_step(t, h), so a unit stepped after it (Gauss-Seidel) gets the values at the end of its
    own step."""

    variables = ([Var(f"omega.{c}", "output", unit="rad/s") for c in AX]
                 + [Var(f"alpha.{c}", "output", unit="rad/s2") for c in AX]
                 + [Var(f"f.{c}", "output", unit="m/s2") for c in AX])

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.j = 0
        self.w = W0.copy()

    def _publish(self) -> None:
        a = accel(self.j)
        for i, c in enumerate(AX):
            self[f"omega.{c}"] = float(self.w[i])
            self[f"alpha.{c}"] = float(a[i])
            self[f"f.{c}"] = float(F[i])

    def initialize(self, t0: float) -> None:
        self._publish()

    def do_step(self, t: float, h: float) -> None:
        self.w = self.w + accel(self.j) * h
        self.j += 1
        self._publish()


def omega_knots() -> np.ndarray:
    """omega at t_0 .. t_N, as the source computes it."""
    w = [W0.copy()]
    for j in range(N):
        w.append(w[-1] + accel(j) * H)
    return np.array(w)


MAPPING = {**{f"omega.{c}": f"AngularRate_{c.upper()}" for c in AX},
           **{f"f.{c}": f"Accel_{c.upper()}" for c in AX},
           **{f"gyro.{c}": f"GyroRate_{c.upper()}" for c in AX},
           **{f"acc.{c}": f"Accel_Out_{c.upper()}" for c in AX}}


@pytest.fixture(scope="module")
def supplier_fmu() -> Path:
    return fmu_path(Path(__file__).parent / "fmus" / "supplier_imu", 2)


def _toml(supplier: Path, alpha: bool) -> str:
    mapping = ", ".join(f'"{k}" = "{v}"' for k, v in MAPPING.items())
    sup_par = "\n".join([f'GyroBias_{c.upper()} = {float(GYRO_BIAS_DEG[i])!r}' for i, c in enumerate(AX)]
                        + [f'GyroSF_{c.upper()} = {float(GYRO_SF[i])!r}' for i, c in enumerate(AX)]
                        + [f'AccBias_{c.upper()} = {float(ACC_BIAS_G[i])!r}' for i, c in enumerate(AX)]
                        + [f'AccSF_{c.upper()} = {float(ACC_SF[i])!r}' for i, c in enumerate(AX)])
    # our IMU, the same coefficients in SI
    ref_par = "\n".join([f'"gyro.bias.{c}" = {float(GYRO_BIAS_DEG[i] * DEG)!r}' for i, c in enumerate(AX)]
                        + [f'"gyro.sf.{c}" = {float(GYRO_SF[i])!r}' for i, c in enumerate(AX)]
                        + [f'"acc.bias.{c}" = {float(ACC_BIAS_G[i] * G0)!r}' for i, c in enumerate(AX)]
                        + [f'"acc.sf.{c}" = {float(ACC_SF[i])!r}' for i, c in enumerate(AX)]
                        + ['"gyro.output" = 1', '"acc.output" = 1'])
    conns = "\n".join(f'[[connections]]\nfrom = "motion.{a}"\nto = "{u}.{a}"'
                      for u in ("sup", "ref") for a in ("omega", "f"))
    if alpha:
        conns += '\n[[connections]]\nfrom = "motion.alpha"\nto = "ref.alpha"'
    return f"""
[system]
name = "supplier"
step = {H}
stop = {N * H!r}

[units.motion]
component = "test_supplier_imu:MotionSource"

[units.sup]
fmu = "{supplier}"
role = "imu"
role_options = {{ gyro_output = "rate", acc_output = "specific_force" }}
mapping = {{ {mapping} }}
[units.sup.parameters]
{sup_par}

[units.ref]
fmu = "builtin:imu"
role = "imu"
role_options = {{ gyro_output = "rate", acc_output = "specific_force" }}
[units.ref.parameters]
{ref_par}

{conns}

[record]
signals = ["sup.gyro", "sup.acc", "ref.gyro", "ref.acc", "motion.omega"]
"""


def _block(rec, unit: str, sensor: str) -> np.ndarray:
    return np.column_stack([rec[f"{unit}.{sensor}.{c}"] for c in AX])


@pytest.mark.parametrize("alpha", [False, True], ids=["no-alpha", "alpha"])
def test_supplier_matches_builtin_imu(supplier_fmu, tmp_path, alpha):
    f = tmp_path / "supplier.toml"
    f.write_text(_toml(supplier_fmu, alpha))
    rec = simulate(load_system(f))
    assert rec.rows == N + 1 and rec.complete

    w = omega_knots()
    np.testing.assert_allclose(_block(rec, "motion", "omega"), w, rtol=0, atol=0)
    # physics, per interval j (row j + 1): (1 + sf) * mean + bias, in SI
    gyro = (1 + GYRO_SF) * 0.5 * (w[:-1] + w[1:]) + GYRO_BIAS_DEG * DEG
    acc = np.tile((1 + ACC_SF) * F + ACC_BIAS_G * G0, (N, 1))
    sup_g, sup_a = _block(rec, "sup", "gyro"), _block(rec, "sup", "acc")
    ref_g, ref_a = _block(rec, "ref", "gyro"), _block(rec, "ref", "acc")
    # both report zero before the first interval
    for x in (sup_g, sup_a, ref_g, ref_a):
        np.testing.assert_array_equal(x[0], 0.0)

    def close(a, b):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())

    close(sup_g[1:], gyro)
    close(sup_a[1:], acc)
    close(ref_a[1:], acc)
    close(ref_a, sup_a)
    if not alpha:
        close(ref_g, sup_g)
        close(ref_g[1:], gyro)
    else:
        # the Hermite term where alpha differs at the two knots of an interval
        a = np.array([accel(j) for j in range(N + 1)])
        hermite = (1 + GYRO_SF) * H * (a[:-1] - a[1:]) / 12
        assert np.count_nonzero(np.abs(hermite).max(axis=1)) >= 5  # kinks are exercised
        close(ref_g[1:], gyro + hermite)
        np.testing.assert_allclose(ref_g[1:] - sup_g[1:], hermite, rtol=0,
                                   atol=1e-12 * np.abs(gyro).max())


def test_check_fmu_accepts_with_mapping(supplier_fmu, capsys):
    args = ["check-fmu", str(supplier_fmu), "--role", "imu"]
    args += [x for k, v in MAPPING.items() for x in ("--map", f"{k}={v}")]
    args += ["--option", "gyro_output=rate", "--option", "acc_output=specific_force"]
    rc = cli_main(args)
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "verdict: ACCEPTED" in out
    assert "unit candidate against role imu: conforms" in out
    # the conversions come from the FMU's own unit definitions
    assert f"AngularRate_X: deg/s converted to rad/s (x {DEG:.12g})" in out
    assert f"Accel_Out_Z: g converted to m/s2 (x {G0:.12g})" in out
    assert "optional input alpha.x not offered" in out


def test_check_fmu_refuses_without_mapping(supplier_fmu, capsys):
    rc = cli_main(["check-fmu", str(supplier_fmu), "--role", "imu", "--option", "gyro_output=rate",
                   "--option", "acc_output=specific_force"])
    out = capsys.readouterr().out
    assert rc == 1
    assert "verdict: REFUSED" in out
    assert "12 problem(s)" in out
    for c in AX:
        assert f"missing input omega.{c} [rad/s, Real]" in out
        assert f"missing input f.{c} [m/s2, Real]" in out
        assert f"missing output gyro.{c} [rad/s, Real]" in out
        assert f"missing output acc.{c} [m/s2, Real]" in out


@pytest.mark.parametrize("source, target, said", [
    ("motion.f.x", "sup.omega.x", "motion.f.x is in m/s2 but sup.omega.x takes rad/s"),
    ("motion.omega.x", "sup.f.x", "motion.omega.x is in rad/s but sup.f.x takes m/s2"),
])
def test_a_wire_into_a_role_name_of_another_quantity_is_refused(supplier_fmu, tmp_path, source, target, said):
    """A connection whose target is reached through the supplier's mapping converts that end
    into the role's unit; what the source puts in must be the same quantity (a specific force
    wired into a rate input ran, the gyro reading 9.8 rad/s)."""
    text = _toml(supplier_fmu, False).replace('from = "motion.omega"\nto = "sup.omega"',
                                              f'from = "{source}"\nto = "{target}"', 1)
    assert source in text
    f = tmp_path / "wrong.toml"
    f.write_text(text)
    with pytest.raises(OrchestratorError, match=said):
        simulate(load_system(f))
