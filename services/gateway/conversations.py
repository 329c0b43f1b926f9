"""The conversations the gateway bridges, each followed through its interaction protocol.

A foreign agent and a roco agent talk through the gateway in conversations (FIPA SC00061
§2.4: one ``conversation-id`` names one), each following an interaction protocol (FIPA
SC00026 fipa-request, roco-notify, …) whose state machine the specification gives
(:func:`services.spec.protocol_defs.machine_of`). The gateway follows each one, per (foreign
name, roco agent, conversation-id), with the runtime's own rules (:func:`services.runtime.
protocol_state.judge`, through a bounded :class:`~services.runtime.protocol_state.
ProtocolStates`): what a foreign agent sends that its conversation's state does not allow is
refused (``refused.protocol_state``, answered not-understood: FIPA SC00037 §3.12), what a roco
agent sends that it does not allow is not posted (``dropped.out_of_protocol``), and a foreign
name's conversation has ended when its tracker says so (services/gateway/identity.py).

Roles come from the specification: the foreign agent plays its external role (``x_fipa``,
:meth:`~services.spec.model.SystemSpec.role_of`), the initiator of a protocol when the
channel's entry for it names that role (:attr:`~services.spec.model.ChannelProtocol.initiator`),
else the participant. The table takes the roco agent's side (``local_role``), so that the gateway
judges what comes in as the agent it forwards to will (services/runtime/admission.py): a
``cancel`` that crossed the agent's last answer on the HTTP wire (FIPA SC00026 §2, the cancel
meta-protocol) is a late cancel the agent may answer, not a violation.
"""

from __future__ import annotations

from dataclasses import dataclass

from services.runtime.protocol_state import ConversationError, ProtocolStates
from services.spec.model import SpecError, SystemSpec, channel_between
from services.spec.protocol_defs import machine_of
from shared.fipa_codec import Communicate
from shared.fipa_codec.protocols import (
    INITIATOR,
    PARTICIPANT,
    Protocol,
    ProtocolViolation,
    Role,
    is_terminal_report,
)

__all__ = ["Conversations", "Side"]


@dataclass(frozen=True)
class Side:
    """How the gateway follows one protocol between a foreign agent and a roco agent: the
    protocol's state machine (None: the specification gives it none, so its conversations are
    not followed) and the role the foreign agent plays in it."""

    machine: Protocol | None
    foreign: Role


def _other(role: Role) -> Role:
    return PARTICIPANT if role == INITIATOR else INITIATOR


def _key(agent: str, conversation_id: str) -> str:
    """The table's conversation key for ``conversation_id`` with roco agent ``agent`` (whose
    name, a name of the specification, has no space): one foreign agent's conversations with
    two roco agents are two conversations even under one conversation-id."""
    return f"{agent} {conversation_id}"


class Conversations:
    """The protocol state of every conversation between a foreign agent and a roco agent that
    the gateway bridges, under ``spec``: at most ``max_open`` open ones (the oldest forgotten
    beyond) and the newest ``max_ended`` ended ones (for communicates that crossed their end).
    Used from the gateway's thread only."""

    def __init__(self, spec: SystemSpec, *, max_open: int, max_ended: int) -> None:
        self.spec = spec
        self.states = ProtocolStates(max_open=max_open, max_ended=max_ended)

    def side(self, foreign: str, agent: str, protocol: str | None) -> Side | None:
        """How conversations of ``protocol`` between ``foreign`` and ``agent`` are followed;
        None when the specification has no such conversation (no channel between their roles,
        or not that protocol on it)."""
        role = self.spec.role_of(foreign)
        channel = channel_between(self.spec, role, agent) if protocol is not None else None
        entry = next((cp for cp in channel.protocols if cp.protocol == protocol), None) if channel else None
        if entry is None or protocol is None:
            return None
        try:
            machine: Protocol | None = machine_of(self.spec, protocol)
        except SpecError:  # a protocol without a state machine is not followed (as agents do)
            machine = None
        return Side(machine, INITIATOR if entry.initiator == role else PARTICIPANT)

    def follow(self, foreign: str, agent: str, msg: Communicate, *, inbound: bool) -> str | None:
        """Follow ``msg``, sent by ``foreign`` to ``agent`` (``inbound``) or by ``agent`` to
        ``foreign``, in its conversation: None when its conversation's state allows it (or its
        protocol is not followed), else why not, in one line (the state machine's reason, as
        :func:`~services.runtime.protocol_state.judge` gives it; the conversation then stays
        where it was). A followed protocol's communicate needs a conversation-id (FIPA SC00061
        leaves it optional; the agents need it too, services/runtime/admission.py)."""
        side = self.side(foreign, agent, msg.protocol)
        if side is None or side.machine is None:
            return None
        cid = msg.conversation_id
        if cid is None:
            return (
                f"{msg.performative.value} in protocol {msg.protocol} needs a conversation-id: "
                "roco follows each conversation by it (FIPA SC00061 §2.4)"
            )
        try:
            self.states.observe(
                foreign,
                _key(agent, cid),
                side.machine,
                side.foreign if inbound else _other(side.foreign),
                msg.performative,
                local_role=_other(side.foreign),
                terminal=is_terminal_report(msg),
                reply_with=msg.reply_with,
                in_reply_to=msg.in_reply_to,
            )
        except (ProtocolViolation, ConversationError) as exc:
            return " ".join(str(exc).split())
        finally:
            self.states.commit()  # nothing is undone: the gateway has no output buffer to drop
        return None

    def ended(self, foreign: str, agent: str, protocol: str | None, conversation_id: str | None) -> bool:
        """Whether the conversation ``conversation_id`` of ``protocol`` between ``foreign`` and
        ``agent`` is over: its tracker has finished (a final state, or a not-understood ended
        it: :attr:`~services.runtime.protocol_state.CrossingTracker.is_finished`), or no such
        conversation is open (there can be none, it was refused before it began, or it was
        forgotten). A conversation of a protocol that is not followed is never over here (it
        ends by age or number, services/gateway/identity.py)."""
        side = self.side(foreign, agent, protocol)
        if side is None:
            return True
        if side.machine is None:
            return False
        if conversation_id is None:
            return True
        tracker = self.states.get(foreign, _key(agent, conversation_id))
        return tracker is None or tracker.is_finished

    def __len__(self) -> int:
        return len(self.states)
