"""Transport: how buffers reach other agents. Zenoh in client mode against a router
(design.md), explicit endpoints, no multicast scouting.

Subscriber callbacks run on Zenoh's threads and only enqueue (calling Zenoh from inside a
callback has deadlocked: platform-notes.md); all publishing happens on the agent's thread.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from typing import Protocol

import zenoh

Callback = Callable[[str, bytes], None]
AliveCallback = Callable[[str, bool], None]


class Transport(Protocol):
    """What the runtime needs of a transport."""

    def publish(self, key: str, payload: bytes) -> None: ...
    def subscribe(self, key_expr: str, callback: Callback) -> None: ...
    def announce(self, key: str) -> None: ...
    def watch(self, key_expr: str, callback: AliveCallback) -> None: ...
    def close(self) -> None: ...


CONNECT_RETRY = {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2}
"""How often a session tries its endpoints again while it has no connection: 0.1 s, then
doubling up to 1 s (Zenoh's default: 1 s doubling up to 4 s). A client whose router is lost
(e.g. killed and started again on the same endpoint) reconnects by itself on this schedule and
Zenoh declares its subscribers and liveliness tokens again: the session is back within ~1 s of
the router listening again (docs/recovery.md, "Router restart")."""


def client_config(endpoints: list[str], *, wait_for_router: bool = True) -> zenoh.Config:
    """A Zenoh client configuration connecting to ``endpoints`` (e.g. ``tcp/127.0.0.1:7447``)
    with multicast scouting off. ``wait_for_router`` retries forever instead of failing
    ``zenoh.open`` after ~0.1 s when no router answers (platform-notes.md). Either way a session
    that loses its router reconnects on the :data:`CONNECT_RETRY` schedule, forever."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps(endpoints))
    conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if wait_for_router:
        conf.insert_json5("connect/timeout_ms", "-1")
    return conf


def router_config(listen: list[str], connect: list[str] | None = None) -> zenoh.Config:
    """A Zenoh router configuration listening on ``listen``, optionally meshed with other
    routers at ``connect`` (reconnected on the :data:`CONNECT_RETRY` schedule when one of them
    restarts); multicast scouting off."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"router"')
    conf.insert_json5("listen/endpoints", json.dumps(listen))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
        conf.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    return conf


class ZenohTransport:
    """A :class:`Transport` over one Zenoh session."""

    def __init__(self, endpoints: list[str], *, wait_for_router: bool = True) -> None:
        self.session = zenoh.open(client_config(endpoints, wait_for_router=wait_for_router))
        self._subs: list[zenoh.Subscriber] = []
        self._tokens: list[tuple[str, zenoh.LivelinessToken]] = []
        self._lock = threading.Lock()

    def publish(self, key: str, payload: bytes) -> None:
        self.session.put(key, payload)

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.payload.to_bytes())

        with self._lock:
            self._subs.append(self.session.declare_subscriber(key_expr, on_sample))

    def announce(self, key: str) -> None:
        """Declare a liveliness token on ``key`` for the life of this transport."""
        with self._lock:
            self._tokens.append((key, self.session.liveliness().declare_token(key)))

    def withdraw(self, key: str) -> None:
        """Undeclare the liveliness tokens on ``key`` (``announce`` declares it again); used by
        the fault layer to make a partitioned agent look gone."""
        with self._lock:
            gone = [tok for k, tok in self._tokens if k == key]
            self._tokens = [(k, tok) for k, tok in self._tokens if k != key]
        for tok in gone:
            tok.undeclare()

    def watch(self, key_expr: str, callback: AliveCallback) -> None:
        """Call ``callback(key, alive)`` whenever a liveliness token matching ``key_expr``
        appears (True; tokens alive at the time of the call included) or disappears (False:
        undeclared, or its owner's session ended or was lost). Runs on Zenoh's threads."""

        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        with self._lock:
            self._subs.append(self.session.liveliness().declare_subscriber(key_expr, on_sample, history=True))

    def close(self) -> None:
        for _, tok in self._tokens:
            tok.undeclare()
        for sub in self._subs:
            sub.undeclare()
        self.session.close()
