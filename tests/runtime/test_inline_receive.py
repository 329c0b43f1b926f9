"""An idle agent takes a communicate in on the thread it arrived on: the same checks,
in the same order, one thread at a time; streams, undeclared keys and errors go back to the
agent's own thread (services/runtime/engine.py ``Engine._take_here``)."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import ClassVar

import pytest

from services.runtime import engine as agent_module
from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.engine import INLINE_OUTPUT_MAX
from services.runtime.memory_transport import MemoryBus, MemoryTransport
from services.runtime.transport import Callback, ZenohTransport
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery
from tests.runtime.test_agent_runtime import KEY, query
from tests.support.router import embedded_router

DELIVERY = "zenoh-callback"
WAIT_S = 10.0
AGENT = "agent"


class ThreadedTransport(MemoryTransport):
    """A memory transport that calls its subscribers back on a thread of its own, as Zenoh
    does, and records which thread put each publication."""

    inline_receive = True

    def __init__(self, bus: MemoryBus) -> None:
        super().__init__(bus)
        self._deliveries: queue.SimpleQueue[tuple[Callback, str, bytes] | threading.Event | None] = (
            queue.SimpleQueue()
        )
        self.put_by: list[tuple[str, str]] = []
        self.undeclared: set[str] = set()
        self._thread = threading.Thread(target=self._deliver, name=DELIVERY, daemon=True)
        self._thread.start()

    def _deliver(self) -> None:
        while (item := self._deliveries.get()) is not None:
            if isinstance(item, threading.Event):
                item.set()
                continue
            callback, key, payload = item
            callback(key, payload)

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        self.bus.subscribe(key_expr, lambda k, p: self._deliveries.put((callback, k, p)))

    def publish(self, key: str, payload: bytes) -> None:
        self.put_by.append((key, threading.current_thread().name))
        super().publish(key, payload)

    def declared(self, key: str) -> bool:
        return key not in self.undeclared

    def flush(self) -> None:
        """Return once everything delivered before the call has been handled."""
        done = threading.Event()
        self._deliveries.put(done)
        assert done.wait(5)

    def close(self) -> None:
        self._deliveries.put(None)
        super().close()


class Answering(Agent):
    """a_km answering object queries; records the thread of each step that took one in."""

    name = "a_km"
    period: ClassVar[float] = 60.0  # the agent's thread wakes for input only, never for time
    extra = 0
    """Payloads on ``test/out`` each answer also puts (more than INLINE_OUTPUT_MAX: a stream)."""

    def build_fsm(self) -> FSM:
        self.handled_on: list[str] = []
        self.fail_persist = False
        self.started = threading.Event()
        return FSM([Behaviour("answer", self._answer, terminal=lambda: False)])

    def _answer(self) -> None:
        while self.engine.x:
            item = self.engine.x.popleft()
            self.handled_on.append(threading.current_thread().name)
            if item.performative is Performative.QUERY_REF and isinstance(item.content, ObjectQuery):
                self.engine.reply(item, Performative.INFORM_REF, Answer())
                for i in range(self.extra):
                    self.emit("test/out", str(i).encode())

    def setup(self) -> None:
        self.started.set()

    def persist(self) -> None:
        if self.fail_persist and self.handled_on:
            raise OSError("disk full")


@dataclass
class Running:
    bus: MemoryBus
    transport: ThreadedTransport
    agent: Answering
    to_pl: queue.SimpleQueue[Communicate]
    thread: threading.Thread
    raised: list[BaseException] = field(default_factory=list)

    def idle(self) -> None:
        """Return once the agent's thread has run the actions up to a wait: set-up has begun
        under the turn, and the turn is free only while they are suspended waiting for input
        (period 60 s: nothing else wakes them)."""
        assert self.agent.started.wait(5)
        with self.agent.engine._turn:
            pass


def start(
    agent_cls: type[Answering] = Answering, transport_cls: type[ThreadedTransport] = ThreadedTransport
) -> Running:
    bus = MemoryBus()
    transport = transport_cls(bus)
    agent = agent_cls(transport)
    agent.engine.bind()
    to_pl: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    bus.subscribe(keys.inbox_key("a_pl"), lambda k, p: [to_pl.put(decode(part)) for part in unpack(p)])
    raised: list[BaseException] = []

    def run() -> None:
        try:
            agent.engine.run()
        except BaseException as exc:  # what run() raised, for the test to see
            raised.append(exc)

    thread = threading.Thread(target=run, name=AGENT, daemon=True)
    thread.start()
    r = Running(bus, transport, agent, to_pl, thread, raised)
    r.idle()
    return r


@pytest.fixture(autouse=True)
def every_arrival_apart(monkeypatch: pytest.MonkeyPatch) -> None:
    """Communicates a test publishes back to back count as apart (see the gap's own test)."""
    monkeypatch.setattr(agent_module, "INLINE_GAP_S", 0.0)


@pytest.fixture
def running() -> Iterator[Running]:
    r = start()
    yield r
    r.agent.engine.stop()
    r.thread.join(timeout=5)
    assert not r.thread.is_alive()
    r.transport.close()


def test_an_idle_agent_answers_on_the_thread_the_communicate_arrived_on(running: Running) -> None:
    running.bus.publish(KEY, encode(query("q1")))
    reply = running.to_pl.get(timeout=5)
    assert reply.performative is Performative.INFORM_REF and reply.in_reply_to == "q1"
    assert running.agent.handled_on == [DELIVERY]
    assert running.transport.put_by == [(keys.fipa_key("C4", "a_km", "a_pl"), DELIVERY)]
    assert running.agent.counters["received_inline"] == 1


def test_bad_input_taken_in_on_the_receiving_thread_gets_not_understood(running: Running) -> None:
    running.bus.publish(KEY, b"\x00garbage")
    running.bus.publish(KEY, encode(query("q2", protocol="fipa-request")))
    running.bus.publish(KEY, encode(query("q3")))
    first, second, third = (running.to_pl.get(timeout=5) for _ in range(3))
    assert first.performative is Performative.NOT_UNDERSTOOD and "malformed" in first.content.decode()
    assert second.performative is Performative.NOT_UNDERSTOOD and "unexpected" in second.content.decode()
    assert third.performative is Performative.INFORM_REF and third.in_reply_to == "q3"
    assert running.agent.counters["rejected"] == 2
    assert {thread for _, thread in running.transport.put_by} == {DELIVERY}


def test_input_that_arrives_while_a_step_runs_waits_and_keeps_its_order(running: Running) -> None:
    agent = running.agent
    with agent.engine._turn:  # the agent's actions are running (on some thread)
        for n in range(5):
            running.bus.publish(KEY, encode(query(f"q{n}", conversation_id=f"c{n}")))
        running.transport.flush()
        assert [decode(p).reply_with for _, p in agent.engine._inbox] == [f"q{n}" for n in range(5)]
        assert running.to_pl.empty()
    answers = [running.to_pl.get(timeout=5).in_reply_to for _ in range(5)]
    assert answers == [f"q{n}" for n in range(5)]
    assert agent.handled_on[0] == AGENT  # the waiting input went to the agent's thread
    assert agent.counters["received_inline"] == 0
    # taken in by one step, the five answers to a_pl left in one put (one batch)
    assert [key for key, _ in running.transport.put_by] == [keys.fipa_key("C4", "a_km", "a_pl")]


def test_a_step_that_puts_a_stream_goes_on_on_the_agents_thread() -> None:
    class Streaming(Answering):
        extra = INLINE_OUTPUT_MAX + 1

    r = start(Streaming)
    try:
        r.bus.publish(KEY, encode(query("q1")))
        reply = r.to_pl.get(timeout=5)
        assert reply.in_reply_to == "q1"
        r.idle()
        assert r.agent.handled_on == [DELIVERY]  # taken in where it arrived ...
        assert len(r.transport.put_by) == 1 + INLINE_OUTPUT_MAX + 1
        assert {thread for _, thread in r.transport.put_by} == {AGENT}  # ... put by the agent's thread
    finally:
        r.agent.engine.stop()
        r.thread.join(timeout=5)
        r.transport.close()


def test_a_step_that_would_declare_a_publisher_goes_on_on_the_agents_thread(running: Running) -> None:
    reply_key = keys.fipa_key("C4", "a_km", "a_pl")
    running.transport.undeclared.add(reply_key)
    running.bus.publish(KEY, encode(query("q1")))
    assert running.to_pl.get(timeout=5).in_reply_to == "q1"
    assert running.agent.handled_on == [DELIVERY]
    assert running.transport.put_by == [(reply_key, AGENT)]


def test_an_error_in_a_step_on_the_receiving_thread_is_raised_by_run() -> None:
    r = start()
    r.agent.fail_persist = True
    r.bus.publish(KEY, encode(query("q1")))
    r.thread.join(timeout=5)
    assert not r.thread.is_alive()
    assert len(r.raised) == 1 and isinstance(r.raised[0], OSError)
    assert r.agent.handled_on == [DELIVERY]
    r.transport.close()


def test_agent_thread_mode_hands_every_communicate_to_the_agents_thread(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("ROCO_RECEIVE", "agent-thread")
    r = start()
    try:
        r.bus.publish(KEY, encode(query("q1")))
        assert r.to_pl.get(timeout=5).in_reply_to == "q1"
        assert r.agent.handled_on == [AGENT]
        assert r.transport.put_by == [(keys.fipa_key("C4", "a_km", "a_pl"), AGENT)]
    finally:
        r.agent.engine.stop()
        r.thread.join(timeout=5)
        r.transport.close()


def test_what_arrives_together_is_taken_in_together_by_the_agents_thread(
    running: Running, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(agent_module, "INLINE_GAP_S", 10.0)
    for n in range(3):
        running.bus.publish(KEY, encode(query(f"q{n}", conversation_id=f"c{n}")))
    answers = [running.to_pl.get(timeout=5).in_reply_to for _ in range(3)]
    assert answers == ["q0", "q1", "q2"]
    # the first arrived apart from anything before it; the next two within the gap
    assert running.agent.counters["received_inline"] == 1
    assert running.agent.handled_on[0] == DELIVERY and AGENT in running.agent.handled_on


class Computing(Answering):
    """Each step computes (CPU time of its thread) for twice the inline budget."""

    def _answer(self) -> None:
        started = time.thread_time()
        while time.thread_time() - started < 2 * agent_module.INLINE_BUDGET_S:
            pass
        super()._answer()


class Waiting(Answering):
    """Each step waits, without computing, for twice the inline budget (as a thread does that
    waits for a core while many processes share few, or for room in a full link)."""

    def _answer(self) -> None:
        time.sleep(2 * agent_module.INLINE_BUDGET_S)
        super()._answer()


@pytest.mark.parametrize(("agent_cls", "second_on"), [(Computing, AGENT), (Waiting, DELIVERY)])
def test_only_a_step_that_computes_past_the_budget_ends_inline_receiving(
    monkeypatch: pytest.MonkeyPatch, agent_cls: type[Answering], second_on: str
) -> None:
    monkeypatch.setattr(agent_module, "INLINE_BUDGET_S", 0.02)
    r = start(agent_cls)
    try:
        for n in range(2):
            r.bus.publish(KEY, encode(query(f"q{n}", conversation_id=f"c{n}")))
            assert r.to_pl.get(timeout=5).in_reply_to == f"q{n}"
            r.idle()
        assert r.agent.handled_on == [DELIVERY, second_on]
    finally:
        r.agent.engine.stop()
        r.thread.join(timeout=5)
        r.transport.close()


# ---- over Zenoh: puts from the receiving thread while both links' queues are full ----------
BULK = 600
"""Communicates of 64 kB each side streams to the other (≈ 38 MB each way: far more than
Zenoh's transmission queue holds, so both sides' puts block for room)."""
ANSWER_EVERY = 5
ANSWERS = 8
"""Every ANSWER_EVERY-th bulk arrival is answered with ANSWERS puts from the receiving thread,
as an idle agent's step taken in there puts its answers (at most INLINE_OUTPUT_MAX)."""


@pytest.fixture
def router_endpoint(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    yield from embedded_router(tmp_path_factory, "inline-router")


def test_puts_from_the_receiving_thread_go_through_while_both_links_are_full(router_endpoint: str) -> None:
    """Two sessions as agents use them stream to each other with congestion control BLOCK
    (their streaming threads block while the queues are full) and each answers what it receives
    from its receiving thread at the same time, as an idle agent's step taken in there does:
    every communicate arrives on both sides, none is lost, nothing deadlocks. The receiving
    thread is fed through a FIFO with room (transport.py ``RECEIVE_QUEUE``), so a put that waits
    there never stops Zenoh reading the link; with the 256 places of zenoh-python's own
    callbacks this test deadlocked in 2 of 3 runs."""
    assert ANSWERS <= INLINE_OUTPUT_MAX
    names = ("a_pl", "a_km")
    transports = {n: ZenohTransport([router_endpoint]) for n in names}
    payload = b"x" * 65_536
    want = BULK + BULK // ANSWER_EVERY * ANSWERS
    got = {n: 0 for n in names}
    bulk_in = {n: 0 for n in names}
    done = {n: threading.Event() for n in names}
    lock = threading.Lock()
    hello = {n: threading.Event() for n in names}
    try:
        for me, peer in (names, names[::-1]):
            # bulk on one channel's key, answers on another's: both reach the peer's inbox
            bulk, answer = keys.fipa_key("C4", peer, me), keys.fipa_key("C5", me, peer)

            def arrived(key: str, data: bytes, me: str = me, bulk: str = bulk, answer: str = answer) -> None:
                if data == b"hello":  # the route from the peer is there
                    hello[me].set()
                    return
                with lock:
                    got[me] += 1
                    total = got[me]
                    bulk_in[me] += key == bulk
                    answer_now = key == bulk and bulk_in[me] % ANSWER_EVERY == 0
                if answer_now:
                    for _ in range(ANSWERS):  # on the receiving thread, as _take_here puts
                        transports[me].publish(answer, payload)
                if total >= want:
                    done[me].set()

            transports[me].subscribe(keys.inbox_key(me), arrived)
        # both publishers of each side declared here (never from a receiving thread), and
        # put until the peer has one: a subscription reaches the router a moment after it is
        # declared, and what is put before that goes nowhere
        for _ in range(200):
            for me, peer in (names, names[::-1]):
                for channel in ("C4", "C5"):
                    transports[me].publish(keys.fipa_key(channel, me, peer), b"hello")
            if all(h.wait(0.05) for h in hello.values()):
                break
        assert all(h.is_set() for h in hello.values()), "no route between the two sessions"
        for me, peer in (names, names[::-1]):
            assert transports[me].declared(keys.fipa_key("C5", me, peer))

        def stream(me: str, peer: str) -> None:
            for _ in range(BULK):
                transports[me].publish(keys.fipa_key("C4", me, peer), payload)

        threads = [threading.Thread(target=stream, args=p, daemon=True) for p in (names, names[::-1])]
        for t in threads:
            t.start()
        for n in names:
            assert done[n].wait(30), f"{n} got {got[n]} of {want}: the links deadlocked"
        for t in threads:
            t.join(timeout=30)
            assert not t.is_alive()
        assert got == {n: want for n in names}
    finally:
        for t in transports.values():
            t.close()


class BurstTransport(ThreadedTransport):
    """A threaded transport that says, as ZenohTransport's receiving threads do, whether more
    input waits behind the communicate being called back (here: set by the test)."""

    burst = False

    def more_waiting(self) -> bool:
        return self.burst


def test_a_transport_that_reports_a_burst_decides_what_is_taken_in_here(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """With ``more_waiting`` the time between arrivals no longer counts: back-to-back
    communicates are taken in here while nothing waits behind them, and a burst goes to the
    agent's thread."""
    monkeypatch.setattr(agent_module, "INLINE_GAP_S", 10.0)  # the gap rule would hand all over
    r = start(transport_cls=BurstTransport)
    transport, agent, to_pl = r.transport, r.agent, r.to_pl
    assert isinstance(transport, BurstTransport)
    try:
        for n in range(2):
            r.bus.publish(KEY, encode(query(f"q{n}", conversation_id=f"c{n}")))
            assert to_pl.get(timeout=5).in_reply_to == f"q{n}"
            r.idle()
        assert agent.counters["received_inline"] == 2
        transport.burst = True
        r.bus.publish(KEY, encode(query("q2", conversation_id="c2")))
        assert to_pl.get(timeout=5).in_reply_to == "q2"
        assert agent.counters["received_inline"] == 2 and agent.handled_on[-1] == AGENT
    finally:
        agent.engine.stop()
        r.thread.join(timeout=5)
        transport.close()


def test_a_receiving_thread_knows_whether_a_sample_waits_behind_the_one_it_calls_back(
    router_endpoint: str,
) -> None:
    """The first sample is called back while nothing follows it; two more put meanwhile (and
    in the FIFO before a marker put after them on the same link arrives) are called back, the
    first with one behind it, the last with none."""
    receiver = ZenohTransport([router_endpoint])
    sender = ZenohTransport([router_endpoint])
    try:
        seen: list[tuple[bytes, bool]] = []
        probed, first = threading.Event(), threading.Event()
        release, marker, done = threading.Event(), threading.Event(), threading.Event()

        def on_sample(key: str, payload: bytes) -> None:
            seen.append((payload, receiver.more_waiting()))
            probed.set()
            if payload == b"first":
                first.set()
                assert release.wait(WAIT_S)
            if payload == b"third":
                done.set()

        receiver.subscribe(keys.inbox_key("a_pl"), on_sample)
        receiver.subscribe("test/marker", lambda k, p: marker.set())
        key = keys.fipa_key("C4", "a_km", "a_pl")
        deadline = time.monotonic() + WAIT_S
        while not probed.wait(0.05):  # until the subscriber's declaration has reached the sender
            assert time.monotonic() < deadline
            sender.publish(key, b"probe")
        sender.publish(key, b"first")  # after every probe, on the same link
        assert first.wait(WAIT_S)
        sender.publish(key, b"second")
        sender.publish(key, b"third")
        sender.publish("test/marker", b"")
        assert marker.wait(WAIT_S)
        release.set()
        assert done.wait(WAIT_S)
        seen = [s for s in seen if s[0] != b"probe"]
        assert seen == [(b"first", False), (b"second", True), (b"third", False)]
        assert not receiver.more_waiting()  # not on a receiving thread
    finally:
        sender.close()
        receiver.close()
