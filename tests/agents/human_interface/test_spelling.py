"""Typos (spelling.py, language.py): the distance, the candidates among a_hi's words, a
correction taken only when one meaning is clearly meant, a word near two meanings named, a
typo'd stop never read as anything else, and the work bounded."""

from __future__ import annotations

import string

import pytest

from services.agents.human_interface import language, spelling
from services.agents.human_interface.language import (
    MAX_CORRECTED_TOKENS,
    MAX_TYPO_WORDS,
    Ambiguous,
    Command,
    Dialogue,
    Incomplete,
    Misspelt,
    NotUnderstood,
    StatusRequest,
    Stop,
    default_grammar,
    default_vocabulary,
    interpret,
)
from services.agents.human_interface.spelling import (
    MAX_LETTERS,
    candidates,
    distance,
    known_words,
    max_distance,
)
from shared.fipa_codec.languages.l_hc import TaskAtom
from tests.agents.human_interface.test_corpus import two_cups


@pytest.mark.parametrize(
    ("a", "b", "d"),
    [
        ("stop", "stop", 0),
        ("stpo", "stop", 1),  # a transposition
        ("jarr", "jar", 1),  # an insertion
        ("tble", "table", 1),  # a deletion
        ("doimg", "doing", 1),  # m beside n
        ("smash", "stash", 2),  # m far from t: a deletion and an insertion
        ("poor", "pour", 2),
        ("cupbaord", "cupboard", 1),
        ("ca", "abc", 3),  # the optimal-string-alignment variant: no substring edited twice
    ],
)
def test_the_distance(a: str, b: str, d: int) -> None:
    assert distance(a, b, 5) == d == distance(b, a, 5)


def test_the_distance_stops_past_its_limit() -> None:
    assert distance("pour", "tidy", 1) == 2
    assert distance("a" * 20, "b", 2) == 3


def test_how_far_a_word_may_be_from_its_candidate() -> None:
    assert [max_distance("x" * n) for n in (3, 4, 7, 8, MAX_LETTERS, MAX_LETTERS + 1)] == [0, 1, 1, 2, 2, 0]


def test_candidates_are_the_nearest_known_words() -> None:
    known = known_words(default_grammar().phrases, default_vocabulary())
    assert {"doing", "stop", "table", "mug", "minutes", "localise"} <= known
    assert candidates("doimg", known) == ("doing",)
    assert candidates("pout", known) == ("out", "pour", "put")
    assert candidates("stop", known) == ()  # a known word is no typo
    # three letters: two adjacent ones swapped, else one typed with the key beside it; never a
    # letter added or left out ("jra" is one such edit from many short words)
    assert candidates("jra", known) == ("jar",) and candidates("teh", known) == ("the",)
    assert candidates("jat", known) == ("jar",) and candidates("cpu", known) == ("cup",)
    assert candidates("cuo", known) == ("cup",) and candidates("jaw", known) == ()
    assert candidates("smash", known) == ()


@pytest.mark.parametrize(
    ("sentence", "intent", "read_as"),
    [
        ("what are you doimg", StatusRequest(), (("doimg", "doing"),)),
        ("plase bring me the cup", Command(TaskAtom("bring", ("cup",))), (("plase", "please"),)),
        (
            "poir the jarr itno the bowl",
            Command(TaskAtom("pour", ("jar", "bowl"))),
            (("poir", "pour"), ("jarr", "jar"), ("itno", "into")),
        ),
        ("bring me the cup within two minuts", Command(TaskAtom("bring", ("cup",)), deadline_s=120.0),
         (("minuts", "minutes"),)),
        ("tidy teh cpu away", Command(TaskAtom("return", ("cup",))), (("teh", "the"), ("cpu", "cup"))),
    ],
)  # fmt: skip
def test_a_typo_is_corrected_when_one_reading_is_meant(
    sentence: str, intent: Command | StatusRequest, read_as: tuple[tuple[str, str], ...]
) -> None:
    got = interpret(sentence)
    assert got == intent and got.read_as == read_as


def test_a_question_back_after_a_correction_says_what_was_read() -> None:
    with pytest.raises(NotUnderstood) as info:
        interpret("pour the jarr")
    assert str(info.value).startswith("I read 'jarr' as 'jar'. Into what should I pour the jar?")


def test_a_word_near_two_meanings_is_named_not_guessed() -> None:
    with pytest.raises(Misspelt) as info:
        interpret("pout the jar into the bowl")
    assert info.value.word == "pout" and info.value.candidates == ("pour", "put")
    assert str(info.value).startswith("I do not know 'pout': did you mean 'pour' or 'put'?")


@pytest.mark.parametrize(
    "sentence",
    ["stpo", "Stpo!", "sotp", "oh no, stpo", "stpo the pouring", "cancle", "abrot", "hakt the jar"],
)
def test_a_typod_stop_is_a_stop(sentence: str) -> None:
    assert isinstance(interpret(sentence), Stop)


@pytest.mark.parametrize("sentence", ["dont stpo", "don't stpo, keep going"])
def test_a_negated_typod_stop_is_no_stop_nor_anything_else(sentence: str) -> None:
    with pytest.raises(NotUnderstood):
        interpret(sentence)


def _one_edit(word: str) -> set[str]:
    """Every word one edit from ``word`` (spelling.py's distance 1) of at least 4 letters."""
    letters = string.ascii_lowercase
    out = {word[:i] + c + word[i:] for i in range(len(word) + 1) for c in letters}
    out |= {word[:i] + word[i + 1 :] for i in range(len(word))}
    out |= {word[:i] + word[i + 1] + word[i] + word[i + 2 :] for i in range(len(word) - 1)}
    out |= {word[:i] + c + word[i + 1 :] for i in range(len(word)) for c in letters}
    return {e for e in out if e != word and len(e) >= 4 and distance(e, word, 1) <= 1}


@pytest.mark.parametrize("stop", ["stop", "halt", "pause", "cancel"])
def test_a_typod_stop_is_a_stop_or_named_never_anything_else(stop: str) -> None:
    """Every one-edit typo of a stop word, alone or before "the cup", is a stop or refused
    ("pase the cup": "pause" or "pass", named), never a command or a question."""
    for typo in sorted(_one_edit(stop)):
        for sentence in (typo, f"{typo} the cup"):
            try:
                got = interpret(sentence)
            except (Ambiguous, Incomplete) as exc:
                pytest.fail(f"{sentence!r} was asked back: {exc}")
            except NotUnderstood:
                continue
            assert isinstance(got, Stop), f"{sentence!r} was read as {got!r}"


def test_an_answer_to_a_question_is_corrected_too() -> None:
    talk = Dialogue()
    with pytest.raises(Ambiguous):
        interpret("bring me the cup", vocabulary=two_cups(), dialogue=talk)
    got = interpret("the one on the tabel", vocabulary=two_cups(), dialogue=talk)
    assert got == Command(TaskAtom("bring", ("cup_2",))) and got.read_as == (("tabel", "table"),)


def test_every_unknown_word_is_named_in_a_refusal() -> None:
    with pytest.raises(NotUnderstood) as info:
        interpret("bring me the bowl or the jra")
    assert "'or'" in str(info.value) and "I do not know 'jra' either." in str(info.value)


def _counted(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    real = spelling.distance

    def counting(a: str, b: str, limit: int) -> int:
        calls.append(1)
        return real(a, b, limit)

    monkeypatch.setattr(spelling, "distance", counting)
    return calls


def test_the_work_is_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _counted(monkeypatch)
    known = known_words(default_grammar().phrases, default_vocabulary())
    interpret("brign me the cupp")
    assert 0 < len(calls) <= 2 * len(known)  # one distance per known word, per unknown word
    calls.clear()
    long = "please robot " * (MAX_CORRECTED_TOKENS // 2) + "brign me the cup"  # a token per word
    with pytest.raises(NotUnderstood, match="'brign'"):
        interpret(long)
    assert calls == []  # a long line is not corrected
    many = " ".join(["brign", "me", "the", "cupp", *["wibble"] * MAX_TYPO_WORDS])
    with pytest.raises(NotUnderstood):
        interpret(many)
    assert calls == []  # nor one with too many unknown words


def test_reading_tried_per_sentence_is_bounded(monkeypatch: pytest.MonkeyPatch) -> None:
    tried: list[int] = []
    real = language._meaning

    def counting(*args: object, **kwargs: object) -> str | None:
        tried.append(1)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(language, "_meaning", counting)
    with pytest.raises(NotUnderstood):
        interpret("pout the bowk itno the baol")
    assert len(tried) <= language.MAX_READINGS_TRIED
