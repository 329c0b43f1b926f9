"""a_hi's language: every form of the earlier pattern-based version still understood (now by the
grammar), urgency, deadlines, words from the ontology, one-line answers when not understood."""

from __future__ import annotations

import pytest

from services.agents.human_interface.language import (
    URGENT_PRIORITY,
    Command,
    Incomplete,
    NotUnderstood,
    StatusRequest,
    Stop,
    UnknownReference,
    default_vocabulary,
    describe,
    interpret,
)
from shared.fipa_codec.languages.l_hc import TaskAtom


@pytest.mark.parametrize(
    ("sentence", "name", "args"),
    [
        ("pour the jar into the bowl", "pour", ("jar", "bowl")),
        ("Pour jar in bowl.", "pour", ("jar", "bowl")),
        ("put the jar on the table", "place", ("jar", "table")),
        ("place the cup on the table", "place", ("cup", "table")),
        ("put the jar back on the table", "place", ("jar", "table")),
        ("bring the cup to the table", "bring", ("cup",)),
        ("bring me the jar", "bring", ("jar",)),
        ("fetch the bowl", "bring", ("bowl",)),
        ("get me the jar", "bring", ("jar",)),
        ("put the jar back in the cabinet", "return", ("jar",)),
        ("put the jar back", "return", ("jar",)),
        ("return the cup", "return", ("cup",)),
        ("put the cup away", "return", ("cup",)),
        ("put the jar in the cabinet", "return", ("jar",)),
        ("hand me the cup", "hand_over", ("cup",)),
        ("give me the jar", "hand_over", ("jar",)),
        ("hand over the bowl", "hand_over", ("bowl",)),
        ("give the cup to me", "hand_over", ("cup",)),
    ],
)
def test_every_command_form_names_its_task(sentence: str, name: str, args: tuple[str, ...]) -> None:
    intent = interpret(sentence)
    assert intent == Command(TaskAtom(name, args))


@pytest.mark.parametrize("sentence", ["stop", "Stop everything!", "cancel", "please stop now", "STOP."])
def test_stop_forms(sentence: str) -> None:
    assert interpret(sentence) == Stop()


@pytest.mark.parametrize(
    "sentence", ["what are you doing?", "Status", "What's going on?", "robot, what are you doing now?"]
)
def test_status_forms(sentence: str) -> None:
    assert interpret(sentence) == StatusRequest()


@pytest.mark.parametrize(
    "sentence",
    [
        "Please, pour the jar into the bowl!",
        "could you please pour the jar into the bowl?",
        "POUR THE JAR INTO THE BOWL please",
        "I'd like you to pour the jar into the bowl, thanks",
    ],
)
def test_articles_politeness_punctuation_and_case_are_tolerated(sentence: str) -> None:
    assert interpret(sentence) == Command(TaskAtom("pour", ("jar", "bowl")))


@pytest.mark.parametrize(
    "sentence",
    [
        "urgently bring me the cup",
        "bring me the cup now",
        "quickly bring me the cup",
        "bring me the cup right away",
        "first, bring me the cup",
        "bring me the cup immediately",
    ],
)
def test_urgency_raises_the_priority(sentence: str) -> None:
    intent = interpret(sentence)
    assert isinstance(intent, Command)
    assert intent.goal == TaskAtom("bring", ("cup",))
    assert intent.priority == URGENT_PRIORITY > 0


def test_priority_defaults_to_zero_and_an_explicit_priority_wins() -> None:
    plain = interpret("bring me the cup")
    assert isinstance(plain, Command) and plain.priority == 0
    given = interpret("urgently bring me the cup", priority=2)
    assert isinstance(given, Command) and given.priority == 2
    unhurried = interpret("bring me the cup", priority=7)
    assert isinstance(unhurried, Command) and unhurried.priority == 7


@pytest.mark.parametrize(
    ("sentence", "seconds"),
    [
        ("pour the jar into the bowl within 30 seconds", 30.0),
        ("pour the jar into the bowl within 2 minutes", 120.0),
        ("within 1.5 min pour the jar into the bowl", 90.0),
        ("pour the jar into the bowl within a minute", 60.0),
        ("pour the jar into the bowl within an hour", 3600.0),
        ("pour the jar into the bowl within ten seconds", 10.0),
    ],
)
def test_within_sets_the_deadline(sentence: str, seconds: float) -> None:
    intent = interpret(sentence)
    assert isinstance(intent, Command)
    assert intent.goal == TaskAtom("pour", ("jar", "bowl"))
    assert intent.deadline_s == seconds
    assert intent.priority == 0


def test_urgency_and_deadline_together() -> None:
    intent = interpret("bring me the mug right away, within 45 seconds")
    assert intent == Command(TaskAtom("bring", ("cup",)), URGENT_PRIORITY, 45.0)


@pytest.mark.parametrize(
    ("sentence", "args"),
    [
        ("pour the glass jar into the salad bowl", ("jar", "bowl")),
        ("put the mug on the kitchen table", ("cup", "table")),
        ("put the coffee cup on the dining table", ("cup", "table")),
    ],
)
def test_multi_word_names_map_to_known_names(sentence: str, args: tuple[str, ...]) -> None:
    intent = interpret(sentence)
    assert isinstance(intent, Command) and intent.goal.args == args


def test_the_words_for_things_come_from_the_ontology() -> None:
    vocabulary = default_vocabulary()
    assert {t.name for t in vocabulary.things} >= {"jar", "bowl", "cup", "table", "cabinet"}
    assert vocabulary.named(("mug",))[0].name == "cup"
    assert vocabulary.named(("cupboard",))[0].name == "cabinet"
    assert interpret("put the jar back in the cupboard") == Command(TaskAtom("return", ("jar",)))


def test_an_unknown_object_is_named_in_the_answer() -> None:
    """Before the grammar, an unknown phrase was passed on as a name (``teapot``) for a_pl to
    refuse; now a_hi says at once which word it does not know and what it can name."""
    for sentence, word in (("pour the teapot into the bowl", "teapot"), ("hand me the tea pot", "tea")):
        with pytest.raises(UnknownReference) as info:
            interpret(sentence)
        text = str(info.value)
        assert f"'{word}'" in text and "the jar" in text and "\n" not in text


def test_an_unknown_verb_is_named_with_what_could_be_said() -> None:
    with pytest.raises(NotUnderstood) as info:
        interpret("sing me a song")
    text = str(info.value)
    assert not isinstance(info.value, Incomplete)
    assert "'sing'" in text and "pour" in text and "hand over" in text and "stop" in text
    assert "'pour the jar into the bowl'" in text and "\n" not in text


def test_an_empty_sentence_is_not_understood() -> None:
    with pytest.raises(NotUnderstood, match="empty sentence"):
        interpret("  ")


@pytest.mark.parametrize(
    ("sentence", "missing", "question"),
    [
        ("pour it into the bowl", "object", "Which object should I pour into the bowl?"),
        ("pour into the bowl", "object", "Which object should I pour into the bowl?"),
        ("pour the jar", "destination", "Into what should I pour the jar?"),
        ("put the jar on", "destination", "Where should I put the jar?"),
        ("put it on the table", "object", "Which object should I put on the table?"),
        ("bring me that", "object", "What should I bring?"),
        ("hand me", "object", "What should I hand you?"),
        ("put it back", "object", "What should I put back?"),
    ],
)
def test_an_incomplete_sentence_gets_a_question(sentence: str, missing: str, question: str) -> None:
    with pytest.raises(Incomplete) as info:
        interpret(sentence)
    assert info.value.missing == missing
    assert str(info.value).startswith(question)
    assert "Say e.g." in str(info.value)


def test_other_polite_refusals() -> None:
    with pytest.raises(NotUnderstood, match="one object at a time"):
        interpret("bring me the jar and the cup")
    with pytest.raises(NotUnderstood, match="say 'stop'"):
        interpret("stop the pouring")
    with pytest.raises(NotUnderstood, match="within 30 seconds"):
        interpret("pour the jar into the bowl within 3 parsecs")


def test_describe_words_every_task() -> None:
    assert describe(TaskAtom("pour", ("jar", "bowl"))) == "pour the jar into the bowl"
    assert describe(TaskAtom("place", ("cup", "table"))) == "put the cup on the table"
    assert describe(TaskAtom("bring", ("cup",))) == "bring the cup to the table"
    assert describe(TaskAtom("return", ("jar",))) == "put the jar back in the cabinet"
    assert describe(TaskAtom("hand_over", ("tea_pot",))) == "hand you the tea pot"
    assert describe(TaskAtom("fetch", ("cup",))) == "pick up the cup"  # tasks.toml's first frame
    assert describe(TaskAtom("localise", ("bowl",))) == "find the bowl"
    assert describe(TaskAtom("juggle", ("bowl",))) == "juggle(bowl)"  # a task with no words
