"""The calibration controller: a Python unit that walks a schedule (components.control.schedule)
against any turntable that fills the ``turntable`` role.

It uses only the role's per-axis variables: it drives ``<axis>.mode``, ``<axis>.angle_cmd``,
``<axis>.rate_cmd`` and reads ``<axis>.angle`` (encoder) and ``<axis>.rate``; the axis names
come from the configuration (``axes``), so a two-axis table with its own names works too.

Behaviour (sampled at the controller's own step, e.g. 10 Hz = step_multiple 20 at 5 ms; the
command decided at t holds over [t, t + h)):

* **index**: position mode, rate feed-forward 0, target rounded to a whole encoder count
  (``counts_per_rev``, 2^24 by default; 0 = no rounding) so that a settled table reads exactly
  the command; each axis goes the shortest way round unless the step says ``absolute``. The step
  ends when the table is **settled**: on every axis |angle - command| <= settle_tol and
  |rate| <= settle_rate_tol, at every controller sample over ``settle_hold`` seconds. Not
  settled within ``index_timeout``: :class:`ScheduleFault` naming the step.
* **dwell**: hold for the duration (rounded up to whole controller steps).
* **rotate**: rate mode at the rate until the next controller sample would fall inside the
  braking distance (rate^2 / 2 acc_max); for one controller step a reduced rate is commanded
  that leaves about the braking distance, then position mode to the exact target start + n
  turns (in counts: exact), and wait until settled. ``acc_max`` [rad/s^2] is the table's
  acceleration limit as the controller assumes it (per axis; a scenario reads it from the FMU);
  a wrong value costs a less smooth stop, not accuracy.
* **rate**: rate mode for the duration, then rate 0 until |rate| <= settle_rate_tol, then
  position mode on the encoder reading where it stopped, and wait until settled.

Outputs ``segment`` (Integer: index into :attr:`labels`) and ``done`` (1 when the schedule is
finished; the commands then hold). :attr:`events` lists each step's start and end time.
Deterministic: decisions depend only on the inputs and integer step counts.
"""
from __future__ import annotations

import math

from components.control.schedule import (
    AXIS_POSITIONS,
    COUNTS_PER_REV,
    DEG,
    Dwell,
    Index,
    Rate,
    Rotate,
    Schedule,
    load_schedule,
    schedule_from_dict,
)
from components.errors import ScheduleError, ScheduleFault
from orchestrator.component import Component, Var

TWO_PI = 2.0 * math.pi


class CalibrationController(Component):
    """Walks ``schedule`` (a :class:`Schedule`, a ready-made name or path, or a parsed dict).

    Config: ``axes`` (role axis names, base to plate), ``counts_per_rev`` (encoder counts per
    revolution the commands are rounded to; 0 = none), ``acc_max`` (table acceleration limit
    [rad/s^2]: one number or one per axis), ``overrides`` (schedule parameter values)."""

    feedthrough: dict = {}

    def __init__(self, name: str, schedule, axes=("outer", "middle", "inner"),
                 counts_per_rev: int = COUNTS_PER_REV, acc_max=200 * DEG, overrides: dict | None = None,
                 stop_when_done: bool = False, rate_max=None) -> None:
        self.stop_when_done = stop_when_done  # end the co-simulation when the schedule is done
        if isinstance(schedule, Schedule):
            if overrides:
                raise ScheduleError("overrides apply to a schedule loaded by name, path or dict")
            self.schedule = schedule
        elif isinstance(schedule, dict):
            self.schedule = schedule_from_dict(schedule, f"units.{name}.config.schedule", overrides)
        else:
            self.schedule = load_schedule(schedule, overrides)
        self.axes = [str(a) for a in axes]
        if not self.axes or len(set(self.axes)) != len(self.axes):
            raise ValueError(f"controller {name}: axes {axes!r}: expected distinct axis names")
        n = len(self.axes)
        if isinstance(acc_max, (int, float)):
            acc_max = [float(acc_max)] * n
        acc_max = [float(a) for a in acc_max]
        if len(acc_max) != n or not all(a > 0 for a in acc_max):
            raise ValueError(f"controller {name}: acc_max {acc_max!r}: expected a positive value or one per axis")
        self.acc_max = acc_max
        # the table's rate limit per axis [rad/s] when known: a rotation faster than it would be
        # run at the limit, its segment labelled with the rate the schedule asked for
        self.rate_max = [float(r) for r in ([rate_max] * n if isinstance(rate_max, (int, float)) else rate_max)] \
            if rate_max is not None else None
        if not isinstance(counts_per_rev, int) or counts_per_rev < 0:
            raise ValueError(f"controller {name}: counts_per_rev {counts_per_rev!r}: expected an integer >= 0")
        self.counts_per_rev = counts_per_rev
        self.q = TWO_PI / counts_per_rev if counts_per_rev else 0.0
        self.variables = (
            [Var(f"{a}.mode", "output", "Integer", 0, None, "0 position, 1 rate") for a in self.axes]
            + [Var(f"{a}.angle_cmd", "output", "Real", 0.0, "rad") for a in self.axes]
            + [Var(f"{a}.rate_cmd", "output", "Real", 0.0, "rad/s") for a in self.axes]
            + [Var(f"{a}.angle", "input", "Real", 0.0, "rad") for a in self.axes]
            + [Var(f"{a}.rate", "input", "Real", 0.0, "rad/s") for a in self.axes]
            + [Var("segment", "output", "Integer", 0, None, "index into the controller's labels"),
               Var("done", "output", "Integer", 0, None, "1 when the schedule is finished")])
        super().__init__(name)
        self._check_schedule()
        self.labels: list[str] = self.schedule.labels
        self._label_index = {lab: i for i, lab in enumerate(self.labels)}
        self.events: list[dict] = []
        self.finished = False
        self._reset()

    # ----------------------------------------------------------------- setup
    def _check_schedule(self) -> None:
        n = len(self.axes)
        src = self.schedule.source
        for s in self.schedule.steps:
            if isinstance(s, Index) and len(s.angles) != n:
                raise ScheduleError(f"{src}: step {s.origin} (index): {len(s.angles)} angles for a table with "
                                    f"{n} axes ({', '.join(self.axes)}): expected {n}")
            if isinstance(s, (Rotate, Rate)):
                k = self._axis_index(s)
                if self.rate_max is not None and abs(s.rate) > self.rate_max[k] * (1 + 1e-12):
                    raise ScheduleError(f"{src}: step {s.origin} ({s.kind}): rate {s.rate / DEG:g} deg/s, beyond the "
                                        f"table's {self.axes[k]} axis limit of {self.rate_max[k] / DEG:g} deg/s (it would "
                                        "turn at the limit under this step's label)")

    def _axis_index(self, s) -> int:
        a, n = s.axis, len(self.axes)
        if isinstance(a, str) and a in self.axes:
            return self.axes.index(a)
        if isinstance(a, str) and a in AXIS_POSITIONS and AXIS_POSITIONS.index(a) < n:
            return AXIS_POSITIONS.index(a)
        if isinstance(a, int) and 0 <= a < n:
            return a
        raise ScheduleError(f"{self.schedule.source}: step {s.origin} ({s.kind}): key 'axis' = {a!r}: expected "
                            f"one of the table's axes {self.axes} or a position "
                            f"{list(AXIS_POSITIONS[:n])} / 0..{n - 1}")

    def _reset(self) -> None:
        self._t0 = None
        self._period = None
        self._i = -1
        self._cmd = [0.0] * len(self.axes)       # commanded angle [rad]
        self._counts = [0] * len(self.axes)      # the same in counts (when rounding)
        self._phase = ""
        self._enter_tick = 0
        self._phase_tick = 0
        self._hold_since = None
        self._end_tick = 0

    def provenance(self) -> dict:
        s = self.schedule
        return {**super().provenance(), "schedule": s.name, "schedule_source": s.source,
                "schedule_parameters": s.parameters, "axes": self.axes, "counts_per_rev": self.counts_per_rev,
                "acc_max": self.acc_max}

    # ----------------------------------------------------------------- helpers
    def _to_counts(self, angle: float) -> int:
        return int(round(angle / self.q))

    def _set_cmd(self, k: int, angle: float | None = None, counts: int | None = None) -> None:
        if self.q:
            if counts is None:
                counts = self._to_counts(angle)
            self._counts[k] = counts
            self._cmd[k] = counts * self.q
        else:
            self._cmd[k] = float(angle)
        self[f"{self.axes[k]}.angle_cmd"] = self._cmd[k]

    def _position(self, k: int) -> None:
        a = self.axes[k]
        self[f"{a}.mode"] = 0
        self[f"{a}.rate_cmd"] = 0.0
        self[f"{a}.angle_cmd"] = self._cmd[k]

    def _ticks(self, seconds: float) -> int:
        return max(0, math.ceil(seconds / self._period - 1e-9))

    def _state(self) -> str:
        parts = []
        for k, a in enumerate(self.axes):
            parts.append(f"{a}: angle - command = {self[f'{a}.angle'] - self._cmd[k]:.3e} rad, "
                         f"rate = {self[f'{a}.rate']:.3e} rad/s")
        st = self.schedule.settings
        return "; ".join(parts) + f" (tolerances {st.settle_tol:.3e} rad, {st.settle_rate_tol:.3e} rad/s)"

    def _fault(self, s, t: float, what: str) -> ScheduleFault:
        return ScheduleFault(f"{self.schedule.source}: step {s.origin} ({s.kind}, label {s.label!r}) at "
                             f"t = {t:.6g} s: {what}; {self._state()}")

    def _settled_now(self) -> bool:
        st = self.schedule.settings
        return all(abs(self[f"{a}.angle"] - self._cmd[k]) <= st.settle_tol and
                   abs(self[f"{a}.rate"]) <= st.settle_rate_tol for k, a in enumerate(self.axes))

    def _settled(self, tick: int) -> bool:
        """Settled at every sample over the hold time up to this tick."""
        if not self._settled_now():
            self._hold_since = None
            return False
        if self._hold_since is None:
            self._hold_since = tick
        return tick - self._hold_since >= self._ticks(self.schedule.settings.settle_hold)

    def _wait_settled(self, s, tick: int, t: float, since: int, limit: float) -> bool:
        if self._settled(tick):
            return True
        if (tick - since) * self._period > limit + 1e-9:
            raise self._fault(s, t, f"the table did not settle within {limit:g} s")
        return False

    # ----------------------------------------------------------------- steps
    def _enter(self, tick: int, t: float) -> None:
        s = self.schedule.steps[self._i]
        self._enter_tick = self._phase_tick = tick
        self._hold_since = None
        self["segment"] = self._label_index[s.segment_labels[0]]
        self.events.append({"step": s.origin, "kind": s.kind, "label": s.segment_labels[0], "start": t})
        if isinstance(s, Index):
            for k, target in enumerate(s.angles):
                if self.q:
                    n = self.counts_per_rev
                    tc = self._to_counts(target)
                    if not s.absolute:
                        d = (tc - self._counts[k]) % n
                        if d > n // 2:
                            d -= n
                        tc = self._counts[k] + d
                    self._set_cmd(k, counts=tc)
                else:
                    new = target
                    if not s.absolute:
                        d = (target - self._cmd[k]) % TWO_PI
                        new = self._cmd[k] + (d - TWO_PI if d > math.pi else d)
                    self._set_cmd(k, angle=new)
                self._position(k)
        elif isinstance(s, Dwell):
            self._end_tick = tick + self._ticks(s.duration)
        elif isinstance(s, Rotate):
            k = self._axis_index(s)
            sign = 1 if s.rate > 0 else -1
            if self.q:
                self._set_cmd(k, counts=self._counts[k] + sign * s.turns * self.counts_per_rev)
            else:
                self._set_cmd(k, angle=self._cmd[k] + sign * s.turns * TWO_PI)
            a = self.axes[k]
            self[f"{a}.mode"] = 1
            self[f"{a}.rate_cmd"] = s.rate
            self._phase = "spin"
            w = abs(s.rate)
            self._end_tick = tick + self._ticks(s.turns * TWO_PI / w + 4 * w / self.acc_max[k]
                                                + self.schedule.settings.index_timeout)
        elif isinstance(s, Rate):
            k = self._axis_index(s)
            a = self.axes[k]
            self[f"{a}.mode"] = 1
            self[f"{a}.rate_cmd"] = s.rate
            self[f"{a}.angle_cmd"] = self[f"{a}.angle"]
            self._phase = "spin"
            self._end_tick = tick + self._ticks(s.duration)

    def _run(self, tick: int, t: float) -> bool:
        """Advance the current step at this tick; True when it is complete."""
        s = self.schedule.steps[self._i]
        st = self.schedule.settings
        if isinstance(s, Index):
            return self._wait_settled(s, tick, t, self._enter_tick, st.index_timeout)
        if isinstance(s, Dwell):
            return tick >= self._end_tick
        k = self._axis_index(s)
        a = self.axes[k]
        if isinstance(s, Rotate):
            if self._phase == "spin":
                sign = 1.0 if s.rate > 0 else -1.0
                d = (self._cmd[k] - self[f"{a}.angle"]) * sign     # distance left [rad]
                w, A, P = abs(s.rate), self.acc_max[k], self._period
                if d - w * P > w * w / (2 * A):
                    if tick > self._end_tick:
                        raise self._fault(s, t, "the rotation did not reach its target in time")
                    return False
                # one step at a reduced rate w2 that leaves about the braking distance from w2:
                # w2 P + (w - w2)^2 / 2A + w2^2 / 2A = d
                b = P - w / A
                disc = b * b - 4 / A * (w * w / (2 * A) - d)
                w2 = (-b + math.sqrt(disc)) * A / 2 if disc >= 0 else 0.0
                self[f"{a}.rate_cmd"] = sign * min(max(w2, 0.0), w)
                self._phase = "approach"
                return False
            if self._phase == "approach":
                return self._hold(k, tick)
            return self._wait_settled(s, tick, t, self._phase_tick, st.index_timeout)
        # Rate
        if self._phase == "spin":
            if tick < self._end_tick:
                return False
            self[f"{a}.rate_cmd"] = 0.0
            self._phase = "brake"
            self._phase_tick = tick
            return False
        if self._phase == "brake":
            if abs(self[f"{a}.rate"]) > st.settle_rate_tol:
                if (tick - self._phase_tick) * self._period > st.index_timeout + 1e-9:
                    raise self._fault(s, t, f"the axis did not stop within {st.index_timeout:g} s")
                return False
            self._set_cmd(k, angle=self[f"{a}.angle"])
            return self._hold(k, tick)
        return self._wait_settled(s, tick, t, self._phase_tick, st.index_timeout)

    def _hold(self, k: int, tick: int) -> bool:
        """Position control on the target; the step then waits until the axis has settled."""
        self._position(k)
        self._phase = "stop"
        self._phase_tick = tick
        self._hold_since = None
        return False

    # ----------------------------------------------------------------- life cycle
    def initialize(self, t0: float) -> None:
        self._reset()
        self.events = []
        self.finished = False
        self.stop_requested = False
        self["done"] = 0
        self["segment"] = 0

    def do_step(self, t: float, h: float) -> None:
        if self._t0 is None:
            self._t0, self._period = t, h
            for k, a in enumerate(self.axes):     # start from where the table is
                self._set_cmd(k, angle=self[f"{a}.angle"])
                self._position(k)
            self._i = 0
            self._enter(0, t)
        if self.finished:
            return
        tick = int(round((t - self._t0) / self._period))
        while self._run(tick, t):
            self.events[-1]["end"] = t
            self._i += 1
            if self._i >= len(self.schedule.steps):
                self.finished = True
                self["done"] = 1
                self.stop_requested = self.stop_when_done
                return
            self._enter(tick, t)
