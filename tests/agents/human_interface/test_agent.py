"""a_hi on a MemoryBus against a scripted stand-in for a_co: commands, progress, stop
(cancel), status (query-ref), a_co that does not serve subscriptions, malformed input."""

from __future__ import annotations

import queue
import threading
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import pytest

from services.agents.human_interface import agent as hi_module
from services.agents.human_interface.agent import HumanInterface
from services.runtime import keys
from services.runtime.agent import Agent, Received
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport, ReportKind
from services.runtime.memory_transport import MemoryBus
from services.runtime.state_store import ENV_STATE_DIR
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Progress,
    ProgressSubscription,
    Status,
    StatusQuery,
    TaskAtom,
    TaskState,
    TaskStatus,
)

TIMEOUT = 5.0


class ScriptedCo(Agent):
    """A tiny stand-in for a_co. Every received communicate goes to :attr:`inbox`; the test
    makes it act by :meth:`do` (the action runs on the agent's own thread). Subscriptions
    are answered by ``subscriptions``: "agree", "not-understood" (as an a_co that does not
    serve them) or "ignore"."""

    name = "a_co"
    period = 0.01

    def __init__(self, transport: Any, subscriptions: str = "agree") -> None:
        self.mode = subscriptions
        super().__init__(transport)

    def build_fsm(self) -> FSM:
        self.inbox: queue.SimpleQueue[Received] = queue.SimpleQueue()
        self.subscription: Received | None = None
        self.subscribed = threading.Event()
        self.subscribes: list[str] = []
        self.subscribe_seen: queue.SimpleQueue[str] = queue.SimpleQueue()
        return FSM([Behaviour("serve", self._serve, terminal=lambda: False)])

    def _serve(self) -> None:
        while self.r:
            action = self.r.popleft()
            if action is not None:
                action(self)
        while self.engine.x:
            item = self.engine.x.popleft()
            if item.performative is Performative.SUBSCRIBE:
                self.subscribes.append(item.msg.conversation_id or "")
                self.subscribe_seen.put(item.msg.conversation_id or "")
                if self.mode == "agree":
                    self.subscription = item
                    self.engine.reply(item, Performative.AGREE)
                    self.subscribed.set()
                elif self.mode == "not-understood":
                    self.engine.not_understood(item.sender, item.channel, "unexpected subscribe", item.msg)
                continue
            self.inbox.put(item)

    def do(self, action: Callable[[ScriptedCo], object]) -> None:
        """Run ``action(self)`` on the agent's thread."""
        self.post(action)

    def progress(self, progress: Progress) -> None:
        """Inform a_hi's subscription (call inside an action)."""
        assert self.subscription is not None
        self.engine.reply(self.subscription, Performative.INFORM, progress)

    def receive(self, performative: Performative, timeout: float = TIMEOUT) -> Received:
        """The next received communicate with ``performative`` (others are skipped)."""
        while True:
            item = self.inbox.get(timeout=timeout)
            if item.performative is performative:
                return item


class Person:
    """The person's side: sentences in, reports out, sorted by request."""

    def __init__(self, bus: MemoryBus) -> None:
        self.bus = bus
        self._q: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
        self._held: dict[str, list[HumanReport]] = defaultdict(list)
        dec = msgspec.json.Decoder(HumanReport)
        bus.subscribe(keys.HUMAN_OUT, lambda k, p: self._q.put(dec.decode(p)))

    def say(self, text: str, request_id: str, priority: int = 0) -> None:
        payload = msgspec.json.encode(HumanInput(text=text, request_id=request_id, priority=priority))
        self.bus.publish(keys.HUMAN_IN, payload)

    def next(self, request_id: str, timeout: float = TIMEOUT) -> HumanReport:
        """The next report about ``request_id``."""
        if self._held[request_id]:
            return self._held[request_id].pop(0)
        while True:
            report = self._q.get(timeout=timeout)
            if report.request_id == request_id:
                return report
            self._held[report.request_id].append(report)

    def until_final(self, request_id: str) -> list[HumanReport]:
        """Reports about ``request_id`` up to and including its final one."""
        out = [self.next(request_id)]
        while out[-1].kind not in FINAL_REPORTS:
            out.append(self.next(request_id))
        return out


class Stage:
    """a_hi and (optionally) the stand-in a_co on one bus, each on its own thread."""

    def __init__(self) -> None:
        self.bus = MemoryBus()
        self.person = Person(self.bus)
        self.agents: list[tuple[Agent, threading.Thread]] = []
        self.hi: HumanInterface | None = None

    def start(self, agent: Agent) -> None:
        agent.engine.bind()
        t = threading.Thread(target=agent.engine.run, name=agent.name, daemon=True)
        t.start()
        self.agents.append((agent, t))

    def co(self, subscriptions: str = "agree") -> ScriptedCo:
        co = ScriptedCo(self.bus.transport(), subscriptions)
        self.start(co)
        return co

    def start_hi(self) -> HumanInterface:
        self.hi = HumanInterface(self.bus.transport())
        self.start(self.hi)
        return self.hi

    def stop(self) -> None:
        for agent, _ in self.agents:
            agent.engine.stop()
        for _, t in self.agents:
            t.join(timeout=TIMEOUT)


def _ready(stage: Stage) -> tuple[ScriptedCo, HumanInterface, Person]:
    co = stage.co()
    hi = stage.start_hi()
    assert co.subscribed.wait(TIMEOUT), "a_hi did not subscribe to a_co's progress"
    return co, hi, stage.person


def test_a_hi_subscribes_to_progress_at_start_up(stage: Stage) -> None:
    co, _hi, _ = _ready(stage)
    assert co.subscribes == ["hi-progress"]
    assert co.subscription is not None
    assert co.subscription.msg.protocol == "fipa-subscribe"
    assert isinstance(co.subscription.content, ProgressSubscription)


def test_command_agree_progress_inform_gives_readable_reports(stage: Stage) -> None:
    co, hi, person = _ready(stage)
    person.say("Please pour the glass jar into the bowl!", "r1")
    request = co.receive(Performative.REQUEST)
    assert request.msg.protocol == "fipa-request" and request.msg.conversation_id == "cmd-r1"
    assert request.content == HumanCommand(
        text="Please pour the glass jar into the bowl!", goal=TaskAtom("pour", ("jar", "bowl"))
    )
    cid = request.msg.conversation_id

    def run(co: ScriptedCo) -> None:
        co.engine.reply(request, Performative.AGREE)
        co.progress(Progress(command_id=cid, state=TaskState.PLANNING, detail="plan #1 requested"))
        co.progress(Progress(command_id=cid, state=TaskState.RUNNING, step="pour(jar,bowl)/fetch_jar/grasp"))
        co.engine.reply(
            request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True, detail="done")
        )

    co.do(run)
    reports = person.until_final("r1")
    assert [(r.kind, r.text) for r in reports] == [
        (ReportKind.ACCEPTED, "I will pour the jar into the bowl."),
        (ReportKind.PROGRESS, "pour the jar into the bowl: planning; plan #1 requested"),
        (ReportKind.PROGRESS, "pour the jar into the bowl: running pour(jar,bowl)/fetch_jar/grasp"),
        (ReportKind.SUCCEEDED, "pour the jar into the bowl: succeeded; done"),
    ]
    assert not hi.commands and len(hi.engine.pending_replies) == 1  # only the subscription stays open


def test_the_outcomes_told_are_kept_across_a_restart_and_given_to_whoever_asks(
    stage: Stage, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A command's final report is kept in a_hi's NOTE (told.py): what its queryable of
    ``roco/human/outcomes`` answers, and what an a_hi started after it on the same state folder
    answers too (an a_hi that died after telling: its publisher's cache is gone)."""
    monkeypatch.setenv(ENV_STATE_DIR, str(tmp_path))
    co, hi, person = _ready(stage)
    person.say("pour the jar into the bowl", "r1")
    request = co.receive(Performative.REQUEST)
    cid = request.msg.conversation_id or ""

    def run(co: ScriptedCo) -> None:
        co.engine.reply(request, Performative.AGREE)
        co.engine.reply(
            request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True, detail="done")
        )

    co.do(run)
    final = person.until_final("r1")[-1]
    stage.stop()  # a_hi persists after each step: stopped, it has written what it told
    told = msgspec.json.decode(hi.note.answer(), type=list[HumanReport])
    assert [(r.request_id, r.kind) for r in told] == [("r1", ReportKind.SUCCEEDED)]
    assert told[-1] == final
    again = HumanInterface(MemoryBus().transport())
    assert msgspec.json.decode(again.note.answer(), type=list[HumanReport]) == told


@pytest.mark.requirement("R1.1", "R1.2")
def test_priority_and_deadline_reach_a_co(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("bring me the mug within 2 minutes", "r1", priority=3)
    first = co.receive(Performative.REQUEST)
    assert first.content == HumanCommand(
        text="bring me the mug within 2 minutes",
        goal=TaskAtom("bring", ("cup",)),
        priority=3,
        deadline_s=120.0,
    )
    person.say("urgently hand me the jar", "r2")
    second = co.receive(Performative.REQUEST)
    assert isinstance(second.content, HumanCommand)
    assert second.content.goal == TaskAtom("hand_over", ("jar",)) and second.content.priority == 5
    co.do(lambda co: co.engine.reply(first, Performative.AGREE))
    assert person.next("r1").text == "I will bring the cup to the table (priority 3, within 120 s)."


def test_preemption_and_failure_are_reported_with_their_detail(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("pour the jar into the bowl", "r1")
    request = co.receive(Performative.REQUEST)
    cid = request.msg.conversation_id or ""

    def run(co: ScriptedCo) -> None:
        co.engine.reply(request, Performative.AGREE)
        co.progress(
            Progress(
                command_id=cid,
                state=TaskState.PREEMPTED,
                step="pour(jar,bowl)/fetch_jar/grasp",
                detail="for 'bring the cup to the table'",
            )
        )
        co.engine.reply(
            request,
            Performative.FAILURE,
            CommandOutcome(command_id=cid, succeeded=False, detail="grasp failed: injected failure"),
        )

    co.do(run)
    reports = person.until_final("r1")
    assert reports[1].text == (
        "pour the jar into the bowl: preempted pour(jar,bowl)/fetch_jar/grasp "
        "for 'bring the cup to the table'"
    )
    assert reports[-1].kind is ReportKind.FAILED
    assert reports[-1].text == "pour the jar into the bowl: failed; grasp failed: injected failure"


def test_refuse_is_a_failed_report_with_the_reason(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("pour the cup into the bowl", "r1")
    request = co.receive(Performative.REQUEST)
    co.do(
        lambda co: co.engine.fail(
            request, Performative.REFUSE, "I do not know how to pour the cup into the bowl"
        )
    )
    (report,) = person.until_final("r1")
    assert report.kind is ReportKind.FAILED
    assert (
        report.text == "pour the cup into the bowl: refused; I do not know how to pour the cup into the bowl"
    )


def test_stop_sends_cancel_in_every_open_command_conversation(stage: Stage) -> None:
    co, hi, person = _ready(stage)
    person.say("pour the jar into the bowl", "r1")
    first = co.receive(Performative.REQUEST)
    person.say("bring me the cup", "r2")
    second = co.receive(Performative.REQUEST)
    co.do(
        lambda co: (co.engine.reply(first, Performative.AGREE), co.engine.reply(second, Performative.AGREE))
    )
    assert person.next("r1").kind is ReportKind.ACCEPTED
    assert person.next("r2").kind is ReportKind.ACCEPTED

    person.say("stop everything!", "r3")
    cancels = [co.receive(Performative.CANCEL), co.receive(Performative.CANCEL)]
    assert {c.msg.conversation_id for c in cancels} == {"cmd-r1", "cmd-r2"}
    assert all(c.msg.protocol == "fipa-request" and isinstance(c.content, HumanCommand) for c in cancels)
    stopping = person.next("r3")
    assert stopping.kind is ReportKind.PROGRESS
    assert stopping.text == "Stopping 2 commands: pour the jar into the bowl; bring the cup to the table."
    assert person.next("r1").text == "pour the jar into the bowl: stopping, as you asked"

    def answer(co: ScriptedCo) -> None:
        for c in cancels:
            detail = "stopped; the jar was put down on the table" if c.msg.conversation_id == "cmd-r1" else ""
            co.engine.reply(
                c, Performative.INFORM, CommandOutcome(command_id="", succeeded=False, detail=detail)
            )

    co.do(answer)
    r1 = person.next("r1")
    assert r1.kind is ReportKind.STOPPED
    assert r1.text == "pour the jar into the bowl: stopped; the jar was put down on the table"
    assert person.next("r2").text == "bring the cup to the table: stopping, as you asked"
    r2 = person.next("r2")
    assert (r2.kind, r2.text) == (ReportKind.STOPPED, "bring the cup to the table: stopped")
    final = person.next("r3")
    assert final.kind is ReportKind.STOPPED
    assert final.text.splitlines() == [r1.text, r2.text]
    assert not hi.commands and not hi.stops


def test_a_cancel_that_fails_leaves_the_command_open_and_the_stop_failed(stage: Stage) -> None:
    co, hi, person = _ready(stage)
    person.say("pour the jar into the bowl", "r1")
    request = co.receive(Performative.REQUEST)
    co.do(lambda co: co.engine.reply(request, Performative.AGREE))
    assert person.next("r1").kind is ReportKind.ACCEPTED
    person.say("cancel", "r2")
    cancel = co.receive(Performative.CANCEL)
    co.do(lambda co: co.engine.fail(cancel, Performative.FAILURE, "the pour cannot be interrupted"))
    final = person.until_final("r2")[-1]
    assert final.kind is ReportKind.FAILED
    assert final.text == "pour the jar into the bowl: could not be stopped; the pour cannot be interrupted"
    assert "cmd-r1" in hi.commands
    cid = request.msg.conversation_id or ""
    co.do(
        lambda co: co.engine.reply(
            request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True)
        )
    )
    assert person.until_final("r1")[-1].kind is ReportKind.SUCCEEDED


def test_an_outcome_crossing_the_cancel_ends_the_stop_too(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("fetch the jar", "r1")
    request = co.receive(Performative.REQUEST)
    person.say("stop", "r2")
    cancel = co.receive(Performative.CANCEL)

    def run(co: ScriptedCo) -> None:  # the outcome was on its way when the cancel came
        co.engine.reply(request, Performative.INFORM, CommandOutcome(command_id="cmd-r1", succeeded=True))
        co.engine.fail(cancel, Performative.FAILURE, "already finished")

    co.do(run)
    assert person.until_final("r1")[-1].kind is ReportKind.SUCCEEDED
    reports = person.until_final("r2")
    assert reports[-1].kind is ReportKind.STOPPED
    assert "ended before it could be stopped" in reports[-1].text


def test_stop_with_nothing_running_says_so(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("stop", "r1")
    (report,) = person.until_final("r1")
    assert report.kind is ReportKind.STOPPED
    assert report.text == "Nothing is running, so there is nothing to stop."
    with pytest.raises(queue.Empty):
        co.receive(Performative.CANCEL, timeout=0.3)


def test_status_query_reports_one_line_per_task(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("pour the jar into the bowl", "r1")
    request = co.receive(Performative.REQUEST)
    person.say("What are you doing?", "r2")
    query = co.receive(Performative.QUERY_REF)
    assert query.msg.protocol == "fipa-query" and isinstance(query.content, StatusQuery)
    status = Status(
        tasks=(
            TaskStatus(
                command_id=request.msg.conversation_id or "",
                text="pour the jar into the bowl",
                state=TaskState.RUNNING,
                step="pour(jar,bowl)/fetch_jar/grasp",
                deadline_in_s=42.4,
            ),
            TaskStatus(command_id="cmd-x", text="bring me the cup", state=TaskState.WAITING, priority=5),
        )
    )
    co.do(lambda co: co.engine.reply(query, Performative.INFORM_REF, status))
    (report,) = person.until_final("r2")
    assert report.kind is ReportKind.STATUS
    assert report.text.splitlines() == [
        "pour the jar into the bowl: running pour(jar,bowl)/fetch_jar/grasp, 42 s left to its deadline",
        "'bring me the cup': waiting, priority 5",
    ]


def test_status_with_no_tasks_and_without_an_answer(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("status", "r1")
    query = co.receive(Performative.QUERY_REF)
    co.do(lambda co: co.engine.reply(query, Performative.INFORM_REF, Status()))
    (report,) = person.until_final("r1")
    assert (report.kind, report.text) == (
        ReportKind.STATUS,
        "I am not doing anything: no command is running or waiting.",
    )
    person.say("what are you doing", "r2")
    query = co.receive(Performative.QUERY_REF)
    co.do(lambda co: co.engine.fail(query, Performative.REFUSE, "busy"))
    (report,) = person.until_final("r2")
    assert report.kind is ReportKind.STATUS
    assert report.text.startswith("a_co did not tell me its status (busy)")


def test_a_not_understood_sentence_sends_nothing(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("pour it into the bowl", "r1")
    (report,) = person.until_final("r1")
    assert report.kind is ReportKind.NOT_UNDERSTOOD
    assert report.text.startswith("Which object should I pour into the bowl?")
    with pytest.raises(queue.Empty):
        co.inbox.get(timeout=0.3)


def _communicate(perf: Performative, conversation_id: str, content: Any = None) -> bytes:
    language, body = encode_content(content) if content is not None else (None, b"")
    return encode(
        Communicate(
            performative=perf,
            sender=AgentIdentifier("a_co"),
            receiver=(AgentIdentifier("a_hi"),),
            content=body,
            language=language,
            encoding="msgpack" if body else None,
            ontology="O_RoCo" if body else None,
            protocol="fipa-request",
            conversation_id=conversation_id,
        )
    )


def test_malformed_and_unexpected_communicates_get_not_understood(stage: Stage) -> None:
    co, hi, person = _ready(stage)
    answers: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    stage.bus.subscribe(keys.fipa_key("C2", "a_hi", "a_co"), lambda k, p: answers.put(decode(p)))
    inbox = keys.fipa_key("C2", "a_co", "a_hi")

    stage.bus.publish(inbox, b"\x93not a communicate")
    nu = answers.get(timeout=TIMEOUT)
    assert nu.performative is Performative.NOT_UNDERSTOOD
    assert b"malformed" in nu.content

    outcome = CommandOutcome(command_id="cmd-nobody", succeeded=True)
    stage.bus.publish(inbox, _communicate(Performative.INFORM, "cmd-nobody", outcome))
    nu = answers.get(timeout=TIMEOUT)
    assert nu.performative is Performative.NOT_UNDERSTOOD and nu.conversation_id == "cmd-nobody"
    assert b"no such conversation" in nu.content

    stage.bus.publish(inbox, _communicate(Performative.REQUEST, "c-odd", StatusQuery()))
    nu = answers.get(timeout=TIMEOUT)
    assert nu.performative is Performative.NOT_UNDERSTOOD and nu.conversation_id == "c-odd"

    stage.bus.publish(keys.HUMAN_IN, b"{not json")  # a malformed sentence: logged, ignored

    person.say("hand me the cup", "r1")  # a_hi keeps working
    request = co.receive(Performative.REQUEST)
    co.do(lambda co: co.engine.reply(request, Performative.AGREE))
    assert person.next("r1").kind is ReportKind.ACCEPTED
    assert hi.counters["behaviour_errors"] == 0 and hi.counters["handler_errors"] == 0


def test_a_co_that_does_not_serve_subscriptions(stage: Stage, monkeypatch: pytest.MonkeyPatch) -> None:
    """As the old a_co: subscribe answered with not-understood. a_hi retries quietly, each
    time in a new conversation, with a growing interval; commands still work."""
    monkeypatch.setattr(hi_module, "SUBSCRIBE_RETRY_S", (0.05, 0.2))
    co = stage.co(subscriptions="not-understood")
    hi = stage.start_hi()
    person = stage.person
    person.say("put the jar on the table", "r1")
    request = co.receive(Performative.REQUEST)
    cid = request.msg.conversation_id or ""

    def run(co: ScriptedCo) -> None:
        co.engine.reply(request, Performative.AGREE)
        co.engine.reply(request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True))

    co.do(run)
    kinds = [r.kind for r in person.until_final("r1")]
    assert kinds == [ReportKind.ACCEPTED, ReportKind.SUCCEEDED]
    attempts = [co.subscribe_seen.get(timeout=TIMEOUT) for _ in range(4)]
    assert attempts == ["hi-progress", "hi-progress-2", "hi-progress-3", "hi-progress-4"]
    assert not hi.progress.subscribed
    assert hi.progress.interval == 0.2  # doubled from 0.05 up to the longest interval
    assert hi.counters["behaviour_errors"] == 0


def test_subscribes_when_a_co_comes_up_later(stage: Stage, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hi_module, "SUBSCRIBE_REPLY_BY_S", 0.2)
    hi = stage.start_hi()
    co = stage.co()  # its liveliness token appears after a_hi's first attempt was lost
    assert co.subscribed.wait(TIMEOUT)
    person = stage.person
    person.say("return the cup", "r1")
    request = co.receive(Performative.REQUEST)
    cid = request.msg.conversation_id or ""

    def run(co: ScriptedCo) -> None:
        co.engine.reply(request, Performative.AGREE)
        co.progress(Progress(command_id=cid, state=TaskState.WAITING, detail="for the robot"))

    co.do(run)
    reports = [person.next("r1"), person.next("r1")]
    assert reports[1].text == "put the cup back in the cabinet: waiting for the robot"
    assert hi.progress.subscribed and hi.progress.conversation_id == co.subscribes[-1]
