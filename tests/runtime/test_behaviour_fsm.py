"""Behaviours iterate their transition function until terminal or error; the FSM switches on
initial conditions (paper §3.2). An FSM takes its behaviours as a sequence, each under its own
name: a name is written once."""

from __future__ import annotations

from typing import Any

import pytest

from services.runtime.behaviour import FSM, Arc, Behaviour, FsmError, once, periodic


def _b(name: str, doc: str = "") -> Behaviour:
    return Behaviour(name, lambda: None, terminal=lambda: True, doc=doc)


def test_fsm_follows_first_true_initial_condition() -> None:
    flags = {"go": False}
    fsm = FSM(
        [_b(n) for n in ("a", "b", "c")],
        arcs=[Arc("a", "b", lambda: flags["go"], "go"), Arc("a", "c"), Arc("b", "a"), Arc("c", "a")],
    )
    assert fsm.next_state("a") == "c"
    flags["go"] = True
    assert fsm.next_state("a") == "b"
    assert fsm.next_state("b") == "a"


def test_fsm_keys_its_behaviours_by_their_names_and_starts_in_the_first_unless_told() -> None:
    a, b, tick = _b("a"), _b("b"), periodic("tick", 1.0, lambda: None)
    fsm = FSM([a, b, tick], [Arc("a", "b")])
    assert fsm.initial == "a"
    assert list(fsm.states) == ["a", "b", "tick"] and fsm.states["b"] is b and fsm.states["tick"] is tick
    assert FSM([a, b], initial="b").initial == "b"
    assert fsm.arcs == [Arc("a", "b")]


def test_a_once_behaviour_ends_after_one_transition_without_waiting_for_input() -> None:
    ran: list[str] = []
    b = once("schedule", lambda: ran.append("schedule"), "decide")
    b.on_enter()
    b.transition()
    assert ran == ["schedule"] and b.terminal() and not b.error() and not b.waits
    assert (b.name, b.doc, b.timer) == ("schedule", "decide", None)


def test_fsm_rejects_unknown_states_duplicates_and_dead_ends() -> None:
    b = _b("a")
    with pytest.raises(FsmError, match="initial state 'x' has no behaviour"):
        FSM([b], initial="x")
    with pytest.raises(FsmError, match="unknown state 'nowhere'"):
        FSM([b], arcs=[Arc("a", "nowhere")])
    with pytest.raises(FsmError, match="two behaviours are named 'a'"):
        FSM([b, _b("other"), _b("a")])
    with pytest.raises(FsmError, match="at least one behaviour"):
        FSM([])
    mapping: Any = {"a": b}  # the old form: a name written twice
    with pytest.raises(FsmError, match="not a mapping"):
        FSM(mapping)
    fsm = FSM([b], arcs=[Arc("a", "a", lambda: False)])
    with pytest.raises(FsmError, match="no initial condition"):
        fsm.next_state("a")


def test_fsm_describes_itself_as_data_and_dot() -> None:
    fsm = FSM([_b("idle", doc="wait")], arcs=[Arc("idle", "idle", label="again")])
    assert fsm.describe() == {
        "initial": "idle",
        "states": {"idle": "wait"},
        "arcs": [("idle", "idle", "again")],
    }
    assert 'idle -> idle [label="again"]' in fsm.to_dot("x")
