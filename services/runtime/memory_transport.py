"""An in-process :class:`~services.runtime.transport.Transport`: several agents in one
process share a :class:`MemoryBus` (unit tests of agent logic; single-process experiments).
Key matching uses Zenoh's own key-expression semantics."""

from __future__ import annotations

import threading

import zenoh

from services.runtime.transport import Callback


class MemoryBus:
    """Delivers every publication to the subscribers whose key expression intersects it."""

    def __init__(self) -> None:
        self._subs: list[tuple[zenoh.KeyExpr, Callback]] = []
        self._tokens: set[str] = set()
        self._lock = threading.Lock()
        self.published: list[tuple[str, bytes]] = []

    def transport(self) -> MemoryTransport:
        return MemoryTransport(self)

    def publish(self, key: str, payload: bytes) -> None:
        ke = zenoh.KeyExpr(key)
        with self._lock:
            self.published.append((key, payload))
            targets = [cb for expr, cb in self._subs if expr.intersects(ke)]
        for cb in targets:
            cb(key, payload)

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        with self._lock:
            self._subs.append((zenoh.KeyExpr(key_expr), callback))

    def announce(self, key: str) -> None:
        with self._lock:
            self._tokens.add(key)

    def alive(self) -> set[str]:
        with self._lock:
            return set(self._tokens)


class MemoryTransport:
    """One agent's handle on a :class:`MemoryBus`."""

    def __init__(self, bus: MemoryBus) -> None:
        self.bus = bus

    def publish(self, key: str, payload: bytes) -> None:
        self.bus.publish(key, payload)

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        self.bus.subscribe(key_expr, callback)

    def announce(self, key: str) -> None:
        self.bus.announce(key)

    def close(self) -> None:
        return None
