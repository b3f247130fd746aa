"""The two plant roles of architecture.md §3 (``turntable`` and ``imu``) and the ``builtin:`` scheme
that names the project's own FMUs in system files, registered with the orchestrator through its
``orchestrator.plugins`` entry point (so a system file that names them runs without importing
``components`` first)."""
from __future__ import annotations

from orchestrator.fmu_resolver import register_fmu_resolver
from orchestrator.roles import Role, RoleVariable, register_role

DEFAULT_AXES = ("outer", "middle", "inner")


def turntable_role(axes=DEFAULT_AXES) -> Role:
    """``axes``: the table's axes, a list of names or one string ("outer", "outer,inner")."""
    if isinstance(axes, str):
        axes = axes.replace(",", " ").split()
    # the names are the table's own (outer/middle/inner for ours, yaw/pitch for another's)
    if not axes or len(set(axes)) != len(axes) or not all(isinstance(a, str) and a.isidentifier() for a in axes):
        raise ValueError(f"axes {list(axes)!r}: expected distinct axis names, e.g. {list(DEFAULT_AXES)}")
    v = []
    for a in axes:
        v += [
            RoleVariable(f"{a}.mode", "input", "Integer", None, True, "0 position, 1 rate"),
            RoleVariable(f"{a}.angle_cmd", "input", "Real", "rad"),
            RoleVariable(f"{a}.rate_cmd", "input", "Real", "rad/s"),
            RoleVariable(f"{a}.angle", "output", "Real", "rad", True, "encoder angle"),
            RoleVariable(f"{a}.rate", "output", "Real", "rad/s"),
        ]
    for c in "xyz":
        v.append(RoleVariable(f"plate.omega.{c}", "output", "Real", "rad/s"))
    for c in "xyz":
        v.append(RoleVariable(f"plate.alpha.{c}", "output", "Real", "rad/s2"))
    for c in "xyz":
        v.append(RoleVariable(f"plate.f.{c}", "output", "Real", "m/s2"))
    for c in "wxyz":
        v.append(RoleVariable(f"plate.q.{c}", "output", "Real", "1"))
    # integrals over the communication step just ended (for exact IMU increments when the
    # motion inside a step is not a polynomial); a table without them still plugs in
    for c in "xyz":
        v.append(RoleVariable(f"plate.omega_int.{c}", "output", "Real", "rad", False))
    for c in "xyz":
        v.append(RoleVariable(f"plate.f_int.{c}", "output", "Real", "m/s", False))
    return Role("turntable", v, "servo, gimbal chain, base and Earth; plate motion in plate axes")


GYRO_KINDS = {"increment": "rad", "rate": "rad/s", "counts": "1"}
ACC_KINDS = {"increment": "m/s", "specific_force": "m/s2", "rate": "m/s2", "counts": "1"}
OUTPUT_CODES = {"increment": 0, "rate": 1, "specific_force": 1, "counts": 2}  # fmus/imu gyro.output


def imu_role(gyro_output: str = "increment", acc_output: str = "increment") -> Role:
    """``gyro_output`` / ``acc_output``: the kind of output the unit gives (its binding), which
    fixes the SI unit its outputs are converted to (as in measurement-log.md)."""
    if gyro_output not in GYRO_KINDS:
        raise ValueError(f"gyro_output {gyro_output!r}: expected one of {sorted(GYRO_KINDS)}")
    if acc_output not in ACC_KINDS:
        raise ValueError(f"acc_output {acc_output!r}: expected one of {sorted(ACC_KINDS)}")
    v = [RoleVariable(f"omega.{c}", "input", "Real", "rad/s") for c in "xyz"]
    v += [RoleVariable(f"f.{c}", "input", "Real", "m/s2") for c in "xyz"]
    v += [RoleVariable(f"alpha.{c}", "input", "Real", "rad/s2", False) for c in "xyz"]
    v += [RoleVariable(f"omega_int.{c}", "input", "Real", "rad", False) for c in "xyz"]
    v += [RoleVariable(f"f_int.{c}", "input", "Real", "m/s", False) for c in "xyz"]
    v.append(RoleVariable("temperature_env", "input", "Real", "degC", False))
    agg = {"increment": "sum", "counts": "sum", "rate": "mean", "specific_force": "mean"}

    def hint(key: str, kind: str, kinds: dict) -> str:
        others = ", ".join(f"{k!r} [{u}]" for k, u in kinds.items() if k != kind)
        return (f"the role takes {key} = {kind!r} [{kinds[kind]}] here; for an output of another kind set "
                f"{key} in the unit's role_options: {others}")

    v += [RoleVariable(f"gyro.{c}", "output", "Real", GYRO_KINDS[gyro_output], aggregate=agg[gyro_output],
                       accepts_integer=gyro_output == "counts", unit_hint=hint("gyro_output", gyro_output, GYRO_KINDS))
          for c in "xyz"]
    v += [RoleVariable(f"acc.{c}", "output", "Real", ACC_KINDS[acc_output], aggregate=agg[acc_output],
                       accepts_integer=acc_output == "counts", unit_hint=hint("acc_output", acc_output, ACC_KINDS))
          for c in "xyz"]
    v.append(RoleVariable("temperature", "output", "Real", "degC", False))
    # our IMU FMU picks its output kind by parameter; a supplier's without them is left alone
    settings = {"gyro.output": OUTPUT_CODES[gyro_output], "acc.output": OUTPUT_CODES[acc_output]}
    return Role("imu", v, "sensor physics, error effects, noise; outputs per interval", settings)


def _builtin(name: str):
    from fmus.build import MODELS, fmu_path

    fmi = 2
    if name.endswith("@3"):
        name, fmi = name[:-2], 3
    if name not in MODELS:
        raise ValueError(f"builtin:{name}: expected one of {', '.join('builtin:' + m for m in MODELS)}")
    return fmu_path(name, fmi)


def register() -> None:
    """The ``orchestrator.plugins`` entry point (pyproject.toml): the two roles and ``builtin:``."""
    register_role("turntable", turntable_role)
    register_role("imu", imu_role)
    register_fmu_resolver("builtin", _builtin)
