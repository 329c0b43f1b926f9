"""a_hi's table of verb forms (services/agents/human_interface/verb_forms.json) is what
scripts/verb_forms.py writes from LemmInflect's tables for a_hi's grammar now: a verb added to
tasks.toml or grammar.py without running the script again fails here, naming the command."""

from __future__ import annotations

import json

import pytest

from services.agents.human_interface.inflection import TABLE, verb_lemmas
from services.bench import parts

verb_forms = parts.scripts_module("verb_forms")


def test_the_shipped_table_is_the_scripts_output() -> None:
    shipped = json.loads(TABLE.read_text())
    assert shipped == verb_forms.table(), "out of date: run python scripts/verb_forms.py"


def test_a_verb_added_to_the_grammar_makes_the_table_out_of_date(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(verb_forms, "TELLING", (*verb_forms.TELLING, "wash"))
    assert json.loads(TABLE.read_text()) != verb_forms.table()  # "washed" would be missing


def test_the_forms_a_hi_reads() -> None:
    assert verb_lemmas("poured") == ("pour",) and verb_lemmas("brought") == ("bring",)
    assert verb_lemmas("watching") == ("watch",) and "see" in verb_lemmas("saw")
    assert verb_lemmas("possible") == () and verb_lemmas("pour") == ()
