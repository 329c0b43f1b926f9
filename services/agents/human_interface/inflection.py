"""The base form of an English verb said in another form ("poured" → "pour", "brought" →
"bring", "emptied" → "empty"), from LemmInflect's lemma tables (the ``lemminflect`` package,
which ships them: nothing is downloaded), so that "I need the beans poured into the bowl" is
read with a_hi's own verbs (tolerance.py ``wished``).

The tables load on the first word (≈ 0.2 s on a 2-core VM), or at a_hi's start (:func:`load`,
reading.py)."""

from __future__ import annotations

import functools

MAX_WORD = 24
"""A longer word is no verb form looked up (the lookup is a dictionary probe, the bound keeps
the input's work fixed)."""


@functools.cache
def _lemmas() -> object:
    from lemminflect import getAllLemmas

    return getAllLemmas


def load() -> None:
    """Load the lemma tables now (a_hi's start), so that the first line read does not wait."""
    verb_lemmas("put")


@functools.lru_cache(maxsize=4096)
def verb_lemmas(word: str) -> tuple[str, ...]:
    """The base forms ``word`` (lower case) is of as a verb in LemmInflect's dictionary, most
    likely first: ("pour",) for "poured", ("see", "saw") for "saw"; () for a word it holds no
    verb form of ("possible"), longer than :data:`MAX_WORD` or not of letters only."""
    if len(word) > MAX_WORD or not word.isalpha():
        return ()
    get = _lemmas()
    return tuple(get(word, upos="VERB").get("VERB", ()))  # type: ignore[operator]


__all__ = ["MAX_WORD", "load", "verb_lemmas"]
