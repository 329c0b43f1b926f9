"""Batches in the agent runtime (shared/fipa_codec/batch.py): what one step sends to
one receiver leaves in one put, and every communicate of a batch that arrives is checked as if it
had come alone (malformed, sender binding, duplicates, the interface), in order."""

from __future__ import annotations

import queue
from collections.abc import Iterator

import pytest

from services.runtime import keys
from services.runtime.memory_transport import MemoryBus, MemoryTransport
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.batch import is_batch, pack, unpack
from tests.runtime.test_agent_runtime import KEY, Counter, query, serving

TO_PL = keys.fipa_key("C4", "a_km", "a_pl")


class Recording(MemoryTransport):
    """The in-memory transport, keeping every put as it was made (key, payload)."""

    def __init__(self, bus: MemoryBus) -> None:
        super().__init__(bus)
        self.puts: list[tuple[str, bytes]] = []

    def publish(self, key: str, payload: bytes) -> None:
        self.puts.append((key, payload))
        super().publish(key, payload)


@pytest.fixture
def running() -> Iterator[tuple[Counter, Recording, queue.SimpleQueue[Communicate]]]:
    """a_km (answering queries) running; what it puts, and what reaches a_pl."""
    bus = MemoryBus()
    transport = Recording(bus)
    agent = Counter(transport)
    with serving(bus, agent) as to_pl:
        yield agent, transport, to_pl


Running = tuple[Counter, Recording, queue.SimpleQueue[Communicate]]


def test_each_communicate_of_a_batch_is_checked_alone_and_the_answers_leave_together(
    running: Running,
) -> None:
    agent, transport, to_pl = running
    q1 = encode(query("q1", conversation_id="c1"))
    batch = [
        q1,
        b"\x00garbage",
        encode(query("q2", conversation_id="c2", sender=AgentIdentifier("a_co"))),  # a spoof
        q1,  # a copy: dropped (the original is not answered yet: nothing to send again)
        encode(
            query("q3", conversation_id="c3", performative=Performative.PROPOSE)
        ),  # not in a_km's interface
        encode(query("q4", conversation_id="c4")),
    ]
    # one query answered first: the agent's start-up is over (a slow start-up, e.g. writing
    # its FSM record to a tap folder, would take part of the batch in its own step)
    agent.engine._on_payload(KEY, encode(query("q0", conversation_id="c0")))
    assert to_pl.get(timeout=5).in_reply_to == "q0"
    before = len(transport.puts)
    with agent.engine._turn:  # as the transport's receiving thread calls it, between two steps
        agent.engine._on_payload(KEY, pack(batch))
    got = [to_pl.get(timeout=5) for _ in range(5)]
    assert [(m.performative, m.in_reply_to) for m in got] == [
        (Performative.NOT_UNDERSTOOD, None),
        (Performative.NOT_UNDERSTOOD, "q2"),
        (Performative.NOT_UNDERSTOOD, "q3"),
        (Performative.INFORM_REF, "q1"),
        (Performative.INFORM_REF, "q4"),
    ]
    assert "malformed" in got[0].content.decode() and "sender does not match" in got[1].content.decode()
    assert agent.counters["duplicates"] == 1 and agent.counters["rejected"] == 3
    # taken in by one step: the five answers left in one put, counted per communicate
    answers = [p for key, p in transport.puts[before:] if key == TO_PL]
    assert len(answers) == 1 and is_batch(answers[0]) and len(unpack(answers[0])) == 5
    assert agent.counters["published"] == 6


def test_a_lone_answer_is_not_wrapped(running: Running) -> None:
    agent, transport, to_pl = running
    agent.engine._on_payload(KEY, encode(query("q1")))
    assert to_pl.get(timeout=5).in_reply_to == "q1"
    puts = [p for key, p in transport.puts if key == TO_PL]
    assert len(puts) == 1 and not is_batch(puts[0]) and decode(puts[0]).in_reply_to == "q1"
