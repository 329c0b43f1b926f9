"""a_co's progress towards the person (C2, fipa-subscribe, FIPA SC00035): progress made while
no subscription is agreed is kept and sent, in order, right after the next agree, so that none
is lost however late a_hi's subscribe comes; kept within bounds and across a restart."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.agents.coordinator import agent as coordinator
from services.agents.coordinator.agent import Coordinator
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.runtime.state_store import ENV_STATE_DIR
from services.spec.model import channel_between
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_ex import Wait
from shared.fipa_codec.languages.l_hc import (
    HumanCommand,
    Progress,
    ProgressSubscription,
    TaskAtom,
)
from shared.fipa_codec.languages.l_hfsm import Execute, HierarchicalPlan, PlanNode
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from tests.support.messages import communicate

P = Performative
POUR = HumanCommand(text="pour the jar into the bowl", goal=TaskAtom("pour", ("jar", "bowl")))


def plan_of(cid: str) -> HierarchicalPlan:
    """A plan of two leaves, ``pour/a`` and ``pour/b``, for command ``cid``."""
    leaves = tuple(PlanNode(name=n, action=Execute(Wait(duration=1.0))) for n in ("a", "b"))
    return HierarchicalPlan(
        plan_id=f"{cid}-p1", task_id=cid, root=PlanNode(name="pour", children=leaves), complete=True, cost=2.0
    )


class Wire:
    """One a_co on a MemoryBus; every communicate it publishes is collected."""

    def __init__(self) -> None:
        self.bus = MemoryBus()
        self.agent = Coordinator(self.bus.transport())
        self.out: list[Communicate] = []
        self.bus.subscribe(keys.FIPA_ALL, lambda _key, payload: self.out.append(decode(payload)))
        self.agent.engine.bind()

    def deliver(self, msg: Communicate, state: str = "trigger") -> None:
        """Take ``msg`` into a_co's input buffer, then run one step of behaviour ``state``."""
        assert msg.sender is not None
        channel = channel_between(self.agent.engine.spec, msg.sender.name, self.agent.name)
        assert channel is not None
        self.agent.engine.take(keys.fipa_key(channel.name, msg.sender.name, self.agent.name), encode(msg))
        self.agent.engine.protocol_states.commit()
        self.step(state)

    def step(self, state: str) -> None:
        self.agent.engine.fsm.states[state].transition()
        self.agent.engine.dispatch()
        self.agent.persist()

    def last(self, performative: Performative, receiver: str) -> Communicate:
        """The latest ``performative`` a_co sent ``receiver``."""
        return [m for m in self.out if m.performative is performative and m.receiver[0].name == receiver][-1]

    def sent(self, conversation: str) -> list[tuple[Performative, Progress | None]]:
        """What a_co sent a_hi in ``conversation``: (performative, the Progress it carried)."""
        said = []
        for m in self.out:
            if m.conversation_id != conversation or m.sender is None or m.sender.name != "a_co":
                continue
            term = decode_content(m.language, m.content) if m.language and m.content else None
            said.append((m.performative, term if isinstance(term, Progress) else None))
        return said


def command(w: Wire, cid: str = "cmd-1") -> None:
    """a_hi's command ``cid``; a_co agrees (procReq) and asks a_pl for plan #1 (compSP)."""
    w.deliver(
        communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", cid, POUR, reply_with=f"{cid}-r"), "procReq"
    )
    w.agent.engine.fsm.states["compSP"].on_enter()
    w.agent.engine.dispatch()
    w.agent.persist()


def subscribe(w: Wire, cid: str) -> None:
    w.deliver(
        communicate(
            P.SUBSCRIBE, "a_hi", "a_co", "fipa-subscribe", cid, ProgressSubscription(), reply_with=cid
        )
    )


def planned(w: Wire, cid: str = "cmd-1") -> None:
    """a_pl answers the plan request of ``cid``; a_co schedules it and sends it to a_ta."""
    asked = w.last(P.REQUEST, "a_pl")
    assert asked.conversation_id == f"{cid}-plan1"
    w.deliver(
        communicate(
            P.INFORM,
            "a_pl",
            "a_co",
            "fipa-request",
            asked.conversation_id,
            plan_of(cid),
            in_reply_to=asked.reply_with,
        ),
        "compSP",
    )
    w.step("schedule")
    w.step("switch")


def running(w: Wire, step: str) -> None:
    """a_ta reports it runs ``step`` of the plan a_co sent it (coordinate on C1)."""
    run = w.last(P.REQUEST, "a_ta")
    status = SWStatus(state=SWState.RUNNING, plan_id="cmd-1-p1", step=step)
    w.deliver(
        communicate(
            P.INFORM, "a_ta", "a_co", "coordinate", run.conversation_id, status, in_reply_to=run.reply_with
        )
    )


def words(said: list[tuple[Performative, Progress | None]]) -> list[str]:
    return [p.value if q is None else f"{q.state.value}:{q.step or q.detail}" for p, q in said]


def test_progress_made_before_the_subscription_follows_its_agree_in_order() -> None:
    w = Wire()
    command(w)
    planned(w)
    running(w, "pour/a")
    assert w.sent("hi-progress") == [] and len(w.agent.note.unsent) == 5
    # a_hi's subscribe comes late (its first attempt timed out at a_hi): agree, then every
    # change so far, each an inform answering the subscribe
    subscribe(w, "hi-progress")
    assert words(w.sent("hi-progress")) == [
        "agree",
        "waiting:accepted",
        "planning:plan #1 requested",
        "waiting:plan #1 ready",
        "running:plan cmd-1-p1",
        "running:pour/a",
    ]
    assert {m.in_reply_to for m in w.out if m.conversation_id == "hi-progress"} == {"hi-progress"}
    assert not w.agent.note.unsent
    running(w, "pour/b")  # later changes go at once
    assert words(w.sent("hi-progress"))[-1] == "running:pour/b"
    assert w.agent.counters["rejected"] == 0 and w.agent.counters["progress_dropped"] == 0


def test_progress_between_a_cancelled_subscription_and_the_next_is_sent_on_the_next() -> None:
    w = Wire()
    subscribe(w, "hi-progress")
    command(w)
    w.deliver(communicate(P.CANCEL, "a_hi", "a_co", "fipa-subscribe", "hi-progress", ProgressSubscription()))
    planned(w)
    subscribe(w, "hi-progress-2")
    assert words(w.sent("hi-progress")) == [
        "agree",
        "waiting:accepted",
        "planning:plan #1 requested",
        "inform",  # the answer to the cancel
    ]
    assert words(w.sent("hi-progress-2")) == ["agree", "waiting:plan #1 ready", "running:plan cmd-1-p1"]


def test_a_newer_subscription_takes_the_progress_and_none_is_sent_twice() -> None:
    """a_hi's attempt it gave up and its next attempt both reach a_co: what was kept goes
    once, on the first agreed, and later changes on the latest."""
    w = Wire()
    command(w)
    subscribe(w, "hi-progress")
    subscribe(w, "hi-progress-2")
    planned(w)
    assert words(w.sent("hi-progress")) == ["agree", "waiting:accepted", "planning:plan #1 requested"]
    assert words(w.sent("hi-progress-2")) == ["agree", "waiting:plan #1 ready", "running:plan cmd-1-p1"]


def test_what_is_kept_is_bounded_per_command_and_in_all(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(coordinator, "PROGRESS_KEPT_PER_COMMAND", 3)
    monkeypatch.setattr(coordinator, "PROGRESS_KEPT", 4)
    w = Wire()
    command(w)  # accepted, plan #1 requested
    planned(w)  # plan #1 ready, running: the oldest of cmd-1, accepted, goes
    assert [p.detail for p in w.agent.note.unsent] == ["plan #1 requested", "plan #1 ready", "plan cmd-1-p1"]
    command(w, "cmd-2")  # four in all at most: the oldest, plan #1 requested of cmd-1, goes
    assert [(p.command_id, p.detail) for p in w.agent.note.unsent] == [
        ("cmd-1", "plan #1 ready"),
        ("cmd-1", "plan cmd-1-p1"),
        ("cmd-2", "accepted"),
        ("cmd-2", "plan #1 requested"),
    ]
    assert w.agent.counters["progress_dropped"] == 2
    subscribe(w, "hi-progress")
    assert len(w.sent("hi-progress")) == 5 and not w.agent.note.unsent


def test_progress_not_yet_sent_is_kept_across_a_restart(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    first = Wire()
    command(first)
    second = Wire()  # a new process: nothing in memory
    second.agent.setup()
    subscribe(second, "hi-progress")
    assert words(second.sent("hi-progress")) == ["agree", "waiting:accepted", "planning:plan #1 requested"]


def test_an_agreed_subscription_is_taken_back_and_gets_the_progress_at_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """a_co serves its progress stream once the runtime took back what it kept: the agreed
    subscription kept across a restart takes it, without a new subscribe."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    first = Wire()
    subscribe(first, "hi-progress")
    first.agent.persist()
    second = Wire()  # a new process
    second.agent.setup()
    assert second.agent.progress.conversation is not None
    command(second)
    assert words(second.sent("hi-progress")) == ["waiting:accepted", "planning:plan #1 requested"]
