"""Sending one communicate: building it, following it in its conversation's protocol state,
encoding it and putting it into the output buffer, in one call (paper §3.2: the output
buffer y; FIPA SC00061 §2), compiled by mypyc with the rest of the agent runtime's hot path
(services/runtime/native.py). The counterpart of services/runtime/admission.py ``admit``.

:class:`Outbox` holds what every communicate an agent sends needs (its name and identifier,
its conversations' protocol states, its duplicate filter, the replies it awaits, its output
buffer and counters) and :meth:`Outbox.send` does, for each one, what ``Engine.send`` promises
(services/runtime/engine.py): the checks against the interface (kept per receiver,
performative, protocol and content type by the agent, ``SendChecks.outgoing``), the
communicate's construction (with its own checks, shared/fipa_codec/message.py), the
conversation's protocol state, stepped (services/runtime/admission.py ``step``), encoding with
its size limit, the reply awaited, the answer remembered for a copy of what it answers, the
output buffer and the ``sent.<performative>`` counter; :meth:`Outbox.dispatch` puts the output
buffer on the transport after each step, in batches per receiver. What the agent does when a
check fails (count, log, raise SpecViolation) stays the agent's (:class:`Host`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import NamedTuple, NoReturn, Protocol

import msgspec

from services.runtime.admission import step
from services.runtime.dedup import Dedup
from services.runtime.keys import FIPA_PREFIX, is_communicate_key
from services.runtime.lookups import Followed
from services.runtime.protocol_state import ProtocolStates
from services.runtime.replies import Pending, PendingReplies
from services.runtime.sources import Sources
from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from shared.fipa_codec.batch import runs
from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES, too_long, write
from shared.fipa_codec.languages import encode_term
from shared.fipa_codec.protocols import REPORT_LANGUAGE, is_terminal_report

SENT_COUNTER = {p: f"sent.{p.value}" for p in Performative}
"""The counter of every communicate sent, by performative (``sent.<performative>``)."""


class Outgoing(NamedTuple):
    """What every communicate an agent sends to one receiver, of one performative in one
    protocol, carrying a term of one type (or none) shares, once the interface allowed it
    (services/runtime/send_checks.py ``SendChecks.outgoing``): its ``key`` and ``receiver``, its content
    ``language`` and ``ontology``, ``followed``, the conversation's state machine and the
    agent's role in it (None: not followed), ``protocol``, its name as a plain ``str``
    (what the communicate carries: one of ``str``'s subclasses, e.g. services/spec/names.py
    ``ProtocolName``, is not a word known to be valid without a call,
    shared/fipa_codec/message.py), and ``streams``: the performative opens a conversation
    of the protocol that many replies answer (services/runtime/send_checks.py ``SendChecks._streams``;
    a reply awaited stays awaited after the first)."""

    key: str
    receiver: tuple[AgentIdentifier, ...]
    language: str | None
    ontology: str | None
    followed: Followed | None
    protocol: str
    streams: bool


class Host(Protocol):
    """What :class:`Outbox` asks of its agent's engine (services/runtime/engine.py ``Engine``)."""

    @property
    def sources(self) -> Sources:
        """The agent's clocks and fresh identifiers (read on every send: it may be replaced)."""
        ...

    def outgoing(
        self, to: str, performative: Performative, protocol: str, content: msgspec.Struct | None
    ) -> Outgoing:
        """The interface's checks of such a communicate (raises SpecViolation), kept."""
        ...

    def conversation_stepped(
        self, peer: str, conversation_id: str, performative: Performative, outcome: str
    ) -> None:
        """A conversation opened anew, or a communicate that crossed another: logged, counted."""
        ...

    def send_violation(self, conversation_id: str | None, text: str) -> NoReturn:
        """Count, log and raise SpecViolation."""
        ...


class Outbox:
    """The sending half of one agent's runtime (see the module): ``host`` the agent,
    ``name`` and ``aid`` its name and identifier, ``states`` its conversations' protocol
    states, ``dedup`` its duplicate filter, ``pending`` the replies it awaits, ``outgoings``
    the interface's answers it keeps per (receiver, performative, protocol, content type),
    ``y`` its output buffer of (key, payload) and ``counters`` its counters (all shared with
    the agent, which changes them in place)."""

    def __init__(
        self,
        host: Host,
        name: str,
        aid: AgentIdentifier,
        states: ProtocolStates,
        dedup: Dedup,
        pending: PendingReplies,
        outgoings: dict[tuple[str, Performative, str, type], Outgoing],
        y: list[tuple[str, bytes]],
        counters: Counter[str],
    ) -> None:
        self.host = host
        self.name = name
        self.aid = aid
        self.states = states
        self.dedup = dedup
        self.pending = pending
        self.outgoings = outgoings
        self.y = y
        self.counters = counters
        self.prefix = f"{name}-"

    def send(
        self,
        to: str,
        performative: Performative,
        content: msgspec.Struct | None,
        protocol: str,
        conversation_id: str | None,
        reply_with: str | None,
        in_reply_to: str | None,
        reply_by_s: float | None,
        expect_reply: bool,
        retry_s: float | None,
    ) -> Communicate:
        """Put a communicate for ``to`` into the output buffer (arguments and errors as
        services/runtime/engine.py ``Engine.send``: SpecViolation through the host when the
        interface or the conversation's protocol state forbids it, ContentError for a term of
        no content language, EncodeError when it is too large, ValueError for a ``retry_s``
        that is not positive). Returns the communicate."""
        if retry_s is not None and not retry_s > 0:
            raise ValueError(f"retry_s must be positive, not {retry_s}")
        host = self.host
        out = self.outgoings.get((to, performative, protocol, type(content)))
        if out is None:
            out = host.outgoing(to, performative, protocol, content)
        body = encode_term(content) if content is not None else b""
        awaits = expect_reply or reply_by_s is not None or retry_s is not None
        sources = host.sources
        if awaits and reply_with is None:
            reply_with = sources.new_id(self.prefix)
        deadline = sources.time() + reply_by_s if reply_by_s is not None else None
        msg = Communicate(
            performative=performative,
            sender=self.aid,
            receiver=out.receiver,
            content=body,
            language=out.language,
            encoding="msgpack" if body else None,
            ontology=out.ontology,
            protocol=out.protocol,
            conversation_id=conversation_id or sources.new_id("c-"),
            reply_with=reply_with,
            in_reply_to=in_reply_to,
            reply_by=deadline,
        )
        cid = msg.conversation_id
        followed = out.followed
        if followed is not None and cid is not None:
            self._follow(to, cid, followed, msg)
        payload = write(msg)  # shared.fipa_codec.encode, without its Python call
        if len(payload) > MAX_COMMUNICATE_BYTES:
            raise too_long(msg, len(payload))
        if awaits and reply_with is not None:
            self._await(msg, to, out, payload, retry_s, reply_with, cid, sources)
        if in_reply_to is not None:  # a copy of what it answers gets it again
            self.dedup.answered(to, in_reply_to, out.key, payload)
        self.y.append((out.key, payload))
        self.counters[SENT_COUNTER[performative]] += 1
        return msg

    def dispatch(self, publish: Callable[[str, bytes], None], batched: bool) -> None:
        """Put the output buffer with ``publish`` (the transport's: key, payload), in order,
        and empty it; ``batched``: communicates in a row to one receiver go in one put, a
        batch (shared/fipa_codec/batch.py ``runs``). Counts the communicates put
        (``published``) and keeps the protocol states of what was sent. (services/runtime/
        engine.py ``Engine.dispatch``.)"""
        y = self.y
        if len(y) == 1:  # the usual step: one communicate, no batch to look for
            key, payload = y[0]
            publish(key, payload)
            if key.startswith(FIPA_PREFIX):  # keys.is_communicate_key, without its Python call
                self.counters["published"] += 1
        elif y:
            published = 0
            for key, payload, count in runs(y, is_communicate_key if batched else _alone):
                publish(key, payload)
                if is_communicate_key(key):
                    published += count
            if published:
                self.counters["published"] += published
        y.clear()
        self.states.commit()

    def _follow(self, to: str, cid: str, followed: Followed, msg: Communicate) -> None:
        """Step the protocol state of conversation ``cid`` with ``to`` by ``msg``, about to be
        sent; the host raises SpecViolation when the state does not allow it."""
        performative = msg.performative
        # is_terminal_report asks the language first: only an L_SW inform may be one
        terminal = msg.language == REPORT_LANGUAGE and is_terminal_report(msg)
        outcome, why = step(self.states, self.name, to, cid, followed, performative, True, terminal, msg)
        if outcome != "step":
            self.host.conversation_stepped(to, cid, performative, outcome)
        if why is not None:
            self.host.send_violation(
                cid, f"{self.name}: may not send {performative.value} to {to} in conversation {cid}: {why}"
            )

    def _await(
        self,
        msg: Communicate,
        to: str,
        out: Outgoing,
        payload: bytes,
        retry_s: float | None,
        reply_with: str,
        cid: str | None,
        sources: Sources,
    ) -> None:
        """Await replies to ``msg`` (its reply-with ``reply_with``), sent to ``to`` on
        ``out.key`` as ``payload``: its reply-by deadline, and retransmission every ``retry_s``
        (services/runtime/replies.py)."""
        protocol = msg.protocol
        assert protocol is not None
        retries = retry_s is not None
        self.pending.expect(
            Pending(
                reply_with,
                to,
                protocol,
                cid,
                msg.reply_by,
                streaming=out.streams,
                retry_s=retry_s,
                key=out.key if retries else "",
                payload=payload if retries else b"",
                next_retry=sources.time() + retry_s if retry_s is not None else None,
            )
        )


def _alone(key: str) -> bool:
    """No key's communicates are batched (``Engine.batch_puts`` False)."""
    return False
