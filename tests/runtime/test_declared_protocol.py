"""Two in-process agents converse through protocols their specification declares by name in
its own table (tests/support/notify_agents.py): the runtime's roles and protocol state take the
declared state machines (services/spec/protocol_defs.py ``machine_of``) as they take the
built-in ones — a one-message ``notify`` and a two-message ``tell``."""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.runtime.roles import Conversation, handlers_of, role_problems
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from tests.support.notify_agents import NOTIFY, SPEC, TELL
from tests.support.notify_listener import Listener
from tests.support.notify_sender import Sender
from tests.support.role_agents import RUNNING, TIMEOUT, Scripted


@pytest.fixture
def pair() -> Iterator[tuple[MemoryBus, Sender, Listener]]:
    bus = MemoryBus()
    n, listener = Sender(bus.transport(), SPEC), Listener(bus.transport(), SPEC)
    threads = []
    agents: tuple[Scripted, Scripted] = (n, listener)
    for agent in agents:
        agent.engine.bind()
        threads.append(threading.Thread(target=agent.engine.run, daemon=True))
        threads[-1].start()
    yield bus, n, listener
    for agent, thread in zip(agents, threads, strict=True):
        agent.engine.stop()
        thread.join(timeout=5)
        assert not thread.is_alive()


def _on_thread(agent: Scripted, ask: Callable[[Any], object]) -> object:
    """``ask(agent)`` run on the agent's own thread; its result."""
    out: queue.SimpleQueue[object] = queue.SimpleQueue()
    agent.do(lambda a: out.put(ask(a)))
    return out.get(timeout=TIMEOUT)


def test_the_agents_play_exactly_the_declared_roles() -> None:
    for cls in (Sender, Listener):
        assert role_problems(SPEC, cls.name, cls.ROLES, list(handlers_of(cls))) == []


def test_a_notification_arrives_and_ends_the_conversation_on_both_sides(
    pair: tuple[MemoryBus, Sender, Listener],
) -> None:
    """The sender's role declares a reply-by and a retransmission period: a one-message
    protocol waits for no reply (nothing answers a notification), so the sender keeps no
    pending reply and no open conversation."""
    _bus, n, listener = pair
    opened = _on_thread(n, lambda a: a.roles.open("C1", NOTIFY, RUNNING))
    assert isinstance(opened, Conversation)
    protocol, said, conv = listener.next()
    assert (protocol, said) == (NOTIFY, "inform")
    assert conv.content == RUNNING and conv.conversation_id == opened.conversation_id
    assert _on_thread(listener, lambda a: (conv.finished, list(a.roles))) == (True, [])
    assert _on_thread(n, lambda a: (opened.finished, list(a.roles), len(a.engine.pending_replies))) == (
        True,
        [],
        0,
    )
    for agent in (n, listener):
        assert agent.counters["protocol_violations"] == 0 and agent.counters["send_violations"] == 0


def test_a_told_statement_is_confirmed(pair: tuple[MemoryBus, Sender, Listener]) -> None:
    _bus, n, listener = pair
    opened = _on_thread(n, lambda a: a.roles.open("C1", TELL, RUNNING))
    assert isinstance(opened, Conversation)
    assert listener.next()[:2] == (TELL, "inform")
    protocol, said, conv = n.next()
    assert (protocol, said, conv) == (TELL, "confirm", opened)
    assert _on_thread(n, lambda a: (conv.finished, list(a.roles), len(a.engine.pending_replies))) == (
        True,
        [],
        0,
    )
    for agent in (n, listener):
        assert agent.counters["protocol_violations"] == 0 and agent.counters["send_violations"] == 0


def test_a_second_confirm_is_outside_the_declared_machine(pair: tuple[MemoryBus, Sender, Listener]) -> None:
    """The runtime checks what arrives against the declared machine: a confirm after the
    conversation ended in 'confirmed' is a protocol violation, answered not-understood."""
    bus, n, _listener = pair
    wire: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    bus.subscribe(keys.fipa_key("C1", "a_n", "a_l"), lambda _k, payload: wire.put(decode(payload)))
    opened = _on_thread(n, lambda a: a.roles.open("C1", TELL, RUNNING))
    assert isinstance(opened, Conversation)
    assert n.next()[:2] == (TELL, "confirm")
    assert wire.get(timeout=TIMEOUT).performative is Performative.INFORM
    again = Communicate(
        performative=Performative.CONFIRM,
        sender=AgentIdentifier("a_l"),
        receiver=(AgentIdentifier("a_n"),),
        protocol=TELL,
        conversation_id=opened.conversation_id,
    )
    bus.publish(keys.fipa_key("C1", "a_l", "a_n"), encode(again))
    answer = wire.get(timeout=TIMEOUT)
    assert answer.performative is Performative.NOT_UNDERSTOOD
    assert n.counters["protocol_violations"] == 1


def test_a_malformed_notification_is_answered_not_understood_without_a_violation(
    pair: tuple[MemoryBus, Sender, Listener],
) -> None:
    """The participant answers a notification it cannot read not-understood (FIPA SC00037 §3.12):
    after the end of the conversation, outside the machine, and taken by both agents as
    ending it (services/runtime/protocol_state.py ``follow``)."""
    bus, n, listener = pair
    wire: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    bus.subscribe(keys.fipa_key("C1", "a_l", "a_n"), lambda _k, payload: wire.put(decode(payload)))
    unreadable = Communicate(
        performative=Performative.INFORM,
        sender=AgentIdentifier("a_n"),
        receiver=(AgentIdentifier("a_l"),),
        content=b"\xc1",  # no msgpack value
        language="L_SW",
        encoding="msgpack",
        ontology="O_RoCo",
        protocol=NOTIFY,
        conversation_id="n-1",
        reply_with="n-1-r",
    )
    bus.publish(keys.fipa_key("C1", "a_n", "a_l"), encode(unreadable))
    answer = wire.get(timeout=TIMEOUT)
    assert answer.performative is Performative.NOT_UNDERSTOOD
    assert (answer.conversation_id, answer.in_reply_to) == ("n-1", "n-1-r")
    # a round trip after it: a_n takes communicates in order, so the not-understood went first
    opened = _on_thread(n, lambda a: a.roles.open("C1", TELL, RUNNING))
    assert isinstance(opened, Conversation)
    assert n.next()[:2] == (TELL, "confirm")
    assert listener.counters["rejected"] == 1
    for agent in (n, listener):
        assert agent.counters["protocol_violations"] == 0 and agent.counters["send_violations"] == 0
