"""How a receiving thread waits for its next communicate: adaptive polling before sleeping.

A thread that sleeps in a blocking ``recv()`` is woken by Zenoh's network thread when a sample
arrives; on the 2-core VMs roco is measured on, each such wake-up of a sleeping thread costs
≈ 50 µs (docs/benchmarks.md, "Adaptive polling"), two per round trip. While a conversation is
quick (answers come back within :data:`DEFAULT_MAX_POLL_US`), the receiving thread instead polls
its FIFO (``try_recv``), giving its core away between polls (``sched_yield``, the GIL released),
for a window that adapts as Linux KVM's halt-polling does (``halt_poll_ns``, grow/shrink):

- a wait that ends within the window is a hit: the window stays;
- a poll that misses, then a sleep that ends within the maximum: the window grows (doubles,
  from :data:`GROW_START_US`), so the next quick answer is caught;
- a sleep longer than the maximum: the window shrinks (halves, to 0 below the start), so a
  thread whose peers answer slowly, or a fleet whose cores are busy, sleeps at once.

An idle agent therefore sleeps as before; only quick exchanges spend CPU on polling, at most
the window per communicate. ``ROCO_RECEIVE_POLL_US`` sets the maximum window (µs; 0 turns
polling off).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from typing import Protocol, TypeVar

from shared.settings import Settings

T = TypeVar("T")
T_co = TypeVar("T_co", covariant=True)

ENV_POLL = Settings.env_name("receive_poll_us")
DEFAULT_MAX_POLL_US = Settings().receive_poll_us
"""Longest poll window (µs): above a round trip through a router on one host (≈ 250–600 µs
measured), far below the gaps of an agent at work (ms)."""
GROW_START_US = 50.0
"""The window a thread starts polling with after a quick sleep (µs), doubled at each further
quick sleep up to the maximum."""


class Source(Protocol[T_co]):
    """A FIFO that can be read without waiting (``try_recv``: an item or None) and with
    (``recv``: blocks until an item; raises when the FIFO is closed), e.g. a Zenoh subscriber
    with a ``FifoChannel`` handler."""

    def try_recv(self) -> T_co | None: ...
    def recv(self) -> T_co: ...


def max_poll_us(env: Mapping[str, str] | None = None) -> float:
    """The maximum poll window (µs) from ``ROCO_RECEIVE_POLL_US`` of ``env`` (default
    ``os.environ``, read now; unset: :data:`DEFAULT_MAX_POLL_US`). Raises ValueError, naming
    the variable, for a value that is not a number ≥ 0."""
    return Settings.from_env(env, only=("receive_poll_us",)).receive_poll_us


class AdaptivePoll:
    """Waits for the next item of a :class:`Source`, polling first for an adaptive window
    (module docstring). One per receiving thread; not thread-safe.

    ``max_us``: the longest window (µs; 0: always sleep at once). ``clock`` (s) and ``yield_``
    (called between polls) are injectable for tests; by default ``time.perf_counter`` and
    ``os.sched_yield``."""

    def __init__(
        self,
        max_us: float = DEFAULT_MAX_POLL_US,
        *,
        clock: Callable[[], float] = time.perf_counter,
        yield_: Callable[[], None] = os.sched_yield,
    ) -> None:
        self.max_s = max_us / 1e6
        self.window_s = 0.0
        """The current poll window (s)."""
        self.polled = 0
        """Waits that ended in the poll (no sleep)."""
        self.slept = 0
        """Waits that ended in a sleep."""
        self._clock = clock
        self._yield = yield_

    def next(self, source: Source[T]) -> T:
        """The next item of ``source``: polled for at most the current window, else waited for
        in ``source.recv()`` (whose exceptions pass through). Adapts the window."""
        start = self._clock()
        item = source.try_recv()
        if item is not None:
            return item
        if self.window_s > 0.0:
            end = start + self.window_s
            while self._clock() < end:
                self._yield()
                item = source.try_recv()
                if item is not None:
                    self.polled += 1
                    return item
        got = source.recv()
        self.slept += 1
        waited = self._clock() - start
        if waited <= self.max_s:
            grown = max(GROW_START_US / 1e6, 2.0 * self.window_s)
            self.window_s = min(self.max_s, grown)
        else:
            halved = self.window_s / 2.0
            self.window_s = halved if halved >= GROW_START_US / 1e6 else 0.0
        return got
