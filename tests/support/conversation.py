"""One conversation walked message by message through its interaction protocol, by the rules
the agents' runtime follows it with (:func:`services.runtime.protocol_state.follow`; the rules
themselves: :func:`services.runtime.protocol_state.judge`), for the tests.

:class:`Walk` takes a message as a role and a performative (:meth:`Walk.step`) or as a
communicate from the wire (:meth:`Walk.observe`, the roles told by who sent the first one).
Messages stepped are, by default, unlinked: none names another in its ``in-reply-to``, so any of
them may have crossed the other side's latest on the wire and the follower may place it before
what arrived first (:attr:`~shared.fipa_codec.protocols.Protocol.crossing_transitions` open to
it). A walk made with ``linked=True`` sets each step's ``in-reply-to`` to the other side's latest
``reply-with``: every message was sent after its sender saw all the other had sent, so nothing
crossed and only the machine's own transitions are taken, in arrival order.

A protocol given by name is looked up as the runtime does: the state machine the shipped
specification declares or names (:func:`services.spec.protocol_defs.protocols_of`), else the
codec's library (:data:`shared.fipa_codec.protocols.PROTOCOLS`), so that a protocol moved from
one to the other (``coordinate``) resolves either way.
"""

from __future__ import annotations

import functools

from services.runtime.protocol_state import CrossingTracker, follow
from services.spec.model import DEFAULT_SPEC
from services.spec.protocol_defs import protocols_of
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.message import Communicate
from shared.fipa_codec.protocols import (
    INITIATOR,
    PARTICIPANT,
    PROTOCOLS,
    Protocol,
    Role,
    is_terminal_report,
)

NOT_UNDERSTOOD = "not-understood"
"""The state of a walk a not-understood ended (the machines' final state of that name; a
machine with no such state, one of a single message, ends there too)."""


@functools.cache
def known_protocols() -> dict[str, Protocol]:
    """Every protocol a name resolves to: the codec's library, and over it the shipped
    specification's (read once per test session)."""
    return {**PROTOCOLS, **protocols_of(DEFAULT_SPEC)}


def protocol_named(name: str) -> Protocol:
    """The state machine of protocol ``name`` (see the module docstring); ValueError for a
    name neither the specification nor the codec knows."""
    known = known_protocols()
    if name not in known:
        raise ValueError(f"unknown interaction protocol {name!r}; known: {', '.join(known)}")
    return known[name]


def _other(role: Role) -> Role:
    return PARTICIPANT if role == INITIATOR else INITIATOR


class Walk:
    """Follows one conversation (one conversation-id between one initiator and one
    participant) through ``protocol`` (a state machine, or a name: :func:`protocol_named`).

    ``history`` holds the accepted messages as (role, performative, state after it); a message
    refused leaves the walk as it was. ``linked``: see the module docstring.
    """

    def __init__(self, protocol: Protocol | str, *, linked: bool = False) -> None:
        self.protocol = protocol if isinstance(protocol, Protocol) else protocol_named(protocol)
        self.linked = linked
        self.tracker: CrossingTracker | None = None
        """The runtime's follower of the conversation (None until a message is accepted)."""
        self.history: list[tuple[Role, Performative, str]] = []
        self.initiator: str | None = None
        """The name of the agent that sent the first communicate observed (None: none yet)."""
        self._latest: dict[Role, str | None] = {INITIATOR: None, PARTICIPANT: None}

    @property
    def state(self) -> str:
        """Where the conversation stands: the machine's initial state before any message,
        ``not-understood`` once one ended it, else the state of the follower's most in-order
        reading."""
        if self.tracker is None:
            return self.protocol.initial
        return NOT_UNDERSTOOD if self.tracker.aborted else self.tracker.state

    @property
    def states(self) -> frozenset[str]:
        """Every state the conversation may stand in (one per reading of what crossed)."""
        if self.tracker is None:
            return frozenset({self.protocol.initial})
        return frozenset({NOT_UNDERSTOOD}) if self.tracker.aborted else self.tracker.states

    @property
    def is_finished(self) -> bool:
        """True once the conversation has ended in every reading (or by a not-understood)."""
        return self.tracker is not None and self.tracker.is_finished

    @property
    def may_be_finished(self) -> bool:
        """True once the conversation has ended in some reading."""
        return self.tracker is not None and self.tracker.may_be_finished

    @property
    def crossings(self) -> int:
        """Messages accepted only as having crossed another on the wire."""
        return 0 if self.tracker is None else self.tracker.crossings

    def allowed(self) -> list[tuple[Role, Performative, bool]]:
        """What the machine allows in :attr:`state` (:meth:`Protocol.allowed`)."""
        return self.protocol.allowed(self.state)

    def step(self, role: Role | str, performative: Performative | str, *, terminal: bool = False) -> str:
        """Follow a message ``role`` sent (``terminal``: an inform that reports a terminal
        L_SW state, for ``coordinate``); the state after it. Raises ProtocolViolation or
        ConversationError as :func:`~services.runtime.protocol_state.follow` does, ValueError
        for an unknown role or performative; the walk is then unchanged."""
        checked = _role(role)
        reply_with = in_reply_to = None
        if self.linked:
            reply_with = f"{checked}-{len(self.history) + 1}"
            in_reply_to = self._latest[_other(checked)]
        return self._follow(checked, Performative(performative), terminal, reply_with, in_reply_to)

    def observe(self, msg: Communicate) -> str:
        """Follow communicate ``msg`` with its own ``reply-with`` and ``in-reply-to`` (whatever
        ``linked`` says): its role is ``initiator`` when its sender sent the first communicate
        observed (or this is the first), else ``participant``; ``terminal`` from
        :func:`~shared.fipa_codec.protocols.is_terminal_report`. The state after it; raises
        ValueError for a communicate without sender, else as :meth:`step`."""
        if msg.sender is None:
            raise ValueError("cannot tell the role of a communicate without sender")
        initiator = self.initiator if self.initiator is not None else msg.sender.name
        role: Role = INITIATOR if msg.sender.name == initiator else PARTICIPANT
        state = self._follow(role, msg.performative, is_terminal_report(msg), msg.reply_with, msg.in_reply_to)
        self.initiator = initiator
        return state

    def _follow(
        self,
        role: Role,
        performative: Performative,
        terminal: bool,
        reply_with: str | None,
        in_reply_to: str | None,
    ) -> str:
        work = self.tracker.copy() if self.tracker is not None else None  # refused: unchanged
        self.tracker, _ = follow(
            work,
            self.protocol,
            role,
            performative,
            terminal=terminal,
            reply_with=reply_with,
            in_reply_to=in_reply_to,
        )
        self._latest[role] = reply_with
        self.history.append((role, performative, self.state))
        return self.state


def _role(role: str) -> Role:
    """``role`` as a Role; ValueError for neither ``initiator`` nor ``participant``."""
    if role == INITIATOR:
        return INITIATOR
    if role == PARTICIPANT:
        return PARTICIPANT
    raise ValueError(f"role must be 'initiator' or 'participant', not {role!r}")
