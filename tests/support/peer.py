"""A real agent on a MemoryBus and a scripted peer that plays the other end of one of its
channels: it sends what the test says (a performative, a term, or content that does not
decode) and collects what the agent answers."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import msgspec

from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Communicate, Performative, decode, encode
from tests.support.messages import communicate

TIMEOUT_S = 60.0
GARBAGE = b"\xc1 not msgpack"
"""Content no content language decodes (0xc1 is never used in msgpack)."""


class Peer:
    """Plays ``name`` on ``channel`` towards ``agent`` on ``bus``."""

    def __init__(self, bus: MemoryBus, name: str, agent: str, channel: str) -> None:
        self.bus, self.name, self.agent, self.channel = bus, name, agent, channel
        self.got: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        bus.subscribe(keys.fipa_key(channel, agent, name), lambda _k, p: self.got.put(decode(p)))
        self.n = 0

    def send(
        self,
        perf: Performative,
        protocol: str,
        cid: str,
        term: msgspec.Struct | None = None,
        **overrides: Any,
    ) -> Communicate:
        """Send ``perf`` in conversation ``cid`` with ``term`` as content (``overrides``: any
        field, e.g. ``content=GARBAGE, language="L_WM"``); returns it."""
        self.n += 1
        fields: dict[str, Any] = {"reply_with": f"{self.name}-{self.n}", **overrides}
        msg = communicate(perf, self.name, self.agent, protocol, cid, term, **fields)
        self.bus.publish(keys.fipa_key(self.channel, self.name, self.agent), encode(msg))
        return msg

    def garbage(
        self, perf: Performative, protocol: str, cid: str, language: str, **overrides: Any
    ) -> Communicate:
        """Send ``perf`` whose content in ``language`` does not decode."""
        return self.send(
            perf,
            protocol,
            cid,
            content=GARBAGE,
            language=language,
            ontology="O_RoCo",
            encoding="msgpack",
            **overrides,
        )

    def next(
        self, *performatives: Performative, cid: str | None = None, timeout: float = TIMEOUT_S
    ) -> Communicate:
        """The next communicate from the agent (of ``performatives`` and conversation ``cid``
        when given: others are skipped). Raises queue.Empty after ``timeout`` s."""
        while True:
            msg = self.got.get(timeout=timeout)
            if (not performatives or msg.performative in performatives) and cid in (
                None,
                msg.conversation_id,
            ):
                return msg


@contextmanager
def running(*agents: Agent) -> Iterator[None]:
    """``agents`` bound and each running its FSM in a thread of its own; stopped at the end."""
    threads = []
    for a in agents:
        a.engine.bind()
    for a in agents:
        t = threading.Thread(target=a.engine.run, name=a.name, daemon=True)
        t.start()
        threads.append(t)
    try:
        yield
    finally:
        for a in agents:
            a.engine.stop()
        for t in threads:
            t.join(timeout=5)
