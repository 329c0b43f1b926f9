"""What people say around a command (tolerance.py, steps.py, inflection.py): steps towards one
goal, a wish with the verb after the thing, context sentences that name what "it" is, a verb in
another form. Each reading is said back, and each has a line it must not take for a command."""

from __future__ import annotations

import pytest

from services.agents.human_interface.dialogue import Offer
from services.agents.human_interface.inflection import MAX_WORD, verb_lemmas
from services.agents.human_interface.intents import Command, NotUnderstood
from services.agents.human_interface.language import default_vocabulary, interpret
from services.agents.human_interface.steps import bare_bring, one_goal
from shared.fipa_codec.languages.l_hc import TaskAtom

POUR = Command(TaskAtom("pour", ("jar", "bowl")))
FETCH_JAR = Command(TaskAtom("fetch", ("jar",)))
BRING_JAR = Command(TaskAtom("bring", ("jar",)))
RETURN_JAR = Command(TaskAtom("return", ("jar",)))
BRING_CUP = Command(TaskAtom("bring", ("cup",)))


def _read(line: str) -> Command | NotUnderstood:
    try:
        got = interpret(line, vocabulary=default_vocabulary())
    except NotUnderstood as exc:
        return exc
    assert isinstance(got, Command), got
    return got


def test_a_step_towards_the_last_command_is_its_step() -> None:
    assert one_goal([FETCH_JAR, POUR]) == [FETCH_JAR, POUR]
    assert one_goal([BRING_JAR, POUR]) == [BRING_JAR, POUR]  # "take the jar and pour it …"
    assert one_goal([bare_bring(BRING_JAR), RETURN_JAR]) == [FETCH_JAR, RETURN_JAR]


def test_two_goals_are_not_one() -> None:
    assert one_goal([BRING_CUP, POUR]) is None  # "bring me the cup and pour the jar …"
    assert one_goal([BRING_JAR, RETURN_JAR]) is None  # "bring me the jar and put it back"
    assert one_goal([FETCH_JAR, Command(TaskAtom("pour", ("cup", "bowl")))]) is None


def test_a_question_back_counts_by_the_command_another_request_names() -> None:
    grab = Offer("bring or pick up?", BRING_JAR, FETCH_JAR)
    assert one_goal([grab, FETCH_JAR]) == [FETCH_JAR, FETCH_JAR]  # "grab the jar and hold it"
    assert one_goal([FETCH_JAR, grab]) == [FETCH_JAR, FETCH_JAR]
    assert one_goal([grab, grab]) is None  # which of the two is still not known


@pytest.mark.parametrize(
    ("line", "read"),
    [
        ("take the jar and pour the beans into the bowl", "pour the beans into the bowl"),
        ("First find the jar, then pour it into the bowl.", "pour it into the bowl."),
        ("Get the jar. Pour the beans in the bowl. Thanks.", "Pour the beans in the bowl."),
    ],
)
def test_a_line_of_steps_is_its_last_command_said_back(line: str, read: str) -> None:
    got = _read(line)
    assert isinstance(got, Command) and got.goal == POUR.goal and got.priority == 0, got
    assert (line, read) in got.read_as


@pytest.mark.parametrize(
    ("line", "goal"),
    [
        ("I need the beans poured into the bowl", POUR.goal),
        ("can you get the cup brought to me", BRING_CUP.goal),
        ("Make the beans go in the bowl!", POUR.goal),
        ("the cup should be in the cabinet", TaskAtom("return", ("cup",))),
        ("the bowl needs to go on the table", TaskAtom("place", ("bowl", "table"))),
    ],
)
def test_a_wish_with_the_verb_after_the_thing_is_its_command(line: str, goal: TaskAtom) -> None:
    got = _read(line)
    assert isinstance(got, Command) and got.goal == goal, got
    assert got.read_as and got.read_as[0][0] == line  # said back


@pytest.mark.parametrize(
    "line",
    [
        "the beans poured into the bowl",  # said, not asked
        "I poured the beans into the bowl",
        "the beans went in the bowl",
        "I don't want the beans poured into the bowl",
        "the cup should not be in the cabinet",
        "I want the cup washed",
    ],
)
def test_a_thing_said_done_or_not_wished_is_no_command(line: str) -> None:
    assert isinstance(_read(line), NotUnderstood)


@pytest.mark.parametrize(
    ("line", "goal"),
    [
        ("The beans are in the jar. I want them in the bowl.", POUR.goal),  # them: the plural one
        ("The cup is on the table. Put it back in the cabinet.", TaskAtom("return", ("cup",))),
        ("The bowl is empty. Fill it with the beans.", POUR.goal),  # "empty" said of the bowl
        ("I have a bowl here. Pour the beans into it.", POUR.goal),  # told, not asked
        ("You see the bowl on the table? Put the beans in it.", POUR.goal),
    ],
)
def test_a_sentence_of_context_names_what_it_is(line: str, goal: TaskAtom) -> None:
    got = _read(line)
    assert isinstance(got, Command) and got.goal == goal, got


def test_a_negated_context_still_keeps_its_object() -> None:
    assert isinstance(_read("I don't need the bowl. Bring it here."), NotUnderstood)


def test_verb_forms_come_from_the_package_and_are_bounded() -> None:
    assert verb_lemmas("poured")[0] == "pour"
    assert verb_lemmas("brought")[0] == "bring"
    assert verb_lemmas("emptied")[0] == "empty"
    assert verb_lemmas("x" * (MAX_WORD + 1)) == ()
    assert verb_lemmas("pour3d") == ()
