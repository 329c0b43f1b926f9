"""Interaction protocols declared as state machines in a specification file
(services/spec/protocol_defs.py)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from services.spec.check import check_report
from services.spec.model import DEFAULT_SPEC, SpecError, load
from services.spec.protocol_defs import (
    declares_state_machine,
    protocol_from_table,
    protocols_of,
    read_raw,
    role_mismatches,
)
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import PROTOCOLS, ConversationTracker

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


def test_the_shipped_spec_uses_the_built_in_protocols_and_declares_roco_notify() -> None:
    """The four protocols the paper's channels use are the built-in ones; roco-notify (a_hi's
    notices, one inform) is declared in the specification's table, as is any protocol an agent
    added to it declares (docs/spec.md's walk-through: ``kitchen-warning``)."""
    protocols = protocols_of(DEFAULT_SPEC)
    assert set(protocols) == set(load(DEFAULT_SPEC).protocols)
    tables = read_raw(DEFAULT_SPEC)["protocols"]
    for name, protocol in protocols.items():
        if name in PROTOCOLS:
            assert protocol is PROTOCOLS[name]
        else:
            assert declares_state_machine(tables[name]), name
    assert {"fipa-request", "fipa-query", "fipa-subscribe", "coordinate"} <= set(protocols)
    notify = protocols["roco-notify"]
    assert "roco-notify" not in PROTOCOLS and notify.final == {"told"}


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
        "'infrom' is not a FIPA performative (FIPA SC00037); did you mean 'inform'?"
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


DOCS = Path(__file__).parents[2] / "docs" / "spec.md"


@dataclass(frozen=True)
class Rule:
    """A rule a declared state machine must satisfy (docs/spec.md, "Declaring a protocol's
    state machine"): a planted declaration that breaks it, the whole error after
    ``FILE: protocol NAME: ``, and the part of it the docs' table quotes."""

    table: dict[str, Any]
    error: str
    documented: str


RULES: dict[str, Rule] = {
    "known keys": Rule(
        _with(transition=[]),
        "unknown key(s) transition; known: cancellable, description, final, initial, initiator, "
        "participant, spec, terminal, transitions; remove or rename it",
        "unknown key(s) K; known: …",
    ),
    "has transitions": Rule(
        _with(transitions=None),
        "a state machine needs 'transitions'; add transitions = [[state, role, performative, state], ...]",
        "a state machine needs 'transitions'",
    ),
    "has final states": Rule(
        _with(final=None),
        "a state machine needs 'final' (the final states); add final = [the states that end the "
        "conversation]",
        "a state machine needs 'final'",
    ),
    "initial is a name": Rule(
        _with(initial=""),
        "'initial' must be a state name, not ''; name a state, or leave it out (\"start\")",
        "'initial' must be a state name",
    ),
    "a final state": Rule(
        _with(final=[]),
        "'final' names no state; name the states that end the conversation",
        "'final' names no state",
    ),
    "a transition": Rule(
        _with(transitions=[]),
        '\'transitions\' is empty; list at least the opening ["start", "initiator", performative, state]',
        "'transitions' is empty",
    ),
    "four names": Rule(
        _edit(1, ["requested", "participant", "refuse"]),
        "transition 2 ['requested', 'participant', 'refuse']: expected [state, role, performative, "
        "state], four names",
        "expected [state, role, performative, state], four names",
    ),
    "a role": Rule(
        _edit(1, ["requested", "responder", "refuse", "refused"]),
        'transition 2 ["requested", "responder", "refuse", "refused"]: role \'responder\' is neither '
        "'initiator' nor 'participant'; write one of them",
        "is neither 'initiator' nor 'participant'",
    ),
    "a FIPA performative": Rule(
        _edit(1, ["requested", "participant", "infrom", "refused"]),
        'transition 2 ["requested", "participant", "infrom", "refused"]: \'infrom\' is not a FIPA '
        "performative (FIPA SC00037); did you mean 'inform'?",
        "is not a FIPA performative (FIPA SC00037)",
    ),
    "not-understood implicit": Rule(
        _edit(1, ["requested", "participant", "not-understood", "refused"]),
        'transition 2 ["requested", "participant", "not-understood", "refused"]: not-understood is '
        "implicit (either role, in every state after the first that is not final); leave it out",
        "not-understood is implicit",
    ),
    "listed for the role": Rule(
        _edit(1, ["requested", "participant", "propose", "refused"]),
        'transition 2 ["requested", "participant", "propose", "refused"]: the participant may not '
        "send 'propose' ('participant' lists agree, failure, inform, refuse); add it to "
        "'participant', or change the transition",
        "the participant may not send 'X'",
    ),
    "the initiator opens": Rule(
        _edit(0, ["start", "participant", "inform", "requested"]),
        'transition 1 ["start", "participant", "inform", "requested"] opens the conversation from '
        "the participant; the first message is the initiator's (its sender is the initiator): make "
        "the role 'initiator', or leave from a later state",
        "opens the conversation from the participant",
    ),
    "one next state": Rule(
        _plus(["requested", "participant", "refuse", "done"]),
        'transition 8 ["requested", "participant", "refuse", "done"] conflicts with transition 2: '
        "the same state, role and performative lead to 'refused' and 'done'; keep one of the two",
        "the same state, role and performative lead to",
    ),
    "final is final": Rule(
        _plus(["done", "initiator", "request", "requested"]),
        'transition 8 ["done", "initiator", "request", "requested"] leaves the final state \'done\'; '
        "remove it, or take 'done' out of 'final'",
        "leaves the final state",
    ),
    "cancel meta-protocol's own": Rule(
        _plus(["agreed", "initiator", "cancel", "agreed"]),
        'transition 8 ["agreed", "initiator", "cancel", "agreed"] conflicts with the cancel '
        "meta-protocol ('cancellable'), which leads there to 'cancelling'; remove it (the "
        "meta-protocol adds that transition)",
        "conflicts with the cancel meta-protocol",
    ),
    "cancellable state": Rule(
        _with(cancellable=["asleep"]),
        "cancellable state 'asleep' is not a non-final state of the transitions; name a state the "
        "transitions reach that is not final, or take it out of 'cancellable'",
        "is not a non-final state of the transitions",
    ),
    "cancel listed": Rule(
        _with(initiator=["request"]),
        "the cancel meta-protocol ('cancellable') lets the initiator send 'cancel', which "
        "'initiator' does not list; add it to 'initiator', or drop 'cancellable'",
        "lets the initiator send 'cancel', which 'initiator' does not list",
    ),
    "initial not final": Rule(
        _with(initial="done"),
        "invalid state machine: the initial state 'done' is final; take it out of 'final', or name "
        "another 'initial'",
        "the initial state 'S' is final",
    ),
    "reachable": Rule(
        _plus(["limbo", "participant", "inform", "done"]),
        "invalid state machine: state 'limbo' is unreachable from 'start'; add a transition into it "
        "from a reachable state, or remove the transitions that leave it",
        "state 'S' is unreachable from",
    ),
    "final reachable": Rule(
        _plus(["agreed", "participant", "agree", "waiting"]),
        "invalid state machine: no final state can be reached from 'waiting' (only not-understood "
        "would end the conversation); add a transition from it toward a final state, or name it in "
        "'final'",
        "no final state can be reached from",
    ),
}


@pytest.mark.parametrize("rule", list(RULES))
def test_each_rule_broken_gives_its_own_error_saying_what_to_change(rule: str) -> None:
    with pytest.raises(SpecError) as err:
        protocol_from_table("ask", RULES[rule].table, source="spec.toml")
    assert str(err.value) == f"spec.toml: protocol ask: {RULES[rule].error}"


def test_the_docs_table_quotes_every_rule_s_error() -> None:
    """docs/spec.md's table of rules quotes each error (and each quote is in its error)."""
    text = DOCS.read_text()
    section = text[text.index("## Declaring a protocol's state machine") :]
    section = section[: section.index("\n## ")]
    for name, rule in RULES.items():
        assert f"`{rule.documented}`" in section, name
        pattern = re.escape(rule.documented).replace("'X'", "'.+'").replace("'S'", "'.+'")
        pattern = pattern.replace("K;", ".+;").replace("…", ".+")
        assert re.search(pattern, rule.error), name


def test_a_terminal_transition_follows_the_rules_of_a_transition() -> None:
    table = {**COORDINATE_TABLE, "terminal": [["running", "participant", "infrom", "ending"]]}
    with pytest.raises(SpecError) as err:
        protocol_from_table("coordinate", table)
    assert str(err.value) == (
        'protocol coordinate: terminal transition 1 ["running", "participant", "infrom", "ending"]: '
        "'infrom' is not a FIPA performative (FIPA SC00037); did you mean 'inform'?"
    )


NOTIFY_TABLE: dict[str, Any] = {
    "initiator": ["inform"],
    "participant": [],
    "final": ["told"],
    "transitions": [["start", "initiator", "inform", "told"]],
}


def test_a_one_message_protocol_is_valid_and_has_no_not_understood_state() -> None:
    """Before, every machine got the state not-understood, which a protocol with no state after
    the first that is not final never reaches: 'state 'not-understood' is unreachable'."""
    notify = protocol_from_table("notify", NOTIFY_TABLE)
    assert notify.states == {"start", "told"} and notify.final == {"told"}
    assert notify.allowed("start") == [("initiator", Performative.INFORM, False)]
    assert notify.allowed("told") == []
    tracker = ConversationTracker(notify)
    assert tracker.step("initiator", "inform") == "told" and tracker.is_finished


def test_a_state_after_the_first_brings_not_understood_back() -> None:
    table = {**NOTIFY_TABLE, "participant": ["confirm"]}
    table["transitions"] = [*NOTIFY_TABLE["transitions"], ["told", "participant", "confirm", "confirmed"]]
    table["final"] = ["confirmed"]
    tell = protocol_from_table("tell", table)
    assert tell.states == {"start", "told", "confirmed", "not-understood"}
    assert tell.next_state("told", "initiator", Performative.NOT_UNDERSTOOD) == "not-understood"
    assert tell.next_state("start", "initiator", Performative.NOT_UNDERSTOOD) is None


def test_a_protocol_neither_declared_nor_built_in_is_an_error(tmp_path: Path) -> None:
    text = DEFAULT_SPEC.read_text()
    text = text.replace("[protocols.coordinate]", "[protocols.handshake]")
    text = text.replace('protocol = "coordinate"', 'protocol = "handshake"')
    path = tmp_path / "spec.toml"
    path.write_text(text)
    error = (
        "protocol handshake declares no state machine (cancellable, final, initial, terminal, "
        f"transitions) and is not a built-in protocol ({', '.join(PROTOCOLS)}); declare its state "
        "machine in [protocols.handshake] (docs/spec.md), or use a built-in protocol"
    )
    with pytest.raises(SpecError) as err:
        protocols_of(path)
    assert str(err.value) == f"{path}: {error}"
    ok, report = check_report(path)
    assert not ok and f"- {error}" in report.splitlines()
    assert "`declares no state machine`" in DOCS.read_text()


def test_role_lists_and_machines_agree() -> None:
    """role_mismatches found that coordinate's participant could refuse or fail by the spec's
    list but not by the state machine (a_ta refuses a request without a plan); the machine
    now has those transitions."""
    spec = load(DEFAULT_SPEC)
    for name in ("fipa-request", "fipa-query", "fipa-subscribe", "coordinate"):
        assert role_mismatches(PROTOCOLS[name], spec.protocols[name]) == []
