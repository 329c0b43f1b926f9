"""Direct subscriptions keep the order of arrival across keys (services/runtime/transport.py
``subscribe(..., direct=True)``, ``subscribe_recovering(..., direct=True)``): their callbacks run
on the Zenoh network thread that read the samples. With zenoh-python's default a callback runs on
a thread of its subscription's own, and samples put one after the other on two keys reached
their callbacks out of order (49 to 639 adjacent pairs of 20,000 in runs on a 2-core VM): the
traffic recorder's sync token could be enqueued before what was routed before it."""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Iterator

import pytest
import zenoh

from services.runtime.session import open_client
from services.runtime.transport import ZenohTransport
from tests.support.router import embedded_router

N = 20_000
KEYS = ("test/direct/a", "test/direct/b")
BLOCK = zenoh.CongestionControl.BLOCK
"""The puts wait for room (as the runtime's): with Zenoh's default (DROP) a loaded machine drops
samples of a burst (3,352 of 20,000 arrived in a CI run), and this test is about their order."""


@pytest.fixture
def router_endpoint(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    yield from embedded_router(tmp_path_factory, "direct-router")


def test_two_direct_subscriptions_see_the_puts_of_one_session_in_order(router_endpoint: str) -> None:
    receiver = ZenohTransport([router_endpoint])
    sender = open_client(router_endpoint)
    got: list[int] = []
    heard: set[str] = set()
    lock = threading.Lock()
    all_in = threading.Event()

    def take(key: str, payload: bytes) -> None:
        n = int(payload)
        with lock:
            if n < 0:  # a probe: the router routes this key to the receiver
                heard.add(key)
                return
            got.append(n)
            if len(got) == N:
                all_in.set()

    try:
        receiver.subscribe(KEYS[0], take, direct=True)
        receiver.subscribe_recovering(KEYS[1], lambda a: take(a.key, a.payload), direct=True)
        deadline = time.monotonic() + 30
        while heard != set(KEYS):
            assert time.monotonic() < deadline, f"only {heard} routed to the receiver"
            for key in KEYS:
                sender.put(key, b"-1")
            all_in.wait(0.05)  # a probe's round trip (all_in is not set yet)
        for i in range(N):
            sender.put(KEYS[i % 2], str(i).encode(), congestion_control=BLOCK)
        assert all_in.wait(60), f"{len(got)} of {N} samples arrived"
        with lock:
            out_of_order = sum(1 for x, y in itertools.pairwise(got) if y < x)
        assert out_of_order == 0
    finally:
        sender.close()
        receiver.close()


def test_a_direct_watch_sees_a_token_before_what_its_owner_put_next(
    router_endpoint: str,
) -> None:
    """The recorder's presence record: a token that appeared before a communicate routed after it
    is written before that communicate (on a thread of its own the liveliness subscriber let a
    replayed a_ta see ag_ex appear after the request it had sent because ag_ex was there)."""
    n = 1_000
    receiver = ZenohTransport([router_endpoint])
    sender = open_client(router_endpoint)
    events: list[tuple[str, int]] = []
    lock = threading.Lock()
    all_in = threading.Event()
    probe = threading.Event()

    def on_alive(key: str, alive: bool) -> None:
        with lock:
            events.append(("token", int(key.rsplit("/", 1)[1])))

    def on_data(key: str, payload: bytes) -> None:
        i = int(payload)
        if i < 0:
            probe.set()
            return
        with lock:
            events.append(("data", i))
            if i == n - 1:
                all_in.set()

    tokens = []
    try:
        receiver.watch("test/presence/alive/*", on_alive, history=False, direct=True)
        receiver.subscribe("test/presence/data", on_data, direct=True)
        deadline = time.monotonic() + 30
        while not probe.is_set():
            assert time.monotonic() < deadline, "the data key is not routed to the receiver"
            sender.put("test/presence/data", b"-1")
            probe.wait(0.05)
        for i in range(n):
            tokens.append(sender.liveliness().declare_token(f"test/presence/alive/{i}"))
            sender.put("test/presence/data", str(i).encode(), congestion_control=BLOCK)
        assert all_in.wait(60), "not every put arrived"
        with lock:
            place = {e: k for k, e in enumerate(events)}
        late = [i for i in range(n) if place.get(("token", i), len(events)) > place[("data", i)]]
        assert late == [], f"{len(late)} of {n} tokens reached the watch after their owner's put"
    finally:
        for token in tokens:
            token.undeclare()
        sender.close()
        receiver.close()
