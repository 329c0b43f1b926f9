"""A receiving thread of the Zenoh transport ends only when the transport is closed: one that
ends otherwise is told (``ZenohTransport.on_lost``, ``lost``), so that the agent's process ends
instead of living on deaf (services/runtime/transport.py, services/runtime/main.py)."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator

import pytest

from services.runtime import keys
from services.runtime.transport import ZenohTransport
from tests.support.router import embedded_router

WAIT_S = 10.0


class Planted(BaseException):
    """What no ``except Exception`` catches: a callback that raises it ends its thread."""


@pytest.fixture(scope="module")
def endpoint(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    yield from embedded_router(tmp_path_factory, "receiving_thread")


def test_a_receiving_thread_that_ends_before_close_is_told_and_close_is_quiet(endpoint: str) -> None:
    inbox = keys.inbox_key("deaf")
    key = keys.fipa_key("C1", "someone", "deaf")
    told: queue.SimpleQueue[str] = queue.SimpleQueue()
    got: queue.SimpleQueue[bytes] = queue.SimpleQueue()

    def callback(_key: str, payload: bytes) -> None:
        if payload == b"fault":
            raise ValueError("a handler's fault: logged, the thread goes on")
        if payload == b"end":
            raise Planted("the thread's end")
        got.put(payload)

    receiver = ZenohTransport([endpoint])
    sender = ZenohTransport([endpoint])
    try:
        receiver.on_lost = told.put
        receiver.subscribe(inbox, callback)
        ready = threading.Event()
        receiver.subscribe(keys.COUNTERS_ASK, lambda k, p: ready.set())
        while not ready.is_set():  # the subscriptions reach the router: a put is not lost
            sender.publish(keys.COUNTERS_ASK, b"")
            ready.wait(0.05)
        sender.publish(key, b"fault")
        sender.publish(key, b"one")
        assert got.get(timeout=WAIT_S) == b"one"
        assert receiver.lost is None
        sender.publish(key, b"end")
        why = told.get(timeout=WAIT_S)
        assert why == f"the receiving thread of {inbox} ended: Planted: the thread's end"
        assert receiver.lost == why
    finally:
        sender.close()
        receiver.close()
    assert told.empty()  # closing ends the other receiving threads quietly


def test_closing_ends_receiving_threads_quietly(endpoint: str) -> None:
    told: list[str] = []
    transport = ZenohTransport([endpoint])
    transport.on_lost = told.append
    transport.subscribe(keys.inbox_key("quiet"), lambda k, p: None)
    transport.close()
    assert told == [] and transport.lost is None
