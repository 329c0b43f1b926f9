"""The protocol roles of one agent at run time (:class:`Roles`; docs/spec.md, "Protocol
roles"): each received communicate routed to its conversation and handler
(services/runtime/roles/route.py), the communicates its conversations send, reply-by deadlines
and retransmission, cancel and not-understood, the subscriptions its roles keep or serve, and
its conversations kept across a restart. What it owns of each protocol is listed in
services/runtime/roles/__init__.py; it reaches its agent through
:class:`~services.runtime.roles.host.RoleHost` alone.
"""

from __future__ import annotations

import itertools
from collections import OrderedDict
from collections.abc import Callable, Container, Iterator, Sequence
from typing import Any, TypeVar

import msgspec

from services.runtime import keys
from services.runtime.replies import Pending
from services.runtime.roles.check import agent_problems, expand_roles, path_to
from services.runtime.roles.confirmed import ConfirmedInforms
from services.runtime.roles.conversation import Conversation, is_deadline
from services.runtime.roles.declare import RestoreError, RoleDecl, RoleMismatch, handler_for, handlers_of
from services.runtime.roles.host import RoleHost
from services.runtime.roles.route import _OPENS, _ORPHAN, _REPEATED, RoleTable, note, role_table, route
from services.runtime.roles.served import ServedSubscription
from services.runtime.roles.subscriptions import StandingSubscription
from services.runtime.state_store import NO_DATA, KeptConversation, KeptConversations
from services.runtime.values import Received, SpecViolation
from services.spec.names import FIPA_QUERY
from services.spec.protocol_defs import machine_of, streams
from shared.fipa_codec import Communicate, DecodeError, decode
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, Protocol

__all__ = ["ENDED_KEPT", "MAX_OPEN", "Roles"]

S = TypeVar("S", bound=msgspec.Struct)

MAX_OPEN = 1024
"""Open conversations a :class:`Roles` keeps before it forgets the oldest (bounded memory)."""
ENDED_KEPT = 256
"""Ended conversations a :class:`Roles` remembers when asked to (:meth:`Conversation.forget`
with ``remember``), the oldest forgotten first."""


class Roles:
    """The protocol roles of one agent at run time: its declarations, its handlers, the
    conversations open in each role. Built by services/runtime/engine.py ``Engine`` from its agent's
    class's ``roles`` and :func:`handles` methods; raises RoleMismatch (one line) when they
    differ from the specification (:func:`role_problems`)."""

    def __init__(
        self, host: RoleHost, agent: object, declared: Sequence[RoleDecl], *, check: bool = True
    ) -> None:
        self.host = host
        """The engine running the agent these roles belong to
        (:class:`~services.runtime.roles.host.RoleHost`)."""
        self.agent = agent
        """The agent, whose handlers (:func:`handles` methods) the roles call."""
        self.declared = tuple(expand_roles(host.spec, host.name, declared))
        """The declared roles, each on EVERY_CHANNEL replaced by those it stands for."""
        self._handlers = handlers_of(type(agent))
        problems = agent_problems(host.spec, host.name, type(agent)) if check else []
        if problems:
            more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
            raise RoleMismatch(problems[0] + more)
        self._by_peer: dict[tuple[str, str], RoleDecl] = {}
        channels = {ch.name: ch for ch in host.spec.channels}
        for decl in self.declared:
            ends = channels[decl.channel].ends
            peer = ends[1] if ends[0] == host.name else ends[0]
            self._by_peer[(peer, decl.protocol)] = decl
        self._peer_of = {decl: peer for (peer, _), decl in self._by_peer.items()}
        self._tables = {
            key: role_table(decl, machine_of(host.spec, decl.protocol), self._handlers)
            for key, decl in self._by_peer.items()
        }
        """:attr:`_by_peer`'s roles as :class:`RoleTable`\\s, what :meth:`take` looks up."""
        self._open: OrderedDict[tuple[str, str], Conversation] = OrderedDict()
        self._subscriptions: dict[
            tuple[RoleDecl, str], StandingSubscription | ServedSubscription[Any] | ConfirmedInforms
        ] = {}
        """The subscriptions the roles keep (by role and first conversation-id), and the streams
        they serve and the informs they report (by role and "")."""
        self.ticks = False
        """:meth:`tick` has something to look at (a subscription is kept): the agent calls it
        on every step only then."""
        self._ended: OrderedDict[str, Any] = OrderedDict()  # :meth:`Conversation.forget`, remember
        self._restored_openings: OrderedDict[tuple[str, str], None] = OrderedDict()
        """(sender, reply-with) of the openings of participant conversations taken back after a
        restart (the last :data:`ENDED_KEPT`): a copy that comes after the conversation ended
        is its opening again, not a new one (:func:`route`, :meth:`_repeated`)."""
        self._taken_up = itertools.count(1)
        self.keeps = any(d.keep for d in self.declared)
        """Some role keeps its conversations across a restart (:meth:`kept`)."""
        self._held: dict[int, Conversation] = {}
        """Conversations of a role declared ``resume_in`` that ended while the agent's data of
        them was set, by :attr:`Conversation._seq`: kept until the agent sets it to None."""
        self._unserved: dict[RoleDecl, Conversation] = {}
        """Per role, the latest subscription taken back after a restart before the agent served
        its stream (:meth:`serve`, called in the agent's ``__init__`` after the runtime's)."""

    # ---- the agent's side ---------------------------------------------------------------
    def role(self, channel: str, protocol: str) -> RoleDecl:
        """The declared role on ``channel`` in ``protocol``; KeyError when none."""
        for decl in self.declared:
            if decl.channel == channel and decl.protocol == protocol:
                return decl
        raise KeyError(f"{self.host.name} declares no {protocol} role on {channel}")

    def peer_of(self, decl: RoleDecl) -> str:
        """The agent at the other end of ``decl``'s channel."""
        return self._peer_of[decl]

    def subscribe(
        self,
        channel: str,
        protocol: str,
        content: msgspec.Struct,
        *,
        conversation_id: str,
        reply_by_s: float | None = None,
        retry_s: tuple[float, float] = (1.0, 60.0),
        at_start: bool = False,
        while_away: bool = True,
        on_subscribed: Callable[[Conversation], None] | None = None,
        on_lost: Callable[[Conversation], None] | None = None,
    ) -> StandingSubscription:
        """Keep a subscription open in the initiator role on ``channel`` in ``protocol``
        (declared ``resubscribes=True``), subscribing ``content`` (FIPA SC00035): the role
        subscribes when the peer's token appears (``at_start``: at once), again with a doubling
        back-off from ``retry_s[0]`` to ``retry_s[1]`` s after a refuse, failure, not-understood
        or passed reply-by deadline (``reply_by_s`` s, the role's when None), and again when
        the peer comes back; each attempt in conversation ``conversation_id`` (``-2``, ``-3``,
        …); ``while_away``: attempts go on while the peer's token is
        away. ``on_subscribed``/``on_lost``: called with the conversation when the peer agrees,
        and when an agreed subscription ends. Returns the handle (its ``subscribed``); the
        agent handles the stream's ``inform``\\s. A role keeps several subscriptions apart by
        their conversation-ids; :meth:`unsubscribe` ends one. Raises KeyError for a role not
        declared or not declared ``resubscribes``, or a subscription of ``conversation_id``
        kept already; ValueError for a back-off that is not (first ≤ longest)
        (services/runtime/roles/subscriptions.py)."""
        decl = self.role(channel, protocol)
        if not decl.resubscribes or decl.role != INITIATOR:
            raise KeyError(
                f"{self.host.name} declares no resubscribing initiator role of {protocol} on {channel}"
            )
        if (decl, conversation_id) in self._subscriptions:
            kept = f"the subscription {conversation_id} of {protocol} on {channel}"
            raise KeyError(f"{self.host.name} keeps {kept} already")
        sub = StandingSubscription(
            self,
            decl,
            content,
            conversation_id=conversation_id,
            reply_by_s=reply_by_s if reply_by_s is not None else decl.reply_by_s,
            retry_s=retry_s,
            at_start=at_start,
            while_away=while_away,
            on_subscribed=on_subscribed,
            on_lost=on_lost,
        )
        self._subscriptions[(decl, conversation_id)] = sub
        self.ticks = True
        return sub

    def unsubscribe(self, sub: StandingSubscription) -> None:
        """Stop keeping ``sub`` (from :meth:`subscribe`) open: its latest attempt, unless it has
        ended, is cancelled (FIPA SC00026 §2 cancel meta-protocol; the peer's answer to the
        cancel reaches the agent's ``inform`` handler as :attr:`Conversation.answers_cancel`),
        and no attempt follows. Nothing for a subscription not kept."""
        if self._subscriptions.get((sub.decl, sub.base_id)) is not sub:
            return
        del self._subscriptions[(sub.decl, sub.base_id)]
        sub.end()

    def _kept_for(
        self, decl: RoleDecl, conv: Conversation
    ) -> StandingSubscription | ServedSubscription[Any] | ConfirmedInforms | None:
        """The subscription of ``decl`` that ``conv`` belongs to: the stream served or the
        informs reported in it, or the kept one of which ``conv`` is an attempt
        (:meth:`StandingSubscription.owns`); None: the agent's own."""
        served = self._subscriptions.get((decl, ""))
        if served is not None:
            return served
        for (of, _), sub in self._subscriptions.items():
            if of == decl and isinstance(sub, StandingSubscription) and sub.owns(conv):
                return sub
        return None

    def serve(
        self,
        channel: str,
        protocol: str,
        *,
        unsent: Callable[[], list[S]],
        about: Callable[[S], str],
        kept_each: int,
        kept_in_all: int,
        dropped: str,
    ) -> ServedSubscription[S]:
        """Serve the stream of the participant role on ``channel`` in ``protocol`` (a
        subscription: fipa-subscribe) to its latest agreed subscription
        (services/runtime/roles/served.py): the agent's ``subscribe`` handler agrees with
        :meth:`ServedSubscription.agree`, it informs with :meth:`ServedSubscription.inform`;
        the role answers ``cancel`` and ends the subscription on ``not-understood``. Informs
        made while none is agreed are kept in the list ``unsent()`` gives, in order, sent after
        the next agree: at most ``kept_each`` per ``about(inform)`` and ``kept_in_all`` in all,
        the oldest dropped first and counted under ``dropped``. A subscription taken back after
        a restart before this call takes the stream (the latest such). Raises KeyError for a role not
        declared, not a participant's, of a protocol that is no subscription (no stream with a
        cancel meta-protocol) or served already; ValueError for a bound below 1."""
        decl = self.role(channel, protocol)
        machine = machine_of(self.host.spec, protocol)
        if decl.role != PARTICIPANT or not streams(machine) or "cancelling" not in machine.states:
            raise KeyError(
                f"{self.host.name} declares no participant role of a subscription {protocol} on {channel}"
            )
        if any(of == decl for of, _ in self._subscriptions):
            raise KeyError(f"{self.host.name} serves the {protocol} subscription on {channel} already")
        served = ServedSubscription(
            self,
            decl,
            unsent=unsent,
            about=about,
            kept_each=kept_each,
            kept_in_all=kept_in_all,
            dropped=dropped,
        )
        self._subscriptions[(decl, "")] = served
        kept = self._unserved.pop(decl, None)
        if kept is not None and not kept.finished:
            served.taken_back(kept)
        self.ticks = True
        return served

    def report(self, channel: str, protocol: str, *, retry_s: float | None) -> ConfirmedInforms:
        """Send the informs of the participant role on ``channel`` in ``protocol`` (declared
        ``confirmed_informs=True``) one at a time, each once the peer confirmed the one before,
        retransmitted every ``retry_s`` (s) until then (services/runtime/roles/confirmed.py).
        Raises KeyError for a role not declared, not so declared, or reported already."""
        decl = self.role(channel, protocol)
        if not decl.confirmed_informs:
            raise KeyError(
                f"{self.host.name} declares no {protocol} role on {channel} with confirmed informs"
            )
        if any(of == decl for of, _ in self._subscriptions):
            raise KeyError(f"{self.host.name} reports in the {protocol} role on {channel} already")
        reports = ConfirmedInforms(self, decl, retry_s=retry_s)
        self._subscriptions[(decl, "")] = reports
        return reports

    def ended(self, conversation_id: str) -> Any:
        """The :attr:`Conversation.data` of conversation ``conversation_id``, which this agent
        forgot lately with ``remember`` (the last :data:`ENDED_KEPT`); None when it is not
        remembered."""
        return self._ended.get(conversation_id)

    def withdraw_queries(self) -> int:
        """Withdraw every query this agent asked and still waits on (:meth:`Conversation.cancel_if_open`:
        a cancel, FIPA SC00027 §2): called when the agent stops, so that no participant answers
        a question nobody will read. Requests are left alone: what they started (a plan, a
        motion) is the other agents' to end, and a restarted agent takes them up again.
        Returns how many were withdrawn."""
        open_queries = [  # not one this agent cancelled already: it may wait for the cancel's answer
            c
            for c in self
            if c.decl.role == INITIATOR and c.decl.protocol == FIPA_QUERY and not c.finished and not c.cancels
        ]
        for conv in open_queries:
            conv.cancel_if_open()
        return len(open_queries)

    def free_id(self, base: str, taken: Container[str] = ()) -> str:
        """A conversation-id for a new conversation: ``base``, else ``base-2``, ``base-3``, …,
        the first that no conversation of this agent has open, none it remembers as ended
        (:meth:`ended`) had, and that is not in ``taken``."""
        open_ids = {cid for _, cid in self._open}
        cid, n = base, 1
        while cid in open_ids or cid in self._ended or cid in taken:
            n += 1
            cid = f"{base}-{n}"
        return cid

    def peer_changed(self, peer: str, alive: bool) -> None:
        """``peer``'s liveliness token appeared or disappeared: the subscriptions kept with it
        act on it (services/runtime/roles/subscriptions.py)."""
        for sub in list(self._subscriptions.values()):
            if sub.peer == peer:
                sub.peer_changed(alive)

    def tick(self, now: float) -> None:
        """Make the subscription attempts due at POSIX time ``now``."""
        for sub in self._subscriptions.values():
            sub.tick(now)

    def open(
        self,
        channel: str,
        protocol: str,
        content: msgspec.Struct | None,
        *,
        performative: Performative | None = None,
        data: Any = None,
        conversation_id: str | None = None,
        reply_by_s: float | None = None,
        retry_s: float | None = None,
    ) -> Conversation:
        """Open a conversation as the initiator of ``protocol`` on ``channel``: send its
        opening communicate (``performative``, or the protocol's only opening performative)
        carrying ``content``. ``reply_by_s``/``retry_s`` default to the role's; an opening
        that ends the conversation (the inform of a one-message protocol) awaits no reply,
        and the conversation is not kept open. Raises KeyError
        for a role not declared, SpecViolation for a performative that does not open the
        protocol."""
        decl = self.role(channel, protocol)
        if decl.unused:
            raise KeyError(f"{self.host.name} declares its {protocol} role on {channel} unused")
        if decl.role != INITIATOR:
            raise KeyError(
                f"{self.host.name} is the participant of {protocol} on {channel}, not the initiator"
            )
        machine = machine_of(self.host.spec, protocol)
        openers = sorted(
            (p for (s, r, p) in machine.transitions if s == machine.initial and r == INITIATOR),
            key=lambda p: p.value,
        )
        perf = performative or (openers[0] if len(openers) == 1 else None)
        if perf is None:
            raise ValueError(f"{protocol} opens with {' or '.join(p.value for p in openers)}: name one")
        conv = Conversation(self, decl, self._peer_of[decl], conversation_id or "", data=data)
        answered = _answered(machine, perf)
        msg = self.send_in(
            conv,
            perf,
            content,
            _default(reply_by_s, decl.reply_by_s, answered),
            _default(retry_s, decl.retry_s, answered),
            expect=answered,
        )
        conv.opening = Received.of(msg, content, decl.channel)
        if msg.reply_with is not None:
            conv.awaited.add(msg.reply_with)
        self._keep(conv)
        self.settle(conv)  # forgotten at once when the opening ended it
        return conv

    def restore(
        self,
        channel: str,
        protocol: str,
        state: str,
        *,
        kept: bytes | None = None,
        conversation_id: str | None = None,
        reply_by_s: float | None = None,
        retry_s: float | None = None,
        data: Any = None,
        expect: type | None = None,
    ) -> Conversation:
        """Re-enter a conversation kept across a restart (docs/recovery.md) in ``state`` of its
        protocol's state machine, reached by the shortest path of communicates (an ``inform``
        counts as non-terminal). ``kept`` is :meth:`Conversation.keep` of the conversation
        before the restart (the communicate that opened it); without it, ``conversation_id``
        names the conversation. When this agent sent the opening communicate and
        ``reply_by_s`` (s) or ``retry_s`` (s) is given, the wait for its reply is re-entered:
        retransmitted at once and every ``retry_s`` until answered, ended by a local failure
        after ``reply_by_s``. ``expect``: the type the opening's content must have. Raises
        RestoreError (a ValueError) for kept bytes that do not decode, name no conversation or
        carry content of another type, and when no path leads to ``state``; KeyError for a role
        not declared."""
        decl = self.role(channel, protocol)
        peer = self._peer_of[decl]
        opening: Received | None = None
        if kept is not None:
            try:
                msg = decode(kept)
                content = decode_content(msg.language, msg.content) if msg.language and msg.content else None
            except (DecodeError, ContentError) as exc:
                raise RestoreError(f"a kept {protocol} conversation does not decode: {exc}") from None
            if not msg.conversation_id:
                raise RestoreError(f"a kept {protocol} communicate names no conversation")
            if expect is not None and not isinstance(content, expect):
                what = type(content).__name__ if content is not None else "no content"
                raise RestoreError(f"a kept {protocol} conversation carries {what}, not {expect.__name__}")
            opening = Received.of(msg, content, decl.channel)
            conversation_id = msg.conversation_id
        if not conversation_id:
            raise RestoreError("restore needs the kept communicate or the conversation-id")
        machine = machine_of(self.host.spec, protocol)
        path = path_to(machine, state)
        if path is None:
            raise RestoreError(f"{protocol} has no state {state!r} to restore a conversation in")
        self.host.restore_conversation(
            peer,
            conversation_id,
            protocol,
            [(perf, role == decl.role) for role, perf in path],
            opening.msg.reply_with if opening is not None else None,
        )
        mine = opening is not None and opening.sender == self.host.name
        conv = Conversation(
            self,
            decl,
            peer,
            conversation_id,
            last=None if mine else opening,
            opening=opening,
            data=data,
            knows_sent=opening is not None,
        )
        if mine and opening is not None and kept is not None and opening.msg.reply_with:
            if reply_by_s is not None or retry_s is not None:
                self.await_reply(conv, opening.msg.reply_with, reply_by_s, retry_s, kept)
            conv.awaited.add(opening.msg.reply_with)
        self._keep(conv)
        return conv

    def kept(self) -> KeptConversations:
        """The open conversations of the roles declared with ``keep``, oldest first, as the
        agent's state file keeps them (services/runtime/state_store.py): each with the protocol
        state it is in, its opening and its :attr:`Conversation.data` (JSON of the Struct the
        role declares; a conversation of such a role is kept once the agent set its data; of a
        role declared ``resume_in``, for as long as it is set, ended or not). A conversation
        restored by its id alone, or one not yet begun, is left out."""
        if self._held:
            self._held = {seq: c for seq, c in self._held.items() if c.data is not None}
        out: list[KeptConversation] = []
        for conv in sorted([*self._open.values(), *self._held.values()], key=lambda c: c._seq):
            state = self._kept_state(conv)
            if state is None:
                continue
            keep = conv.decl.keep
            data = NO_DATA
            if isinstance(keep, type) and conv.data is not None:
                data = msgspec.Raw(msgspec.json.encode(conv.data))
            out.append(
                KeptConversation(
                    channel=conv.decl.channel,
                    protocol=conv.decl.protocol,
                    state=state,
                    opening=conv.keep(),
                    data=data,
                )
            )
        return KeptConversations(conversations=out)

    @staticmethod
    def _kept_state(conv: Conversation) -> str | None:
        """The protocol state :meth:`kept` keeps ``conv`` in, or None when it keeps it not."""
        decl = conv.decl
        if not decl.keep or conv.opening is None or (isinstance(decl.keep, type) and conv.data is None):
            return None  # (of a role with a note: once the agent set its data)
        if decl.resume_in is not None and conv.data is not None:
            return conv.state or decl.resume_in  # held while its data is set, ended or not
        return None if conv.finished else conv.state

    def take_back(self, kept: KeptConversations) -> list[Conversation]:
        """Re-enter the conversations ``kept`` by :meth:`kept` before a restart (docs/recovery.md):
        a participant's in the protocol state it was in (its role's ``resume_in``, if
        declared: :attr:`RoleDecl.resume_in`); an initiator's in the state its
        opening leads to, the opening sent again (at once, then as the role retransmits, until
        the reply-by deadline) — its participant answers a repeated opening as it answered it
        (:meth:`_repeated`), so what was answered while this agent was down is not lost. Each
        gets its :attr:`Conversation.data` back, decoded as the role declares. A conversation
        that cannot be taken back (its role no longer keeps any, its data or opening does not
        decode, no path leads to its state) is logged and left out. Returns those taken back,
        oldest first."""
        out: list[Conversation] = []
        for k in kept.conversations:
            try:
                decl = self.role(k.channel, k.protocol)
                if not decl.keep:
                    raise RestoreError(f"the {k.protocol} role on {k.channel} keeps no conversations")
                data = None
                if isinstance(decl.keep, type) and bytes(k.data) != bytes(NO_DATA):
                    data = msgspec.json.decode(k.data, type=decl.keep)
                state = decl.resume_in or k.state
                if decl.role == INITIATOR:
                    machine = machine_of(self.host.spec, k.protocol)
                    opened = machine.next_state(machine.initial, INITIATOR, decode(k.opening).performative)
                    state = opened or state
                conv = self.restore(
                    k.channel,
                    k.protocol,
                    state,
                    kept=k.opening,
                    reply_by_s=decl.reply_by_s if decl.role == INITIATOR else None,
                    retry_s=decl.retry_s if decl.role == INITIATOR else None,
                    data=data,
                )
            except (
                KeyError,
                DecodeError,
                RestoreError,
                SpecViolation,
                msgspec.DecodeError,
                msgspec.ValidationError,
            ) as exc:
                self.host.log.warning(
                    "a kept %s conversation cannot be taken back (%s): dropped", k.protocol, exc
                )
                continue
            self._taken_back(conv)
            out.append(conv)
        return out

    def await_reply(
        self,
        conv: Conversation,
        reply_with: str,
        reply_by_s: float | None,
        retry_s: float | None,
        payload: bytes = b"",
    ) -> None:
        """Wait for the reply to ``reply_with`` (services/runtime/replies.py): until
        ``reply_by_s`` from now, retransmitting ``payload`` at once and every ``retry_s``."""
        now = self.host.sources.time()
        again = retry_s is not None and bool(payload)
        self.host.pending_replies.expect(
            Pending(
                reply_with,
                conv.peer,
                conv.decl.protocol,
                conv.conversation_id,
                now + reply_by_s if reply_by_s is not None else None,
                retry_s=retry_s if again else None,
                key=keys.fipa_key(conv.decl.channel, self.host.name, conv.peer) if again else "",
                payload=payload if again else b"",
                next_retry=now if again else None,
            )
        )

    def conversations(self, channel: str, protocol: str) -> list[Conversation]:
        """The open conversations of the role on ``channel`` in ``protocol``, oldest first
        (e.g. a fipa-subscribe participant's subscribers)."""
        decl = self.role(channel, protocol)
        return [c for c in self._open.values() if c.decl == decl]

    # ---- the runtime's side -------------------------------------------------------------
    def answers_earlier_opening(self, sender: str, msg: Communicate) -> bool:
        """Whether ``msg`` from ``sender`` replies, in a conversation this agent opened (and
        has open), to a communicate it did not send in that opening: a reply to an earlier
        opening of the conversation-id, e.g. an update a_ta sent in a_km's subscription just
        before a_km restarted and subscribed again. Such a reply is late, not a violation."""
        decl = self._by_peer.get((self.host.spec.role_of(sender), msg.protocol or ""))
        conv = self._open.get((sender, msg.conversation_id or ""))
        return (
            decl is not None
            and decl.role == INITIATOR
            and conv is not None
            and conv.decl == decl
            and conv.answers_other(msg)
        )

    def not_understood_sent(self, peer: str, channel: str, about: Communicate, why: str) -> None:
        """This agent answered ``about`` from ``peer`` not-understood for ``why``, which ends
        its conversation (FIPA SC00037 §3.12). A conversation this agent opened there awaits
        no more: it stops waiting and ends through the agent's not-understood (else failure)
        handler (:attr:`Conversation.unreadable`, its reason ``why``), at once instead of at
        its reply-by deadline, or never when it has none (a_co's plan on C1)."""
        conv = self._open.get((peer, about.conversation_id or ""))
        if conv is None or conv.decl.role != INITIATOR:
            return
        conv.stop_awaiting_replies()
        ended = Communicate(
            performative=Performative.NOT_UNDERSTOOD,
            sender=about.sender,
            receiver=about.receiver,
            content=why.encode(),
            encoding="utf-8",
            protocol=about.protocol,
            conversation_id=about.conversation_id,
            in_reply_to=about.in_reply_to,  # what it answered: e.g. the answer to a cancel
        )
        self.host.x.append(Received.of(ended, None, channel, local=True))

    def take(self, item: Received) -> None:
        """Route one received communicate (already checked against the interface and the
        conversation's protocol state by the agent) to its conversation and handler: its
        role's :class:`RoleTable`, then :func:`route`."""
        msg = item.msg
        sender = item.sender
        table = self._tables.get((self.host.spec.role_of(sender), msg.protocol or ""))
        if table is None:  # outside every role: the interface check lets nothing through here
            self._no_role(item)
            return
        cid = msg.conversation_id or ""
        conv = self._open.get((sender, cid))
        way = route(table, conv, item, self._restored_openings)
        if way is _OPENS:
            conv = Conversation(self, table.decl, sender, cid, opening=item)
            self._keep(conv)
        elif way is _REPEATED:
            self._repeated(conv, item)
            return
        elif way is _ORPHAN:
            self._orphan(table.decl, item)
            return
        assert conv is not None
        self._hand(table, conv, item)

    def _no_role(self, item: Received) -> None:
        """``item`` belongs to none of the agent's roles: answered not-understood (unless the
        runtime made it)."""
        if not item.local:
            self.host.not_understood(
                item.sender, item.channel, f"no role for {item.msg.protocol or ''}", item.msg
            )

    def _hand(self, table: RoleTable, conv: Conversation, item: Received) -> None:
        """Hand ``item``, received in ``conv``, to its handler (:class:`RoleTable`); a
        subscription the role keeps takes the answers it acts on itself; a cancel with no
        handler is answered ``failure``; a passed deadline with none is logged. A fault in the
        handler must not stop the agent nor strand the peer (:meth:`_fault`)."""
        cancel = note(table, conv, item)
        if cancel:
            conv._cancel = item
        deadline = is_deadline(item)
        method = table.on_deadline if deadline else table.on_received.get(item.msg.performative)
        sub = self._kept_for(table.decl, conv)
        try:
            if sub is not None and not sub.take(conv):
                pass  # an answer the subscription's role acts on itself
            elif method is not None:
                getattr(self.agent, method)(conv)
            elif cancel:
                conv.refuse_with(Performative.FAILURE, "this conversation cannot be cancelled")
            elif deadline:
                self.host.log.info(
                    "reply-by deadline of %s in conversation %s with %s passed",
                    item.msg.in_reply_to,
                    item.msg.conversation_id or "",
                    item.sender,
                )
        except Exception as exc:  # a fault in a handler must not stop the agent nor strand the peer
            self._fault(table, conv, item, exc)
        finally:
            conv._cancel = None
        self.settle(conv)

    def _fault(self, table: RoleTable, conv: Conversation, item: Received, exc: Exception) -> None:
        """The handler of ``item`` raised ``exc``: logged and counted (``handler_errors``); a
        participant's peer gets ``failure`` with the reason instead of waiting for its
        deadline."""
        agent = self.host
        agent.counters["handler_errors"] += 1
        agent.log.exception(
            "handler of %s in conversation %s raised",
            item.msg.performative.value,
            item.msg.conversation_id or "",
        )
        if not table.initiator and not conv.finished and not item.local:
            self._fail_quietly(item, f"internal error: {type(exc).__name__}: {exc}")

    def _repeated(self, conv: Conversation | None, item: Received) -> None:
        """The opening of ``conv`` came again (FIPA SC00061 §2.4: the same reply-with from the
        same sender is the same communicate): e.g. a_hi's request retransmitted to an a_co that
        restarted meanwhile, or a_co's plan sent again to an a_ta that kept it; ``conv`` None:
        the opening of a conversation taken back after this agent's restart that has ended since
        (a_hi restarted too, before it heard the end, and sends its kept request again). It is
        not acted on twice: what this process answered it is published again (none after a
        restart: the peer hears the answers still to come), and it is counted
        (``repeated_requests``)."""
        reply_with = item.msg.reply_with
        if conv is not None:
            again = conv.answer_again(conv.opening.msg.reply_with if conv.opening is not None else None)
        else:
            again = self.publish_again(item.sender, reply_with)
        self.host.counters["repeated_requests"] += 1
        self.host.log.info(
            "%s from %s in conversation %s came again%s; not acted on twice (%d answer(s) sent again)",
            item.performative.value,
            item.sender,
            item.msg.conversation_id,
            "" if conv is not None else " after it ended",
            again,
        )

    def _fail_quietly(self, item: Received, reason: str) -> bool:
        """Answer ``item`` with ``failure`` and ``reason``; False when the conversation's state
        allows no failure (the peer is then left to its deadline)."""
        try:
            self.host.fail(item, Performative.FAILURE, reason)
        except SpecViolation:
            return False
        return True

    def _orphan(self, decl: RoleDecl, item: Received) -> None:
        """A communicate for a conversation this role does not have: a cancel of one that
        ended (answered ``failure`` when the state allows it), or a late reply (dropped)."""
        agent = self.host
        if item.local:
            return
        if decl.role == PARTICIPANT and item.performative is Performative.CANCEL:
            if not self._fail_quietly(item, "nothing to cancel: the conversation has ended"):
                agent.log.info("cancel of ended conversation %s left unanswered", item.msg.conversation_id)
            return
        if item.performative is Performative.NOT_UNDERSTOOD:
            return
        agent.counters["late_replies"] += 1
        agent.log.info(
            "%s from %s in conversation %s dropped: the conversation is no longer open",
            item.performative.value,
            item.sender,
            item.msg.conversation_id,
        )

    def _method(self, decl: RoleDecl, perf: Performative | None) -> str | None:
        key = handler_for(self._handlers.keys(), decl, perf)
        return self._handlers[key] if key is not None else None

    def _keep(self, conv: Conversation) -> None:
        if not conv._seq:
            conv._seq = next(self._taken_up)
        key = (conv.peer, conv.conversation_id)
        self._open.pop(key, None)
        self._open[key] = conv
        while len(self._open) > MAX_OPEN:
            self._open.popitem(last=False)

    def forget(self, conv: Conversation) -> None:
        if self._open.get((conv.peer, conv.conversation_id)) is conv:
            del self._open[(conv.peer, conv.conversation_id)]

    def remember(self, conv: Conversation) -> None:
        self._ended[conv.conversation_id] = conv.data
        while len(self._ended) > ENDED_KEPT:
            self._ended.popitem(last=False)

    def _taken_back(self, conv: Conversation) -> None:
        """``conv`` was taken back after a restart: a served subscription takes its stream (or
        will, once served); a participant's opening is remembered (:meth:`_repeated`)."""
        opening = conv.opening
        if conv.decl.role == PARTICIPANT and opening is not None and opening.msg.reply_with:
            self._restored_openings[(opening.sender, opening.msg.reply_with)] = None
            while len(self._restored_openings) > ENDED_KEPT:
                self._restored_openings.popitem(last=False)
        served = self._subscriptions.get((conv.decl, ""))
        if isinstance(served, ServedSubscription):
            served.taken_back(conv)
        elif (
            served is None
            and conv.decl.role == PARTICIPANT
            and streams(machine_of(self.host.spec, conv.decl.protocol))
        ):
            self._unserved[conv.decl] = conv  # its stream, served later, takes it (:meth:`serve`)

    def settle(self, conv: Conversation) -> None:
        """Forget a conversation that has ended, once nothing of it waits in the input
        buffer (the protocol state follows every communicate when it is acquired: the end
        may already be there while earlier communicates wait for their handlers)."""
        key = (conv.peer, conv.conversation_id)
        if self._open.get(key) is not conv or not conv.finished:
            return
        if any(i.sender == conv.peer and i.msg.conversation_id == conv.conversation_id for i in self.host.x):
            return
        del self._open[key]
        if conv.decl.resume_in is not None and conv.data is not None:
            self._held[conv._seq] = conv  # the agent still holds it: kept (:meth:`kept`)

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
        answering = to or conv.to_answer
        if (
            performative is Performative.INFORM
            and answering is not None
            and answering.performative is Performative.CANCEL
            and "cancelling" in machine_of(self.host.spec, conv.decl.protocol).states
        ):
            conv._cancelled = True  # the cancel meta-protocol: this inform says it is cancelled
        in_reply_to = answering.msg.reply_with if answering is not None and not answering.local else None
        reply_with = self.send_in(
            conv, performative, content, reply_by_s, retry_s, expect=False, in_reply_to=in_reply_to
        ).reply_with
        if in_reply_to is not None:
            conv.replied_to = in_reply_to
        return reply_with

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
        msg = self.host.send(
            conv.peer,
            performative,
            content,
            protocol=conv.decl.protocol,
            conversation_id=conv.conversation_id or None,
            # every communicate of a role can be answered unambiguously, and two of them are
            # never byte-identical (a copy is what a receiver drops: services/runtime/dedup.py)
            reply_with=self.host.sources.new_id(f"{self.host.name}-"),
            in_reply_to=in_reply_to,
            reply_by_s=reply_by_s,
            expect_reply=expect,
            retry_s=retry_s,
        )
        if not conv.conversation_id:
            conv.conversation_id = msg.conversation_id or ""
        return msg

    def __iter__(self) -> Iterator[Conversation]:
        return iter(list(self._open.values()))

    # ---- what a conversation asks of its roles (:class:`ConversationHost`) -------------------
    def fail(self, to: Received, performative: Performative, reason: str) -> None:
        """Answer ``to`` with ``refuse`` or ``failure`` carrying ``reason`` (the agent's
        ``fail``; raises SpecViolation when the state does not allow it)."""
        self.host.fail(to, performative, reason)

    def stop_awaiting_replies(self, conversation_id: str) -> None:
        """No more reply-by deadlines nor retransmissions in ``conversation_id``
        (services/runtime/replies.py)."""
        self.host.pending_replies.forget_conversation(conversation_id)

    def protocol_state(self, peer: str, conversation_id: str) -> str | None:
        """The protocol state of the conversation with ``peer`` (services/runtime/protocol_state.py),
        None before its first communicate."""
        tracker = self.host.protocol_states.get(peer, conversation_id)
        return None if tracker is None else tracker.state

    def protocol_finished(self, peer: str, conversation_id: str) -> bool:
        """The conversation with ``peer`` reached a final state of its protocol."""
        tracker = self.host.protocol_states.get(peer, conversation_id)
        return tracker is not None and tracker.is_finished

    def publish_again(self, peer: str, in_reply_to: str | None) -> int:
        """Publish again, byte for byte, what this agent answered ``peer``'s ``in_reply_to``
        (services/runtime/dedup.py); returns how many."""
        again = self.host.dedup.answers(peer, in_reply_to)
        for key, payload in again:
            self.host.emit(key, payload)
        return len(again)


def _answered(machine: Protocol, opening: Performative) -> bool:
    """Whether the initiator's ``opening`` leaves the conversation open for an answer: not
    when it ends it (the inform of a one-message protocol), which then awaits nothing."""
    return machine.next_state(machine.initial, INITIATOR, opening) not in machine.final


def _default(given: float | None, role: float | None, answered: bool) -> float | None:
    """A wait (s) of an opening: the one ``given``, else the ``role``'s; none when nothing
    answers the opening."""
    if not answered:
        return None
    return given if given is not None else role
