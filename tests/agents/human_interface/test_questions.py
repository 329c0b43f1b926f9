"""a_hi's reader of questions about the kitchen (questions.py), through language.py's
``interpret``: many wordings of each kind, references resolved as a command's are, unknown
things said so, and sentences that are no questions left to the command grammar."""

from __future__ import annotations

import pytest

from services.agents.human_interface.language import (
    Ambiguous,
    Command,
    Dialogue,
    Incomplete,
    NotUnderstood,
    StatusRequest,
    Stop,
    UnknownReference,
    WorldQuestion,
    default_vocabulary,
    interpret,
)
from services.agents.human_interface.questions import MAX_QUESTION_CHARS, question_words
from shared.fipa_codec.languages.l_hc import TaskAtom
from tests.agents.human_interface.test_corpus import two_cups

QUESTIONS: tuple[tuple[str, WorldQuestion], ...] = (
    ("what is in the bowl?", WorldQuestion("contents", "bowl")),
    ("What's in the bowl?", WorldQuestion("contents", "bowl")),
    ("whats inside the salad bowl", WorldQuestion("contents", "bowl")),
    ("what does the jar hold?", WorldQuestion("contents", "jar")),
    ("what does the glass jar contain", WorldQuestion("contents", "jar")),
    ("is there anything in the cup?", WorldQuestion("contents", "cup")),
    ("robot, what is in the cabinet?", WorldQuestion("contents", "cabinet")),
    ("what is in the cupboard now?", WorldQuestion("contents", "cabinet")),
    ("where is the cup?", WorldQuestion("where", "cup")),
    ("where's the jar", WorldQuestion("where", "jar")),
    ("wheres the dish", WorldQuestion("where", "bowl")),
    ("where are the beans?", WorldQuestion("where", "jar")),
    ("where is the small cup right now?", WorldQuestion("where", "cup")),
    ("Where did you put the bowl?", WorldQuestion("where", "bowl")),
    ("where have you left the mug", WorldQuestion("where", "cup")),
    ("what is on the table?", WorldQuestion("on", "table")),
    ("what's on the kitchen table", WorldQuestion("on", "table")),
    ("is there anything on the table?", WorldQuestion("on", "table")),
    ("is the jar empty?", WorldQuestion("empty", "jar")),
    ("please, is the bowl empty", WorldQuestion("empty", "bowl")),
    ("is the bowl full?", WorldQuestion("full", "bowl")),
    ("is the cup on the table?", WorldQuestion("located", "cup", place="table", relation="on")),
    ("is the jar in the cabinet", WorldQuestion("located", "jar", place="cabinet", relation="in")),
    ("is the bowl inside the cupboard?", WorldQuestion("located", "bowl", place="cabinet", relation="in")),
    ("how many spheres are in the bowl?", WorldQuestion("count", "bowl")),
    ("how many balls are there in the jar", WorldQuestion("count", "jar")),
    ("how many things are in the cabinet?", WorldQuestion("count", "cabinet", counted="things")),
    ("how many objects are inside the cabinet", WorldQuestion("count", "cabinet", counted="things")),
    ("how full is the bowl?", WorldQuestion("count", "bowl")),
    ("how much is in the jar?", WorldQuestion("count", "jar")),
    ("what did you see?", WorldQuestion("seen")),
    ("what have you seen so far", WorldQuestion("seen")),
    ("what do you see?", WorldQuestion("seen")),
    ("what can you do?", WorldQuestion("abilities")),
    ("what are you able to do", WorldQuestion("abilities")),
    ("help", WorldQuestion("abilities")),
)
"""Questions against the kitchen as O_RoCo states it (one jar, bowl, cup, table, cabinet)."""

NOT_QUESTIONS: tuple[tuple[str, object], ...] = (
    ("pour the jar into the bowl", Command(TaskAtom("pour", ("jar", "bowl")))),
    ("please pour what is in the jar into the bowl", Command(TaskAtom("pour", ("jar", "bowl")))),
    ("find the jar", Command(TaskAtom("localise", ("jar",)))),
    ("tell me where the cup is", Command(TaskAtom("localise", ("cup",)))),
    ("have you seen the bowl?", Command(TaskAtom("localise", ("bowl",)))),
    ("put the cup on the table", Command(TaskAtom("place", ("cup", "table")))),
    ("what are you doing?", StatusRequest()),
    ("stop", Stop()),
)
"""Sentences that are no questions about the kitchen: commands, a status request, a stop."""


@pytest.mark.parametrize(("sentence", "question"), QUESTIONS, ids=[s for s, _ in QUESTIONS])
def test_each_wording_of_a_question_is_read(sentence: str, question: WorldQuestion) -> None:
    assert interpret(sentence, vocabulary=default_vocabulary()) == question


@pytest.mark.parametrize(("sentence", "intent"), NOT_QUESTIONS, ids=[s for s, _ in NOT_QUESTIONS])
def test_commands_status_and_stops_stay_what_they_were(sentence: str, intent: object) -> None:
    assert interpret(sentence, vocabulary=default_vocabulary()) == intent


def test_references_resolve_as_in_a_command() -> None:
    kitchen = two_cups()
    assert interpret("where is the blue cup?", vocabulary=kitchen) == WorldQuestion("where", "cup_2")
    on_the_table = WorldQuestion("contents", "cup_2")
    assert interpret("what is in the cup on the table", vocabulary=kitchen) == on_the_table
    with pytest.raises(Ambiguous, match="Which cup"):
        interpret("is the cup empty?", vocabulary=kitchen)


def test_it_is_the_last_thing_named_and_a_question_names_one() -> None:
    talk = Dialogue()
    assert interpret("bring me the jar", dialogue=talk) == Command(TaskAtom("bring", ("jar",)))
    assert interpret("is it empty?", dialogue=talk) == WorldQuestion("empty", "jar")
    assert interpret("where is the bowl?", dialogue=talk) == WorldQuestion("where", "bowl")
    assert interpret("what is in it?", dialogue=talk) == WorldQuestion("contents", "bowl")
    assert interpret("put it on the table", dialogue=talk) == Command(TaskAtom("place", ("bowl", "table")))


def test_a_question_drops_the_question_a_hi_asked_back() -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous):
        interpret("hand me the cup", vocabulary=two_cups(), dialogue=talk)
    assert talk.pending is not None
    assert interpret("what is in the jar?", vocabulary=two_cups(), dialogue=talk) == WorldQuestion(
        "contents", "jar"
    )
    assert talk.pending is None


def test_an_unknown_thing_is_said_to_be_unseen() -> None:
    with pytest.raises(UnknownReference, match="I have not seen a spoon"):
        interpret("where is the spoon?")
    with pytest.raises(UnknownReference, match="I have not seen an egg"):
        interpret("is the egg in the cabinet?")
    with pytest.raises(UnknownReference, match="I have not seen a teapot"):
        interpret("what is in the teapot")


def test_a_question_cut_short_asks_which_object() -> None:
    for cut in ("where is", "where's", "where is the", "what is in the"):
        with pytest.raises(Incomplete, match="Which object do you ask about"):
            interpret(cut)
    with pytest.raises(Incomplete, match="Which object do you mean"):
        interpret("where is it?", dialogue=Dialogue())


def test_a_line_over_the_bound_is_not_read_as_a_question() -> None:
    short = "where is the " + "small " * 2 + "cup?"
    assert interpret(short) == WorldQuestion("where", "cup")
    long = "where is the " + "small " * 40 + "cup?"
    assert len(long) > MAX_QUESTION_CHARS
    with pytest.raises(NotUnderstood):  # the command grammar's refusal: "where" is no verb
        interpret(long)


def test_question_words_drop_address_please_and_now() -> None:
    assert question_words("Robot, please: what's in the bowl now, please?") == "whats in the bowl"
