"""What the protocol roles ask of the engine that runs their agent, and what a kept
subscription asks of the roles: two small protocols (PEP 544), so that the roles reach the
engine (services/runtime/engine.py ``Engine``) through these members alone, as the receiving
half does through services/runtime/admission.py ``Host``.
"""

from __future__ import annotations

import logging
from collections import Counter, deque
from typing import Any, Protocol

import msgspec

from services.runtime.dedup import Dedup
from services.runtime.protocol_state import ProtocolStates
from services.runtime.replies import PendingReplies
from services.runtime.roles.conversation import Conversation
from services.runtime.roles.declare import RoleDecl
from services.runtime.sources import Sources
from services.runtime.values import Received
from services.spec.model import SystemSpec
from shared.fipa_codec import Communicate
from shared.fipa_codec.acts import Performative

__all__ = ["RoleHost", "SubscriptionHost"]


class RoleHost(Protocol):
    """What :class:`~services.runtime.roles.dispatch.Roles` asks of its agent
    (services/runtime/engine.py ``Engine``): its name and specification, its input buffer ``x``,
    its log and counters, the peers alive, its clocks and identifiers, the replies it awaits,
    the protocol state of its conversations and the answers it keeps, and sending."""

    spec: SystemSpec
    log: logging.Logger
    counters: Counter[str]
    x: deque[Received]
    peers: set[str]
    sources: Sources
    dedup: Dedup
    pending_replies: PendingReplies
    protocol_states: ProtocolStates

    @property
    def name(self) -> str:
        """The agent's name, as in the specification."""
        ...

    def send(
        self,
        to: str,
        performative: Performative,
        content: msgspec.Struct | None = None,
        *,
        protocol: str,
        conversation_id: str | None = None,
        reply_with: str | None = None,
        in_reply_to: str | None = None,
        reply_by_s: float | None = None,
        expect_reply: bool = False,
        retry_s: float | None = None,
    ) -> Communicate:
        """Send a communicate to agent ``to`` (raises SpecViolation when not allowed)."""
        ...

    def fail(self, to: Received, performative: Performative, reason: str) -> None:
        """Answer ``to`` with ``refuse`` or ``failure`` carrying ``reason`` as UTF-8 text."""
        ...

    def not_understood(
        self, sender: str, channel: str, why: str, about: Communicate | None, reason: str = "unhandled"
    ) -> None:
        """Answer ``about`` from ``sender`` with ``not-understood`` for ``why``."""
        ...

    def emit(self, key: str, payload: bytes) -> None:
        """Put an encoded communicate on ``key`` into the output buffer as it is."""
        ...

    def restore_conversation(
        self,
        peer: str,
        conversation_id: str,
        protocol: str,
        history: list[tuple[Performative, bool]],
        opening_reply_with: str | None = None,
    ) -> None:
        """Re-enter the protocol state ``history`` leads to, the opening communicate's
        reply-with known (raises SpecViolation)."""
        ...


class SubscriptionHost(Protocol):
    """What a subscription a role keeps or serves (services/runtime/roles/subscriptions.py,
    services/runtime/roles/served.py) asks of its roles
    (services/runtime/roles/dispatch.py ``Roles``)."""

    @property
    def host(self) -> RoleHost:
        """The agent the roles belong to."""
        ...

    def peer_of(self, decl: RoleDecl) -> str:
        """The agent at the other end of ``decl``'s channel."""
        ...

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
        """Open a conversation as the initiator of ``protocol`` on ``channel``."""
        ...
