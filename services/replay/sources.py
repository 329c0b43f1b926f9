"""The clock and randomness a replayed agent runs on (services/runtime/sources.py ``Sources``)."""

from __future__ import annotations

import random


class ReplaySources:
    """A clock that stands still while the agent computes and moves only when the replay's
    driver sets it (:meth:`set`: the time the next input reached the agent, or the time the agent
    waits for), and random bytes from a generator seeded with ``seed``. Both clocks read the
    same value, in POSIX s: ``start`` at first."""

    def __init__(self, start: float, seed: int = 0) -> None:
        self.now = start
        self._random = random.Random(seed)

    def set(self, t: float) -> None:
        """Move the clock to ``t`` (POSIX s); never back."""
        self.now = max(self.now, t)

    def time(self) -> float:
        return self.now

    def monotonic(self) -> float:
        return self.now

    def random_bytes(self, n: int) -> bytes:
        return self._random.randbytes(n)

    def new_id(self, prefix: str = "") -> str:
        return f"{prefix}{self.random_bytes(6).hex()}"
