"""Protocol roles built from the specification's state machines (paper §4 step 3, §5.4;
FIPA SC00025 interaction protocol library; docs/spec.md, "Protocol roles").

An agent declares the roles it plays, one :class:`RoleDecl` per (channel, interaction
protocol): initiator or participant, and the content languages it speaks there, each named as
services/spec/names.py names it (``participant(C5, FIPA_REQUEST, L_EX, L_SD)``; generated from
the specification, services/spec/render_names.py). A role declared on :data:`EVERY_CHANNEL`
stands for one such role on every channel where the specification gives the agent that role of
that protocol in exactly those languages (:func:`expand_roles`): an agent that answers the same
queries wherever they come from serves a channel added to the specification later without an
edit of its code. It writes one *handler* per performative the other role may send
(:func:`handles`: ``@handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)``), and nothing
else of the protocol. The runtime's :class:`Roles` — the same code for every protocol, driven
by the protocol's state machine in the specification (``[protocols.NAME]``, or the built-in
FIPA machine of :mod:`shared.fipa_codec.protocols`) — owns what the protocol implies:

- routing each received communicate to its conversation and its handler (no agent compares
  performatives: the role does, from the machine's transitions);
- reply-with / in-reply-to / conversation-id of every communicate a conversation sends
  (:meth:`Conversation.reply`, :meth:`Conversation.send`);
- reply-by deadlines (a passed deadline reaches the initiator's ``failure`` handler with
  :attr:`Conversation.timed_out`, or an :func:`on_deadline` handler), retransmission until the
  first answer (``retry_s``); duplicate communicates are dropped and the answers already sent
  published again (services/runtime/dedup.py); every communicate a role sends carries a fresh
  reply-with, so that answers name what they answer and no two are byte-identical;
- ``cancel`` (FIPA SC00026 §2 cancel meta-protocol): a participant's ``cancel`` handler is
  optional; without one, or once the conversation has ended, the role answers ``failure``
  with the reason; the cancel's answer answers the cancel (:attr:`Conversation.answering`,
  or later :meth:`Conversation.answer_cancel`), and its ``inform`` ends the conversation
  (:attr:`Conversation.answers_cancel`);
- ``not-understood``: it ends the conversation; an initiator's conversation ends through its
  ``failure`` handler (:attr:`Conversation.not_understood`) unless the agent handles
  ``not-understood`` itself, also when the initiator sent it (:attr:`Conversation.unreadable`:
  an answer it could not read);
- ``agree`` (to an initiator) is noted on the conversation (:attr:`Conversation.agreed`);
  a handler for it is optional;
- a fault in a handler is logged and counted (``handler_errors``); a participant's peer gets
  ``failure`` with the reason instead of waiting for its deadline;
- a reply in a conversation the role no longer has (abandoned, or from before a restart) is
  counted (``late_replies``) and dropped;
- the opening of an open conversation again (the same reply-with from the same sender, FIPA
  SC00061 §2.4: a retransmission that reached a restarted agent, or a copy that is not
  byte-identical) is not handed to the agent: the participant role publishes again what the
  conversation answered it and counts it (``repeated_requests``);
- a fipa-subscribe initiator role declared ``resubscribes`` keeps its subscription open
  (:meth:`Roles.subscribe`, services/runtime/subscriptions.py): it subscribes when the peer's
  token appears and again after a refusal, failure or passed deadline, with a back-off, and
  when the peer comes back; the agent handles the stream's informs only;
- a fipa-subscribe participant role whose stream the agent has it serve (:meth:`Roles.serve`,
  services/runtime/served.py) informs the latest agreed subscription, keeps (bounded) what is
  informed while none is and sends it after the next agree, answers ``cancel`` and ends the
  subscription on ``not-understood``; the agent's ``subscribe`` handler only agrees or refuses;
- conversations the agent ended and asked it to remember (``abandon(remember=True)``): their
  data for what is said of them later (:meth:`Roles.ended`), their conversation-ids not chosen
  again (:meth:`Roles.free_id`);
- the conversation's state across a restart: :meth:`Conversation.keep` gives the
  communicate that opened it, :meth:`Roles.restore` takes it back in the state the agent
  names (and waits again for an unanswered opening of its own); a role declared with ``keep``
  has the runtime do it for each of its open conversations, with the agent's data of it
  (:meth:`Roles.kept`, :meth:`Roles.take_back`; the agent gets each back in
  ``on_restored(conversation)``, services/runtime/agent.py); a participant role declared
  ``resume_in`` takes each back in that protocol state, and keeps it while the agent's data of
  it is set, even once it has ended (:attr:`RoleDecl.resume_in`).

An initiator role the specification gives an agent but in which it opens no conversation is
declared ``unused`` (:func:`initiator`); it needs no handlers. To act on a timer (open a
conversation every few seconds), an agent uses a periodic behaviour
(services/runtime/behaviour.py :func:`~services.runtime.behaviour.periodic`).

What each declaration and handler must be is derived from the specification
(:func:`role_problems`): at start an agent whose declared roles or handlers differ from its
interface in the specification refuses to start, with one line naming the spec entry; ``roco
spec verify-code`` runs the same comparison for every agent without starting it.
"""

from __future__ import annotations

import enum
import inspect
import itertools
from collections import OrderedDict
from collections.abc import Callable, Collection, Container, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import msgspec

from services.runtime import keys
from services.runtime.code_scan import findings_text, scan
from services.spec.model import ChannelSpec, SpecError, SystemSpec
from services.spec.names import FIPA_QUERY
from services.spec.protocol_defs import machine_of, streams
from services.spec.render_names import spellings
from shared.fipa_codec import Communicate, DecodeError, decode, encode
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.languages import ContentError, decode_content
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, Protocol, Role

if TYPE_CHECKING:
    from services.runtime.agent import Agent, Received
    from services.runtime.served import ServedSubscription
    from services.runtime.state_store import KeptConversations
    from services.runtime.subscriptions import StandingSubscription

__all__ = [
    "EVERY_CHANNEL",
    "INITIATOR",
    "PARTICIPANT",
    "Conversation",
    "HandlerKey",
    "RestoreError",
    "RoleDecl",
    "RoleMismatch",
    "Roles",
    "agent_problems",
    "code_problems",
    "expand_roles",
    "handlers_of",
    "handles",
    "initiator",
    "on_deadline",
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


EVERY_CHANNEL = "*"
"""The channel of a role declared for every channel the specification gives the agent with its
protocol, role and languages (:func:`expand_roles`)."""

MAX_OPEN = 1024
"""Open conversations a :class:`Roles` keeps before it forgets the oldest (bounded memory)."""
ENDED_KEPT = 256
"""Ended conversations a :class:`Roles` remembers when asked to (:meth:`Conversation.abandon`
with ``remember``), the oldest forgotten first."""


class RoleMismatch(SpecError):
    """An agent's declared roles or handlers differ from its interface in the specification."""


class RestoreError(ValueError):
    """A conversation kept across a restart cannot be taken back (see :meth:`Roles.restore`)."""


@dataclass(frozen=True)
class RoleDecl:
    """An agent plays ``role`` (initiator or participant) of interaction ``protocol`` on
    ``channel`` (C1..C8, or :data:`EVERY_CHANNEL`), speaking content ``languages`` there (every
    language the specification gives that channel's protocol). ``reply_by_s`` (s) and ``retry_s`` (s) are
    the defaults of the conversations this role opens (initiators only): the reply-by deadline
    and the retransmission period until the first answer (None: none)."""

    channel: str
    protocol: str
    role: Role
    languages: tuple[str, ...]
    reply_by_s: float | None = None
    retry_s: float | None = None
    unused: bool = False
    """An initiator role the specification gives the agent but in which it opens no
    conversation: it needs no handlers, and ``self.roles.open`` refuses it."""
    keep: bool | type[msgspec.Struct] = False
    """The role keeps its open conversations across a restart of the agent (docs/recovery.md,
    :meth:`Roles.kept`, :meth:`Roles.take_back`); a msgspec Struct type: with the agent's
    data of each (:attr:`Conversation.data`, an instance of it)."""
    resubscribes: bool = False
    """A fipa-subscribe initiator role that keeps its subscription open itself
    (:meth:`Roles.subscribe`, services/runtime/subscriptions.py): it handles ``agree``,
    ``refuse`` and ``failure``; the agent handles the stream's ``inform``\\s only."""
    resume_in: str | None = None
    """A participant role declared with ``keep`` takes each kept conversation back in this
    state of its protocol's state machine, whatever state it was kept in (e.g. a_ta's plan in
    coordinate's ``running``: it reports its outcome again, which ``ending`` does not allow);
    and it keeps a conversation for as long as the agent's data of it is set, even once it has
    ended (a not-understood ended a_ta's plan conversation while a_ta still runs the plan).
    None: taken back in the state it was kept in, and kept while open. Checked against the
    protocol's states when the agent starts (:func:`role_problems`)."""

    def __post_init__(self) -> None:
        if self.resume_in is not None and (self.role != PARTICIPANT or not self.keep):
            raise ValueError(f"{self}: resume_in is for a participant role declared with keep")

    def __str__(self) -> str:
        where = "every channel" if self.channel == EVERY_CHANNEL else self.channel
        return f"{self.role} of {self.protocol} on {where} ({', '.join(self.languages)})"


def initiator(
    channel: str,
    protocol: str,
    *languages: str,
    reply_by_s: float | None = None,
    retry_s: float | None = None,
    unused: bool = False,
    resubscribes: bool = False,
    keep: bool | type[msgspec.Struct] = False,
) -> RoleDecl:
    """The initiator role of ``protocol`` on ``channel`` (or :data:`EVERY_CHANNEL`), in
    ``languages``: ``initiator(C3, FIPA_REQUEST, L_HFSM)``, each a name of
    services/spec/names.py (a plain string for a specification without one). ``unused``: the
    agent opens no conversation in it (see :attr:`RoleDecl.unused`). The role keeps the
    names' spellings as plain ``str`` (:func:`_spelling`). ``resubscribes``: the role keeps
    its subscription open itself (:attr:`RoleDecl.resubscribes`); ``keep``: the role keeps its
    conversations across a restart (:attr:`RoleDecl.keep`)."""
    return RoleDecl(
        _spelling(channel),
        _spelling(protocol),
        INITIATOR,
        tuple(_spelling(lang) for lang in languages),
        reply_by_s,
        retry_s,
        unused,
        keep,
        resubscribes,
    )


def participant(
    channel: str,
    protocol: str,
    *languages: str,
    keep: bool | type[msgspec.Struct] = False,
    resume_in: str | None = None,
) -> RoleDecl:
    """The participant role of ``protocol`` on ``channel`` (or :data:`EVERY_CHANNEL`: every
    channel where the specification makes the agent its participant in exactly ``languages``),
    in ``languages``: ``participant(C5, FIPA_REQUEST, L_EX, L_SD)``, named as by
    :func:`initiator`; ``keep`` as there; ``resume_in``: the protocol state a kept
    conversation is taken back in (:attr:`RoleDecl.resume_in`). Raises ValueError for
    ``resume_in`` without ``keep``."""
    return RoleDecl(
        _spelling(channel),
        _spelling(protocol),
        PARTICIPANT,
        tuple(_spelling(lang) for lang in languages),
        keep=keep,
        resume_in=resume_in,
    )


def _spelling(name: str) -> str:
    """``name`` as a plain ``str``: a member of services/spec/names.py is a ``str`` subclass
    equal to the specification's spelling; a role keeps the spelling itself, so that what the
    roles put in communicates, keys and logs is that spelling whichever way the agent named it."""
    return str.__str__(name)


@dataclass(frozen=True)
class HandlerKey:
    """What a handler handles: ``performative`` received in ``protocol`` while the agent
    plays ``role``; ``channel`` None: on every channel where it plays that role."""

    protocol: str
    role: Role
    performative: Performative | None
    """None: a reply-by deadline of this agent's passed (:func:`on_deadline`)."""
    channel: str | None = None

    def __str__(self) -> str:
        where = f" on {self.channel}" if self.channel else ""
        what = self.performative.value if self.performative else "a passed reply-by deadline"
        return f"{what} received as {self.role} of {self.protocol}{where}"


Handler = Callable[[Any, "Conversation"], None]
F = TypeVar("F", bound=Callable[..., None])
T = TypeVar("T")
S = TypeVar("S", bound=msgspec.Struct)
_MARK = "__roco_handles__"


def handles(
    protocol: str, role: Role, *performatives: Performative, channel: str | None = None
) -> Callable[[F], F]:
    """Mark an agent method ``method(self, conversation)`` as the handler of ``performatives``
    received in ``protocol`` while the agent plays ``role`` (on ``channel``, or on every
    channel where it plays that role): ``@handles(FIPA_REQUEST, PARTICIPANT,
    Performative.REQUEST)``, the protocol and channel named as services/spec/names.py names
    them. Raises ValueError for something that is not a FIPA performative (FIPA SC00037), such
    as a misspelt string that slipped past the types."""
    keys = []
    where = _spelling(channel) if channel is not None else None
    for name in performatives:
        try:
            keys.append(HandlerKey(_spelling(protocol), role, Performative(name), where))
        except ValueError:
            raise ValueError(f"{name!r} is not a FIPA performative (FIPA SC00037)") from None

    return _marker(keys)


def on_deadline(protocol: str, role: Role, *, channel: str | None = None) -> Callable[[F], F]:
    """Mark an agent method ``method(self, conversation)`` as the handler of a reply-by
    deadline that passed in a conversation of ``protocol`` where the agent plays ``role``
    (:attr:`Conversation.last` is then the runtime's local ``failure``): ``@on_deadline(
    COORDINATE, PARTICIPANT)``. Without one, an initiator's ``failure`` handler gets it; a
    participant's passed deadline is logged."""
    return _marker(
        [HandlerKey(_spelling(protocol), role, None, _spelling(channel) if channel is not None else None)]
    )


def _marker(keys: Sequence[HandlerKey]) -> Callable[[F], F]:
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


def expand_roles(spec: SystemSpec, agent: str, declared: Iterable[RoleDecl]) -> list[RoleDecl]:
    """``declared`` with each role on :data:`EVERY_CHANNEL` replaced by the same role (its
    reply-by, retransmission and ``unused``) on every channel where the specification gives
    ``agent`` that role of that protocol in exactly those languages, in the specification's
    order; a channel the agent declares that protocol on by itself is left to that declaration.
    A role on EVERY_CHANNEL that covers no channel is dropped (:func:`role_problems` names it)."""
    declared = list(declared)
    own = {(d.channel, d.protocol) for d in declared if d.channel != EVERY_CHANNEL}
    given = spec_roles(spec, agent)
    out: list[RoleDecl] = []
    for decl in declared:
        if decl.channel != EVERY_CHANNEL:
            out.append(decl)
            continue
        out += [
            replace(decl, channel=r.channel)
            for r in given
            if _covers(decl, r) and (r.channel, r.protocol) not in own
        ]
    return out


def _covers(decl: RoleDecl, given: RoleDecl) -> bool:
    """Whether role ``decl`` on EVERY_CHANNEL stands for ``given``, a role of the specification."""
    return (
        given.protocol == decl.protocol
        and given.role == decl.role
        and given.languages == tuple(sorted(decl.languages))
    )


def _every_channel_problems(spec: SystemSpec, agent: str, declared: Sequence[RoleDecl]) -> list[str]:
    """The roles on EVERY_CHANNEL in ``declared`` that are declared twice or cover no channel."""
    problems: list[str] = []
    seen: set[tuple[str, str, tuple[str, ...]]] = set()
    given = spec_roles(spec, agent)
    own = {(d.channel, d.protocol) for d in declared if d.channel != EVERY_CHANNEL}
    for decl in declared:
        if decl.channel != EVERY_CHANNEL:
            continue
        key = (decl.protocol, decl.role, tuple(sorted(decl.languages)))
        if key in seen:
            problems.append(f"agent {agent} declares {decl} twice")
            continue
        seen.add(key)
        covered = [r for r in given if _covers(decl, r)]
        if not covered:
            problems.append(
                f"agent {agent} declares itself {decl}, but no [[channels]] entry makes it the "
                f"{decl.role} of {decl.protocol} in {', '.join(sorted(decl.languages)) or 'no language'}"
            )
        elif all((r.channel, r.protocol) in own for r in covered):
            problems.append(
                f"agent {agent} declares itself {decl}, but declares each such channel "
                f"({', '.join(r.channel for r in covered)}) by itself: the role on every channel covers none"
            )
    return problems


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
    something no declared role receives. A role on :data:`EVERY_CHANNEL` counts as one per
    channel it stands for (:func:`expand_roles`); one that stands for no channel is a problem.
    Empty: they agree."""
    where = f"agent {agent}"
    problems = _every_channel_problems(spec, agent, declared)
    declared = expand_roles(spec, agent, declared)
    want = {(r.channel, r.protocol): r for r in spec_roles(spec, agent)}
    channels = {ch.name: ch for ch in spec.channels}
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
            problems.append(
                f"{where} declares no {role.role} role for {role.protocol} on {role.channel}, which "
                f"[[channels]] {role.channel} gives it (in {', '.join(role.languages)})"
            )
    handlers = list(handlers)
    valid = [d for d in declared if want.get((d.channel, d.protocol)) == _normal(d)]
    problems += [p for d in valid if (p := _resume_problem(spec, agent, d)) is not None]
    for decl in valid:
        if decl.unused:
            continue
        machine = machine_of(spec, decl.protocol)
        for perf in sorted(
            incoming(machine, decl.role) - optional(machine, decl.role) - _kept_by_role(decl),
            key=lambda p: p.value,
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
            and not d.unused
            and (h.performative is None or h.performative in incoming(machine_of(spec, d.protocol), d.role))
            for d in valid
        ):
            problems.append(f"{where} has a handler for {h}, which no role it declares receives")
    return problems


def code_problems(
    spec: SystemSpec, agent: str, declared: Sequence[RoleDecl], files: Iterable[Path]
) -> list[str]:
    """What in ``files`` (an agent's code) sends outside its declared roles, compares a
    performative, names a performative none of its roles may send, or opens a conversation
    where it is not the initiator (services/runtime/code_scan.py, reading the names of
    services/spec/names.py by ``spec``'s spellings), one line each."""
    declared = expand_roles(spec, agent, declared)
    may_send: set[Performative] = set()
    for decl in declared:
        if decl.protocol in spec.protocols:
            may_send |= outgoing(machine_of(spec, decl.protocol), decl.role)
    opens = frozenset((d.channel, d.protocol) for d in declared if d.role == INITIATOR and not d.unused)
    return findings_text(scan(files, frozenset(may_send), opens, spellings(spec)), agent)


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


def _resume_problem(spec: SystemSpec, agent: str, decl: RoleDecl) -> str | None:
    """Why ``decl``'s ``resume_in`` (:attr:`RoleDecl.resume_in`) names no state its protocol
    can take a conversation back in (:meth:`Roles.restore`: a state other than the initial
    one that non-final transitions lead to from it), or None."""
    if decl.resume_in is None:
        return None
    machine = machine_of(spec, decl.protocol)
    can = sorted(s for s in machine.states - machine.final - {machine.initial} if _path_to(machine, s))
    if decl.resume_in in can:
        return None
    return (
        f"agent {agent} takes its kept {decl.protocol} conversations on {decl.channel} back in "
        f"{decl.resume_in!r}, which is no state of [protocols.{decl.protocol}] to take one back in "
        f"(one of: {', '.join(can)})"
    )


def _kept_by_role(decl: RoleDecl) -> frozenset[Performative]:
    """What a role that keeps its subscription open (:attr:`RoleDecl.resubscribes`) handles
    itself: every answer but the stream's ``inform``."""
    if not decl.resubscribes:
        return frozenset()
    return frozenset({Performative.AGREE, Performative.REFUSE, Performative.FAILURE})


def _normal(decl: RoleDecl) -> RoleDecl:
    return RoleDecl(decl.channel, decl.protocol, decl.role, tuple(sorted(decl.languages)))


def _other(role: Role) -> Role:
    return PARTICIPANT if role == INITIATOR else INITIATOR


def _handler_for(
    handlers: Collection[HandlerKey], decl: RoleDecl, perf: Performative | None
) -> HandlerKey | None:
    """The handler of ``perf`` for ``decl``: a channel's own before one for every channel."""
    for channel in (decl.channel, None):
        key = HandlerKey(decl.protocol, decl.role, perf, channel)
        if key in handlers:
            return key
    return None


# ---------------------------------------------------------------------------------------------
# Where a received communicate goes


_AGREE, _INFORM, _CANCEL = Performative.AGREE, Performative.INFORM, Performative.CANCEL
"""(Module names: an enum member's lookup on its class costs 0.1–0.3 µs on CPython 3.11 here,
timeit, and :meth:`Roles.take` runs for every communicate an agent with roles receives.)"""


@dataclass(frozen=True, slots=True)
class RoleTable:
    """What a role does with each communicate the peer sends in it, worked out once from the
    role's declaration, its protocol's state machine and the agent's handlers
    (:func:`role_table`), so that :meth:`Roles.take` asks neither per communicate.

    ``initiator``: the role is the initiator; ``opens``: the performatives that open a
    conversation of a participant role (fipa-request's ``request``; none for an initiator);
    ``cancelling``: the protocol follows the cancel meta-protocol (FIPA SC00026 §2: a
    ``cancelling`` state); ``answers_cancels``: a participant role of such a protocol, which
    answers a ``cancel`` by itself; ``on_received``: the handler (method name) of each
    performative the peer may send (an initiator's ``not-understood`` without a handler of its
    own goes to its ``failure`` handler); ``on_deadline``: the handler of a passed reply-by
    deadline (an initiator's ``failure`` handler without one; None: the role logs it)."""

    decl: RoleDecl
    initiator: bool
    opens: frozenset[Performative]
    cancelling: bool
    answers_cancels: bool
    on_received: Mapping[Performative, str]
    on_deadline: str | None


def role_table(decl: RoleDecl, machine: Protocol, handlers: Mapping[HandlerKey, str]) -> RoleTable:
    """The :class:`RoleTable` of ``decl`` in its protocol's state ``machine`` with the agent's
    ``handlers`` (:func:`handlers_of`)."""
    initiator = decl.role == INITIATOR
    failure = _method_of(handlers, decl, Performative.FAILURE)
    on_received = {p: m for p in Performative if (m := _method_of(handlers, decl, p)) is not None}
    if initiator and failure is not None:
        on_received.setdefault(Performative.NOT_UNDERSTOOD, failure)
    on_deadline = _method_of(handlers, decl, None) or (failure if initiator else None)
    opens = frozenset() if initiator else _openings(machine)
    cancelling = "cancelling" in machine.states
    answers_cancels = cancelling and not initiator
    return RoleTable(decl, initiator, opens, cancelling, answers_cancels, on_received, on_deadline)


def _method_of(handlers: Mapping[HandlerKey, str], decl: RoleDecl, perf: Performative | None) -> str | None:
    """The name of the agent's method that handles ``perf`` received in ``decl``'s role (None:
    a passed reply-by deadline), or None when it has none."""
    key = _handler_for(handlers.keys(), decl, perf)
    return handlers[key] if key is not None else None


class Route(enum.Enum):
    """Where :meth:`Roles.take` puts a received communicate of one of the agent's roles
    (:func:`route`; a communicate of none is answered not-understood)."""

    CONVERSATION = "conversation"
    """The next communicate of an open conversation: to its handler."""
    OPENS = "opens"
    """It opens a conversation of a participant role: a new conversation, to its handler."""
    REPEATED = "repeated"
    """The opening of an open conversation came again (the same reply-with from the same
    sender, FIPA SC00061 §2.4): not acted on twice, the answers published again
    (:meth:`Roles._repeated`)."""
    ORPHAN = "orphan"
    """No such conversation, or a reply to an earlier opening of its conversation-id: a late
    reply dropped, or a cancel of an ended conversation answered ``failure``
    (:meth:`Roles._orphan`)."""


_CONVERSATION, _OPENS, _REPEATED, _ORPHAN = Route.CONVERSATION, Route.OPENS, Route.REPEATED, Route.ORPHAN
"""(Module names, as ``_AGREE`` above: compared once per communicate.)"""


def route(
    table: RoleTable,
    conv: Conversation | None,
    item: Received,
    restored: Container[tuple[str, str]] = (),
) -> Route:
    """Where ``item``, received in ``table``'s role, goes (:class:`Route`), ``conv`` being the
    open conversation with its sender and conversation-id (None: none); ``restored``: (sender,
    reply-with) of the openings of conversations taken back after a restart, which may have
    ended since (their opening coming again is :data:`Route.REPEATED` too). Pure: reads its
    arguments, changes nothing. A conversation restored after a restart by its id alone does
    not know what it awaited: no reply in it is taken for one to an earlier opening."""
    if item.msg.performative in table.opens:
        if conv is None:
            return _REPEATED if (item.sender, item.msg.reply_with) in restored else _OPENS
        return _REPEATED if not item.local and conv.repeats(item) else _OPENS
    if conv is None or (table.initiator and conv.answers_other(item.msg)):
        return _ORPHAN
    return _CONVERSATION


def _note(table: RoleTable, conv: Conversation, item: Received) -> bool:
    """Note on ``conv`` what ``item``, received in it, says of it: the peer agreed (to an
    initiator), or its ``inform`` answered this agent's cancel (the cancel meta-protocol: the
    conversation is cancelled). True when ``item`` is a ``cancel`` the role answers by itself
    (a participant's, in the cancel meta-protocol): the role's answers answer it while its
    handler runs."""
    conv.last = item
    perf = item.msg.performative
    if perf is _AGREE and table.initiator:
        conv.agreed = True
    if perf is _INFORM and table.cancelling and conv.answers_cancel:
        conv._cancelled = True
    return perf is _CANCEL and table.answers_cancels and not item.local


def _deadline(item: Received) -> bool:
    """``item`` is the runtime's failure for a reply-by deadline that passed (not a
    not-understood this agent sent: :meth:`Roles.not_understood_sent`)."""
    return item.local and item.msg.performative is Performative.FAILURE


# ---------------------------------------------------------------------------------------------
# The conversations and the roles at run time


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

    roles: Roles = field(repr=False)
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
    answered_last: str | None = field(default=None, repr=False)
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
    def why(self) -> str:
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
        return self.last is not None and _deadline(self.last)

    @property
    def answers_to(self) -> str | None:
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
    def answered(self) -> bool:
        """The peer's latest communicate is an answer with content (not a refusal, failure or
        the runtime's deadline)."""
        return self.last is not None and not self.last.local and self.last.content is not None

    @property
    def state(self) -> str | None:
        """The conversation's state in its protocol's state machine (e.g. ``requested``,
        ``agreed`` in fipa-request; shared/fipa_codec/protocols.py), None before its first
        communicate."""
        tracker = self.roles.agent.protocol_states.get(self.peer, self.conversation_id)
        return None if tracker is None else tracker.state

    @property
    def finished(self) -> bool:
        """The conversation has reached a final state of its protocol (or a not-understood
        ended it, or the peer's ``inform`` answered this agent's cancel: ``cancelled``, which
        the protocol state alone cannot tell from an inform that crossed the cancel)."""
        if self._cancelled:
            return True
        tracker = self.roles.agent.protocol_states.get(self.peer, self.conversation_id)
        return tracker is not None and tracker.is_finished

    @property
    def answering(self) -> Received | None:
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
        """Answer :attr:`answering` (or ``to``, a communicate received in this conversation
        earlier: e.g. a cancel answered once the robot is safe) with ``performative`` carrying
        ``content``. Returns its reply-with (every communicate of a role has one). Raises
        SpecViolation when the role or the conversation's state does not allow it."""
        return self._sent(self.roles._reply(self, performative, content, to=to))

    def answer_cancel(
        self, cancelled: bool, content: msgspec.Struct | None = None, *, to: Received | None = None
    ) -> str | None:
        """Answer the peer's ``cancel`` (``to``, received in this conversation earlier, or the
        one the running ``cancel`` handler takes) by the cancel meta-protocol (FIPA SC00026 §2):
        ``inform`` when the conversation is ``cancelled`` (it ends), else ``failure``, carrying
        ``content``. Returns its reply-with; raises SpecViolation as :meth:`reply`."""
        return self.reply(Performative.INFORM if cancelled else Performative.FAILURE, content, to=to)

    def refuse_with(self, performative: Performative, reason: str, *, to: Received | None = None) -> None:
        """Answer :attr:`answering` (or ``to``) with ``refuse`` or ``failure`` whose content
        is ``reason`` as UTF-8 text (FIPA SC00037: a reason a person can read). Raises
        SpecViolation as :meth:`reply`."""
        answering = to or self.answering
        assert answering is not None, "nothing received to answer"
        self.roles.agent.fail(answering, performative, reason)
        self.roles._settle(self)

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
            self.roles._reply(self, performative, content, reply_by_s=reply_by_s, retry_s=retry_s)
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
        reply_with = self.roles._send(
            self, Performative.CANCEL, content, reply_by_s, None, expect=False
        ).reply_with
        if reply_with is not None:
            self.cancels.add(reply_with)
            self.awaited.add(reply_with)
        self.roles._settle(self)
        return reply_with

    def await_reply(self, reply_by_s: float) -> None:
        """Wait for the answer to this agent's opening communicate until ``reply_by_s`` (s)
        from now, without retransmission (e.g. the outcome after an ``agree``, which ended
        the first wait's retransmissions but not its deadline)."""
        if self.opening is not None and self.opening.msg.reply_with:
            self.roles._await(self, self.opening.msg.reply_with, reply_by_s, None)

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

    def stop_waiting(self) -> None:
        """Stop waiting for replies in this conversation: no reply-by deadline, no
        retransmission. The conversation stays open: what the peer sends still arrives."""
        self.roles.agent.pending_replies.forget_conversation(self.conversation_id)

    def abandon(self, *, remember: bool = False) -> None:
        """:meth:`stop_waiting`, and forget the conversation: what the peer still sends in
        it is dropped as a late reply. ``remember``: its conversation-id and :attr:`data` are
        remembered (the last :data:`ENDED_KEPT`), for what is said of it later
        (:meth:`Roles.ended`), and its conversation-id is not chosen again (:meth:`Roles.free_id`)."""
        self.stop_waiting()
        self.roles._forget(self)
        if remember:
            self.roles._remember(self)

    def withdraw(self, *, forget: bool = True) -> None:
        """The initiator no longer wants this conversation: :meth:`stop_waiting`, :meth:`cancel`
        it when it is still open (FIPA SC00026 §2, the cancel meta-protocol: the participant
        stops working on it), and, with ``forget``, :meth:`abandon` it (what the peer still
        sends is dropped as a late reply; else it is taken as it comes)."""
        self.stop_waiting()
        if not self.finished:
            self.cancel()
        if forget:
            self.abandon()

    def decode(self, kept: bytes) -> Received:
        """A communicate of this conversation kept encoded (FIPA SC00061 msgpack, e.g. the
        peer's ``cancel``, to be answered after a restart), as received on its channel, its
        content decoded. Raises RestoreError (a ValueError) when it does not decode."""
        from services.runtime.agent import Received

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
        ``in_reply_to`` (default :attr:`answered_last`: e.g. the last ``confirm`` to a peer
        that may have restarted; a peer that still has it drops the copy,
        services/runtime/dedup.py). Returns how many (0: nothing answered, or forgotten)."""
        agent = self.roles.agent
        again = agent.dedup.answers(self.peer, in_reply_to or self.answered_last)
        for key, payload in again:
            agent.emit(key, payload)
        return len(again)

    def _sent(self, reply_with: str | None) -> str | None:
        if reply_with is not None:
            self.awaited.add(reply_with)
        self.roles._settle(self)
        return reply_with


class Roles:
    """The protocol roles of one agent at run time: its declarations, its handlers, the
    conversations open in each role. Built by :class:`~services.runtime.agent.Agent` from its
    class's ``roles`` and :func:`handles` methods; raises RoleMismatch (one line) when they
    differ from the specification (:func:`role_problems`)."""

    def __init__(self, agent: Agent, declared: Sequence[RoleDecl], *, check: bool = True) -> None:
        self.agent = agent
        self.declared = tuple(expand_roles(agent.spec, agent.name, declared))
        """The declared roles, each on EVERY_CHANNEL replaced by those it stands for."""
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
        self._tables = {
            key: role_table(decl, machine_of(agent.spec, decl.protocol), self._handlers)
            for key, decl in self._by_peer.items()
        }
        """:attr:`_by_peer`'s roles as :class:`RoleTable`\\s, what :meth:`take` looks up."""
        self._open: OrderedDict[tuple[str, str], Conversation] = OrderedDict()
        self._subscriptions: dict[tuple[RoleDecl, str], StandingSubscription | ServedSubscription[Any]] = {}
        """The subscriptions the roles keep (by role and first conversation-id) and serve (by
        role and "")."""
        self.ticks = False
        """:meth:`tick` has something to look at (a subscription is kept): the agent calls it
        on every step only then."""
        self._ended: OrderedDict[str, Any] = OrderedDict()  # :meth:`Conversation.abandon`, remember
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

    # ---- the agent's side ---------------------------------------------------------------
    def role(self, channel: str, protocol: str) -> RoleDecl:
        """The declared role on ``channel`` in ``protocol``; KeyError when none."""
        for decl in self.declared:
            if decl.channel == channel and decl.protocol == protocol:
                return decl
        raise KeyError(f"{self.agent.name} declares no {protocol} role on {channel}")

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
        same_id: bool = False,
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
        … added unless ``same_id``); ``while_away``: attempts go on while the peer's token is
        away. ``on_subscribed``/``on_lost``: called with the conversation when the peer agrees,
        and when an agreed subscription ends. Returns the handle (its ``subscribed``); the
        agent handles the stream's ``inform``\\s. A role keeps several subscriptions apart by
        their conversation-ids; :meth:`unsubscribe` ends one. Raises KeyError for a role not
        declared or not declared ``resubscribes``, or a subscription of ``conversation_id``
        kept already; ValueError for a back-off that is not (first ≤ longest)
        (services/runtime/subscriptions.py)."""
        from services.runtime.subscriptions import StandingSubscription

        decl = self.role(channel, protocol)
        if not decl.resubscribes or decl.role != INITIATOR:
            raise KeyError(
                f"{self.agent.name} declares no resubscribing initiator role of {protocol} on {channel}"
            )
        if (decl, conversation_id) in self._subscriptions:
            kept = f"the subscription {conversation_id} of {protocol} on {channel}"
            raise KeyError(f"{self.agent.name} keeps {kept} already")
        sub = StandingSubscription(
            self,
            decl,
            content,
            conversation_id=conversation_id,
            reply_by_s=reply_by_s if reply_by_s is not None else decl.reply_by_s,
            retry_s=retry_s,
            at_start=at_start,
            same_id=same_id,
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
    ) -> StandingSubscription | ServedSubscription[Any] | None:
        """The subscription of ``decl`` that ``conv`` belongs to: the one served, or the kept one
        of which it is an attempt (:meth:`StandingSubscription.owns`); None: the agent's own."""
        from services.runtime.subscriptions import StandingSubscription

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
        (services/runtime/served.py): the agent's ``subscribe`` handler agrees with
        :meth:`ServedSubscription.agree`, it informs with :meth:`ServedSubscription.inform`;
        the role answers ``cancel`` and ends the subscription on ``not-understood``. Informs
        made while none is agreed are kept in the list ``unsent()`` gives, in order, sent after
        the next agree: at most ``kept_each`` per ``about(inform)`` and ``kept_in_all`` in all,
        the oldest dropped first and counted under ``dropped``. Raises KeyError for a role not
        declared, not a participant's, of a protocol that is no subscription (no stream with a
        cancel meta-protocol) or served already; ValueError for a bound below 1."""
        from services.runtime.served import ServedSubscription

        decl = self.role(channel, protocol)
        machine = machine_of(self.agent.spec, protocol)
        if decl.role != PARTICIPANT or not streams(machine) or "cancelling" not in machine.states:
            raise KeyError(
                f"{self.agent.name} declares no participant role of a subscription {protocol} on {channel}"
            )
        if any(of == decl for of, _ in self._subscriptions):
            raise KeyError(f"{self.agent.name} serves the {protocol} subscription on {channel} already")
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
        self.ticks = True
        return served

    def ended(self, conversation_id: str) -> Any:
        """The :attr:`Conversation.data` of conversation ``conversation_id``, which this agent
        abandoned lately with ``remember`` (the last :data:`ENDED_KEPT`); None when it is not
        remembered."""
        return self._ended.get(conversation_id)

    def withdraw_queries(self) -> int:
        """Withdraw every query this agent asked and still waits on (:meth:`Conversation.withdraw`:
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
            conv.withdraw()
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
        act on it (services/runtime/subscriptions.py)."""
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
            raise KeyError(f"{self.agent.name} declares its {protocol} role on {channel} unused")
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
        from services.runtime.agent import Received

        conv = Conversation(self, decl, self._peer_of[decl], conversation_id or "", data=data)
        answered = _answered(machine, perf)
        msg = self._send(
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
        before = self._open.get((conv.peer, conv.conversation_id)) if conversation_id else None
        if before is not None and before.decl == decl and streams(machine):
            # a stream opened anew (e.g. a_km subscribing again when a_ta's token reappears):
            # what the peer sent in it before it saw the new opening still arrives, and is news
            # (services/runtime/protocol_state.py: it crosses the opening), not a late reply
            conv.awaited |= before.awaited
        self._keep(conv)
        self._settle(conv)  # forgotten at once when the opening ended it
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
        from services.runtime.agent import Received

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
        machine = machine_of(self.agent.spec, protocol)
        path = _path_to(machine, state)
        if path is None:
            raise RestoreError(f"{protocol} has no state {state!r} to restore a conversation in")
        self.agent.restore_conversation(
            peer, conversation_id, protocol, [(perf, role == decl.role) for role, perf in path]
        )
        mine = opening is not None and opening.sender == self.agent.name
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
                self._await(conv, opening.msg.reply_with, reply_by_s, retry_s, kept)
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
        from services.runtime.state_store import NO_DATA, KeptConversation, KeptConversations

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
        from services.runtime.agent import SpecViolation
        from services.runtime.state_store import NO_DATA

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
                    machine = machine_of(self.agent.spec, k.protocol)
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
                self.agent.log.warning(
                    "a kept %s conversation cannot be taken back (%s): dropped", k.protocol, exc
                )
                continue
            self._taken_back(conv)
            out.append(conv)
        return out

    def _await(
        self,
        conv: Conversation,
        reply_with: str,
        reply_by_s: float | None,
        retry_s: float | None,
        payload: bytes = b"",
    ) -> None:
        """Wait for the reply to ``reply_with`` (services/runtime/replies.py): until
        ``reply_by_s`` from now, retransmitting ``payload`` at once and every ``retry_s``."""
        from services.runtime.replies import Pending

        now = self.agent.sources.time()
        again = retry_s is not None and bool(payload)
        self.agent.pending_replies.expect(
            Pending(
                reply_with,
                conv.peer,
                conv.decl.protocol,
                conv.conversation_id,
                now + reply_by_s if reply_by_s is not None else None,
                retry_s=retry_s if again else None,
                key=keys.fipa_key(conv.decl.channel, self.agent.name, conv.peer) if again else "",
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
        decl = self._by_peer.get((self.agent.spec.role_of(sender), msg.protocol or ""))
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
        from services.runtime.agent import Received

        conv = self._open.get((peer, about.conversation_id or ""))
        if conv is None or conv.decl.role != INITIATOR:
            return
        conv.stop_waiting()
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
        self.agent.x.append(Received.of(ended, None, channel, local=True))

    def take(self, item: Received) -> None:
        """Route one received communicate (already checked against the interface and the
        conversation's protocol state by the agent) to its conversation and handler: its
        role's :class:`RoleTable`, then :func:`route`."""
        msg = item.msg
        sender = item.sender
        table = self._tables.get((self.agent.spec.role_of(sender), msg.protocol or ""))
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
            self.agent.not_understood(
                item.sender, item.channel, f"no role for {item.msg.protocol or ''}", item.msg
            )

    def _hand(self, table: RoleTable, conv: Conversation, item: Received) -> None:
        """Hand ``item``, received in ``conv``, to its handler (:class:`RoleTable`); a
        subscription the role keeps takes the answers it acts on itself; a cancel with no
        handler is answered ``failure``; a passed deadline with none is logged. A fault in the
        handler must not stop the agent nor strand the peer (:meth:`_fault`)."""
        cancel = _note(table, conv, item)
        if cancel:
            conv._cancel = item
        deadline = _deadline(item)
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
                self.agent.log.info(
                    "reply-by deadline of %s in conversation %s with %s passed",
                    item.msg.in_reply_to,
                    item.msg.conversation_id or "",
                    item.sender,
                )
        except Exception as exc:  # a fault in a handler must not stop the agent nor strand the peer
            self._fault(table, conv, item, exc)
        finally:
            conv._cancel = None
        self._settle(conv)

    def _fault(self, table: RoleTable, conv: Conversation, item: Received, exc: Exception) -> None:
        """The handler of ``item`` raised ``exc``: logged and counted (``handler_errors``); a
        participant's peer gets ``failure`` with the reason instead of waiting for its
        deadline."""
        agent = self.agent
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
            answers = self.agent.dedup.answers(item.sender, reply_with)
            for key, payload in answers:
                self.agent.emit(key, payload)
            again = len(answers)
        self.agent.counters["repeated_requests"] += 1
        self.agent.log.info(
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

    def _method(self, decl: RoleDecl, perf: Performative | None) -> str | None:
        key = _handler_for(self._handlers.keys(), decl, perf)
        return self._handlers[key] if key is not None else None

    def _keep(self, conv: Conversation) -> None:
        if not conv._seq:
            conv._seq = next(self._taken_up)
        key = (conv.peer, conv.conversation_id)
        self._open.pop(key, None)
        self._open[key] = conv
        while len(self._open) > MAX_OPEN:
            self._open.popitem(last=False)

    def _forget(self, conv: Conversation) -> None:
        if self._open.get((conv.peer, conv.conversation_id)) is conv:
            del self._open[(conv.peer, conv.conversation_id)]

    def _remember(self, conv: Conversation) -> None:
        self._ended[conv.conversation_id] = conv.data
        while len(self._ended) > ENDED_KEPT:
            self._ended.popitem(last=False)

    def _taken_back(self, conv: Conversation) -> None:
        """``conv`` was taken back after a restart: a served subscription takes its stream; a
        participant's opening is remembered (:meth:`_repeated`)."""
        from services.runtime.served import ServedSubscription

        opening = conv.opening
        if conv.decl.role == PARTICIPANT and opening is not None and opening.msg.reply_with:
            self._restored_openings[(opening.sender, opening.msg.reply_with)] = None
            while len(self._restored_openings) > ENDED_KEPT:
                self._restored_openings.popitem(last=False)
        served = self._subscriptions.get((conv.decl, ""))
        if isinstance(served, ServedSubscription):
            served.taken_back(conv)

    def _settle(self, conv: Conversation) -> None:
        """Forget a conversation that has ended, once nothing of it waits in the input
        buffer (the protocol state follows every communicate when it is acquired: the end
        may already be there while earlier communicates wait for their handlers)."""
        key = (conv.peer, conv.conversation_id)
        if self._open.get(key) is not conv or not conv.finished:
            return
        if any(i.sender == conv.peer and i.msg.conversation_id == conv.conversation_id for i in self.agent.x):
            return
        del self._open[key]
        if conv.decl.resume_in is not None and conv.data is not None:
            self._held[conv._seq] = conv  # the agent still holds it: kept (:meth:`kept`)

    def _reply(
        self,
        conv: Conversation,
        performative: Performative,
        content: msgspec.Struct | None,
        *,
        reply_by_s: float | None = None,
        retry_s: float | None = None,
        to: Received | None = None,
    ) -> str | None:
        answering = to or conv.answering
        if (
            performative is Performative.INFORM
            and answering is not None
            and answering.performative is Performative.CANCEL
            and "cancelling" in machine_of(self.agent.spec, conv.decl.protocol).states
        ):
            conv._cancelled = True  # the cancel meta-protocol: this inform says it is cancelled
        in_reply_to = answering.msg.reply_with if answering is not None and not answering.local else None
        reply_with = self._send(
            conv, performative, content, reply_by_s, retry_s, expect=False, in_reply_to=in_reply_to
        ).reply_with
        if in_reply_to is not None:
            conv.answered_last = in_reply_to
        return reply_with

    def _send(
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
        msg = self.agent.send(
            conv.peer,
            performative,
            content,
            protocol=conv.decl.protocol,
            conversation_id=conv.conversation_id or None,
            # every communicate of a role can be answered unambiguously, and two of them are
            # never byte-identical (a copy is what a receiver drops: services/runtime/dedup.py)
            reply_with=self.agent.sources.new_id(f"{self.agent.name}-"),
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


def _path_to(machine: Protocol, state: str) -> list[tuple[Role, Performative]] | None:
    """The shortest sequence of (sender's role, performative) from the initial state to
    ``state`` by non-terminal transitions, not-understood left out; None when there is none."""
    paths: dict[str, list[tuple[Role, Performative]]] = {machine.initial: []}
    todo = [machine.initial]
    while todo:
        here = todo.pop(0)
        if here == state:
            return paths[here]
        for (source, role, perf), target in machine.transitions.items():
            if source == here and target not in paths and perf is not Performative.NOT_UNDERSTOOD:
                paths[target] = [*paths[here], (role, perf)]
                todo.append(target)
    return None


def _openings(machine: Protocol) -> frozenset[Performative]:
    """The performatives that open a conversation of ``machine`` (the initiator's first)."""
    return frozenset(p for p in Performative if machine.next_state(machine.initial, INITIATOR, p) is not None)
