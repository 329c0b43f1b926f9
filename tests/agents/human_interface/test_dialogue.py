"""A person's conversation with a_hi: "it" for the last object named, questions back when a
reference is ambiguous, and the command going on with the answer."""

from __future__ import annotations

import pytest

from services.agents.human_interface.language import (
    Ambiguous,
    Command,
    Dialogue,
    Incomplete,
    NotUnderstood,
    interpret,
)
from services.agents.human_interface.vocabulary import Vocabulary
from shared.fipa_codec.languages.l_hc import TaskAtom
from tests.agents.human_interface.test_corpus import two_cups


@pytest.fixture(scope="module")
def kitchen() -> Vocabulary:
    """The kitchen with a second cup, on the table."""
    return two_cups()


def test_it_is_the_last_object_the_same_person_named(kitchen: Vocabulary) -> None:
    ann, bob = Dialogue(), Dialogue()
    assert interpret("bring me the small cup", vocabulary=kitchen, dialogue=ann) == Command(
        TaskAtom("bring", ("cup",))
    )
    assert interpret("hand me the jar", vocabulary=kitchen, dialogue=bob) == Command(
        TaskAtom("hand_over", ("jar",))
    )
    assert interpret("put it on the table", vocabulary=kitchen, dialogue=ann) == Command(
        TaskAtom("place", ("cup", "table"))
    )
    # "now" first is the next step, not haste (grammar.py); "… right now" is haste
    assert interpret("now put that back", vocabulary=kitchen, dialogue=bob) == Command(
        TaskAtom("return", ("jar",))
    )
    assert interpret("put that back right now", vocabulary=kitchen, dialogue=bob) == Command(
        TaskAtom("return", ("jar",)), priority=5
    )
    with pytest.raises(Incomplete, match="Which object should I put on the table"):
        interpret("put it on the table", vocabulary=kitchen, dialogue=Dialogue())


def test_an_ambiguous_reference_is_asked_back_and_the_answer_completes_the_command(
    kitchen: Vocabulary,
) -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous) as info:
        interpret("urgently bring me the cup within 2 minutes", vocabulary=kitchen, dialogue=talk)
    assert str(info.value) == "Which cup: the one in the cabinet or the one on the table?"
    assert talk.pending is not None and set(talk.pending.candidates) == {"cup", "cup_2"}
    answer = interpret("the one on the table", vocabulary=kitchen, dialogue=talk)
    assert answer == Command(TaskAtom("bring", ("cup_2",)), priority=5, deadline_s=120.0)
    assert talk.pending is None and talk.last == "cup_2"


@pytest.mark.parametrize(
    ("reply", "chosen"),
    [
        ("the blue one", "cup_2"),
        ("the small one", "cup"),
        ("the one in the cabinet", "cup"),
        ("the mug on the table", "cup_2"),
    ],
)
def test_answers_by_adjective_or_place(kitchen: Vocabulary, reply: str, chosen: str) -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous):
        interpret("fill the cup from the jar", vocabulary=kitchen, dialogue=talk)
    assert interpret(reply, vocabulary=kitchen, dialogue=talk) == Command(TaskAtom("pour", ("jar", chosen)))


def test_an_answer_that_is_no_candidate_asks_again_and_a_new_command_drops_the_question(
    kitchen: Vocabulary,
) -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous):
        interpret("hand me the cup", vocabulary=kitchen, dialogue=talk)
    with pytest.raises(Ambiguous, match="which of them do you mean"):
        interpret("the jar", vocabulary=kitchen, dialogue=talk)
    assert talk.pending is not None
    assert interpret("pour the jar into the bowl", vocabulary=kitchen, dialogue=talk) == Command(
        TaskAtom("pour", ("jar", "bowl"))
    )
    assert talk.pending is None
    with pytest.raises(NotUnderstood, match="What should I do with the bowl"):
        interpret("the bowl", vocabulary=kitchen, dialogue=talk)


@pytest.mark.parametrize("non_answer", ["hmm", "I don't know", "whatever", "not sure", "it", "the cup"])
def test_an_answer_that_names_no_candidate_asks_the_question_again(
    kitchen: Vocabulary, non_answer: str
) -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous) as asked:
        interpret("urgently bring me the cup within 2 minutes", vocabulary=kitchen, dialogue=talk)
    question = str(asked.value)
    with pytest.raises(Ambiguous) as again:
        interpret(non_answer, vocabulary=kitchen, dialogue=talk)
    text = str(again.value)
    assert text.endswith(question) and text != question and "\n" not in text
    assert set(again.value.candidates) == {"cup", "cup_2"}
    assert talk.pending is not None and talk.pending.question == question
    answer = interpret("the blue one", vocabulary=kitchen, dialogue=talk)
    assert answer == Command(TaskAtom("bring", ("cup_2",)), priority=5, deadline_s=120.0)
    assert talk.pending is None


def test_an_answer_naming_a_thing_that_does_not_fit_says_so_and_asks_again(kitchen: Vocabulary) -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous):
        interpret("fill the cup from the jar", vocabulary=kitchen, dialogue=talk)
    with pytest.raises(Ambiguous) as again:
        interpret("the glass one", vocabulary=kitchen, dialogue=talk)
    assert str(again.value).startswith("I know of no one:") and str(again.value).endswith("?")
    assert interpret("the small one", vocabulary=kitchen, dialogue=talk) == Command(
        TaskAtom("pour", ("jar", "cup"))
    )


def test_a_refused_line_keeps_the_question_and_a_new_request_drops_it(kitchen: Vocabulary) -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous):
        interpret("hand me the cup", vocabulary=kitchen, dialogue=talk)
    with pytest.raises(NotUnderstood, match="control character"):
        interpret("the one\x1b on the table", vocabulary=kitchen, dialogue=talk)
    assert talk.pending is not None
    with pytest.raises(Ambiguous, match="does not answer"):  # no verb a_hi knows: no new request
        interpret("sing me a song", vocabulary=kitchen, dialogue=talk)
    assert interpret("find the bowl", vocabulary=kitchen, dialogue=talk) == Command(
        TaskAtom("localise", ("bowl",))
    )
    assert talk.pending is None


@pytest.mark.parametrize(
    ("answer", "priority", "deadline_s"),
    [
        ("the small one, and make it quick", 5, None),
        ("the small one within 2 minutes", 0, 120.0),
        ("the small one", 0, None),
    ],
)
def test_an_urgency_or_deadline_said_in_the_answer_goes_to_the_command(
    kitchen: Vocabulary, answer: str, priority: int, deadline_s: float | None
) -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous):
        interpret("bring me the cup", vocabulary=kitchen, dialogue=talk)
    assert interpret(answer, vocabulary=kitchen, dialogue=talk) == Command(
        TaskAtom("bring", ("cup",)), priority, deadline_s
    )
