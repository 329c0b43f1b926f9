"""The checks of a received communicate that need nothing but the communicate, the key it came
on and the agent's interface (paper §4 steps 3–4; FIPA SC00061 §2): who sent it, whether the
interface accepts it on that channel, its content language, ontology and content. Pure
functions: each returns the :class:`Refusal` the agent answers with ``not-understood``, or
None. The agent (services/runtime/agent.py ``Agent._take_communicate``) runs them on every
communicate it takes in, before the checks that need its state (the conversation's
conversation-id and protocol state, the bound on open conversations)."""

from __future__ import annotations

from typing import NamedTuple

import msgspec

from services.runtime.protocol_state import expected_ontology
from services.spec.model import MessageKind
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages import ContentError, decode_content

PLAIN_REASONS = frozenset({Performative.FAILURE, Performative.REFUSE, Performative.NOT_UNDERSTOOD})
"""Performatives whose content may be a reason in plain UTF-8 text, in no content language
(FIPA SC00037: a reason a person can read)."""


class Refusal(NamedTuple):
    """Why a received communicate is answered ``not-understood``: ``reason`` in words (the
    answer's content) and ``counter``, the reason it is counted under (``rejected.<counter>``;
    services/runtime/limits.py ``REJECT_REASONS``)."""

    reason: str
    counter: str


def interface_refusal(
    sender: str, channel: str, msg: Communicate, kind: MessageKind | None
) -> Refusal | None:
    """A communicate ``msg`` that came from ``sender`` on ``channel`` (the parts of its key),
    ``kind`` being the interface's received kind of its sender, performative and protocol
    (None: none): refused when its sender is not the key's, or the interface does not accept
    it on that channel."""
    if msg.sender is None or msg.sender.name != sender:
        return Refusal("sender does not match the key it came on", "sender_mismatch")
    if kind is None or kind.channel != channel:
        why = f"unexpected {msg.performative.value} in protocol {msg.protocol} on {channel}"
        return Refusal(why, "not_in_interface")
    return None


def content_of(msg: Communicate, kind: MessageKind) -> tuple[msgspec.Struct | None, Refusal | None]:
    """The decoded content of ``msg``, which the interface accepts as ``kind`` (None when it is
    not checked: no content, a kind with no language, or a reason in plain text), or the
    refusal: a language the kind does not accept, an ontology other than the language's
    (:func:`~services.runtime.protocol_state.expected_ontology`), content that does not decode
    in its language or is a term the kind may not carry."""
    language = msg.language
    if language is None:
        return None, _unlabelled(msg, kind)
    checked = bool(kind.languages and msg.content)
    if checked and language not in kind.languages:
        return None, Refusal(f"language {language} not accepted here", "language")
    if msg.ontology != expected_ontology(language):
        why = f"language {language} needs ontology {expected_ontology(language)}, not {msg.ontology}"
        return None, Refusal(why, "ontology")
    if not checked:
        return None, None
    try:
        content = decode_content(language, msg.content)
    except ContentError as exc:
        return None, Refusal(str(exc), "content")
    if kind.contents and type(content).__name__ not in kind.contents:
        why = (
            f"{msg.performative.value} in {msg.protocol} may carry {', '.join(kind.contents)}, "
            f"not {type(content).__name__}"
        )
        return None, Refusal(why, "content_type")
    return content, None


def _unlabelled(msg: Communicate, kind: MessageKind) -> Refusal | None:
    """A communicate that names no content language: refused when it has content and ``kind``
    has languages, unless the content is a reason in plain UTF-8 text."""
    plain_reason = msg.encoding == "utf-8" and msg.performative in PLAIN_REASONS
    if kind.languages and msg.content and not plain_reason:
        return Refusal(f"language {msg.language} not accepted here", "language")
    return None
