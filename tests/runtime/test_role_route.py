"""Where a role puts a received communicate (services/runtime/roles/): each role's
``RoleTable``, worked out once from its protocol's state machine and the agent's handlers, and
the pure ``route`` of one communicate — a new conversation, the next communicate of an open one,
its opening again, or a reply to no conversation of this agent."""

from __future__ import annotations

from services.runtime.agent import Received
from services.runtime.memory_transport import MemoryBus
from services.runtime.roles import RoleTable, Route, role_table, route
from services.spec.protocol_defs import machine_of
from shared.fipa_codec import AgentIdentifier, Communicate
from tests.support.role_agents import SPEC, P
from tests.support.role_initiator import Initiator
from tests.support.role_participant import Participant


def received(perf: P, sender: str, protocol: str, cid: str, **kw: str) -> Received:
    to = "a_p" if sender == "a_i" else "a_i"
    msg = Communicate(
        performative=perf,
        sender=AgentIdentifier(sender),
        receiver=(AgentIdentifier(to),),
        protocol=protocol,
        conversation_id=cid,
        **kw,  # type: ignore[arg-type]
    )
    return Received.of(msg, None, "C1")


def table_of(agent: Initiator | Participant, protocol: str) -> RoleTable:
    return role_table(agent.roles.role("C1", protocol), machine_of(SPEC, protocol), agent.roles._handlers)


def test_a_participants_table_knows_its_openings_its_cancels_and_its_handlers() -> None:
    p = Participant(MemoryBus().transport(), SPEC)
    table = role_table(
        p.roles.role("C1", "fipa-subscribe"), machine_of(SPEC, "fipa-subscribe"), p.roles._handlers
    )
    assert table.opens == {P.SUBSCRIBE}
    assert table.cancelling and table.answers_cancels and not table.initiator
    assert table.on_received[P.SUBSCRIBE] == "on_request"
    assert table.on_received[P.CANCEL] == "on_unsubscribe"
    coordinate = role_table(
        p.roles.role("C1", "coordinate"), machine_of(SPEC, "coordinate"), p.roles._handlers
    )
    assert not coordinate.answers_cancels  # coordinate's cancel is a request of its own (paper §5.4)


def test_an_initiators_not_understood_and_deadline_go_to_its_failure_handler() -> None:
    i = Initiator(MemoryBus().transport(), SPEC)
    table = role_table(
        i.roles.role("C1", "fipa-request"), machine_of(SPEC, "fipa-request"), i.roles._handlers
    )
    assert table.initiator and table.opens == frozenset() and not table.answers_cancels
    assert table.on_received[P.NOT_UNDERSTOOD] == table.on_received[P.FAILURE] == "on_answer"
    assert table.on_deadline == "on_answer"


def test_a_request_opens_a_conversation_and_the_same_request_again_repeats_it() -> None:
    p = Participant(MemoryBus().transport(), SPEC)
    table = p.roles._tables[("a_i", "fipa-request")]
    request = received(P.REQUEST, "a_i", "fipa-request", "c1", reply_with="r1")
    assert route(table, None, request) is Route.OPENS
    p.roles.take(request)
    conv = p.roles._open[("a_i", "c1")]
    assert route(table, conv, request) is Route.REPEATED
    # a new request (another reply-with) in the conversation-id opens it anew
    assert (
        route(table, conv, received(P.REQUEST, "a_i", "fipa-request", "c1", reply_with="r2")) is Route.OPENS
    )
    assert route(table, None, received(P.CANCEL, "a_i", "fipa-request", "c9")) is Route.ORPHAN


def test_a_reply_goes_to_its_conversation_unless_it_answers_another_opening() -> None:
    i = Initiator(MemoryBus().transport(), SPEC)
    table = i.roles._tables[("a_p", "fipa-request")]
    conv = i.roles.open("C1", "fipa-request", None)
    assert conv.opening is not None
    opening = conv.opening.msg.reply_with or ""
    cid = conv.conversation_id
    assert route(table, conv, received(P.AGREE, "a_p", "fipa-request", cid, in_reply_to=opening)) is (
        Route.CONVERSATION
    )
    earlier = received(P.INFORM, "a_p", "fipa-request", cid, in_reply_to="a_i-earlier")
    assert route(table, conv, earlier) is Route.ORPHAN
    assert route(table, None, received(P.INFORM, "a_p", "fipa-request", "gone")) is Route.ORPHAN
    conv.knows_sent = False  # restored by its id alone: it cannot tell an earlier opening's reply
    assert route(table, conv, earlier) is Route.CONVERSATION
