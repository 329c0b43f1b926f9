"""The words of a task are data (tasks.toml, task_words.py, task_grammar.py): a task a_pl does
not know is understood from its entry alone, by interpret and by a_hi; tasks.toml names a_pl's
tasks; a malformed or colliding entry is refused with one line naming it."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.agents.human_interface.agent import HumanInterface
from services.agents.human_interface.language import (
    Ambiguous,
    Command,
    Incomplete,
    NotUnderstood,
    describe,
    interpret,
)
from services.agents.human_interface.task_grammar import Grammar, default_grammar, load_grammar
from services.agents.human_interface.task_words import (
    MAX_BYTES,
    TASKS_FILE,
    TaskWordsError,
    read_task_words,
)
from services.agents.planner.domain import TASKS
from services.runtime.human import ReportKind
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import HumanCommand, TaskAtom
from tests.agents.human_interface.test_agent import TIMEOUT, Stage
from tests.agents.human_interface.test_corpus import two_cups

WIPE = """
[[tasks]]
task = "wipe"
frames = ["wipe GOAL with THEME", "clean GOAL with THEME"]
ask = { GOAL = "What should I wipe with {THEME}?" }
"""
"""An entry for a task a_pl does not know: wipe(THEME, GOAL)."""

NEW = len(read_task_words().sayings)
"""The index of an entry added after tasks.toml's."""


def with_entry(tmp_path: Path, entry: str) -> Path:
    """A copy of tasks.toml with ``entry`` added at its end."""
    path = tmp_path / "tasks.toml"
    path.write_text(TASKS_FILE.read_text() + entry)
    return path


@pytest.fixture
def wipe(tmp_path: Path) -> Grammar:
    return load_grammar(with_entry(tmp_path, WIPE))


def test_a_task_a_pl_does_not_know_is_understood_from_its_entry_alone(wipe: Grammar) -> None:
    with pytest.raises(NotUnderstood, match="I do not know 'wipe' as a command"):
        interpret("wipe the table with the cup")  # tasks.toml as it is
    goal = Command(TaskAtom("wipe", ("cup", "table")))
    assert interpret("wipe the table with the cup", grammar=wipe) == goal
    assert interpret("could you clean the kitchen table with the mug, please?", grammar=wipe) == goal
    urgent = interpret("wipe the table with the cup right away, within 2 minutes", grammar=wipe)
    assert urgent == Command(goal.goal, priority=5, deadline_s=120.0)
    assert describe(goal.goal, wipe.words) == "wipe the table with the cup"
    # the other tasks are read as before
    assert interpret("pour the jar into the bowl", grammar=wipe) == Command(TaskAtom("pour", ("jar", "bowl")))
    assert interpret("find the jar", grammar=wipe) == Command(TaskAtom("localise", ("jar",)))
    with pytest.raises(NotUnderstood, match=r"I can: .*, find, wipe, stop"):
        interpret("sing", grammar=wipe)


def test_the_slots_of_a_new_task_are_resolved_and_asked_for_as_any_reference(wipe: Grammar) -> None:
    with pytest.raises(Ambiguous, match="Which cup: the one in the cabinet or the one on the table"):
        interpret("wipe the table with the cup", vocabulary=two_cups(), grammar=wipe)
    with pytest.raises(Incomplete) as info:
        interpret("wipe the table", grammar=wipe)
    assert info.value.missing == "object"
    assert str(info.value) == "Wipe the table with what? Say e.g. 'wipe the table with the bowl'."
    with pytest.raises(Incomplete) as info:
        interpret("wipe with the cup", grammar=wipe)
    assert info.value.missing == "destination"
    assert str(info.value) == "What should I wipe with the cup? Say e.g. 'wipe the bowl with the cup'."
    with pytest.raises(Incomplete, match=r"^Wipe the table with what"):
        interpret("wipe the table with it", grammar=wipe)  # nothing named before


def test_args_orders_the_arguments(tmp_path: Path) -> None:
    ordered = WIPE.replace("frames =", 'args = ["GOAL", "THEME"]\nframes =')
    grammar = load_grammar(with_entry(tmp_path, ordered))
    goal = TaskAtom("wipe", ("table", "cup"))
    assert interpret("wipe the table with the cup", grammar=grammar) == Command(goal)


def test_a_closed_class_word_of_a_frame_reads_as_its_class(tmp_path: Path) -> None:
    """ "into" is grammar.lark's class IN: a frame saying "into" also reads "in" and "inside"."""
    grammar = load_grammar(with_entry(tmp_path, '[[tasks]]\ntask = "peer"\nframes = ["peer into THEME"]\n'))
    for sentence in ("peer into the jar", "peer in the jar", "peer inside the jar"):
        assert interpret(sentence, grammar=grammar) == Command(TaskAtom("peer", ("jar",)))


def test_a_hi_given_a_task_words_file_sends_the_new_task_to_a_co(tmp_path: Path) -> None:
    stage = Stage()
    try:
        co = stage.co()
        hi = HumanInterface(stage.bus.transport(), tasks=with_entry(tmp_path, WIPE))
        stage.hi = hi
        stage.start(hi)
        assert co.subscribed.wait(TIMEOUT)
        stage.person.say("please wipe the table with the cup", "r1")
        request = co.receive(Performative.REQUEST)
        assert isinstance(request.content, HumanCommand)
        assert request.content.goal == TaskAtom("wipe", ("cup", "table"))
        co.do(lambda co: co.engine.reply(request, Performative.AGREE))
        accepted = stage.person.next("r1")
        assert (accepted.kind, accepted.text) == (ReportKind.ACCEPTED, "I will wipe the table with the cup.")
    finally:
        stage.stop()


def test_a_hi_refuses_to_start_with_a_malformed_task_words_file(tmp_path: Path) -> None:
    bad = with_entry(tmp_path, '[[tasks]]\ntask = "seek"\nframes = ["seek PLACE"]\n')
    with pytest.raises(TaskWordsError, match=r"tasks\[\d+\] \('seek'\): frame 'seek PLACE' names an unknown"):
        HumanInterface(MemoryBus().transport(), tasks=bad)


def test_tasks_toml_names_tasks_a_pl_accepts_with_their_arguments() -> None:
    sayings = default_grammar().words.sayings
    assert {s.task for s in sayings} >= {"fetch", "localise"}
    for s in sayings:
        assert s.task in TASKS, s.task
        assert len(s.args) == TASKS[s.task][0], s.task


def entry(task: str, frames: str, more: str = "") -> str:
    return f'[[tasks]]\ntask = "{task}"\nframes = {frames}\n{more}'


MALFORMED = [
    (entry("seek", '["seek PLACE"]'), "frame 'seek PLACE' names an unknown slot 'PLACE'"),
    (entry("seek", '["seek THEME", ""]'), "frame 1 ('') is empty"),
    (entry("seek", "[]"), "no frames"),
    (entry("look-up", '["seek THEME"]'), "task 'look-up' is not an identifier"),
    (entry("Seek", '["seek THEME"]'), "task 'Seek' is not an identifier"),
    (
        entry("carry", '["bring THEME"]'),
        "frame 'bring THEME' collides with a built-in frame: 'bring it' already reads as "
        "grammar.lark's rule 'bring'",
    ),
    (entry("set", '["put THEME on GOAL"]'), "'put it on it' already reads as grammar.lark's rule 'put'"),
    (entry("halt", '["stop THEME"]'), "already reads as grammar.lark's rule 'stop'"),
    (
        entry("seek", '["seek THEME", "find THEME"]'),
        "frame 'find THEME' reads the same as frame 'find THEME' of tasks[2] ('localise')",
    ),
    (
        entry("peer", '["peer into THEME", "peer in THEME"]'),
        "frame 'peer in THEME' reads the same as frame 'peer into THEME'",
    ),
    (entry("seek", '["seek THEME", "seek THEME"]'), "frame 'seek THEME' is given twice"),
    (entry("seek", '["seek THEME", "look around"]'), "frame 'look around' names no slot; every frame"),
    (entry("seek", '["THEME away"]'), "begins with a slot"),
    (entry("swap", '["swap THEME THEME"]'), "names a slot twice"),
    (entry("swap", '["swap THEME GOAL"]'), "has two slots side by side"),
    (entry("seek", '["Seek THEME"]'), "'Seek' is neither a slot"),
    (entry("seek", '["where THEME belongs"]'), "frame 'where THEME belongs' cannot be read as written"),
    (entry("seek", '["seek THEME"]', 'ask = { GOAL = "Where?" }\n'), "ask names 'GOAL'"),
    (entry("seek", '["seek THEME"]', 'ask = { THEME = "Seek {THEME}?" }\n'), "ask.THEME names {THEME}"),
    (entry("seek", '["seek THEME"]', 'args = ["THEME", "PLACE"]\n'), "args names an unknown slot 'PLACE'"),
    (entry("seek", '["seek THEME"]', 'example = ""\n'), "example must be one non-empty line"),
    (entry("localise", '["seek THEME in GOAL"]'), "2 argument(s), but tasks[2] gives the same task 1"),
    ('[[tasks]]\ntask = "seek"\nframe = ["seek THEME"]\n', "unknown field `frame` - at `$.tasks[3]`"),
    ("[[tasks]]\ntask = 3\nframes = []\n", "Expected `str`, got `int` - at `$.tasks[3].task`"),
]


@pytest.mark.parametrize(("text", "says"), MALFORMED, ids=[s for _, s in MALFORMED])
def test_a_malformed_entry_is_refused_with_one_line_naming_it(tmp_path: Path, text: str, says: str) -> None:
    path = with_entry(tmp_path, text)
    with pytest.raises(TaskWordsError) as info:
        load_grammar(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}: ")
    assert f"tasks[{NEW}]" in message, message
    assert says in message, message


def test_a_missing_unreadable_or_oversized_file_is_refused_with_one_line(tmp_path: Path) -> None:
    files = tmp_path
    cases = {
        files / "none.toml": "no such task words file",
        files: "is a directory",
    }
    syntax = files / "syntax.toml"
    syntax.write_text("[[tasks]\n")
    cases[syntax] = "line 1"
    large = files / "large.toml"
    large.write_text("#" * (MAX_BYTES + 1))
    cases[large] = f"a task words file has at most {MAX_BYTES}"
    for path, says in cases.items():
        with pytest.raises(TaskWordsError) as info:
            load_grammar(path)
        assert "\n" not in str(info.value) and str(info.value).startswith(f"{path}: ")
        assert says in str(info.value)
