"""Behaviours and the FSM of behaviours (paper §3.2, Figure 2).

A behaviour B(f, f^τ, f^ε) iterates its transition function f until its terminal condition
f^τ or its error condition f^ε holds. An FSM's states each carry one behaviour; its arcs carry
initial conditions f^σ, evaluated in order when a behaviour ends; the first that holds selects
the next state. A behaviour marked ``waits`` is a communication state: between iterations the
agent blocks (up to its sampling period) until new input arrives.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

Predicate = Callable[[], bool]


def _never() -> bool:
    return False


def _always() -> bool:
    return True


def _nothing() -> None:
    return None


@dataclass(frozen=True)
class Behaviour:
    """A behaviour ^cB_{j,name}: ``transition`` (the transition function, computing output
    buffers and memory from input buffers and memory), ``terminal`` and ``error`` conditions,
    ``on_enter`` run once when its state is entered, ``waits`` True for communication states."""

    name: str
    transition: Callable[[], None]
    terminal: Predicate
    error: Predicate = _never
    on_enter: Callable[[], None] = _nothing
    waits: bool = True
    doc: str = ""


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


@dataclass
class FSM:
    """^cF_j: states (one behaviour each), arcs, the initial state."""

    initial: str
    states: dict[str, Behaviour] = field(default_factory=dict)
    arcs: list[Arc] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.initial not in self.states:
            raise FsmError(f"initial state {self.initial!r} has no behaviour")
        for arc in self.arcs:
            for end in (arc.source, arc.target):
                if end not in self.states:
                    raise FsmError(f"arc {arc.source}->{arc.target}: unknown state {end!r}")

    def next_state(self, current: str) -> str:
        """The target of the first arc out of ``current`` whose initial condition holds.
        Raises FsmError when none holds."""
        for arc in self.arcs:
            if arc.source == current and arc.condition():
                return arc.target
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
