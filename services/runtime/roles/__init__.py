"""Protocol roles built from the specification's state machines (paper §4 step 3, §5.4;
FIPA SC00025 interaction protocol library). The manual: docs/spec.md, "Protocol roles".

An agent declares the roles it plays, one :class:`RoleDecl` per (channel, interaction
protocol) — :func:`initiator` or :func:`participant`, with the content languages it speaks
there, named as services/spec/names.py names them; :data:`EVERY_CHANNEL` for every channel
the specification gives it that role on (:func:`expand_roles`), :data:`EVERY_NOTICE` for every
notice protocol — and one handler per performative the other role may send (:func:`handles`,
:func:`on_deadline`). :class:`Roles`, the same code for every protocol, owns the rest of the
protocol: routing, reply-with / in-reply-to / conversation-id, reply-by deadlines and
retransmission, cancel and not-understood, repeated openings, subscriptions kept open or
served, informs confirmed one at a time, conversations kept across a restart. An agent whose
declared roles or handlers differ from the specification refuses to start
(:func:`role_problems`; ``roco spec verify-code`` runs the same comparison).

An agent imports what it writes of its roles from here (the rest of its API from
services/runtime/agent.py). The modules: declare.py (what an author writes), check.py (roles
held against the specification), conversation.py (one conversation), route.py (where a
received communicate goes), dispatch.py (:class:`Roles`, reaching its agent through host.py's
``RoleHost``), subscriptions.py and served.py (fipa-subscribe kept open, served), confirmed.py
(a participant's informs one at a time until confirmed).
"""

from services.runtime.roles.check import (
    agent_problems,
    code_problems,
    expand_roles,
    incoming,
    optional,
    outgoing,
    role_problems,
    spec_roles,
)
from services.runtime.roles.confirmed import ConfirmedInforms
from services.runtime.roles.conversation import Conversation
from services.runtime.roles.declare import (
    EVERY_CHANNEL,
    EVERY_NOTICE,
    HandlerKey,
    RestoreError,
    RoleDecl,
    RoleMismatch,
    handlers_of,
    handles,
    initiator,
    on_deadline,
    participant,
)
from services.runtime.roles.dispatch import Roles
from services.runtime.roles.route import RoleTable, Route, role_table, route
from services.runtime.roles.served import ServedSubscription
from services.runtime.roles.subscriptions import StandingSubscription
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT

__all__ = [
    "EVERY_CHANNEL",
    "EVERY_NOTICE",
    "INITIATOR",
    "PARTICIPANT",
    "ConfirmedInforms",
    "Conversation",
    "HandlerKey",
    "RestoreError",
    "RoleDecl",
    "RoleMismatch",
    "RoleTable",
    "Roles",
    "Route",
    "ServedSubscription",
    "StandingSubscription",
    "agent_problems",
    "code_problems",
    "expand_roles",
    "handlers_of",
    "handles",
    "incoming",
    "initiator",
    "on_deadline",
    "optional",
    "outgoing",
    "participant",
    "role_problems",
    "role_table",
    "route",
    "spec_roles",
]
