"""An agent of another FIPA platform, as roco's own tools play one: it sends a ``Sentence`` to
a roco agent through the ACL gateway (C8, fipa-request: docs/gateway.md) and takes the answers
the gateway posts back to it. ``roco scenario`` uses it for a ``say`` step ``from = "gateway"``
(services/scenario/model.py).

Sending: one HTTP MTP post (FIPA SC00084, services/gateway/http_mtp.py) of an XML envelope
(FIPA SC00085, services/gateway/envelope.py) and a ``request`` in the ACL string form (FIPA
SC00070), language ``L_HC``, ontology ``O_RoCo``, protocol ``fipa-request``; the sender's
agent identifier and the envelope's ``from`` name the platform's own HTTP address, where the
gateway posts the answers. Receiving: an HTTP MTP server of its own (services/gateway/server.py)
on ``127.0.0.1:port``; each message it reads (string form) is handed to ``on_answer``.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable

import msgspec

from services.gateway.envelope import Envelope
from services.gateway.http_mtp import MTPMessage, post_message
from services.gateway.server import MTPServer
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.aid import AgentIdentifier
from shared.fipa_codec.languages.l_hc import Sentence
from shared.fipa_codec.string_form import format_datetime, parse, to_bytes

__all__ = ["NAME", "ForeignPlatform"]

NAME = "roco-scenario@127.0.0.1/platform"
"""The foreign agent's name: a FIPA SC00070 word that names no agent of roco."""


class ForeignPlatform:
    """A foreign agent ``name`` whose platform receives at ``http://127.0.0.1:port/acc``
    (:attr:`address`); ``on_answer`` is called (on a reader thread) with each message posted
    to it. :meth:`start` raises OSError when the port cannot be bound."""

    def __init__(self, port: int, on_answer: Callable[[Communicate], None], name: str = NAME) -> None:
        self.name = name
        self.address = f"http://127.0.0.1:{port}/acc"
        self.on_answer = on_answer
        self.counts: dict[str, int] = {}
        """The server's answers by ``http.<status>`` (services/gateway/server.py)."""
        self._server = MTPServer(("127.0.0.1", port), self._deliver, self._count)
        self._numbers = itertools.count(1)

    def start(self) -> None:
        """Serve the platform's address. Raises OSError when it cannot be bound."""
        self._server.start()

    def stop(self) -> None:
        """Stop serving and free the port."""
        self._server.stop()

    def _count(self, name: str) -> None:
        self.counts[name] = self.counts.get(name, 0) + 1

    def _deliver(self, message: MTPMessage, peer: str) -> None:
        """A message the gateway posted: read (string form; StringFormError, a ValueError, is
        answered 406 by the server) and handed over."""
        self.on_answer(parse(message.payload))

    def request(self, gateway: str, to: str, text: str) -> str:
        """Post a ``request`` of ``Sentence(text)`` for agent ``to`` to the gateway's HTTP
        address ``gateway``; its conversation-id (each request a new one). Raises
        services.gateway.http_mtp.MTPError when the gateway does not answer 200,
        aiohttp.ClientError, OSError or TimeoutError when it cannot be reached."""
        conversation = f"{self.name.split('@')[0]}-{next(self._numbers)}"
        me = AgentIdentifier(self.name, (self.address,))
        msg = Communicate(
            performative=Performative.REQUEST,
            sender=me,
            receiver=(AgentIdentifier(to),),
            content=msgspec.json.encode(Sentence(text=text)),
            language="L_HC",
            ontology="O_RoCo",
            protocol="fipa-request",
            conversation_id=conversation,
            reply_with=f"{conversation}-r1",
        )
        envelope = Envelope(
            to=(AgentIdentifier(to),),
            from_=me,
            payload_encoding="UTF-8",
            date=format_datetime(time.time()),
        )
        post_message(gateway, MTPMessage(envelope, to_bytes(msg)))
        return conversation
