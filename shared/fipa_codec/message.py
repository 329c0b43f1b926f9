"""The communicate (paper eq. 3) as the FIPA ACL message of FIPA SC00061.

All 13 message parameters of SC00061 §2 are fields of :class:`Communicate`; user-defined
parameters (SC00061 §2.1: names starting with ``X-``) travel in ``user_params``.
Times (``reply_by``) are POSIX seconds (UTC), as floats.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import msgspec

from shared.fipa_codec.acts import Performative
from shared.fipa_codec.aid import AgentIdentifier
from shared.fipa_codec.names import KNOWN_WORDS, check_word


class Communicate(msgspec.Struct, frozen=True, omit_defaults=True, kw_only=True, rename="kebab", gc=False):
    """A FIPA ACL message M = ⟨V, Z, L, O, I, t_b, m_w, m_t, m_c⟩ (paper eq. 3) plus addressing.

    Fields (FIPA SC00061 §2, wire names in kebab case):
      performative: the communicative act V (one of the 22 of SC00037).
      sender, receiver, reply_to: agent identifiers; ``receiver`` holds one or more.
      content: Z, bytes in the content language ``language`` under ``encoding``
        (roco's languages use ``encoding="msgpack"``; see ``shared.fipa_codec.languages``).
      language, encoding, ontology: L, the content encoding, O.
      protocol: I, the interaction protocol name (``fipa-request``, ``coordinate``…); a FIPA
        SC00070 word (checked on construction and decoding: ValueError).
      conversation_id, reply_with, in_reply_to: m_c, m_w, m_t.
      reply_by: t_b, POSIX time in seconds by which a reply is expected.
      user_params: ``X-`` parameters; keys must start with ``X-``.
    Raises ValueError on construction when a user parameter lacks ``X-`` or ``protocol`` is
    not an SC00070 word (so every communicate that can be built can be written in the string
    form; decoded from the wire, msgspec reports it as a ValidationError). Only
    ``performative`` is mandatory (SC00061 §2); an empty ``receiver`` is accepted.
    The FIPA string form (SC00070) is in ``shared.fipa_codec.string_form``. Not tracked by
    the garbage collector (``gc=False``: it holds nothing that could refer back to it), so
    that building and decoding communicates sets off no collections.
    """

    performative: Performative
    sender: AgentIdentifier | None = None
    receiver: tuple[AgentIdentifier, ...] = ()
    reply_to: tuple[AgentIdentifier, ...] = ()
    content: bytes = b""
    language: str | None = None
    encoding: str | None = None
    ontology: str | None = None
    protocol: str | None = None
    conversation_id: str | None = None
    reply_with: str | None = None
    in_reply_to: str | None = None
    reply_by: float | None = None
    user_params: dict[str, str] = {}

    def __post_init__(self) -> None:
        protocol = self.protocol
        if protocol is not None and (type(protocol) is not str or protocol not in KNOWN_WORDS):
            check_word(protocol, ":protocol")
        if self.user_params:
            for key in self.user_params:
                if not key.startswith(("X-", "x-")):
                    raise ValueError(f"user-defined parameter {key!r} must start with 'X-'")

    def reply(
        self,
        performative: Performative,
        sender: AgentIdentifier,
        *,
        content: bytes = b"",
        language: str | None = None,
        ontology: str | None = None,
        reply_with: str | None = None,
        reply_by: float | None = None,
    ) -> Communicate:
        """A reply in the same conversation (SC00061 §2.4): receiver = reply-to or sender,
        in-reply-to = this reply-with; protocol, conversation-id, ontology carried over.

        Raises ValueError when this communicate has no sender and no reply-to.
        """
        targets = self.reply_to or ((self.sender,) if self.sender is not None else ())
        if not targets:
            raise ValueError("cannot reply to a communicate without sender or reply-to")
        return Communicate(
            performative=performative,
            sender=sender,
            receiver=targets,
            content=content,
            language=language if language is not None else (self.language if content else None),
            encoding="msgpack" if content else None,
            ontology=ontology if ontology is not None else self.ontology,
            protocol=self.protocol,
            conversation_id=self.conversation_id,
            in_reply_to=self.reply_with,
            reply_with=reply_with,
            reply_by=reply_by,
        )


_IDS_PER_READ = 256
"""Identifiers :func:`new_id` draws from one ``os.urandom`` read."""
_ids: Iterator[str] = iter(())


def _fresh_ids() -> None:
    """Forget the identifiers drawn but not handed out (a forked child must not reuse its
    parent's)."""
    global _ids
    _ids = iter(())


os.register_at_fork(after_in_child=_fresh_ids)


def new_id(prefix: str = "") -> str:
    """A fresh identifier for conversation-id or reply-with: ``prefix`` + 12 hex digits (48
    random bits from ``os.urandom``, read :data:`_IDS_PER_READ` at a time: ≈ 0.15 µs, where
    one read per identifier took ≈ 0.5 µs and ``uuid.uuid4`` ≈ 4 µs; each is handed out once,
    from any thread: ``next`` on a list's iterator is one step under the GIL)."""
    global _ids
    try:
        return prefix + next(_ids)
    except StopIteration:
        drawn = os.urandom(6 * _IDS_PER_READ).hex()
        _ids = iter([drawn[i : i + 12] for i in range(0, len(drawn), 12)])
        return prefix + next(_ids)
