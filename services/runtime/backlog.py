"""Communicates that wait behind a put in progress on their key leave together, in one put.

JADE's message transport batches only when a backlog builds for one receiver, so an idle link
adds no latency while a stream goes fast. :class:`Backlog` does that for any put function and
any key (a key of ``roco/fipa/**`` is one sender, one receiver, one channel):

- a :meth:`Backlog.publish` that finds no put in progress on its key puts at once, on the
  calling thread: no hand-off to another thread, nothing waits to fill a batch;
- one that finds a put in progress on its key (another thread's: a full link makes a put with
  congestion control BLOCK wait for room; a Zenoh put also lets other Python threads run while
  it is in Zenoh) appends its payload to the key's pending list and returns;
- the thread that holds the put, when its put returns, puts what is pending as one payload
  (shared/fipa_codec/batch.py :func:`~shared.fipa_codec.batch.join`: at most
  :data:`~shared.fipa_codec.batch.BATCH_MAX_COMMUNICATES` communicates and
  :data:`~shared.fipa_codec.batch.BATCH_MAX_BYTES`, a larger payload alone), and again until
  nothing is pending, then returns.

Per key, payloads are put in the order :meth:`Backlog.publish` was called (FIFO), each once.
Nothing is dropped and memory stays bounded: a publish that finds its key's pending list
holding one batch's worth waits until the holder takes it (as a put with congestion control
BLOCK waits for room). A put that raises raises in the thread that holds it; what is pending
stays pending and goes, first, with the key's next publish.

Within one agent its steps run one at a time (``Agent`` holds its turn while it puts), so what
arrives while a step puts waits in the agent's input queue and the next step's answers to one
receiver leave in one batch already (``Engine.dispatch``); the backlog here joins what other
threads put on the same key meanwhile: the fault layer's worker (services/runtime/faults.py),
several agents or clients on one transport.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable

from shared.fipa_codec.batch import BATCH_MAX_BYTES, BATCH_MAX_COMMUNICATES, count, join

Put = Callable[[bytes], None]
"""A put on one key: one payload (an encoded communicate or a batch of them)."""


class _Key:
    """One key's state: whether a thread holds a put on it, and what waits behind that put
    (payloads, their communicates and bytes)."""

    __slots__ = ("busy", "communicates", "pending", "put", "size")

    def __init__(self, put: Put) -> None:
        self.put = put
        self.busy = False
        self.pending: deque[bytes] = deque()
        self.communicates = 0
        self.size = 0

    def full(self) -> bool:
        return self.communicates >= BATCH_MAX_COMMUNICATES or self.size >= BATCH_MAX_BYTES

    def take(self) -> list[bytes]:
        """The payloads at the front of the pending list that go in one put (at least one;
        together at most one batch's communicates and bytes), taken off it."""
        first = self.pending.popleft()
        group, n, size = [first], count(first), len(first)
        while self.pending:
            nxt = self.pending[0]
            n2, size2 = n + count(nxt), size + len(nxt)
            if n2 > BATCH_MAX_COMMUNICATES or size2 > BATCH_MAX_BYTES:
                break
            group.append(self.pending.popleft())
            n, size = n2, size2
        self.communicates -= n
        self.size -= size
        return group


class Backlog:
    """Puts on each key through ``put_for(key)`` (asked once per key; its payloads: encoded
    communicates or batches of them, shared/fipa_codec/batch.py), joining per key what waits
    behind a put in progress (see the module docstring). Thread-safe; keeps state for every key
    it was given (the caller bounds the keys)."""

    def __init__(self, put_for: Callable[[str], Put]) -> None:
        self._put_for = put_for
        self._lock = threading.Lock()
        self._room = threading.Condition(self._lock)
        """Notified whenever a key's pending list shrinks or its put is let go."""
        self._keys: dict[str, _Key] = {}
        self.joined = 0
        """Puts that carried more than one waiting payload (a batch formed here)."""

    def publish(self, key: str, payload: bytes) -> None:
        """Put ``payload`` on ``key`` now on this thread, or, when another thread's put on
        ``key`` is in progress, leave it for that thread to put after its own (waiting while
        one batch's worth already waits). Raises what ``put`` raised (this thread's puts only)."""
        with self._lock:
            k = self._keys.get(key)
            if k is None:
                k = self._keys[key] = _Key(self._put_for(key))
            mine: bytes | None = payload
            if k.busy or k.pending:
                if not self._wait_behind(k, payload):
                    return
                mine = None  # this thread holds the put now: its payload waits with the rest
            k.busy = True
        try:
            if mine is not None:
                k.put(mine)
            with self._lock:
                if not k.pending:  # nothing waited: the common case, one put
                    k.busy = False
                    return
        except BaseException:
            self._let_go(k)
            raise
        self._drain(k)

    def _wait_behind(self, k: _Key, payload: bytes) -> bool:
        """Append ``payload`` to ``k``'s pending list, first waiting for room while a put is in
        progress (lock held). Returns whether this thread must hold the put now (none is in
        progress: what waits is left by a holder whose put raised, and goes first)."""
        while k.busy and k.full():
            self._room.wait()
        k.pending.append(payload)
        k.communicates += count(payload)
        k.size += len(payload)
        return not k.busy

    def _drain(self, k: _Key) -> None:
        """Put what waits on ``k``'s key (this thread holds its put), a batch at a time, until
        nothing does."""
        try:
            while True:
                with self._lock:
                    if not k.pending:
                        k.busy = False
                        return
                    group = k.take()
                    self.joined += len(group) > 1
                    self._room.notify_all()
                k.put(join(group))
        except BaseException:
            self._let_go(k)
            raise

    def _let_go(self, k: _Key) -> None:
        """This thread's put raised: let go of ``k``'s put (what waits stays, for the next)."""
        with self._lock:
            k.busy = False
            self._room.notify_all()
