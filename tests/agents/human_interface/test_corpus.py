"""The corpus (corpus.py): every sentence maps to its L_HC command, question or refusal."""

from __future__ import annotations

import functools

import pytest
from rdflib import Graph

from services.agents.human_interface.language import (
    Ambiguous,
    Command,
    Incomplete,
    NotUnderstood,
    StatusRequest,
    Stop,
    WorldQuestion,
    default_vocabulary,
    interpret,
)
from services.agents.human_interface.vocabulary import KNOWLEDGE_FILES, Vocabulary
from services.agents.planner.domain import TASKS
from shared.fipa_codec.languages.l_hc import TaskAtom
from tests.agents.human_interface.corpus import (
    BAD_INPUT,
    DEADLINES,
    LOCALISE,
    PARAPHRASES,
    PHRASAL,
    POLITE,
    POSSESSIVES,
    REFERENCES,
    REFUSALS,
    SECOND_CUP,
    STATUS,
    STOP,
    TAG_QUESTIONS,
    VOICES,
    VOICES_REFUSED,
    WISHES,
    Ask,
    Do,
    Expected,
    Question,
    Refuse,
)


@functools.cache
def two_cups() -> Vocabulary:
    """The kitchen of O_RoCo with :data:`SECOND_CUP` stated beside it."""
    graph = Graph()
    for path in KNOWLEDGE_FILES:
        graph.parse(path, format="turtle")
    graph.parse(data=SECOND_CUP, format="turtle")
    return Vocabulary.from_graph(graph)


def check(sentence: str, expected: Expected, vocabulary: Vocabulary) -> None:
    if isinstance(expected, Do):
        assert interpret(sentence, vocabulary=vocabulary) == Command(
            TaskAtom(expected.task, expected.args), expected.priority, expected.deadline_s
        )
        return
    if isinstance(expected, Question):
        question = interpret(sentence, vocabulary=vocabulary)
        assert isinstance(question, WorldQuestion), question
        assert (question.kind, question.thing) == (expected.kind, expected.thing), question
        return
    if expected == STOP:
        assert interpret(sentence, vocabulary=vocabulary) == Stop()
        return
    if expected == STATUS:
        assert interpret(sentence, vocabulary=vocabulary) == StatusRequest()
        return
    with pytest.raises(NotUnderstood) as info:
        interpret(sentence, vocabulary=vocabulary)
    text = str(info.value)
    assert "\n" not in text and text.strip() == text, "one line"
    if isinstance(expected, Ask):
        wanted = Ambiguous if expected.kind == "which" else Incomplete
        assert isinstance(info.value, wanted), f"{type(info.value).__name__}: {text}"
        assert text.endswith((".", "?")) and "?" in text, text
    else:
        assert isinstance(expected, Refuse)
        assert not isinstance(info.value, Ambiguous | Incomplete), f"{type(info.value).__name__}: {text}"
    assert expected.says in text, text


@pytest.mark.parametrize(("sentence", "expected"), PARAPHRASES, ids=[s for s, _ in PARAPHRASES])
@pytest.mark.requirement("R1.1")
def test_paraphrases_of_the_tasks(sentence: str, expected: Expected) -> None:
    check(sentence, expected, default_vocabulary())


@pytest.mark.parametrize(("sentence", "expected"), REFERENCES, ids=[s for s, _ in REFERENCES])
def test_ambiguous_unknown_and_located_references(sentence: str, expected: Expected) -> None:
    check(sentence, expected, two_cups())


@pytest.mark.parametrize(
    ("sentence", "expected"),
    (*REFUSALS, *VOICES_REFUSED),
    ids=[ascii(s) if s else "(empty)" for s, _ in (*REFUSALS, *VOICES_REFUSED)],
)
def test_sentences_that_must_be_refused(sentence: str, expected: Expected) -> None:
    check(sentence, expected, default_vocabulary())


EVERYDAY = {
    "phrasal": PHRASAL,
    "possessive": POSSESSIVES,
    "polite": POLITE,
    "wish": WISHES,
    "tag": TAG_QUESTIONS,
    "deadline": DEADLINES,
    "localise": LOCALISE,
    "voices": VOICES,
}
"""The groups of everyday wordings beyond the first paraphrases (corpus.py), by name."""
_EVERYDAY = [(f"{group}: {s}", s, e) for group, sentences in EVERYDAY.items() for s, e in sentences]


@pytest.mark.parametrize(
    ("sentence", "expected"), [(s, e) for _, s, e in _EVERYDAY], ids=[i for i, _, _ in _EVERYDAY]
)
@pytest.mark.requirement("R1.1")
def test_everyday_wordings(sentence: str, expected: Expected) -> None:
    check(sentence, expected, default_vocabulary())


@pytest.mark.parametrize(("sentence", "expected"), BAD_INPUT, ids=[ascii(s) for s, _ in BAD_INPUT])
def test_bad_input_is_refused_and_a_vague_place_asked_back(sentence: str, expected: Expected) -> None:
    check(sentence, expected, default_vocabulary())


def test_the_corpus_is_large_and_covers_every_task_a_pl_accepts() -> None:
    groups = (PARAPHRASES, REFERENCES, REFUSALS, VOICES_REFUSED, BAD_INPUT, *EVERYDAY.values())
    paraphrases = {s.lower() for s, e in PARAPHRASES if isinstance(e, Do) or e in (STOP, STATUS)}
    unsure = [e for _, e in REFERENCES if not isinstance(e, Do)]
    sentences = [s for group in groups for s, _ in group]
    assert len(sentences) >= 400
    assert len(paraphrases) >= 100
    assert len(unsure) >= 20
    assert len(REFUSALS) >= 30
    for name, group in EVERYDAY.items():  # each gap has its own sentences, most of them understood
        understood = [e for _, e in group if isinstance(e, Do | Question)]
        assert len(group) >= 15 and len(understood) >= 0.8 * len(group), name
    refused = [e for _, e in BAD_INPUT if isinstance(e, Refuse)]
    asked = [e for _, e in BAD_INPUT if isinstance(e, Ask)]
    assert len(refused) >= 15 and len(asked) >= 10
    tasks = {e.task: len(e.args) for _, e in PARAPHRASES if isinstance(e, Do)}
    assert tasks == {name: arity for name, (arity, _) in TASKS.items()}
