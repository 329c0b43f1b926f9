"""Interaction protocols (FIPA SC00026-SC00036, paper §5.4 coordinate) as state machines, and
conversations followed through them by the runtime's rules (services/runtime/protocol_state.py
``judge``; walked with tests/support/conversation.py).

A path is walked *linked* (each message names the other side's latest in its in-reply-to: it
was sent after its sender saw all the other had sent, so nothing crossed on the wire) unless it
relies on a crossing (:data:`CROSSING_PATHS`: an agree or a refuse sent before the cancel
arrived, an auction's price or end called before a bid arrived, a cancel sent before
coordinate's terminal inform arrived), which only an unlinked walk takes.
"""

from __future__ import annotations

from collections.abc import Mapping

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from shared.fipa_codec.protocols import INITIATOR as I_
from shared.fipa_codec.protocols import PARTICIPANT as R_
from shared.fipa_codec.protocols import (
    PROTOCOLS,
    Protocol,
    ProtocolViolation,
    Role,
    is_terminal_report,
)
from tests.support.conversation import NOT_UNDERSTOOD, Walk, protocol_named

P = Performative

Step = tuple[Role, Performative] | tuple[Role, Performative, bool]
"""A message: (sender's role, performative), or with ``terminal`` (coordinate's informs)."""
Path = list[Step]
Key = tuple[str, Role, Performative]

FIPA_LIBRARY = {
    "fipa-request",
    "fipa-query",
    "fipa-subscribe",
    "fipa-request-when",
    "fipa-contract-net",
    "fipa-iterated-contract-net",
    "fipa-english-auction",
    "fipa-dutch-auction",
    "fipa-brokering",
    "fipa-recruiting",
    "fipa-propose",
}
"""The eleven protocols of the FIPA interaction protocol library (SC00025)."""

HAPPY_PATHS: dict[str, list[Path]] = {
    "fipa-request": [
        [(I_, P.REQUEST), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.REQUEST), (R_, P.INFORM)],  # agree skipped
        [(I_, P.REQUEST), (R_, P.REFUSE)],
        [(I_, P.REQUEST), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.REQUEST), (R_, P.FAILURE)],
        [(I_, P.REQUEST), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.REQUEST), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.REQUEST), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-query": [
        # a query-ref is answered by inform (inform-result) or inform-ref
        [(I_, P.QUERY_REF), (R_, P.INFORM)],
        [(I_, P.QUERY_REF), (R_, P.INFORM_REF)],
        [(I_, P.QUERY_REF), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.QUERY_REF), (R_, P.AGREE), (R_, P.INFORM_REF)],
        [(I_, P.QUERY_REF), (R_, P.REFUSE)],
        [(I_, P.QUERY_REF), (R_, P.FAILURE)],
        [(I_, P.QUERY_REF), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.QUERY_REF), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.QUERY_REF), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.FAILURE)],
        # a query-if is answered by inform (inform-t/f) only
        [(I_, P.QUERY_IF), (R_, P.INFORM)],
        [(I_, P.QUERY_IF), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.QUERY_IF), (R_, P.REFUSE)],
        [(I_, P.QUERY_IF), (R_, P.FAILURE)],
        [(I_, P.QUERY_IF), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.QUERY_IF), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.QUERY_IF), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.QUERY_IF), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-request-when": [
        [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.REQUEST_WHEN), (R_, P.REFUSE)],
        [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.REQUEST_WHEN), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (I_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-subscribe": [
        [(I_, P.SUBSCRIBE), (R_, P.AGREE), (R_, P.INFORM), (R_, P.INFORM), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.SUBSCRIBE), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.SUBSCRIBE), (R_, P.REFUSE)],
        [(I_, P.SUBSCRIBE), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.SUBSCRIBE), (R_, P.AGREE), (R_, P.INFORM), (I_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-contract-net": [
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (R_, P.INFORM)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (R_, P.FAILURE)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.REJECT_PROPOSAL)],
        [(I_, P.CFP), (R_, P.REFUSE)],
        # the initiator may cancel at any point (SC00029 §2): before a proposal, after one
        # and after accepting it
        [(I_, P.CFP), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-iterated-contract-net": [
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (R_, P.INFORM)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (R_, P.FAILURE)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.REJECT_PROPOSAL)],
        [(I_, P.CFP), (R_, P.REFUSE)],
        # re-iterated twice with a revised cfp, then refused
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.CFP), (R_, P.REFUSE)],
        [
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.ACCEPT_PROPOSAL),
            (I_, P.CANCEL),
            (R_, P.INFORM),
        ],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (I_, P.CANCEL), (R_, P.FAILURE)],
        # the initiator may cancel at any point (SC00030 §2)
        [(I_, P.CFP), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.CFP), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-english-auction": [
        # start-auction, a price, a bid taken, a higher price nobody bids, end, the winner asked
        [
            (I_, P.INFORM),
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.ACCEPT_PROPOSAL),
            (I_, P.CFP),
            (I_, P.INFORM),
            (I_, P.REQUEST),
        ],
        [(I_, P.INFORM), (I_, P.CFP), (I_, P.CFP), (I_, P.INFORM)],  # never bid
        # a bid too late, a bid taken, then outbid
        [
            (I_, P.INFORM),
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.REJECT_PROPOSAL),
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.ACCEPT_PROPOSAL),
            (I_, P.CFP),
            (I_, P.REJECT_PROPOSAL),
            (I_, P.INFORM),
        ],
        [(I_, P.INFORM), (I_, P.CFP), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-dutch-auction": [
        [
            (I_, P.INFORM),
            (I_, P.CFP),
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.ACCEPT_PROPOSAL),
            (I_, P.INFORM),
            (I_, P.REQUEST),
        ],
        [(I_, P.INFORM), (I_, P.CFP), (I_, P.CFP), (I_, P.INFORM)],  # never bid
        [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.REJECT_PROPOSAL), (I_, P.INFORM)],
        [(I_, P.INFORM), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-brokering": [
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.PROXY), (R_, P.REFUSE)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.PROXY), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-recruiting": [
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.PROXY), (R_, P.REFUSE)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.PROXY), (R_, P.AGREE), (I_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-propose": [
        [(I_, P.PROPOSE), (R_, P.ACCEPT_PROPOSAL)],
        [(I_, P.PROPOSE), (R_, P.REJECT_PROPOSAL)],
        [(I_, P.PROPOSE), (R_, P.NOT_UNDERSTOOD)],
    ],
    "coordinate": [
        [
            (I_, P.REQUEST),
            (R_, P.INFORM, False),
            (I_, P.CONFIRM),
            (R_, P.INFORM, False),
            (I_, P.CONFIRM),
            (R_, P.INFORM, True),
            (I_, P.CONFIRM),
        ],
        [(I_, P.REQUEST), (R_, P.INFORM, True), (I_, P.CONFIRM)],  # at once Error
        [(I_, P.REQUEST), (R_, P.REFUSE)],  # no plan in the request
        [(I_, P.REQUEST), (R_, P.FAILURE)],
        [
            (I_, P.REQUEST),
            (R_, P.INFORM, False),
            (I_, P.CONFIRM),
            (I_, P.CANCEL),
            (R_, P.INFORM, False),
            (I_, P.CONFIRM),
            (R_, P.INFORM, True),
            (I_, P.CONFIRM),
        ],
        # cancelled before the first report is confirmed
        [
            (I_, P.REQUEST),
            (R_, P.INFORM, False),
            (I_, P.CANCEL),
            (I_, P.CONFIRM),
            (R_, P.INFORM, True),
            (I_, P.CONFIRM),
        ],
        [(I_, P.REQUEST), (R_, P.INFORM, False), (I_, P.NOT_UNDERSTOOD)],
        # a_co confirms again (it probes an a_ta that reappears); the plan goes on
        [
            (I_, P.REQUEST),
            (R_, P.INFORM, False),
            (I_, P.CONFIRM),
            (I_, P.CONFIRM),
            (R_, P.INFORM, True),
            (I_, P.CONFIRM),
        ],
    ],
}
"""Paths every message of which was sent after its sender saw all the other had sent (walked
linked), by protocol."""

CROSSING_PATHS: dict[str, list[Path]] = {
    "fipa-request": [
        # the agree was sent before the cancel arrived; the cancel is then answered (SC00026 §2)
        [(I_, P.REQUEST), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.REQUEST), (I_, P.CANCEL), (R_, P.REFUSE)],  # the refuse crossed the cancel
    ],
    "fipa-query": [
        [(I_, P.QUERY_IF), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.QUERY_REF), (I_, P.CANCEL), (R_, P.REFUSE)],
        [(I_, P.QUERY_REF), (I_, P.CANCEL), (R_, P.INFORM_REF)],  # the answer crossed the cancel
    ],
    "fipa-request-when": [
        [(I_, P.REQUEST_WHEN), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.REQUEST_WHEN), (I_, P.CANCEL), (R_, P.REFUSE)],
    ],
    "fipa-subscribe": [
        [(I_, P.SUBSCRIBE), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.SUBSCRIBE), (I_, P.CANCEL), (R_, P.REFUSE)],
    ],
    "fipa-contract-net": [
        # the proposal was sent before the cancel arrived; the cancel is then answered
        [(I_, P.CFP), (I_, P.CANCEL), (R_, P.PROPOSE), (R_, P.INFORM)],
        [(I_, P.CFP), (I_, P.CANCEL), (R_, P.REFUSE)],
    ],
    "fipa-iterated-contract-net": [
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.CFP), (I_, P.CANCEL), (R_, P.PROPOSE), (R_, P.FAILURE)],
        [(I_, P.CFP), (I_, P.CANCEL), (R_, P.REFUSE)],
    ],
    "fipa-english-auction": [
        # the next price crossed the bid on the wire; the bid still wins
        [
            (I_, P.INFORM),
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.CFP),
            (I_, P.ACCEPT_PROPOSAL),
            (I_, P.INFORM),
            (I_, P.REQUEST),
        ],
        [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.INFORM)],  # the end crossed the bid
    ],
    "fipa-dutch-auction": [
        # a lower price crossed the bid on the wire; the bid still wins
        [
            (I_, P.INFORM),
            (I_, P.CFP),
            (R_, P.PROPOSE),
            (I_, P.CFP),
            (I_, P.ACCEPT_PROPOSAL),
            (I_, P.INFORM),
            (I_, P.REQUEST),
        ],
        [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.INFORM)],  # the end crossed the bid
    ],
    "fipa-brokering": [
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],  # agree crossed the cancel
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.REFUSE)],  # refuse crossed the cancel
    ],
    "fipa-recruiting": [
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.REFUSE)],
    ],
    "coordinate": [
        # a_co's second cancel crossed a_ta's terminal inform, which a_co then confirms
        [(I_, P.REQUEST), (I_, P.CANCEL), (R_, P.INFORM, True), (I_, P.CANCEL), (I_, P.CONFIRM)],
    ],
}
"""Paths one message of which crossed another on the wire (walked unlinked), by protocol."""


def _machine(name: str) -> Protocol:
    """The codec's machine of ``name`` (FIPA's library), else the one the shipped
    specification declares (coordinate)."""
    return PROTOCOLS[name] if name in PROTOCOLS else protocol_named(name)


def _terminal(step: Step) -> bool:
    """Whether ``step`` is an inform flagged terminal."""
    return len(step) > 2 and bool(step[2])


def _run(name: str, steps: Path, *, linked: bool) -> Walk:
    walk = Walk(_machine(name), linked=linked)
    for step in steps:
        walk.step(step[0], step[1], terminal=_terminal(step))
    return walk


def _arrival(protocol: Protocol, steps: Path, *, crossing: bool) -> tuple[list[tuple[str, Key]], str]:
    """The machine's transitions ``steps`` take in arrival order, each as (table, key), where
    the table is ``transition``, ``terminal`` or (with ``crossing``) ``crossing``; and the
    state they end in. AssertionError when the machine has none for a step."""
    tables: dict[str, Mapping[Key, str]] = {
        "terminal": protocol.terminal_transitions,
        "transition": protocol.transitions,
        "crossing": protocol.crossing_transitions if crossing else {},
    }
    state = protocol.initial
    taken: list[tuple[str, Key]] = []
    for step in steps:
        key: Key = (state, step[0], step[1])
        kinds = [k for k, table in tables.items() if key in table and (k != "terminal" or _terminal(step))]
        assert kinds, f"{protocol.name}: no transition for {key} in {steps}"
        taken.append((kinds[0], key))
        state = tables[kinds[0]][key]
    return taken, state


def _paths(name: str) -> list[tuple[Path, bool]]:
    """Every path of ``name``, with True for one that relies on a crossing."""
    return [(p, False) for p in HAPPY_PATHS[name]] + [(p, True) for p in CROSSING_PATHS.get(name, [])]


def test_the_codec_holds_the_fipa_library_and_every_protocol_has_paths() -> None:
    assert set(PROTOCOLS) == FIPA_LIBRARY  # coordinate is the specification's
    # the FIPA interaction protocol library (SC00025): all eleven of its protocols
    assert {p.spec for p in PROTOCOLS.values() if p.spec.startswith("FIPA")} == {
        f"FIPA SC000{n}" for n in range(26, 37)
    }
    assert set(HAPPY_PATHS) == FIPA_LIBRARY | {"coordinate"}
    assert set(CROSSING_PATHS) <= set(HAPPY_PATHS)
    for name in HAPPY_PATHS:
        protocol = _machine(name)
        assert protocol.name == name
        assert protocol.spec and protocol.description


def _fails_a_cancel(name: str, steps: Path) -> bool:
    return _arrival(_machine(name), steps, crossing=False)[1] == "cancel-failed"


@pytest.mark.parametrize(
    ("name", "steps"),
    [
        (name, steps)
        for name, paths in HAPPY_PATHS.items()
        for steps in paths
        if not _fails_a_cancel(name, steps)
    ],
)
def test_a_happy_path_ends_the_conversation_and_nothing_follows_its_end(name: str, steps: Path) -> None:
    """Walked linked, every path ends in a final state; after the end nothing more belongs to
    the conversation, whoever sends it (judge): no outcome, no cancel of what has ended."""
    walk = _run(name, steps, linked=True)
    assert walk.is_finished, walk.states
    assert walk.states == {walk.state} and walk.state in walk.protocol.final
    assert len(walk.history) == len(steps) and walk.crossings == 0
    probes = [(I_, P.INFORM), (R_, P.INFORM), (R_, P.FAILURE), (I_, P.CANCEL)]
    if walk.state == NOT_UNDERSTOOD:  # its sender's (the other's: see the test below)
        probes = [(role, perf) for role, perf in probes if role == steps[-1][0]]
    for role, perf in probes:
        with pytest.raises(ProtocolViolation):
            walk.step(role, perf)
        assert len(walk.history) == len(steps) and walk.is_finished


@pytest.mark.parametrize(
    ("name", "steps", "answer"),
    [
        ("fipa-request", [(I_, P.REQUEST), (R_, P.NOT_UNDERSTOOD)], (I_, P.CANCEL)),
        ("fipa-request-when", [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (I_, P.NOT_UNDERSTOOD)], (R_, P.INFORM)),
    ],
)
def test_a_communicate_sent_after_seeing_a_not_understood_is_refused(
    name: str, steps: Path, answer: tuple[Role, Performative]
) -> None:
    """The not-understood ended the conversation (FIPA SC00037 §3.12; judge): a communicate
    whose in-reply-to names it was sent after its sender saw the end, so it does not belong to
    the conversation (only one sent before the not-understood arrived does)."""
    walk = _run(name, steps, linked=True)
    with pytest.raises(ProtocolViolation):
        walk.step(*answer)


@pytest.mark.parametrize(
    ("name", "steps"),
    [(name, steps) for name, paths in HAPPY_PATHS.items() for steps in paths if _fails_a_cancel(name, steps)],
)
def test_a_failed_cancel_leaves_the_conversation_going_on_where_the_cancel_found_it(
    name: str, steps: Path
) -> None:
    """FIPA SC00026 §2 (and each cancellable protocol's §2): the participant answers a cancel
    by failure when "the cancellation has failed": the machine's cancel-failed, and the
    conversation goes on from where the cancel found it."""
    protocol = _machine(name)
    walk = _run(name, steps, linked=True)
    found = _arrival(protocol, steps[: [s[1] for s in steps].index(P.CANCEL)], crossing=False)[1]
    assert walk.state == "cancel-failed" and walk.states == {"cancel-failed", found}
    assert not walk.is_finished and walk.may_be_finished


@pytest.mark.parametrize(
    ("name", "steps"),
    [(name, steps) for name, paths in CROSSING_PATHS.items() for steps in paths],
)
def test_a_path_that_relies_on_a_crossing_is_followed_only_unlinked(name: str, steps: Path) -> None:
    """Unlinked, the message that crossed is placed by reordering (or takes a crossing
    transition) and the conversation may have ended; linked (each message sent after seeing
    the other side's latest) the same path breaks the protocol."""
    walk = _run(name, steps, linked=False)
    assert walk.crossings >= 1 and walk.may_be_finished
    assert walk.state == _arrival(walk.protocol, steps, crossing=True)[1]
    with pytest.raises(ProtocolViolation):
        _run(name, steps, linked=True)


@pytest.mark.parametrize(
    ("name", "steps", "crossed"),
    [
        # a query-if is answered by inform, never inform-ref (SC00027 §2)
        ("fipa-query", [(I_, P.QUERY_IF), (I_, P.CANCEL)], (R_, P.INFORM_REF)),
        # the participant agrees once (SC00026 §2)
        ("fipa-request", [(I_, P.REQUEST), (R_, P.AGREE), (I_, P.CANCEL)], (R_, P.AGREE)),
        # a refuse answers the subscription, not what follows the agree (SC00035 §2)
        ("fipa-subscribe", [(I_, P.SUBSCRIBE), (R_, P.AGREE), (I_, P.CANCEL)], (R_, P.REFUSE)),
        # an accepted participant reports inform or failure, it no longer refuses (SC00029 §2)
        (
            "fipa-contract-net",
            [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (I_, P.CANCEL)],
            (R_, P.REFUSE),
        ),
    ],
)
def test_what_crossed_a_cancel_is_what_the_participant_could_send_where_the_cancel_found_it(
    name: str, steps: Path, crossed: tuple[Role, Performative]
) -> None:
    """An answer sent before the cancel arrived was sent where the cancel found the
    conversation, so the protocol must allow it there (walked unlinked: any crossing may be
    taken)."""
    walk = _run(name, steps, linked=False)
    with pytest.raises(ProtocolViolation):
        walk.step(*crossed)


@pytest.mark.parametrize(
    ("name", "steps", "bad"),
    [
        ("fipa-request", [], (R_, P.INFORM)),  # inform before request
        ("fipa-request", [], (I_, P.QUERY_REF)),
        ("fipa-request", [(I_, P.REQUEST)], (I_, P.REQUEST)),
        ("fipa-request", [(I_, P.REQUEST)], (I_, P.INFORM)),  # wrong role
        ("fipa-request", [(I_, P.REQUEST), (R_, P.AGREE)], (R_, P.AGREE)),
        ("fipa-request", [(I_, P.REQUEST), (R_, P.AGREE)], (R_, P.REFUSE)),
        ("fipa-request", [(I_, P.REQUEST), (I_, P.CANCEL)], (I_, P.CANCEL)),
        ("fipa-request", [(I_, P.REQUEST), (I_, P.CANCEL)], (R_, P.AGREE)),  # agree seeing the cancel
        ("fipa-request", [(I_, P.REQUEST), (R_, P.INFORM)], (I_, P.CANCEL)),  # cancel seeing the end
        ("fipa-request", [], (I_, P.NOT_UNDERSTOOD)),  # nothing to misunderstand yet
        ("fipa-request", [(I_, P.REQUEST)], (I_, P.NOT_UNDERSTOOD)),  # the initiator received nothing
        ("fipa-query", [], (I_, P.REQUEST)),
        ("fipa-query", [(I_, P.QUERY_IF)], (R_, P.INFORM_IF)),
        ("fipa-query", [(I_, P.QUERY_IF)], (R_, P.INFORM_REF)),  # a query-if is answered by inform
        ("fipa-query", [(I_, P.QUERY_IF), (R_, P.AGREE)], (R_, P.INFORM_REF)),
        ("fipa-request-when", [(I_, P.REQUEST_WHEN)], (R_, P.INFORM)),  # agree required
        ("fipa-subscribe", [(I_, P.SUBSCRIBE)], (R_, P.INFORM)),  # agree required
        ("fipa-subscribe", [(I_, P.SUBSCRIBE), (R_, P.AGREE)], (I_, P.CONFIRM)),
        ("fipa-contract-net", [(I_, P.CFP)], (R_, P.ACCEPT_PROPOSAL)),
        ("fipa-contract-net", [(I_, P.CFP), (R_, P.PROPOSE)], (R_, P.INFORM)),
        # a revised cfp is fipa-iterated-contract-net's (SC00030), not this protocol's (SC00029)
        ("fipa-contract-net", [(I_, P.CFP), (R_, P.PROPOSE)], (I_, P.CFP)),
        ("fipa-contract-net", [(I_, P.CFP), (I_, P.CANCEL)], (R_, P.PROPOSE)),  # seeing the cancel
        ("fipa-iterated-contract-net", [(I_, P.CFP)], (I_, P.CFP)),  # a revised cfp needs a proposal
        ("fipa-iterated-contract-net", [(I_, P.CFP), (R_, P.PROPOSE)], (R_, P.PROPOSE)),
        ("fipa-iterated-contract-net", [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL)], (I_, P.CFP)),
        ("fipa-iterated-contract-net", [(I_, P.CFP)], (R_, P.CANCEL)),  # only the initiator cancels
        ("fipa-english-auction", [], (I_, P.CFP)),  # a price before start-auction
        ("fipa-english-auction", [(I_, P.INFORM)], (R_, P.PROPOSE)),  # a bid before a price
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP)], (I_, P.ACCEPT_PROPOSAL)),  # no bid
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE)], (R_, P.PROPOSE)),
        # a bid seen is accepted or rejected before the next price or the end: only a price or
        # the end called before the bid arrived goes without (CROSSING_PATHS)
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE)], (I_, P.CFP)),
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE)], (I_, P.INFORM)),
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP)], (I_, P.REQUEST)),  # not the winner
        (
            "fipa-english-auction",
            [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL)],
            (R_, P.PROPOSE),  # the leader does not outbid itself
        ),
        (
            "fipa-english-auction",
            [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL)],
            (I_, P.REQUEST),  # the winner is asked once the auction has ended
        ),
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP)], (I_, P.CANCEL)),
        ("fipa-dutch-auction", [(I_, P.INFORM)], (R_, P.PROPOSE)),
        ("fipa-dutch-auction", [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE)], (I_, P.CFP)),
        (
            "fipa-dutch-auction",
            [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.REJECT_PROPOSAL)],
            (I_, P.CFP),  # another bid won: no lower price
        ),
        (
            "fipa-dutch-auction",
            [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.REJECT_PROPOSAL)],
            (I_, P.REQUEST),  # not the winner
        ),
        (
            "fipa-dutch-auction",
            [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL)],
            (I_, P.CFP),  # the first bid won: the price falls no further
        ),
        ("fipa-dutch-auction", [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE)], (R_, P.PROPOSE)),
        ("fipa-brokering", [], (I_, P.REQUEST)),
        ("fipa-brokering", [(I_, P.PROXY)], (R_, P.INFORM)),  # agree required
        ("fipa-brokering", [(I_, P.PROXY), (R_, P.AGREE)], (R_, P.AGREE)),
        ("fipa-brokering", [(I_, P.PROXY)], (I_, P.PROXY)),
        ("fipa-brokering", [(I_, P.PROXY), (I_, P.CANCEL)], (R_, P.REFUSE)),  # seeing the cancel
        ("fipa-recruiting", [(I_, P.PROXY)], (R_, P.INFORM)),  # agree required
        ("fipa-recruiting", [(I_, P.PROXY), (R_, P.AGREE)], (R_, P.REFUSE)),
        ("fipa-recruiting", [(I_, P.PROXY), (R_, P.AGREE)], (I_, P.PROXY)),
        ("fipa-propose", [(I_, P.PROPOSE)], (I_, P.ACCEPT_PROPOSAL)),
        ("fipa-propose", [(I_, P.PROPOSE)], (I_, P.CANCEL)),
        ("coordinate", [], (I_, P.CONFIRM)),
        ("coordinate", [(I_, P.REQUEST)], (I_, P.CONFIRM)),  # confirm without inform
        ("coordinate", [(I_, P.REQUEST)], (R_, P.CONFIRM)),
        ("coordinate", [(I_, P.REQUEST), (R_, P.INFORM)], (R_, P.INFORM)),  # unconfirmed
        # the terminal state's confirm ends the conversation: nothing to confirm again
        ("coordinate", [(I_, P.REQUEST), (R_, P.INFORM, True), (I_, P.CONFIRM)], (I_, P.CONFIRM)),
        # a cancel after the terminal inform arrived: only one that crossed it is taken
        ("coordinate", [(I_, P.REQUEST), (R_, P.INFORM, True)], (I_, P.CANCEL)),
        ("coordinate", [(I_, P.REQUEST), (R_, P.INFORM)], (R_, P.FAILURE)),  # failure once running
        ("coordinate", [(I_, P.REQUEST)], (R_, P.CANCEL)),
        ("coordinate", [(I_, P.REQUEST), (R_, P.INFORM, True)], (R_, P.INFORM)),
    ],
)
def test_a_message_the_protocol_does_not_allow_is_refused_and_changes_nothing(
    name: str, steps: Path, bad: tuple[Role, Performative]
) -> None:
    """Walked linked: each message was sent after its sender saw the other's latest, so no
    crossing excuses it."""
    walk = _run(name, steps, linked=True)
    before = (walk.state, list(walk.history))
    with pytest.raises(ProtocolViolation) as info:
        walk.step(*bad)
    exc = info.value
    assert (exc.protocol, exc.state, exc.role, exc.performative) == (name, before[0], *bad)
    assert f"the {bad[0]} may not send {bad[1].value!r}" in str(exc)
    assert (walk.state, walk.history) == before  # unchanged
    assert isinstance(exc, ValueError)


@pytest.mark.parametrize("name", list(HAPPY_PATHS))
def test_every_branch_is_taken(name: str) -> None:
    """The paths take every transition of the machine (not-understood aside:
    test_machine_is_well_formed), terminal and crossing ones included, and end in every final
    state."""
    protocol = _machine(name)
    untaken, ended = _branches(protocol, _paths(name))
    assert untaken == {}
    assert ended == set(protocol.final)


def _branches(
    protocol: Protocol, paths: list[tuple[Path, bool]]
) -> tuple[dict[tuple[str, Key], str], set[str]]:
    """The transitions (not-understood aside) ``paths`` (each with whether it relies on a
    crossing) leave untaken, by (table, key), and the states they end in."""
    tables = {
        "transition": protocol.transitions,
        "terminal": protocol.terminal_transitions,
        "crossing": protocol.crossing_transitions,
    }
    untaken = {
        (kind, key): target
        for kind, table in tables.items()
        for key, target in table.items()
        if key[2] is not P.NOT_UNDERSTOOD
    }
    ended: set[str] = set()
    for steps, crossing in paths:
        taken, end = _arrival(protocol, steps, crossing=crossing)
        for edge in taken:
            untaken.pop(edge, None)
        ended.add(end)
    return untaken, ended


def test_the_branch_check_sees_a_branch_left_out() -> None:
    """Planted: the English auction's paths without the bid that the auction's end crossed."""
    protocol = PROTOCOLS["fipa-english-auction"]
    paths = [(p, c) for p, c in _paths(protocol.name) if p[-2:] != [(R_, P.PROPOSE), (I_, P.INFORM)]]
    untaken, ended = _branches(protocol, paths)
    assert untaken == {("crossing", ("bid", I_, P.INFORM)): "ended"}
    assert ended == set(protocol.final)


def test_a_not_understood_comes_from_the_receiver_of_a_communicate_and_ends_the_conversation() -> None:
    """FIPA SC00037 §3.12: the sender of not-understood tells the receiver it did not
    understand what the receiver did; so only a party that received a communicate (and has not
    answered with not-understood yet) may send one, also of the message that ended the
    conversation (a malformed final inform). It ends the conversation (judge)."""
    walk = Walk("fipa-request", linked=True)
    walk.step(I_, P.REQUEST)
    with pytest.raises(ProtocolViolation, match="received nothing"):
        walk.step(I_, P.NOT_UNDERSTOOD)
    walk.step(R_, P.INFORM)
    assert walk.state == "done" and walk.is_finished
    assert walk.step(I_, P.NOT_UNDERSTOOD) == NOT_UNDERSTOOD and walk.is_finished
    with pytest.raises(ProtocolViolation):
        walk.step(I_, P.NOT_UNDERSTOOD)  # answered already
    quiet = _run("fipa-english-auction", HAPPY_PATHS["fipa-english-auction"][1], linked=True)
    with pytest.raises(ProtocolViolation, match="received nothing"):
        quiet.step(I_, P.NOT_UNDERSTOOD)  # the participant never bid: nothing to misunderstand


def test_violation_message_lists_what_is_allowed() -> None:
    walk = Walk("fipa-request")
    with pytest.raises(ProtocolViolation) as info:
        walk.step("participant", "inform")
    assert str(info.value) == (
        "fipa-request: the participant may not send 'inform' in state 'start'; allowed: initiator request"
    )


def test_coordinate_terminal_flag() -> None:
    walk = _run("coordinate", [(I_, P.REQUEST)], linked=True)
    assert walk.step(R_, P.INFORM, terminal=False) == "reported"
    walk.step(I_, P.CONFIRM)
    assert walk.step(R_, P.INFORM, terminal=True) == "ending"
    assert not walk.is_finished
    assert walk.step(I_, P.CONFIRM) == "finished"
    assert walk.is_finished


def test_terminal_flag_is_ignored_elsewhere() -> None:
    walk = _run("fipa-request", [(I_, P.REQUEST)], linked=True)
    assert walk.step(R_, P.INFORM, terminal=True) == "done"


def test_bad_arguments() -> None:
    walk = Walk(PROTOCOLS["fipa-request"])
    with pytest.raises(ValueError, match="role"):
        walk.step("observer", P.REQUEST)
    with pytest.raises(ValueError):
        walk.step(I_, "shout")
    with pytest.raises(ValueError, match="unknown interaction protocol"):
        Walk("fipa-auction")


# -- observe: roles and terminal flag from communicates -----------------------------------


def _sw(state: SWState, reply_with: str | None = None, in_reply_to: str | None = None) -> Communicate:
    language, content = encode_content(SWStatus(state=state, plan_id="p1"))
    return Communicate(
        performative=P.INFORM,
        sender=AgentIdentifier("a_ta"),
        receiver=(AgentIdentifier("a_co"),),
        content=content,
        language=language,
        encoding="msgpack",
        protocol="coordinate",
        reply_with=reply_with,
        in_reply_to=in_reply_to,
    )


def _from(
    sender: str, perf: Performative, reply_with: str | None = None, in_reply_to: str | None = None
) -> Communicate:
    return Communicate(
        performative=perf,
        sender=AgentIdentifier(sender),
        protocol="coordinate",
        reply_with=reply_with,
        in_reply_to=in_reply_to,
    )


def test_observe_coordinate_conversation() -> None:
    """Each communicate answers the other's latest (its in-reply-to): a_co's last confirm
    answers the terminal report and ends the conversation."""
    walk = Walk("coordinate")
    walk.observe(_from("a_co", P.REQUEST, "co-0"))
    assert walk.initiator == "a_co"
    for n, state in enumerate((SWState.RUNNING, SWState.TERMINATING), start=1):
        assert walk.observe(_sw(state, f"ta-{n}", f"co-{n - 1}")) == "reported"
        assert walk.observe(_from("a_co", P.CONFIRM, f"co-{n}", f"ta-{n}")) == "running"
    assert walk.observe(_sw(SWState.PREEMPTED, "ta-3", "co-2")) == "ending"
    assert walk.observe(_from("a_co", P.CONFIRM, "co-3", "ta-3")) == "finished"
    assert walk.is_finished


def test_observe_rejects_wrong_sender_role() -> None:
    walk = Walk("coordinate")
    walk.observe(_from("a_co", P.REQUEST))
    with pytest.raises(ProtocolViolation, match="participant may not send 'confirm'"):
        walk.observe(_from("a_ta", P.CONFIRM))
    with pytest.raises(ValueError, match="without sender"):
        walk.observe(Communicate(performative=P.INFORM))


def test_is_terminal_report() -> None:
    for state in SWState:
        assert is_terminal_report(_sw(state)) == (state in TERMINAL_SW_STATES)
    assert {s.value for s in TERMINAL_SW_STATES} == {"Succeeded", "Error", "Preempted", "Replan"}
    msg = _sw(SWState.SUCCEEDED)
    assert not is_terminal_report(Communicate(performative=P.CONFIRM, content=msg.content, language="L_SW"))
    assert not is_terminal_report(Communicate(performative=P.INFORM, content=b"\x00", language="L_SW"))
    assert not is_terminal_report(Communicate(performative=P.INFORM, content=msg.content, language="L_WM"))


# -- the machines themselves ---------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(HAPPY_PATHS))
def test_machine_is_well_formed(name: str) -> None:
    p = _machine(name)
    assert p.initial in p.states and p.final <= p.states
    assert "not-understood" in p.final
    for (source, role, _perf), target in p.transitions.items():
        assert source in p.states and target in p.states and role in (I_, R_)
        assert source not in p.final
    # every non-initial, non-final state allows not-understood from both sides
    for state in p.states - p.final - {p.initial}:
        assert p.next_state(state, I_, P.NOT_UNDERSTOOD) == "not-understood"
        assert p.next_state(state, R_, P.NOT_UNDERSTOOD) == "not-understood"
    # only the initiator opens
    assert {role for role, _, _ in p.allowed(p.initial)} == {I_}
    # a crossing transition is taken only by a message that may have crossed another
    for key, target in p.crossing_transitions.items():
        assert p.next_state(*key) is None and p.next_state(*key, crossing=True) == target


@pytest.mark.parametrize("name", sorted(HAPPY_PATHS))
def test_to_dot(name: str) -> None:
    p = _machine(name)
    dot = p.to_dot()
    assert dot.startswith(f'digraph "{name}" {{') and dot.rstrip().endswith("}")
    assert f'__start -> "{p.initial}"' in dot
    assert "not-understood" not in dot
    full = p.to_dot(not_understood=True)
    assert "P: not-understood" in full and '"not-understood" [shape=doublecircle]' in full
    for final in p.final - {"not-understood"}:
        assert f'"{final}" [shape=doublecircle]' in dot


def test_coordinate_dot_marks_terminal_informs() -> None:
    dot = _machine("coordinate").to_dot()
    assert '"running" -> "ending" [label="P: inform [terminal]"]' in dot
    assert '"reported" -> "running" [label="I: confirm"]' in dot


@pytest.mark.parametrize(
    ("kwargs", "problem"),
    [
        ({"initial": "nowhere"}, "initial state"),
        ({"final": frozenset({"b", "zz"})}, "final state 'zz'"),
        ({"states": frozenset({"a", "b", "c"})}, "unreachable"),
        (
            {"transitions": {("a", "participant", P.REQUEST): "b", ("b", "initiator", P.INFORM): "a"}},
            "leaves final",
        ),
        ({"transitions": {("a", "someone", P.REQUEST): "b"}}, "unknown role"),
        ({"final": frozenset({"a"})}, "initial state is final"),
        ({"crossing_transitions": {("a", "initiator", P.REQUEST): "b"}}, "is also a transition"),
        ({"crossing_transitions": {("b", "participant", P.AGREE): "b"}}, "crossing transition leaves final"),
        ({"crossing_transitions": {("a", "participant", P.AGREE): "zz"}}, "crossing transition uses unknown"),
    ],
)
def test_bad_machines_are_rejected(kwargs: dict[str, object], problem: str) -> None:
    args: dict[str, object] = {
        "name": "t",
        "states": frozenset({"a", "b"}),
        "initial": "a",
        "final": frozenset({"b"}),
        "transitions": {("a", "initiator", P.REQUEST): "b"},
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=problem):
        Protocol(**args)  # type: ignore[arg-type]


def test_dead_end_is_rejected() -> None:
    with pytest.raises(ValueError, match="no final state can be reached from 'c'"):
        Protocol(
            name="t",
            states=frozenset({"a", "b", "c"}),
            initial="a",
            final=frozenset({"b"}),
            transitions={("a", "initiator", P.REQUEST): "b", ("a", "initiator", P.CFP): "c"},
        )


@given(st.sampled_from(sorted(HAPPY_PATHS)), st.data())
@settings(max_examples=300)
def test_random_walks_only_take_allowed_steps(name: str, data: st.DataObject) -> None:
    """Walking linked by what the machine allows where the conversation may stand never
    raises (a not-understood only from a party that received something: judge), and any
    message the machine allows nowhere it may stand does."""
    protocol = _machine(name)
    walk = Walk(protocol, linked=True)
    for _ in range(20):
        if walk.is_finished:
            break
        allowed = {(r, p, t) for state in walk.states for r, p, t in protocol.allowed(state)}
        options = sorted(
            (o for o in allowed if o[1] is not P.NOT_UNDERSTOOD or _heard(walk, o[0])),
            key=lambda o: (o[0], o[1].value, o[2]),
        )
        assert options, f"{name}: dead end in {walk.states}"
        role, perf, terminal = data.draw(st.sampled_from(options))
        walk.step(role, perf, terminal=terminal)
        if walk.state == NOT_UNDERSTOOD:  # what follows it: test_a_communicate_sent_after_seeing_…
            break
        role2 = data.draw(st.sampled_from([I_, R_]))
        perf2 = data.draw(st.sampled_from(list(P)))
        anywhere = {(r, p) for state in walk.states for r, p, _ in protocol.allowed(state)}
        if (role2, perf2) not in anywhere and perf2 is not P.NOT_UNDERSTOOD:
            with pytest.raises(ProtocolViolation):
                walk.step(role2, perf2)


def _heard(walk: Walk, role: Role) -> bool:
    """Whether ``role`` has received a communicate it may answer with not-understood."""
    return walk.tracker is not None and walk.tracker.heard(role)
