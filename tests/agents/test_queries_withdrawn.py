"""An agent that stops withdraws the queries it still waits on (Roles.withdraw_queries: a
cancel, FIPA SC00027 §2), so that no participant answers a question nobody will read; the
participant may answer the cancel with inform or failure, or its agree may cross it."""

from __future__ import annotations

import pytest

from services.agents.human_interface.agent import HumanInterface
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Performative
from tests.agents.test_more_protocol_branches import STATUS, Person, a_hi_with_a_co, answer
from tests.support.peer import Peer, running

P = Performative


@pytest.mark.parametrize(
    "then", [P.INFORM, P.FAILURE, P.AGREE], ids=["cancelled", "cancel-failed", "crossing"]
)
def test_a_status_query_agreed_and_unanswered_is_cancelled_when_a_hi_stops(then: Performative) -> None:
    with a_hi_with_a_co() as (hi, a_co, person, _):
        person.say(STATUS, "r1")
        query = a_co.next(P.QUERY_REF)
        assert query.conversation_id is not None
        answer(a_co, query, P.AGREE)  # agreed: the status comes later
        hi.engine.stop()
        cancel = a_co.next(P.CANCEL, cid=query.conversation_id)
        if then is P.AGREE:  # the participant's agree again, sent before the cancel reached it
            answer(a_co, query, P.AGREE)
        else:
            a_co.send(then, "fipa-query", query.conversation_id, in_reply_to=cancel.reply_with)
    assert cancel.sender is not None and cancel.sender.name == "a_hi" and not hi.roles.withdraw_queries()


def test_an_answered_query_is_not_cancelled_when_a_hi_stops() -> None:
    with a_hi_with_a_co() as (hi, a_co, person, _):
        person.say(STATUS, "r1")
        query = a_co.next(P.QUERY_REF)
        assert query.conversation_id is not None
        answer(a_co, query, P.FAILURE)  # answered: nothing left to withdraw
        person.final("r1")
        assert hi.roles.withdraw_queries() == 0


def test_a_vocabulary_query_agreed_and_unanswered_is_cancelled_when_a_hi_stops() -> None:
    bus = MemoryBus()
    hi = HumanInterface(bus.transport())
    a_km = Peer(bus, "a_km", "a_hi", "C7")
    Person(bus)
    with running(hi):
        bus.announce(keys.alive_key("a_km"))
        query = a_km.next(P.QUERY_REF)
        assert query.conversation_id is not None
        answer(a_km, query, P.AGREE)
        hi.engine.stop()
        a_km.next(P.CANCEL, cid=query.conversation_id)
        answer(a_km, query, P.AGREE)  # crossing the cancel
