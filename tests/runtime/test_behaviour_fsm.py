"""Behaviours iterate their transition function until terminal or error; the FSM switches on
initial conditions (paper §3.2)."""

from __future__ import annotations

import pytest

from services.runtime.behaviour import FSM, Arc, Behaviour, FsmError


def test_fsm_follows_first_true_initial_condition() -> None:
    flags = {"go": False}
    fsm = FSM(
        initial="a",
        states={n: Behaviour(n, lambda: None, terminal=lambda: True) for n in ("a", "b", "c")},
        arcs=[Arc("a", "b", lambda: flags["go"], "go"), Arc("a", "c"), Arc("b", "a"), Arc("c", "a")],
    )
    assert fsm.next_state("a") == "c"
    flags["go"] = True
    assert fsm.next_state("a") == "b"
    assert fsm.next_state("b") == "a"


def test_fsm_rejects_unknown_states_and_dead_ends() -> None:
    b = Behaviour("a", lambda: None, terminal=lambda: True)
    with pytest.raises(FsmError):
        FSM(initial="x", states={"a": b})
    with pytest.raises(FsmError):
        FSM(initial="a", states={"a": b}, arcs=[Arc("a", "nowhere")])
    fsm = FSM(initial="a", states={"a": b}, arcs=[Arc("a", "a", lambda: False)])
    with pytest.raises(FsmError, match="no initial condition"):
        fsm.next_state("a")


def test_fsm_describes_itself_as_data_and_dot() -> None:
    fsm = FSM(
        initial="idle",
        states={"idle": Behaviour("idle", lambda: None, terminal=lambda: True, doc="wait")},
        arcs=[Arc("idle", "idle", label="again")],
    )
    assert fsm.describe() == {
        "initial": "idle",
        "states": {"idle": "wait"},
        "arcs": [("idle", "idle", "again")],
    }
    assert 'idle -> idle [label="again"]' in fsm.to_dot("x")
