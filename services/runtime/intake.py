"""The checks of a received communicate that need nothing but the communicate, the key it came
on and the agent's interface (paper §4 steps 3–4; FIPA SC00061 §2): who sent it, whether the
interface accepts it on that channel, its content language, ontology and content. Pure
functions: each returns the :class:`Refusal` the agent answers with ``not-understood``, or
None. The agent's take-in (services/runtime/admission.py ``admit``) runs them on every
communicate it takes in, before the checks that need its state (the conversation's
conversation-id and protocol state, the bound on open conversations): the sender's, then
those that depend only on the communicate's sender, channel, performative, protocol,
language, ontology and encoding (:func:`screen`, kept per such tuple), then its content's
(:func:`screened`)."""

from __future__ import annotations

from typing import NamedTuple

import msgspec

from services.runtime.protocol_state import expected_ontology
from services.spec.model import MessageKind
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.encoding import DECODE_ERRORS
from shared.fipa_codec.languages import Language, load_all

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
        return SENDER_MISMATCH
    if kind is None or kind.channel != channel:
        return _not_in_interface(msg.performative, msg.protocol, channel)
    return None


SENDER_MISMATCH = Refusal("sender does not match the key it came on", "sender_mismatch")
"""The refusal of a communicate whose sender is not the one its key names."""


def _not_in_interface(performative: Performative, protocol: str | None, channel: str) -> Refusal:
    return Refusal(f"unexpected {performative.value} in protocol {protocol} on {channel}", "not_in_interface")


class Screen(NamedTuple):
    """The checks of a received communicate that depend only on its sender, the channel it came
    on, its performative, protocol, content language, ontology and encoding, and whether it has
    content (:func:`screen`): the ``refusal`` they lead to (None: none), else the ``language``
    its content is decoded in (None: the content is not checked) and the names of the terms it
    may carry (``contents``; empty: any). The same for every communicate of that tuple: an
    agent keeps one per tuple (services/runtime/lookups.py ``Lookups.screen``)."""

    refusal: Refusal | None
    language: Language | None = None
    contents: tuple[str, ...] = ()


def screen(
    channel: str,
    performative: Performative,
    protocol: str | None,
    language: str | None,
    ontology: str | None,
    encoding: str | None,
    has_content: bool,
    kind: MessageKind | None,
) -> Screen:
    """The checks of :func:`interface_refusal` after the sender's, then those of
    :func:`content_of` before decoding, for a communicate of ``performative`` in ``protocol``
    that came on ``channel`` (``kind``: the interface's received kind of its sender,
    performative and protocol, None: none), in content ``language`` with ``ontology`` and
    ``encoding``, with content (``has_content``) or not."""
    if kind is None or kind.channel != channel:
        return Screen(_not_in_interface(performative, protocol, channel))
    if language is None:
        return Screen(_unlabelled(performative, encoding, has_content, kind))
    checked = bool(kind.languages and has_content)
    if checked and language not in kind.languages:
        return Screen(Refusal(f"language {language} not accepted here", "language"))
    if ontology != expected_ontology(language):
        why = f"language {language} needs ontology {expected_ontology(language)}, not {ontology}"
        return Screen(Refusal(why, "ontology"))
    if not checked:
        return Screen(None)
    known = load_all().get(language)
    if known is None:
        return Screen(Refusal(f"unknown content language {language!r}", "content"))
    return Screen(None, known, kind.contents)


def screened(msg: Communicate, checks: Screen) -> tuple[msgspec.Struct | None, Refusal | None]:
    """The decoded content of ``msg`` once its :class:`Screen` ``checks`` passed (None when the
    content is not checked), or the refusal: content that does not decode in its language or
    is a term its kind may not carry."""
    if checks.refusal is not None or checks.language is None:
        return None, checks.refusal
    try:  # the language's decode, without its Python call for content that decodes
        content = checks.language.read(msg.content)
    except DECODE_ERRORS as exc:
        return None, Refusal(str(checks.language.error(exc)), "content")
    if checks.contents and type(content).__name__ not in checks.contents:
        why = (
            f"{msg.performative.value} in {msg.protocol} may carry {', '.join(checks.contents)}, "
            f"not {type(content).__name__}"
        )
        return None, Refusal(why, "content_type")
    return content, None


def content_of(msg: Communicate, kind: MessageKind) -> tuple[msgspec.Struct | None, Refusal | None]:
    """The decoded content of ``msg``, which the interface accepts as ``kind`` (None when it is
    not checked: no content, a kind with no language, or a reason in plain text), or the
    refusal: a language the kind does not accept, an ontology other than the language's
    (:func:`~services.runtime.protocol_state.expected_ontology`), content that does not decode
    in its language or is a term the kind may not carry (:func:`screen`, then :func:`screened`)."""
    checks = screen(
        kind.channel,
        msg.performative,
        msg.protocol,
        msg.language,
        msg.ontology,
        msg.encoding,
        bool(msg.content),
        kind,
    )
    return screened(msg, checks)


def _unlabelled(
    performative: Performative, encoding: str | None, has_content: bool, kind: MessageKind
) -> Refusal | None:
    """A communicate that names no content language: refused when it has content and ``kind``
    has languages, unless the content is a reason in plain UTF-8 text."""
    plain_reason = encoding == "utf-8" and performative in PLAIN_REASONS
    if kind.languages and has_content and not plain_reason:
        return Refusal("language None not accepted here", "language")
    return None
