"""a_hi asks a_km for the words (C7, fipa-query, L_WM) before it reads a sentence: a thing a_km
learnt a moment ago can be named; a conversation per person keeps "it" and questions back; a
stop is acted on at once. On a MemoryBus with the real a_km, a stand-in a_co and a_ta."""

from __future__ import annotations

import logging
import queue

import msgspec
import pytest

from services.agents.human_interface.agent import HumanInterface
from services.agents.knowledge.agent import KnowledgeManager
from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.human import HumanInput, ReportKind
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import HumanCommand, TaskAtom
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate
from tests.agents.human_interface.test_agent import TIMEOUT, ScriptedCo, Stage
from tests.agents.human_interface.test_corpus import two_cups
from tests.agents.knowledge.test_agent import Peer


def say(stage: Stage, text: str, request_id: str, person: str = "") -> None:
    payload = msgspec.json.encode(HumanInput(text=text, request_id=request_id, person=person))
    stage.bus.publish(keys.HUMAN_IN, payload)


def goal(co: ScriptedCo) -> TaskAtom:
    request = co.receive(Performative.REQUEST)
    assert isinstance(request.content, HumanCommand)
    return request.content.goal


def _with_km(stage: Stage) -> tuple[ScriptedCo, HumanInterface, Peer]:
    ta = Peer(stage.bus)  # plays a_ta towards a_km
    stage.start(KnowledgeManager(stage.bus.transport()))  # its token is there before a_hi starts
    co = stage.co()
    hi = stage.start_hi()
    assert co.subscribed.wait(TIMEOUT)
    return co, hi, ta


@pytest.mark.requirement("R1.3")
def test_a_thing_a_km_learns_at_run_time_can_be_named_the_next_moment(stage: Stage) -> None:
    co, _hi, ta = _with_km(stage)
    say(stage, "bring me the tea pot", "r1")
    (report,) = stage.person.until_final("r1")
    assert report.kind is ReportKind.NOT_UNDERSTOOD and "'tea'" in report.text
    ta.update(
        WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="tea_pot", location="table", relation="on"),))
    )
    say(stage, "could you bring me the tea pot?", "r1")  # the same request id: a new C7 conversation
    assert goal(co) == TaskAtom("bring", ("tea_pot",))
    asked = [k for k, _ in stage.bus.published if k == keys.fipa_key("C7", "a_hi", "a_km")]
    answered = [k for k, _ in stage.bus.published if k == keys.fipa_key("C7", "a_km", "a_hi")]
    # a query-ref and its inform-ref when a_km's token appeared (a_hi started), and one per sentence
    assert len(asked) == len(answered) == 3


def test_it_is_kept_per_person(stage: Stage) -> None:
    co, _hi, _ta = _with_km(stage)
    say(stage, "bring me the cup", "a1", person="ann")
    assert goal(co) == TaskAtom("bring", ("cup",))
    say(stage, "hand me the jar", "b1", person="bob")
    assert goal(co) == TaskAtom("hand_over", ("jar",))
    say(stage, "put it on the table", "a2", person="ann")
    assert goal(co) == TaskAtom("place", ("cup", "table"))
    say(stage, "put it back", "b2", person="bob")
    assert goal(co) == TaskAtom("return", ("jar",))


def test_a_question_back_and_the_answer_that_completes_the_command(stage: Stage) -> None:
    co = stage.co()
    hi = HumanInterface(stage.bus.transport())
    hi.vocabulary = two_cups()  # a_km away: a_hi reads with the last words it has
    stage.hi = hi
    stage.start(hi)
    assert co.subscribed.wait(TIMEOUT)
    say(stage, "bring me the cup", "r1", person="ann")
    (question,) = stage.person.until_final("r1")
    assert question.kind is ReportKind.NOT_UNDERSTOOD
    assert question.text == "Which cup: the one in the cabinet or the one on the table?"
    say(stage, "the blue one", "r2", person="bob")  # another person: no question pending
    (other,) = stage.person.until_final("r2")
    assert other.kind is ReportKind.NOT_UNDERSTOOD
    say(stage, "the one on the table", "r3", person="ann")
    assert goal(co) == TaskAtom("bring", ("cup_2",))


class SilentKm(Agent):
    """An a_km that is alive and never answers."""

    name = "a_km"
    period = 0.01

    def build_fsm(self) -> FSM:
        return FSM([Behaviour("idle", self._idle, terminal=lambda: False)])

    def _idle(self) -> None:
        self.engine.x.clear()


def _with_silent_km(stage: Stage) -> ScriptedCo:
    stage.start(SilentKm(stage.bus.transport()))
    co = stage.co()
    stage.start_hi()
    assert co.subscribed.wait(TIMEOUT)
    return co


def test_stop_acts_at_once_and_drops_the_sentences_waiting_for_words(stage: Stage) -> None:
    co = _with_silent_km(stage)
    say(stage, "bring me the cup", "r1")
    say(stage, "stop", "r2")
    (dropped,) = stage.person.until_final("r1")
    assert dropped.kind is ReportKind.NOT_UNDERSTOOD and "dropped" in dropped.text
    (stopped,) = stage.person.until_final("r2")
    assert stopped.kind is ReportKind.STOPPED
    with pytest.raises(queue.Empty):
        co.inbox.get(timeout=0.3)


def test_without_an_answer_from_a_km_the_last_words_are_used(
    stage: Stage, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING, logger="a_hi")
    co = _with_silent_km(stage)
    say(stage, "pour the jar into the bowl", "r1")
    assert goal(co) == TaskAtom("pour", ("jar", "bowl"))  # after the query's reply-by (2 s)
    warned = [r.getMessage() for r in caplog.records if "gave no vocabulary" in r.getMessage()]
    assert warned and all(w.startswith("a_km gave no vocabulary (a_km did not answer") for w in warned)
