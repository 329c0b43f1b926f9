"""The stop matcher (stop.py): what is a stop and what is not, what a stop names, and that its
work is linear in the length of a line and bounded for a longer one."""

from __future__ import annotations

import pytest

from services.agents.human_interface.stop import WINDOW_CHARS, StopMatch, StopWords, default_stop_words
from services.runtime.human import MAX_LINE_CHARS
from tests.agents.human_interface import corpus

STOPS = (
    # the words, bare
    "stop",
    "cancel",
    "halt",
    "abort",
    "freeze",
    "wait",
    "hold on",
    "hang on",
    "never mind",
    "nevermind",
    "that's enough",
    "enough",
    "forget it",
    "don't do that",
    "pause",
    "quit it",
    "hold up",
    "scratch that",
    # punctuation, capitals, letters drawn out
    "STOP!",
    "Stop.",
    "stop!!!",
    "STOP STOP STOP",
    "stooooop",
    "Wait!",
    "Halt!",
    "Cancel.",
    "ENOUGH!",
    "Never mind.",
    "...stop",
    # please, address, urgency
    "stop please",
    "please stop",
    "please, stop now!",
    "Robot, stop!",
    "velma stop",
    "stop right now",
    "stop immediately",
    "cancel, please",
    "could you stop please?",
    "can you stop?",
    "would you please stop",
    "just stop",
    "I said stop",
    "I told you to stop",
    "emergency stop",
    "e-stop",
    # interjections
    "oh no, stop!",
    "hey, STOP",
    "no no no, stop pouring",
    "whoa, wait",
    "oops, cancel that",
    "ah, hold on",
    "uh oh, halt",
    "oh no no no stop",
    "hey robot, stop pouring",
    "ok, that is enough, thank you",
    "alright, enough",
    "sorry, never mind",
    # contractions, curly and straight
    "don't!",
    "no, don't!",
    "don’t do that",
    "that’s enough",
    "that's enough now",
    "don't pour it",
    "don't touch that",
    "don't move",
    "do not do that",
    "don't you dare",
    "can't you stop?",
    "why don't you stop",
    "you can stop now",
    "you're spilling it, stop",
    # a stop that names what to stop
    "stop pouring",
    "stop the pour",
    "cancel that",
    "stop what you're doing",
    "stop whatever you are doing",
    "cancel the command",
    "stop it",
    "stop everything",
    "abort all tasks",
    "halt the robot",
    "stop moving",
    "cancel my last command",
    "stop pouring the jar into the bowl",
    "forget about it",
    "pause the pour",
    # wait and friends
    "wait a second",
    "wait a minute",
    "hold on a sec please",
    "hang on a moment",
    "one moment please",
    "wait wait wait",
    "just a second",
    "stand still",
    "stay put",
    "not so fast",
    "that will do",
    # inside a longer sentence about what the robot does
    "stop, you're spilling it",
    "wait, that's the wrong cup",
    "stop - you're spilling it",
    "wait... that's the wrong bowl",
    "the bowl is full, stop",
    "that's the wrong jar, cancel!",
    "careful! stop!",
    "oh no you're spilling it stop",
    "make it stop",
    "stop, the bowl is already full",
    "hold on, that's not the bowl I meant",
    "no wait, that's wrong",
    "cancel everything and bring me the cup",
    "never mind, forget it",
    "don't stop... actually, stop",
)

NOT_STOPS = (
    # commands, status, a reply
    "pour the jar into the bowl",
    "bring me the cup",
    "hold the jar",
    "hold it",
    "pick up the cup",
    "find the jar",
    "where is the stopper?",
    "what are you doing?",
    "status",
    "the one on the table",
    # a command whose verb is no stop word
    "pour and then wait",
    "pour the jar into the bowl, then wait",
    "pour it into the bowl and stop when it is full",
    "hand me the cup, I'll wait",
    "put the jar down and wait there",
    "pour enough beans into the bowl",
    "look for the stop sign",
    # waiting with a time, a reason or a purpose
    "wait 5 seconds before pouring",
    "wait for me",
    "wait until the bowl is on the table",
    "hold on to the jar",
    # go on
    "don't stop",
    "do not stop",
    "please don't stop now",
    "keep going",
    "carry on",
    "go on",
    "continue",
    "no need to stop",
    "you don't have to stop",
    "I didn't say stop",
    "don't cancel it",
    "never stop",
    "you can't stop now",
    "don't wait",
    "stop? no, keep going",
    "never mind, carry on",
    "wait, don't stop",
    # questions about stopping
    "what happens if I say stop?",
    "how do I stop you?",
    "why did you stop?",
    "did you stop?",
    "is it stopped?",
    "is that enough?",
    "anyway, enough about me. how's it going?",
    "it will stop",
    # no stop word
    "oh no",
    "hey",
    "you're spilling it",
    "that's the wrong cup",
    "don't forget the cup",
    "don't worry",
    "thanks",
    "please",
    "",
    "!!!",
    "stopwatch",
)


@pytest.fixture(scope="module")
def words() -> StopWords:
    return default_stop_words()


def test_the_tables_are_large_enough() -> None:
    assert len(STOPS) >= 80 and len(NOT_STOPS) >= 30
    assert len(set(STOPS)) == len(STOPS) and len(set(NOT_STOPS)) == len(NOT_STOPS)


@pytest.mark.parametrize("line", STOPS)
def test_a_stop(words: StopWords, line: str) -> None:
    assert words.match(line) is not None


@pytest.mark.parametrize("line", NOT_STOPS)
def test_not_a_stop(words: StopWords, line: str) -> None:
    assert words.match(line) is None


@pytest.mark.parametrize(
    ("line", "said", "names"),
    [
        ("stop", "stop", ""),
        ("Stop everything!", "stop", ""),
        ("stop what you're doing", "stop", ""),
        ("cancel that", "cancel", ""),
        ("stop, you're spilling it", "stop", ""),
        ("stop pouring", "stop", "pouring"),
        ("stop the pour now, please", "stop", "the pour"),
        ("cancel the command", "cancel", "the command"),
        ("oh no, hold on a sec", "hold on", ""),
        ("don't do that", "dont", ""),
        ("don't touch the jar", "dont", "touch the jar"),
        ("you're spilling it, stop!", "stop", ""),
        (
            "stop " + "pouring the jar " * 10,
            "stop",
            "pouring the jar pouring the jar pouring the …",
        ),
    ],
)
def test_what_a_stop_says_and_names(words: StopWords, line: str, said: str, names: str) -> None:
    assert words.match(line) == StopMatch(said, names)


def _corpus() -> list[tuple[str, object]]:
    """Every (sentence, expected) pair of corpus.py, whatever table holds it."""
    return [
        pair
        for table in vars(corpus).values()
        if isinstance(table, tuple)
        for pair in table
        if isinstance(pair, tuple) and len(pair) == 2 and isinstance(pair[0], str)
    ]


def test_the_corpus_stops_are_stops_and_its_commands_are_not(words: StopWords) -> None:
    """Every sentence the grammar reads as a stop is caught first; no command is taken for one."""
    pairs = _corpus()
    assert len(pairs) > 200
    for sentence, expected in pairs:
        if expected == corpus.STOP:
            assert words.match(sentence) is not None, sentence
        elif not isinstance(expected, corpus.Refuse):  # a command, a question back, a status request
            assert words.match(sentence) is None, sentence


def test_the_command_verbs_come_from_the_grammar() -> None:
    """Without the grammar's verbs a stop word later in a command's line makes it a stop."""
    line = "pour the jar into the bowl, then stop"
    assert StopWords().match(line) is not None
    assert default_stop_words().match(line) is None


def _work(words: StopWords, line: str) -> tuple[StopMatch | None, int]:
    before = words.examined
    match = words.match(line)
    return match, words.examined - before


@pytest.mark.parametrize(
    ("unit", "end", "stop"),
    [
        ("my bowl overflows ", "stop", True),  # the whole clause is scanned for its end
        ("please ", "stop", True),  # fillers before the stop word
        ("stop ", "", True),
        ("don't ", "stop", False),
        ("wait, ", "keep going", False),  # a clause each
        ("pour the jar into the bowl ", "", False),
        ("xq" * 40 + " ", "", False),
    ],
)
def test_the_work_is_linear_in_the_length_and_bounded(
    words: StopWords, unit: str, end: str, stop: bool
) -> None:
    """The matcher's work (phrase look-ups) grows at most linearly with the line's length up to
    the bound, and no further beyond it; a stop at the end of a very long line is still found."""
    per_char = []
    for length in (10, 30, 100, 300, MAX_LINE_CHARS):
        line = (unit * (length // len(unit) + 1))[: max(length - len(end), 0)] + end
        _, work = _work(words, line)
        per_char.append(work / len(line))
    assert max(per_char) <= 1.0  # at most one look-up per character, whatever the length
    works = []
    for times in (10, 1000):  # 10,000 and 1,000,000 characters
        long = unit * (times * MAX_LINE_CHARS // len(unit)) + end
        match, work = _work(words, long)
        assert (match is not None) == stop
        works.append(work)
    assert works[0] == works[1] <= 2 * MAX_LINE_CHARS  # only its start and its end are read


def test_a_long_line_is_read_at_its_start_and_its_end(words: StopWords) -> None:
    filler = "the jar is on the table and the bowl is next to it " * 100
    assert len(filler) > 2 * WINDOW_CHARS
    assert words.match("stop! " + filler) is not None
    assert words.match(filler + " oh no, stop") is not None
    assert words.match(filler) is None
    assert words.match(filler + " stop " + filler) is None  # its middle is not read
    # a word cut by the window is not read as another word
    assert words.match("x" * (WINDOW_CHARS - 2) + "stop" + "x" * WINDOW_CHARS) is None
    assert words.match(filler + "nonstop") is None
