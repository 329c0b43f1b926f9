"""More branches of the interaction protocols a pour never takes, each taken by a real agent
against a scripted peer on a MemoryBus (tests/support/peer.py), as in
tests/agents/test_protocol_branches.py: a participant that answers at once without agree
(FIPA SC00026 §2), refuses with a term, ends a subscription with failure (SC00035 §2), answers
a cancel with failure, or lets a reply-by pass; an answer the other side cannot read, or does
not understand (SC00037 §3.12); an answer that crosses a cancel on the wire. A reply-by
deadline passes by moving the real agent's clock (``Agent.sources``,
services/runtime/sources.py), not by waiting. ``roco spec coverage --tests`` counts them
(docs/spec.md, "Coverage")."""

from __future__ import annotations

import queue
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import msgspec
import pytest

from services.agents.coordinator.agent import Coordinator
from services.agents.human_interface.agent import (
    AGREE_BY_S,
    COMMAND_REPLY_BY_S,
    STATUS_REPLY_BY_S,
    SUBSCRIBE_REPLY_BY_S,
    SUBSCRIPTION,
    HumanInterface,
)
from services.agents.knowledge.agent import KnowledgeManager
from services.agents.task_executor.agent import SW_RETRY_S, TaskExecutor
from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport, ReportKind
from services.runtime.memory_transport import MemoryBus
from services.runtime.sources import SYSTEM
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Progress,
    Sentence,
    SentenceReport,
    Status,
    StatusQuery,
    TaskAtom,
    TaskState,
)
from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan, PlanNode
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery, ObjectUpdate, SparqlQuery, WorldUpdate
from tests.support.peer import Peer, running

P = Performative
FOREIGN = "da0@host:1099/JADE"
"""An agent of another FIPA platform (plays x_fipa on C8)."""
BRING = "bring the cup to the table"
STATUS = "what are you doing?"


class MovedClock:
    """An agent's sources (services/runtime/sources.py) whose wall clock, which its reply-by
    deadlines are read on, a test moves ``ahead`` (s); the rest are the system's."""

    def __init__(self) -> None:
        self.ahead = 0.0
        self.monotonic = SYSTEM.monotonic
        self.random_bytes = SYSTEM.random_bytes
        self.new_id = SYSTEM.new_id

    def time(self) -> float:
        return SYSTEM.time() + self.ahead


class Person:
    """The person at a_hi's receptor and effector (services/runtime/human.py)."""

    def __init__(self, bus: MemoryBus) -> None:
        self.bus = bus
        self.reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
        decoder = msgspec.json.Decoder(HumanReport)
        bus.subscribe(keys.HUMAN_OUT, lambda _k, p: self.reports.put(decoder.decode(p)))

    def say(self, text: str, request_id: str) -> None:
        self.bus.publish(keys.HUMAN_IN, msgspec.json.encode(HumanInput(text=text, request_id=request_id)))

    def final(self, request_id: str) -> HumanReport:
        """The final report (services/runtime/human.py FINAL_REPORTS) about ``request_id``."""
        while True:
            report = self.reports.get(timeout=60.0)
            if report.request_id == request_id and report.kind in FINAL_REPORTS:
                return report

    def next(self, request_id: str) -> HumanReport:
        while True:
            report = self.reports.get(timeout=60.0)
            if report.request_id == request_id:
                return report


@contextmanager
def a_hi_with_a_co(*, alive: bool = False) -> Iterator[tuple[HumanInterface, Peer, Person, MovedClock]]:
    """A real a_hi (a_km away: it reads with its own vocabulary), a scripted a_co on C2
    (its token announced when ``alive``: a_hi then subscribes to its progress) and a person;
    a_hi's clock can be moved."""
    bus = MemoryBus()
    hi = HumanInterface(bus.transport())
    clock = MovedClock()
    hi.sources = clock
    a_co = Peer(bus, "a_co", "a_hi", "C2")
    person = Person(bus)
    with running(hi):
        if alive:
            bus.announce(keys.alive_key("a_co"))
        yield hi, a_co, person, clock


def answer(
    peer: Peer, to: Communicate, perf: Performative, term: msgspec.Struct | None = None
) -> Communicate:
    """``peer`` answers ``to`` in its conversation with ``perf`` carrying ``term``; returns it."""
    assert to.conversation_id is not None and to.protocol is not None
    return peer.send(perf, to.protocol, to.conversation_id, term, in_reply_to=to.reply_with)


# ---- C2 fipa-request: a_co answers a_hi's command at once, refuses it, or says nothing ---------


@pytest.mark.parametrize(
    ("perf", "succeeded", "told"),
    [(P.INFORM, True, ReportKind.SUCCEEDED), (P.FAILURE, False, ReportKind.FAILED)],
    ids=["done", "failed"],
)
def test_a_hi_takes_a_command_answered_at_once_without_agree(
    perf: Performative, succeeded: bool, told: ReportKind
) -> None:
    """FIPA SC00026 §2 lets the participant leave out the agree when the outcome comes at once:
    a_hi ends the command with the outcome a_co gave and tells the person why."""
    with a_hi_with_a_co() as (hi, a_co, person, _):
        person.say(BRING, "r1")
        request = a_co.next(P.REQUEST)
        detail = "it was there already" if succeeded else "the cup is out of reach"
        answer(a_co, request, perf, CommandOutcome(command_id="x", succeeded=succeeded, detail=detail))
        report = person.final("r1")
    assert report.kind is told and detail in report.text, report
    assert not hi.commands


def test_a_command_a_co_refuses_with_its_outcome_is_reported_refused() -> None:
    """a_co refuses a command with a CommandOutcome (the specification's content of refuse on
    C2): a_hi tells the person it was refused, with the outcome's detail."""
    with a_hi_with_a_co() as (hi, a_co, person, _):
        person.say(BRING, "r1")
        request = a_co.next(P.REQUEST)
        refused = CommandOutcome(command_id="x", succeeded=False, detail="the robot is switched off")
        answer(a_co, request, P.REFUSE, refused)
        report = person.final("r1")
    assert report.kind is ReportKind.FAILED and "refused" in report.text, report
    assert "switched off" in report.text and not hi.commands


def test_an_answer_a_hi_cannot_read_ends_the_command_at_once() -> None:
    """a_co answers a command with an agree whose content does not decode: a_hi answers
    not-understood, which ends the command's conversation (FIPA SC00037 §3.12), and tells the
    person at once that the command failed, and why (not after AGREE_BY_S)."""
    with a_hi_with_a_co() as (hi, a_co, person, _):
        person.say(BRING, "r1")
        request = a_co.next(P.REQUEST)
        assert request.conversation_id is not None
        a_co.garbage(P.AGREE, "fipa-request", request.conversation_id, "L_HC", in_reply_to=request.reply_with)
        a_co.next(P.NOT_UNDERSTOOD, cid=request.conversation_id)
        report = person.final("r1")
    assert report.kind is ReportKind.FAILED and "a_hi could not read a_co's answer" in report.text, report
    assert hi.counters["deadline_failures"] == 0 and not hi.commands


@pytest.mark.parametrize("agreed", [False, True], ids=["unanswered", "agreed-unfinished"])
def test_a_command_whose_reply_by_passes_fails(agreed: bool) -> None:
    """a_co neither agrees within AGREE_BY_S nor, having agreed, ends the command within
    COMMAND_REPLY_BY_S: the reply-by passes (a_hi's clock is moved past it) and a_hi tells the
    person the command failed, and why."""
    with a_hi_with_a_co() as (hi, a_co, person, clock):
        person.say(BRING, "r1")
        request = a_co.next(P.REQUEST)
        if agreed:
            answer(a_co, request, P.AGREE)
            assert person.next("r1").kind is ReportKind.ACCEPTED
        clock.ahead = (COMMAND_REPLY_BY_S if agreed else AGREE_BY_S) + 1.0
        report = person.final("r1")
    assert report.kind is ReportKind.FAILED, report
    assert f"did not {'finish' if agreed else 'answer'} within" in report.text, report
    assert hi.counters["deadline_failures"] >= 1 and not hi.commands


# ---- C2 fipa-subscribe: a_co ends a_hi's progress subscription, or fails to cancel one ----------


def test_a_progress_subscription_a_co_ends_with_failure_is_made_again() -> None:
    """a_co ends the agreed progress subscription with failure (FIPA SC00035 §2): a_hi
    subscribes again, in a new conversation, and tells the person the progress of the new one."""
    with a_hi_with_a_co(alive=True) as (hi, a_co, person, _):
        first = a_co.next(P.SUBSCRIBE)
        answer(a_co, first, P.AGREE)
        answer(a_co, first, P.FAILURE)
        again = a_co.next(P.SUBSCRIBE)
        answer(a_co, again, P.AGREE)
        progress = Progress(command_id="cmd-r9", state=TaskState.RUNNING, step="fetch")
        answer(a_co, again, P.INFORM, progress)
        report = person.next("r9")
    assert first.conversation_id == SUBSCRIPTION and again.conversation_id != SUBSCRIPTION
    assert report.kind is ReportKind.PROGRESS and "fetch" in report.text, report
    assert hi.progress.subscribed and hi.counters["rejected"] == 0


def test_a_superfluous_subscription_whose_cancel_fails_leaves_the_newer_one() -> None:
    """a_co lets a_hi's first subscribe pass its reply-by (a_hi's clock is moved) and agrees
    to it only after a_hi subscribed again: a_hi cancels the superfluous one (the role:
    services/runtime/roles/subscriptions.py), a_co answers the cancel with failure (SC00035 §2: it
    could not cancel), and a_hi goes on with the newer subscription."""
    with a_hi_with_a_co(alive=True) as (hi, a_co, person, clock):
        first = a_co.next(P.SUBSCRIBE)
        clock.ahead = SUBSCRIBE_REPLY_BY_S + 1.0
        again = a_co.next(P.SUBSCRIBE)
        answer(a_co, first, P.AGREE)  # late
        cancel = a_co.next(P.CANCEL)
        answer(a_co, cancel, P.FAILURE)
        answer(a_co, again, P.AGREE)
        answer(a_co, again, P.INFORM, Progress(command_id="cmd-r9", state=TaskState.PLANNING))
        report = person.next("r9")
    assert cancel.conversation_id == first.conversation_id != again.conversation_id
    assert report.kind is ReportKind.PROGRESS, report
    assert hi.progress.conversation_id == again.conversation_id and hi.progress.subscribed


# ---- C2 fipa-query: a status answer a_hi cannot read, or none ----------------------------------


def test_a_status_answer_a_hi_cannot_read_is_not_understood_and_the_person_is_told() -> None:
    """a_co answers a status query with content that does not decode: a_hi answers
    not-understood (FIPA SC00037 §3.12), which ends the query, and tells the person at once
    (not at the reply-by) what it knows without a_co's status."""
    with a_hi_with_a_co() as (hi, a_co, person, _):
        person.say(STATUS, "r1")
        query = a_co.next(P.QUERY_REF)
        assert query.conversation_id is not None
        a_co.garbage(P.INFORM_REF, "fipa-query", query.conversation_id, "L_HC", in_reply_to=query.reply_with)
        a_co.next(P.NOT_UNDERSTOOD, cid=query.conversation_id)
        report = person.final("r1")
    assert report.kind is ReportKind.STATUS and "did not tell me its status (L_HC" in report.text, report
    assert hi.counters["deadline_failures"] == 0


def test_a_status_query_whose_reply_by_passes_is_answered_from_what_a_hi_knows() -> None:
    """a_co does not answer a status query within STATUS_REPLY_BY_S (a_hi's clock is moved):
    a_hi tells the person so, with what it knows of its commands."""
    with a_hi_with_a_co() as (hi, a_co, person, clock):
        person.say(STATUS, "r1")
        a_co.next(P.QUERY_REF)
        clock.ahead = STATUS_REPLY_BY_S + 1.0
        report = person.final("r1")
    assert report.kind is ReportKind.STATUS, report
    assert "did not answer in time" in report.text and "no command of mine is open" in report.text, report
    assert hi.counters["deadline_failures"] >= 1


# ---- C1 coordinate: a_ta ends a plan at once, or reports a state a_co cannot read ----------------


@contextmanager
def a_co_running_a_plan() -> Iterator[tuple[Coordinator, Peer, Peer, Communicate]]:
    """A real a_co, with a_hi, a_pl and a_ta scripted: a_hi's command is agreed, a_pl's plan
    for it sent to a_ta; yields a_co, a_hi, a_ta and a_co's plan request to a_ta."""
    bus = MemoryBus()
    co = Coordinator(bus.transport())
    a_hi = Peer(bus, "a_hi", "a_co", "C2")
    a_pl = Peer(bus, "a_pl", "a_co", "C3")
    a_ta = Peer(bus, "a_ta", "a_co", "C1")
    command = HumanCommand(text=BRING, goal=TaskAtom("bring", ("cup", "table")))
    with running(co):
        a_hi.send(P.REQUEST, "fipa-request", "cmd-1", command)
        a_hi.next(P.AGREE, cid="cmd-1")
        asked = a_pl.next(P.REQUEST)
        plan = HierarchicalPlan(plan_id="p1", task_id="cmd-1", root=PlanNode(name="bring"), cost=1.0)
        answer(a_pl, asked, P.INFORM, plan)
        yield co, a_hi, a_ta, a_ta.next(P.REQUEST)


def outcome(peer: Peer, cid: str) -> tuple[Performative, CommandOutcome]:
    """The outcome a_co answers command ``cid`` with (inform or failure, a CommandOutcome)."""
    end = peer.next(P.INFORM, P.FAILURE, cid=cid)
    told = decode_content("L_HC", end.content)
    assert isinstance(told, CommandOutcome), told
    return end.performative, told


def test_a_plan_a_ta_fails_at_once_fails_the_command() -> None:
    """a_ta answers the plan with failure before any L_SW state (the coordinate protocol
    allows it: paper §5.4): a_co fails the person's command, saying why, and the robot is free
    for the next plan."""
    with a_co_running_a_plan() as (co, a_hi, a_ta, request):
        a_ta.send(
            P.FAILURE,
            "coordinate",
            request.conversation_id or "",
            content=b"the arm controller is down",
            encoding="utf-8",
            in_reply_to=request.reply_with,
        )
        perf, told = outcome(a_hi, "cmd-1")
    assert perf is P.FAILURE and not told.succeeded and "arm controller is down" in told.detail, told
    assert co.note.ta_task is None and not co.tasks


@pytest.mark.parametrize(
    ("state", "succeeded"), [(SWState.SUCCEEDED, True), (SWState.ERROR, False)], ids=["succeeded", "error"]
)
def test_a_plan_a_ta_ends_at_once_with_a_terminal_state_ends_the_command(
    state: SWState, succeeded: bool
) -> None:
    """a_ta reports a terminal L_SW state first, with no Running before it (a plan with
    nothing to do, or one that cannot start): a_co confirms it, which ends the coordinate
    conversation, and ends the command as the state says."""
    with a_co_running_a_plan() as (co, a_hi, a_ta, request):
        report = SWStatus(state=state, plan_id="p1", reason="" if succeeded else "no arm")
        inform = answer(a_ta, request, P.INFORM, report)
        confirm = a_ta.next(P.CONFIRM, cid=request.conversation_id)
        perf, told = outcome(a_hi, "cmd-1")
    assert confirm.in_reply_to == inform.reply_with, confirm
    assert perf is (P.INFORM if succeeded else P.FAILURE) and told.succeeded is succeeded, told
    assert co.note.ta_task is None and not co.tasks


def test_a_state_a_co_cannot_read_is_not_understood_and_ends_the_command() -> None:
    """a_ta reports an L_SW state whose content does not decode: a_co answers not-understood
    (FIPA SC00037 §3.12), which ends the coordinate conversation, and does not wait for a
    plan that conversation can no longer report on."""
    with a_co_running_a_plan() as (co, a_hi, a_ta, request):
        cid = request.conversation_id or ""
        a_ta.garbage(P.INFORM, "coordinate", cid, "L_SW", in_reply_to=request.reply_with)
        a_ta.next(P.NOT_UNDERSTOOD, cid=cid)
        perf, told = outcome(a_hi, "cmd-1")
    assert perf is P.FAILURE and "a_ta sent a state a_co could not read" in told.detail, told
    assert co.note.ta_task is None and not co.tasks


# ---- C6 fipa-subscribe: a_ta ends a_km's environment subscription -------------------------------


def test_an_environment_subscription_a_ta_ends_with_failure_is_made_again() -> None:
    """a_ta ends the agreed environment subscription with failure (FIPA SC00035 §2): a_km
    subscribes again at once, in a new conversation (a conversation-id names one conversation,
    FIPA SC00061), and keeps what a_ta sends in the new one (a query answers from it)."""
    bus = MemoryBus()
    km = KnowledgeManager(bus.transport())
    a_ta = Peer(bus, "a_ta", "a_km", "C6")
    with running(km):
        first = a_ta.next(P.SUBSCRIBE)
        answer(a_ta, first, P.AGREE)
        answer(a_ta, first, P.FAILURE)
        again = a_ta.next(P.SUBSCRIBE)
        answer(a_ta, again, P.AGREE)
        answer(
            a_ta, again, P.INFORM, WorldUpdate(stamp=1.0, objects=(ObjectUpdate(name="jar", particles=7),))
        )
        a_ta.send(P.QUERY_REF, "fipa-query", "jar?", ObjectQuery(name="jar"))
        known = a_ta.next(P.INFORM_REF, cid="jar?")
    assert again.conversation_id == f"{first.conversation_id}-2" and again.reply_with != first.reply_with
    told = decode_content("L_WM", known.content)
    assert isinstance(told, Answer) and [o.particles for o in told.objects] == [7], told
    assert km.environment.subscribed and km.counters["updates"] == 1


# ---- C8 fipa-request: a foreign agent's request failed at once, cancelled, not understood ---------


@contextmanager
def a_hi_with_a_foreigner() -> Iterator[tuple[HumanInterface, Peer, Peer]]:
    """A real a_hi, a scripted a_co on C2 and a foreign agent on C8 (docs/gateway.md)."""
    bus = MemoryBus()
    hi = HumanInterface(bus.transport())
    foreign = Peer(bus, FOREIGN, "a_hi", "C8")
    a_co = Peer(bus, "a_co", "a_hi", "C2")
    with running(hi):
        yield hi, foreign, a_co


def report_of(msg: Communicate) -> SentenceReport:
    told = decode_content("L_HC", msg.content)
    assert isinstance(told, SentenceReport), told
    return told


def test_a_foreign_request_a_co_refuses_fails_before_any_agree() -> None:
    """A foreign agent's command that a_co refuses (with a CommandOutcome) is answered with
    failure at once, with no agree before it (FIPA SC00026 §2): the request was understood but
    cannot be carried out."""
    with a_hi_with_a_foreigner() as (hi, foreign, a_co):
        foreign.send(P.REQUEST, "fipa-request", "bring", Sentence(text=BRING))
        request = a_co.next(P.REQUEST)
        answer(
            a_co, request, P.REFUSE, CommandOutcome(command_id="x", succeeded=False, detail="switched off")
        )
        first = foreign.next(cid="bring")
    assert first.performative is P.FAILURE, first
    assert report_of(first).kind == ReportKind.FAILED.value and "switched off" in report_of(first).text
    assert not hi.commands and not hi.foreign.open


def test_a_foreign_cancel_after_agree_stops_the_command_and_is_answered_once_it_stopped() -> None:
    """A foreign agent cancels its request after a_hi agreed: a_hi cancels the command with
    a_co as a person's stop would, and answers the foreign cancel once a_co has stopped it:
    ``inform`` in reply to the cancel (the cancel meta-protocol, FIPA SC00026 §2), which ends
    the request; nothing else is sent in it."""
    with a_hi_with_a_foreigner() as (hi, foreign, a_co):
        foreign.send(P.REQUEST, "fipa-request", "bring", Sentence(text=BRING))
        request = a_co.next(P.REQUEST)
        answer(a_co, request, P.AGREE)
        assert foreign.next(cid="bring").performative is P.AGREE
        cancel = foreign.send(P.CANCEL, "fipa-request", "bring")
        stop = a_co.next(P.CANCEL)
        assert stop.conversation_id == request.conversation_id
        answer(a_co, stop, P.INFORM, CommandOutcome(command_id="x", succeeded=False, detail="stopped"))
        done = foreign.next(cid="bring")
    assert done.performative is P.INFORM and done.in_reply_to == cancel.reply_with, done
    assert report_of(done).kind == ReportKind.STOPPED.value, report_of(done)
    assert not hi.commands and not hi.foreign.open and not hi.foreign.cancels
    assert hi.counters["handler_errors"] == 0


def test_a_foreign_cancel_with_nothing_under_way_fails_and_the_request_goes_on() -> None:
    """A foreign agent cancels its status question while a_hi waits for a_co's answer: no
    command of it runs, so the cancel is answered ``failure`` at once and the answer still
    comes (FIPA SC00026 §2: the request goes on)."""
    with a_hi_with_a_foreigner() as (hi, foreign, a_co):
        foreign.send(P.REQUEST, "fipa-request", "status", Sentence(text=STATUS))
        query = a_co.next(P.QUERY_REF)
        cancel = foreign.send(P.CANCEL, "fipa-request", "status")
        refused = foreign.next(cid="status")
        answer(a_co, query, P.INFORM_REF, Status(tasks=()))
        done = foreign.next(cid="status")
    assert refused.performative is P.FAILURE and refused.in_reply_to == cancel.reply_with, refused
    assert "nothing of it is under way" in report_of(refused).text
    assert done.performative is P.INFORM, done
    assert not hi.foreign.open and not hi.foreign.cancels


@pytest.mark.parametrize("after", [P.AGREE, P.INFORM], ids=["agree", "inform"])
def test_a_foreign_not_understood_ends_its_request_and_a_hi_goes_on(after: Performative) -> None:
    """The foreign agent answers a_hi's agree, or its final inform, with not-understood (FIPA
    SC00037 §3.12): that ends the request's conversation, a_hi sends nothing more in it (the
    command itself goes on with a_co) and answers the foreign agent's next request."""
    with a_hi_with_a_foreigner() as (hi, foreign, a_co):
        foreign.send(P.REQUEST, "fipa-request", "bring", Sentence(text=BRING))
        request = a_co.next(P.REQUEST)
        answer(a_co, request, P.AGREE)
        seen = [foreign.next(cid="bring")]
        if after is P.INFORM:
            answer(a_co, request, P.INFORM, CommandOutcome(command_id="x", succeeded=True))
            seen.append(foreign.next(cid="bring"))
        foreign.send(P.NOT_UNDERSTOOD, "fipa-request", "bring", in_reply_to=seen[-1].reply_with)
        if after is P.AGREE:
            answer(a_co, request, P.INFORM, CommandOutcome(command_id="x", succeeded=True))
        foreign.send(P.REQUEST, "fipa-request", "status", Sentence(text=STATUS))
        query = a_co.next(P.QUERY_REF)
        answer(a_co, query, P.INFORM_REF, Status(tasks=()))
        while (last := foreign.next()).conversation_id != "status":
            seen.append(last)
    assert [m.performative for m in seen] == [P.AGREE, P.INFORM][: len(seen)], seen
    assert len(seen) == (2 if after is P.INFORM else 1) and last.performative is P.INFORM, seen
    assert not hi.commands and not hi.foreign.open


# ---- answers crossing a cancel on the wire -------------------------------------------------------


def cross(
    monkeypatch: pytest.MonkeyPatch,
    owner: object,
    method: str,
    cancel: Callable[[], Communicate],
    when: Callable[..., bool] = lambda *_: True,
) -> list[Communicate]:
    """The first time the real agent calls ``owner.method`` (with arguments ``when`` takes),
    ``cancel()`` first puts the peer's cancel on the bus: the agent is in the middle of a
    step (it holds its turn), so the cancel waits in its input while the agent answers what it
    is answering, and the two cross on the wire, as over a network with latency (FIPA SC00026
    §2). Returns the list the cancel is put in once sent."""
    original = getattr(owner, method)
    sent: list[Communicate] = []

    def first_the_cancel(*args: object, **kwargs: object) -> object:
        if not sent and when(*args, **kwargs):
            sent.append(cancel())
        return original(*args, **kwargs)

    monkeypatch.setattr(owner, method, first_the_cancel)
    return sent


def late_cancel_answered(peer: Peer, cid: str, cancel: Communicate) -> Communicate:
    """The agent's answer to ``cancel``, which came after the conversation had ended."""
    answered = peer.next(cid=cid)
    assert answered.in_reply_to == cancel.reply_with, answered
    return answered


KM_ANSWERS = [
    ("ASK { ?s ?p ?o }", P.INFORM_REF),
    ("SELECT ?s WHERE { SERVICE <http://example.org/sparql> { ?s ?p ?o } }", P.REFUSE),
    ("this is not SPARQL", P.FAILURE),
]


@pytest.mark.parametrize(("text", "perf"), KM_ANSWERS, ids=[p.value for _, p in KM_ANSWERS])
@pytest.mark.parametrize(("channel", "asker"), [("C7", "a_hi"), ("C6", "a_ta")])
def test_a_km_answer_crossing_a_cancel_ends_the_query_and_the_cancel_is_answered(
    monkeypatch: pytest.MonkeyPatch, channel: str, asker: str, text: str, perf: Performative
) -> None:
    """The querier cancels while a_km is answering: a_km's answer (inform-ref, refuse or
    failure) crosses the cancel and ends the query; the cancel, which comes after that end, is
    answered with failure (nothing to cancel), and a_km goes on answering."""
    bus = MemoryBus()
    km = KnowledgeManager(bus.transport())
    them = Peer(bus, asker, "a_km", channel)
    sent = cross(monkeypatch, km.world, "answer", lambda: them.send(P.CANCEL, "fipa-query", "q"))
    with running(km):
        query = them.send(P.QUERY_REF, "fipa-query", "q", SparqlQuery(query=text))
        answered = them.next(cid="q")
        (cancel,) = sent
        failed = late_cancel_answered(them, "q", cancel)
        them.send(P.QUERY_REF, "fipa-query", "q2", SparqlQuery(query="ASK { ?s ?p ?o }"))
        assert them.next(cid="q2").performative is P.INFORM_REF
    assert answered.performative is perf and answered.in_reply_to == query.reply_with, answered
    assert failed.performative is P.FAILURE and b"nothing to cancel" in failed.content, failed
    assert km.counters["handler_errors"] == 0 and km.counters["rejected"] == 0


def test_a_co_answers_crossing_a_cancel_end_their_conversations(monkeypatch: pytest.MonkeyPatch) -> None:
    """a_hi cancels while a_co answers: a status query (inform-ref), a yes/no question, a
    request and a subscribe that carry nothing (each refused). Each answer crosses the cancel
    and ends its conversation; each cancel, coming after that end, is answered with failure."""
    bus = MemoryBus()
    co = Coordinator(bus.transport())
    a_hi = Peer(bus, "a_hi", "a_co", "C2")
    cases = [
        ("status", P.QUERY_REF, "fipa-query", StatusQuery(), P.INFORM_REF, "status"),
        ("yes-no", P.QUERY_IF, "fipa-query", StatusQuery(), P.REFUSE, "_on_yes_no_query"),
        ("empty-command", P.REQUEST, "fipa-request", None, P.REFUSE, "_accept"),
        ("empty-subscribe", P.SUBSCRIBE, "fipa-subscribe", None, P.REFUSE, "_on_subscribe"),
    ]
    with running(co):
        for cid, opening, protocol, term, perf, method in cases:
            sent = cross(monkeypatch, co, method, lambda p=protocol, c=cid: a_hi.send(P.CANCEL, p, c))
            asked = a_hi.send(opening, protocol, cid, term)
            answered = a_hi.next(cid=cid)
            assert answered.performative is perf and answered.in_reply_to == asked.reply_with, answered
            (cancel,) = sent
            assert late_cancel_answered(a_hi, cid, cancel).performative is P.FAILURE
    assert co.counters["handler_errors"] == 0 and co.counters["rejected"] == 0 and not co.tasks


FOREIGN_CROSSINGS = [
    (BRING, ReportKind.ACCEPTED, P.AGREE),
    (STATUS, ReportKind.STATUS, P.INFORM),
    ("flibbertigibbet the quux", ReportKind.NOT_UNDERSTOOD, P.REFUSE),
]


@pytest.mark.parametrize(
    ("text", "kind", "perf"), FOREIGN_CROSSINGS, ids=[p.value for _, _, p in FOREIGN_CROSSINGS]
)
def test_a_hi_answer_crossing_a_foreign_cancel(
    monkeypatch: pytest.MonkeyPatch, text: str, kind: ReportKind, perf: Performative
) -> None:
    """A foreign agent cancels its request while a_hi answers it (an agree, the final inform,
    or a refuse of a sentence it did not understand): the answer crosses the cancel. After a
    final answer a_hi answers the cancel with failure; after an agree it cancels the command
    with a_co, whose outcome crosses that cancel: the foreign cancel is then answered with
    failure and the outcome still answers the request (FIPA SC00026 §2)."""
    with a_hi_with_a_foreigner() as (hi, foreign, a_co):
        sent = cross(
            monkeypatch,
            hi.foreign,
            "answer",
            lambda: foreign.send(P.CANCEL, "fipa-request", "ask"),
            when=lambda report: report.kind is kind,
        )
        asked = foreign.send(P.REQUEST, "fipa-request", "ask", Sentence(text=text))
        if kind is not ReportKind.NOT_UNDERSTOOD:
            opened = a_co.next(P.REQUEST, P.QUERY_REF)
            if opened.performative is P.REQUEST:
                answer(a_co, opened, P.AGREE)
            else:
                answer(a_co, opened, P.INFORM_REF, Status(tasks=()))
        answered = foreign.next(cid="ask")
        (cancel,) = sent
        if perf is P.AGREE:
            assert a_co.next(P.CANCEL).conversation_id == opened.conversation_id
            answer(a_co, opened, P.INFORM, CommandOutcome(command_id="x", succeeded=True))
        failed = late_cancel_answered(foreign, "ask", cancel)
        if perf is P.AGREE:
            assert foreign.next(cid="ask").performative is P.INFORM
    assert answered.performative is perf and answered.in_reply_to == asked.reply_with, answered
    assert report_of(answered).kind == kind.value and failed.performative is P.FAILURE, failed
    assert hi.counters["handler_errors"] == 0 and not hi.foreign.open


# ---- C1 coordinate: a_co does not confirm a_ta's state ----------------------------------------


def test_a_ta_sends_an_unconfirmed_state_again_until_a_co_confirms_it() -> None:
    """a_co (scripted) is silent for ten minutes after a_ta's first L_SW inform (a_ta's clock
    is moved): a_ta, which may send its next state only after the confirm (paper §5.4), sends
    the same inform again and waits on, with no time-out; a_co's late confirm lets the plan's
    terminal state through, and its confirm ends the conversation: a_ta takes the next plan."""
    bus = MemoryBus()
    ta = TaskExecutor(bus.transport())
    clock = MovedClock()
    ta.sources = clock
    a_co = Peer(bus, "a_co", "a_ta", "C1")
    plan = HierarchicalPlan(plan_id="p1", task_id="t1", root=PlanNode(name="nothing"))

    def next_state(peer: Peer, previous: Communicate) -> Communicate:
        """a_ta's next L_SW inform after ``previous`` (copies of it, sent before the confirm
        arrived, are skipped: a minute of them at most)."""
        for _ in range(int(60 / SW_RETRY_S)):
            inform = peer.next(P.INFORM, cid="plan")
            if inform.reply_with != previous.reply_with:
                return inform
        raise AssertionError(f"a_ta still sends {previous.reply_with} after its confirm")

    def state(inform: Communicate) -> SWState:
        status = decode_content("L_SW", inform.content)
        assert isinstance(status, SWStatus), status
        return status.state

    with running(ta):
        a_co.send(P.REQUEST, "coordinate", "plan", plan)
        first = a_co.next(P.INFORM, cid="plan")
        clock.ahead = 600.0
        again = a_co.next(P.INFORM, cid="plan")
        informs = [first]
        while state(informs[-1]) not in TERMINAL_SW_STATES:
            confirm = SWStatus(state=state(informs[-1]), plan_id="p1")
            a_co.send(P.CONFIRM, "coordinate", "plan", confirm, in_reply_to=informs[-1].reply_with)
            informs.append(next_state(a_co, informs[-1]))
        last = informs[-1]
        a_co.send(
            P.CONFIRM,
            "coordinate",
            "plan",
            SWStatus(state=state(last), plan_id="p1"),
            in_reply_to=last.reply_with,
        )
        a_co.send(
            P.REQUEST, "coordinate", "next", HierarchicalPlan(plan_id="p2", task_id="t2", root=plan.root)
        )
        following = a_co.next(P.INFORM, cid="next")  # a_ta is free for the next plan
    assert state(first) is SWState.RUNNING and again.reply_with == first.reply_with, again
    assert state(last) is SWState.SUCCEEDED and state(following) is SWState.RUNNING, last
    assert ta.counters["deadline_failures"] == 0 and ta.counters["rejected"] == 0
