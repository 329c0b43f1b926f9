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
receiver leave in one batch already (``Agent._dispatch``); the backlog here joins what other
threads put on the same key meanwhile: the fault layer's worker (services/runtime/faults.py),
several agents or clients on one transport.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable

from shared.fipa_codec.batch import BATCH_MAX_BYTES, BATCH_MAX_COMMUNICATES, count, join

Put = Callable[[str, bytes], None]


class _Key:
    """One key's state: whether a thread holds a put on it, and what waits behind that put
    (payloads, their communicates and bytes)."""

    __slots__ = ("busy", "communicates", "pending", "size")

    def __init__(self) -> None:
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
    """Puts through ``put(key, payload)`` (payloads: encoded communicates or batches of them,
    shared/fipa_codec/batch.py), joining per key what waits behind a put in progress (see the
    module docstring). Thread-safe; keeps state for every key it was given (the caller bounds
    the keys)."""

    def __init__(self, put: Put) -> None:
        self._put = put
        self._room = threading.Condition(threading.Lock())
        self._keys: dict[str, _Key] = {}
        self.joined = 0
        """Puts that carried more than one waiting payload (a batch formed here)."""

    def publish(self, key: str, payload: bytes) -> None:
        """Put ``payload`` on ``key`` now on this thread, or, when another thread's put on
        ``key`` is in progress, leave it for that thread to put after its own (waiting while
        one batch's worth already waits). Raises what ``put`` raised (this thread's puts only)."""
        with self._room:
            k = self._keys.get(key)
            if k is None:
                k = self._keys[key] = _Key()
            while k.busy and k.full():
                self._room.wait()
            if k.busy:
                k.pending.append(payload)
                k.communicates += count(payload)
                k.size += len(payload)
                return
            k.busy = True
            first: bytes | None = payload
            if k.pending:  # left by a holder whose put raised: they go first
                k.pending.append(payload)
                k.communicates += count(payload)
                k.size += len(payload)
                first = None
        self._hold(key, k, first)

    def _hold(self, key: str, k: _Key, first: bytes | None) -> None:
        """Put ``first`` (unless None), then what is pending on ``key``, until nothing is."""
        try:
            if first is not None:
                self._put(key, first)
            while True:
                with self._room:
                    if not k.pending:
                        k.busy = False
                        return
                    group = k.take()
                    self.joined += len(group) > 1
                    self._room.notify_all()
                self._put(key, join(group))
        except BaseException:
            with self._room:
                k.busy = False
                self._room.notify_all()
            raise
