"""Algebraic loops solved by fixed-point iteration (``system.algorithm = "iterative"``).

A loop of direct feed-through (an output that depends on an input at the same instant, around a
cycle of connections) has no step order without delay. Instead of accepting a one-step delay
(an explicit order, or Jacobi), each communication step of the units in the loop is repeated:
save their states, step them in order, read the loop's values, restore the states and step
again with the new values, until the values change by less than the tolerance. The result is
the implicit coupling of the loop at every step end (a fixed point of the loop's equations),
the classic "strong coupling" of co-simulation; it needs every unit of the loop to get and set
its state (FMI ``canGetAndSetFMUstate``; a Python component's instance attributes).

A loop whose map is not a contraction (e.g. y = u + 1 around y = u) has no fixed point the
iteration reaches: the step then fails naming the loop, the time and the last change.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from orchestrator.errors import SystemError_, UnitError
from orchestrator.wiring import strongly_connected

DEFAULT_TOLERANCE = 1e-10
DEFAULT_MAX_ITERATIONS = 100


@dataclass
class LoopGroup:
    """The units iterated together (a strongly connected set of units holding an algebraic
    loop, in stepping order) and the exchange slots of the values they feed back."""

    units: list[str]
    slots: list[int] = field(default_factory=list)
    iterations_max: int = 0
    iterations_total: int = 0
    steps: int = 0


def loop_groups(order: list[str], connections, loop_units: list[set[str]]) -> list[LoopGroup]:
    """One group per set of units connected in a cycle that holds an algebraic loop: the whole
    cycle of units is repeated, so a unit without feed-through inside it (a lag) also sees the
    loop's converged values."""
    edges: dict[str, list[str]] = {n: [] for n in order}
    for c in connections:
        if c.source.unit != c.target.unit and c.target.unit not in edges[c.source.unit]:
            edges[c.source.unit].append(c.target.unit)
    groups = []
    for comp in strongly_connected(order, edges):
        if len(comp) > 1 and any(set(comp) & lu for lu in loop_units):
            groups.append(LoopGroup([n for n in order if n in comp]))
    return groups


def check_iterable(groups: list[LoopGroup], units: dict, multiples: dict[str, int], where: str) -> None:
    """Refuse, naming the rule, what fixed-point iteration cannot do."""
    for g in groups:
        cannot = [n for n in g.units if not getattr(units[n], "can_get_set_state", False)]
        if cannot:
            raise SystemError_(
                f"{where}: algorithm = \"iterative\": the units {cannot} in the loop of {g.units} cannot get and "
                "set their state (canGetAndSetFMUstate is false), so a step cannot be repeated; break the loop "
                "with a one-step delay instead (system.order, or algorithm = \"jacobi\")")
        slow = [n for n in g.units if multiples.get(n, 1) != 1]
        if slow:
            raise SystemError_(f"{where}: algorithm = \"iterative\": the units {slow} in the loop of {g.units} step "
                               "at a multiple of the communication step; a loop is iterated at every step")


def bind_slots(groups: list[LoopGroup], connections, exchange, where: str) -> None:
    """Each group's fed-back values: the exchange slots of its outputs that its units read."""
    for g in groups:
        g.slots = sorted({exchange.slots[(c.source.unit, c.source.var)] for c in connections
                          if c.derivative_order == 0 and c.source.unit in g.units and c.target.unit in g.units})
        if set(g.slots) & set(exchange.objects):
            raise SystemError_(f"{where}: the loop of {g.units} exchanges strings or binaries; fixed-point "
                               "iteration compares numbers: break it with a one-step delay")


class FixedPointIteration:
    """Repeats a loop group's step until the values it feeds back stop changing."""

    def __init__(self, tolerance: float = DEFAULT_TOLERANCE, max_iterations: int = DEFAULT_MAX_ITERATIONS) -> None:
        self.tolerance = tolerance
        self.max_iterations = max_iterations

    def step(self, group: LoopGroup, ports: list, values: np.ndarray, t: float, step_one) -> bool:
        """Step *ports* (the group's, in order) from *t* by ``step_one(port) -> asked to end``
        until the group's slot values converge; True if a unit asked to end the run."""
        states = [p.unit.get_state() for p in ports]
        try:
            prev = values[group.slots].copy()
            change = float("inf")
            for k in range(1, self.max_iterations + 1):
                ending = False
                for p in ports:
                    ending = step_one(p) or ending
                cur = values[group.slots]
                change = float(np.max(np.abs(cur - prev) / np.maximum(1.0, np.abs(cur)))) if len(cur) else 0.0
                if change <= self.tolerance:
                    group.iterations_max = max(group.iterations_max, k)
                    group.iterations_total += k
                    group.steps += 1
                    return ending
                prev = cur.copy()
                for p, s in zip(ports, states):
                    p.unit.set_state(s)
            raise UnitError(f"algebraic loop of {group.units}: no fixed point reached at t = {t:.9g} s after "
                            f"{self.max_iterations} iterations (last relative change {change:.3g}, tolerance "
                            f"{self.tolerance:g}); the loop's equations may have no solution the iteration finds "
                            "(it is not a contraction): break it with a one-step delay (system.order or "
                            "algorithm = \"jacobi\") or change the loop")
        finally:
            for p, s in zip(ports, states):
                p.unit.free_state(s)

    @staticmethod
    def note(group: LoopGroup) -> str:
        mean = group.iterations_total / group.steps if group.steps else 0.0
        return (f"algebraic loop of {group.units} solved by fixed-point iteration at each of {group.steps} steps "
                f"({mean:.1f} iterations on average, at most {group.iterations_max})")
