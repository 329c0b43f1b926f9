"""From a sentence to a task (L_HC). A deliberately small, pattern-based understanding of
kitchen commands — a named simplification: no speech, no statistical language model.

Understood forms (articles optional, case-insensitive):
  pour [the] X into|in [the] Y      → pour(X, Y)
  fetch|bring|get [the] X           → fetch(X)
  put|place [the] X on [the] Y      → place(X, Y)
"""

from __future__ import annotations

import re

from shared.fipa_codec.languages.l_hc import TaskAtom

_ART = r"(?:the\s+|a\s+|an\s+)?"
_WORD = r"([a-z][a-z_]*)"
_PATTERNS: tuple[tuple[re.Pattern[str], str], ...] = (
    (re.compile(rf"^pour\s+{_ART}{_WORD}\s+(?:into|in)\s+{_ART}{_WORD}$"), "pour"),
    (re.compile(rf"^(?:fetch|bring|get)\s+(?:me\s+)?{_ART}{_WORD}$"), "fetch"),
    (re.compile(rf"^(?:put|place)\s+{_ART}{_WORD}\s+on\s+{_ART}{_WORD}$"), "place"),
)


class NotUnderstood(ValueError):
    """The sentence matches no known command form; the message says which forms exist."""


def interpret(sentence: str) -> TaskAtom:
    """The task a sentence asks for. Raises NotUnderstood for anything else."""
    text = re.sub(r"[.!?]+$", "", " ".join(sentence.lower().split())).removeprefix("please ")
    text = re.sub(r"\s+please$", "", text)
    for pattern, name in _PATTERNS:
        m = pattern.match(text)
        if m:
            return TaskAtom(name, tuple(m.groups()))
    raise NotUnderstood(
        f"I do not understand {sentence!r}; try 'pour the jar into the bowl', "
        "'fetch the jar' or 'put the bowl on the table'"
    )
