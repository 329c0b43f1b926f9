"""Interaction protocols declared as state machines in a specification file
(services/spec/protocol_defs.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from services.spec.model import DEFAULT_SPEC, SpecError, load
from services.spec.protocol_defs import protocol_from_table, protocols_of, role_mismatches
from shared.fipa_codec.protocols import PROTOCOLS

FIXTURES = Path(__file__).with_name("fixtures")

REQUEST_TABLE: dict[str, Any] = {
    "initiator": ["request", "cancel"],
    "participant": ["agree", "refuse", "failure", "inform"],
    "final": ["refused", "failed", "done"],
    "cancellable": ["requested", "agreed"],
    "transitions": [
        ["start", "initiator", "request", "requested"],
        ["requested", "participant", "refuse", "refused"],
        ["requested", "participant", "agree", "agreed"],
        ["requested", "participant", "failure", "failed"],
        ["requested", "participant", "inform", "done"],
        ["agreed", "participant", "failure", "failed"],
        ["agreed", "participant", "inform", "done"],
    ],
}

COORDINATE_TABLE: dict[str, Any] = {
    "initiator": ["request", "confirm", "cancel"],
    "participant": ["inform", "refuse", "failure"],
    "initial": "start",
    "final": ["finished", "refused", "failed"],
    "transitions": [
        ["start", "initiator", "request", "requested"],
        ["requested", "participant", "refuse", "refused"],
        ["requested", "participant", "failure", "failed"],
        ["requested", "participant", "inform", "reported"],
        ["reported", "initiator", "confirm", "running"],
        ["running", "participant", "inform", "reported"],
        ["running", "initiator", "confirm", "running"],
        ["ending", "initiator", "confirm", "finished"],
        ["requested", "initiator", "cancel", "requested"],
        ["reported", "initiator", "cancel", "reported"],
        ["running", "initiator", "cancel", "running"],
        ["ending", "initiator", "cancel", "ending"],
    ],
    "terminal": [
        ["requested", "participant", "inform", "ending"],
        ["running", "participant", "inform", "ending"],
    ],
}


@pytest.mark.parametrize(
    ("name", "table"), [("fipa-request", REQUEST_TABLE), ("coordinate", COORDINATE_TABLE)]
)
def test_a_table_builds_the_same_machine_as_the_library(name: str, table: dict[str, Any]) -> None:
    built = protocol_from_table(name, table)
    library = PROTOCOLS[name]
    assert built.states == library.states
    assert built.initial == library.initial
    assert built.final == library.final
    assert dict(built.transitions) == dict(library.transitions)
    assert dict(built.terminal_transitions) == dict(library.terminal_transitions)


def test_the_shipped_spec_uses_the_built_in_protocols() -> None:
    protocols = protocols_of(DEFAULT_SPEC)
    assert set(protocols) == set(load(DEFAULT_SPEC).protocols)
    for name, protocol in protocols.items():
        assert protocol is PROTOCOLS[name]


def test_a_declared_machine_replaces_the_built_in_one() -> None:
    protocols = protocols_of(FIXTURES / "deadlock_protocol.toml")
    assert protocols["fipa-request"] is PROTOCOLS["fipa-request"]
    coordinate = protocols["coordinate"]
    assert coordinate is not PROTOCOLS["coordinate"]
    assert coordinate.final == {"finished", "cancelled", "not-understood"}


def test_the_malformed_fixture_names_file_protocol_and_transition() -> None:
    path = FIXTURES / "malformed_protocol.toml"
    with pytest.raises(SpecError) as err:
        protocols_of(path)
    assert str(err.value) == (
        f"{path}: protocol coordinate: transition 2 "
        '["requested", "participant", "infrom", "reported"]: '
        "'infrom' is not a FIPA performative (FIPA SC00037)"
    )


def _with(**changes: Any) -> dict[str, Any]:
    table = dict(REQUEST_TABLE)
    for key, value in changes.items():
        if value is None:
            del table[key]
        else:
            table[key] = value
    return table


def _edit(index: int, edge: list[Any]) -> dict[str, Any]:
    transitions = list(REQUEST_TABLE["transitions"])
    transitions[index] = edge
    return _with(transitions=transitions)


def _plus(*edges: list[str]) -> dict[str, Any]:
    return _with(transitions=[*REQUEST_TABLE["transitions"], *edges])


@pytest.mark.parametrize(
    ("table", "message"),
    [
        (_with(transitions=None), "a state machine needs 'transitions'"),
        (_with(final=None), "a state machine needs 'final' (the final states)"),
        (_with(final=[]), "'final' names no state"),
        (_with(transitions=[]), "'transitions' is empty"),
        (_with(transition=[]), "unknown key(s) transition; known: cancellable, description, final,"),
        (
            _edit(1, ["requested", "participant", "refuse"]),
            "transition 2 ['requested', 'participant', 'refuse']: expected [state, role, performative, "
            "state], four names",
        ),
        (
            _edit(1, ["requested", "responder", "refuse", "refused"]),
            'transition 2 ["requested", "responder", "refuse", "refused"]: role \'responder\' is '
            "neither 'initiator' nor 'participant'",
        ),
        (
            _edit(1, ["requested", "participant", "not-understood", "refused"]),
            "not-understood is implicit (either role, in every state after the first); leave it out",
        ),
        (
            _edit(1, ["requested", "participant", "propose", "refused"]),
            'transition 2 ["requested", "participant", "propose", "refused"]: the participant may '
            "not send 'propose' ('participant' lists agree, failure, inform, refuse)",
        ),
        (
            _plus(["requested", "participant", "refuse", "done"]),
            'transition 8 ["requested", "participant", "refuse", "done"] conflicts with transition '
            "2: the same state, role and performative lead to 'refused' and 'done'",
        ),
        (
            _plus(["done", "initiator", "request", "requested"]),
            'transition 8 ["done", "initiator", "request", "requested"] leaves the final state \'done\'',
        ),
        (
            _plus(["agreed", "initiator", "cancel", "agreed"]),
            'transition 8 ["agreed", "initiator", "cancel", "agreed"] conflicts with the cancel '
            "meta-protocol ('cancellable'), which leads there to 'cancelling'",
        ),
        (
            _with(cancellable=["asleep"]),
            "cancellable state 'asleep' is not a non-final state of the transitions",
        ),
        (
            _with(initiator=["request"]),
            "the cancel meta-protocol ('cancellable') lets the initiator send 'cancel', which "
            "'initiator' does not list",
        ),
        (
            _plus(["limbo", "participant", "inform", "done"]),
            "invalid state machine: state 'limbo' is unreachable",
        ),
        (
            _plus(["agreed", "participant", "agree", "waiting"]),
            "invalid state machine: no final state can be reached from 'waiting'",
        ),
        (_with(initial="done"), "invalid state machine: the initial state is final"),
    ],
)
def test_a_malformed_table_gives_a_precise_error(table: dict[str, Any], message: str) -> None:
    with pytest.raises(SpecError) as err:
        protocol_from_table("ask", table, source="spec.toml")
    assert str(err.value).startswith("spec.toml: protocol ask: ")
    assert message in str(err.value)


def test_a_protocol_neither_declared_nor_built_in_is_an_error(tmp_path: Path) -> None:
    text = DEFAULT_SPEC.read_text()
    text = text.replace("[protocols.coordinate]", "[protocols.handshake]")
    text = text.replace('protocol = "coordinate"', 'protocol = "handshake"')
    path = tmp_path / "spec.toml"
    path.write_text(text)
    with pytest.raises(SpecError, match=r"protocol handshake declares no state machine .* not a built-in"):
        protocols_of(path)


def test_role_lists_and_machines_agree() -> None:
    """role_mismatches found that coordinate's participant could refuse or fail by the spec's
    list but not by the state machine (a_ta refuses a request without a plan); the machine
    now has those transitions."""
    spec = load(DEFAULT_SPEC)
    for name in ("fipa-request", "fipa-query", "fipa-subscribe", "coordinate"):
        assert role_mismatches(PROTOCOLS[name], spec.protocols[name]) == []
