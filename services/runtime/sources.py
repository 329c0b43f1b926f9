"""Where an agent reads the time and draws what must differ from run to run: its clocks, its
random bytes, the fresh identifiers of its conversations and replies (FIPA SC00061
conversation-id, reply-with).

The runtime and the agents read them from ``Agent.sources`` only, never from ``time`` or
``os`` directly, so that whoever builds an agent can give it other sources: ``roco replay``
(services/replay) gives a replayed agent a clock set from the traffic record's times and
seeded random bytes, which makes it deterministic. A transport offers such sources as its
optional ``sources`` attribute (services/runtime/transport.py ``Transport``); without one the
agent gets :data:`SYSTEM`, the system's own functions, called with no layer in between.
"""

from __future__ import annotations

import os
import time as _time
from typing import Protocol

from shared.fipa_codec.message import new_id


class Sources(Protocol):
    """An agent's clocks and randomness."""

    def time(self) -> float:
        """The wall clock: POSIX s (as ``time.time``)."""
        ...

    def monotonic(self) -> float:
        """A clock that never goes back, for durations and deadlines: s from any origin (as
        ``time.monotonic``)."""
        ...

    def random_bytes(self, n: int) -> bytes:
        """``n`` random bytes (as ``os.urandom``)."""
        ...

    def new_id(self, prefix: str = "") -> str:
        """A fresh identifier: ``prefix`` + 12 hex digits (as shared/fipa_codec/message.py
        :func:`~shared.fipa_codec.message.new_id`)."""
        ...


class SystemSources:
    """The system's clocks and ``os.urandom``: the functions themselves, so that reading them
    through an agent costs one attribute lookup more than calling them."""

    time = staticmethod(_time.time)
    monotonic = staticmethod(_time.monotonic)
    random_bytes = staticmethod(os.urandom)
    new_id = staticmethod(new_id)


SYSTEM: Sources = SystemSources()
"""The sources of every agent whose transport offers none."""
