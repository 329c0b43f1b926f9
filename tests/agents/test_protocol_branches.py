"""The branches of the interaction protocols a pour never takes, taken by each real agent
against a scripted peer on a MemoryBus (tests/support/peer.py): content that does not decode
is answered with not-understood by either role (FIPA SC00037 §3.12), a_km answers every query
of every channel it serves, a query cancelled before its answer ends as cancelled, and a
subscribe nobody answers times out and is sent again. ``roco spec coverage --tests`` counts
them (docs/spec.md, "Coverage")."""

from __future__ import annotations

import queue
from typing import Any

import msgspec
import pytest

from services.agents.coordinator.agent import Coordinator
from services.agents.executor.agent import ExecutorAgent
from services.agents.human_interface.agent import HumanInterface
from services.agents.knowledge.agent import KnowledgeManager
from services.agents.planner.agent import Planner
from services.agents.task_executor.agent import TaskExecutor
from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.human import HumanInput
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Communicate, Performative, decode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    ProgressSubscription,
    Sentence,
    Status,
    StatusQuery,
    TaskAtom,
)
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, PlanNode
from shared.fipa_codec.languages.l_sw import TERMINAL_SW_STATES, SWState, SWStatus
from shared.fipa_codec.languages.l_wm import (
    Answer,
    GraspQuery,
    HypotheticalQuery,
    ObjectQuery,
    PlacementQuery,
    PourQuery,
    SceneQuery,
    SparqlQuery,
    Subscription,
)
from tests.support.fake_executor import FakeExecutor
from tests.support.peer import Peer, running

P = Performative
BRING = TaskAtom("bring", ("cup", "table"))
FOREIGN = "da0@host:1099/JADE"
"""An agent of another FIPA platform (plays x_fipa on C8)."""
WAIT_S = 60.0
"""How long a test waits for what follows a reply-by deadline (2–5 s) on a loaded machine."""

PARTICIPANTS = [
    (KnowledgeManager, "C7", "a_hi", P.QUERY_REF, "fipa-query", "L_WM"),
    (KnowledgeManager, "C6", "a_ta", P.QUERY_IF, "fipa-query", "L_WM"),
    (Coordinator, "C2", "a_hi", P.REQUEST, "fipa-request", "L_HC"),
    (Coordinator, "C2", "a_hi", P.QUERY_REF, "fipa-query", "L_HC"),
    (Planner, "C3", "a_co", P.REQUEST, "fipa-request", "L_HFSM"),
    (TaskExecutor, "C1", "a_co", P.REQUEST, "coordinate", "L_HFSM"),
    (TaskExecutor, "C6", "a_km", P.SUBSCRIBE, "fipa-subscribe", "L_WM"),
    (HumanInterface, "C8", FOREIGN, P.REQUEST, "fipa-request", "L_HC"),
]


@pytest.mark.parametrize(
    ("cls", "channel", "peer", "perf", "protocol", "language"),
    PARTICIPANTS,
    ids=[f"{c[0].name}-{c[1]}-{c[4]}" for c in PARTICIPANTS],
)
def test_a_participant_answers_content_it_cannot_read_with_not_understood(
    cls: type[Agent], channel: str, peer: str, perf: Performative, protocol: str, language: str
) -> None:
    bus = MemoryBus()
    agent = cls(bus.transport())
    them = Peer(bus, peer, agent.name, channel)
    with running(agent):
        them.garbage(perf, protocol, "garbled", language)
        answer = them.next(P.NOT_UNDERSTOOD, cid="garbled")
    assert answer.protocol == protocol and answer.in_reply_to == f"{peer}-1"


INITIATORS = [
    # (agent, channel, the peer it opens a conversation with when the peer's token appears,
    #  what it opens with, the answer sent back in content that does not decode)
    (HumanInterface, "C7", "a_km", P.QUERY_REF, P.INFORM_REF, "L_WM"),
    (HumanInterface, "C2", "a_co", P.SUBSCRIBE, P.AGREE, "L_HC"),
    (KnowledgeManager, "C6", "a_ta", P.SUBSCRIBE, P.AGREE, "L_WM"),
]


@pytest.mark.parametrize(
    ("cls", "channel", "peer", "opening", "answer", "language"),
    INITIATORS,
    ids=[f"{c[0].name}-{c[1]}-{c[3].value}" for c in INITIATORS],
)
def test_an_initiator_answers_an_answer_it_cannot_read_with_not_understood(
    cls: type[Agent], channel: str, peer: str, opening: Performative, answer: Performative, language: str
) -> None:
    bus = MemoryBus()
    agent = cls(bus.transport())
    them = Peer(bus, peer, agent.name, channel)
    with running(agent):
        bus.announce(keys.alive_key(peer))
        opened = them.next(opening)
        assert opened.conversation_id is not None and opened.protocol is not None
        them.garbage(answer, opened.protocol, opened.conversation_id, language, in_reply_to=opened.reply_with)
        them.next(P.NOT_UNDERSTOOD, cid=opened.conversation_id)


QUERIES = [
    SparqlQuery(query="ASK { ?s ?p ?o }"),
    ObjectQuery(name="jar"),
    SceneQuery(),
    GraspQuery(object="jar", arm="left"),
    PlacementQuery(object="bowl", surface="table"),
    PourQuery(source="jar", target="bowl"),
    HypotheticalQuery(changes=(), query=ObjectQuery(name="jar")),
    SparqlQuery(query="this is not SPARQL"),  # refused
    ObjectQuery(name="unicorn"),  # no such thing: failure or an empty answer
]


@pytest.mark.parametrize("perf", [P.QUERY_REF, P.QUERY_IF])
def test_a_km_answers_every_query_a_ta_may_ask_on_c6(perf: Performative) -> None:
    """a_ta's C6 query role is never used by a_ta (its plans carry what it needs), but the
    specification lets it ask a_km anything a_pl may: a_km answers each kind, or says why not."""
    bus = MemoryBus()
    km = KnowledgeManager(bus.transport())
    a_ta = Peer(bus, "a_ta", "a_km", "C6")
    with running(km):
        for i, query in enumerate(QUERIES):
            a_ta.send(perf, "fipa-query", f"q{i}", query)
            answer = a_ta.next(cid=f"q{i}")
            assert answer.performative in (P.INFORM, P.INFORM_REF, P.FAILURE, P.REFUSE), answer


def test_a_query_cancelled_before_a_km_answers_ends_as_cancelled() -> None:
    """a_hi's query and its cancel both wait in a_km's input before a_km runs: a_km takes the
    cancel (FIPA SC00027 §2, the cancel meta-protocol) and answers inform or failure."""
    bus = MemoryBus()
    km = KnowledgeManager(bus.transport())
    a_hi = Peer(bus, "a_hi", "a_km", "C7")
    km.engine.bind()
    a_hi.send(P.QUERY_IF, "fipa-query", "ask", SparqlQuery(query="ASK { ?s ?p ?o }"))
    a_hi.send(P.CANCEL, "fipa-query", "ask")
    with running(km):
        first = a_hi.next(cid="ask")
        answers = [first.performative]
        if first.performative not in (P.INFORM, P.FAILURE) or first.in_reply_to != "a_hi-2":
            answers.append(a_hi.next(P.INFORM, P.FAILURE, cid="ask").performative)
    assert answers[-1] in (P.INFORM, P.FAILURE)


def test_a_km_subscription_nobody_answers_times_out_and_is_sent_again() -> None:
    """a_km subscribes to a_ta's observations when a_ta's token appears (C6, reply-by 2 s); a
    silent a_ta lets the reply-by pass (a time-out, in a_km's FSM record) and a_km subscribes
    again."""
    bus = MemoryBus()
    km = KnowledgeManager(bus.transport())
    a_ta = Peer(bus, "a_ta", "a_km", "C6")
    with running(km):
        bus.announce(keys.alive_key("a_ta"))
        first = a_ta.next(P.SUBSCRIBE)
        again = a_ta.next(P.SUBSCRIBE, timeout=WAIT_S)
    assert km.counters["deadline_failures"] >= 1
    assert again.reply_with != first.reply_with


CANCELS = [
    (Coordinator, "C2", "a_hi", P.REQUEST, "fipa-request", HumanCommand(text="bring the cup", goal=BRING)),
    (Coordinator, "C2", "a_hi", P.SUBSCRIBE, "fipa-subscribe", ProgressSubscription()),
    (Coordinator, "C2", "a_hi", P.QUERY_IF, "fipa-query", StatusQuery()),
    (Planner, "C3", "a_co", P.REQUEST, "fipa-request", GroundTaskNetwork(task_id="t1", tasks=(BRING,))),
    (KnowledgeManager, "C4", "a_pl", P.QUERY_REF, "fipa-query", ObjectQuery(name="jar")),
    (TaskExecutor, "C6", "a_km", P.SUBSCRIBE, "fipa-subscribe", Subscription()),
    (HumanInterface, "C8", FOREIGN, P.REQUEST, "fipa-request", Sentence(text="bring the cup to the table")),
]


@pytest.mark.parametrize(
    ("cls", "channel", "peer", "opening", "protocol", "term"),
    CANCELS,
    ids=[f"{c[0].name}-{c[1]}-{c[4]}" for c in CANCELS],
)
def test_a_cancel_that_waits_with_its_opening_is_answered(
    cls: type[Agent], channel: str, peer: str, opening: Performative, protocol: str, term: msgspec.Struct
) -> None:
    """The opening and its cancel both wait in the participant's input before it runs: it
    answers the cancel with inform (cancelled) or failure (FIPA SC00026/27/35 §2, the cancel
    meta-protocol), whatever it answered the opening (an agree or an answer crossing the cancel
    are allowed)."""
    bus = MemoryBus()
    agent = cls(bus.transport())
    them = Peer(bus, peer, agent.name, channel)
    agent.engine.bind()
    them.send(opening, protocol, "cancelled", term)
    cancel = them.send(P.CANCEL, protocol, "cancelled", term if protocol == "fipa-subscribe" else None)
    with running(agent):
        while True:
            answer = them.next(cid="cancelled")
            if answer.in_reply_to == cancel.reply_with:
                break
    assert answer.performative in (P.INFORM, P.FAILURE), answer


class Executor(ExecutorAgent):
    """ag_ex with the fake robot of tests/support/fake_executor.py."""

    def make_executor(self) -> Any:
        return FakeExecutor()


EMPTY = [
    (Executor, "C5", "a_ta", P.REQUEST, "fipa-request"),
    (TaskExecutor, "C1", "a_co", P.REQUEST, "coordinate"),
    (TaskExecutor, "C6", "a_km", P.SUBSCRIBE, "fipa-subscribe"),
    (Planner, "C3", "a_co", P.REQUEST, "fipa-request"),
    (Coordinator, "C2", "a_hi", P.SUBSCRIBE, "fipa-subscribe"),
    (Coordinator, "C2", "a_hi", P.QUERY_REF, "fipa-query"),
    (Coordinator, "C2", "a_hi", P.REQUEST, "fipa-request"),
    (KnowledgeManager, "C7", "a_hi", P.QUERY_REF, "fipa-query"),
    (KnowledgeManager, "C6", "a_ta", P.QUERY_REF, "fipa-query"),
]


@pytest.mark.parametrize(
    ("cls", "channel", "peer", "opening", "protocol"),
    EMPTY,
    ids=[f"{c[0].name}-{c[1]}-{c[4]}" for c in EMPTY],
)
@pytest.mark.parametrize("cancelled", [False, True], ids=["alone", "with-a-cancel"])
def test_a_participant_refuses_an_opening_that_carries_nothing(
    cls: type[Agent], channel: str, peer: str, opening: Performative, protocol: str, cancelled: bool
) -> None:
    """An opening without the term its channel's protocol carries (a plan, a subscription, a
    query) is refused with a reason: the participant cannot do what it does not know; also
    when a cancel of it waits behind it (the refuse crosses the cancel on the wire)."""
    bus = MemoryBus()
    agent = cls(bus.transport())
    them = Peer(bus, peer, agent.name, channel)
    agent.engine.bind()
    them.send(opening, protocol, "empty")
    if cancelled:
        them.send(P.CANCEL, protocol, "empty")
    with running(agent):
        answer = them.next(cid="empty")
    # with a cancel behind it, the participant may take the cancel first (inform: cancelled)
    assert answer.performative is P.REFUSE or (cancelled and answer.performative is P.INFORM), answer


SUBSCRIPTIONS = [
    (TaskExecutor, "C6", "a_km", Subscription()),
    (Coordinator, "C2", "a_hi", ProgressSubscription()),
]


@pytest.mark.parametrize(
    ("cls", "channel", "peer", "term"), SUBSCRIPTIONS, ids=[f"{c[0].name}-{c[1]}" for c in SUBSCRIPTIONS]
)
def test_an_agreed_subscription_is_cancelled_with_inform(
    cls: type[Agent], channel: str, peer: str, term: msgspec.Struct
) -> None:
    """The subscriber cancels a subscription the participant agreed to: the participant ends
    it with inform (FIPA SC00035 §2)."""
    bus = MemoryBus()
    agent = cls(bus.transport())
    them = Peer(bus, peer, agent.name, channel)
    with running(agent):
        them.send(P.SUBSCRIBE, "fipa-subscribe", "sub", term)
        them.next(P.AGREE, cid="sub")
        cancel = them.send(P.CANCEL, "fipa-subscribe", "sub", term)
        while (answer := them.next(cid="sub")).in_reply_to != cancel.reply_with:
            pass
    assert answer.performative is P.INFORM, answer


def test_a_hi_subscription_nobody_answers_times_out_and_is_sent_again() -> None:
    """a_hi subscribes to a_co's progress when a_co's token appears (C2, reply-by 5 s); a
    silent a_co lets the reply-by pass (a time-out) and a_hi subscribes again."""
    bus = MemoryBus()
    hi = HumanInterface(bus.transport())
    a_co = Peer(bus, "a_co", "a_hi", "C2")
    with running(hi):
        bus.announce(keys.alive_key("a_co"))
        first = a_co.next(P.SUBSCRIBE)
        again = a_co.next(P.SUBSCRIBE, timeout=WAIT_S)
    assert hi.counters["deadline_failures"] >= 1
    assert again.reply_with != first.reply_with


# Each way a participant may answer a query (FIPA SC00027 §2): at once, or after agree; with
# the answer, inform, or failure. roco's participants answer at once with the answer; a
# scripted one takes the other branches towards the real initiator, which ends each query.
ANSWERS = [
    (P.AGREE, P.INFORM_REF),
    (P.AGREE, P.INFORM),
    (P.AGREE, P.FAILURE),
    (P.INFORM,),
    (P.FAILURE,),
    (P.REFUSE,),
]


def _answer(peer: Peer, query: Communicate, answers: tuple[Performative, ...], term: msgspec.Struct) -> None:
    assert query.conversation_id is not None
    for perf in answers:
        content = term if perf in (P.INFORM, P.INFORM_REF) else None
        peer.send(perf, "fipa-query", query.conversation_id, content, in_reply_to=query.reply_with)


def test_a_hi_takes_every_answer_to_its_vocabulary_query() -> None:
    """a_hi asks a_km for its vocabulary (C7) whenever a_km's token appears; each time a_km
    answers another way, and a_hi's query ends (a_hi asks again at the next appearance)."""
    bus = MemoryBus()
    hi = HumanInterface(bus.transport())
    a_km = Peer(bus, "a_km", "a_hi", "C7")
    with running(hi):
        for answers in ANSWERS:
            bus.announce(keys.alive_key("a_km"))
            _answer(a_km, a_km.next(P.QUERY_REF), answers, Answer(variables=("w",), rows=()))
            bus.withdraw(keys.alive_key("a_km"))
    assert hi.counters["rejected"] == 0


def test_a_hi_takes_every_answer_to_a_status_query() -> None:
    """A person asks what the robot is doing; a_hi asks a_co (C2 fipa-query), which answers
    each way the protocol allows; a_hi tells the person each time."""
    bus = MemoryBus()
    hi = HumanInterface(bus.transport())
    a_co = Peer(bus, "a_co", "a_hi", "C2")
    reports: queue.SimpleQueue[bytes] = queue.SimpleQueue()
    bus.subscribe(keys.HUMAN_OUT, lambda _k, p: reports.put(p))
    with running(hi):
        bus.announce(keys.alive_key("a_co"))
        for i, answers in enumerate(ANSWERS):
            bus.publish(
                keys.HUMAN_IN, msgspec.json.encode(HumanInput(text="what are you doing?", request_id=f"r{i}"))
            )
            _answer(a_co, a_co.next(P.QUERY_REF), answers, Status(tasks=()))
    assert hi.counters["rejected"] == 0


def test_a_ta_follows_a_coordinate_conversation_through_its_cancels_and_repeated_confirms() -> None:
    """a_co (scripted) sends a plan and a cancel that both wait in a_ta's input (the cancel
    finds no plan running yet: nothing to halt); it confirms each L_SW state, the first one
    twice (a_co probing an a_ta that reappears), and cancels again after the terminal state
    before confirming it (paper §5.4, Figure 8: the coordinate protocol tolerates both)."""
    bus = MemoryBus()
    ta = TaskExecutor(bus.transport())
    a_co = Peer(bus, "a_co", "a_ta", "C1")
    plan = HierarchicalPlan(plan_id="p1", task_id="t1", root=PlanNode(name="nothing"))
    halt = SWStatus(state=SWState.TERMINATING, plan_id="p1", reason="cancelled")
    ta.engine.bind()
    a_co.send(P.REQUEST, "coordinate", "plan", plan)
    a_co.send(P.CANCEL, "coordinate", "plan", halt)
    states = []
    with running(ta):
        while True:
            inform = a_co.next(P.INFORM, cid="plan")
            status = decode_content("L_SW", inform.content)
            assert isinstance(status, SWStatus)
            states.append(status.state)
            if status.state in TERMINAL_SW_STATES:
                a_co.send(P.CANCEL, "coordinate", "plan", halt)
            confirm = SWStatus(state=status.state, plan_id="p1")
            a_co.send(P.CONFIRM, "coordinate", "plan", confirm, in_reply_to=inform.reply_with)
            if len(states) == 1:
                a_co.send(P.CONFIRM, "coordinate", "plan", confirm, in_reply_to=inform.reply_with)
            if status.state in TERMINAL_SW_STATES:
                break
    assert states[0] is SWState.RUNNING and states[-1] is SWState.SUCCEEDED, states
    assert ta.counters["rejected"] == 0


def test_a_pl_whose_knowledge_queries_fail_goes_to_finalize_and_fails_the_request() -> None:
    """a_km (scripted) fails every query a_pl asks for a planning problem: a_pl's FSM goes
    from initialize to finalize without searching (Table 4, "knowledge missing") and a_pl
    answers a_co's request with failure, saying why."""
    bus = MemoryBus()
    pl = Planner(bus.transport())
    a_co = Peer(bus, "a_co", "a_pl", "C3")
    a_km = Peer(bus, "a_km", "a_pl", "C4")

    def fail(_key: str, payload: bytes) -> None:  # a_km fails each query as it is asked
        query = decode(payload)
        if query.performative in (P.QUERY_REF, P.QUERY_IF) and query.conversation_id is not None:
            a_km.send(P.FAILURE, "fipa-query", query.conversation_id, in_reply_to=query.reply_with)

    bus.subscribe(keys.fipa_key("C4", "a_pl", "a_km"), fail)
    with running(pl):
        bus.announce(keys.alive_key("a_km"))
        a_co.send(P.REQUEST, "fipa-request", "plan", GroundTaskNetwork(task_id="t1", tasks=(BRING,)))
        answer = a_co.next(P.FAILURE, P.REFUSE, P.INFORM, cid="plan")
    assert answer.performative is P.FAILURE, answer


def test_a_foreign_agent_is_answered_each_way_a_hi_answers_a_person() -> None:
    """A foreign agent's sentences (C8) are answered as a person's reports (services/agents/
    human_interface/agent.py): a status question at once with inform, a command with agree and,
    when a_co (scripted) fails it, with failure."""
    bus = MemoryBus()
    hi = HumanInterface(bus.transport())
    foreign = Peer(bus, FOREIGN, "a_hi", "C8")
    a_co = Peer(bus, "a_co", "a_hi", "C2")
    with running(hi):
        bus.announce(keys.alive_key("a_co"))
        foreign.send(P.REQUEST, "fipa-request", "status", Sentence(text="what are you doing?"))
        query = a_co.next(P.QUERY_REF)
        assert query.conversation_id is not None
        a_co.send(
            P.INFORM_REF, "fipa-query", query.conversation_id, Status(tasks=()), in_reply_to=query.reply_with
        )
        assert foreign.next(cid="status").performative is P.INFORM
        foreign.send(P.REQUEST, "fipa-request", "bring", Sentence(text="bring the cup to the table"))
        request = a_co.next(P.REQUEST)
        cid = request.conversation_id
        assert cid is not None
        a_co.send(P.AGREE, "fipa-request", cid, in_reply_to=request.reply_with)
        assert foreign.next(cid="bring").performative is P.AGREE
        failed = CommandOutcome(command_id=cid, succeeded=False, detail="the cup is out of reach")
        a_co.send(P.FAILURE, "fipa-request", cid, failed, in_reply_to=request.reply_with)
        assert foreign.next(P.INFORM, P.FAILURE, cid="bring").performative is P.FAILURE
