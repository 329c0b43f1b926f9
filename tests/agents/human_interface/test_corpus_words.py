"""The person's words (corpus.toml): progress asked in any wording, every task by its own name
and common verbs, urgency in a clause, typos corrected and said back or named, things a_hi must
refuse. Each sentence is read as a_hi reads a line (stop.py first, then language.py's
``interpret``) against the kitchen as O_RoCo states it; the share answered as meant must be at
least :data:`AS_MEANT`, and every refusal and every typo must hold."""

from __future__ import annotations

import functools
import tomllib
from dataclasses import dataclass
from pathlib import Path

from services.agents.human_interface.intents import (
    URGENT_PRIORITY,
    Ambiguous,
    Command,
    Incomplete,
    Intent,
    Misspelt,
    NotUnderstood,
    StatusRequest,
    Stop,
    WorldQuestion,
)
from services.agents.human_interface.language import default_vocabulary, interpret
from services.agents.human_interface.stop import StopWords, command_openings
from services.agents.human_interface.task_grammar import default_grammar
from services.agents.planner.domain import TASKS
from shared.fipa_codec.languages.l_hc import TaskAtom

CORPUS = Path(__file__).with_name("corpus.toml")
OTHER_HANDS = Path(__file__).with_name("other_hands.toml")
"""Sentences written by someone other than the grammar's authors (its header)."""
AS_MEANT = 0.97
"""The least share of the corpus answered as meant."""
MIN_SENTENCES = 300


@dataclass(frozen=True)
class Case:
    """One sentence of the corpus and what it means (corpus.toml's header)."""

    group: str
    say: str
    want: str
    urgent: bool = False
    deadline_s: float | None = None
    read: str | None = None


def load(path: Path = CORPUS) -> list[Case]:
    """The cases of ``path``, by group in file order."""
    with path.open("rb") as f:
        data = tomllib.load(f)
    return [Case(group, **entry) for group, entries in data.items() for entry in entries]


@functools.cache
def stop_words() -> StopWords:
    return StopWords(command_openings(default_grammar()))


def outcome(sentence: str) -> Intent | NotUnderstood:
    """What a_hi makes of ``sentence`` as a line of its own (agent.py ``_on_input``)."""
    if stop_words().match(sentence) is not None:
        return Stop()
    try:
        return interpret(sentence, vocabulary=default_vocabulary())
    except NotUnderstood as exc:
        return exc


def as_meant(case: Case, got: Intent | NotUnderstood) -> bool:
    """Whether ``got`` is what ``case`` means (a typo also said back: ``read_as``)."""
    kind, *rest = case.want.split()
    if kind == "status":
        meant = isinstance(got, StatusRequest)
    elif kind == "stop":
        meant = isinstance(got, Stop)
    elif kind == "refuse":
        meant = isinstance(got, NotUnderstood) and not isinstance(got, Ambiguous | Incomplete)
    elif kind == "ask":
        meant = isinstance(got, Ambiguous | Incomplete)
    elif kind == "named":
        meant = isinstance(got, Misspelt) and got.word == rest[0]
    elif kind == "question":
        meant = isinstance(got, WorldQuestion) and [got.kind, *([got.thing] if rest[1:] else [])] == rest
    else:
        priority = URGENT_PRIORITY if case.urgent else 0
        meant = got == Command(TaskAtom(kind, tuple(rest)), priority, case.deadline_s)
    if meant and case.read and not kind.startswith(("named", "refuse")):
        written, read = case.read.split(":")
        said = getattr(got, "read_as", ())
        meant = (written, read) in said or (kind == "stop" and not said)  # a stop found by stop.py
        meant = meant or _left_out(written, said)
    return meant


def _left_out(written: str, said: tuple[tuple[str, str], ...]) -> bool:
    """Whether the typo ``written`` was left out of a line read otherwise, and that said back
    (tolerance.py: "pleeze put the jar away" read as "put the jar away")."""
    return any(written in line.lower().split() and written not in text.lower().split() for line, text in said)


def typo_handled(case: Case, got: Intent | NotUnderstood) -> bool:
    """A typo is corrected (said back), named in the refusal, or the line is stopped on."""
    written, read = (case.read or ":").split(":")
    if isinstance(got, NotUnderstood):
        return f"'{written}'" in str(got)
    if isinstance(got, Stop) and case.want == "stop":
        return True
    said = getattr(got, "read_as", ())
    return (written, read) in said or _left_out(written, said)


def test_the_corpus_is_answered_as_meant() -> None:
    cases = load()
    results = [(c, outcome(c.say)) for c in cases]
    wrong = [(c, got) for c, got in results if not as_meant(c, got)]
    for c, got in wrong:
        print(f"[{c.group}] {c.say!r}: want {c.want!r}, got {got!r}")
    share = 1 - len(wrong) / len(cases)
    print(f"{len(cases)} sentences, {share:.1%} answered as meant")
    assert len(cases) >= MIN_SENTENCES
    refusals = [(c, got) for c, got in results if c.want == "refuse"]
    assert all(isinstance(got, NotUnderstood) for _, got in refusals), [
        c.say for c, got in refusals if not isinstance(got, NotUnderstood)
    ]
    typos = [(c, got) for c, got in results if c.read]
    assert all(typo_handled(c, got) for c, got in typos), [
        (c.say, got) for c, got in typos if not typo_handled(c, got)
    ]
    assert share >= AS_MEANT, f"{share:.1%} answered as meant; {len(wrong)} wrong (printed)"


def test_the_corpus_covers_each_kind_of_sentence() -> None:
    cases = load()
    groups = {c.group for c in cases}
    assert groups >= {"status", "names", "urgency", "stops", "typos", "refusals", "questions"}
    wants = [c.want.split()[0] for c in cases]
    assert {name for name in TASKS} <= set(wants)
    assert wants.count("status") >= 40 and wants.count("refuse") >= 50 and wants.count("question") >= 30
    assert sum(1 for c in cases if c.read) >= 40
    assert len({c.say.lower() for c in cases}) == len(cases), "each sentence once"


def test_every_task_of_a_pl_is_a_command_by_its_own_name() -> None:
    """Each task of a_pl's domain, said by its name ("localise the jar", "hand_over the cup",
    "place the cup on the table"), is a command. ``fetch`` reads as ``bring``, as in English
    ("fetch the cup" brings it; the task ``fetch``, taking a thing in a hand, is "pick up")."""
    also = {"fetch": "bring"}
    second = {"pour": "into the bowl", "place": "on the table"}
    for name, (arity, _) in TASKS.items():
        said = name.replace("_", " ") + " the cup" + (f" {second[name]}" if arity == 2 else "")
        args = ("cup",) if arity == 1 else ("cup", "bowl" if name == "pour" else "table")
        got = outcome(said)
        assert got == Command(TaskAtom(also.get(name, name), args)), f"{said!r}: {got!r}"
        assert isinstance(outcome(name.replace("_", " ")), Incomplete | Command), name
