"""The backlog (services/runtime/backlog.py): a publish with no put in progress on its key is put
at once on the calling thread; what is published behind a put in progress leaves in one batch,
put by the thread that holds the put, bounded, in order, nothing lost."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator

import pytest

from services.runtime import keys
from services.runtime.backlog import Backlog
from services.runtime.transport import ZenohTransport
from shared.fipa_codec import Performative, encode
from shared.fipa_codec.batch import BATCH_MAX_BYTES, BATCH_MAX_COMMUNICATES, count, is_batch, pack, unpack
from tests.support.messages import communicate as message
from tests.support.router import embedded_router

KEY = "roco/fipa/C4/a_km/a_pl"
OTHER = "roco/fipa/C4/a_km/a_co"


def communicate(text: str, size: int = 0) -> bytes:
    """One encoded inform in conversation ``text``, its content ``size`` bytes."""
    return encode(message(Performative.INFORM, "a_km", "a_pl", None, text, content=b"x" * size))


def contents(puts: list[tuple[str, bytes]], key: str = KEY) -> list[bytes]:
    """The communicates put on ``key``, each batch split, in order."""
    return [part for k, payload in puts if k == key for part in unpack(payload)]


class Gate:
    """A put function that records (key, payload, thread) and, while ``closed`` is set for a
    call, waits in that call for :meth:`open` (a put in progress, deterministically)."""

    def __init__(self) -> None:
        self.puts: list[tuple[str, bytes]] = []
        self.threads: list[int] = []
        self.entered = threading.Event()
        self._open = threading.Event()
        self.hold_next = False

    def __call__(self, key: str, payload: bytes) -> None:
        self.puts.append((key, payload))
        self.threads.append(threading.get_ident())
        if self.hold_next:
            self.hold_next = False
            self.entered.set()
            assert self._open.wait(10.0)

    def open(self) -> None:
        self._open.set()

    def on(self, key: str) -> Callable[[bytes], None]:
        """The put on ``key``."""
        return lambda payload: self(key, payload)


@pytest.fixture
def gate() -> Iterator[Gate]:
    g = Gate()
    yield g
    g.open()


def in_thread(backlog: Backlog, key: str, payload: bytes) -> threading.Thread:
    """A thread that publishes ``payload`` (started)."""
    thread = threading.Thread(target=backlog.publish, args=(key, payload))
    thread.start()
    return thread


def test_an_idle_publish_is_put_at_once_alone_on_its_thread(gate: Gate) -> None:
    backlog = Backlog(gate.on)
    one, two = communicate("one"), communicate("two")
    backlog.publish(KEY, one)
    assert gate.puts == [(KEY, one)]  # put before publish returned
    backlog.publish(KEY, two)
    assert gate.puts == [(KEY, one), (KEY, two)]  # nothing waits to fill a batch
    assert gate.threads == [threading.get_ident()] * 2 and backlog.joined == 0


def test_what_waits_behind_a_put_in_progress_leaves_in_one_batch(gate: Gate) -> None:
    backlog = Backlog(gate.on)
    first = communicate("first")
    waiting = [communicate(f"w{i}") for i in range(3)]
    gate.hold_next = True
    holder = in_thread(backlog, KEY, first)
    assert gate.entered.wait(10.0)
    for payload in waiting:
        backlog.publish(KEY, payload)  # returns at once: appended behind the put in progress
    assert gate.puts == [(KEY, first)]
    gate.open()
    holder.join(10.0)
    assert gate.puts == [(KEY, first), (KEY, pack(waiting))]
    assert gate.threads == [holder.ident] * 2 and backlog.joined == 1


def test_another_key_is_not_held_up_by_a_put_in_progress(gate: Gate) -> None:
    backlog = Backlog(gate.on)
    gate.hold_next = True
    holder = in_thread(backlog, KEY, communicate("held"))
    assert gate.entered.wait(10.0)
    other = communicate("other")
    backlog.publish(OTHER, other)
    assert gate.puts[-1] == (OTHER, other)  # put at once on this thread
    gate.open()
    holder.join(10.0)


def test_batches_waiting_join_without_nesting_in_order(gate: Gate) -> None:
    backlog = Backlog(gate.on)
    gate.hold_next = True
    holder = in_thread(backlog, KEY, communicate("held"))
    assert gate.entered.wait(10.0)
    step = [communicate(f"s{i}") for i in range(3)]
    backlog.publish(KEY, pack(step))  # a step's batch
    backlog.publish(KEY, communicate("alone"))
    gate.open()
    holder.join(10.0)
    last = gate.puts[-1][1]
    assert is_batch(last) and unpack(last) == [*step, communicate("alone")]
    assert not any(is_batch(part) for part in unpack(last))


def test_what_waits_is_bounded_and_the_publisher_waits_for_room(gate: Gate) -> None:
    """One batch's worth waits at most; a further publish waits (as a BLOCK put waits for room)
    until the holder takes it; every put stays within the batch limits; nothing is lost."""
    backlog = Backlog(gate.on)
    gate.hold_next = True
    holder = in_thread(backlog, KEY, communicate("held"))
    assert gate.entered.wait(10.0)
    size = BATCH_MAX_BYTES // 100  # ≈ 100 fill the bytes, fewer than the count limit
    sent = [communicate(f"p{i}", size) for i in range(350)]

    def produce() -> None:
        for payload in sent:
            backlog.publish(KEY, payload)

    producer = threading.Thread(target=produce)
    producer.start()
    producer.join(0.5)
    assert producer.is_alive()  # waits for room: the holder is still in its put
    gate.open()
    holder.join(10.0)
    producer.join(10.0)
    assert contents(gate.puts) == [communicate("held"), *sent]
    for _, payload in gate.puts[1:]:
        assert count(payload) <= BATCH_MAX_COMMUNICATES
        assert sum(len(p) for p in unpack(payload)) <= BATCH_MAX_BYTES
    assert backlog.joined >= 1


def test_the_count_limit_bounds_a_batch(gate: Gate) -> None:
    backlog = Backlog(gate.on)
    gate.hold_next = True
    holder = in_thread(backlog, KEY, communicate("held"))
    assert gate.entered.wait(10.0)
    step = pack([communicate(f"s{i}") for i in range(BATCH_MAX_COMMUNICATES - 1)])
    backlog.publish(KEY, step)
    backlog.publish(KEY, communicate("a"))
    over = in_thread(backlog, KEY, communicate("b"))  # one over the limit: waits for room
    gate.open()
    holder.join(10.0)
    over.join(10.0)
    assert [count(p) for _, p in gate.puts] == [1, BATCH_MAX_COMMUNICATES, 1]


def test_a_put_that_raises_leaves_what_waits_for_the_next_publish() -> None:
    puts: list[tuple[str, bytes]] = []
    entered, release = threading.Event(), threading.Event()
    failed: list[BaseException] = []

    def put(key: str, payload: bytes) -> None:
        if not puts and not failed and not entered.is_set():
            entered.set()
            release.wait(10.0)
            raise ConnectionError("session closed")
        puts.append((key, payload))

    backlog = Backlog(lambda key: lambda payload: put(key, payload))

    def hold() -> None:
        try:
            backlog.publish(KEY, communicate("lost"))
        except ConnectionError as exc:
            failed.append(exc)

    holder = threading.Thread(target=hold)
    holder.start()
    assert entered.wait(10.0)
    backlog.publish(KEY, communicate("a"))
    backlog.publish(KEY, communicate("b"))
    release.set()
    holder.join(10.0)
    assert failed and puts == []  # the holder's error is its own; a and b still wait
    backlog.publish(KEY, communicate("c"))
    assert contents(puts) == [communicate("a"), communicate("b"), communicate("c")]


def test_order_per_key_under_concurrency_nothing_lost() -> None:
    """Four threads publish on two keys at once through a put that lets other threads run (as a
    Zenoh put does): per key, each thread's communicates arrive in its order, each once."""
    lock = threading.Lock()
    puts: list[tuple[str, bytes]] = []

    def put(key: str, payload: bytes) -> None:
        os.sched_yield()
        with lock:
            puts.append((key, payload))
        os.sched_yield()

    backlog = Backlog(lambda key: lambda payload: put(key, payload))
    n = 500
    sent = {
        (t, key): [communicate(f"{t}:{key[-4:]}:{i}") for i in range(n)]
        for t in range(4)
        for key in (KEY, OTHER)
    }

    def produce(t: int) -> None:
        for i in range(n):
            for key in (KEY, OTHER):
                backlog.publish(key, sent[(t, key)][i])

    threads = [threading.Thread(target=produce, args=(t,)) for t in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30.0)
    for key in (KEY, OTHER):
        got = contents(puts, key)
        assert len(got) == 4 * n
        for t in range(4):
            mine = set(sent[(t, key)])
            assert [p for p in got if p in mine] == sent[(t, key)]


@pytest.fixture(scope="module")
def router_endpoint(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    yield from embedded_router(tmp_path_factory, "backlog-router")


def test_threads_putting_on_one_zenoh_key_arrive_in_order_none_lost(router_endpoint: str) -> None:
    """Over Zenoh: three threads put on one key of one transport at once; the receiver gets every
    communicate once, each thread's in its order (batches split)."""
    sender, receiver = ZenohTransport([router_endpoint]), ZenohTransport([router_endpoint])
    key = keys.fipa_key("C4", "a_km", "a_pl")
    n, threads = 2000, 3
    got: list[bytes] = []
    hello, done = threading.Event(), threading.Event()

    def arrived(_key: str, payload: bytes) -> None:
        if payload == b"hello":
            hello.set()
            return
        got.extend(unpack(payload))
        if len(got) >= n * threads:
            done.set()

    try:
        receiver.subscribe(keys.inbox_key("a_pl"), arrived)
        while not hello.is_set():  # the route to the receiver is there (the publisher declared)
            sender.publish(key, b"hello")
            hello.wait(0.05)
        sent = {t: [communicate(f"{t}-{i}", 100) for i in range(n)] for t in range(threads)}
        workers = [
            threading.Thread(target=lambda t=t: [sender.publish(key, p) for p in sent[t]])
            for t in range(threads)
        ]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join(30.0)
        assert done.wait(30.0)
        assert len(got) == n * threads
        for t in range(threads):
            mine = set(sent[t])
            assert [p for p in got if p in mine] == sent[t]
    finally:
        sender.close()
        receiver.close()
