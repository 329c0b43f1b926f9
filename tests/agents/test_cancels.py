"""Cancels an agent can receive by the specification are answered as FIPA's cancel
meta-protocol says (SC00026 §2, SC00027 §2): ``inform`` when cancelled, ``failure`` when
there is nothing to cancel — never ignored, never a crash."""

from __future__ import annotations

import queue

from services.runtime import keys
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from tests.support.memory_fleet import MemoryFleet


def cancel(fleet: MemoryFleet, channel: str, sender: str, receiver: str, protocol: str) -> Communicate:
    answers: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    fleet.bus.subscribe(keys.fipa_key(channel, receiver, sender), lambda k, p: answers.put(decode(p)))
    msg = Communicate(
        performative=Performative.CANCEL,
        sender=AgentIdentifier(sender),
        receiver=(AgentIdentifier(receiver),),
        protocol=protocol,
        conversation_id=f"gone-{receiver}",
    )
    fleet.bus.publish(keys.fipa_key(channel, sender, receiver), encode(msg))
    while True:
        answer = answers.get(timeout=10)
        if answer.conversation_id == msg.conversation_id:
            return answer


def test_a_cancel_of_a_plan_request_that_was_answered_gets_failure() -> None:
    with MemoryFleet() as fleet:
        answer = cancel(fleet, "C3", "a_co", "a_pl", "fipa-request")
        assert answer.performative is Performative.FAILURE
        assert b"nothing to cancel" in answer.content
        # a_pl keeps working
        fleet.wait_for_initial_knowledge()
        assert fleet.command("pour the jar into the bowl")[-1].kind.value == "succeeded"


def test_a_cancel_of_an_answered_query_gets_failure() -> None:
    with MemoryFleet() as fleet:
        for channel, sender in (("C4", "a_pl"), ("C6", "a_ta")):
            answer = cancel(fleet, channel, sender, "a_km", "fipa-query")
            assert answer.performative is Performative.FAILURE
            assert b"nothing to cancel" in answer.content
