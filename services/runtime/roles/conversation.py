"""One conversation a protocol role of an agent takes part in (docs/spec.md, "Protocol
roles"): what it received, what it answers, and the communicates it sends, which go through a
:class:`ConversationHost` (the agent's :class:`~services.runtime.roles.dispatch.Roles`) that
sets conversation-id, in-reply-to and reply-with and checks them against the protocol's state
machine (FIPA SC00061 §2; SC00026 §2 for cancel).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

import msgspec

from services.runtime.roles.declare import RestoreError, RoleDecl
from services.runtime.values import Received
from shared.fipa_codec import Communicate, DecodeError, decode, encode
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.protocols import PARTICIPANT

__all__ = ["Conversation", "ConversationHost", "is_deadline"]

T = TypeVar("T")


class ConversationHost(Protocol):
    """What a :class:`Conversation` asks of the roles it belongs to
    (services/runtime/roles/dispatch.py ``Roles``)."""

    def reply_in(
        self,
        conv: Conversation,
        performative: Performative,
        content: msgspec.Struct | None,
        *,
        reply_by_s: float | None = None,
        retry_s: float | None = None,
        to: Received | None = None,
    ) -> str | None:
        """Send ``performative`` in ``conv`` answering ``to`` (default: what it answers
        now); returns its reply-with. Raises SpecViolation when the state forbids it."""
        ...

    def send_in(
        self,
        conv: Conversation,
        performative: Performative,
        content: msgspec.Struct | None,
        reply_by_s: float | None,
        retry_s: float | None,
        *,
        expect: bool,
        in_reply_to: str | None = None,
    ) -> Communicate:
        """Send ``performative`` in ``conv``; returns the communicate sent."""
        ...

    def fail(self, to: Received, performative: Performative, reason: str) -> None:
        """Answer ``to`` with ``refuse`` or ``failure`` carrying ``reason`` as UTF-8 text."""
        ...

    def settle(self, conv: Conversation) -> None:
        """Forget ``conv`` once it has ended and nothing of it waits for a handler."""
        ...

    def await_reply(
        self, conv: Conversation, reply_with: str, reply_by_s: float | None, retry_s: float | None
    ) -> None:
        """Wait for the reply to ``reply_with`` until ``reply_by_s`` s from now."""
        ...

    def stop_awaiting_replies(self, conversation_id: str) -> None:
        """No more reply-by deadlines nor retransmissions in ``conversation_id``."""
        ...

    def forget(self, conv: Conversation) -> None:
        """``conv`` is no longer open: what its peer sends in it is a late reply."""
        ...

    def remember(self, conv: Conversation) -> None:
        """Remember ``conv``'s conversation-id and data after it ended."""
        ...

    def protocol_state(self, peer: str, conversation_id: str) -> str | None:
        """The state of the conversation with ``peer`` in its protocol's machine (None: none yet)."""
        ...

    def protocol_finished(self, peer: str, conversation_id: str) -> bool:
        """The conversation with ``peer`` reached a final state of its protocol."""
        ...

    def publish_again(self, peer: str, in_reply_to: str | None) -> int:
        """Publish again, byte for byte, what was answered to ``peer``'s ``in_reply_to``;
        returns how many."""
        ...


def is_deadline(item: Received) -> bool:
    """``item`` is the runtime's failure for a reply-by deadline that passed (not a
    not-understood this agent sent: :meth:`Roles.not_understood_sent`)."""
    return item.local and item.msg.performative is Performative.FAILURE


@dataclass(eq=False)
class Conversation:
    """One conversation a role of this agent takes part in (what roco calls a conversation;
    its protocol state is followed by services/runtime/protocol_state.py, the replies awaited
    in it are kept by services/runtime/replies.py).

    ``decl`` is the role, ``peer`` the other agent, ``conversation_id`` the FIPA
    conversation-id; ``last`` the latest communicate received in it (None before the first;
    the runtime's local ``failure`` when a reply-by deadline passed); ``data`` whatever the
    agent attaches (e.g. what a query was about). Replies and further communicates go
    through :meth:`reply`, :meth:`refuse_with`, :meth:`send` and :meth:`cancel`, which set
    conversation-id, in-reply-to and reply-with and which the protocol's state machine
    checks (SpecViolation)."""

    host: ConversationHost = field(repr=False)
    """Where its communicates go: the :class:`~services.runtime.roles.dispatch.Roles` of its agent."""
    decl: RoleDecl
    peer: str
    conversation_id: str
    last: Received | None = None
    opening: Received | None = None
    """The communicate that opened the conversation: the peer's (participant) or this
    agent's own (initiator)."""
    data: Any = None
    agreed: bool = False
    """The participant agreed (fipa-request, fipa-query, fipa-subscribe)."""
    awaited: set[str] = field(default_factory=set, repr=False)
    """The reply-with of every communicate this agent sent in it (what a reply may answer)."""
    knows_sent: bool = field(default=True, repr=False)
    """False for a conversation restored by its id alone: it does not know what this agent
    sent before the restart, so no reply in it is taken for a stale one."""
    cancels: set[str] = field(default_factory=set, repr=False)
    """The reply-with of every cancel this agent sent in it awaiting an answer."""
    replied_to: str | None = field(default=None, repr=False)
    """The reply-with of the peer's communicate this agent last answered in it (None: none
    yet), what :meth:`answer_again` publishes the answers to."""
    _cancel: Received | None = field(default=None, repr=False)
    _cancelled: bool = field(default=False, repr=False)
    _seq: int = field(default=0, repr=False)  # the order in which the role took it up
    _kept: bytes | None = field(default=None, repr=False)  # :meth:`keep`, once encoded

    @property
    def content(self) -> msgspec.Struct | None:
        """The decoded content of :attr:`last` (a term of its language), or None."""
        return self.last.content if self.last is not None else None

    @property
    def reason(self) -> str:
        """The plain-text reason of :attr:`last` (refuse, failure, not-understood, or the
        runtime's ``reply-by deadline passed``), or its performative's name."""
        if self.last is None:
            return ""
        msg = self.last.msg
        text = msg.content.decode("utf-8", "replace") if msg.encoding == "utf-8" else ""
        return text or msg.performative.value

    @property
    def explanation(self) -> str:
        """Why the peer answered :attr:`last` negatively (refuse, failure, not-understood) or
        not at all, in words for a person: ``<peer> did not answer in time`` when the reply-by
        deadline passed, else the plain-text reason it gave, or ``no reason given``."""
        if self.timed_out:
            return f"{self.peer} did not answer in time"
        msg = self.last.msg if self.last is not None else None
        text = (
            msg.content.decode("utf-8", "replace").strip()
            if msg is not None and msg.encoding == "utf-8"
            else ""
        )
        return text or "no reason given"

    @property
    def timed_out(self) -> bool:
        """The reply-by deadline passed before the peer answered (the runtime ended it)."""
        return self.last is not None and is_deadline(self.last)

    @property
    def last_answers(self) -> str | None:
        """The reply-with of this agent's communicate that :attr:`last` answers (its
        in-reply-to; None: it answers none), to be compared with what :meth:`send` returned."""
        return self.last.msg.in_reply_to if self.last is not None else None

    def repeats(self, item: Received) -> bool:
        """``item`` is the communicate that opened this conversation again: the same sender
        and non-empty reply-with (FIPA SC00061 §2.4), e.g. a retransmission after a restart."""
        opening = self.opening
        reply_with = item.msg.reply_with
        return (
            opening is not None
            and bool(reply_with)
            and opening.msg.reply_with == reply_with
            and opening.sender == item.sender
        )

    def answers_other(self, msg: Communicate) -> bool:
        """``msg`` replies to a communicate this agent did not send in this conversation (in
        this opening of its conversation-id): a reply to an earlier opening. Never so for a
        conversation restored by its id alone (it does not know what it sent)."""
        return self.knows_sent and msg.in_reply_to is not None and msg.in_reply_to not in self.awaited

    @property
    def not_understood(self) -> bool:
        """A ``not-understood`` ended the conversation: the peer's, or this agent's
        (:attr:`unreadable`)."""
        return self.last is not None and self.last.performative is Performative.NOT_UNDERSTOOD

    @property
    def unreadable(self) -> bool:
        """This agent could not read the peer's latest communicate and answered it
        not-understood, which ended the conversation (:meth:`Roles.not_understood_sent`)."""
        return self.last is not None and self.last.local and self.not_understood

    @property
    def state(self) -> str | None:
        """The conversation's state in its protocol's state machine (e.g. ``requested``,
        ``agreed`` in fipa-request; shared/fipa_codec/protocols.py), None before its first
        communicate."""
        return self.host.protocol_state(self.peer, self.conversation_id)

    @property
    def finished(self) -> bool:
        """The conversation has reached a final state of its protocol (or a not-understood
        ended it, or the peer's ``inform`` answered this agent's cancel: ``cancelled``, which
        the protocol state alone cannot tell from an inform that crossed the cancel)."""
        if self._cancelled:
            return True
        return self.host.protocol_finished(self.peer, self.conversation_id)

    @property
    def to_answer(self) -> Received | None:
        """The communicate this agent's next reply answers (its in-reply-to): a participant
        answers the communicate that opened the conversation — or, while its ``cancel``
        handler runs, the cancel (FIPA SC00026 §2: the cancel is answered by itself); an
        initiator answers the latest communicate received (e.g. coordinate's ``confirm`` of
        an ``inform``)."""
        if self._cancel is not None:
            return self._cancel
        if self.decl.role == PARTICIPANT and self.opening is not None:
            return self.opening
        return self.last

    def reply(
        self,
        performative: Performative,
        content: msgspec.Struct | None = None,
        *,
        to: Received | None = None,
    ) -> str | None:
        """Answer :attr:`to_answer` (or ``to``, a communicate received in this conversation
        earlier: e.g. a cancel answered once the robot is safe) with ``performative`` carrying
        ``content``. Returns its reply-with (every communicate of a role has one). Raises
        SpecViolation when the role or the conversation's state does not allow it."""
        return self._sent(self.host.reply_in(self, performative, content, to=to))

    def answer_cancel(
        self, cancelled: bool, content: msgspec.Struct | None = None, *, to: Received | None = None
    ) -> str | None:
        """Answer the peer's ``cancel`` (``to``, received in this conversation earlier, or the
        one the running ``cancel`` handler takes) by the cancel meta-protocol (FIPA SC00026 §2):
        ``inform`` when the conversation is ``cancelled`` (it ends), else ``failure``, carrying
        ``content``. Returns its reply-with; raises SpecViolation as :meth:`reply`."""
        return self.reply(Performative.INFORM if cancelled else Performative.FAILURE, content, to=to)

    def refuse_with(self, performative: Performative, reason: str, *, to: Received | None = None) -> None:
        """Answer :attr:`to_answer` (or ``to``) with ``refuse`` or ``failure`` whose content
        is ``reason`` as UTF-8 text (FIPA SC00037: a reason a person can read). Raises
        SpecViolation as :meth:`reply`."""
        answering = to or self.to_answer
        assert answering is not None, "nothing received to answer"
        self.host.fail(answering, performative, reason)
        self.host.settle(self)

    def send(
        self,
        performative: Performative,
        content: msgspec.Struct | None = None,
        *,
        reply_by_s: float | None = None,
        retry_s: float | None = None,
    ) -> str | None:
        """Send a further communicate of this conversation as :meth:`reply` does, awaiting a
        reply when ``reply_by_s`` (s: the reply-by deadline) or ``retry_s`` (s: retransmitted
        until the first answer; ``RESEND_ON_RETURN``: only when the peer reappears) is given.
        Returns its reply-with."""
        return self._sent(
            self.host.reply_in(self, performative, content, reply_by_s=reply_by_s, retry_s=retry_s)
        )

    @property
    def answers_cancel(self) -> bool:
        """:attr:`last` answers a cancel this agent sent (the cancel meta-protocol's inform
        or failure, or the runtime's failure when the cancel's reply-by deadline passed)."""
        return self.last is not None and self.last.msg.in_reply_to in self.cancels

    def cancel(self, content: msgspec.Struct | None = None, *, reply_by_s: float | None = None) -> str | None:
        """The initiator cancels the conversation (FIPA SC00026 §2 cancel meta-protocol, or
        the coordinate protocol's cancel, paper §5.4), carrying ``content``; it refers to the
        conversation, not to one communicate (no in-reply-to). With ``reply_by_s`` (s) its
        answer is awaited (:attr:`answers_cancel`) and a local failure ends the wait. Returns
        the cancel's reply-with."""
        reply_with = self.host.send_in(
            self, Performative.CANCEL, content, reply_by_s, None, expect=False
        ).reply_with
        if reply_with is not None:
            self.cancels.add(reply_with)
            self.awaited.add(reply_with)
        self.host.settle(self)
        return reply_with

    def await_reply(self, reply_by_s: float) -> None:
        """Wait for the answer to this agent's opening communicate until ``reply_by_s`` (s)
        from now, without retransmission (e.g. the outcome after an ``agree``, which ended
        the first wait's retransmissions but not its deadline)."""
        if self.opening is not None and self.opening.msg.reply_with:
            self.host.await_reply(self, self.opening.msg.reply_with, reply_by_s, None)

    def opening_content(self, kind: type[T]) -> T:
        """The content of the communicate that opened the conversation, of type ``kind``
        (e.g. after :meth:`Roles.restore` with ``expect=kind``). Raises TypeError otherwise."""
        content = self.opening.content if self.opening is not None else None
        if not isinstance(content, kind):
            raise TypeError(f"conversation {self.conversation_id} opened with {type(content).__name__}")
        return content

    def keep(self) -> bytes:
        """The communicate that opened this conversation, encoded (FIPA SC00061 msgpack), to
        be kept across a restart and given back to :meth:`Roles.restore`."""
        assert self.opening is not None, "a conversation restored by its id alone has no opening"
        if self._kept is None:
            self._kept = encode(self.opening.msg)
        return self._kept

    def stop_awaiting_replies(self) -> None:
        """Stop waiting for replies in this conversation: no reply-by deadline, no
        retransmission. The conversation stays open: what the peer sends still arrives."""
        self.host.stop_awaiting_replies(self.conversation_id)

    def forget(self, *, remember: bool = False) -> None:
        """:meth:`stop_awaiting_replies`, and forget the conversation: what the peer still sends in
        it is dropped as a late reply. ``remember``: its conversation-id and :attr:`data` are
        remembered (the last :data:`ENDED_KEPT`), for what is said of it later
        (:meth:`Roles.ended`), and its conversation-id is not chosen again (:meth:`Roles.free_id`)."""
        self.stop_awaiting_replies()
        self.host.forget(self)
        if remember:
            self.host.remember(self)

    def cancel_if_open(self, *, forget: bool = True) -> None:
        """The initiator no longer wants this conversation: :meth:`stop_awaiting_replies`,
        :meth:`cancel` it when it is still open (FIPA SC00026 §2, the cancel meta-protocol: the
        participant stops working on it), and, with ``forget``, :meth:`forget` it (what the
        peer still sends is dropped as a late reply; else it is taken as it comes)."""
        self.stop_awaiting_replies()
        if not self.finished:
            self.cancel()
        if forget:
            self.forget()

    def decode(self, kept: bytes) -> Received:
        """A communicate of this conversation kept encoded (FIPA SC00061 msgpack, e.g. the
        peer's ``cancel``, to be answered after a restart), as received on its channel, its
        content decoded. Raises RestoreError (a ValueError) when it does not decode."""
        try:
            msg = decode(kept)
            content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
        except (DecodeError, ContentError) as exc:
            raise RestoreError(
                f"a kept communicate of {self.conversation_id} does not decode: {exc}"
            ) from None
        return Received.of(msg, content, self.decl.channel)

    def answer_again(self, in_reply_to: str | None = None) -> int:
        """Publish again, byte for byte, what this agent answered the peer's communicate
        ``in_reply_to`` (default :attr:`replied_to`: e.g. the last ``confirm`` to a peer
        that may have restarted; a peer that still has it drops the copy,
        services/runtime/dedup.py). Returns how many (0: nothing answered, or forgotten)."""
        return self.host.publish_again(self.peer, in_reply_to or self.replied_to)

    def _sent(self, reply_with: str | None) -> str | None:
        if reply_with is not None:
            self.awaited.add(reply_with)
        self.host.settle(self)
        return reply_with
