"""Taking in one received communicate: every check of it, from its key to its conversation's
protocol state, in one call (paper §4 steps 3–4; FIPA SC00061 §2), compiled by mypyc with the
rest of the agent runtime's hot path (services/runtime/native.py).

:func:`admit` runs, in this order, on every communicate an agent takes in: the key it came
on (``Lookups.parse``), the duplicate filter (``Dedup.seen``), decoding with its agent
names' validation (``shared.fipa_codec.decode``), the sender's binding to the key, the
interface's checks kept per sender, channel, performative, protocol, language, ontology and
encoding, its content (services/runtime/intake.py ``screened``), then its conversation: a
conversation-id where its protocol is followed, the bound on open conversations per peer,
and its protocol state, stepped (:func:`step`). It decides and changes only the protocol
state and the duplicate filter; what the agent does about the outcome (answer
not-understood, count, log, put the communicate into its input buffer) is the agent's
(services/runtime/engine.py ``Engine.not_taken``). :meth:`Gate.take_all` takes a step's inputs in,
in one call.
"""

from __future__ import annotations

from collections import Counter, deque
from collections.abc import Callable
from typing import Any, Final, Protocol

import msgspec

from services.runtime.dedup import Dedup
from services.runtime.intake import SENDER_MISMATCH, Refusal, screened
from services.runtime.lookups import Followed, Lookups
from services.runtime.protocol_state import ConversationError, Outcome, ProtocolStates
from services.runtime.replies import PendingReplies
from shared.fipa_codec import Communicate, DecodeError, Performative, decode
from shared.fipa_codec.encoding import DECODE_ERRORS, MAX_COMMUNICATE_BYTES, decode_error, read
from shared.fipa_codec.protocols import (
    INITIATOR,
    PARTICIPANT,
    REPORT_LANGUAGE,
    ProtocolViolation,
    Role,
    is_terminal_report,
)

TAKEN: Final = 0
"""Every check passed: the communicate goes into the agent's input buffer."""
BAD_KEY: Final = 1
"""The key is no communicate key: counted and dropped."""
UNDECODABLE: Final = 2
"""The payload does not decode (``error``); ``copy`` when the same bytes came before."""
COPY: Final = 3
"""Byte-identical to a communicate taken in before: dropped, its answers sent again."""
REFUSED: Final = 4
"""The sender's binding, the interface or the content refused it (``refusal``)."""
NO_CONVERSATION_ID: Final = 5
"""Its protocol is followed and it has no conversation-id."""
TOO_MANY: Final = 6
"""It opens one more conversation while its sender has the most open."""
OUT_OF_STATE: Final = 7
"""Its conversation's protocol state does not allow it (``why``)."""
RECEIVED_COUNTER = {p: f"received.{p.value}" for p in Performative}
"""The counter of every communicate received, by performative (``received.<performative>``)."""


class Admission:
    """What :func:`admit` found: ``verdict`` (:data:`TAKEN`, or why not), the ``channel`` and
    ``sender`` of its key, the decoded communicate ``msg`` and ``content`` (None: not
    decoded, or not checked), and by verdict: ``refusal`` (:data:`REFUSED`), ``why``
    (:data:`OUT_OF_STATE`), ``error`` and ``copy`` (:data:`UNDECODABLE`), ``outcome`` (what
    :data:`TAKEN` did to its conversation's protocol state, "" when not followed)."""

    def __init__(
        self,
        verdict: int,
        channel: str = "",
        sender: str = "",
        msg: Communicate | None = None,
        content: msgspec.Struct | None = None,
    ) -> None:
        self.verdict = verdict
        self.channel = channel
        self.sender = sender
        self.msg = msg
        self.content = content
        self.refusal: Refusal | None = None
        self.why = ""
        self.error: DecodeError | None = None
        self.copy = False
        self.outcome = ""


class Host(Protocol):
    """What :class:`Gate` asks of its agent's engine (services/runtime/engine.py ``Engine``)."""

    def conversation_stepped(
        self, peer: str, conversation_id: str, performative: Performative, outcome: str
    ) -> None:
        """A conversation opened anew, or a communicate that crossed another: logged, counted."""
        ...

    def take_event(self, key: str, payload: Any) -> None:
        """An input of the runtime's own (one of :class:`Gate`'s ``events``): taken in."""
        ...

    def not_taken(self, found: Admission) -> None:
        """A communicate :func:`admit` did not take: counted, and answered or dropped."""
        ...

    def take_raised(self, key: str) -> None:
        """Taking in the communicate that came on ``key`` raised (the exception is being
        handled): counted and logged; the agent goes on."""
        ...


class Gate:
    """The receiving half of one agent's runtime: :func:`admit` and, for a communicate it
    takes, what follows in the same call: the ``received.<performative>`` counter, a
    conversation opened anew or a crossing told to the ``host``, the reply awaited noted
    (``pending``) and the communicate put into the input buffer ``x`` as
    ``received(msg, content, channel, False, performative, sender)``
    (services/runtime/values.py ``Received``). ``lookups``, ``dedup``, ``states``,
    ``pending``, ``x`` and ``counters`` are the agent's own (shared, changed in place);
    ``events`` are the keys of the agent's other inputs (the runtime's own events, which
    :meth:`take_all` hands to the host)."""

    def __init__(
        self,
        host: Host,
        lookups: Lookups,
        dedup: Dedup,
        states: ProtocolStates,
        pending: PendingReplies,
        x: deque[Any],
        counters: Counter[str],
        received: Callable[[Communicate, msgspec.Struct | None, str, bool, Performative, str], Any],
        events: frozenset[str] = frozenset(),
    ) -> None:
        self.host = host
        self.events = events
        self.lookups = lookups
        self.dedup = dedup
        self.states = states
        self.pending = pending
        self.x = x
        self.counters = counters
        self.received = received

    def take_all(self, inbox: deque[tuple[str, Any]], max_open: int) -> None:
        """Take in, in order, the inputs that were in ``inbox`` when it began (popped; what
        arrives meanwhile stays for the next call): a communicate by :meth:`take` (one it does
        not take goes to the host's ``not_taken``), an input whose key is one of ``events`` by
        the host's ``take_event``. No input stops the others: one whose taking in raised is
        the host's ``take_raised``."""
        host, events = self.host, self.events
        for _ in range(len(inbox)):
            key, payload = inbox.popleft()
            if key in events:
                host.take_event(key, payload)
                continue
            try:
                found = self.take(key, payload, max_open)
                if found is not None:
                    host.not_taken(found)
            except Exception:  # no input may stop the agent
                host.take_raised(key)

    def take(self, key: str, payload: bytes, max_open: int) -> Admission | None:
        """Take in the communicate ``payload`` that came on ``key`` (:func:`admit`, a sender
        with ``max_open`` open conversations opening no more): None when it went into the
        input buffer, else what :func:`admit` found (the agent answers or drops it)."""
        found = admit(self.lookups, self.dedup, self.states, max_open, key, payload)
        msg = found.msg
        if found.verdict != TAKEN or msg is None:
            return found
        performative = msg.performative
        self.counters[RECEIVED_COUNTER[performative]] += 1
        outcome = found.outcome
        if outcome and outcome != "step":
            self.host.conversation_stepped(found.sender, msg.conversation_id or "", performative, outcome)
        self.pending.answered(msg.in_reply_to, performative)  # if one was awaited
        self.x.append(self.received(msg, found.content, found.channel, False, performative, found.sender))
        return None


def admit(
    lookups: Lookups, dedup: Dedup, states: ProtocolStates, max_open: int, key: str, payload: bytes
) -> Admission:
    """Check the communicate ``payload`` that came on ``key`` (see the module), against
    ``lookups`` (the agent's specification and interface), ``dedup`` (its duplicate filter)
    and ``states`` (its conversations' protocol states: a sender with ``max_open`` open
    conversations may open no more), and step its conversation's protocol state."""
    try:
        channel, sender, _receiver = lookups.parse(key)
    except ValueError:
        return Admission(BAD_KEY)
    copy = dedup.seen(payload)
    try:  # shared.fipa_codec.decode, without its Python call for a communicate that decodes
        msg = read(payload) if len(payload) <= MAX_COMMUNICATE_BYTES else decode(payload)
    except DECODE_ERRORS as exc:
        found = Admission(UNDECODABLE, channel, sender)
        found.error, found.copy = decode_error(exc), copy
        return found
    if copy:
        return Admission(COPY, channel, sender, msg)
    if msg.sender is None or msg.sender.name != sender:
        return _refused(channel, sender, msg, SENDER_MISMATCH)
    checks = lookups.screen(
        sender,
        channel,
        msg.performative,
        msg.protocol,
        msg.language,
        msg.ontology,
        msg.encoding,
        bool(msg.content),
    )
    content, refusal = screened(msg, checks)
    if refusal is not None:
        return _refused(channel, sender, msg, refusal)
    return _in_conversation(lookups, states, max_open, channel, sender, msg, content)


def _refused(channel: str, sender: str, msg: Communicate, refusal: Refusal) -> Admission:
    found = Admission(REFUSED, channel, sender, msg)
    found.refusal = refusal
    return found


def _in_conversation(
    lookups: Lookups,
    states: ProtocolStates,
    max_open: int,
    channel: str,
    sender: str,
    msg: Communicate,
    content: msgspec.Struct | None,
) -> Admission:
    """:func:`admit`'s checks of ``msg``'s conversation, once the interface accepted it."""
    cid = msg.conversation_id
    protocol = msg.protocol
    followed = lookups.followed(sender, protocol) if protocol is not None else None
    if cid is None:
        # its answer could not be told apart from those of other such conversations, nor
        # followed in the protocol: FIPA SC00061 leaves conversation-id optional, roco needs it
        return Admission(TAKEN if followed is None else NO_CONVERSATION_ID, channel, sender, msg, content)
    if states.open_with(sender) >= max_open and states.get(sender, cid) is None:
        return Admission(TOO_MANY, channel, sender, msg, content)
    if followed is None:
        return Admission(TAKEN, channel, sender, msg, content)
    terminal = msg.language == REPORT_LANGUAGE and is_terminal_report(msg)  # the language first: no call
    outcome, why = step(states, lookups.name, sender, cid, followed, msg.performative, False, terminal, msg)
    found = Admission(TAKEN if why is None else OUT_OF_STATE, channel, sender, msg, content)
    found.why, found.outcome = why or "", outcome
    return found


def step(
    states: ProtocolStates,
    me: str,
    peer: str,
    conversation_id: str,
    followed: Followed,
    performative: Performative,
    sent: bool,
    terminal: bool | None,
    msg: Communicate | None = None,
) -> tuple[Outcome | str, str | None]:
    """Advance the protocol state of conversation ``conversation_id`` of agent ``me`` with
    ``peer`` by one communicate (``sent`` by ``me``, else received; ``followed``: the
    protocol's state machine and ``me``'s role; ``msg`` the communicate, whose reply-with and
    in-reply-to tell what it answers). Returns what ``ProtocolStates.observe`` did ("" when
    it refused) and None, or the reason the state does not allow it."""
    machine, mine = followed
    role: Role = mine if sent else (PARTICIPANT if mine == INITIATOR else INITIATOR)
    try:
        outcome = states.observe(
            peer,
            conversation_id,
            machine,
            role,
            performative,
            local_role=mine,
            terminal=terminal,
            reply_with=None if msg is None else msg.reply_with,
            in_reply_to=None if msg is None else msg.in_reply_to,
        )
    except (ProtocolViolation, ConversationError) as exc:
        # observe leaves the table unchanged when it raises: it tells whether the
        # conversation was known before this communicate
        if states.get(peer, conversation_id) is None:
            return "", f"no such conversation of {me} with {peer} ({exc})"
        return "", str(exc)
    return outcome, None
