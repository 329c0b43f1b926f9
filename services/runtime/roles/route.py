"""Where a received communicate of one of an agent's roles goes: each role's
:class:`RoleTable`, worked out once from its declaration, its protocol's state machine
(``[protocols.NAME]`` of the specification, or shared/fipa_codec/protocols.py) and the
agent's handlers, and :func:`route`, which sends one communicate to its conversation, opens
one, or names it a repeated opening or an orphan (FIPA SC00061 §2.4; FIPA SC00026 §2, the
cancel meta-protocol). Read by :class:`~services.runtime.roles.dispatch.Roles` for every
communicate.
"""

from __future__ import annotations

import enum
from collections.abc import Container, Mapping
from dataclasses import dataclass

from services.runtime.roles.conversation import Conversation
from services.runtime.roles.declare import HandlerKey, RoleDecl, handler_for
from services.runtime.values import Received
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, Protocol

__all__ = ["RoleTable", "Route", "note", "role_table", "route"]

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
    key = handler_for(handlers.keys(), decl, perf)
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


def note(table: RoleTable, conv: Conversation, item: Received) -> bool:
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


def _openings(machine: Protocol) -> frozenset[Performative]:
    """The performatives that open a conversation of ``machine`` (the initiator's first)."""
    return frozenset(p for p in Performative if machine.next_state(machine.initial, INITIATOR, p) is not None)
