"""Building communicates by hand in tests: a performative between two agents, in a protocol
and conversation, with a language term as content (language and ontology taken from it)."""

from __future__ import annotations

from typing import Any

import msgspec

from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.languages import encode_content, language_of


def communicate(
    perf: Performative,
    sender: str,
    receiver: str,
    protocol: str | None,
    cid: str | None,
    term: msgspec.Struct | None = None,
    **overrides: Any,
) -> Communicate:
    """The communicate, then ``overrides`` of any field (e.g. ``reply_with``)."""
    language, body = encode_content(term) if term is not None else (None, b"")
    fields: dict[str, Any] = dict(
        performative=perf,
        sender=AgentIdentifier(sender),
        receiver=(AgentIdentifier(receiver),),
        content=body,
        language=language,
        encoding="msgpack" if body else None,
        ontology=language_of(term).ontology if term is not None else None,
        protocol=protocol,
        conversation_id=cid,
    )
    fields.update(overrides)
    return Communicate(**fields)
