"""Describing words read by their meaning (similarity.py, meaning.py ``_by_meaning``), grounded
in what a_km says of the things: "the little bowl" is the small bowl only because a_km says a
bowl is small; "no, the other one" (language.py) takes the other of the two things a_hi's last
question offered."""

from __future__ import annotations

import pytest
from rdflib import Graph

from services.agents.human_interface import similarity
from services.agents.human_interface.language import (
    Ambiguous,
    Command,
    Dialogue,
    NotUnderstood,
    UnknownReference,
    WorldQuestion,
    interpret,
)
from services.agents.human_interface.vocabulary import KNOWLEDGE_FILES, Vocabulary
from shared.fipa_codec.languages.l_hc import TaskAtom

PREFIX = "@prefix roco: <https://w3id.org/roco/O_RoCo#> .\n"
SMALL_BLUE_BOWL = 'roco:bowl_2 a roco:Bowl ; roco:on roco:table ; roco:adjective "blue" , "small" .'


def _kitchen(extra: str = "") -> Vocabulary:
    graph = Graph()
    for path in KNOWLEDGE_FILES:
        graph.parse(path, format="turtle")
    if extra:
        graph.parse(data=PREFIX + extra, format="turtle")
    return Vocabulary.from_graph(graph)


def _bring(line: str, v: Vocabulary) -> Command:
    got = interpret(line, vocabulary=v)
    assert isinstance(got, Command), got
    return got


@pytest.mark.parametrize(
    ("line", "meant", "read"),
    [
        ("bring me the little bowl", "bowl_2", ("little", "small")),
        ("bring me the tiny bowl", "bowl_2", ("tiny", "small")),
        ("bring me the big bowl", "bowl", ("big", "large")),
        ("bring me the huge bowl", "bowl", ("huge", "large")),
    ],
)
def test_a_describing_word_reaches_the_one_a_km_uses(line: str, meant: str, read: tuple[str, str]) -> None:
    got = _bring(line, _kitchen(SMALL_BLUE_BOWL))
    assert got.goal == TaskAtom("bring", (meant,))
    assert read in got.read_as  # said back: "I read 'little' as 'small'."


def test_the_word_reaches_small_only_because_a_km_says_a_bowl_is_small() -> None:
    """The planted fault: the same kitchen without a_km's "small" for the second bowl."""
    v = _kitchen('roco:bowl_2 a roco:Bowl ; roco:on roco:table ; roco:adjective "blue" .')
    with pytest.raises(UnknownReference):
        interpret("bring me the little bowl", vocabulary=v)


def test_a_word_near_nothing_a_km_says_is_refused() -> None:
    v = _kitchen(SMALL_BLUE_BOWL)
    with pytest.raises(NotUnderstood) as info:
        interpret("bring me the tall bowl", vocabulary=v)
    assert "'tall'" in str(info.value)
    with pytest.raises(UnknownReference):  # a_km says no cup is large
        interpret("bring me the huge cup", vocabulary=v)


def test_nouns_are_not_read_by_meaning() -> None:
    """Between kitchen nouns the model does not separate (similarity.py): never guessed."""
    assert similarity.similarity("pan", "beans") < similarity.NEAR
    with pytest.raises(NotUnderstood):
        interpret("bring me the pan", vocabulary=_kitchen())


def test_the_model_separates_describing_words() -> None:
    assert similarity.nearest("little", ["small", "large"]) is not None
    assert similarity.nearest("little", ["small", "large"])[0] == "small"  # type: ignore[index]
    assert similarity.nearest("big", ["small", "large"])[0] == "large"  # type: ignore[index]
    assert similarity.nearest("tall", ["small", "large", "big"]) is None
    assert similarity.similarity("x" * (similarity.MAX_WORD + 1), "small") == 0.0


def test_no_the_other_one_takes_the_other_of_the_two_offered() -> None:
    v, talk = _kitchen(SMALL_BLUE_BOWL), Dialogue()
    with pytest.raises(Ambiguous):
        interpret("bring me the bowl", vocabulary=v, dialogue=talk)
    first = interpret("the small one", vocabulary=v, dialogue=talk)
    assert isinstance(first, Command) and first.goal == TaskAtom("bring", ("bowl_2",))
    other = interpret("no, the other one", vocabulary=v, dialogue=talk)
    assert isinstance(other, Command)
    assert other.goal == TaskAtom("bring", ("bowl",))
    assert other.instead_of == first.goal  # a_hi stops the first (agent.py ``_command``)
    again = interpret("sorry, I meant the other one", vocabulary=v, dialogue=talk)
    assert isinstance(again, Command) and again.goal == first.goal


def test_the_other_one_after_another_command_is_not_guessed() -> None:
    v, talk = _kitchen(SMALL_BLUE_BOWL), Dialogue()
    with pytest.raises(Ambiguous):
        interpret("bring me the bowl", vocabulary=v, dialogue=talk)
    interpret("the small one", vocabulary=v, dialogue=talk)
    interpret("put the jar on the table", vocabulary=v, dialogue=talk)
    with pytest.raises(NotUnderstood) as info:
        interpret("no, the other one", vocabulary=v, dialogue=talk)
    assert "choice of two" in str(info.value)


@pytest.mark.parametrize(
    ("line", "task"),
    [
        ("I'm so tired today. Could you bring me the cup?", TaskAtom("bring", ("cup",))),
        ("I lost the bowl. Can you find it?", TaskAtom("localise", ("bowl",))),
        ("Put the cup on the table for my teddy.", TaskAtom("place", ("cup", "table"))),
        ("Quick, pick up the cup before the baby knocks it over!", TaskAtom("fetch", ("cup",))),
        ("Bowl on table.", TaskAtom("place", ("bowl", "table"))),
        ("Cup back in cabinet.", TaskAtom("return", ("cup",))),
        ("The jar, please put on the table.", TaskAtom("place", ("jar", "table"))),
        ("Please, you pour beans from jar to bowl.", TaskAtom("pour", ("jar", "bowl"))),
        ("I need that you bring me the cup.", TaskAtom("bring", ("cup",))),
        ("Where did I leave my cup? Could you find it for me, dear?", TaskAtom("localise", ("cup",))),
        ("Jar on table put please.", TaskAtom("place", ("jar", "table"))),
        ("jar into bowl... pour... zzz", TaskAtom("pour", ("jar", "bowl"))),
        ("Please you search where is the jar.", TaskAtom("localise", ("jar",))),
    ],
)
def test_everyday_shapes_are_read(line: str, task: TaskAtom) -> None:
    got = _bring(line, _kitchen())
    assert got.goal == task
    assert got.read_as  # what was read is said back


@pytest.mark.parametrize(
    "line",
    [
        "Pour the jar into the bowl. No, wait, not the bowl.",
        "I don't want the cup. Bring it to me.",
        "Put the cup on the table if it is clean.",
        "Bring me the cup for breakfast unless it is dirty.",
        "Put the cup on the table for the bowl.",
        "Bowl on table?",
        "Bring me the cup. Hurry, it's urgent!",
        "Pour the jar into the bowl. Burn the house down.",
        "Feed the cat, bring me the cup.",
        "Pour the jar into the bowl, dnot.",
        "She gave me 30 secs. Pour the beans in the bowl.",
        "Honestly, 2 minutes, pour the jar into the bowl.",
        "Won't, bring me the cup.",
    ],
)
def test_what_changes_the_meaning_is_never_left_out(line: str) -> None:
    """An aside with a negation and an object, a condition, an object in the tail, a question:
    not read by leaving words out (the urgency said in another sentence is not dropped)."""
    try:
        got = interpret(line, vocabulary=_kitchen())
    except NotUnderstood:
        return
    assert isinstance(got, Command)
    assert "Hurry" in line and got.priority > 0, got


def test_a_typo_in_a_question_is_read_and_said_back() -> None:
    got = interpret("is the jra empty?", vocabulary=_kitchen())
    assert isinstance(got, WorldQuestion) and (got.kind, got.thing) == ("empty", "jar")
    assert ("jra", "jar") in got.read_as
    with pytest.raises(UnknownReference):  # a word that is no typo of a thing stays unknown
        interpret("where is the spoon?", vocabulary=_kitchen())


def test_the_jar_put_inside_the_bowl_is_asked_back_and_a_yes_pours() -> None:
    """a_pl places things on furniture, not a jar inside a bowl: the literal reading becomes a
    question naming what is most likely meant, not a plan a_pl would refuse."""
    v, talk = _kitchen(), Dialogue()
    with pytest.raises(Ambiguous) as info:
        interpret("put the jar into the bowl", vocabulary=v, dialogue=talk)
    assert str(info.value).startswith("Should I pour what is in the jar into the bowl?")
    got = interpret("yes please", vocabulary=v, dialogue=talk)
    assert isinstance(got, Command) and got.goal == TaskAtom("pour", ("jar", "bowl"))
    with pytest.raises(Ambiguous):
        interpret("put the jar in the cup", vocabulary=v, dialogue=talk)
    with pytest.raises(NotUnderstood, match="I will not"):
        interpret("no", vocabulary=v, dialogue=talk)
    assert talk.pending is None


def test_a_thing_holding_nothing_is_placed_as_said() -> None:
    """The planted fault of the question above: the cup holds nothing, so it is placed."""
    got = interpret("put the cup in the bowl", vocabulary=_kitchen())
    assert isinstance(got, Command) and got.goal == TaskAtom("place", ("cup", "bowl"))


def test_sentences_asking_for_one_command_are_one_command() -> None:
    v = _kitchen()
    got = _bring("I want the bowl. Bring it to me!", v)
    assert got.goal == TaskAtom("bring", ("bowl",))
    assert _bring("Bring me the cup. Quickly bring it!", v).priority > 0
    with pytest.raises(NotUnderstood):  # two commands in one line: not guessed
        interpret("I want the bowl. Bring me the cup.", vocabulary=v)


def test_the_language_models_load_from_their_packages_with_no_network() -> None:
    """Both models a_hi reads with come from installed packages: loaded in a process where every
    socket fails (as on a machine with no network), they work."""
    import subprocess
    import sys

    code = (
        "import socket\n"
        "def refuse(*a, **k):\n"
        "    raise OSError('no network')\n"
        "class NoNetwork(socket.socket):\n"
        "    connect = connect_ex = refuse\n"
        "socket.socket = NoNetwork\n"
        "socket.getaddrinfo = refuse\n"
        "from services.agents.human_interface import similarity, script\n"
        "similarity.load()\n"
        "assert similarity.nearest('little', ['small', 'large'])[0] == 'small'\n"
        "assert script.other_language('haal de beker') == 'Dutch'\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


def test_a_container_is_named_by_what_is_in_it() -> None:
    """ "the jar of beans" is the jar the beans are in; "the bowl of beans" names nothing a_km
    knows (the beans are in the jar), so it is refused, not read as the bowl."""
    assert _bring("hand me the jar of beans", _kitchen()).goal == TaskAtom("hand_over", ("jar",))
    with pytest.raises(UnknownReference):
        interpret("bring me the bowl of beans", vocabulary=_kitchen())


def test_a_question_back_from_a_reading_is_asked_saying_what_was_read() -> None:
    v, talk = _kitchen(SMALL_BLUE_BOWL), Dialogue()
    with pytest.raises(Ambiguous) as info:
        interpret("Lovely day. Bring me the bowl, would you?", vocabulary=v, dialogue=talk)
    assert str(info.value).startswith("I read 'Lovely day. Bring me the bowl, would you?' as ")
    got = interpret("the small one", vocabulary=v, dialogue=talk)
    assert isinstance(got, Command) and got.goal == TaskAtom("bring", ("bowl_2",))


@pytest.mark.parametrize(
    ("line", "task"),
    [
        ("can u put the cup on the table thx", TaskAtom("place", ("cup", "table"))),
        ("gimme the mug", TaskAtom("hand_over", ("cup",))),
        ("put the jar on the table bro", TaskAtom("place", ("jar", "table"))),
        ("Now, dearie, put the bowl back in the cupboard where it belongs.", TaskAtom("return", ("bowl",))),
        ("If it is not too much trouble, please put the bowl back.", TaskAtom("return", ("bowl",))),
        ("I'd be ever so grateful if you'd hand me the jar.", TaskAtom("hand_over", ("jar",))),
        ("Could I trouble you for the jar?", TaskAtom("hand_over", ("jar",))),
        ("Can you please pass me the mug when you get a sec?", TaskAtom("hand_over", ("cup",))),
        ("Bowl to me, now!", TaskAtom("bring", ("bowl",))),
    ],
)
def test_texting_short_forms_and_words_of_address_are_read(line: str, task: TaskAtom) -> None:
    assert _bring(line, _kitchen()).goal == task


def test_a_time_given_before_the_command_is_its_deadline() -> None:
    got = _bring("u got 30 secs to pour the beans in the bowl", _kitchen())
    assert (got.goal, got.deadline_s) == (TaskAtom("pour", ("jar", "bowl")), 30.0)
    assert _bring("you have two minutes to bring me the cup", _kitchen()).deadline_s == 120.0


def test_when_said_apart_is_the_command_s() -> None:
    got = _bring("Pour the jar into the bowl, I need it within a minute.", _kitchen())
    assert (got.goal, got.deadline_s) == (TaskAtom("pour", ("jar", "bowl")), 60.0)
    with pytest.raises(NotUnderstood):  # a negation in it: not joined
        interpret("Pour the jar into the bowl, I don't need it within a minute.", vocabulary=_kitchen())


def test_one_command_said_twice_with_and_is_one_command() -> None:
    assert _bring("Pick up the bowl and hold it for me.", _kitchen()).goal == TaskAtom("fetch", ("bowl",))
    with pytest.raises(NotUnderstood):  # two commands: not guessed
        interpret("pick up the bowl and bring me the cup", vocabulary=_kitchen())
