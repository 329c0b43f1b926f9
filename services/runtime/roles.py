"""Protocol roles built from the specification's state machines (paper §4 step 3, §5.4;
FIPA SC00025 interaction protocol library; issue 17).

An agent declares the roles it plays, one :class:`RoleDecl` per (channel, interaction
protocol): initiator or participant, and the content languages it speaks there. It writes one
*handler* per performative the other role may send (:func:`handles`), and nothing else of the
protocol. The runtime's :class:`Roles` — the same code for every protocol, driven by the
protocol's state machine in the specification (``[protocols.NAME]``, or the built-in FIPA
machine of :mod:`shared.fipa_codec.protocols`) — owns what the protocol implies:

- routing each received communicate to its conversation and its handler (no agent compares
  performatives: the role does, from the machine's transitions);
- reply-with / in-reply-to / conversation-id of every communicate a conversation sends
  (:meth:`Conversation.reply`, :meth:`Conversation.send`);
- reply-by deadlines (a passed deadline reaches the initiator's ``failure`` handler with
  :attr:`Conversation.timed_out`), retransmission until the first answer (``retry_s``);
  duplicate communicates are dropped and the answers already sent published again
  (services/runtime/dedup.py);
- ``cancel`` (FIPA SC00026 §2 cancel meta-protocol): a participant's ``cancel`` handler is
  optional; without one, or once the conversation has ended, the role answers ``failure``
  with the reason;
- ``not-understood``: it ends the conversation; an initiator's conversation ends through its
  ``failure`` handler (:attr:`Conversation.not_understood`) unless the agent handles
  ``not-understood`` itself;
- ``agree`` (to an initiator) is noted on the conversation (:attr:`Conversation.agreed`);
  a handler for it is optional;
- a reply to a conversation the role no longer has (it timed out, or the agent restarted) is
  counted (``late_replies``) and dropped.

What each declaration and handler must be is derived from the specification
(:func:`role_problems`): at start an agent whose declared roles or handlers differ from its
interface in the specification refuses to start, with one line naming the spec entry; ``roco
spec verify-code`` runs the same comparison for every agent without starting it.
"""

from __future__ import annotations

import inspect
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import msgspec

from services.runtime.code_scan import findings_text, scan
from services.spec.model import ChannelSpec, SpecError, SystemSpec
from services.spec.protocol_defs import machine_of
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, Protocol, Role

if TYPE_CHECKING:
    from services.runtime.agent import Agent, Received

__all__ = [
    "INITIATOR",
    "PARTICIPANT",
    "Conversation",
    "HandlerKey",
    "RoleDecl",
    "RoleMismatch",
    "Roles",
    "agent_problems",
    "code_problems",
    "handlers_of",
    "handles",
    "initiator",
    "participant",
    "role_problems",
    "spec_roles",
]


def optional(machine: Protocol, role: Role) -> frozenset[Performative]:
    """Performatives a role handles by itself when the agent writes no handler for them (see
    the module docstring): ``not-understood``; ``agree`` to an initiator; ``cancel`` to a
    participant where the machine follows the cancel meta-protocol (a ``cancelling`` state;
    coordinate's cancel is a request of its own, paper §5.4). Every other performative the
    peer may send needs a handler."""
    out = {Performative.NOT_UNDERSTOOD}
    if role == INITIATOR:
        out.add(Performative.AGREE)
    elif "cancelling" in machine.states:
        out.add(Performative.CANCEL)
    return frozenset(out)


MAX_OPEN = 1024
"""Open conversations a :class:`Roles` keeps before it forgets the oldest (bounded memory)."""


class RoleMismatch(SpecError):
    """An agent's declared roles or handlers differ from its interface in the specification."""


@dataclass(frozen=True)
class RoleDecl:
    """An agent plays ``role`` (initiator or participant) of interaction ``protocol`` on
    ``channel`` (C1..C6), speaking content ``languages`` there (every language the
    specification gives that channel's protocol). ``reply_by_s`` (s) and ``retry_s`` (s) are
    the defaults of the conversations this role opens (initiators only): the reply-by deadline
    and the retransmission period until the first answer (None: none)."""

    channel: str
    protocol: str
    role: Role
    languages: tuple[str, ...]
    reply_by_s: float | None = None
    retry_s: float | None = None

    def __str__(self) -> str:
        return f"{self.role} of {self.protocol} on {self.channel} ({', '.join(self.languages)})"


def initiator(
    channel: str,
    protocol: str,
    *languages: str,
    reply_by_s: float | None = None,
    retry_s: float | None = None,
) -> RoleDecl:
    """The initiator role of ``protocol`` on ``channel``, in ``languages``."""
    return RoleDecl(channel, protocol, INITIATOR, tuple(languages), reply_by_s, retry_s)


def participant(channel: str, protocol: str, *languages: str) -> RoleDecl:
    """The participant role of ``protocol`` on ``channel``, in ``languages``."""
    return RoleDecl(channel, protocol, PARTICIPANT, tuple(languages))


@dataclass(frozen=True)
class HandlerKey:
    """What a handler handles: ``performative`` received in ``protocol`` while the agent
    plays ``role``; ``channel`` None: on every channel where it plays that role."""

    protocol: str
    role: Role
    performative: Performative
    channel: str | None = None

    def __str__(self) -> str:
        where = f" on {self.channel}" if self.channel else ""
        return f"{self.performative.value} received as {self.role} of {self.protocol}{where}"


Handler = Callable[[Any, "Conversation"], None]
F = TypeVar("F", bound=Callable[..., None])
_MARK = "__roco_handles__"


def handles(protocol: str, role: Role, *performatives: str, channel: str | None = None) -> Callable[[F], F]:
    """Mark an agent method ``method(self, conversation)`` as the handler of ``performatives``
    received in ``protocol`` while the agent plays ``role`` (on ``channel``, or on every
    channel where it plays that role). Raises ValueError for a name that is not a FIPA
    performative (FIPA SC00037)."""
    keys = []
    for name in performatives:
        try:
            keys.append(HandlerKey(protocol, role, Performative(name), channel))
        except ValueError:
            raise ValueError(f"{name!r} is not a FIPA performative (FIPA SC00037)") from None

    def mark(fn: F) -> F:
        setattr(fn, _MARK, (*getattr(fn, _MARK, ()), *keys))
        return fn

    return mark


def handlers_of(cls: type) -> dict[HandlerKey, str]:
    """Every handler of an agent class: key → method name. Raises RoleMismatch when two
    methods handle the same key."""
    out: dict[HandlerKey, str] = {}
    for name in dir(cls):
        fn = getattr(cls, name, None)
        for key in getattr(fn, _MARK, ()):
            if key in out and out[key] != name:
                raise RoleMismatch(f"{cls.__name__}: {out[key]} and {name} both handle {key}")
            out[key] = name
    return out


# ---------------------------------------------------------------------------------------------
# The comparison with the specification


def spec_roles(spec: SystemSpec, agent: str) -> list[RoleDecl]:
    """The roles the specification gives ``agent``: per channel it ends and protocol of that
    channel, initiator or participant, with every language the channel gives the protocol
    (paper §4 step 4, the agent's interface)."""
    out = []
    for ch in spec.channels:
        if agent not in ch.ends:
            continue
        for cp in ch.protocols:
            role: Role = INITIATOR if cp.initiator == agent else PARTICIPANT
            out.append(RoleDecl(ch.name, cp.protocol, role, _languages(ch, cp.protocol)))
    return out


def _languages(ch: ChannelSpec, protocol: str) -> tuple[str, ...]:
    names: list[str] = []
    for cp in ch.protocols:
        if cp.protocol == protocol:
            for value in cp.languages.values():
                for lang in (value,) if isinstance(value, str) else value:
                    if lang not in names:
                        names.append(lang)
    return tuple(sorted(names))


def incoming(machine: Protocol, role: Role) -> frozenset[Performative]:
    """The performatives the other role may send in ``machine`` (not-understood included)."""
    other = PARTICIPANT if role == INITIATOR else INITIATOR
    out = {p for (_, r, p) in [*machine.transitions, *machine.terminal_transitions] if r == other}
    return frozenset(out | {Performative.NOT_UNDERSTOOD})


def outgoing(machine: Protocol, role: Role) -> frozenset[Performative]:
    """The performatives ``role`` may send in ``machine`` (not-understood included)."""
    out = {p for (_, r, p) in [*machine.transitions, *machine.terminal_transitions] if r == role}
    return frozenset(out | {Performative.NOT_UNDERSTOOD})


def role_problems(
    spec: SystemSpec, agent: str, declared: Sequence[RoleDecl], handlers: Iterable[HandlerKey]
) -> list[str]:
    """Where ``agent``'s declared roles and handlers differ from the specification, one line
    each, naming the spec entry: a role the spec gives it that it does not declare, a role it
    declares that the spec does not give it (no such channel, the agent does not end it, the
    protocol is not on it, or the spec gives it the other role), languages other than the
    channel's, a performative the other role may send with no handler, and a handler for
    something no declared role receives. Empty: they agree."""
    where = f"agent {agent}"
    want = {(r.channel, r.protocol): r for r in spec_roles(spec, agent)}
    channels = {ch.name: ch for ch in spec.channels}
    problems: list[str] = []
    seen: set[tuple[str, str]] = set()
    for decl in declared:
        key = (decl.channel, decl.protocol)
        entry = f"[[channels]] {decl.channel}"
        if key in seen:
            problems.append(f"{where} declares {decl.protocol} on {decl.channel} twice")
            continue
        seen.add(key)
        ch = channels.get(decl.channel)
        if ch is None:
            problems.append(f"{where} declares {decl}, but the specification has no channel {decl.channel}")
        elif agent not in ch.ends:
            problems.append(
                f"{where} declares {decl}, but {entry} joins {' and '.join(ch.ends)}: no channel "
                f"between {agent} and its peer there"
            )
        elif key not in want:
            problems.append(f"{where} declares {decl}, but {entry} carries no protocol {decl.protocol}")
        elif want[key].role != decl.role:
            problems.append(
                f"{where} declares itself {decl.role} of {decl.protocol} on {decl.channel}, but "
                f"{entry} makes it the {want[key].role}"
            )
        elif tuple(sorted(decl.languages)) != want[key].languages:
            problems.append(
                f"{where}: its {decl.protocol} role on {decl.channel} speaks "
                f"{', '.join(decl.languages) or 'no language'}, but {entry} carries "
                f"{', '.join(want[key].languages)} there"
            )
    for key, role in want.items():
        if key not in seen:
            problems.append(f"{where} declares no role for {role}: {role.role} by [[channels]] {key[0]}")
    handlers = list(handlers)
    valid = [d for d in declared if want.get((d.channel, d.protocol)) == _normal(d)]
    for decl in valid:
        machine = machine_of(spec, decl.protocol)
        for perf in sorted(
            incoming(machine, decl.role) - optional(machine, decl.role), key=lambda p: p.value
        ):
            if _handler_for(handlers, decl, perf) is None:
                problems.append(
                    f"{where} has no handler for {perf.value} received as {decl.role} of "
                    f"{decl.protocol} on {decl.channel} (the state machine of [protocols.{decl.protocol}] "
                    f"lets the {_other(decl.role)} send it)"
                )
    for h in handlers:
        if not any(
            h.protocol == d.protocol
            and h.role == d.role
            and h.channel in (None, d.channel)
            and h.performative in incoming(machine_of(spec, d.protocol), d.role)
            for d in valid
        ):
            problems.append(f"{where} has a handler for {h}, which no role it declares receives")
    return problems


def code_problems(
    spec: SystemSpec, agent: str, declared: Sequence[RoleDecl], files: Iterable[Path]
) -> list[str]:
    """What in ``files`` (an agent's code) sends outside its declared roles, compares a
    performative, names a performative none of its roles may send, or opens a conversation
    where it is not the initiator (services/runtime/code_scan.py), one line each."""
    may_send: set[Performative] = set()
    for decl in declared:
        if decl.protocol in spec.protocols:
            may_send |= outgoing(machine_of(spec, decl.protocol), decl.role)
    opens = frozenset((d.channel, d.protocol) for d in declared if d.role == INITIATOR)
    return findings_text(scan(files, frozenset(may_send), opens), agent)


def agent_problems(spec: SystemSpec, agent: str, cls: type, files: Iterable[Path] | None = None) -> list[str]:
    """Every way agent class ``cls`` differs from agent ``agent``'s interface in ``spec``:
    its roles and handlers (:func:`role_problems`) and its code (:func:`code_problems`; the
    module of the class that declares ``ROLES`` unless ``files`` are given). A class that declares no roles
    (``ROLES`` None) is one problem."""
    declared = getattr(cls, "ROLES", None)
    if declared is None:
        return [f"agent {agent}: {cls.__name__} declares no protocol roles (ROLES)"]
    problems = role_problems(spec, agent, declared, handlers_of(cls))
    if files is None:
        owner = next(c for c in cls.__mro__ if "ROLES" in vars(c))
        source = inspect.getsourcefile(owner)
        files = [Path(source)] if source is not None else []
    return problems + code_problems(spec, agent, declared, files)


def _normal(decl: RoleDecl) -> RoleDecl:
    return RoleDecl(decl.channel, decl.protocol, decl.role, tuple(sorted(decl.languages)))


def _other(role: Role) -> Role:
    return PARTICIPANT if role == INITIATOR else INITIATOR


def _handler_for(handlers: Sequence[HandlerKey], decl: RoleDecl, perf: Performative) -> HandlerKey | None:
    """The handler of ``perf`` for ``decl``: a channel's own before one for every channel."""
    for channel in (decl.channel, None):
        key = HandlerKey(decl.protocol, decl.role, perf, channel)
        if key in handlers:
            return key
    return None


# ---------------------------------------------------------------------------------------------
# Conversations and the roles at run time


@dataclass(eq=False)
class Conversation:
    """One conversation a role of this agent takes part in.

    ``decl`` is the role, ``peer`` the other agent, ``conversation_id`` the FIPA
    conversation-id; ``last`` the latest communicate received in it (None before the first);
    ``data`` whatever the agent attaches (e.g. what a query was about). Replies and further
    communicates go through :meth:`reply`, :meth:`refuse_with`, :meth:`send` and
    :meth:`cancel`, which the protocol's state machine checks (SpecViolation)."""

    roles: Roles = field(repr=False)
    decl: RoleDecl
    peer: str
    conversation_id: str
    last: Received | None = None
    opening: Received | None = None
    """The communicate that opened the conversation, when the peer opened it (participant)."""
    data: Any = None
    reply_with: str | None = None
    """The reply-with of this agent's latest communicate awaiting a reply (initiator)."""
    agreed: bool = False
    """The participant agreed (fipa-request, fipa-query, fipa-subscribe)."""
    awaited: set[str] = field(default_factory=set, repr=False)
    """The reply-with of every communicate this agent sent in it expecting a reply."""

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
    def timed_out(self) -> bool:
        """The reply-by deadline passed before the peer answered (the runtime ended it)."""
        return self.last is not None and self.last.local

    @property
    def not_understood(self) -> bool:
        """The peer answered ``not-understood``."""
        return self.last is not None and self.last.performative is Performative.NOT_UNDERSTOOD

    @property
    def answered(self) -> bool:
        """The peer's latest communicate is an answer with content (not a refusal, failure or
        the runtime's deadline)."""
        return self.last is not None and not self.last.local and self.last.content is not None

    @property
    def finished(self) -> bool:
        """The conversation has reached a final state of its protocol (or a not-understood
        ended it)."""
        tracker = self.roles.agent.protocol_states.get(self.peer, self.conversation_id)
        return tracker is not None and tracker.is_finished

    def reply(self, performative: Performative, content: msgspec.Struct | None = None) -> None:
        """Answer the latest communicate received (in-reply-to its reply-with). Raises
        SpecViolation when the role or the conversation's state does not allow it."""
        self._sent(self.roles._reply(self, performative, content))

    def refuse_with(self, performative: Performative, reason: str) -> None:
        """Answer the latest communicate with ``refuse`` or ``failure`` whose content is
        ``reason`` as UTF-8 text (FIPA SC00037: a reason a person can read)."""
        assert self.last is not None, "nothing received to answer"
        self.roles.agent.fail(self.last, performative, reason)
        self.roles._settle(self)

    def send(
        self,
        performative: Performative,
        content: msgspec.Struct | None = None,
        *,
        reply_by_s: float | None = None,
        retry_s: float | None = None,
    ) -> None:
        """Send a further communicate of this conversation (e.g. coordinate's ``confirm``),
        in reply to the latest received, expecting a reply when the protocol lets the peer
        answer it."""
        self._sent(self.roles._reply(self, performative, content, reply_by_s=reply_by_s, retry_s=retry_s))

    def cancel(self, content: msgspec.Struct | None = None) -> None:
        """The initiator cancels the conversation (FIPA SC00026 §2 cancel meta-protocol)."""
        self.roles.agent.conversations.forget_conversation(self.conversation_id)
        self._sent(self.roles._open_send(self, Performative.CANCEL, content, None, None, expect=True))

    def _sent(self, reply_with: str | None) -> None:
        if reply_with is not None:
            self.reply_with = reply_with
            self.awaited.add(reply_with)
        self.roles._settle(self)


class Roles:
    """The protocol roles of one agent at run time: its declarations, its handlers, the
    conversations open in each role. Built by :class:`~services.runtime.agent.Agent` from its
    class's ``roles`` and :func:`handles` methods; raises RoleMismatch (one line) when they
    differ from the specification (:func:`role_problems`)."""

    def __init__(self, agent: Agent, declared: Sequence[RoleDecl], *, check: bool = True) -> None:
        self.agent = agent
        self.declared = tuple(declared)
        self._handlers = handlers_of(type(agent))
        problems = agent_problems(agent.spec, agent.name, type(agent)) if check else []
        if problems:
            more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
            raise RoleMismatch(problems[0] + more)
        self._by_peer: dict[tuple[str, str], RoleDecl] = {}
        channels = {ch.name: ch for ch in agent.spec.channels}
        for decl in self.declared:
            ends = channels[decl.channel].ends
            peer = ends[1] if ends[0] == agent.name else ends[0]
            self._by_peer[(peer, decl.protocol)] = decl
        self._peer_of = {decl: peer for (peer, _), decl in self._by_peer.items()}
        self._open: OrderedDict[tuple[str, str], Conversation] = OrderedDict()

    # ---- the agent's side ---------------------------------------------------------------
    def role(self, channel: str, protocol: str) -> RoleDecl:
        """The declared role on ``channel`` in ``protocol``; KeyError when none."""
        for decl in self.declared:
            if decl.channel == channel and decl.protocol == protocol:
                return decl
        raise KeyError(f"{self.agent.name} declares no {protocol} role on {channel}")

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
        carrying ``content``. ``reply_by_s``/``retry_s`` default to the role's. Raises KeyError
        for a role not declared, SpecViolation for a performative that does not open the
        protocol."""
        decl = self.role(channel, protocol)
        if decl.role != INITIATOR:
            raise KeyError(
                f"{self.agent.name} is the participant of {protocol} on {channel}, not the initiator"
            )
        machine = machine_of(self.agent.spec, protocol)
        openers = sorted(
            (p for (s, r, p) in machine.transitions if s == machine.initial and r == INITIATOR),
            key=lambda p: p.value,
        )
        perf = performative or (openers[0] if len(openers) == 1 else None)
        if perf is None:
            raise ValueError(f"{protocol} opens with {' or '.join(p.value for p in openers)}: name one")
        conv = Conversation(self, decl, self._peer_of[decl], conversation_id or "", data=data)
        conv.reply_with = self._open_send(
            conv,
            perf,
            content,
            reply_by_s if reply_by_s is not None else decl.reply_by_s,
            retry_s if retry_s is not None else decl.retry_s,
            expect=True,
        )
        if conv.reply_with is not None:
            conv.awaited.add(conv.reply_with)
        self._keep(conv)
        return conv

    def conversations(self, channel: str, protocol: str) -> list[Conversation]:
        """The open conversations of the role on ``channel`` in ``protocol``, oldest first
        (e.g. a fipa-subscribe participant's subscribers)."""
        decl = self.role(channel, protocol)
        return [c for c in self._open.values() if c.decl == decl]

    # ---- the runtime's side -------------------------------------------------------------
    def take(self, item: Received) -> None:
        """Route one received communicate (already checked against the interface and the
        conversation's protocol state by the agent) to its conversation and handler."""
        agent = self.agent
        protocol = item.msg.protocol or ""
        decl = self._by_peer.get((item.sender, protocol))
        cid = item.msg.conversation_id or ""
        if decl is None:  # outside every role: the interface check lets nothing through here
            if not item.local:
                agent.not_understood(item.sender, item.channel, f"no role for {protocol}", item.msg)
            return
        perf = item.performative
        conv = self._open.get((item.sender, cid))
        machine = machine_of(agent.spec, protocol)
        if decl.role == PARTICIPANT and _opens(machine, perf):
            conv = Conversation(self, decl, item.sender, cid, opening=item)
            self._keep(conv)
        stale = (
            conv is not None
            and decl.role == INITIATOR
            and item.msg.in_reply_to is not None
            and item.msg.in_reply_to not in conv.awaited
        )
        if conv is None or stale:  # a reply to an earlier opening of a reused conversation-id
            self._orphan(decl, item)
            return
        conv.last = item
        if perf is Performative.AGREE and decl.role == INITIATOR:
            conv.agreed = True
        method = self._method(decl, perf)
        if method is None and perf is Performative.NOT_UNDERSTOOD and decl.role == INITIATOR:
            method = self._method(decl, Performative.FAILURE)
        before = conv.last if perf is Performative.CANCEL and decl.role == PARTICIPANT else None
        try:
            if method is not None:
                getattr(agent, method)(conv)
            elif perf is Performative.CANCEL:
                conv.refuse_with(Performative.FAILURE, "this conversation cannot be cancelled")
        except Exception as exc:  # a fault in a handler must not stop the agent nor strand the peer
            agent.counters["handler_errors"] += 1
            agent.log.exception("handler of %s in conversation %s raised", perf.value, cid)
            if decl.role == PARTICIPANT and not conv.finished and not item.local:
                self._fail_quietly(item, f"internal error: {type(exc).__name__}: {exc}")
        if before is not None:  # the cancel is answered: what comes next answers the request
            conv.last = before
        self._settle(conv)

    def _fail_quietly(self, item: Received, reason: str) -> bool:
        """Answer ``item`` with ``failure`` and ``reason``; False when the conversation's state
        allows no failure (the peer is then left to its deadline)."""
        from services.runtime.agent import SpecViolation

        try:
            self.agent.fail(item, Performative.FAILURE, reason)
        except SpecViolation:
            return False
        return True

    def _orphan(self, decl: RoleDecl, item: Received) -> None:
        """A communicate for a conversation this role does not have: a cancel of one that
        ended (answered ``failure`` when the state allows it), or a late reply (dropped)."""
        agent = self.agent
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

    def _method(self, decl: RoleDecl, perf: Performative) -> str | None:
        key = _handler_for(list(self._handlers), decl, perf)
        return self._handlers[key] if key is not None else None

    def _keep(self, conv: Conversation) -> None:
        key = (conv.peer, conv.conversation_id)
        self._open.pop(key, None)
        self._open[key] = conv
        while len(self._open) > MAX_OPEN:
            self._open.popitem(last=False)

    def _settle(self, conv: Conversation) -> None:
        """Forget a conversation that has ended."""
        if conv.finished:
            existing = self._open.get((conv.peer, conv.conversation_id))
            if existing is conv:
                del self._open[(conv.peer, conv.conversation_id)]

    def _reply(
        self,
        conv: Conversation,
        performative: Performative,
        content: msgspec.Struct | None,
        *,
        reply_by_s: float | None = None,
        retry_s: float | None = None,
    ) -> str | None:
        machine = machine_of(self.agent.spec, conv.decl.protocol)
        expect = bool(incoming_after(machine, conv.decl.role, performative))
        return self._open_send(conv, performative, content, reply_by_s, retry_s, expect=expect)

    def _open_send(
        self,
        conv: Conversation,
        performative: Performative,
        content: msgspec.Struct | None,
        reply_by_s: float | None,
        retry_s: float | None,
        *,
        expect: bool,
    ) -> str | None:
        last = conv.last
        msg = self.agent.send(
            conv.peer,
            performative,
            content,
            protocol=conv.decl.protocol,
            conversation_id=conv.conversation_id or None,
            in_reply_to=last.msg.reply_with if last is not None and not last.local else None,
            reply_by_s=reply_by_s,
            expect_reply=expect,
            retry_s=retry_s,
        )
        if not conv.conversation_id:
            conv.conversation_id = msg.conversation_id or ""
        return msg.reply_with

    def __iter__(self) -> Iterator[Conversation]:
        return iter(list(self._open.values()))


def _opens(machine: Protocol, perf: Performative) -> bool:
    return machine.next_state(machine.initial, INITIATOR, perf) is not None


def incoming_after(machine: Protocol, role: Role, performative: Performative) -> frozenset[Performative]:
    """What the other role may send after ``role`` sent ``performative`` in some state of
    ``machine``, cancel and not-understood left out (empty: no reply is awaited)."""
    other = _other(role)
    edges = [*machine.transitions.items(), *machine.terminal_transitions.items()]
    targets = {t for (_, r, p), t in edges if r == role and p is performative}
    return frozenset(
        p
        for (s, r, p), _ in edges
        if s in targets and r == other and p not in (Performative.NOT_UNDERSTOOD, Performative.CANCEL)
    )
