"""The interface's checks of what an agent sends (paper §4 step 4; FIPA SC00061 §2): the
channel to the receiver, the performative, protocol, content language and term its interface
allows, and the conversation's protocol state (services/runtime/admission.py ``step``);
a violation is counted, logged and raised as SpecViolation. What one (receiver,
performative, protocol, content type) shares is found once and kept (:class:`Outgoing`,
services/runtime/emission.py), so that a send checks the interface once per route.
"""

from __future__ import annotations

import logging
from collections import Counter
from typing import NoReturn

import msgspec

from services.runtime.admission import step
from services.runtime.emission import Outgoing
from services.runtime.lookups import Followed, Lookups
from services.runtime.protocol_state import ProtocolStates
from services.runtime.values import SpecViolation
from services.spec.model import SystemSpec
from services.spec.protocol_defs import machine_of, streams
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages import language_of
from shared.fipa_codec.protocols import INITIATOR, is_terminal_report

ROUTES_KEPT = 1024
"""Routes (receiver, performative, protocol, content type) whose :class:`Outgoing` is kept."""


class SendChecks:
    """One agent's checks of what it sends: ``name`` and ``spec`` the agent's and its system's,
    ``lookups`` the specification's kept answers (services/runtime/lookups.py), ``states`` its
    conversations' protocol states, ``counters`` and ``log`` its own (shared, changed in
    place)."""

    def __init__(
        self,
        name: str,
        spec: SystemSpec,
        lookups: Lookups,
        states: ProtocolStates,
        counters: Counter[str],
        log: logging.Logger,
    ) -> None:
        self.name = name
        self.spec = spec
        self.lookups = lookups
        self.states = states
        self.counters = counters
        self.log = log
        self.outgoings: dict[tuple[str, Performative, str, type], Outgoing] = {}
        """:meth:`outgoing` per (receiver, performative, protocol, content type); read by
        services/runtime/emission.py ``Outbox.send`` before it asks."""
        self._streaming: dict[tuple[str, Performative], bool] = {}

    def outgoing(
        self, to: str, performative: Performative, protocol: str, content: msgspec.Struct | None
    ) -> Outgoing:
        """What every communicate to ``to`` of ``performative`` in ``protocol`` carrying a term
        of ``content``'s type shares (:class:`Outgoing`), checked against the interface the
        first time and kept (at most :data:`ROUTES_KEPT`); raises SpecViolation (no channel,
        or the interface forbids it; nothing kept) or ContentError (a term of no content
        language)."""
        route = (to, performative, protocol, type(content))
        found = self.outgoings.get(route)
        if found is None:
            found = self._route(to, performative, protocol, content)
            if len(self.outgoings) < ROUTES_KEPT:
                self.outgoings[route] = found
        return found

    def _route(
        self, to: str, performative: Performative, protocol: str, content: msgspec.Struct | None
    ) -> Outgoing:
        """:meth:`outgoing` found anew."""
        channel = self.lookups.channel(to)
        if channel is None:
            raise SpecViolation(f"{self.name}: no channel to {to}")
        language = language_of(content) if content is not None else None
        self.check(
            to,
            performative.value,
            protocol,
            language.name if language is not None else None,
            type(content).__name__ if content is not None else None,
        )
        return Outgoing(
            self.lookups.key(channel.name, to),
            (self.lookups.aid(to),),
            language.name if language is not None else None,
            language.ontology if language is not None else None,
            self.lookups.followed(to, protocol),
            str(protocol),  # a plain str: a subclass's (ProtocolName) is checked by a call per send
            self._streams(protocol, performative),
        )

    def _streams(self, protocol: str, performative: Performative) -> bool:
        """``performative`` opens a conversation of ``protocol`` that streams: many replies
        answer it (fipa-subscribe's informs, coordinate's reports; from the state machine).
        Asked once per pair (raises SpecError, keeping nothing, for a protocol without a
        state machine)."""
        found = self._streaming.get((protocol, performative))
        if found is None:
            found = False
            if protocol in self.spec.protocols:
                machine = machine_of(self.spec, protocol)
                opens = machine.next_state(machine.initial, INITIATOR, performative) is not None
                found = streams(machine) and opens
            self._streaming[(protocol, performative)] = found
        return found

    def check(
        self, to: str, performative: str, protocol: str, language: str | None, term: str | None = None
    ) -> None:
        """Raise SpecViolation (:meth:`violation`) unless the interface lets the agent send
        ``performative`` to ``to`` in ``protocol``, in content ``language`` carrying ``term``
        (a type's name; None: not checked)."""
        kind = self.lookups.sends(to, performative, protocol)
        if kind is None:
            self.violation(None, f"{self.name}: may not send {performative} to {to} in {protocol}")
        if language is not None and kind.languages and language not in kind.languages:
            self.violation(
                None,
                f"{self.name}: {performative} to {to} in {protocol} must use "
                f"{'/'.join(kind.languages)}, not {language}",
            )
        if term is not None and kind.contents and term not in kind.contents:
            self.violation(
                None,
                f"{self.name}: {performative} to {to} in {protocol} may carry "
                f"{', '.join(kind.contents)}, not {term}",
            )

    def violation(self, conversation_id: str | None, text: str) -> NoReturn:
        """Count (``send_violations``), log and raise SpecViolation(``text``): a violation the
        agent's own code is about to commit."""
        self.counters["send_violations"] += 1
        self.log.warning("refused to send (conversation %s): %s", conversation_id, text)
        raise SpecViolation(text)

    def follow_send(self, to: str, msg: Communicate, followed: Followed | None) -> None:
        """Follow ``msg``, about to be sent to ``to``, in its conversation's protocol state
        (``followed``: its state machine and the agent's role, ``Lookups.followed``; None:
        not followed); raises SpecViolation when the state does not allow it."""
        cid = msg.conversation_id
        if followed is None or cid is None:
            return
        why = self.step(to, cid, followed, msg.performative, True, is_terminal_report(msg), msg)
        if why is not None:
            said = f"{self.name}: may not send {msg.performative.value} to {to} in conversation {cid}"
            self.violation(cid, f"{said}: {why}")

    def follow(
        self,
        peer: str,
        conversation_id: str | None,
        protocol: str | None,
        performative: Performative,
        sent: bool,
        terminal: bool | None,
        msg: Communicate | None = None,
    ) -> str | None:
        """Advance the protocol state of conversation ``conversation_id`` with ``peer`` by one
        communicate (``sent`` by this agent, else received; ``msg`` the communicate, whose
        reply-with and in-reply-to tell what it answers). Returns None when the state allows
        it (or the conversation is not followed: no conversation-id, a protocol without a state
        machine), else the reason."""
        if conversation_id is None or protocol is None:
            return None
        followed = self.lookups.followed(peer, protocol)
        if followed is None:
            return None
        return self.step(peer, conversation_id, followed, performative, sent, terminal, msg)

    def step(
        self,
        peer: str,
        conversation_id: str,
        followed: Followed,
        performative: Performative,
        sent: bool,
        terminal: bool | None,
        msg: Communicate | None = None,
    ) -> str | None:
        """:meth:`follow` in a followed conversation (``followed``: its state machine and the
        agent's role; services/runtime/admission.py ``step``)."""
        outcome, why = step(
            self.states, self.name, peer, conversation_id, followed, performative, sent, terminal, msg
        )
        if outcome != "step":
            self.stepped(outcome)
        return why

    def stepped(self, outcome: str) -> None:
        """Count a communicate that crossed another on the wire (``crossings``)."""
        if outcome == "crossing":
            self.counters["crossings"] += 1
