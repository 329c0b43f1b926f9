"""What the two agents of tests/runtime/test_roles.py share: their specification (a_i
initiates, a_p takes part in, every protocol roco knows, on one channel C1) and an agent that
answers by a script (data) and reports every step it handles. The agents themselves are in
role_initiator.py and role_participant.py: the module that declares an agent's roles is read
when it starts (services/runtime/code_scan.py), and each may name only what its roles send."""

from __future__ import annotations

import queue
from collections.abc import Callable
from typing import Any, ClassVar, Literal

import msgspec

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.roles import (
    INITIATOR,
    PARTICIPANT,
    Conversation,
    handles,
    incoming,
    optional,
    outgoing,
)
from services.spec.model import (
    AgentSpec,
    ChannelProtocol,
    ChannelSpec,
    ProtocolRoles,
    SystemSpec,
    default_spec,
)
from services.spec.protocol_defs import machine_of
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.protocols import PROTOCOLS, Protocol, Role

P = Performative
TIMEOUT = 10.0
NU = P.NOT_UNDERSTOOD
CANCEL = "cancel"
"""In a script: cancel the conversation (awaiting the answer)."""
Script = dict[tuple[str, str], list[tuple[Performative | Literal["cancel"], msgspec.Struct | None]]]
COORDINATE = "coordinate"
"""The paper's protocol (§5.4, Figure 8), declared in the shipped specification."""
MACHINES: dict[str, Protocol] = {**PROTOCOLS, COORDINATE: machine_of(default_spec(), COORDINATE)}
"""Every protocol roco knows: the eleven of the FIPA library and the specification's coordinate."""


def _spec() -> SystemSpec:
    """Two agents joined by C1, which carries every protocol of :data:`MACHINES`, a_i
    initiating; coordinate's table is the shipped specification's (its state machine)."""
    protocols = {
        name: ProtocolRoles(
            initiator=tuple(sorted(p.value for p in outgoing(m, INITIATOR) - {NU})),
            participant=tuple(sorted(p.value for p in outgoing(m, PARTICIPANT) - {NU})),
        )
        for name, m in PROTOCOLS.items()
    }
    protocols[COORDINATE] = default_spec().protocols[COORDINATE]
    channel = ChannelSpec(
        name="C1",
        ends=("a_i", "a_p"),
        transmits="everything",
        protocols=tuple(
            ChannelProtocol(
                protocol=name,
                initiator="a_i",
                languages={p.value: "L_SW" for p in outgoing(m, INITIATOR) | outgoing(m, PARTICIPANT) - {NU}},
            )
            for name, m in MACHINES.items()
        ),
    )
    agents = tuple(AgentSpec(name=n, group=n, implementation="tests:none") for n in ("a_i", "a_p"))
    # its stubs import roco's names module, which a test renders from this specification in its
    # place (tests/support/spec_names.py): no module of the checkout has to be written for it
    return SystemSpec(
        system="T", agents=agents, protocols=protocols, channels=(channel,), names="services.spec.names"
    )


SPEC = _spec()
RUNNING = SWStatus(state=SWState.RUNNING, plan_id="p")
DONE = SWStatus(state=SWState.SUCCEEDED, plan_id="p")


def handling_all(role: Role, fn: Callable[[Any, Conversation], None]) -> Callable[[Any, Conversation], None]:
    """A copy of ``fn`` marked as the handler of everything the other role may send in every
    protocol."""

    def handler(self: Any, conv: Conversation) -> None:
        fn(self, conv)

    for name, machine in MACHINES.items():
        perfs = sorted(incoming(machine, role) - optional(machine, role), key=lambda p: p.value)
        handler = handles(name, role, *perfs)(handler)
    return handler


class Scripted(Agent):
    """Answers by :attr:`script` ((protocol, performative received) → what to send) and puts
    every conversation step into :attr:`seen`; runs posted actions on its own thread."""

    script: ClassVar[Script]
    period = 0.01

    def build_fsm(self) -> FSM:
        self.seen: queue.SimpleQueue[tuple[str, str, Conversation]] = queue.SimpleQueue()
        self.fault: str | None = None  # a protocol whose handler raises
        self.silent: set[str] = set()  # protocols whose handler answers nothing
        return FSM([Behaviour("run", self._run, terminal=lambda: False)])

    def _run(self) -> None:
        while self.r:
            action = self.r.popleft()
            if action is not None:
                action(self)
        self.handle_received()

    def handle(self, conv: Conversation) -> None:
        assert conv.last is not None
        protocol, said = conv.decl.protocol, conv.last.performative.value
        self.seen.put((protocol, "deadline" if conv.timed_out else said, conv))
        if protocol == self.fault:
            raise RuntimeError("a planted fault")
        played = conv.data if isinstance(conv.data, set) else set()
        conv.data = played
        step = (protocol, said, repr(conv.content))
        if protocol in self.silent or conv.finished or step in played:
            return  # each step of the script plays once per conversation and content
        played.add(step)
        for performative, content in self.script.get((protocol, said), []):
            if isinstance(performative, Performative):
                conv.reply(performative, content)
            else:
                conv.cancel(reply_by_s=TIMEOUT)

    def do(self, action: Callable[[Scripted], object]) -> None:
        self.post(action)

    def next(self) -> tuple[str, str, Conversation]:
        return self.seen.get(timeout=TIMEOUT)
