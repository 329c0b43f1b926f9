"""a_s of tests/runtime/test_served.py: on C1 with a_i (whose communicates the tests deliver by
hand), the participant of a fipa-subscribe it serves through its role (services/runtime/roles/served.py)
and of a fipa-request whose cancels it answers later, and the initiator of a fipa-query.
The module that declares an agent's roles is read when it starts (services/runtime/code_scan.py)."""

from __future__ import annotations

from typing import Any

import msgspec

from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.roles import (
    INITIATOR,
    PARTICIPANT,
    Conversation,
    ServedSubscription,
    handles,
    initiator,
    outgoing,
    participant,
)
from services.runtime.transport import Transport
from services.spec.model import AgentSpec, ChannelProtocol, ChannelSpec, ProtocolRoles, SystemSpec
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.protocols import PROTOCOLS

P = Performative
NU = P.NOT_UNDERSTOOD
SUBSCRIBE, REQUEST, QUERY = "fipa-subscribe", "fipa-request", "fipa-query"
KEPT_EACH, KEPT_IN_ALL = 2, 3


def _spec() -> SystemSpec:
    """a_i and a_s joined by C1: a_i subscribes and requests, a_s queries, all in L_SW."""
    initiators = {SUBSCRIBE: "a_i", REQUEST: "a_i", QUERY: "a_s"}
    protocols = {
        name: ProtocolRoles(
            initiator=tuple(sorted(p.value for p in outgoing(PROTOCOLS[name], INITIATOR) - {NU})),
            participant=tuple(sorted(p.value for p in outgoing(PROTOCOLS[name], PARTICIPANT) - {NU})),
        )
        for name in initiators
    }
    channel = ChannelSpec(
        name="C1",
        ends=("a_i", "a_s"),
        transmits="statuses",
        protocols=tuple(
            ChannelProtocol(
                protocol=name,
                initiator=who,
                languages={
                    p.value: "L_SW"
                    for p in outgoing(PROTOCOLS[name], INITIATOR) | outgoing(PROTOCOLS[name], PARTICIPANT)
                    if p is not NU
                },
            )
            for name, who in initiators.items()
        ),
    )
    agents = tuple(AgentSpec(name=n, group=n, implementation="tests:none") for n in ("a_i", "a_s"))
    return SystemSpec(system="T", agents=agents, protocols=protocols, channels=(channel,))


SPEC = _spec()


class ServerNote(msgspec.Struct, kw_only=True):
    """What a_s keeps across a restart: the statuses not yet sent to a subscriber."""

    unsent: list[SWStatus] = msgspec.field(default_factory=list)


class Server(Agent):
    name = "a_s"
    NOTE = ServerNote
    note: ServerNote
    ROLES = (
        participant("C1", SUBSCRIBE, "L_SW", keep=True),
        participant("C1", REQUEST, "L_SW"),
        initiator("C1", QUERY, "L_SW", reply_by_s=60.0),
    )

    def __init__(self, transport: Transport, spec: SystemSpec | None = None) -> None:
        self.cancels: list[tuple[Conversation, Received]] = []  # to be answered later
        self.why: list[str] = []  # Conversation.explanation of every negative answer to a query
        self.answered: list[Any] = []  # what the queries were answered
        super().__init__(transport, spec or SPEC)
        # served once the runtime took back what it kept: a kept subscription takes the stream
        self.stream = self.serve_statuses()

    def serve_statuses(self) -> ServedSubscription[SWStatus]:
        """The role's stream of statuses (services/runtime/roles/served.py)."""
        return self.roles.serve(
            "C1",
            SUBSCRIBE,
            unsent=lambda: self.note.unsent,
            about=lambda status: status.plan_id,
            kept_each=KEPT_EACH,
            kept_in_all=KEPT_IN_ALL,
            dropped="statuses_dropped",
        )

    def build_fsm(self) -> FSM:
        return FSM([Behaviour("serve", self.handle_received, terminal=lambda: False)])

    @handles(SUBSCRIBE, PARTICIPANT, P.SUBSCRIBE)
    def on_subscribe(self, conv: Conversation) -> None:
        if isinstance(conv.content, SWStatus):
            self.stream.agree(conv)
        else:
            conv.refuse_with(P.REFUSE, "statuses only")

    @handles(REQUEST, PARTICIPANT, P.REQUEST)
    def on_request(self, conv: Conversation) -> None:
        conv.reply(P.AGREE)

    @handles(REQUEST, PARTICIPANT, P.CANCEL)
    def on_cancel(self, conv: Conversation) -> None:
        assert conv.last is not None
        self.cancels.append((conv, conv.last))

    @handles(QUERY, INITIATOR, P.INFORM, P.INFORM_REF)
    def on_answer(self, conv: Conversation) -> None:
        self.answered.append(conv.content)

    @handles(QUERY, INITIATOR, P.REFUSE, P.FAILURE)
    def on_no_answer(self, conv: Conversation) -> None:
        self.why.append(conv.explanation)
