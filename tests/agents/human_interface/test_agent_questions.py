"""a_hi answers a person's questions about the kitchen from a_km (C7, fipa-query, L_WM): on a
MemoryBus with the real a_km and a stand-in a_co and a_ta. The answer says when the knowledge is
from, measured on a_hi's clock (here a wall clock started at :data:`NOW`); when a_km is away, fails
or does not answer in time, a_hi says it cannot reach its knowledge — it never leaves the person
waiting. "What can you do?" needs no a_km."""

from __future__ import annotations

import threading

import pytest

import services.agents.human_interface.asking as asking
from services.agents.human_interface.agent import HumanInterface
from services.agents.human_interface.answers import NO_KNOWLEDGE
from services.agents.human_interface.vocabulary import VOCABULARY_QUERY
from services.agents.knowledge.agent import KnowledgeManager
from services.agents.knowledge.world_model import KnowledgeError
from services.runtime import keys
from services.runtime.human import HumanReport, ReportKind, RequestKind
from services.runtime.memory_transport import MemoryTransport
from services.runtime.sources import SYSTEM
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import Answer, ObjectUpdate, WorldUpdate
from tests.agents.human_interface.test_agent import Stage
from tests.agents.human_interface.test_agent_words import say
from tests.agents.knowledge.test_agent import Peer

NOW = 1_800_000_000.0
"""a_hi's wall clock (POSIX s) when a test starts it."""
LOOKED = NOW - 7200.0
"""When a_ta saw the bowl (its clock): two hours before, as long as a test takes less than 30 min."""
POSE = Pose(position=(0.7, -0.2, 0.85), orientation=(1.0, 0.0, 0.0, 0.0))


class ClockFromNow:
    """The system's clocks and identifiers, but a wall clock that starts at :data:`NOW`."""

    monotonic = staticmethod(SYSTEM.monotonic)
    random_bytes = staticmethod(SYSTEM.random_bytes)
    new_id = staticmethod(SYSTEM.new_id)

    def __init__(self) -> None:
        self.start = SYSTEM.monotonic()

    def time(self) -> float:
        return NOW + SYSTEM.monotonic() - self.start


def start_hi(stage: Stage) -> HumanInterface:
    transport = stage.bus.transport()
    transport.sources = ClockFromNow()  # type: ignore[attr-defined]
    stage.hi = HumanInterface(transport)
    stage.start(stage.hi)
    return stage.hi


def with_km(stage: Stage) -> tuple[KnowledgeManager, Peer]:
    ta = Peer(stage.bus)  # plays a_ta towards a_km
    km = KnowledgeManager(stage.bus.transport())
    stage.start(km)  # its token is there before a_hi starts
    co = stage.co()
    start_hi(stage)
    assert co.subscribed.wait(5.0)
    return km, ta


def answer(stage: Stage, text: str, request_id: str) -> HumanReport:
    say(stage, text, request_id)
    (report,) = stage.person.until_final(request_id)
    return report


def c7(stage: Stage) -> list[str]:
    return [k for k, _ in stage.bus.published if k == keys.fipa_key("C7", "a_hi", "a_km")]


def test_what_is_in_the_bowl_before_and_after_a_ta_looked(stage: Stage) -> None:
    _km, ta = with_km(stage)
    before = answer(stage, "what is in the bowl?", "q1")
    assert (before.kind, before.request) == (ReportKind.ANSWER, RequestKind.QUESTION)
    assert before.text == "I have not looked into the bowl yet."
    assert before.done_as_asked
    ta.update(
        WorldUpdate(stamp=12.0, objects=(ObjectUpdate(name="bowl", pose=POSE, particles=18),), seen_at=LOOKED)
    )
    after = answer(stage, "What's in the bowl?", "q2")
    assert after.text == "The bowl held 18 spheres when I last looked, 2 h ago."
    empty = answer(stage, "is it empty?", "q3")
    assert empty.text == "No, the bowl held 18 spheres when I last looked, 2 h ago."
    where = answer(stage, "where is the bowl?", "q4")
    assert where.text == "The bowl is in the cabinet; I last saw it 2 h ago."
    # each sentence asked a_km for the words, each question once more for the answer
    assert len(c7(stage)) == 1 + 4 + 4


def test_an_unknown_thing_is_said_to_be_unseen_without_asking_a_km(stage: Stage) -> None:
    with_km(stage)
    report = answer(stage, "where is the spoon?", "q1")
    assert report.kind is ReportKind.NOT_UNDERSTOOD and report.text.startswith("I have not seen a spoon")
    assert len(c7(stage)) == 1 + 1  # the words only


def test_what_can_you_do_is_answered_from_a_hi_s_own_task_words(stage: Stage) -> None:
    start_hi(stage)  # no a_km
    report = answer(stage, "what can you do?", "q1")
    assert report.kind is ReportKind.ANSWER
    assert "pour" in report.text and "find" in report.text and "'what is in the bowl?'" in report.text
    assert c7(stage) == []


def test_with_a_km_away_the_person_is_told_at_once(stage: Stage) -> None:
    start_hi(stage)  # no a_km
    report = answer(stage, "what is in the jar?", "q1")
    assert (report.kind, report.text) == (ReportKind.ANSWER, NO_KNOWLEDGE)
    assert c7(stage) == []


def test_a_failing_a_km_is_told_as_knowledge_out_of_reach(stage: Stage) -> None:
    km, _ta = with_km(stage)
    sparql = km.world.sparql

    def failing(text: str) -> Answer:
        if text == VOCABULARY_QUERY:
            return sparql(text)
        raise KnowledgeError("the store is broken")

    km.world.sparql = failing  # type: ignore[method-assign]
    report = answer(stage, "is the jar empty?", "q1")
    assert (report.kind, report.text) == (ReportKind.ANSWER, NO_KNOWLEDGE)


def test_an_a_km_that_does_not_answer_in_time_is_told_as_knowledge_out_of_reach(
    stage: Stage, monkeypatch: pytest.MonkeyPatch
) -> None:
    km, _ta = with_km(stage)
    monkeypatch.setattr(asking, "QUESTION_REPLY_BY_S", 0.3)
    sparql = km.world.sparql
    release = threading.Event()

    def stuck(text: str) -> Answer:
        if text != VOCABULARY_QUERY:
            release.wait(10.0)  # a_km busy past a_hi's reply-by deadline
        return sparql(text)

    km.world.sparql = stuck  # type: ignore[method-assign]
    try:
        report = answer(stage, "what is on the table?", "q1")
    finally:
        release.set()
    assert (report.kind, report.text) == (ReportKind.ANSWER, NO_KNOWLEDGE)


def test_a_question_open_when_a_km_went_away_is_asked_again_of_the_a_km_back(stage: Stage) -> None:
    """a_km's token goes while a question waits for it (its answer is lost with it), then
    comes back (a restarted a_km): a_hi asks the question again, and the person gets its answer."""
    km, _ta = with_km(stage)
    sparql = km.world.sparql
    asked, release = threading.Event(), threading.Event()

    def slow(text: str) -> Answer:
        if text != VOCABULARY_QUERY and not asked.is_set():
            asked.set()
            release.wait(10.0)  # the first a_km never answers in time: it goes away meanwhile
        return sparql(text)

    km.world.sparql = slow  # type: ignore[method-assign]
    say(stage, "where is the cup?", "q1")
    try:
        assert asked.wait(5.0)
        transport = km.engine.transport
        assert isinstance(transport, MemoryTransport)
        transport.withdraw(keys.alive_key("a_km"))  # gone: its session ended
        transport.announce(keys.alive_key("a_km"))  # back: a restarted a_km
    finally:
        release.set()
    (report,) = stage.person.until_final("q1")
    assert (report.kind, report.text) == (ReportKind.ANSWER, "The cup is in the cabinet, as far as I know.")
    questions = [
        p for k, p in stage.bus.published if k == keys.fipa_key("C7", "a_hi", "a_km") and b"seenAt" in p
    ]
    assert len(questions) == 2  # asked, and asked again
