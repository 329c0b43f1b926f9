"""A participant role's informs confirmed one at a time (services/runtime/roles/confirmed.py;
coordinate, paper §5.4, Figure 8): the next inform waits for the confirm of the one before,
a confirm of another inform changes nothing, a not-understood ends the wait, and the final
inform's confirm is told."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import Any

import msgspec
import pytest

from services.runtime.roles import (
    PARTICIPANT,
    ConfirmedInforms,
    RoleDecl,
    participant,
    role_problems,
    spec_roles,
)
from services.runtime.values import Received
from services.spec.model import default_spec
from shared.fipa_codec import AgentIdentifier, Communicate, Performative

DECL = participant("C1", "coordinate", "L_HFSM", "L_SW", confirmed_informs=True)


class Status(msgspec.Struct):
    n: int


@dataclass
class FakeHost:
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("test"))


@dataclass
class FakeRoles:
    host: FakeHost = field(default_factory=FakeHost)

    def peer_of(self, decl: RoleDecl) -> str:
        return "a_co"

    def open(self, *args: Any, **kwargs: Any) -> Any:
        raise AssertionError("a participant opens nothing")


@dataclass(eq=False)
class FakeConversation:
    """What ConfirmedInforms uses of a Conversation: ``send``, ``last`` and ``finished`` (a
    not-understood received ends it, as the protocol state would say)."""

    conversation_id: str = "plan-1"
    sent: list[tuple[int, float | None]] = field(default_factory=list)
    last: Received | None = None
    finished: bool = False

    def send(self, performative: Performative, content: Status, *, retry_s: float | None = None) -> str:
        assert performative is Performative.INFORM
        self.sent.append((content.n, retry_s))
        return f"r{len(self.sent)}"

    def receive(self, performative: Performative, in_reply_to: str) -> None:
        msg = Communicate(
            performative=performative,
            sender=AgentIdentifier("a_co"),
            receiver=(AgentIdentifier("a_ta"),),
            protocol="coordinate",
            conversation_id=self.conversation_id,
            in_reply_to=in_reply_to,
        )
        self.last = Received.of(msg, None, "C1")
        self.finished = self.finished or performative is Performative.NOT_UNDERSTOOD


def reports() -> tuple[ConfirmedInforms, Any]:
    return ConfirmedInforms(FakeRoles(), DECL, retry_s=5.0), FakeConversation()  # type: ignore[arg-type]


def test_one_inform_at_a_time_until_confirmed() -> None:
    r, conv = reports()
    r.inform(conv, Status(n=1))
    r.inform(conv, Status(n=2))
    r.inform(conv, Status(n=3), final=True)
    assert conv.sent == [(1, 5.0)] and r.awaiting
    conv.receive(Performative.CONFIRM, "r9")  # a confirm of another inform: nothing moves
    assert r.take(conv) is False and conv.sent == [(1, 5.0)]
    conv.receive(Performative.CONFIRM, "r1")
    assert r.take(conv) is False
    assert [n for n, _ in conv.sent] == [1, 2]
    conv.receive(Performative.CONFIRM, "r2")
    r.take(conv)
    assert [n for n, _ in conv.sent] == [1, 2, 3] and not r.final_confirmed(conv)
    conv.receive(Performative.CONFIRM, "r3")
    r.take(conv)
    assert r.final_confirmed(conv) and not r.awaiting
    r.done_with(conv)
    assert not r.final_confirmed(conv)


def test_a_not_understood_ends_the_conversation_and_other_communicates_go_to_the_handler() -> None:
    """The peer's not-understood ends the wait and the conversation (FIPA SC00037 §3.12): the
    informs still waiting in it are not sent, and a final one among them counts as confirmed
    (nobody will confirm it)."""
    r, conv = reports()
    r.inform(conv, Status(n=1))
    r.inform(conv, Status(n=2), final=True)
    conv.receive(Performative.CANCEL, "")
    assert r.take(conv) is True  # the agent's cancel handler takes it
    conv.receive(Performative.NOT_UNDERSTOOD, "r1")
    assert r.take(conv) is False
    assert r.final_confirmed(conv) and [n for n, _ in conv.sent] == [1]
    r.inform(conv, Status(n=3))
    assert [n for n, _ in conv.sent] == [1] and not r.awaiting


def test_only_a_participant_role_has_its_informs_confirmed() -> None:
    from services.runtime.roles import initiator

    with pytest.raises(TypeError):
        initiator("C1", "coordinate", "L_HFSM", confirmed_informs=True)  # type: ignore[call-arg]
    with pytest.raises(ValueError, match="confirmed_informs is for a participant"):
        RoleDecl("C1", "coordinate", "initiator", ("L_HFSM",), confirmed_informs=True)


def test_confirmed_informs_in_a_protocol_without_a_confirm_is_a_problem() -> None:
    """a_ta's coordinate role may have its informs confirmed; its participant role of a_km's
    subscription (fipa-subscribe: no confirm) may not."""
    spec = default_spec()
    declared = [
        replace(d, confirmed_informs=True) if d.role == PARTICIPANT else d for d in spec_roles(spec, "a_ta")
    ]
    problems = [p for p in role_problems(spec, "a_ta", declared, ()) if "confirmed one at a time" in p]
    assert problems == [
        "agent a_ta has its fipa-subscribe informs on C6 confirmed one at a time, but in "
        "[protocols.fipa-subscribe] the participant sends no inform or the initiator no confirm"
    ]
