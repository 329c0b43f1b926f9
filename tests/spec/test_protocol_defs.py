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
    machine_of,
    protocol_from_table,
    protocols_of,
    read_raw,
    role_lists,
    role_mismatches,
)
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR as _I
from shared.fipa_codec.protocols import PARTICIPANT as _R
from shared.fipa_codec.protocols import PROTOCOLS, Protocol, _build
from tests.support.conversation import Walk

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

_P = Performative
FORMER_COORDINATE = _build(
    "coordinate",
    "paper §5.4, Figure 8",
    "a_co requests a_ta to execute a plan (L_HFSM); a_ta informs its supervised-worker "
    "states (L_SW), each confirmed by a_co before the next; a_co may cancel at any time "
    "while the plan runs (a_ta then goes on reporting, e.g. Terminating, Preempted); the "
    "conversation ends when a terminal state (Succeeded, Error, Preempted, Replan) is "
    "confirmed. A cancel that crosses the terminal inform on the wire is tolerated, as is a "
    "confirm sent again while the plan runs. a_ta "
    "may refuse a request it cannot run (no plan in it) or fail it at once.",
    [
        ("start", _I, _P.REQUEST, "requested"),
        ("requested", _R, _P.REFUSE, "refused"),
        ("requested", _R, _P.FAILURE, "failed"),
        ("requested", _R, _P.INFORM, "reported"),
        ("reported", _I, _P.CONFIRM, "running"),
        ("running", _R, _P.INFORM, "reported"),
        ("running", _I, _P.CONFIRM, "running"),
        ("ending", _I, _P.CONFIRM, "finished"),
        ("requested", _I, _P.CANCEL, "requested"),
        ("reported", _I, _P.CANCEL, "reported"),
        ("running", _I, _P.CANCEL, "running"),
    ],
    ["finished", "refused", "failed"],
    terminal_edges=[
        ("requested", _R, _P.INFORM, "ending"),
        ("running", _R, _P.INFORM, "ending"),
    ],
    crossing_edges=[("ending", _I, _P.CANCEL, "ending")],
)
"""coordinate as shared/fipa_codec/protocols.py built it (COORDINATE) before it moved to the
specification's [protocols.coordinate] (paper §5.4, Figure 8)."""

COORDINATE_TABLE: dict[str, Any] = read_raw(DEFAULT_SPEC)["protocols"]["coordinate"]
"""The shipped specification's declaration of coordinate."""


def _same_machine(built: Protocol, expected: Protocol) -> None:
    assert built.name == expected.name
    assert built.states == expected.states
    assert built.initial == expected.initial
    assert built.final == expected.final
    assert dict(built.transitions) == dict(expected.transitions)
    assert dict(built.terminal_transitions) == dict(expected.terminal_transitions)
    assert dict(built.crossing_transitions) == dict(expected.crossing_transitions)
    assert (built.spec, built.description) == (expected.spec, expected.description)


def test_a_table_builds_the_same_machine_as_the_library() -> None:
    built = protocol_from_table("fipa-request", {**REQUEST_TABLE, "spec": "FIPA SC00026"})
    library = PROTOCOLS["fipa-request"]
    assert built.states == library.states
    assert built.initial == library.initial
    assert built.final == library.final
    assert dict(built.transitions) == dict(library.transitions)
    assert dict(built.terminal_transitions) == dict(library.terminal_transitions)
    assert dict(built.crossing_transitions) == dict(library.crossing_transitions)


def test_the_declared_coordinate_is_the_machine_the_codec_built() -> None:
    """coordinate moved from the codec (shared/fipa_codec/protocols.py) to the specification:
    its table builds the machine the codec did, terminal and crossing transitions included."""
    _same_machine(protocol_from_table("coordinate", COORDINATE_TABLE), FORMER_COORDINATE)
    _same_machine(protocols_of(DEFAULT_SPEC)["coordinate"], FORMER_COORDINATE)
    _same_machine(machine_of(load(DEFAULT_SPEC), "coordinate"), FORMER_COORDINATE)
    assert "coordinate" not in PROTOCOLS


def test_the_shipped_spec_uses_the_built_in_protocols_and_declares_its_own() -> None:
    """The FIPA protocols the paper's channels use are the built-in ones; coordinate (the
    paper's a_co/a_ta protocol) and roco-notify (a_hi's notices, one inform) are declared in
    the specification's table, as is any protocol an agent added to it declares (docs/spec.md's
    walk-through: ``kitchen-warning``)."""
    protocols = protocols_of(DEFAULT_SPEC)
    assert set(protocols) == set(load(DEFAULT_SPEC).protocols)
    tables = read_raw(DEFAULT_SPEC)["protocols"]
    for name, protocol in protocols.items():
        if name in PROTOCOLS:
            assert protocol is PROTOCOLS[name]
            assert tables[name] == {}, name  # the role lists come from the machine
        else:
            assert declares_state_machine(tables[name]), name
    assert {"fipa-request", "fipa-query", "fipa-subscribe", "coordinate"} <= set(protocols)
    assert {"fipa-request", "fipa-query", "fipa-subscribe"} <= set(PROTOCOLS)
    notify = protocols["roco-notify"]
    assert "roco-notify" not in PROTOCOLS and notify.final == {"told"}


def test_a_declared_machine_replaces_the_built_in_one() -> None:
    protocols = protocols_of(FIXTURES / "deadlock_protocol.toml")
    assert protocols["fipa-request"] is PROTOCOLS["fipa-request"]
    coordinate = protocols["coordinate"]
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
        "unknown key(s) transition; known: cancellable, crossing, description, final, initial, "
        "initiator, participant, spec, terminal, transitions; remove or rename it",
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
    "crossing joins the machine's states": Rule(
        _with(crossing=[["agreed", "initiator", "cancel", "limbo"]]),
        'crossing transition 1 ["agreed", "initiator", "cancel", "limbo"]: \'limbo\' is no state of '
        "the transitions; a crossing transition joins states the transitions name: name one of them, "
        "or add a transition into it",
        "is no state of the transitions",
    ),
    "crossing only where no transition is": Rule(
        _with(crossing=[["requested", "participant", "agree", "agreed"]]),
        'crossing transition 1 ["requested", "participant", "agree", "agreed"] is also transition 3: a '
        "crossing transition is taken only where no transition is (by a communicate that crossed "
        "the other party's latest); remove one of the two",
        "is also transition N",
    ),
    "crossing not the cancel meta-protocol's": Rule(
        _with(crossing=[["cancelling", "participant", "inform", "done"]]),
        'crossing transition 1 ["cancelling", "participant", "inform", "done"] is also a transition '
        "of the cancel meta-protocol ('cancellable'), which leads there to 'cancelled'; remove it",
        "is also a transition of the cancel meta-protocol",
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
        pattern = pattern.replace("K;", ".+;").replace("…", ".+").replace(r"\ N", r"\ \d+")
        assert re.search(pattern, rule.error), name


def test_a_terminal_transition_follows_the_rules_of_a_transition() -> None:
    table = {**COORDINATE_TABLE, "terminal": [["running", "participant", "infrom", "ending"]]}
    with pytest.raises(SpecError) as err:
        protocol_from_table("coordinate", table)
    assert str(err.value) == (
        'protocol coordinate: terminal transition 1 ["running", "participant", "infrom", "ending"]: '
        "'infrom' is not a FIPA performative (FIPA SC00037); did you mean 'inform'?"
    )


@pytest.mark.parametrize(
    ("crossing", "error"),
    [
        (
            [["ending", "initiator", "cancel"]],
            "crossing transition 1 ['ending', 'initiator', 'cancel']: expected [state, role, "
            "performative, state], four names",
        ),
        (
            [["ending", "initiator", "cancle", "ending"]],
            'crossing transition 1 ["ending", "initiator", "cancle", "ending"]: \'cancle\' is not a '
            "FIPA performative (FIPA SC00037); did you mean 'cancel'?",
        ),
        (
            [["ending", "initiator", "cancel", "ending"], ["ending", "initiator", "cancel", "running"]],
            'crossing transition 2 ["ending", "initiator", "cancel", "running"] conflicts with crossing '
            "transition 1: the same state, role and performative lead to 'ending' and 'running'; keep "
            "one of the two",
        ),
        (
            [["finished", "initiator", "cancel", "finished"]],
            'crossing transition 1 ["finished", "initiator", "cancel", "finished"] leaves the final '
            "state 'finished'; remove it, or take 'finished' out of 'final'",
        ),
        (
            [["ending", "participant", "propose", "ending"]],
            'crossing transition 1 ["ending", "participant", "propose", "ending"]: the participant may '
            "not send 'propose' ('participant' lists failure, inform, refuse); add it to "
            "'participant', or change the transition",
        ),
        ("cancel", "'crossing' must be a list of [state, role, performative, state]"),
    ],
)
def test_a_crossing_transition_follows_the_rules_of_a_transition(crossing: object, error: str) -> None:
    table = {**COORDINATE_TABLE, "participant": ["inform", "refuse", "failure"], "crossing": crossing}
    with pytest.raises(SpecError) as err:
        protocol_from_table("coordinate", table)
    assert str(err.value) == f"protocol coordinate: {error}"


def test_a_crossing_transition_is_taken_only_by_a_communicate_that_crossed() -> None:
    """coordinate's one crossing transition: a_co's cancel that crossed a_ta's terminal inform
    (paper §5.4): in 'ending' a cancel is no transition, only a crossing one."""
    coordinate = protocol_from_table("coordinate", COORDINATE_TABLE)
    assert coordinate.next_state("ending", "initiator", Performative.CANCEL) is None
    assert coordinate.next_state("ending", "initiator", Performative.CANCEL, crossing=True) == "ending"
    assert ("initiator", Performative.CANCEL, False) not in coordinate.allowed("ending")


# ---------------------------------------------------------------- role lists from the machine

SHIPPED_LISTS = {
    "fipa-request": (("request", "cancel"), ("refuse", "agree", "failure", "inform")),
    "fipa-query": (
        ("query-ref", "query-if", "cancel"),
        ("refuse", "agree", "failure", "inform", "inform-ref"),
    ),
    "fipa-subscribe": (("subscribe", "cancel"), ("refuse", "agree", "inform", "failure")),
    "coordinate": (("request", "confirm", "cancel"), ("inform", "refuse", "failure")),
    "roco-notify": (("inform",), ()),
}
"""What each role of the shipped protocols may send: the lists the tables gave before they were
left to the machines (the same sets), in the order the machines' transitions name them."""


def test_a_table_without_role_lists_gets_what_its_machine_lets_each_role_send() -> None:
    spec = load(DEFAULT_SPEC)
    tables = read_raw(DEFAULT_SPEC)["protocols"]
    # the shipped protocols (a copy may add its own, as the new-agent walk-through's does)
    assert {
        name: (roles.initiator, roles.participant)
        for name, roles in spec.protocols.items()
        if name in SHIPPED_LISTS
    } == SHIPPED_LISTS
    for name in ("fipa-request", "fipa-query", "fipa-subscribe", "coordinate"):
        assert "initiator" not in tables[name] and "participant" not in tables[name], name
        assert role_lists(name, tables[name]) == SHIPPED_LISTS[name]


def test_derived_lists_count_terminal_and_crossing_transitions_and_never_not_understood() -> None:
    table = {
        "final": ["done"],
        "transitions": [
            ["start", "initiator", "request", "asked"],
            ["asked", "participant", "agree", "done"],
        ],
        "terminal": [["asked", "participant", "inform", "done"]],
        "crossing": [["asked", "initiator", "confirm", "asked"]],
    }
    assert role_lists("ask", table) == (("request", "confirm"), ("agree", "inform"))
    assert role_lists("ask", {**table, "cancellable": ["asked"]}) == (
        ("request", "cancel", "confirm"),
        ("agree", "inform", "failure"),
    )
    # a built-in machine: FIPA's fipa-propose (SC00036)
    assert role_lists("fipa-propose", {}) == (("propose",), ("accept-proposal", "reject-proposal"))


def _planted(tmp_path: Path, table: str) -> Path:
    """The shipped specification with ``table`` (a [protocols.NAME] table) added."""
    path = tmp_path / "spec.toml"
    path.write_text(DEFAULT_SPEC.read_text() + "\n" + table)
    return path


def test_an_explicit_list_is_kept_and_may_narrow_a_built_in_machine(tmp_path: Path) -> None:
    text = DEFAULT_SPEC.read_text().replace(
        "[protocols.fipa-request]  # FIPA SC00026\n",
        '[protocols.fipa-request]  # FIPA SC00026\ninitiator = ["request"]\n',
    )
    path = tmp_path / "narrow.toml"
    path.write_text(text)
    roles = load(path).protocols["fipa-request"]
    assert roles.initiator == ("request",)
    assert roles.participant == SHIPPED_LISTS["fipa-request"][1]
    assert role_mismatches(PROTOCOLS["fipa-request"], roles) == [
        "fipa-request: the state machine lets the initiator send 'cancel', which "
        "protocols.fipa-request.initiator does not list (the runtime would reject it)"
    ]


def test_lists_from_a_broken_machine_or_none_fail_the_load_naming_the_protocol(tmp_path: Path) -> None:
    broken = _planted(
        tmp_path,
        '[protocols.ask]\nfinal = ["done"]\ntransitions = [["start", "initiator", "reqest", "done"]]\n',
    )
    with pytest.raises(SpecError) as err:
        load(broken)
    assert str(err.value) == (
        f'{broken}: protocol ask: transition 1 ["start", "initiator", "reqest", "done"]: \'reqest\' '
        "is not a FIPA performative (FIPA SC00037); did you mean 'request'?"
    )
    none = _planted(tmp_path, "[protocols.handshake]\n")
    with pytest.raises(SpecError) as err:
        load(none)
    assert str(err.value) == (
        f"{none}: protocol handshake declares no state machine (cancellable, crossing, final, "
        f"initial, terminal, transitions) and is not a built-in protocol ({', '.join(PROTOCOLS)}); "
        "declare its state machine in [protocols.handshake] (docs/spec.md), or use a built-in protocol"
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
    walk = Walk(notify)
    assert walk.step("initiator", "inform") == "told" and walk.is_finished


def test_a_state_after_the_first_brings_not_understood_back() -> None:
    table = {**NOTIFY_TABLE, "participant": ["confirm"]}
    table["transitions"] = [*NOTIFY_TABLE["transitions"], ["told", "participant", "confirm", "confirmed"]]
    table["final"] = ["confirmed"]
    tell = protocol_from_table("tell", table)
    assert tell.states == {"start", "told", "confirmed", "not-understood"}
    assert tell.next_state("told", "initiator", Performative.NOT_UNDERSTOOD) == "not-understood"
    assert tell.next_state("start", "initiator", Performative.NOT_UNDERSTOOD) is None


def test_a_protocol_neither_declared_nor_built_in_is_an_error(tmp_path: Path) -> None:
    path = _planted(tmp_path, '[protocols.handshake]\ninitiator = ["request"]\nparticipant = ["inform"]\n')
    error = (
        "protocol handshake declares no state machine (cancellable, crossing, final, initial, "
        f"terminal, transitions) and is not a built-in protocol ({', '.join(PROTOCOLS)}); declare "
        "its state machine in [protocols.handshake] (docs/spec.md), or use a built-in protocol"
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
    now has those transitions (and the lists now come from the machines)."""
    spec = load(DEFAULT_SPEC)
    for name in ("fipa-request", "fipa-query", "fipa-subscribe", "coordinate"):
        assert role_mismatches(machine_of(spec, name), spec.protocols[name]) == []
