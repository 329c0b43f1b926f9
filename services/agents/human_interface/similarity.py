"""How near two words are in meaning, so that a person's describing word a_km does not use
("little", "huge", "bigger") can reach one it does ("small", "large").

The measure is the cosine similarity of the words' static embeddings in WordLlama (the
``wordllama`` package, MIT licence: token embeddings taken from a large language model's input
layer and trained for similarity, "l2_supercat", 256 dimensions; the 16 MB of weights and the
tokenizer are files of its wheel). They are loaded from the installed package only
(``disable_download``): a_hi never reaches a model hub, and runs with no network. Loading takes
about 0.4 s and 32 MB of memory, once per process; a word's embedding takes about 0.03 ms.

What it is used for, and what not (measured on this model; docs/agents.md):

- **Describing words only.** Between adjectives it separates well: "little"–"small" 0.50 against
  "little"–"large" −0.05; "big"–"large" 0.74 against "big"–"small" 0.25; "tiny"–"small" 0.65;
  "tall"–"big" 0.40 and "pale"–"white" 0.41 stay below :data:`NEAR`. Between kitchen nouns it
  does not: "mug"–"cup" 0.21, "bowl"–"cup" 0.22, "pan"–"beans" 0.38; a noun a_km does not
  list is refused, never guessed.
- **Grounded in a_km's knowledge.** A word is only ever compared with the describing words a_km
  states of the things the person's noun names (meaning.py): "the little bowl" is the small bowl
  only because a_km says a bowl is small, and is refused when no bowl is.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Collection
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

NEAR = 0.45
"""The least similarity at which a word is read as another (cosine, −1…1)."""
MARGIN = 0.15
"""How much nearer the word read must be than the next one: closer, the choice is not clear."""
MAX_WORD = 32
"""Longer words are not compared (bounds the tokenizer's work on outside input)."""

_lock = threading.Lock()


@functools.cache
def _model() -> object:
    """WordLlama's inference object, loaded from the installed package's files (module
    docstring). Raises ImportError when ``wordllama`` is not installed, FileNotFoundError when
    its files are missing (it then never downloads them)."""
    import wordllama
    from wordllama import WordLlama

    return WordLlama.load(cache_dir=Path(wordllama.__file__).parent, disable_download=True)


def load() -> None:
    """Load the model now (a_hi's start), so that the first line read does not wait for it."""
    with _lock:
        _model()


@functools.lru_cache(maxsize=4096)
def _vector(word: str) -> NDArray[np.float32]:
    with _lock:
        model = _model()
    return model.embed([word], norm=True)[0]  # type: ignore[attr-defined]


def similarity(a: str, b: str) -> float:
    """The cosine similarity of words ``a`` and ``b`` (−1…1; 1.0 when equal), 0.0 when either is
    longer than :data:`MAX_WORD` characters."""
    if a == b:
        return 1.0
    if len(a) > MAX_WORD or len(b) > MAX_WORD:
        return 0.0
    return float(_vector(a) @ _vector(b))


@functools.lru_cache(maxsize=4096)
def is_word(word: str) -> bool:
    """Whether ``word`` is one token of the model's tokenizer (Llama 2's, 32,000 pieces): a
    common English word ("says", "cant", "hands"), not a misspelling ("dnot": "d" + "not").
    False for a word longer than :data:`MAX_WORD` characters."""
    if len(word) > MAX_WORD:
        return False
    with _lock:
        model = _model()
    return len(model.tokenizer.encode(word, add_special_tokens=False).ids) == 1  # type: ignore[attr-defined]


def nearest(word: str, options: Collection[str]) -> tuple[str, float] | None:
    """The one of ``options`` that ``word`` means, with its similarity: the nearest, when it is
    at least :data:`NEAR` and nearer than any other by :data:`MARGIN`; else None."""
    scored = sorted(((similarity(word, o), o) for o in options), reverse=True)
    if not scored or scored[0][0] < NEAR:
        return None
    if len(scored) > 1 and scored[0][0] - scored[1][0] < MARGIN:
        return None
    return scored[0][1], scored[0][0]


def near_any(word: str, options: Collection[str]) -> bool:
    """Whether ``word`` is at least :data:`NEAR` to one of ``options`` (it may then describe)."""
    return any(similarity(word, o) >= NEAR for o in options)


__all__ = ["MARGIN", "MAX_WORD", "NEAR", "is_word", "load", "near_any", "nearest", "similarity"]
