"""a_hi's language: every form of the earlier pattern-based version still understood (now by the
grammar), urgency, deadlines, words from the ontology, one-line answers when not understood."""

from __future__ import annotations

import pytest

from services.agents.human_interface import task_grammar
from services.agents.human_interface.grammar import normalise
from services.agents.human_interface.intents import SURFACE
from services.agents.human_interface.language import (
    ALLOWED_CONTROLS,
    MAX_READ_TOKENS,
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
from services.agents.human_interface.task_grammar import default_grammar
from services.agents.planner.domain import SAFE_SURFACE
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
@pytest.mark.requirement("R1.1")
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
@pytest.mark.requirement("R1.2")
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


@pytest.mark.requirement("R1.3")
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


@pytest.mark.parametrize(
    ("sentence", "words"),
    [
        ("Pour the jar's contents!", ["pour", "the", "jar", "s", "contents"]),
        ("the jar’s beans", ["the", "jar", "s", "beans"]),
        ("What's going on? Let's see; where's it?", ["whats", "going", "on", "lets", "see", "wheres", "it"]),
        ("I don't know", ["i", "dont", "know"]),
        ("within -5 seconds", ["within", "-5", "seconds"]),
        ("within −2.5 min", ["within", "-2.5", "min"]),
        ("twenty-five 5-10 well-known", ["twenty", "five", "5", "10", "well", "known"]),
        ("within 1.5 min.", ["within", "1.5", "min"]),
    ],
)
def test_normalise_splits_possessives_joins_contractions_and_keeps_a_minus_sign(
    sentence: str, words: list[str]
) -> None:
    assert normalise(sentence) == words


_ONES = ["", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine"]
_TEENS = ["ten", "eleven", "twelve", "thirteen", "fourteen", "fifteen", "sixteen", "seventeen", "eighteen"]
_TENS = {2: "twenty", 3: "thirty", 4: "forty", 5: "fifty", 6: "sixty"}


def _in_words(n: int) -> str:
    """1..60 in English words, written here independently of grammar.py's table."""
    if n < 10:
        return _ONES[n]
    if n < 19:
        return _TEENS[n - 10]
    if n == 19:
        return "nineteen"
    tens, ones = divmod(n, 10)
    return _TENS[tens] + (f"-{_ONES[ones]}" if ones else "")


@pytest.mark.parametrize("n", range(1, 61))
def test_every_number_word_from_one_to_sixty_sets_a_deadline(n: int) -> None:
    for said in (f"within {_in_words(n)} seconds", f"in {_in_words(n).replace('-', ' ')} minutes"):
        intent = interpret(f"pour the jar into the bowl {said}")
        assert isinstance(intent, Command), said
        assert intent.deadline_s == n * (1 if "seconds" in said else 60), said


@pytest.mark.parametrize(
    ("said", "seconds"),
    [
        ("in a minute", 60.0),
        ("in half a minute", 30.0),
        ("within half an hour", 1800.0),
        ("in a quarter of an hour", 900.0),
        ("within a couple of minutes", 120.0),
        ("in under an hour", 3600.0),
        ("in less than 45 seconds", 45.0),
        ("within the next two hours", 7200.0),
        ("in 3 hrs", 10800.0),
    ],
)
def test_deadline_phrases(said: str, seconds: float) -> None:
    assert interpret(f"bring me the cup {said}") == Command(TaskAtom("bring", ("cup",)), deadline_s=seconds)


@pytest.mark.parametrize(
    ("sentence", "says"),
    [
        ("pour the jar into the bowl within -5 seconds", "The deadline 'within -5 seconds' is negative"),
        ("pour the jar into the bowl in -1 minute", "The deadline 'in -1 minute' is negative"),
        ("pour the jar into the bowl within 0 seconds", "The deadline 'within 0 seconds' leaves no time"),
        ("within zero minutes pour the jar into the bowl", "leaves no time"),
    ],
)
def test_a_negative_or_zero_deadline_is_refused_not_read_as_its_absolute_value(
    sentence: str, says: str
) -> None:
    with pytest.raises(NotUnderstood) as info:
        interpret(sentence)
    text = str(info.value)
    assert not isinstance(info.value, Incomplete)
    assert text.startswith("The deadline '") and says in text
    assert "'within 30 seconds'" in text and "\n" not in text


@pytest.mark.parametrize("code", [*range(0x00, 0x09), 0x0B, 0x0C, *range(0x0E, 0x20), *range(0x7F, 0xA0)])
def test_a_control_character_is_refused_and_named(code: int) -> None:
    with pytest.raises(NotUnderstood) as info:
        interpret(f"pour the jar{chr(code)} into the bowl")
    text = str(info.value)
    assert f"control character (U+{code:04X}, character 13)" in text
    assert "\n" not in text and text.isprintable()


@pytest.mark.parametrize("space", sorted(ALLOWED_CONTROLS))
def test_tabs_and_line_ends_are_ordinary_whitespace(space: str) -> None:
    assert interpret(f"pour the jar{space}into the bowl{space}") == Command(TaskAtom("pour", ("jar", "bowl")))


@pytest.mark.parametrize(
    ("sentence", "question"),
    [
        ("put the cup over there", "Where should I put the cup? I cannot tell where 'over there' is"),
        ("put the jar somewhere", "Where should I put the jar? I cannot tell where 'somewhere' is"),
        ("bring the bowl there", "Where should I bring the bowl? I cannot tell where 'there' is"),
        ("put the cup back anywhere", "Where should I put the cup?"),
        ("pour the jar over there", "Into what should I pour the jar?"),
    ],
)
def test_a_vague_place_is_asked_back_not_guessed(sentence: str, question: str) -> None:
    with pytest.raises(Incomplete) as info:
        interpret(sentence)
    assert info.value.missing == "destination"
    assert str(info.value).startswith(question) and "say e.g." in str(info.value).lower()


def test_here_is_where_the_person_is_and_a_thing_over_there_is_still_brought() -> None:
    assert interpret("bring the cup here") == Command(TaskAtom("bring", ("cup",)))
    assert interpret("bring me the cup over there") == Command(TaskAtom("bring", ("cup",)))


def test_put_down_sets_a_thing_on_the_surface_the_robot_puts_things_down_on() -> None:
    assert SURFACE == SAFE_SURFACE
    for sentence in ("put down the bowl", "put the bowl down", "set the bowl down", "lay down the bowl"):
        assert interpret(sentence) == Command(TaskAtom("place", ("bowl", SURFACE))), sentence
    assert interpret("put the bowl down in the cabinet") == Command(TaskAtom("return", ("bowl",)))


@pytest.mark.parametrize(
    ("sentence", "name", "args"),
    [
        ("would you mind pouring the jar into the bowl", "pour", ("jar", "bowl")),
        ("do you mind putting the cup away", "return", ("cup",)),
        ("would you mind emptying the jar into the bowl", "pour", ("jar", "bowl")),
        ("would you mind quickly getting me the jar", "bring", ("jar",)),
        ("would you mind picking up the cup", "fetch", ("cup",)),
        ("would you mind looking for the bowl", "localise", ("bowl",)),
    ],
)
def test_a_gerund_after_would_you_mind_is_read_as_its_verb(
    sentence: str, name: str, args: tuple[str, ...]
) -> None:
    intent = interpret(sentence)
    assert isinstance(intent, Command) and intent.goal == TaskAtom(name, args)


def test_a_gerund_without_would_you_mind_is_no_command() -> None:
    with pytest.raises(NotUnderstood, match="'pouring'"):
        interpret("pouring the jar into the bowl")


@pytest.mark.parametrize(
    ("sentence", "goal"),
    [
        ("I'd like the cup", TaskAtom("bring", ("cup",))),
        ("I want the jar on the table", TaskAtom("bring", ("jar",))),
        ("I would like the jar back", TaskAtom("bring", ("jar",))),
        ("I'd like the jar back in the cupboard", TaskAtom("return", ("jar",))),
        ("can I have the bowl?", TaskAtom("hand_over", ("bowl",))),
        ("may I have the mug please", TaskAtom("hand_over", ("cup",))),
    ],
)
@pytest.mark.requirement("R1.1")
def test_wishes_are_commands(sentence: str, goal: TaskAtom) -> None:
    assert interpret(sentence) == Command(goal)


def test_a_wish_without_an_object_is_asked_back() -> None:
    with pytest.raises(Incomplete, match="What would you like\\?") as info:
        interpret("I would like")
    assert info.value.missing == "object"


def test_a_run_of_courtesy_words_is_one_token() -> None:
    """ "please please …": the repeats fold into one token (grammar.py FOLDED), so a long line of
    them reads as the short command it is."""
    grammar = default_grammar()
    line = "please please kindly pour the jar into the bowl thanks thank you"
    words = grammar.tag(line, default_vocabulary())
    assert [w.kind for w in words][:2] == ["PLEASE", "POUR"]
    assert words[0].text == "please please kindly" and words[-1].kind == "THANKS"
    assert [w.index for w in words] == list(range(len(words)))
    intent = interpret("please " * 140 + "pour the jar into the bowl")
    assert isinstance(intent, Command) and intent.goal.args == ("jar", "bowl")


def test_a_sentence_of_too_many_tokens_is_refused_unparsed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Past MAX_READ_TOKENS tokens the parser is not run (its work grows with the tokens); at the
    bound the sentence reads as before."""
    at_bound = "please robot " * ((MAX_READ_TOKENS - 6) // 2) + "pour the jar into the bowl"
    assert len(default_grammar().tag(at_bound, default_vocabulary())) == MAX_READ_TOKENS
    assert isinstance(interpret(at_bound), Command)
    parsed: list[int] = []
    real = task_grammar.Grammar.parse

    def counting(self: task_grammar.Grammar, words: object) -> object:
        parsed.append(1)
        return real(self, words)  # type: ignore[arg-type]

    monkeypatch.setattr(task_grammar.Grammar, "parse", counting)
    with pytest.raises(NotUnderstood, match=f"too long for one request \\({MAX_READ_TOKENS + 2} words"):
        interpret("please robot " + at_bound)
    assert parsed == []
