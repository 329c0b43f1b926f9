"""What an agent's runtime answers to a communicate it did not take in (paper §4 steps 3–4;
FIPA SC00037 §3.12 not-understood, §3.17 refuse): a bad key is counted; an undecodable payload,
a refused term, a missing conversation-id or a communicate its conversation's protocol state
does not allow is answered ``not-understood``; a byte-identical copy gets the answers to its
original again; one conversation too many is refused. Warnings about rejected input are
logged at most :data:`LOG_BURST` per :data:`LOG_WINDOW_S`. The verdicts come from
services/runtime/admission.py ``admit``; the counters' names are in services/runtime/limits.py
``REJECT_REASONS``.
"""

from __future__ import annotations

import logging
from collections import Counter
from typing import Protocol

import msgspec

from services.runtime.admission import (
    BAD_KEY,
    COPY,
    NO_CONVERSATION_ID,
    RECEIVED_COUNTER,
    REFUSED,
    TOO_MANY,
    UNDECODABLE,
    Admission,
)
from services.runtime.dedup import Dedup
from services.runtime.emission import SENT_COUNTER
from services.runtime.intake import Refusal
from services.runtime.lookups import Lookups
from services.runtime.protocol_state import ProtocolStates
from services.runtime.roles import Roles
from services.runtime.send_checks import SendChecks
from services.runtime.sources import Sources
from services.runtime.values import Received, SpecViolation
from services.spec.model import Interface, SystemSpec
from shared.fipa_codec import AgentIdentifier, Communicate, DecodeError, Performative, encode
from shared.fipa_codec.protocols import is_terminal_report

LOG_BURST = 50
"""Warnings about rejected input logged per :data:`LOG_WINDOW_S` before the rest are only
counted (and their number logged once the window ends)."""
LOG_WINDOW_S = 10.0


class Host(Protocol):
    """What :class:`Rejections` asks of its engine (services/runtime/engine.py ``Engine``)."""

    name: str
    aid: AgentIdentifier
    spec: SystemSpec
    interface: Interface
    lookups: Lookups
    counters: Counter[str]
    log: logging.Logger
    sources: Sources
    protocol_states: ProtocolStates
    dedup: Dedup
    roles: Roles
    checks: SendChecks
    max_open_per_peer: int
    y: list[tuple[str, bytes]]


class Rejections:
    """The answers of one agent's runtime (its ``host``) to what it did not take in."""

    def __init__(self, host: Host) -> None:
        self.host = host
        self._log_window = (0.0, 0)  # (window start, monotonic s; warnings logged in it)
        self._log_suppressed = 0

    def not_taken(self, found: Admission) -> None:
        """A communicate ``admit`` did not take (``found.verdict``): counted, and answered
        (not-understood, a refuse, or the answers to its original sent again) or dropped."""
        verdict, sender, channel, msg = found.verdict, found.sender, found.channel, found.msg
        counters = self.host.counters
        if verdict == BAD_KEY:
            counters["bad_key"] += 1
            counters["rejected.bad_key"] += 1
            return
        if verdict == UNDECODABLE:
            assert found.error is not None
            self._undecodable(sender, channel, found.error, found.copy)
            return
        assert msg is not None
        if verdict == COPY:
            self._copy(sender, msg)
            return
        counters[RECEIVED_COUNTER[msg.performative]] += 1
        if verdict == REFUSED:
            assert found.refusal is not None
            self._refuse(sender, channel, msg, found.refusal)
        elif verdict == NO_CONVERSATION_ID:
            needs = f"{msg.performative.value} in protocol {msg.protocol} needs a conversation-id"
            self.not_understood(sender, channel, needs, msg, "no_conversation_id")
        elif verdict == TOO_MANY:
            self._refuse_new_conversation(sender, channel, msg, found.content)
        else:
            self._out_of_state(sender, channel, msg, found.why)

    def taking_raised(self, key: str) -> None:
        """Taking in the communicate on ``key`` raised (the exception is being handled):
        counted (``rejected.internal``), its traceback logged; no input may stop the agent."""
        self.host.counters["rejected.internal"] += 1
        self.host.log.exception("taking in a communicate on %s raised", key)

    def not_understood(
        self, sender: str, channel: str, why: str, about: Communicate | None, reason: str = "unhandled"
    ) -> None:
        """Answer ``sender`` with not-understood whose content is ``why`` as UTF-8 text,
        counted under ``rejected.<reason>``. It ends ``about``'s conversation (FIPA SC00037
        §3.12): the runtime no longer follows its protocol state, and a conversation this agent
        opened ends through its handler (``Roles.not_understood_sent``). A not-understood is
        never answered with one (no loops)."""
        host = self.host
        host.counters["rejected"] += 1
        host.counters[f"rejected.{reason}"] += 1
        cid = about.conversation_id if about is not None else None
        self.warn("not-understood to %s (conversation %s): %s", sender, cid, why)
        if about is not None and about.performative is Performative.NOT_UNDERSTOOD:
            return  # never answer a not-understood with one: no loops
        if about is not None and cid is not None and host.protocol_states.get(sender, cid) is not None:
            host.checks.follow(sender, cid, about.protocol, Performative.NOT_UNDERSTOOD, True, None)
        msg = Communicate(
            performative=Performative.NOT_UNDERSTOOD,
            sender=host.aid,
            receiver=(host.lookups.aid(sender),),
            content=why.encode(),
            encoding="utf-8",
            protocol=about.protocol if about else None,
            conversation_id=about.conversation_id if about else None,
            in_reply_to=about.reply_with if about else None,
        )
        self._out(sender, msg.in_reply_to, host.lookups.key(channel, sender), encode(msg))
        if about is not None and cid is not None:
            host.roles.not_understood_sent(sender, channel, about, why)

    def fail(self, to: Received, performative: Performative, reason: str) -> None:
        """Answer ``to`` with ``failure`` or ``refuse`` whose content is ``reason`` as UTF-8
        text (FIPA SC00037: the reason a person or agent can read). Raises SpecViolation when
        the interface does not allow that performative in ``to``'s protocol."""
        host = self.host
        protocol = to.msg.protocol or ""
        host.checks.check(to.sender, performative.value, protocol, None)
        channel = host.lookups.channel(to.sender)
        assert channel is not None  # check found a kind, so a channel exists
        msg = Communicate(
            performative=performative,
            sender=host.aid,
            receiver=(host.lookups.aid(to.sender),),
            content=reason.encode(),
            encoding="utf-8",
            protocol=protocol,
            conversation_id=to.msg.conversation_id,
            in_reply_to=to.msg.reply_with,
        )
        host.checks.follow_send(to.sender, msg, host.lookups.followed(to.sender, protocol))
        self._out(to.sender, msg.in_reply_to, host.lookups.key(channel.name, to.sender), encode(msg))
        host.counters[SENT_COUNTER[performative]] += 1

    def warn(self, fmt: str, *args: object) -> None:
        """Log a warning about rejected input, at most :data:`LOG_BURST` per
        :data:`LOG_WINDOW_S`; the number left out is logged when the next window begins."""
        log = self.host.log
        now = self.host.sources.monotonic()
        start, logged = self._log_window
        if now - start >= LOG_WINDOW_S:
            if self._log_suppressed:
                log.warning(
                    "%d more warnings about rejected input in %.0f s not logged",
                    self._log_suppressed,
                    LOG_WINDOW_S,
                )
            start, logged, self._log_suppressed = now, 0, 0
        if logged < LOG_BURST:
            log.warning(fmt, *args)
            logged += 1
        else:
            self._log_suppressed += 1
        self._log_window = (start, logged)

    def _out(self, to: str, in_reply_to: str | None, key: str, payload: bytes) -> None:
        """Put an encoded answer into the output buffer; remember it as an answer to ``to``'s
        ``in_reply_to`` so that a copy of that communicate gets it again."""
        if in_reply_to is not None:
            self.host.dedup.answered(to, in_reply_to, key, payload)
        self.host.y.append((key, payload))

    def _undecodable(self, sender: str, channel: str, exc: DecodeError, copy: bool) -> None:
        """A payload from ``sender`` that does not decode (``exc``): a copy of one seen already
        is counted as a duplicate; otherwise it is answered not-understood (malformed, or
        oversized)."""
        if copy:
            self.host.counters["duplicates"] += 1
            return
        bad = "oversized" if exc.oversized else "malformed"
        self.not_understood(sender, channel, f"{bad} communicate: {exc.reason}", None, bad)

    def _copy(self, sender: str, msg: Communicate) -> None:
        """A byte-identical copy of ``msg`` came again from ``sender``: dropped, and the
        answers sent to it published again."""
        host = self.host
        host.counters["duplicates"] += 1
        again = host.dedup.answers(sender, msg.reply_with)
        host.log.info(
            "copy of %s from %s (conversation %s) dropped; %d answer(s) sent again",
            msg.performative.value,
            sender,
            msg.conversation_id,
            len(again),
        )
        host.counters["replayed"] += len(again)
        host.y.extend(again)

    def _refuse(self, sender: str, channel: str, msg: Communicate, refusal: Refusal) -> None:
        """Answer ``msg`` not-understood for ``refusal`` (a term its kind may not carry is
        counted as a ``content_violations`` too)."""
        if refusal.counter == "content_type":
            self.host.counters["content_violations"] += 1
        self.not_understood(sender, channel, refusal.reason, msg, refusal.counter)

    def _out_of_state(self, sender: str, channel: str, msg: Communicate, why: str) -> None:
        """The conversation's protocol state does not allow ``msg`` (``why``): a late reply to
        an earlier opening of the conversation is dropped; anything else is a protocol
        violation, answered not-understood."""
        host = self.host
        if host.roles.answers_earlier_opening(sender, msg):
            # not-understood would end (FIPA SC00037 §3.12) the conversation opened anew, and
            # with it what the peer sends in it next (a_km restarted, subscribed again, and
            # lost a_ta's fresh observation after answering a stale update not-understood)
            host.counters["late_replies"] += 1
            host.log.info(
                "%s from %s in conversation %s dropped: it answers an earlier opening (%s)",
                msg.performative.value,
                sender,
                msg.conversation_id,
                msg.in_reply_to,
            )
            return
        host.counters["protocol_violations"] += 1
        self.warn("protocol violation by %s in conversation %s: %s", sender, msg.conversation_id, why)
        self.not_understood(sender, channel, why, msg, "protocol_state")

    def _refuse_new_conversation(
        self, sender: str, channel: str, msg: Communicate, content: msgspec.Struct | None
    ) -> None:
        """``sender`` opens one more conversation while it has ``max_open_per_peer`` open with
        this agent: follow the opening communicate, then ``refuse`` it (FIPA SC00037 §3.17;
        the reason as UTF-8 text), or answer ``not-understood`` where the protocol has no
        refuse for this agent. A communicate that does not open a conversation is a protocol
        violation as usual."""
        host = self.host
        why = host.checks.follow(
            sender, msg.conversation_id, msg.protocol, msg.performative, False, is_terminal_report(msg), msg
        )
        if why is not None:
            host.counters["protocol_violations"] += 1
            self.not_understood(sender, channel, why, msg, "protocol_state")
            return
        text = (
            f"{sender} has {host.protocol_states.open_with(sender) - 1} conversations open with "
            f"{host.name}; at most {host.max_open_per_peer}"
        )
        protocol = msg.protocol or ""
        may_refuse = any(
            k.receiver == host.spec.role_of(sender)
            and k.performative == Performative.REFUSE.value
            and k.protocol == protocol
            for k in host.interface.sends
        )
        if may_refuse:
            try:
                self.fail(Received.of(msg, content, channel), Performative.REFUSE, text)
            except SpecViolation:  # the protocol's state machine has no refuse here
                may_refuse = False
            else:
                host.counters["rejected.too_many_conversations"] += 1
                self.warn("refused conversation %s: %s", msg.conversation_id, text)
        if not may_refuse:
            self.not_understood(sender, channel, text, msg, "too_many_conversations")
