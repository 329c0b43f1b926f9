"""Nothing lost, nothing done twice: retransmission until answered, copies dropped
and answered from memory, and the agents' kept state across a restart (a_co's queue, a_ta's
plan, a_hi's open commands). The agents are driven by hand on a MemoryBus: no threads, no
sleeps; time is moved by setting a pending entry's retransmission time."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Generic, TypeVar

import msgspec
import pytest

from services.agents.coordinator.agent import Coordinator
from services.agents.human_interface.agent import HumanInterface
from services.agents.knowledge.agent import KnowledgeManager
from services.agents.task_executor.agent import PlanNote, TaskExecutor
from services.runtime import keys
from services.runtime.agent import RESEND_ON_RETURN, Agent
from services.runtime.dedup import ANSWERS_PER_REQUEST, Dedup
from services.runtime.human import HumanReport, ReportKind
from services.runtime.memory_transport import MemoryBus, MemoryTransport
from services.runtime.replies import Pending, PendingReplies
from services.runtime.state_store import ENV_STATE_DIR, KeptConversation, KeptConversations, StateFile
from services.spec.model import channel_between
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Wait
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, StatusQuery, TaskAtom, TaskState
from shared.fipa_codec.languages.l_hfsm import Execute, GroundTaskNetwork, HierarchicalPlan, PlanNode
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation
from shared.fipa_codec.languages.l_sw import SWState, SWStatus
from shared.fipa_codec.languages.l_wm import ObjectUpdate, Subscription, WorldUpdate
from tests.support.messages import communicate

P = Performative
POUR = HumanCommand(text="pour the jar into the bowl", goal=TaskAtom("pour", ("jar", "bowl")))
PLAN = HierarchicalPlan(
    plan_id="cmd-1-p1",
    task_id="cmd-1",
    root=PlanNode(name="pour", children=(PlanNode(name="wait", action=Execute(Wait(duration=1.0))),)),
    complete=True,
    cost=1.0,
)


A = TypeVar("A", bound=Agent)


class Wire(Generic[A]):
    """One agent on a MemoryBus, with every communicate published on the bus collected."""

    def __init__(self, cls: type[A], bus: MemoryBus | None = None) -> None:
        self.bus = bus or MemoryBus()
        self.agent = cls(self.bus.transport())
        self.out: list[Communicate] = []
        self.raw: list[bytes] = []
        self.bus.subscribe(keys.FIPA_ALL, self._collect)
        self.agent.engine.bind()

    def _collect(self, key: str, payload: bytes) -> None:
        self.raw.append(payload)
        self.out.append(decode(payload))

    def deliver(self, msg: Communicate | bytes) -> None:
        """Acquire ``msg`` on the channel between its sender and the agent, then dispatch."""
        payload = msg if isinstance(msg, bytes) else encode(msg)
        sender = decode(payload).sender
        assert sender is not None
        channel = channel_between(self.agent.engine.spec, sender.name, self.agent.name)
        assert channel is not None
        self.agent.engine.take(keys.fipa_key(channel.name, sender.name, self.agent.name), payload)
        self.agent.engine.protocol_states.commit()
        self.agent.engine.dispatch()

    def step(self, state: str) -> None:
        """One elementary action of behaviour ``state``: transition, dispatch, new inputs."""
        self.agent.engine.fsm.states[state].transition()
        self.agent.engine.dispatch()
        self.agent.persist()
        self.agent.engine.acquire()

    def mine(self, *performatives: Performative) -> list[Communicate]:
        return [
            m
            for m in self.out
            if m.sender is not None
            and m.sender.name == self.agent.name
            and (not performatives or m.performative in performatives)
        ]


# ---- the building blocks ------------------------------------------------------------------


def test_a_pending_entry_is_retransmitted_on_schedule_until_answered() -> None:
    c = PendingReplies()
    c.expect(
        Pending(
            "r1", "a_pl", "fipa-request", "c1", 100.0, retry_s=5.0, key="k", payload=b"x", next_retry=10.0
        )
    )
    assert c.due(9.9) == [] and c.next_deadline() == 10.0
    (p,) = c.due(10.0)
    assert (p.key, p.payload, p.retransmissions, p.next_retry) == ("k", b"x", 1, 15.0)
    assert c.retry_now("a_km", 11.0) == 0 and c.retry_now("a_pl", 11.0) == 1
    assert [e.reply_with for e in c.due(11.0)] == ["r1"]
    c.answered("r1", "agree")  # any answer: the peer has it
    assert c.due(1e9) == [] and c.retry_now("a_pl", 12.0) == 0 and c.knows("r1")


def test_resend_on_return_is_never_periodic() -> None:
    c = PendingReplies()
    c.expect(
        Pending(
            "r1",
            "ag_ex",
            "fipa-request",
            "c1",
            None,
            retry_s=math.inf,
            key="k",
            payload=b"x",
            next_retry=math.inf,
        )
    )
    assert c.due(1e12) == [] and c.next_deadline() is None
    assert c.retry_now("ag_ex", 5.0) == 1 and len(c.due(5.0)) == 1 and c.due(1e12) == []


def test_dedup_remembers_a_bounded_number_of_communicates() -> None:
    d = Dedup(capacity=2)
    assert [d.seen(b"a"), d.seen(b"b"), d.seen(b"a")] == [False, False, True]
    d.seen(b"c")  # evicts b, the least recently seen
    assert d.seen(b"a") and not d.seen(b"b")
    d.answered("a_hi", "r1", "k", b"agree")
    d.answered("a_hi", "r1", "k", b"inform")
    assert d.answers("a_hi", "r1") == [("k", b"agree"), ("k", b"inform")] and d.answers("a_hi", None) == []
    for i in range(3 * ANSWERS_PER_REQUEST):  # a subscription's stream: the first answers are kept
        d.answered("a_hi", "s1", "k", b"inform %d" % i)
    kept = d.answers("a_hi", "s1")
    assert len(kept) == ANSWERS_PER_REQUEST and kept[0] == ("k", b"inform 0")
    with pytest.raises(ValueError):
        Dedup(capacity=0)


def test_a_state_file_is_written_only_on_change_and_a_corrupt_one_is_set_aside(tmp_path: Path) -> None:
    f = StateFile(tmp_path / "a.json", dict[str, int])
    assert f.load() is None and f.save({"n": 1}) and not f.save({"n": 1}) and f.save({"n": 2})
    assert StateFile(tmp_path / "a.json", dict[str, int]).load() == {"n": 2}
    (tmp_path / "a.json").write_text("{not json")
    assert StateFile(tmp_path / "a.json", dict[str, int]).load() is None
    assert (tmp_path / "a.corrupt").exists() and not (tmp_path / "a.json").exists()
    assert StateFile(None, dict[str, int]).save({"n": 1}) is False


# ---- the runtime ------------------------------------------------------------------------


def test_a_copy_is_not_handled_again_but_its_answer_is_sent_again() -> None:
    w = Wire(Coordinator)
    query = communicate(P.QUERY_REF, "a_hi", "a_co", "fipa-query", "status-1", StatusQuery(), reply_with="q1")
    w.deliver(query)
    w.step("trigger")
    (answer,) = w.mine(P.INFORM_REF)
    w.deliver(query)  # the same bytes again: a_hi did not hear the answer
    assert w.agent.counters["duplicates"] == 1 and w.agent.counters["replayed"] == 1
    assert not w.agent.engine.x  # not handled a second time
    assert w.mine(P.INFORM_REF) == [answer, answer]


def test_an_unanswered_request_is_retransmitted_and_stops_when_answered() -> None:
    w = Wire(Coordinator)
    gtn = GroundTaskNetwork(task_id="cmd-1", tasks=(POUR.goal,), plan_index=1)
    msg = w.agent.engine.send("a_pl", P.REQUEST, gtn, protocol="fipa-request", retry_s=5.0)
    w.agent.engine.dispatch()
    assert msg.reply_with is not None
    pending = w.agent.engine.pending_replies._pending[msg.reply_with]
    pending.next_retry = 0.0  # its time has come
    w.agent.engine.pending_replies.expect(pending)  # moved by hand: expected again, so it is looked at
    w.agent.engine.acquire()
    w.agent.engine.dispatch()
    first, again = [raw for raw, m in zip(w.raw, w.out, strict=True) if m.reply_with == msg.reply_with]
    assert first == again and w.agent.counters["retransmitted"] == 1
    w.deliver(
        communicate(
            P.FAILURE, "a_pl", "a_co", "fipa-request", msg.conversation_id, in_reply_to=msg.reply_with
        ),
    )
    assert pending.next_retry is None


def test_a_request_to_a_peer_that_comes_back_is_sent_to_it_again() -> None:
    bus = MemoryBus()
    w = Wire(TaskExecutor, bus)
    msg = w.agent.engine.send(
        "ag_ex", P.REQUEST, Wait(duration=1.0), protocol="fipa-request", retry_s=RESEND_ON_RETURN
    )
    w.agent.engine.dispatch()
    ag_ex = bus.transport()
    ag_ex.announce(keys.alive_key("ag_ex"))
    w.agent.engine.acquire()
    w.agent.engine.dispatch()
    assert len([m for m in w.out if m.reply_with == msg.reply_with]) == 2
    assert "ag_ex" in w.agent.peers
    ag_ex.close()  # it goes away: nothing is sent to nobody
    w.agent.engine.acquire()
    assert "ag_ex" not in w.agent.peers and w.agent.counters["retransmitted"] == 1


# ---- the agents' kept state -------------------------------------------------------------


def test_a_restarted_a_co_keeps_the_accepted_command_and_does_not_take_it_twice(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    request = encode(communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", POUR, reply_with="r1"))
    first = Wire(Coordinator)
    first.deliver(request)
    first.step("procReq")
    assert [m.performative for m in first.mine()] == [P.AGREE]
    assert (tmp_path / "a_co.json").exists()

    second = Wire(Coordinator)  # a new process: nothing in memory
    second.agent.setup()
    assert list(second.agent.tasks) == ["cmd-1"] and second.agent.tasks["cmd-1"].command == POUR
    second.deliver(request)  # a_hi retransmitted: a copy the new a_co has never seen
    second.step("procReq")
    assert second.agent.counters["repeated_requests"] == 1 and not second.mine(P.REFUSE, P.AGREE)
    # the restored conversation goes on: the person's cancel is handled, not refused
    second.deliver(communicate(P.CANCEL, "a_hi", "a_co", "fipa-request", "cmd-1", POUR, reply_with="x1"))
    second.step("procReq")
    assert second.agent.counters["rejected"] == 0
    (stopped,) = second.mine(P.INFORM)
    assert stopped.conversation_id == "cmd-1" and stopped.in_reply_to == "x1"


def test_a_request_taken_back_and_ended_is_not_taken_again_when_it_comes_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """a_co took a command back after its restart and the command ended (here: stopped); then
    a_hi, restarted too before it heard the end, sends its kept request again — the first this
    a_co receives. It is not opened anew (the command would run twice: chaos seed 12), but
    answered with what this a_co answered it, and counted."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    request = encode(communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", POUR, reply_with="r1"))
    first = Wire(Coordinator)
    first.deliver(request)
    first.step("procReq")
    second = Wire(Coordinator)  # a new process: it takes the command back from its state file
    second.agent.setup()
    second.deliver(communicate(P.CANCEL, "a_hi", "a_co", "fipa-request", "cmd-1", POUR, reply_with="x1"))
    second.step("procReq")
    (stopped,) = second.mine(P.INFORM)
    assert stopped.in_reply_to == "x1" and "cmd-1" not in second.agent.tasks
    second.deliver(request)
    second.step("procReq")
    assert second.agent.counters["repeated_requests"] == 1 and second.agent.counters["duplicates"] == 0
    assert not second.mine(P.AGREE, P.REFUSE) and "cmd-1" not in second.agent.tasks


def test_a_restarted_a_co_goes_on_with_the_plan_a_ta_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    first = Wire(Coordinator)
    first.deliver(communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", POUR, reply_with="r1"))
    first.step("procReq")
    task = first.agent.tasks["cmd-1"]
    task.note.plan, task.needs_plan = PLAN, False
    first.agent.reschedule = True
    first.step("schedule")
    first.step("switch")
    (run,) = first.mine(P.REQUEST)
    assert first.agent.ta is not None and run.conversation_id == first.agent.ta.conversation_id

    second = Wire(Coordinator)
    second.agent.setup()
    assert second.agent.note.ta_task == "cmd-1" and second.agent.tasks["cmd-1"].note.plan == PLAN
    # a_ta's reports go on in the plan's conversation: each is confirmed (the restored
    # conversation does not know what the previous a_co sent, so it takes every report)
    running = SWStatus(state=SWState.RUNNING, plan_id=PLAN.plan_id, step="pour(jar,bowl)/grasp")
    done = SWStatus(state=SWState.SUCCEEDED, plan_id=PLAN.plan_id)
    for status, reply_with in ((running, "s8"), (done, "s9")):
        second.deliver(
            communicate(
                P.INFORM,
                "a_ta",
                "a_co",
                "coordinate",
                run.conversation_id,
                status,
                reply_with=reply_with,
                in_reply_to=run.reply_with,  # a_ta's reports answer the plan's request
            )
        )
        second.step("trigger")
    assert second.agent.counters["rejected"] == 0 and second.agent.counters["late_replies"] == 0
    # both confirmed; the person told
    assert [m.performative for m in second.mine()] == [P.CONFIRM, P.CONFIRM, P.INFORM]
    assert [m.in_reply_to for m in second.mine(P.CONFIRM)] == ["s8", "s9"]
    assert second.mine(P.INFORM)[0].conversation_id == "cmd-1" and not second.agent.tasks


def keep_a_ta_plan(folder: Path, request: Communicate, note: PlanNote, state: str = "running") -> None:
    """Write in ``folder`` a_ta's state file as an a_ta that ran ``request``'s plan keeps it:
    the coordinate role's conversation, kept in protocol ``state`` with a_ta's ``note``."""
    data = msgspec.Raw(msgspec.json.encode(note))
    kept = KeptConversation(
        channel="C1", protocol="coordinate", state=state, opening=encode(request), data=data
    )
    (folder / "a_ta.json").write_bytes(msgspec.json.encode(KeptConversations(conversations=[kept])))


def restarted_a_ta_in_the_wait(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> tuple[Communicate, Wire[TaskExecutor]]:
    """a_co's plan request, and an a_ta restarted (set up) from its state file kept in
    ``tmp_path`` while it ran that plan's ``pour/wait`` leaf."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    request = communicate(P.REQUEST, "a_co", "a_ta", "coordinate", "cmd-1-exec1", PLAN, reply_with="p1")
    keep_a_ta_plan(tmp_path, request, PlanNote(step="pour/wait"))
    w = Wire(TaskExecutor)
    w.agent.setup()
    return request, w


def test_a_restarted_a_ta_reports_replan_in_the_plans_conversation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, w = restarted_a_ta_in_the_wait(tmp_path, monkeypatch)
    # it reports only once the scene is observed and a_km informed (a held object's pose
    # decides how the next plan begins): a_km subscribes, a_ta asks ag_ex to observe
    assert not w.agent.engine.fsm.states["idle"].terminal()
    w.deliver(
        communicate(P.SUBSCRIBE, "a_km", "a_ta", "fipa-subscribe", "km-env", Subscription(), reply_with="s")
    )
    w.step("idle")
    (observe,) = [m for m in w.mine(P.REQUEST) if m.receiver[0].name == "ag_ex"]
    assert not w.agent.engine.fsm.states["idle"].terminal()
    seen = Observation(stamp=3.0, objects=(ObjectObservation(name="jar", pose=Pose((0.7, 0.2, 0.85))),))
    w.deliver(
        communicate(
            P.INFORM,
            "ag_ex",
            "a_ta",
            "fipa-request",
            observe.conversation_id,
            seen,
            in_reply_to=observe.reply_with,
        )
    )
    w.step("idle")
    (update,) = [m for m in w.mine(P.INFORM) if m.receiver[0].name == "a_km"]
    assert msgspec.msgpack.decode(update.content, type=WorldUpdate).objects[0].name == "jar"
    assert w.agent.engine.fsm.states["idle"].terminal()
    assert w.agent.engine.fsm.next_state("idle") == "finished"
    w.agent.engine.fsm.states["finished"].on_enter()
    w.agent.engine.dispatch()
    (report,) = [m for m in w.mine(P.INFORM) if m.receiver[0].name == "a_co"]
    status = msgspec.msgpack.decode(report.content, type=SWStatus)
    assert report.conversation_id == "cmd-1-exec1" and report.in_reply_to == "p1"
    assert status.state is SWState.REPLAN and "a_ta restarted in pour/wait" in (status.reason or "")
    confirm = communicate(
        P.CONFIRM, "a_co", "a_ta", "coordinate", "cmd-1-exec1", in_reply_to=report.reply_with
    )
    w.deliver(confirm)
    w.step("finished")
    assert w.agent.plan is None
    assert not msgspec.json.decode(
        (tmp_path / "a_ta.json").read_bytes(), type=KeptConversations
    ).conversations


def a_hi_that_sent_the_pour(
    request_id: str,
) -> tuple[MemoryBus, list[HumanReport], Wire[HumanInterface], Communicate]:
    """An a_hi on a new bus that took the person's "pour the jar into the bowl" (``request_id``)
    and sent its request to a_co: the bus, the person's reports as they come, a_hi, the request."""
    from services.runtime.human import HumanInput

    bus = MemoryBus()
    reports: list[HumanReport] = []
    bus.subscribe(keys.HUMAN_OUT, lambda k, p: reports.append(msgspec.json.decode(p, type=HumanReport)))
    first = Wire(HumanInterface, bus)
    first.agent.setup()
    first.agent.post(HumanInput(text="pour the jar into the bowl", request_id=request_id))
    first.agent.engine.acquire()
    first.step("interact")  # the line goes to a_hi's reader (reading.py) …
    for _ in range(30):  # … and once it is read (ReadDone), the command goes to a_co
        if first.mine(P.REQUEST):
            break
        first.agent.engine.acquire(timeout=1.0)
        first.step("interact")
    (request,) = first.mine(P.REQUEST)
    return bus, reports, first, request


def test_a_restarted_a_hi_still_tells_the_person_the_outcome(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    bus, reports, _first, request = a_hi_that_sent_the_pour("req-7")
    assert request.protocol == "fipa-request" and (tmp_path / "a_hi.json").exists()

    second = Wire(HumanInterface, bus)
    second.agent.setup()
    cid = request.conversation_id
    assert cid in second.agent.commands
    second.agent.engine.acquire()
    second.agent.engine.dispatch()  # not yet agreed: the request goes again at once
    assert [m.reply_with for m in second.mine(P.REQUEST)] == [request.reply_with]
    outcome = CommandOutcome(command_id=cid or "", succeeded=True, detail="the task succeeded")
    second.deliver(communicate(P.AGREE, "a_co", "a_hi", "fipa-request", cid, in_reply_to=request.reply_with))
    second.deliver(
        communicate(P.INFORM, "a_co", "a_hi", "fipa-request", cid, outcome, in_reply_to=request.reply_with),
    )
    second.step("interact")
    assert [r.kind for r in reports if r.request_id == "req-7"][-1] is ReportKind.SUCCEEDED
    assert second.agent.counters["rejected"] == 0


def test_a_restarted_a_hi_asks_again_for_an_agreed_command_whose_outcome_came_while_it_was_down(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """a_co agreed, then a_hi was killed, and a_co's final inform went while it was down: the
    restarted a_hi sends the request again (the same bytes), and a_co's answers to it, the agree
    and the outcome as it sent them, end the command; the person is told "accepted" once."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    bus, reports, first, request = a_hi_that_sent_the_pour("req-8")
    cid = request.conversation_id or ""
    agree = communicate(P.AGREE, "a_co", "a_hi", "fipa-request", cid, in_reply_to=request.reply_with)
    first.deliver(agree)
    first.step("interact")
    assert first.agent.commands[cid].agreed
    # a_hi is killed; a_co's outcome is sent meanwhile and lost

    second = Wire(HumanInterface, bus)
    second.agent.setup()
    second.agent.engine.acquire()
    second.agent.engine.dispatch()
    assert [m.reply_with for m in second.mine(P.REQUEST)] == [request.reply_with]  # agreed, asked again
    outcome = CommandOutcome(command_id=cid, succeeded=True, detail="the task succeeded")
    second.deliver(agree)  # a_co answers the repeated request as it answered it
    second.deliver(
        communicate(P.INFORM, "a_co", "a_hi", "fipa-request", cid, outcome, in_reply_to=request.reply_with)
    )
    second.step("interact")
    kinds = [r.kind for r in reports if r.request_id == "req-8"]
    assert kinds[-1] is ReportKind.SUCCEEDED and kinds.count(ReportKind.ACCEPTED) == 1, kinds
    assert second.agent.counters["rejected"] == 0 and cid not in second.agent.commands


def a_co_with_the_pour_planned() -> tuple[MemoryBus, Wire[Coordinator], MemoryTransport]:
    """An a_co that took a_hi's pour command (task ``cmd-1``) and holds its plan, not yet
    sent; the bus and a_ta's transport, its token announced."""
    bus = MemoryBus()
    co = Wire(Coordinator, bus)
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))
    co.deliver(communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", POUR, reply_with="r1"))
    co.step("procReq")
    task = co.agent.tasks["cmd-1"]
    task.note.plan, task.needs_plan = PLAN, False
    return bus, co, ta


def test_a_co_probes_an_a_ta_that_reappears_and_plans_again_when_it_lost_the_plan() -> None:
    bus, co, ta = a_co_with_the_pour_planned()
    task = co.agent.tasks["cmd-1"]
    co.agent.reschedule = True
    co.step("schedule")
    co.step("switch")
    (run,) = co.mine(P.REQUEST)
    running = SWStatus(state=SWState.RUNNING, plan_id=PLAN.plan_id, step="pour/wait")
    co.deliver(
        communicate(P.INFORM, "a_ta", "a_co", "coordinate", run.conversation_id, running, reply_with="s1")
    )
    co.step("trigger")
    (confirm,) = co.mine(P.CONFIRM)
    ta.close()  # a_ta's process ends ...
    co.agent.engine.acquire()
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))  # ... and a new one starts
    co.agent.engine.acquire()
    co.agent.engine.dispatch()
    assert co.mine(P.CONFIRM) == [confirm, confirm]  # the probe: the same confirm again
    # the same a_ta would drop the copy; a new one does not know the conversation
    co.deliver(communicate(P.NOT_UNDERSTOOD, "a_ta", "a_co", "coordinate", run.conversation_id))
    co.step("trigger")
    assert co.agent.note.ta_task is None and task.note.state is TaskState.PLANNING and task.needs_plan
    assert "cmd-1" in co.agent.tasks  # planned again, not failed


def test_a_plan_sent_while_a_ta_is_gone_goes_again_when_it_reappears_and_only_then() -> None:
    """Chaos across hosts (seed 2, --realtime): the robot's router was killed just as a_co sent
    a_ta its next plan; the plan reached nobody, a_ta came back with nothing to run, and the
    command waited for ever. The coordinate request is now sent again when a_ta's token
    reappears, until a_ta answers it — and not once it has."""
    bus, co, ta = a_co_with_the_pour_planned()
    ta.close()  # the robot's router dies: a_ta's token is gone ...
    co.agent.engine.acquire()
    co.agent.reschedule = True
    co.step("schedule")
    co.step("switch")  # ... and the plan is sent into the void
    (plan,) = [co.raw[i] for i, m in enumerate(co.out) if m.performative is P.REQUEST]
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))  # the router is back: a_ta's token reappears
    co.agent.engine.acquire()
    co.agent.engine.dispatch()
    again = [co.raw[i] for i, m in enumerate(co.out) if m.performative is P.REQUEST]
    assert again == [plan, plan]  # the same bytes: an a_ta that had it drops the copy
    run = decode(plan)
    running = SWStatus(state=SWState.RUNNING, plan_id=PLAN.plan_id, step="pour/wait")
    answer = communicate(
        P.INFORM, "a_ta", "a_co", "coordinate", run.conversation_id, running, in_reply_to=run.reply_with
    )
    co.deliver(answer)
    ta.close()
    co.agent.engine.acquire()
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))
    co.agent.engine.acquire()
    co.agent.engine.dispatch()
    assert len([m for m in co.out if m.performative is P.REQUEST]) == 2  # answered: not again


def test_a_restarted_a_ta_reports_the_final_state_it_had_reached_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Killed after it informed a_co of its final state (coordinate's ``ending``, where a_ta
    may send nothing), a_ta takes the plan's conversation back in ``running`` (the role's
    ``resume_in``) and reports that state again."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    request = communicate(P.REQUEST, "a_co", "a_ta", "coordinate", "cmd-1-exec1", PLAN, reply_with="p1")
    keep_a_ta_plan(tmp_path, request, PlanNote(outcome=SWState.SUCCEEDED), state="ending")
    w = Wire(TaskExecutor)
    assert w.agent.plan_request is not None and w.agent.plan_request.state == "running"
    w.agent.engine.fsm.states["finished"].on_enter()
    w.agent.engine.dispatch()
    (report,) = [m for m in w.mine(P.INFORM) if m.receiver[0].name == "a_co"]
    assert msgspec.msgpack.decode(report.content, type=SWStatus).state is SWState.SUCCEEDED
    assert w.agent.counters["protocol_violations"] == 0


def test_a_ta_keeps_the_plan_it_runs_after_a_not_understood_ended_its_conversation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """a_co restarted with nothing kept answers a_ta's report not-understood, which ends the
    plan's conversation; a_ta runs the plan on, and the role keeps the conversation for as long
    as a_ta holds it (its note set): restarted, a_ta takes it back and reports on the plan. The
    state file is written only when what it keeps changed."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    first = Wire(TaskExecutor)
    first.deliver(communicate(P.REQUEST, "a_co", "a_ta", "coordinate", "cmd-1-exec1", PLAN, reply_with="p1"))
    first.step("idle")
    ta = first.agent
    ta.engine.state = "running"
    ta.engine.fsm.states["running"].on_enter()  # informs a_co: Running
    first.agent.engine.dispatch()
    (running,) = [m for m in first.mine(P.INFORM) if m.receiver[0].name == "a_co"]
    first.deliver(
        communicate(
            P.NOT_UNDERSTOOD, "a_co", "a_ta", "coordinate", "cmd-1-exec1", in_reply_to=running.reply_with
        )
    )
    first.step("running")  # goes on: the plan's first leaf is sent to ag_ex
    assert ta.plan_request is not None and ta.plan_request.finished and ta.step is not None
    (kept,) = msgspec.json.decode((tmp_path / "a_ta.json").read_bytes(), type=KeptConversations).conversations
    assert msgspec.json.decode(kept.data, type=PlanNote) == PlanNote(step="pour/wait")
    saved: list[KeptConversations] = []
    assert ta.engine._kept is not None
    monkeypatch.setattr(ta.engine._kept, "save", saved.append)
    first.step("running")  # nothing changed (ag_ex has not answered): not encoded, not written
    ta.persist()
    assert saved == []

    second = Wire(TaskExecutor)
    assert second.agent.plan_request is not None and second.agent.plan_request.state == "running"
    assert second.agent.outcome is SWState.REPLAN
    assert second.agent.reason == "a_ta restarted in pour/wait; the robot held position"


def test_an_a_ta_state_file_of_the_earlier_format_is_set_aside(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    request = communicate(P.REQUEST, "a_co", "a_ta", "coordinate", "cmd-1-exec1", PLAN, reply_with="p1")
    earlier = {"request": encode(request), "step": "pour/wait", "outcome": None, "reason": None}
    (tmp_path / "a_ta.json").write_bytes(msgspec.json.encode(earlier))
    w = Wire(TaskExecutor)
    assert w.agent.plan is None and (tmp_path / "a_ta.corrupt").exists()
    assert any("does not decode" in r.getMessage() for r in caplog.records)


def test_a_restarted_a_ta_does_not_queue_again_the_plan_request_it_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    request, w = restarted_a_ta_in_the_wait(tmp_path, monkeypatch)
    assert w.agent.plan_request is not None  # restored: it reports Replan on this plan
    w.deliver(request)  # a_co's copy, sent again as this a_ta's token appeared
    w.step("idle")
    assert not w.agent.requests  # the kept plan is reported on, not run a second time
    other = communicate(P.REQUEST, "a_co", "a_ta", "coordinate", "cmd-1-exec2", PLAN, reply_with="p2")
    w.deliver(other)
    w.step("idle")
    assert len(w.agent.requests) == 1  # a new plan is queued as before


def test_an_update_a_ta_sent_before_a_kms_new_subscription_is_taken_not_dropped() -> None:
    """Chaos across hosts (seed 2, --realtime): the robot's router was killed while a_ta
    localised the bowl; when a_ta's token reappeared a_km subscribed again (same
    conversation-id) and a_ta's update, sent in the first subscription, arrived after that: it
    was dropped as a late reply, a_km never learnt where the bowl stood, and a_pl found "no way
    to pour". It is now taken as the update it is."""
    bus = MemoryBus()
    km = Wire(KnowledgeManager, bus)
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))
    km.agent.setup()
    km.agent.engine.acquire()
    km.agent.engine.dispatch()
    (first,) = km.mine(P.SUBSCRIBE)
    km.deliver(
        communicate(
            P.AGREE, "a_ta", "a_km", "fipa-subscribe", first.conversation_id, in_reply_to=first.reply_with
        )
    )
    km.step("idle")
    ta.close()  # the robot's router dies ...
    km.agent.engine.acquire()
    ta = bus.transport()
    ta.announce(keys.alive_key("a_ta"))  # ... and comes back: a_km subscribes again
    km.agent.engine.acquire()
    km.agent.engine.dispatch()
    assert len(km.mine(P.SUBSCRIBE)) == 2
    update = WorldUpdate(stamp=5.0, objects=(ObjectUpdate(name="bowl", pose=Pose((0.3, -0.5, 0.85))),))
    km.deliver(
        communicate(
            P.INFORM,
            "a_ta",
            "a_km",
            "fipa-subscribe",
            first.conversation_id,
            update,
            in_reply_to=first.reply_with,
        )
    )
    km.step("idle")
    assert km.agent.counters["late_replies"] == 0 and km.agent.counters["protocol_violations"] == 0
    assert km.agent.current == update  # taken for saving


def test_a_restarted_a_km_drops_an_update_sent_to_its_previous_process_and_keeps_its_subscription() -> None:
    """Chaos across hosts (seed 2, not paced): a_km restarted while a_ta's update to the old
    process was in flight; the new a_km, subscribed anew, answered it not-understood, which
    ended its own new subscription: the fresh observation a_ta sends every new subscriber was
    dropped, and a_pl found "no way to pour". The stale update is now dropped as a late reply."""
    bus = MemoryBus()
    km = Wire(KnowledgeManager, bus)
    km.agent.setup()
    km.agent.engine.dispatch()
    (sub,) = km.mine(P.SUBSCRIBE)
    cid = sub.conversation_id
    old = WorldUpdate(stamp=4.0, objects=(ObjectUpdate(name="bowl", pose=Pose((0.7, -0.2, 0.85))),))
    km.deliver(communicate(P.INFORM, "a_ta", "a_km", "fipa-subscribe", cid, old, in_reply_to="a_km-previous"))
    assert not km.mine(P.NOT_UNDERSTOOD) and km.agent.counters["late_replies"] == 1
    km.deliver(communicate(P.AGREE, "a_ta", "a_km", "fipa-subscribe", cid, in_reply_to=sub.reply_with))
    km.step("idle")
    fresh = WorldUpdate(stamp=5.0, objects=(ObjectUpdate(name="bowl", pose=Pose((0.3, -0.5, 0.85))),))
    km.deliver(
        communicate(P.INFORM, "a_ta", "a_km", "fipa-subscribe", cid, fresh, in_reply_to=sub.reply_with)
    )
    km.step("idle")
    assert km.agent.current == fresh and km.agent.environment.subscribed  # the new subscription goes on


def test_an_l_sw_inform_retransmitted_across_a_partition_is_its_copy_and_a_co_confirms_it_as_before(
    tmp_path: Path,
) -> None:
    """The partition of issue 45 at the runtime: a_ta's L_SW inform reaches a_co, whose confirm
    the cut link holds back; a_ta retransmits the inform. The retransmission is the original's
    bytes (its reply-with, conversation-id and content: the same communicate, FIPA SC00061
    §2.4), a_co takes it as a copy and sends its confirm again byte for byte, a_ta drops the
    confirm's copy, and the traffic record of it all conforms, the two copies judged once."""
    from services.recorder.recorder import TrafficWriter
    from services.spec.model import default_spec
    from services.spec_check.conformance import render, verify_run

    co, ta = Wire(Coordinator), Wire(TaskExecutor)  # two buses: the test carries C1 by hand
    crossed: list[tuple[str, bytes]] = []  # what crossed the wire, in order (the record)

    def carry(dst: Wire[Coordinator] | Wire[TaskExecutor], payload: bytes) -> None:
        """``payload`` crosses C1 to ``dst``'s agent."""
        msg = decode(payload)
        assert msg.sender is not None
        crossed.append((keys.fipa_key("C1", msg.sender.name, msg.receiver[0].name), payload))
        dst.deliver(payload)

    hi = communicate(P.REQUEST, "a_hi", "a_co", "fipa-request", "cmd-1", POUR, reply_with="r1")
    crossed.append((keys.fipa_key("C2", "a_hi", "a_co"), encode(hi)))
    co.deliver(hi)
    co.step("procReq")
    task = co.agent.tasks["cmd-1"]
    task.note.plan, task.needs_plan = PLAN, False
    co.agent.reschedule = True
    co.step("schedule")
    co.step("switch")
    crossed += [
        (keys.fipa_key("C2", "a_co", "a_hi"), encode(m)) for m in co.mine() if m.receiver[0].name == "a_hi"
    ]
    (run,) = co.mine(P.REQUEST)
    carry(ta, encode(run))
    ta.step("idle")
    assert ta.agent.plan_request is not None
    ta.agent._inform_co(SWState.RUNNING, step="pour/wait")
    ta.agent.engine.dispatch()
    (inform,) = [raw for raw, m in zip(ta.raw, ta.out, strict=True) if m.receiver[0].name == "a_co"]
    carry(co, inform)
    co.step("trigger")
    (confirm,) = co.mine(P.CONFIRM)
    # the link is cut: the confirm does not reach a_ta, whose retransmission time comes
    original = decode(inform)
    assert original.reply_with is not None
    pending = ta.agent.engine.pending_replies.get(original.reply_with)
    assert pending is not None and pending.retry_s is not None
    pending.next_retry = 0.0
    ta.agent.engine.pending_replies.expect(pending)  # moved by hand: expected again, so it is looked at
    ta.agent.engine.acquire()
    ta.agent.engine.dispatch()
    informs = [raw for raw, m in zip(ta.raw, ta.out, strict=True) if m.receiver[0].name == "a_co"]
    assert len(informs) == 2 and ta.agent.counters["retransmitted"] == 1
    again = decode(informs[1])
    assert informs[1] == inform  # the same communicate: byte for byte
    assert (again.reply_with, again.conversation_id) == (original.reply_with, original.conversation_id)
    carry(co, informs[1])  # the link is back: the retransmission reaches a_co
    assert co.agent.counters["duplicates"] == 1 and co.agent.counters["replayed"] == 1
    assert not co.agent.engine.x  # not taken in a second time
    confirms = [raw for raw, m in zip(co.raw, co.out, strict=True) if m.performative is P.CONFIRM]
    assert len(confirms) == 2 and confirms[0] == confirms[1] == encode(confirm)
    for raw in confirms:
        carry(ta, raw)
    assert ta.agent.counters["duplicates"] == 1  # the confirm's copy: dropped
    assert ta.agent.engine.pending_replies.get(original.reply_with) is None  # answered: sent no more
    assert ta.agent.counters["protocol_violations"] == co.agent.counters["protocol_violations"] == 0

    writer = TrafficWriter(tmp_path)
    for i, (key, payload) in enumerate(crossed):
        writer.write(1000.0 + 0.01 * i, key, payload)
    writer.close()
    report = verify_run(tmp_path, default_spec())
    assert report.full_conformance and report.copies == 2, render(report)
    (c1,) = [c for c in report.conversations if c.conversation_id == run.conversation_id]
    assert c1.messages == 3 and c1.violations == 0  # request, inform, confirm: the copies once
