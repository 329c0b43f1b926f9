"""The branches of the interaction protocols that roco's participants never take, taken by a
scripted participant (tests/support/peer.py) towards the real agent that initiates: a_km
agreeing to a_pl's knowledge query before it answers it (C4), a_pl agreeing to a_co's plan
request before the plan (C3), ag_ex agreeing to a_ta's command before its result (C5) — FIPA
SC00026/27 §2 let a participant agree first —, the initiator's cancel of a conversation the
participant agreed to, the participant's answers that cross that cancel on the wire (an agree,
a refuse, the answer itself, a failure to cancel), a plan request whose reply-by passes, and an
answer the initiator cannot read. Each test asserts what the initiator then does: its
conversation ends, it goes on with its task, it answers nothing or not-understood. ``roco spec
coverage --tests`` counts these branches (docs/spec.md, "Coverage")."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import msgspec
import pytest

from services.agents.coordinator.agent import PLAN_REPLY_BY_S, Coordinator
from services.agents.knowledge.agent import KnowledgeManager
from services.agents.planner.agent import QUERY_REPLY_BY_S, Planner
from services.agents.task_executor.agent import COMMAND_MARGIN_S, TaskExecutor
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.runtime.sources import SYSTEM
from shared.fipa_codec import Communicate, Performative, decode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_ex import HALTED, CommandResult, MoveJoints, Wait
from shared.fipa_codec.languages.l_hc import CommandOutcome, HumanCommand, TaskAtom
from shared.fipa_codec.languages.l_hfsm import (
    Execute,
    GroundTaskNetwork,
    HierarchicalPlan,
    PlanFailure,
    PlanNode,
)
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from shared.fipa_codec.languages.l_wm import (
    Answer,
    GraspQuery,
    HypotheticalQuery,
    ObjectQuery,
    PlacementQuery,
    PourQuery,
    SceneQuery,
)
from shared.fipa_codec.message import new_id
from tests.support.peer import Peer, running

P = Performative
BRING = TaskAtom("bring", ("cup",))
POUR = TaskAtom("pour", ("jar", "bowl"))
"""What a_pl plans from a_km's knowledge alone (a kitchen no one has observed yet)."""


def _content(msg: Communicate) -> msgspec.Struct | None:
    return decode_content(msg.language, msg.content) if msg.language and msg.encoding == "msgpack" else None


def _answer(
    peer: Peer, opening: Communicate, perf: Performative, term: msgspec.Struct | None = None, **fields: str
) -> None:
    """``peer`` answers ``opening`` (in its conversation and protocol) with ``perf`` (and
    ``fields``: e.g. a reply-with of its own when a callback answers, on another thread than
    the test's, which counts the peer's)."""
    assert opening.conversation_id is not None and opening.protocol is not None
    peer.send(perf, opening.protocol, opening.conversation_id, term, in_reply_to=opening.reply_with, **fields)


def _sent(
    bus: MemoryBus, channel: str, sender: str, receiver: str, *perfs: Performative
) -> list[Communicate]:
    """Every communicate ``sender`` put on ``channel`` to ``receiver`` so far (of ``perfs`` when
    given), retransmitted copies left out."""
    key = keys.fipa_key(channel, sender, receiver)
    out: dict[str | None, Communicate] = {}
    for k, payload in list(bus.published):
        if k == key:
            msg = decode(payload)
            if not perfs or msg.performative in perfs:
                out.setdefault(msg.reply_with, msg)
    return list(out.values())


class Clock:
    """An agent's sources (services/runtime/sources.py) whose wall clock the test moves ahead:
    the reply-by deadlines are POSIX times (``Agent.sources.time``), so a deadline of minutes
    passes at once."""

    def __init__(self) -> None:
        self.ahead = 0.0

    def time(self) -> float:
        return SYSTEM.time() + self.ahead

    monotonic = staticmethod(SYSTEM.monotonic)
    random_bytes = staticmethod(SYSTEM.random_bytes)
    new_id = staticmethod(SYSTEM.new_id)


# ---------------------------------------------------------------------------------------------
# C4: a_pl asks, a_km (scripted) answers


class AgreeingKm:
    """Plays a_km towards a real a_pl on ``bus``: agrees to each knowledge query, then answers
    it with what a real a_km, on a bus of its own, answers the same query — ``inform-ref`` as
    ``inform`` to every other query (``alternate``) —, or with ``failure`` (``fail``)."""

    def __init__(self, bus: MemoryBus, *, fail: bool = False, alternate: bool = False) -> None:
        self.peer = Peer(bus, "a_km", "a_pl", "C4")
        self.fail, self.alternate = fail, alternate
        self.km_bus = MemoryBus()
        self.km = KnowledgeManager(self.km_bus.transport())
        self.asker = Peer(self.km_bus, "a_pl", "a_km", "C4")
        self.queries: dict[str, tuple[int, Communicate]] = {}  # by conversation: (order, query)
        self.lock = threading.Lock()  # a_pl's thread puts the queries, a_km's the answers
        bus.subscribe(keys.fipa_key("C4", "a_pl", "a_km"), self._query)
        self.km_bus.subscribe(keys.fipa_key("C4", "a_km", "a_pl"), self._answer)

    def _query(self, _key: str, payload: bytes) -> None:
        query = decode(payload)
        cid = query.conversation_id or ""
        with self.lock:
            if query.performative not in (P.QUERY_REF, P.QUERY_IF) or cid in self.queries:
                return  # a retransmitted copy, or a cancel
            self.queries[cid] = (len(self.queries), query)
        self._send(query, P.AGREE)
        if self.fail:
            self._send(query, P.FAILURE)
        else:
            self.asker.send(query.performative, "fipa-query", cid, _content(query), reply_with=new_id("q-"))

    def _answer(self, _key: str, payload: bytes) -> None:
        answer = decode(payload)
        with self.lock:
            order, query = self.queries[answer.conversation_id or ""]
        perf = answer.performative
        if self.alternate and perf is P.INFORM_REF and order % 2:
            perf = P.INFORM
        self._send(query, perf, _content(answer))

    def _send(self, query: Communicate, perf: Performative, term: msgspec.Struct | None = None) -> None:
        _answer(self.peer, query, perf, term, reply_with=new_id("a_km-"))


@contextmanager
def a_pl_with(
    km: Callable[[MemoryBus], AgreeingKm | Peer], clock: Clock | None = None
) -> Iterator[tuple[Planner, Peer, AgreeingKm | Peer]]:
    """A real a_pl (with ``clock``'s time, when given), a scripted a_co asking it for plans
    (C3), and ``km(bus)`` playing a_km."""
    bus = MemoryBus()
    pl = Planner(bus.transport())
    if clock is not None:
        pl.sources = clock
    a_co = Peer(bus, "a_co", "a_pl", "C3")
    a_km = km(bus)
    agents = (pl, a_km.km) if isinstance(a_km, AgreeingKm) else (pl,)
    with running(*agents):
        bus.announce(keys.alive_key("a_km"))
        yield pl, a_co, a_km


def _plan_for(a_co: Peer, cid: str, task: TaskAtom = POUR) -> Communicate:
    """a_co asks for a plan of ``task`` in conversation ``cid``; a_pl's answer."""
    a_co.send(P.REQUEST, "fipa-request", cid, GroundTaskNetwork(task_id=cid, tasks=(task,)))
    return a_co.next(P.INFORM, P.FAILURE, P.REFUSE, cid=cid)


@pytest.mark.parametrize("alternate", [False, True], ids=["inform-ref", "inform-ref-or-inform"])
def test_a_pl_plans_when_a_km_agrees_before_each_answer(alternate: bool) -> None:
    """a_km agrees to every knowledge query before it answers it (FIPA SC00027 §2), with
    inform-ref, or inform to every other query: a_pl takes each answer as it would without the
    agree, and informs a_co of the plan."""
    with a_pl_with(lambda bus: AgreeingKm(bus, alternate=alternate)) as (pl, a_co, a_km):
        answer = _plan_for(a_co, "plan")
    assert answer.performative is P.INFORM, answer.content
    plan = _content(answer)
    assert isinstance(plan, HierarchicalPlan) and plan.root.leaves(), plan
    assert isinstance(a_km, AgreeingKm) and plan.km_queries == len(a_km.queries) > 1
    assert pl.counters["rejected"] == 0


def test_a_pl_fails_a_plan_request_when_a_km_agrees_then_fails_each_query() -> None:
    """a_km agrees to every query, then fails it: a_pl answers a_co failure, saying which
    thing it knows nothing of (paper Table 4, "knowledge missing")."""
    with a_pl_with(lambda bus: AgreeingKm(bus, fail=True)) as (pl, a_co, _):
        answer = _plan_for(a_co, "plan")
    failure = _content(answer)
    assert answer.performative is P.FAILURE and isinstance(failure, PlanFailure), answer
    assert failure.reason in ("I know of no jar (failure)", "I know of no bowl (failure)"), failure.reason
    assert pl.counters["rejected"] == 0


def test_a_pl_fails_a_plan_request_when_a_km_agrees_and_then_says_nothing() -> None:
    """a_km agrees to every query and then says nothing: when the queries' reply-by
    (QUERY_REPLY_BY_S, a_pl's wall clock moved past it) passes, a_pl answers a_co failure,
    saying which thing it knows nothing of and why."""
    clock = Clock()
    with a_pl_with(lambda bus: Peer(bus, "a_km", "a_pl", "C4"), clock) as (pl, a_co, a_km):
        assert isinstance(a_km, Peer)
        a_co.send(P.REQUEST, "fipa-request", "plan", GroundTaskNetwork(task_id="plan", tasks=(POUR,)))
        a_km.next(P.QUERY_REF)
        for query in _sent(a_km.bus, "C4", "a_pl", "a_km", P.QUERY_REF):
            _answer(a_km, query, P.AGREE)
        clock.ahead = QUERY_REPLY_BY_S + 1.0
        answer = a_co.next(P.INFORM, P.FAILURE, P.REFUSE, cid="plan")
    failure = _content(answer)
    assert answer.performative is P.FAILURE and isinstance(failure, PlanFailure), answer
    assert failure.reason.startswith("I know of no ") and "deadline" in failure.reason, failure.reason
    assert pl.counters["deadline_failures"] >= 1


# The answers a_km (scripted) gives each query of a planning a_co cancels: before a_pl's
# cancel of the query, then after it — in reply to the query (an answer that crossed the
# cancel on the wire) or to the cancel (``TO_CANCEL``: the cancel meta-protocol's answer).
TO_CANCEL = {P.INFORM: "cancelled", P.FAILURE: "could not cancel"}
CROSSINGS: list[tuple[tuple[Performative, ...], tuple[Performative, ...]]] = [
    ((P.AGREE,), (P.INFORM,)),  # agreed, cancelled
    ((P.AGREE,), (P.INFORM_REF, P.FAILURE)),  # agreed, the answer crossed the cancel
    ((), (P.AGREE, P.FAILURE)),  # the agree crossed the cancel, which failed
    ((), (P.REFUSE,)),  # the refuse crossed the cancel
    ((), (P.FAILURE,)),  # could not cancel
]


def _after_cancel(
    a_km: Peer, query: Communicate, cancel: Communicate, answers: tuple[Performative, ...]
) -> None:
    """``a_km`` sends ``answers`` after ``cancel`` of ``query``: the last inform or failure
    answers the cancel, the others the query."""
    for i, perf in enumerate(answers):
        last = i == len(answers) - 1
        if last and perf in TO_CANCEL:
            _answer(a_km, cancel, perf)
        else:
            _answer(a_km, query, perf, Answer(variables=(), rows=()) if perf is P.INFORM_REF else None)


def test_a_pl_cancels_its_open_queries_when_a_co_cancels_the_planning() -> None:
    """a_co cancels a planning while a_pl waits for a_km's answers (some agreed to): a_pl
    answers the cancel, cancels every open query (FIPA SC00027 §2, the cancel meta-protocol),
    takes what a_km then sends — an agree, a refuse or an answer that crossed the cancel, the
    cancel's inform or failure — without a not-understood, and takes up the next request."""
    with a_pl_with(lambda bus: Peer(bus, "a_km", "a_pl", "C4")) as (pl, a_co, a_km):
        assert isinstance(a_km, Peer)
        a_co.send(P.REQUEST, "fipa-request", "plan", GroundTaskNetwork(task_id="plan", tasks=(POUR,)))
        a_km.next(P.QUERY_REF)  # a_pl asks its queries in one put: all of them are on the bus now
        queries = _sent(a_km.bus, "C4", "a_pl", "a_km", P.QUERY_REF)
        assert len(queries) >= len(CROSSINGS), queries
        plan = [CROSSINGS[i] if i < len(CROSSINGS) else ((), (P.INFORM,)) for i in range(len(queries))]
        for query, (before, _) in zip(queries, plan, strict=True):
            for perf in before:
                _answer(a_km, query, perf)
        a_co.send(P.CANCEL, "fipa-request", "plan")
        assert a_co.next(cid="plan").performative is P.INFORM
        cancels = {c.conversation_id: c for c in (a_km.next(P.CANCEL) for _ in queries)}
        for query, (_, after) in zip(queries, plan, strict=True):
            _after_cancel(a_km, query, cancels[query.conversation_id], after)
        a_co.send(P.REQUEST, "fipa-request", "next", GroundTaskNetwork(task_id="next", tasks=(POUR,)))
        again = a_km.next(P.QUERY_REF)  # a_pl took what a_km sent before it, and asks anew
    asked = {q.conversation_id for q in queries}
    assert sorted(cancels) == sorted(asked)  # one cancel for each open query, none twice
    assert again.conversation_id not in asked
    assert pl.counters["rejected"] == 0, pl.counters
    assert not _sent(a_km.bus, "C4", "a_pl", "a_km", P.NOT_UNDERSTOOD)


QUERY_IF = [
    ObjectQuery(name="jar"),
    SceneQuery(),
    GraspQuery(object="jar", arm="left"),
    PlacementQuery(object="bowl", surface="table"),
    PourQuery(source="jar", target="bowl"),
    HypotheticalQuery(changes=(), query=ObjectQuery(name="jar")),
]


def test_a_km_answers_a_pl_every_yes_no_question_in_l_wm() -> None:
    """a_pl asks its yes/no questions (query-if) in SPARQL; the specification lets it ask any
    L_WM query so (C4): a_km answers each with inform and an L_WM Answer (FIPA SC00027: inform
    answers query-if)."""
    bus = MemoryBus()
    km = KnowledgeManager(bus.transport())
    a_pl = Peer(bus, "a_pl", "a_km", "C4")
    with running(km):
        answers = []
        for i, query in enumerate(QUERY_IF):
            a_pl.send(P.QUERY_IF, "fipa-query", f"q{i}", query)
            answers.append(a_pl.next(cid=f"q{i}"))
    for query, answer in zip(QUERY_IF, answers, strict=True):
        assert answer.performative is P.INFORM, (query, answer)
        assert isinstance(_content(answer), Answer), (query, answer)


# ---------------------------------------------------------------------------------------------
# C3: a_co requests plans, a_pl (scripted) answers


class CoordinatorScene:
    """A real a_co on a MemoryBus, with a_hi (C2), a_pl (C3) and a_ta (C1) scripted."""

    def __init__(self, clock: Clock | None = None) -> None:
        self.bus = MemoryBus()
        self.co = Coordinator(self.bus.transport())
        if clock is not None:
            self.co.sources = clock
        self.a_hi = Peer(self.bus, "a_hi", "a_co", "C2")
        self.a_pl = Peer(self.bus, "a_pl", "a_co", "C3")
        self.a_ta = Peer(self.bus, "a_ta", "a_co", "C1")

    def command(self, cid: str) -> Communicate:
        """a_hi commands; a_co agrees; a_pl gets a_co's plan request, returned."""
        self.a_hi.send(P.REQUEST, "fipa-request", cid, HumanCommand(text="bring the cup", goal=BRING))
        assert self.a_hi.next(cid=cid).performative is P.AGREE
        return self.a_pl.next(P.REQUEST, cid=f"{cid}-plan1")

    def outcome(self, cid: str) -> tuple[Communicate, CommandOutcome]:
        """a_co's last answer to a_hi's command ``cid`` (inform, failure, or the inform or
        failure answering a_hi's cancel) and its outcome."""
        answer = self.a_hi.next(P.INFORM, P.FAILURE, cid=cid)
        outcome = _content(answer)
        assert isinstance(outcome, CommandOutcome), answer
        return answer, outcome

    def run(self, request: Communicate) -> None:
        """a_ta runs the plan a_co sends: Running, then Succeeded, each confirmed by a_co."""
        plan = _content(request)
        assert isinstance(plan, HierarchicalPlan)
        for state in (SWState.RUNNING, SWState.SUCCEEDED):
            _answer(self.a_ta, request, P.INFORM, SWStatus(state=state, plan_id=plan.plan_id))
            self.a_ta.next(P.CONFIRM, cid=request.conversation_id)


def _plan(task_id: str) -> HierarchicalPlan:
    return HierarchicalPlan(plan_id=f"{task_id}-p1", task_id=task_id, root=PlanNode(name="nothing"), cost=1.0)


def test_a_co_runs_the_plan_a_pl_agreed_to_make() -> None:
    """a_pl agrees to the plan request, then informs the plan (FIPA SC00026 §2): a_co has a_ta
    run it, and informs a_hi that the command succeeded."""
    s = CoordinatorScene()
    with running(s.co):
        request = s.command("cmd")
        _answer(s.a_pl, request, P.AGREE)
        _answer(s.a_pl, request, P.INFORM, _plan("cmd"))
        s.run(s.a_ta.next(P.REQUEST))
        answer, outcome = s.outcome("cmd")
    assert answer.performative is P.INFORM and outcome.succeeded, outcome
    assert s.co.counters["rejected"] == 0


def test_a_co_fails_the_command_whose_plan_a_pl_agreed_to_and_failed() -> None:
    """a_pl agrees to the plan request, then fails it: a_co fails a_hi's command with a_pl's
    reason, and runs nothing."""
    s = CoordinatorScene()
    with running(s.co):
        request = s.command("cmd")
        _answer(s.a_pl, request, P.AGREE)
        _answer(s.a_pl, request, P.FAILURE, PlanFailure(task_id="cmd", reason="the cup is nowhere"))
        answer, outcome = s.outcome("cmd")
    assert answer.performative is P.FAILURE and outcome.detail == "no plan: the cup is nowhere", outcome
    assert s.a_ta.got.empty()


PLAN_CROSSINGS = [c for c in CROSSINGS if P.INFORM_REF not in c[1]]
"""As :data:`CROSSINGS`, of a plan request (fipa-request has no inform-ref)."""


def _crossing_id(crossing: tuple[tuple[Performative, ...], tuple[Performative, ...]]) -> str:
    before, after = crossing
    return "-".join(p.value for p in before) + "/cancel/" + "-".join(p.value for p in after)


@pytest.mark.parametrize(("before", "after"), PLAN_CROSSINGS, ids=[_crossing_id(c) for c in PLAN_CROSSINGS])
def test_a_co_cancels_the_plan_request_of_a_command_a_hi_stops(
    before: tuple[Performative, ...], after: tuple[Performative, ...]
) -> None:
    """a_hi stops a command a_pl is planning (agreed to, or not yet): a_co cancels its plan
    request at once (FIPA SC00026 §2), answers a_hi's cancel (stopped), drops what a_pl sends
    after the cancel — an agree or a refuse that crossed it, the cancel's inform or failure —
    without a not-understood, and has a_hi's next command planned."""
    s = CoordinatorScene()
    with running(s.co):
        request = s.command("cmd")
        for perf in before:
            _answer(s.a_pl, request, perf)
        stop = s.a_hi.send(P.CANCEL, "fipa-request", "cmd")
        cancel = s.a_pl.next(P.CANCEL, cid=request.conversation_id)
        answer, outcome = s.outcome("cmd")
        for i, perf in enumerate(after):
            last = i == len(after) - 1 and perf in TO_CANCEL
            why = PlanFailure(task_id="cmd", reason=TO_CANCEL.get(perf, "refused"))
            _answer(s.a_pl, cancel if last else request, perf, why if perf in (P.FAILURE, P.REFUSE) else None)
        following = s.command("next")  # a_co took what a_pl sent before it
    assert answer.performative is P.INFORM and answer.in_reply_to == stop.reply_with, answer
    assert not outcome.succeeded and outcome.detail.startswith("stopped"), outcome
    assert following.conversation_id != request.conversation_id
    assert s.co.counters["rejected"] == 0, s.co.counters
    assert s.a_ta.got.empty()


def test_a_co_fails_a_command_whose_plan_a_pl_agreed_to_but_never_sent() -> None:
    """a_pl agrees to the plan request and then says nothing: when the request's reply-by
    (PLAN_REPLY_BY_S, a_co's wall clock moved past it) passes, a_co fails a_hi's command,
    and a plan that comes after that is not run."""
    clock = Clock()
    s = CoordinatorScene(clock)
    with running(s.co):
        request = s.command("cmd")
        _answer(s.a_pl, request, P.AGREE)
        clock.ahead = PLAN_REPLY_BY_S + 1.0
        answer, outcome = s.outcome("cmd")
        _answer(s.a_pl, request, P.INFORM, _plan("cmd"))  # too late
        s.command("next")  # a_co took the late plan before it
    assert answer.performative is P.FAILURE and "deadline" in outcome.detail, outcome
    assert s.co.counters["deadline_failures"] == 1
    assert s.a_ta.got.empty()


# ---------------------------------------------------------------------------------------------
# C5: a_ta commands, ag_ex (scripted) carries out


POSTURE = MoveJoints(positions={"right_arm_0_joint": 1.0}, duration=1.0)
PLAN = HierarchicalPlan(
    plan_id="t1-p1",
    task_id="t1",
    root=PlanNode(
        name="posture",
        children=(
            PlanNode(name="turn", action=Execute(command=POSTURE)),
            PlanNode(name="settle", action=Execute(command=Wait(duration=1.0))),
        ),
    ),
    cost=2.0,
)


class TaskScene:
    """A real a_ta on a MemoryBus, with a_co (C1: it confirms each L_SW inform at once) and
    ag_ex (C5) scripted; a_co has sent :data:`PLAN`."""

    def __init__(self, clock: Clock | None = None) -> None:
        self.bus = MemoryBus()
        self.ta = TaskExecutor(self.bus.transport())
        if clock is not None:
            self.ta.sources = clock
        self.a_co = Peer(self.bus, "a_co", "a_ta", "C1")
        self.ag_ex = Peer(self.bus, "ag_ex", "a_ta", "C5")
        self.bus.subscribe(keys.fipa_key("C1", "a_ta", "a_co"), self._confirm)

    def _confirm(self, _key: str, payload: bytes) -> None:
        inform = decode(payload)
        status = _content(inform)
        if inform.performative is P.INFORM and isinstance(status, SWStatus):
            confirm = SWStatus(state=status.state, plan_id=status.plan_id)
            _answer(self.a_co, inform, P.CONFIRM, confirm, reply_with=new_id("a_co-"))

    def start(self) -> None:
        self.a_co.send(P.REQUEST, "coordinate", "plan", PLAN)

    def states(self) -> Iterator[SWStatus]:
        """a_ta's L_SW states, up to the final one."""
        while True:
            status = _content(self.a_co.next(P.INFORM, cid="plan"))
            assert isinstance(status, SWStatus)
            yield status
            if status.state in TERMINAL_SW_STATES:
                return


def _result(ok: bool, reason: str | None = None) -> CommandResult:
    return CommandResult(command="move_joints", ok=ok, reason=reason, sim_time=1.0)


def test_a_ta_runs_a_plan_whose_commands_ag_ex_agrees_to_first() -> None:
    """ag_ex agrees to each command before its result (FIPA SC00026 §2): a_ta goes on to the
    next leaf after each result, and reports Succeeded."""
    s = TaskScene()
    with running(s.ta):
        s.start()
        commands = []
        for _ in PLAN.root.leaves():
            request = s.ag_ex.next(P.REQUEST)
            commands.append(_content(request))
            _answer(s.ag_ex, request, P.AGREE)
            _answer(s.ag_ex, request, P.INFORM, _result(True))
        final = list(s.states())[-1]
    assert commands == [POSTURE, Wait(duration=1.0)]
    assert final.state is SWState.SUCCEEDED, final
    assert s.ta.counters["rejected"] == 0


def test_a_ta_ends_the_plan_in_error_when_ag_ex_agrees_then_fails() -> None:
    """ag_ex agrees to the first command, then fails it: a_ta ends the plan in Error with
    ag_ex's reason, and sends no further command."""
    s = TaskScene()
    with running(s.ta):
        s.start()
        request = s.ag_ex.next(P.REQUEST)
        _answer(s.ag_ex, request, P.AGREE)
        _answer(s.ag_ex, request, P.FAILURE, _result(False, "joint limit"))
        final = list(s.states())[-1]
    assert final.state is SWState.ERROR and "joint limit" in (final.reason or ""), final
    assert s.ag_ex.got.empty()


@pytest.mark.requirement("R2.1")
@pytest.mark.parametrize("agreed", [True, False], ids=["agreed", "agree-crosses-the-cancel"])
def test_a_ta_halts_the_command_ag_ex_agreed_to_when_a_co_cancels(agreed: bool) -> None:
    """a_co cancels the plan while ag_ex carries out its first command (agreed to, or its
    agree crossing a_ta's cancel on the wire): a_ta cancels the command (FIPA SC00026 §2),
    reports Terminating, and Preempted once ag_ex answers that it halted it; nothing more is
    commanded."""
    s = TaskScene()
    with running(s.ta):
        s.start()
        request = s.ag_ex.next(P.REQUEST)
        if agreed:
            _answer(s.ag_ex, request, P.AGREE)
        s.a_co.send(P.CANCEL, "coordinate", "plan", SWStatus(state=SWState.TERMINATING, plan_id="t1-p1"))
        cancel = s.ag_ex.next(P.CANCEL, cid=request.conversation_id)
        if not agreed:
            _answer(s.ag_ex, request, P.AGREE)
        _answer(s.ag_ex, cancel, P.INFORM, _result(False, HALTED))
        states = list(s.states())
    kinds = [st.state for st in states]
    assert SWState.TERMINATING in kinds and kinds[-1] is SWState.PREEMPTED, kinds
    assert "halted posture/turn" in (states[-1].reason or ""), states[-1]
    assert s.ag_ex.got.empty()
    assert s.ta.counters["rejected"] == 0


def test_a_ta_answers_a_result_it_cannot_read_with_not_understood() -> None:
    """ag_ex answers a command with content that does not decode: a_ta answers not-understood
    (FIPA SC00037 §3.12: the conversation ends there), and when the command's reply-by passes
    (a_ta's wall clock moved past it) ends the plan in Error."""
    clock = Clock()
    s = TaskScene(clock)
    with running(s.ta):
        s.start()
        request = s.ag_ex.next(P.REQUEST)
        assert request.conversation_id is not None
        garbled = s.ag_ex.garbage(
            P.INFORM, "fipa-request", request.conversation_id, "L_EX", in_reply_to=request.reply_with
        )
        answer = s.ag_ex.next(P.NOT_UNDERSTOOD, cid=request.conversation_id)
        clock.ahead = 2 * POSTURE.duration + COMMAND_MARGIN_S + 1.0
        final = list(s.states())[-1]
    assert answer.in_reply_to == garbled.reply_with
    assert final.state is SWState.ERROR and "posture/turn" in (final.reason or ""), final
    assert s.ag_ex.got.empty()
