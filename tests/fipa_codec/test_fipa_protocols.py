"""Interaction protocols (FIPA SC00026-SC00036, paper §5.4 coordinate) as state machines."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from shared.fipa_codec.protocols import (
    PROTOCOLS,
    ConversationTracker,
    Protocol,
    ProtocolViolation,
    is_terminal_report,
)

P = Performative
I_, R_ = "initiator", "participant"

# Each step: (role, performative) or (role, performative, terminal)
Step = tuple

HAPPY_PATHS: dict[str, list[list[Step]]] = {
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
        [(I_, P.QUERY_REF), (R_, P.INFORM)],
        [(I_, P.QUERY_IF), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.QUERY_REF), (R_, P.REFUSE)],
        [(I_, P.QUERY_REF), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.QUERY_IF), (R_, P.FAILURE)],
        [(I_, P.QUERY_REF), (I_, P.CANCEL), (R_, P.INFORM)],
    ],
    "fipa-request-when": [
        [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.REQUEST_WHEN), (R_, P.REFUSE)],
        [(I_, P.REQUEST_WHEN), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.INFORM)],
    ],
    "fipa-subscribe": [
        [(I_, P.SUBSCRIBE), (R_, P.AGREE), (R_, P.INFORM), (R_, P.INFORM), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.SUBSCRIBE), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.SUBSCRIBE), (R_, P.REFUSE)],
        [(I_, P.SUBSCRIBE), (I_, P.CANCEL), (R_, P.FAILURE)],
    ],
    "fipa-contract-net": [
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (R_, P.INFORM)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (R_, P.FAILURE)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.REJECT_PROPOSAL)],
        [(I_, P.CFP), (R_, P.REFUSE)],
        [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL), (I_, P.CANCEL), (R_, P.INFORM)],
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
        [(I_, P.INFORM), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-brokering": [
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.PROXY), (R_, P.REFUSE)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],  # agree crossed the cancel
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.REFUSE)],  # refuse crossed the cancel
        [(I_, P.PROXY), (R_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-recruiting": [
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (R_, P.FAILURE)],
        [(I_, P.PROXY), (R_, P.REFUSE)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.INFORM)],
        [(I_, P.PROXY), (R_, P.AGREE), (I_, P.CANCEL), (R_, P.FAILURE)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.AGREE), (R_, P.INFORM)],
        [(I_, P.PROXY), (I_, P.CANCEL), (R_, P.REFUSE)],
        [(I_, P.PROXY), (R_, P.AGREE), (I_, P.NOT_UNDERSTOOD)],
    ],
    "fipa-propose": [
        [(I_, P.PROPOSE), (R_, P.ACCEPT_PROPOSAL)],
        [(I_, P.PROPOSE), (R_, P.REJECT_PROPOSAL)],
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
        [(I_, P.REQUEST), (I_, P.CANCEL), (R_, P.INFORM, True), (I_, P.CANCEL), (I_, P.CONFIRM)],
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


def _run(name: str, steps: list[Step]) -> ConversationTracker:
    tracker = ConversationTracker(name)
    for step in steps:
        tracker.step(step[0], step[1], terminal=step[2] if len(step) > 2 else False)
    return tracker


def test_registry() -> None:
    assert set(PROTOCOLS) == {
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
        "coordinate",
    }
    # the FIPA interaction protocol library (SC00025): all eleven of its protocols
    assert {p.spec for p in PROTOCOLS.values() if p.spec.startswith("FIPA")} == {
        f"FIPA SC000{n}" for n in range(26, 37)
    }
    assert set(HAPPY_PATHS) == set(PROTOCOLS)
    for name, protocol in PROTOCOLS.items():
        assert protocol.name == name
        assert protocol.spec and protocol.description


@pytest.mark.parametrize(
    ("name", "steps"),
    [(name, steps) for name, paths in HAPPY_PATHS.items() for steps in paths],
)
def test_happy_paths_reach_a_final_state(name: str, steps: list[Step]) -> None:
    tracker = _run(name, steps)
    assert tracker.is_finished, tracker.state
    assert len(tracker.history) == len(steps)
    for role, perf in [(I_, P.INFORM), (R_, P.INFORM), (R_, P.NOT_UNDERSTOOD)]:
        with pytest.raises(ProtocolViolation, match="already ended"):
            tracker.step(role, perf)


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
        ("fipa-request", [], (I_, P.NOT_UNDERSTOOD)),  # nothing to misunderstand yet
        ("fipa-query", [], (I_, P.REQUEST)),
        ("fipa-query", [(I_, P.QUERY_IF)], (R_, P.INFORM_IF)),
        ("fipa-request-when", [(I_, P.REQUEST_WHEN)], (R_, P.INFORM)),  # agree required
        ("fipa-subscribe", [(I_, P.SUBSCRIBE)], (R_, P.INFORM)),  # agree required
        ("fipa-subscribe", [(I_, P.SUBSCRIBE), (R_, P.AGREE)], (I_, P.CONFIRM)),
        ("fipa-contract-net", [(I_, P.CFP)], (R_, P.ACCEPT_PROPOSAL)),
        ("fipa-contract-net", [(I_, P.CFP), (R_, P.PROPOSE)], (R_, P.INFORM)),
        ("fipa-contract-net", [(I_, P.CFP)], (I_, P.CANCEL)),
        ("fipa-iterated-contract-net", [(I_, P.CFP)], (I_, P.CFP)),  # a revised cfp needs a proposal
        ("fipa-iterated-contract-net", [(I_, P.CFP), (R_, P.PROPOSE)], (R_, P.PROPOSE)),
        ("fipa-iterated-contract-net", [(I_, P.CFP), (R_, P.PROPOSE), (I_, P.ACCEPT_PROPOSAL)], (I_, P.CFP)),
        ("fipa-iterated-contract-net", [(I_, P.CFP)], (I_, P.CANCEL)),
        ("fipa-english-auction", [], (I_, P.CFP)),  # a price before start-auction
        ("fipa-english-auction", [(I_, P.INFORM)], (R_, P.PROPOSE)),  # a bid before a price
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP)], (I_, P.ACCEPT_PROPOSAL)),  # no bid
        ("fipa-english-auction", [(I_, P.INFORM), (I_, P.CFP), (R_, P.PROPOSE)], (R_, P.PROPOSE)),
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
        ("coordinate", [(I_, P.REQUEST), (R_, P.INFORM)], (R_, P.FAILURE)),  # failure once running
        ("coordinate", [(I_, P.REQUEST)], (R_, P.CANCEL)),
        ("coordinate", [(I_, P.REQUEST), (R_, P.INFORM, True)], (R_, P.INFORM)),
    ],
)
def test_violations_are_rejected(name: str, steps: list[Step], bad: tuple) -> None:
    tracker = _run(name, steps)
    before = (tracker.state, list(tracker.history))
    with pytest.raises(ProtocolViolation) as info:
        tracker.step(*bad)
    exc = info.value
    assert (exc.protocol, exc.state, exc.role, exc.performative) == (name, before[0], *bad)
    assert f"the {bad[0]} may not send {bad[1].value!r}" in str(exc)
    assert (tracker.state, tracker.history) == before  # unchanged
    assert isinstance(exc, ValueError)


LIBRARY_BRANCHES = [
    "fipa-iterated-contract-net",
    "fipa-english-auction",
    "fipa-dutch-auction",
    "fipa-brokering",
    "fipa-recruiting",
]


@pytest.mark.parametrize("name", LIBRARY_BRANCHES)
def test_every_branch_is_taken(name: str) -> None:
    """The paths of HAPPY_PATHS take every transition of the machine (not-understood aside:
    test_machine_is_well_formed) and end in every final state."""
    protocol = PROTOCOLS[name]
    untaken, ended = _branches(protocol, HAPPY_PATHS[name])
    assert untaken == {}
    assert ended == set(protocol.final)


def _branches(protocol: Protocol, paths: list[list[Step]]) -> tuple[dict, set[str]]:
    """The transitions (not-understood aside) ``paths`` leave untaken, and the states they end in."""
    untaken = {k: t for k, t in protocol.transitions.items() if k[2] is not P.NOT_UNDERSTOOD}
    ended: set[str] = set()
    for steps in paths:
        tracker = ConversationTracker(protocol)
        for role, perf, *_ in steps:
            untaken.pop((tracker.state, role, perf), None)
            tracker.step(role, perf)
        ended.add(tracker.state)
    return untaken, ended


def test_the_branch_check_sees_a_branch_left_out() -> None:
    """Planted: the English auction's paths without the bid that the auction's end crossed."""
    protocol = PROTOCOLS["fipa-english-auction"]
    paths = [p for p in HAPPY_PATHS[protocol.name] if p[-2:] != [(R_, P.PROPOSE), (I_, P.INFORM)]]
    untaken, ended = _branches(protocol, paths)
    assert untaken == {("bid", I_, P.INFORM): "ended"}
    assert ended == set(protocol.final)


def test_violation_message_lists_what_is_allowed() -> None:
    tracker = ConversationTracker("fipa-request")
    with pytest.raises(ProtocolViolation) as info:
        tracker.step("participant", "inform")
    assert str(info.value) == (
        "fipa-request: the participant may not send 'inform' in state 'start'; allowed: initiator request"
    )


def test_coordinate_terminal_flag() -> None:
    tracker = _run("coordinate", [(I_, P.REQUEST)])
    assert tracker.step(R_, P.INFORM, terminal=False) == "reported"
    tracker.step(I_, P.CONFIRM)
    assert tracker.step(R_, P.INFORM, terminal=True) == "ending"
    assert not tracker.is_finished
    assert tracker.step(I_, P.CONFIRM) == "finished"
    assert tracker.is_finished


def test_terminal_flag_is_ignored_elsewhere() -> None:
    tracker = _run("fipa-request", [(I_, P.REQUEST)])
    assert tracker.step(R_, P.INFORM, terminal=True) == "done"


def test_bad_arguments() -> None:
    tracker = ConversationTracker(PROTOCOLS["fipa-request"])
    with pytest.raises(ValueError, match="role"):
        tracker.step("observer", P.REQUEST)
    with pytest.raises(ValueError):
        tracker.step(I_, "shout")
    with pytest.raises(ValueError, match="unknown interaction protocol"):
        ConversationTracker("fipa-auction")


# -- observe: roles and terminal flag from communicates -----------------------------------


def _sw(state: SWState, sender: str = "a_ta") -> Communicate:
    language, content = encode_content(SWStatus(state=state, plan_id="p1"))
    return Communicate(
        performative=P.INFORM,
        sender=AgentIdentifier(sender),
        receiver=(AgentIdentifier("a_co"),),
        content=content,
        language=language,
        encoding="msgpack",
        protocol="coordinate",
    )


def _from(sender: str, perf: Performative) -> Communicate:
    return Communicate(performative=perf, sender=AgentIdentifier(sender), protocol="coordinate")


def test_observe_coordinate_conversation() -> None:
    tracker = ConversationTracker("coordinate")
    tracker.observe(_from("a_co", P.REQUEST))
    assert tracker.initiator == "a_co"
    for state in (SWState.RUNNING, SWState.TERMINATING):
        assert tracker.observe(_sw(state)) == "reported"
        assert tracker.observe(_from("a_co", P.CONFIRM)) == "running"
    assert tracker.observe(_sw(SWState.PREEMPTED)) == "ending"
    assert tracker.observe(_from("a_co", P.CONFIRM)) == "finished"


def test_observe_rejects_wrong_sender_role() -> None:
    tracker = ConversationTracker("coordinate")
    tracker.observe(_from("a_co", P.REQUEST))
    with pytest.raises(ProtocolViolation, match="participant may not send 'confirm'"):
        tracker.observe(_from("a_ta", P.CONFIRM))
    with pytest.raises(ValueError, match="without sender"):
        tracker.observe(Communicate(performative=P.INFORM))


def test_is_terminal_report() -> None:
    for state in SWState:
        assert is_terminal_report(_sw(state)) == (state in TERMINAL_SW_STATES)
    assert {s.value for s in TERMINAL_SW_STATES} == {"Succeeded", "Error", "Preempted", "Replan"}
    msg = _sw(SWState.SUCCEEDED)
    assert not is_terminal_report(Communicate(performative=P.CONFIRM, content=msg.content, language="L_SW"))
    assert not is_terminal_report(Communicate(performative=P.INFORM, content=b"\x00", language="L_SW"))
    assert not is_terminal_report(Communicate(performative=P.INFORM, content=msg.content, language="L_WM"))


# -- the machines themselves ---------------------------------------------------------------


@pytest.mark.parametrize("name", list(PROTOCOLS))
def test_machine_is_well_formed(name: str) -> None:
    p = PROTOCOLS[name]
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


@pytest.mark.parametrize("name", list(PROTOCOLS))
def test_to_dot(name: str) -> None:
    p = PROTOCOLS[name]
    dot = p.to_dot()
    assert dot.startswith(f'digraph "{name}" {{') and dot.rstrip().endswith("}")
    assert f'__start -> "{p.initial}"' in dot
    assert "not-understood" not in dot
    full = p.to_dot(not_understood=True)
    assert "P: not-understood" in full and '"not-understood" [shape=doublecircle]' in full
    for final in p.final - {"not-understood"}:
        assert f'"{final}" [shape=doublecircle]' in dot


def test_coordinate_dot_marks_terminal_informs() -> None:
    dot = PROTOCOLS["coordinate"].to_dot()
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
    ],
)
def test_bad_machines_are_rejected(kwargs: dict, problem: str) -> None:
    args: dict = {
        "name": "t",
        "states": frozenset({"a", "b"}),
        "initial": "a",
        "final": frozenset({"b"}),
        "transitions": {("a", "initiator", P.REQUEST): "b"},
    }
    args.update(kwargs)
    with pytest.raises(ValueError, match=problem):
        Protocol(**args)


def test_dead_end_is_rejected() -> None:
    with pytest.raises(ValueError, match="no final state can be reached from 'c'"):
        Protocol(
            name="t",
            states=frozenset({"a", "b", "c"}),
            initial="a",
            final=frozenset({"b"}),
            transitions={("a", "initiator", P.REQUEST): "b", ("a", "initiator", P.CFP): "c"},
        )


@given(st.sampled_from(list(PROTOCOLS)), st.data())
@settings(max_examples=300)
def test_random_walks_only_take_allowed_steps(name: str, data: st.DataObject) -> None:
    """Walking the machine by its own ``allowed`` never raises, and any other message does."""
    tracker = ConversationTracker(name)
    for _ in range(20):
        if tracker.is_finished:
            break
        options = tracker.allowed()
        assert options, f"{name}: dead end in {tracker.state}"
        role, perf, terminal = data.draw(st.sampled_from(options))
        tracker.step(role, perf, terminal=terminal)
        role2 = data.draw(st.sampled_from([I_, R_]))
        perf2 = data.draw(st.sampled_from(list(P)))
        if not any(r == role2 and p == perf2 for r, p, _ in tracker.allowed()):
            with pytest.raises(ProtocolViolation):
                tracker.step(role2, perf2)
