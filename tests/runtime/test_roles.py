"""Protocol roles built from the state machines (services/runtime/roles/): the same
code plays both roles of every interaction protocol roco knows — the eleven of the FIPA
library (fipa-request ... fipa-propose, SC00026-SC00036) and the paper's coordinate —
between two agents on one bus, and owns what the protocols imply: in-reply-to, reply-by
deadlines, cancel, not-understood, handler faults and late replies."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator

import pytest

from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.runtime.roles import Conversation, handlers_of, role_problems
from shared.fipa_codec import AgentIdentifier, Communicate, decode, encode
from tests.support.role_agents import MACHINES, NU, SPEC, TIMEOUT, P, Scripted
from tests.support.role_initiator import Initiator
from tests.support.role_participant import Participant


@pytest.fixture
def pair() -> Iterator[tuple[MemoryBus, Initiator, Participant]]:
    bus = MemoryBus()
    i, p = Initiator(bus.transport(), SPEC), Participant(bus.transport(), SPEC)
    threads = []
    for agent in (i, p):
        agent.engine.bind()
        threads.append(threading.Thread(target=agent.engine.run, daemon=True))
        threads[-1].start()
    yield bus, i, p
    for agent, thread in zip((i, p), threads, strict=True):
        agent.engine.stop()
        thread.join(timeout=5)
        assert not thread.is_alive()


def test_the_test_agents_play_exactly_the_roles_of_their_spec() -> None:
    for cls in (Initiator, Participant):
        assert role_problems(SPEC, cls.name, cls.ROLES, list(handlers_of(cls))) == []


EXPECTED = {
    # what the initiator's handlers receive, in order, until its conversation has ended (an
    # agree is noted by the role: conv.agreed)
    "fipa-request": ["inform"],
    "fipa-query": ["inform-ref"],
    "fipa-request-when": ["inform"],
    "fipa-subscribe": ["inform", "inform"],  # the second answers the initiator's cancel
    "fipa-propose": ["accept-proposal"],
    "fipa-contract-net": ["propose", "inform"],
    "fipa-iterated-contract-net": ["propose", "inform"],
    "fipa-english-auction": ["propose"],  # then accept-proposal, inform(end-of-auction), request
    "fipa-dutch-auction": ["propose"],
    "fipa-brokering": ["inform"],  # the targets' replies, forwarded
    "fipa-recruiting": ["inform"],
    "coordinate": ["inform", "inform"],  # each confirmed; the second reports a terminal state
}
OPENS = {"fipa-query": P.QUERY_REF}
THEN = {"fipa-english-auction": P.CFP, "fipa-dutch-auction": P.CFP}
"""What the initiator sends at once after the opening: an auction's first price after
inform(start-auction)."""
AGREES = {"fipa-request", "fipa-request-when", "fipa-subscribe", "fipa-brokering", "fipa-recruiting"}


def _open(a: Scripted, protocol: str) -> Conversation:
    conv = a.roles.open("C1", protocol, None, performative=OPENS.get(protocol))
    if protocol in THEN:
        conv.send(THEN[protocol])
    return conv


@pytest.mark.parametrize("protocol", list(MACHINES))
def test_both_roles_of_every_protocol_run_from_its_state_machine(
    pair: tuple[MemoryBus, Initiator, Participant], protocol: str
) -> None:
    _bus, i, p = pair
    opened: queue.SimpleQueue[Conversation] = queue.SimpleQueue()
    i.do(lambda a: opened.put(_open(a, protocol)))
    conv = opened.get(timeout=TIMEOUT)
    said = []
    for _ in EXPECTED[protocol]:
        seen_protocol, performative, seen = i.next()
        assert (seen_protocol, seen) == (protocol, conv)
        said.append(performative)
    assert said == EXPECTED[protocol]
    assert conv.agreed is (protocol in AGREES)
    # on a_i's thread, after what it sent in answer: a final state of the protocol's machine
    done: queue.SimpleQueue[bool] = queue.SimpleQueue()
    if protocol == "coordinate":
        # coordinate lets a_co confirm again while the plan runs, so the last confirm
        # may be read as one that crossed the terminal inform: the conversation may have ended,
        # and both roles keep it open until they forget the oldest (roles.MAX_OPEN)
        def ended(a: Initiator) -> None:
            tracker = a.engine.protocol_states.get("a_p", conv.conversation_id)
            done.put(tracker is not None and "finished" in tracker.states)

        i.do(ended)
        assert done.get(timeout=TIMEOUT)
        return
    i.do(lambda a: done.put(conv.finished))
    assert done.get(timeout=TIMEOUT)
    if protocol in THEN:  # the auctioneer sends the last communicate: the participant handles it
        while p.next()[1] != "request":
            pass
    # the participant's side ended too, and neither role keeps the conversation open
    p.do(lambda a: done.put(not list(a.roles)))
    assert done.get(timeout=TIMEOUT)
    i.do(lambda a: done.put(not list(a.roles)))
    assert done.get(timeout=TIMEOUT)
    for agent in (i, p):
        assert agent.counters["protocol_violations"] == 0 and agent.counters["send_violations"] == 0


def test_a_reply_answers_the_opening_and_the_cancel_answer_answers_the_cancel(
    pair: tuple[MemoryBus, Initiator, Participant],
) -> None:
    bus, i, _p = pair
    wire: queue.SimpleQueue[Communicate] = queue.SimpleQueue()

    bus.subscribe(keys.fipa_key("C1", "a_p", "a_i"), lambda _k, payload: wire.put(decode(payload)))
    opened: queue.SimpleQueue[Conversation] = queue.SimpleQueue()
    i.do(lambda a: opened.put(a.roles.open("C1", "fipa-subscribe", None)))
    conv = opened.get(timeout=TIMEOUT)
    assert conv.opening is not None
    agree, inform, cancelled = wire.get(timeout=TIMEOUT), wire.get(timeout=TIMEOUT), wire.get(timeout=TIMEOUT)
    assert agree.in_reply_to == inform.in_reply_to == conv.opening.msg.reply_with
    assert cancelled.performative is P.INFORM and cancelled.in_reply_to in conv.cancels
    assert {agree.conversation_id, inform.conversation_id, cancelled.conversation_id} == {
        conv.conversation_id
    }


def test_no_answer_by_the_deadline_reaches_the_failure_handler(
    pair: tuple[MemoryBus, Initiator, Participant],
) -> None:
    _bus, i, p = pair
    p.silent.add("fipa-request")
    i.do(lambda a: a.roles.open("C1", "fipa-request", None, reply_by_s=0.2))
    protocol, said, conv = i.next()
    assert (protocol, said) == ("fipa-request", "deadline")
    assert conv.timed_out and conv.reason == "reply-by deadline passed"


def test_a_fault_in_a_participant_handler_answers_failure_and_the_agent_goes_on(
    pair: tuple[MemoryBus, Initiator, Participant],
) -> None:
    _bus, i, p = pair
    p.fault = "fipa-query"
    i.do(lambda a: a.roles.open("C1", "fipa-query", None, performative=P.QUERY_REF))
    protocol, said, conv = i.next()
    assert (protocol, said) == ("fipa-query", "failure")
    assert conv.reason == "internal error: RuntimeError: a planted fault"
    assert p.counters["handler_errors"] == 1
    p.fault = None
    i.do(lambda a: a.roles.open("C1", "fipa-query", None, performative=P.QUERY_REF))
    assert i.next()[:2] == ("fipa-query", "inform-ref")


def test_a_cancel_without_a_handler_gets_failure_and_one_of_an_ended_conversation_too(
    pair: tuple[MemoryBus, Initiator, Participant],
) -> None:
    _bus, i, p = pair
    p.silent.add("fipa-request")  # the request stays open: the participant has no cancel handler
    opened: queue.SimpleQueue[Conversation] = queue.SimpleQueue()
    i.do(lambda a: opened.put(a.roles.open("C1", "fipa-request", None)))
    conv = opened.get(timeout=TIMEOUT)
    assert p.next()[:2] == ("fipa-request", "request")
    i.do(lambda a: conv.cancel(reply_by_s=TIMEOUT))
    protocol, said, answered = i.next()
    assert (protocol, said) == ("fipa-request", "failure") and answered.answers_cancel
    assert answered.reason == "this conversation cannot be cancelled"


def test_a_not_understood_reaches_the_failure_handler(pair: tuple[MemoryBus, Initiator, Participant]) -> None:
    bus, i, p = pair
    p.silent.add("fipa-request")
    opened: queue.SimpleQueue[Conversation] = queue.SimpleQueue()
    i.do(lambda a: opened.put(a.roles.open("C1", "fipa-request", None, conversation_id="c-nu")))
    opened.get(timeout=TIMEOUT)
    nu = Communicate(
        performative=NU,
        sender=AgentIdentifier("a_p"),
        receiver=(AgentIdentifier("a_i"),),
        content=b"no, thanks",
        encoding="utf-8",
        protocol="fipa-request",
        conversation_id="c-nu",
    )
    bus.publish(keys.fipa_key("C1", "a_p", "a_i"), encode(nu))
    protocol, said, conv = i.next()
    assert (protocol, said) == ("fipa-request", "not-understood")
    assert conv.not_understood and conv.reason == "no, thanks" and conv.finished


def test_a_reply_in_an_abandoned_conversation_is_dropped_as_late(
    pair: tuple[MemoryBus, Initiator, Participant],
) -> None:
    bus, i, p = pair
    p.silent.add("fipa-request")
    opened: queue.SimpleQueue[Conversation] = queue.SimpleQueue()
    i.do(lambda a: opened.put(a.roles.open("C1", "fipa-request", None)))
    conv = opened.get(timeout=TIMEOUT)
    assert p.next()[:2] == ("fipa-request", "request")
    i.do(lambda a: conv.forget())
    assert conv.opening is not None
    late = Communicate(
        performative=P.INFORM,
        sender=AgentIdentifier("a_p"),
        receiver=(AgentIdentifier("a_i"),),
        protocol="fipa-request",
        conversation_id=conv.conversation_id,
        in_reply_to=conv.opening.msg.reply_with,
    )
    bus.publish(keys.fipa_key("C1", "a_p", "a_i"), encode(late))
    # a round trip after it: a_i takes communicates in order, so the late one was taken first
    i.do(lambda a: a.roles.open("C1", "fipa-query", None, performative=P.QUERY_REF))
    assert i.next()[:2] == ("fipa-query", "inform-ref")
    assert i.counters["late_replies"] == 1
