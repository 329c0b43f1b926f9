"""The base form of an English verb said in another form ("poured" → "pour", "brought" →
"bring", "emptied" → "empty"), so that "I need the beans poured into the bowl" is read with
a_hi's own verbs (tolerance.py ``wished``), and "I'm watching you pour …" is told, not asked
(tolerance.py ``_told_of_you``).

The forms are a table (:data:`TABLE`, ≈ 10 kB) of the verbs a_hi begins a command with and of
the verbs of perceiving or causing, written by scripts/verb_forms.py from LemmInflect's
inflection tables (the ``lemminflect`` package): a_hi reads the table, not LemmInflect, whose
tables take 33 MiB in a process (measured on this VM). tests/agents/human_interface/
test_verb_forms.py checks that it is current."""

from __future__ import annotations

import functools
import json
from pathlib import Path

TABLE = Path(__file__).with_name("verb_forms.json")
MAX_WORD = 24
"""A longer word is no verb form looked up."""


@functools.cache
def _table() -> dict[str, tuple[str, ...]]:
    raw: dict[str, list[str]] = json.loads(TABLE.read_text())
    return {form: tuple(bases) for form, bases in raw.items()}


def load() -> None:
    """Read the table now (a_hi's start)."""
    _table()


def verb_lemmas(word: str) -> tuple[str, ...]:
    """The base forms ``word`` (lower case) is a form of, of the verbs the table holds: ("pour",)
    for "poured", ("see",) for "saw"; () for any other word, and for one longer than
    :data:`MAX_WORD`."""
    if len(word) > MAX_WORD:
        return ()
    return _table().get(word, ())


__all__ = ["MAX_WORD", "TABLE", "load", "verb_lemmas"]
