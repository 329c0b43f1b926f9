"""a_hi's fast path for a stop, its bound on a line, and a_km's words after a_km (re)starts: on
a MemoryBus with the stand-in a_co of test_agent.py and a_km played by hand on C7."""

from __future__ import annotations

import queue
import threading
from typing import Any

import pytest

from services.agents.human_interface.agent import HumanInterface
from services.agents.human_interface.vocabulary import ROCO_IRI, Vocabulary
from services.runtime import keys
from services.runtime.human import MAX_LINE_CHARS, ReportKind, RequestKind
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import encode_content
from shared.fipa_codec.languages.l_hc import HumanCommand, TaskAtom
from shared.fipa_codec.languages.l_wm import Answer
from tests.agents.human_interface.test_agent import TIMEOUT, Person, ScriptedCo, Stage, _ready
from tests.agents.human_interface.test_agent_words import _with_silent_km, goal, say
from tests.agents.human_interface.test_stop import STOPS


def _two_commands(co: ScriptedCo, person: Person) -> None:
    person.say("pour the jar into the bowl", "r1")
    first = co.receive(Performative.REQUEST)
    person.say("bring me the cup", "r2")
    second = co.receive(Performative.REQUEST)
    co.do(
        lambda co: (co.engine.reply(first, Performative.AGREE), co.engine.reply(second, Performative.AGREE))
    )
    assert person.next("r1").kind is ReportKind.ACCEPTED
    assert person.next("r2").kind is ReportKind.ACCEPTED


def test_every_way_to_say_stop_is_a_stop_and_never_refused(stage: Stage) -> None:
    _co, _hi, person = _ready(stage)
    for n, line in enumerate(STOPS):
        person.say(line, f"s{n}")
        (report,) = person.until_final(f"s{n}")
        assert (report.kind, report.request) == (ReportKind.STOPPED, RequestKind.STOP), line
        assert report.text == "Nothing is running, so there is nothing to stop.", line


def test_a_stop_naming_an_activity_stops_every_command_and_says_so(stage: Stage) -> None:
    co, hi, person = _ready(stage)
    _two_commands(co, person)
    person.say("Oh no, stop pouring!", "r3")
    cancels = [co.receive(Performative.CANCEL), co.receive(Performative.CANCEL)]
    assert {c.msg.conversation_id for c in cancels} == {"cmd-r1", "cmd-r2"}
    stopping = person.next("r3")
    assert (stopping.kind, stopping.request) == (ReportKind.PROGRESS, RequestKind.STOP)
    assert stopping.text == (
        "Stopping 2 commands: pour the jar into the bowl; bring the cup to the table "
        "(I stop every open command, not only 'pouring')."
    )
    assert set(hi.stops["r3"].waiting) == {"cmd-r1", "cmd-r2"}


def test_a_stop_in_a_longer_sentence_is_acted_on_before_a_km_answers(stage: Stage) -> None:
    co = _with_silent_km(stage)  # a_km alive and silent: a sentence waits 2 s for its words
    say(stage, "bring me the cup", "r1")
    say(stage, "wait, that's the wrong cup", "r2")
    (stopped,) = stage.person.until_final("r2")  # before r1's question to a_km has ended
    assert (stopped.kind, stopped.request) == (ReportKind.STOPPED, RequestKind.STOP)
    assert co.inbox.empty()


def test_a_line_over_the_bound_is_refused_with_one_line(stage: Stage) -> None:
    co, hi, person = _ready(stage)
    line = "please " * 140 + "pour the jar into the bowl"
    assert len(line) > MAX_LINE_CHARS
    person.say(line, "r1")
    (report,) = person.until_final("r1")
    assert report.kind is ReportKind.NOT_UNDERSTOOD and report.request is None
    assert report.text == (
        f"Your line has {len(line):,} characters; I read lines of at most 1,000: "
        "please say it in fewer words."
    )
    assert "\n" not in report.text
    with pytest.raises(queue.Empty):
        co.receive(Performative.REQUEST, timeout=0.3)
    person.say(line[-MAX_LINE_CHARS:], "r2")  # at the bound: read as before
    request = co.receive(Performative.REQUEST)
    assert isinstance(request.content, HumanCommand)
    assert request.content.goal == TaskAtom("pour", ("jar", "bowl"))
    assert hi.counters["behaviour_errors"] == 0


def test_a_line_over_the_bound_that_asks_to_stop_still_stops(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    _two_commands(co, person)
    person.say("the beans are going everywhere and " * 300 + "oh no, STOP!", "r3")
    cancels = {co.receive(Performative.CANCEL).msg.conversation_id for _ in range(2)}
    assert cancels == {"cmd-r1", "cmd-r2"}
    assert person.next("r3").text.startswith("Stopping 2 commands")


def test_a_stop_is_not_held_back_by_the_line_being_read_before_it(
    stage: Stage, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The reader thread is held inside the parse of a command; the stop after it is acted on
    meanwhile, and the command, once read, is dropped: a_co never gets it."""
    from services.agents.human_interface import reading

    parsing, release = threading.Event(), threading.Event()
    interpret = reading.interpret

    def held_interpret(text: str, *args: Any, **kwargs: Any) -> Any:
        parsing.set()
        assert release.wait(TIMEOUT), "the test never released the reader"
        return interpret(text, *args, **kwargs)

    monkeypatch.setattr(reading, "interpret", held_interpret)
    co, hi, person = _ready(stage)
    person.say("pour the jar into the bowl", "r1")
    assert parsing.wait(TIMEOUT), "a_hi never began to read r1"
    person.say("stop!", "r2")
    (stopped,) = person.until_final("r2")  # while r1 is still being read
    assert (stopped.kind, stopped.request) == (ReportKind.STOPPED, RequestKind.STOP)
    release.set()
    (dropped,) = person.until_final("r1")
    assert dropped.kind is ReportKind.NOT_UNDERSTOOD
    assert dropped.text == "'pour the jar into the bowl' was dropped: you said stop before I had read it."
    person.say("bring me the cup", "r3")  # the next line is read and sent as before
    request = co.receive(Performative.REQUEST)
    assert request.msg.conversation_id == "cmd-r3"
    assert hi.counters["behaviour_errors"] == 0


# ---- a_km's words after a_km (re)starts ------------------------------------------------------
TEA_POT = (
    (f"{ROCO_IRI}tea_pot", "label", "tea pot"),
    (f"{ROCO_IRI}tea_pot", "on", f"{ROCO_IRI}table"),
    (f"{ROCO_IRI}table", "label", "table"),
)
"""a_km's answer to the vocabulary query after it learnt of a tea pot (rows: thing, kind, word)."""


class HandKm:
    """a_km played by hand: its liveliness token, the questions a_hi asks it on C7, answers."""

    def __init__(self, stage: Stage) -> None:
        self.bus = stage.bus
        self.questions: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        self.bus.subscribe(keys.fipa_key("C7", "a_hi", "a_km"), lambda _k, p: self.questions.put(decode(p)))

    def up(self) -> None:
        self.bus.announce(keys.alive_key("a_km"))

    def down(self) -> None:
        self.bus.withdraw(keys.alive_key("a_km"))

    def question(self) -> Communicate:
        asked = self.questions.get(timeout=TIMEOUT)
        assert asked.performative is Performative.QUERY_REF and asked.protocol == "fipa-query"
        return asked

    def answer(self, asked: Communicate, rows: tuple[tuple[str, str, str], ...]) -> None:
        language, body = encode_content(Answer(variables=("thing", "kind", "word"), rows=rows))
        reply = Communicate(
            performative=Performative.INFORM_REF,
            sender=AgentIdentifier("a_km"),
            receiver=(AgentIdentifier("a_hi"),),
            content=body,
            language=language,
            encoding="msgpack",
            ontology="O_RoCo",
            protocol="fipa-query",
            conversation_id=asked.conversation_id,
            in_reply_to=asked.reply_with,
        )
        self.bus.publish(keys.fipa_key("C7", "a_km", "a_hi"), encode(reply))


class WatchedHi(HumanInterface):
    """a_hi that tells when it takes new words (``words``, set on its thread)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.words = threading.Event()
        super().__init__(*args, **kwargs)

    @property
    def vocabulary(self) -> Vocabulary:
        return HumanInterface.vocabulary.fget(self)  # type: ignore[attr-defined]

    @vocabulary.setter
    def vocabulary(self, value: Vocabulary) -> None:
        HumanInterface.vocabulary.fset(self, value)  # type: ignore[attr-defined]
        self.words.set()


def test_a_km_is_asked_for_its_words_as_soon_as_its_token_appears(stage: Stage) -> None:
    km = HandKm(stage)
    co = stage.co()
    hi = WatchedHi(stage.bus.transport())
    stage.start(hi)
    assert co.subscribed.wait(TIMEOUT)  # a_km not up: a_hi has the files' words
    say(stage, "bring me the tea pot", "r1")
    (report,) = stage.person.until_final("r1")
    assert report.kind is ReportKind.NOT_UNDERSTOOD and "'tea'" in report.text
    assert km.questions.empty() and not hi.words.is_set()
    km.up()
    km.answer(km.question(), TEA_POT)  # asked with no sentence waiting
    assert hi.words.wait(TIMEOUT)
    km.down()  # gone again: the next sentence is read at once, with the words it gave
    say(stage, "bring me the tea pot", "r2")
    assert goal(co) == TaskAtom("bring", ("tea_pot",))


def test_sentences_waiting_for_an_a_km_that_restarts_get_the_new_words(stage: Stage) -> None:
    km = HandKm(stage)
    km.up()
    co, hi, _person = _ready(stage)
    km.question()  # the question when a_hi saw a_km's token: left unanswered (a_km hangs)
    say(stage, "bring me the tea pot", "r1")
    before = km.question()  # the sentence's question, asked of the a_km that hangs
    km.down()
    km.up()  # a_km restarted: asked at once, and the sentence waits for this answer
    km.answer(km.question(), TEA_POT)
    km.answer(before, ((f"{ROCO_IRI}cup", "label", "cup"),))  # too late: dropped, not read with
    assert goal(co) == TaskAtom("bring", ("tea_pot",))
    assert hi.vocabulary.thing("tea_pot") is not None
