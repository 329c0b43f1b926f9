"""An in-process :class:`~services.runtime.transport.Transport`: several agents in one
process share a :class:`MemoryBus` (unit tests of agent logic; single-process experiments).
Key matching uses Zenoh's own key-expression semantics. Unlike Zenoh, the bus carries the
communicates of a batch (what one step put on one key together) one by one: its subscribers,
tests among them, read communicates only. With ``ROCO_TAP_DIR`` set, a bus appends every
communicate put on it to the tap (services/runtime/tap.py)."""

from __future__ import annotations

import threading
import time

import zenoh

from services.runtime.keys import is_communicate_key
from services.runtime.tap import Tap, bus_group
from services.runtime.transport import AliveCallback, Callback
from shared.fipa_codec.batch import unpack


class MemoryBus:
    """Delivers every publication to the subscribers whose key expression intersects it."""

    def __init__(self) -> None:
        self._subs: list[tuple[zenoh.KeyExpr, Callback]] = []
        self._tokens: set[str] = set()
        self._watchers: list[tuple[zenoh.KeyExpr, AliveCallback]] = []
        self._lock = threading.Lock()
        self.published: list[tuple[str, bytes]] = []
        """Every payload put, in order; a batch of communicates as each of them."""
        self.tap = Tap.from_env(bus_group())
        """Where the communicates put are tapped (None: ``ROCO_TAP_DIR`` unset)."""

    def transport(self) -> MemoryTransport:
        return MemoryTransport(self)

    def publish(self, key: str, payload: bytes) -> None:
        """Deliver ``payload`` to the subscribers of ``key``; a batch of communicates
        (shared/fipa_codec/batch.py) one communicate at a time, in order."""
        ke = zenoh.KeyExpr(key)
        if self.tap is not None:
            self.tap.put(time.time(), key, payload)
        parts = unpack(payload) if is_communicate_key(key) else [payload]
        with self._lock:
            self.published += [(key, part) for part in parts]
            targets = [cb for expr, cb in self._subs if expr.intersects(ke)]
        for part in parts:
            for cb in targets:
                cb(key, part)

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        with self._lock:
            self._subs.append((zenoh.KeyExpr(key_expr), callback))

    def announce(self, key: str) -> None:
        self._token_changed(key, True)

    def withdraw(self, key: str) -> None:
        """Remove a liveliness token (as when its owner's session ends)."""
        self._token_changed(key, False)

    def watch(self, key_expr: str, callback: AliveCallback) -> None:
        ke = zenoh.KeyExpr(key_expr)
        with self._lock:
            self._watchers.append((ke, callback))
            present = [k for k in self._tokens if ke.intersects(zenoh.KeyExpr(k))]
        for key in present:
            callback(key, True)

    def _token_changed(self, key: str, alive: bool) -> None:
        ke = zenoh.KeyExpr(key)
        with self._lock:
            if alive == (key in self._tokens):
                return
            if alive:
                self._tokens.add(key)
            else:
                self._tokens.discard(key)
            targets = [cb for expr, cb in self._watchers if expr.intersects(ke)]
        for cb in targets:
            cb(key, alive)

    def alive(self) -> set[str]:
        with self._lock:
            return set(self._tokens)


class MemoryTransport:
    """One agent's handle on a :class:`MemoryBus`."""

    def __init__(self, bus: MemoryBus) -> None:
        self.bus = bus
        self._tokens: list[str] = []

    def publish(self, key: str, payload: bytes) -> None:
        self.bus.publish(key, payload)

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        self.bus.subscribe(key_expr, callback)

    def announce(self, key: str) -> None:
        self._tokens.append(key)
        self.bus.announce(key)

    def withdraw(self, key: str) -> None:
        """Withdraw this transport's liveliness token on ``key`` (``announce`` declares it again)."""
        if key in self._tokens:
            self._tokens.remove(key)
            self.bus.withdraw(key)

    def watch(self, key_expr: str, callback: AliveCallback) -> None:
        self.bus.watch(key_expr, callback)

    def close(self) -> None:
        """Withdraw this transport's liveliness tokens (as a closed Zenoh session does)."""
        for key in self._tokens:
            self.bus.withdraw(key)
        self._tokens.clear()
