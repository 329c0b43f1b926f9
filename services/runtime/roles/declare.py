"""What an agent author writes of its protocol roles (docs/spec.md, "Protocol roles"): one
:class:`RoleDecl` per (channel, interaction protocol), built with :func:`initiator` or
:func:`participant`, and one handler per performative the other role may send, marked with
:func:`handles` (or :func:`on_deadline` for a passed reply-by deadline). :func:`handlers_of`
reads the handlers of an agent class back. The names are those of services/spec/names.py
(generated from the specification, services/spec/render_names.py).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from typing import TypeVar

import msgspec

from services.spec.model import SpecError
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, Role

__all__ = [
    "EVERY_CHANNEL",
    "EVERY_NOTICE",
    "HandlerKey",
    "RestoreError",
    "RoleDecl",
    "RoleMismatch",
    "handler_for",
    "handlers_of",
    "handles",
    "initiator",
    "on_deadline",
    "participant",
]

EVERY_CHANNEL = "*"
"""The channel of a role declared for every channel the specification gives the agent with its
protocol, role and languages (:func:`expand_roles`)."""

EVERY_NOTICE = "*notice"
"""The protocol of a participant role on :data:`EVERY_CHANNEL` that stands for every notice
protocol of the specification (services/spec/notices.py: one initiator ``inform``, nothing
answers), and of its handlers: ``participant(EVERY_CHANNEL, EVERY_NOTICE, L_HC)`` with
``@handles(EVERY_NOTICE, PARTICIPANT, Performative.INFORM)`` (:func:`expand_roles`)."""


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
    (:meth:`Roles.subscribe`, services/runtime/roles/subscriptions.py): it handles ``agree``,
    ``refuse`` and ``failure``; the agent handles the stream's ``inform``\\s only."""
    resume_in: str | None = None
    """A participant role declared with ``keep`` takes each kept conversation back in this
    state of its protocol's state machine, whatever state it was kept in (e.g. a_ta's plan in
    coordinate's ``running``: it reports its outcome again, which ``ending`` does not allow);
    and it keeps a conversation for as long as the agent's data of it is set, even once it has
    ended (a not-understood ended a_ta's plan conversation while a_ta still runs the plan).
    None: taken back in the state it was kept in, and kept while open. Checked against the
    protocol's states when the agent starts (:func:`role_problems`)."""
    confirmed_informs: bool = False
    """A participant role whose peer confirms each ``inform`` before the next (coordinate,
    paper §5.4, Figure 8): the role sends the agent's informs one at a time, each once the one
    before was confirmed, retransmitted until then (:meth:`Roles.report`,
    services/runtime/roles/confirmed.py), and handles ``confirm`` itself."""
    handled_as: str = ""
    """The protocol the role's handlers name when it is not :attr:`protocol`:
    :data:`EVERY_NOTICE` for a role :func:`expand_roles` made from a role on every notice
    protocol; empty otherwise."""

    def __post_init__(self) -> None:
        if self.resume_in is not None and (self.role != PARTICIPANT or not self.keep):
            raise ValueError(f"{self}: resume_in is for a participant role declared with keep")
        if self.confirmed_informs and self.role != PARTICIPANT:
            raise ValueError(f"{self}: confirmed_informs is for a participant role")
        if self.protocol == EVERY_NOTICE and (self.channel != EVERY_CHANNEL or self.role != PARTICIPANT):
            raise ValueError(f"{self}: every notice protocol is a participant role on EVERY_CHANNEL")

    def __str__(self) -> str:
        where = "every channel" if self.channel == EVERY_CHANNEL else self.channel
        what = "every notice protocol" if self.protocol == EVERY_NOTICE else self.protocol
        return f"{self.role} of {what} on {where} ({', '.join(self.languages)})"


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
    confirmed_informs: bool = False,
) -> RoleDecl:
    """The participant role of ``protocol`` on ``channel`` (or :data:`EVERY_CHANNEL`: every
    channel where the specification makes the agent its participant in exactly ``languages``),
    in ``languages``: ``participant(C5, FIPA_REQUEST, L_EX, L_SD)``, named as by
    :func:`initiator`; ``keep`` as there; ``resume_in``: the protocol state a kept
    conversation is taken back in (:attr:`RoleDecl.resume_in`); ``confirmed_informs``: the
    role sends the agent's informs one at a time until confirmed
    (:attr:`RoleDecl.confirmed_informs`). Raises ValueError for ``resume_in`` without
    ``keep``."""
    return RoleDecl(
        _spelling(channel),
        _spelling(protocol),
        PARTICIPANT,
        tuple(_spelling(lang) for lang in languages),
        keep=keep,
        resume_in=resume_in,
        confirmed_informs=confirmed_informs,
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


F = TypeVar("F", bound=Callable[..., None])
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


def handler_for(
    handlers: Collection[HandlerKey], decl: RoleDecl, perf: Performative | None
) -> HandlerKey | None:
    """The handler of ``perf`` for ``decl``: a channel's own before one for every channel, and
    one for its protocol before one for what it is handled as (:attr:`RoleDecl.handled_as`)."""
    for protocol in (decl.protocol, decl.handled_as) if decl.handled_as else (decl.protocol,):
        for channel in (decl.channel, None):
            key = HandlerKey(protocol, decl.role, perf, channel)
            if key in handlers:
                return key
    return None
