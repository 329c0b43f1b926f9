"""Sentences written by someone other than the grammar's authors (other_hands.toml): how many
are understood is a figure (scripts/bench_language.py), not asserted; what must never happen is
asserted: a command the person did not mean, a must-refuse line acted on."""

from __future__ import annotations

from services.agents.human_interface.intents import Command, NotUnderstood
from services.agents.planner.domain import TASKS
from tests.agents.human_interface.test_corpus_words import OTHER_HANDS, as_meant, load, outcome

MUST_REFUSE = ("refuse", "ask", "named")


def test_no_wrong_command_and_every_must_refuse_line_refused() -> None:
    cases = load(OTHER_HANDS)
    assert len(cases) >= 150
    wrong, acted = [], []
    for case in cases:
        got = outcome(case.say)
        kind = case.want.split()[0]
        if kind in TASKS and isinstance(got, Command) and not as_meant(case, got):
            wrong.append((case.say, case.want, got))
        if kind in MUST_REFUSE and not isinstance(got, NotUnderstood):
            acted.append((case.say, got))
    assert not wrong, wrong
    assert not acted, acted
