"""A timed attitude sequence: the simplest table commander (the calibration controller of
components.control.controller walks full schedules and waits for the table to settle)."""
from __future__ import annotations

from orchestrator.component import Component, Var

AXES = ("outer", "middle", "inner")


class AttitudeSequence(Component):
    """Commands the table to the attitudes of ``sequence`` (a list of (t_start, outer, middle,
    inner) in rad, t_start in s), position mode, zero rate feed-forward."""

    variables = [Var(f"{a}.angle_cmd", "output", unit="rad") for a in AXES] + \
        [Var(f"{a}.mode", "output", "Integer", 0) for a in AXES] + \
        [Var(f"{a}.rate_cmd", "output", unit="rad/s") for a in AXES]

    def __init__(self, name: str, sequence: list | None = None) -> None:
        super().__init__(name)
        self.sequence = sorted(sequence or [(0.0, 0.0, 0.0, 0.0)])

    def _apply(self, t: float) -> None:
        current = self.sequence[0]
        for entry in self.sequence:
            if entry[0] <= t + 1e-12:
                current = entry
        for a, angle in zip(AXES, current[1:]):
            self[f"{a}.angle_cmd"] = angle

    def initialize(self, t0: float) -> None:
        self._apply(t0)

    def do_step(self, t: float, h: float) -> None:
        # a sampled commander: the command decided at t holds over [t, t + h), so a unit stepped
        # after this one (Gauss-Seidel) meets each attitude change at its scheduled time
        self._apply(t)
