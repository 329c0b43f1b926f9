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
  with the reason; the cancel's answer answers the cancel (:attr:`Conversation.to_answer`,
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
- a reply in a conversation the role no longer has (forgotten, or from before a restart) is
  counted (``late_replies``) and dropped;
- the opening of an open conversation again (the same reply-with from the same sender, FIPA
  SC00061 §2.4: a retransmission that reached a restarted agent, or a copy that is not
  byte-identical) is not handed to the agent: the participant role publishes again what the
  conversation answered it and counts it (``repeated_requests``);
- a fipa-subscribe initiator role declared ``resubscribes`` keeps its subscription open
  (:meth:`Roles.subscribe`, services/runtime/roles/subscriptions.py): it subscribes when the peer's
  token appears and again after a refusal, failure or passed deadline, with a back-off, and
  when the peer comes back; the agent handles the stream's informs only;
- a fipa-subscribe participant role whose stream the agent has it serve (:meth:`Roles.serve`,
  services/runtime/roles/served.py) informs the latest agreed subscription, keeps (bounded) what is
  informed while none is and sends it after the next agree, answers ``cancel`` and ends the
  subscription on ``not-understood``; the agent's ``subscribe`` handler only agrees or refuses;
- conversations the agent ended and asked it to remember (``forget(remember=True)``): their
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

An agent imports what it writes of its roles from this package (the rest of its API from
services/runtime/agent.py), whose modules are:

- declare.py: what an agent author writes (:class:`RoleDecl`, :func:`initiator`,
  :func:`participant`, :func:`handles`, :func:`on_deadline`);
- check.py: roles held against the specification (:func:`role_problems`,
  :func:`agent_problems`; ``roco spec verify-code``, ``roco spec new-agent``);
- conversation.py: one conversation (:class:`Conversation`) and where its communicates go;
- route.py: where a received communicate goes (:class:`RoleTable`, :func:`route`);
- dispatch.py: the roles at run time (:class:`Roles`), reaching their agent through
  host.py's :class:`~services.runtime.roles.host.RoleHost`;
- subscriptions.py, served.py: a fipa-subscribe initiator's subscription kept open, a
  participant's stream served;
- confirmed.py: a participant's informs sent one at a time until confirmed (coordinate).
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
