"""Typos in the words a_hi knows: the candidates for a word it does not know.

A word of a sentence that is none of a_hi's words (grammar.py tags it ``WORD``) may be a typo of
one of them: "doimg" of "doing", "stpo" of "stop", "tabel" of "table". Its **candidates** are the
words a_hi knows (:func:`known_words`: the words of grammar.lark's closed-class phrases and of
the task frames, the number words and units of a deadline, the nouns and adjectives of the
vocabulary) within a small Damerau-Levenshtein distance (:func:`distance`, the
optimal-string-alignment variant: an insertion, a deletion or a transposition of two adjacent
letters costs 1, a substitution 1 when the two letters are neighbours on a QWERTY keyboard,
:data:`KEY_ROWS`, else 2): 1 for a word of 4 to 7 letters, 2 for one of 8 or more
(:func:`max_distance`); a word of fewer than 4 letters, or of more than :data:`MAX_LETTERS`, has
none. Substitutions are held to a slip of the finger because a word a_hi does not know is as
often a real word of a task it does not have: "smash" is one substitution from "stash" (m and t
are far apart: not corrected), "doimg" one from "doing" (m beside n). Only the candidates at the
smallest distance found are kept: "jarr" is "jar" (1), not also a word at 2.

Which candidate is meant, if any, is language.py's to decide (it reads the sentence with each);
this module only finds them. The work is bounded: per word, one distance per known word of a
length within the limit, each over at most (:data:`MAX_LETTERS` + 1)² cells and cut short once
a row exceeds the limit.
"""

from __future__ import annotations

import itertools
from collections.abc import Collection, Iterable, Mapping

from services.agents.human_interface.grammar import NUMBERS, UNITS
from services.agents.human_interface.stop import STOP_WORDS, WAITING_WORDS
from services.agents.human_interface.vocabulary import Vocabulary

STOPPING = STOP_WORDS + WAITING_WORDS
"""stop.py's phrases that stop (or wait): their words are candidates too, so that a typo of one
is a stop or named, never read as another word ("pase": "pause" or "pass")."""

KEY_ROWS = ("qwertyuiop", "asdfghjkl", "zxcvbnm")
"""The letter rows of a QWERTY keyboard, each set half a key right of the one above: the key at
(row r, column c) neighbours (r, c ± 1), (r - 1, c), (r - 1, c + 1), (r + 1, c - 1), (r + 1, c)."""


def _neighbours() -> frozenset[tuple[str, str]]:
    at = {ch: (r, c) for r, row in enumerate(KEY_ROWS) for c, ch in enumerate(row)}
    near = ((0, -1), (0, 1), (-1, 0), (-1, 1), (1, -1), (1, 0))
    by_place = {place: ch for ch, place in at.items()}
    return frozenset(
        (ch, other)
        for ch, (r, c) in at.items()
        for dr, dc in near
        if (other := by_place.get((r + dr, c + dc))) is not None
    )


NEIGHBOURS = _neighbours()
"""Pairs of letters on neighbouring keys (both orders): a substitution between them costs 1."""

MIN_LETTERS = 4
"""A word of fewer letters is not corrected (too many words are one edit from it), but for two
adjacent letters swapped in a word of three, or one of its letters typed with the key beside it
("teh", "jra", "cpu", "cuo", "jsr": :func:`candidates`)."""
LONG_LETTERS = 8
"""A word of this many letters or more may be two edits from its candidate."""
MAX_LETTERS = 24
"""A longer word is not corrected (it bounds the work of one distance)."""


def max_distance(word: str) -> int:
    """The largest distance of a candidate for ``word``: 0 (not corrected) below
    :data:`MIN_LETTERS` letters or above :data:`MAX_LETTERS`, 1 below :data:`LONG_LETTERS`,
    else 2."""
    n = len(word)
    if n < MIN_LETTERS or n > MAX_LETTERS:
        return 0
    return 1 if n < LONG_LETTERS else 2


def correctable(word: str) -> bool:
    """Whether ``word`` may be corrected: :func:`max_distance` above 0, or three letters (a swap
    of two adjacent ones: :func:`candidates`)."""
    return max_distance(word) > 0 or len(word) == MIN_LETTERS - 1


def distance(a: str, b: str, limit: int) -> int:
    """The optimal-string-alignment distance of ``a`` and ``b`` (Damerau-Levenshtein without
    editing a substring twice: each insertion, deletion or transposition of two adjacent
    characters costs 1, a substitution 1 between :data:`NEIGHBOURS`, else 2), or ``limit + 1``
    as soon as it is known to exceed ``limit``."""
    if abs(len(a) - len(b)) > limit:
        return limit + 1
    before: list[int] = []  # row i - 2
    above = list(range(len(b) + 1))  # row i - 1
    for i in range(1, len(a) + 1):
        row = _row(a, b, i, above, before)
        if min(row) > limit:
            return limit + 1
        before, above = above, row
    return min(above[-1], limit + 1)


def _row(a: str, b: str, i: int, above: list[int], before: list[int]) -> list[int]:
    """Row ``i`` of :func:`distance`'s table, from the two rows ``above`` it."""
    row = [i] + [0] * len(b)
    for j in range(1, len(b) + 1):
        x, y = a[i - 1], b[j - 1]
        cost = 0 if x == y else 1 if (x, y) in NEIGHBOURS else 2
        row[j] = min(above[j] + 1, row[j - 1] + 1, above[j - 1] + cost)
        if i > 1 and j > 1 and x == b[j - 2] and a[i - 2] == y:
            row[j] = min(row[j], before[j - 2] + 1)
    return row


def known_words(
    phrases: Mapping[tuple[str, ...], str], vocabulary: Vocabulary, also: Iterable[str] = STOPPING
) -> frozenset[str]:
    """The words a_hi knows, as candidates: each word of the closed-class ``phrases`` (the
    tagger's: grammar.lark's and the task frames'), of the number words and units of a deadline,
    of the ``vocabulary``'s nouns and adjectives, and of the phrases ``also`` (default: the stop
    and waiting words of stop.py, :data:`STOPPING`: "pase" is as near "pause" as "pass"); words
    of letters only."""
    words: set[str] = set(itertools.chain.from_iterable(p.split() for p in also))
    for phrase in phrases:
        words.update(phrase)
    for number in NUMBERS:
        words.update(number.split())
    words.update(UNITS)
    for noun in vocabulary.nouns:
        words.update(noun)
    for thing in vocabulary.things:
        words.update(thing.adjectives)
    return frozenset(w for w in words if w.isalpha())


def candidates(word: str, known: Collection[str]) -> tuple[str, ...]:
    """The words of ``known`` nearest to ``word`` within :func:`max_distance` (sorted; empty when
    there is none, ``word`` is not corrected, or it is itself a known word: a word of a phrase,
    "what", is no typo); for a word of three letters, the known words it is with two adjacent
    letters swapped or one letter on a neighbouring key (no letter added or left out: "hat" is
    not read as "that")."""
    if word in known:
        return ()
    if len(word) == MIN_LETTERS - 1:
        return _swapped(word, known)
    limit = max_distance(word)
    if limit == 0:
        return ()
    best, found = limit + 1, []
    for k in known:
        d = distance(word, k, min(limit, best))
        if d < best:
            best, found = d, [k]
        elif d == best and d <= limit:
            found.append(k)
    return tuple(sorted(found)) if best <= limit else ()


def _swapped(word: str, known: Collection[str]) -> tuple[str, ...]:
    """The words of ``known`` that are ``word`` with two adjacent letters swapped ("cpu": "cup"),
    or, when none is, with one letter typed with the key beside it ("cuo": "cup"; sorted)."""
    swaps = {word[:i] + word[i + 1] + word[i] + word[i + 2 :] for i in range(len(word) - 1)} - {word}
    found = sorted(swaps & set(known)) or sorted(_slips(word) & set(known))  # "teh": "the", not "ten"
    return tuple(found)


def _slips(word: str) -> set[str]:
    """``word`` with one letter typed with a key beside it, each way."""
    return {word[:i] + b + word[i + 1 :] for i, a in enumerate(word) for x, b in NEIGHBOURS if x == a}


__all__ = [
    "KEY_ROWS",
    "LONG_LETTERS",
    "MAX_LETTERS",
    "MIN_LETTERS",
    "NEIGHBOURS",
    "STOPPING",
    "candidates",
    "correctable",
    "distance",
    "known_words",
    "max_distance",
]
