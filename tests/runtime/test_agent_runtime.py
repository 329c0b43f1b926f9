"""The control subsystem on a transport: elementary actions, buffers, checking against the
specification, not-understood, reply-by deadlines (paper §3.2; FIPA SC00061)."""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Iterator

import msgspec
import pytest

from services.runtime import keys
from services.runtime.agent import Agent, Received, SpecViolation
from services.runtime.behaviour import FSM, Arc, Behaviour
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES, write
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery


class Counter(Agent):
    """Behaviour 'count' runs its transition 5 times, then 'answer' serves queries forever."""

    name = "a_km"

    def build_fsm(self) -> FSM:
        self.count = 0
        self.trace: list[str] = []
        return FSM(
            [
                Behaviour("count", self._count, terminal=lambda: self.count >= 5, waits=False),
                Behaviour("answer", self._answer, terminal=lambda: False),
            ],
            arcs=[Arc("count", "answer", lambda: self.count >= 5)],
        )

    def _count(self) -> None:
        self.count += 1
        self.trace.append(f"count{self.count}")

    def _answer(self) -> None:
        while self.engine.x:
            item = self.engine.x.popleft()
            if item.performative is Performative.QUERY_REF and isinstance(item.content, ObjectQuery):
                self.engine.reply(item, Performative.INFORM_REF, Answer())


@contextlib.contextmanager
def serving(bus: MemoryBus, agent: Agent) -> Iterator[queue.SimpleQueue[Communicate]]:
    """``agent`` (on ``bus``) bound and running on a thread of its own; yields what reaches
    a_pl, decoded; stops the agent and checks that its thread ended."""
    agent.engine.bind()
    to_pl: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    bus.subscribe(keys.inbox_key("a_pl"), lambda k, p: to_pl.put(decode(p)))
    t = threading.Thread(target=agent.engine.run, daemon=True)
    t.start()
    try:
        yield to_pl
    finally:
        agent.engine.stop()
        t.join(timeout=5)
    assert not t.is_alive()


@pytest.fixture
def running() -> Iterator[tuple[MemoryBus, Counter, queue.SimpleQueue[Communicate]]]:
    bus = MemoryBus()
    agent = Counter(bus.transport())
    with serving(bus, agent) as to_pl:
        yield bus, agent, to_pl


def query(reply_with: str = "q1", **overrides: object) -> Communicate:
    lang, body = encode_content(ObjectQuery("jar"))
    fields: dict[str, object] = dict(
        performative=Performative.QUERY_REF,
        sender=AgentIdentifier("a_pl"),
        receiver=(AgentIdentifier("a_km"),),
        content=body,
        language=lang,
        ontology="O_RoCo",
        protocol="fipa-query",
        conversation_id="c1",
        reply_with=reply_with,
    )
    fields.update(overrides)
    return Communicate(**fields)  # type: ignore[arg-type]


KEY = keys.fipa_key("C4", "a_pl", "a_km")


def test_behaviour_iterates_until_terminal_then_switches(running: tuple) -> None:
    bus, agent, to_pl = running
    bus.publish(KEY, encode(query()))
    reply = to_pl.get(timeout=5)
    assert reply.performative is Performative.INFORM_REF
    assert agent.trace == [f"count{i}" for i in range(1, 6)]
    assert agent.engine.state == "answer"


@pytest.mark.parametrize(
    ("payload", "why"),
    [
        (b"\x00garbage", "malformed communicate"),
        (write(query(content=b"\x80" * MAX_COMMUNICATE_BYTES)), "oversized communicate"),  # unchecked size
        (encode(query(performative=Performative.PROPOSE)), "unexpected propose"),
        (encode(query(protocol="fipa-request")), "unexpected query-ref in protocol fipa-request"),
        (encode(query(language="L_SW")), "language L_SW not accepted"),
        (encode(query(content=b"\x91\x01")), "L_WM"),
        (encode(query(sender=AgentIdentifier("a_co"))), "sender does not match"),
    ],
)
def test_bad_input_gets_not_understood_and_agent_keeps_serving(
    running: tuple, payload: bytes, why: str
) -> None:
    bus, agent, to_pl = running
    bus.publish(KEY, payload)
    nu = to_pl.get(timeout=5)
    assert nu.performative is Performative.NOT_UNDERSTOOD
    assert why in nu.content.decode()
    bus.publish(KEY, encode(query("q2")))
    ok = to_pl.get(timeout=5)
    assert ok.performative is Performative.INFORM_REF and ok.in_reply_to == "q2"
    assert agent.counters["rejected"] == 1


def test_not_understood_is_never_answered_with_not_understood(running: tuple) -> None:
    bus, _agent, to_pl = running
    bus.publish(KEY, encode(query(performative=Performative.NOT_UNDERSTOOD, content=b"", language=None)))
    # the not-understood ended conversation c1 (one a_km no longer knows): a query opens another
    bus.publish(KEY, encode(query("q3", conversation_id="c3")))
    first = to_pl.get(timeout=5)
    assert first.performative is Performative.INFORM_REF and first.in_reply_to == "q3"


def test_sending_outside_the_interface_raises() -> None:
    agent = Counter(MemoryBus().transport())
    with pytest.raises(SpecViolation, match="no channel"):
        agent.engine.send("ag_ex", Performative.INFORM, protocol="fipa-request")
    with pytest.raises(SpecViolation, match="may not send request"):
        agent.engine.send("a_pl", Performative.REQUEST, protocol="fipa-query")
    with pytest.raises(SpecViolation, match="must use L_WM"):
        agent.engine.send(
            "a_pl", Performative.INFORM_REF, SWStatus(state=SWState.IDLE), protocol="fipa-query"
        )


class Asker(Agent):
    """a_pl asking a_km something nobody answers, with a reply-by deadline."""

    name = "a_pl"
    period = 0.01

    def build_fsm(self) -> FSM:
        self.got: queue.SimpleQueue[Received] = queue.SimpleQueue()
        return FSM([Behaviour("ask", self._step, terminal=lambda: False)])

    def setup(self) -> None:
        self.engine.send(
            "a_km", Performative.QUERY_REF, ObjectQuery("jar"), protocol="fipa-query", reply_by_s=0.2
        )

    def _step(self) -> None:
        while self.engine.x:
            self.got.put(self.engine.x.popleft())


def test_reply_by_deadline_ends_the_conversation_with_a_local_failure() -> None:
    bus = MemoryBus()
    agent = Asker(bus.transport())
    agent.engine.bind()
    t = threading.Thread(target=agent.engine.run, daemon=True)
    t.start()
    try:
        item = agent.got.get(timeout=5)
        assert item.local and item.performative is Performative.FAILURE
        assert item.msg.content == b"reply-by deadline passed"
        assert agent.counters["deadline_failures"] == 1
        assert len(agent.engine.pending_replies) == 0
    finally:
        agent.engine.stop()
        t.join(timeout=5)


def test_liveliness_token_is_announced_once_the_agent_listens() -> None:
    """The token appears after setup: whoever sees it reaches what setup subscribed to (a
    person's line to a_hi, said as soon as a_hi is seen alive, is never lost)."""

    class Listening(Counter):
        def setup(self) -> None:
            self.engine.transport.subscribe("test/said", lambda key, payload: heard.append(payload))

    bus, heard = MemoryBus(), list[bytes]()
    seen = threading.Event()

    def on_token(key: str, alive: bool) -> None:
        if alive:
            bus.publish("test/said", b"hello")  # as a person would, at once
            seen.set()

    bus.watch(keys.alive_key("a_km"), on_token)
    agent = Listening(bus.transport())
    agent.engine.bind()
    assert keys.alive_key("a_km") not in bus.alive()
    t = threading.Thread(target=agent.engine.run, daemon=True)
    t.start()
    try:
        assert seen.wait(5)
        assert heard == [b"hello"]
    finally:
        agent.engine.stop()
        t.join(timeout=5)


def test_memory_bus_messages_are_valid_msgpack_communicates() -> None:
    bus = MemoryBus()
    agent = Counter(bus.transport())
    agent.engine.take(KEY, encode(query(conversation_id="x")))  # a reply needs a query (fipa-query)
    agent.engine.send("a_pl", Performative.INFORM_REF, Answer(), protocol="fipa-query", conversation_id="x")
    agent.engine.dispatch()
    ((key, payload),) = bus.published
    assert key == keys.fipa_key("C4", "a_km", "a_pl")
    msg = decode(payload)
    assert msg.language == "L_WM" and msg.conversation_id == "x"
    assert msgspec.msgpack.decode(msg.content)["type"] == "answer"


class Faulty(Agent):
    """A transition function that raises once; the agent must keep serving."""

    name = "a_km"

    def build_fsm(self) -> FSM:
        self.raised = False
        return FSM([Behaviour("serve", self._serve, terminal=lambda: False)])

    def _serve(self) -> None:
        while self.engine.x:
            item = self.engine.x.popleft()
            if not self.raised:
                self.raised = True
                raise RuntimeError("a bug")
            self.engine.reply(item, Performative.INFORM_REF, Answer())


def test_an_exception_in_a_behaviour_does_not_stop_the_agent() -> None:
    bus = MemoryBus()
    agent = Faulty(bus.transport())
    with serving(bus, agent) as to_pl:
        bus.publish(KEY, encode(query("q1")))
        bus.publish(KEY, encode(query("q2")))
        reply = to_pl.get(timeout=5)
        assert reply.in_reply_to == "q2"
        assert agent.counters["behaviour_errors"] == 1


def test_a_failing_behaviour_drops_only_its_own_output() -> None:
    """A transition function that raises drops what it was about to send, never the answers
    its step's inputs got on the way in (a not-understood to a malformed communicate)."""
    bus = MemoryBus()
    agent = Faulty(bus.transport())
    actions = agent.engine._elementary_actions()
    next(actions)  # set up; 'serve' waits for input
    agent.engine._inbox.extend([(KEY, b"\xc1 not msgpack"), (KEY, encode(query("q1")))])
    next(actions)  # takes both in; the transition raises on q1
    assert agent.counters["behaviour_errors"] == 1
    answers = [decode(p) for k, p in bus.published if k == keys.fipa_key("C4", "a_km", "a_pl")]
    assert [a.performative for a in answers] == [Performative.NOT_UNDERSTOOD]
    assert answers[0].content.startswith(b"malformed communicate")


def test_an_input_whose_taking_in_raises_is_counted_and_the_next_is_taken_in() -> None:
    """No input stops the others taken in with it: one whose handling raised (here the answer
    to a malformed communicate) is counted ``rejected.internal``; the next is answered."""
    bus = MemoryBus()
    agent = Counter(bus.transport())
    raised: list[object] = []

    def not_taken(found: object) -> None:
        raised.append(found)
        raise RuntimeError("a fault while answering")

    agent.engine.not_taken = not_taken  # type: ignore[method-assign]
    agent.count = 5  # past 'count': the agent answers queries
    agent.engine._inbox.extend([(KEY, b"\xc1 not msgpack"), (KEY, encode(query("q1")))])
    agent.engine.acquire()
    assert len(raised) == 1 and agent.counters["rejected.internal"] == 1
    assert [item.msg.reply_with for item in agent.engine.x] == ["q1"]
    assert agent.engine.x[0].performative is Performative.QUERY_REF and agent.engine.x[0].sender == "a_pl"


def test_a_followed_protocol_without_a_conversation_id_is_not_understood(
    running: tuple[MemoryBus, Counter, queue.SimpleQueue[Communicate]],
) -> None:
    """Its answer could be told from no other's: not-understood, and the agent keeps serving."""
    bus, agent, to_pl = running
    bus.publish(KEY, encode(query("q1", conversation_id=None)))
    reply = to_pl.get(timeout=5)
    assert reply.performative is Performative.NOT_UNDERSTOOD
    assert reply.in_reply_to == "q1" and reply.conversation_id is None
    assert reply.content == b"query-ref in protocol fipa-query needs a conversation-id"
    assert agent.counters["rejected.no_conversation_id"] == 1
    bus.publish(KEY, encode(query("q2")))
    assert to_pl.get(timeout=5).performative is Performative.INFORM_REF


def test_a_step_takes_in_what_had_arrived_when_it_began_not_what_floods_in_meanwhile() -> None:
    agent = Counter(MemoryBus().transport())
    taken: list[object] = []

    def take(key: str, payload: object) -> None:  # each take sees another input arrive
        taken.append(payload)
        if len(taken) < 1000:
            agent.post(("more", len(taken)))

    agent.engine.take_event = take  # type: ignore[method-assign]  # post() puts events
    for i in range(3):
        agent.post(("first", i))
    agent.engine.acquire()
    assert len(taken) == 3  # the behaviours run before the 3 inputs that arrived meanwhile
    assert len(agent.engine._inbox) == 3
    agent.engine.acquire()
    assert len(taken) == 6
