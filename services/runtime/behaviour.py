"""Behaviours and the FSM of behaviours (paper §3.2, Figure 2).

A behaviour B(f, f^τ, f^ε) iterates its transition function f until its terminal condition
f^τ or its error condition f^ε holds. An FSM's states each carry one behaviour; its arcs carry
initial conditions f^σ, evaluated in order when a behaviour ends; the first that holds selects
the next state. A behaviour marked ``waits`` is a communication state: between iterations the
agent blocks (up to its sampling period) until new input arrives.

A *periodic* behaviour (:func:`periodic`) acts on a timer: its transition function takes in
what arrived at every iteration and, once its period has elapsed (:class:`Every`), also acts
(e.g. opens a conversation). The agent then blocks no longer than until the next period is due,
so the action is as punctual as the agent's thread is (docs/agents.md, "An agent that acts on a
timer"). Periods are on the agent's clock (services/runtime/clock.py): the simulation's pace
while the fleet runs as fast as possible, unless a behaviour asks for the wall clock.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from services.runtime.clock import FleetClock

Predicate = Callable[[], bool]


def _never() -> bool:
    return False


def _always() -> bool:
    return True


def _nothing() -> None:
    return None


class Every:
    """A condition that holds once every ``period_s`` seconds (> 0, finite): calling it returns
    True when a period has elapsed since it last did (at the first call too, unless
    ``at_start`` is False: then one period after the first call), else False. Periods are kept on
    a fixed grid of its clock from the first call; periods missed entirely (the agent was busy
    longer than a period) are skipped, not made up.

    Its clock (s): ``clock`` when given; else, once the agent gives it its clocks (:meth:`bind`,
    for every periodic behaviour of its FSM), the agent's :class:`FleetClock`
    (services/runtime/clock.py: the simulation's pace while the fleet runs as fast as possible,
    the wall clock in real time), or with ``wall=True`` the agent's wall clock
    (``sources.monotonic``), for what must keep wall time whatever the simulation does;
    ``time.monotonic`` until then. Raises ValueError for a period that is not a positive finite
    number, or for both ``clock`` and ``wall``."""

    def __init__(
        self,
        period_s: float,
        *,
        at_start: bool = True,
        clock: Callable[[], float] | None = None,
        wall: bool = False,
    ) -> None:
        if not (isinstance(period_s, int | float) and math.isfinite(period_s) and period_s > 0):
            raise ValueError(f"a period must be a positive number of seconds, not {period_s!r}")
        if clock is not None and wall:
            raise ValueError("a timer takes a clock or the wall clock, not both")
        self.period_s = float(period_s)
        self.at_start = at_start
        self.wall = wall
        self.clock: Callable[[], float] = clock or time.monotonic
        self.fleet: FleetClock | None = clock if isinstance(clock, FleetClock) else None
        """The agent's clock, given or once :meth:`bind` gave it (None: another clock)."""
        self._bindable = clock is None
        self.due: float | None = None
        """When (``clock`` s) the condition holds next; None before the first call."""

    def bind(self, fleet: FleetClock, wall_clock: Callable[[], float]) -> None:
        """Run on the agent's clocks (services/runtime/engine.py does it for every timer of its
        FSM): ``fleet``, or ``wall_clock`` (s, monotonic) for a timer that asked for the wall
        clock; a timer given a clock, or that has already run, keeps its clock."""
        if not self._bindable or self.due is not None:
            return
        if self.wall:
            self.clock = wall_clock
        else:
            self.clock = self.fleet = fleet

    def __call__(self) -> bool:
        now = self.clock()
        if self.due is None:
            self.due = now if self.at_start else now + self.period_s
        if now < self.due:
            return False
        missed = math.floor((now - self.due) / self.period_s)
        self.due += (missed + 1) * self.period_s
        return True

    def left(self) -> float:
        """Seconds of its clock until the condition holds next (0 when due or before the first
        call)."""
        return 0.0 if self.due is None else max(0.0, self.due - self.clock())

    def wall_left(self) -> float:
        """Wall seconds until the condition holds next: :meth:`left` at its clock's pace (how
        long the agent may block)."""
        left = self.left()
        return self.fleet.wall_seconds(left) if self.fleet is not None and left else left


@dataclass(frozen=True)
class Behaviour:
    """A behaviour ^cB_{j,name}: ``transition`` (the transition function, computing output
    buffers and memory from input buffers and memory), ``terminal`` and ``error`` conditions,
    ``on_enter`` run once when its state is entered, ``waits`` True for communication states;
    ``timer``: the period of a periodic behaviour (:func:`periodic`), which the agent does not
    block past."""

    name: str
    transition: Callable[[], None]
    terminal: Predicate
    error: Predicate = _never
    on_enter: Callable[[], None] = _nothing
    waits: bool = True
    doc: str = ""
    timer: Every | None = None


def periodic(
    name: str,
    period_s: float,
    act: Callable[[], None],
    *,
    serve: Callable[[], None] = _nothing,
    terminal: Predicate = _never,
    error: Predicate = _never,
    at_start: bool = True,
    doc: str = "",
    clock: Callable[[], float] | None = None,
    wall: bool = False,
) -> Behaviour:
    """A periodic behaviour: a communication state whose transition function runs ``serve``
    (e.g. ``agent.handle_received``: the answers to what ``act`` asked) at every iteration and
    ``act`` once every ``period_s`` seconds (:class:`Every`: at once when the state is first
    entered unless ``at_start`` is False, then on a fixed grid; a period missed while the agent
    was busy is skipped), on the agent's clock (the simulation's pace while the fleet runs as
    fast as possible), or on ``clock``, or with ``wall=True`` on the wall clock (:class:`Every`).
    Between iterations the agent blocks until input arrives or the next period is due.
    ``terminal``/``error`` end it as any behaviour's do. Raises ValueError for a period that is
    not a positive finite number of seconds, or for both ``clock`` and ``wall``."""
    timer = Every(period_s, at_start=at_start, clock=clock, wall=wall)

    def transition() -> None:
        serve()
        if timer():
            act()

    return Behaviour(
        name,
        transition,
        terminal,
        error,
        waits=True,
        doc=doc or f"every {period_s:g} s",
        timer=timer,
    )


def once(name: str, transition: Callable[[], None], doc: str = "") -> Behaviour:
    """A behaviour whose transition function runs once (its terminal condition holds at once)
    and that does not wait for input: a state of computation between communication states
    (e.g. a_co's ``schedule``)."""
    return Behaviour(name, transition, _always, waits=False, doc=doc)


@dataclass(frozen=True)
class Arc:
    """A directed arc from ``source`` to ``target`` labelled with initial condition
    ``condition`` (paper: f^σ_{j,source,target}); ``label`` is its name in drawings."""

    source: str
    target: str
    condition: Predicate = _always
    label: str = ""


class FsmError(RuntimeError):
    """An FSM that is malformed or has no arc to take when a behaviour ends."""


class FSM:
    """^cF_j: states (one behaviour each), arcs, the initial state (paper §3.2, Figure 2).

    ``states`` are the behaviours, each under its own name (:attr:`Behaviour.name`, written
    once: ``FSM([Behaviour("idle", …), Behaviour("busy", …)], arcs)``); ``initial`` names the
    state the agent starts in, by default the first behaviour's. Raises FsmError for no
    behaviour, two behaviours of one name, an ``initial`` that names none, or an arc whose
    end names none."""

    initial: str
    states: dict[str, Behaviour]
    """The behaviours by name, in the order given."""
    arcs: list[Arc]

    def __init__(
        self, states: Sequence[Behaviour], arcs: Sequence[Arc] = (), initial: str | None = None
    ) -> None:
        if isinstance(states, Mapping):
            raise FsmError("states are a sequence of behaviours, each under its own name, not a mapping")
        if not states:
            raise FsmError("an FSM needs at least one behaviour")
        self.states = {}
        for b in states:
            if b.name in self.states:
                raise FsmError(f"two behaviours are named {b.name!r}")
            self.states[b.name] = b
        self.initial = states[0].name if initial is None else initial
        self.arcs = list(arcs)
        if self.initial not in self.states:
            raise FsmError(f"initial state {self.initial!r} has no behaviour")
        for arc in self.arcs:
            for end in (arc.source, arc.target):
                if end not in self.states:
                    raise FsmError(f"arc {arc.source}->{arc.target}: unknown state {end!r}")

    def __repr__(self) -> str:
        return f"FSM(initial={self.initial!r}, states={list(self.states)!r}, arcs={len(self.arcs)})"

    def next_state(self, current: str) -> str:
        """The target of the first arc out of ``current`` whose initial condition holds.
        Raises FsmError when none holds."""
        return self.next_arc(current).target

    def next_arc(self, current: str) -> Arc:
        """The first arc out of ``current`` whose initial condition holds. Raises FsmError
        when none holds."""
        for arc in self.arcs:
            if arc.source == current and arc.condition():
                return arc
        raise FsmError(f"no initial condition holds after state {current!r}")

    def describe(self) -> dict[str, object]:
        """The FSM as data: states with behaviour docs, arcs with labels."""
        return {
            "initial": self.initial,
            "states": {n: b.doc for n, b in self.states.items()},
            "arcs": [(a.source, a.target, a.label) for a in self.arcs],
        }

    def to_dot(self, name: str) -> str:
        """Graphviz source of the FSM (paper Figure 11 style)."""
        lines = [f'digraph "{name}" {{', "  rankdir=LR;", "  start [shape=point];"]
        lines.append(f"  start -> {self.initial};")
        for s in self.states:
            lines.append(f'  {s} [shape=box, style=rounded, label="{s}"];')
        for a in self.arcs:
            label = f' [label="{a.label}"]' if a.label else ""
            lines.append(f"  {a.source} -> {a.target}{label};")
        lines.append("}")
        return "\n".join(lines)
