"""Parsing a sentence with a_hi's grammar (grammar.lark, lark's Earley parser).

A sentence is normalised (lower case, punctuation and apostrophes dropped, decimal points
kept), then **tagged**: at each position the longest phrase known wins, a closed-class phrase
(:data:`PHRASES`, from :data:`WORDS`, plus the words of the task frames task_grammar.py adds)
before a noun or adjective of the :class:`~.vocabulary.Vocabulary` of the same length.
"within N seconds|minutes|hours" becomes one ``DEADLINE`` token (its value in seconds); a
plural of a known noun is ``PLURAL``; any other word is ``WORD``, which no rule accepts, so
that the parse stops at it and :class:`ParseFailure` names it.

:func:`parse` returns every reading of the sentence (lark's ambiguities collapsed), for
meaning.py to choose from. Raises :class:`ParseFailure` (the token where the parse stopped,
or the end of the sentence, and the word classes that were expected there). The parser of
grammar.lark alone is :func:`parser`; task_grammar.py builds the one a_hi uses, grammar.lark
with the rules of the task frames (:func:`build_parser`).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedEOF, UnexpectedInput, UnexpectedToken
from lark.lexer import Lexer
from lark.visitors import CollapseAmbiguities

from services.agents.human_interface.vocabulary import Vocabulary

GRAMMAR_FILE = Path(__file__).with_name("grammar.lark")
MAX_READINGS = 64
"""At most this many readings of one sentence are weighed (a short command has a handful)."""

WORDS: dict[str, tuple[str, ...]] = {
    # polite framing, address, thanks
    "POLITE": (
        "could you",
        "can you",
        "would you",
        "will you",
        "could you maybe",
        "would you mind",
        "i want you to",
        "i need you to",
        "i would like you to",
        "id like you to",
        "i wish you would",
        "do you think you could",
        "i wonder if you could",
        "would you be so kind as to",
        "be so kind and",
        "be a dear and",
        "go and",
        "go",
        "hey",
        "ok",
        "okay",
        "now then",
        "then",
        "lets",
        "you should",
        "i would like to ask you to",
        "you can",
        "try to",
    ),
    "PLEASE": ("please", "kindly", "pls", "plz"),
    "THANKS": ("thanks", "thank you", "thank you very much", "cheers", "ta"),
    "ADDRESS": ("robot", "velma"),
    "URGENT": (
        "urgently",
        "urgent",
        "quickly",
        "quick",
        "fast",
        "now",
        "right now",
        "right away",
        "at once",
        "immediately",
        "asap",
        "as soon as possible",
        "hurry",
        "hurry up",
        "first",
        "straight away",
        "without delay",
        "its urgent",
        "this is urgent",
        "before anything else",
    ),
    # stop and status
    "STOP": ("stop", "cancel", "abort", "halt", "freeze"),
    "EVERYTHING": (
        "everything",
        "all",
        "all commands",
        "all tasks",
        "all of it",
        "what you are doing",
        "whatever you are doing",
        "doing that",
        "that now",
        "all that",
    ),
    "STATUS": (
        "status",
        "status report",
        "report",
        "progress",
        "what are you doing",
        "what are you up to",
        "what are you working on",
        "what are you busy with",
        "whats going on",
        "what is going on",
        "whats happening",
        "what is happening",
        "how is it going",
        "hows it going",
        "how far are you",
        "what is your status",
        "whats your status",
        "are you busy",
        "are you done",
        "what are you doing now",
        "give me a status report",
        "tell me your status",
        "how are you getting on",
    ),
    # verbs of the tasks whose frames are written in grammar.lark (the others: tasks.toml)
    "POUR": ("pour", "tip", "decant", "transfer"),
    "EMPTY": ("empty",),
    "FILL": ("fill", "refill"),
    "BRING": ("bring", "fetch", "get", "grab", "carry"),
    "TAKE": ("take", "remove"),
    "PUT": ("put", "place", "set", "leave", "lay", "move", "stand", "stick", "position"),
    "RETURN": ("return", "store", "stow", "replace"),
    "HAND": ("hand", "give", "pass"),
    # prepositions and particles
    "IN": ("in", "into", "inside", "in to"),
    "ON": ("on", "onto", "upon", "on to", "on top of"),
    "TO": ("to", "towards"),
    "OVER": ("over",),
    "OUT": ("out",),
    "FROM": ("from", "out of", "off", "from inside", "from out of", "off of"),
    "WITH": ("with",),
    "UP": ("up",),
    "DOWN": ("down",),
    "BACK": ("back",),
    "AWAY": ("away",),
    "HOME": (
        "where it belongs",
        "where it was",
        "where it goes",
        "where they belong",
        "in its place",
        "to its place",
        "its place",
        "where you found it",
        "where it came from",
    ),
    "ME": ("me", "us"),
    "HERE": ("here", "there"),
    "FOR": ("for",),
    "OF": ("of",),
    "AND": ("and", "and then", "and also"),
    "REL": ("that is", "thats", "which is", "that stands", "standing", "sitting", "that sits"),
    # references
    "IT": ("it", "them", "this one", "that one"),
    "THAT": ("that", "this"),
    "ONE": ("one",),
    "CONTENTS": ("contents", "content", "what is in", "whats in", "everything in"),
    "DET": ("the", "a", "an", "my", "your", "our", "these", "those", "some"),
}
"""Closed-class words and fixed phrases → word class (a terminal of grammar.lark). Object,
place and adjective words are not here: they come from the vocabulary (the ontology); the
words of the frames in tasks.toml are added by task_grammar.py."""

_NUMBERS = {
    "a": 1, "an": 1, "one": 1, "two": 2, "three": 3, "four": 4, "five": 5, "six": 6, "seven": 7,
    "eight": 8, "nine": 9, "ten": 10, "fifteen": 15, "twenty": 20, "thirty": 30, "forty": 40,
    "fifty": 50, "sixty": 60, "ninety": 90, "half an": 0.5,
}  # fmt: skip
_UNITS = {
    "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
    "min": 60.0, "mins": 60.0, "minute": 60.0, "minutes": 60.0,
    "h": 3600.0, "hour": 3600.0, "hours": 3600.0,
}  # fmt: skip
PHRASES: dict[tuple[str, ...], str] = {
    tuple(p.split()): kind for kind, phrases in WORDS.items() for p in phrases
}
""":data:`WORDS` as the tagger looks them up: the words of a phrase → its word class."""


@dataclass(frozen=True)
class Word:
    """A tagged word or phrase: its word class (``kind``), its ``words``, its index among the
    sentence's tokens (``index``); ``seconds`` for a DEADLINE."""

    kind: str
    words: tuple[str, ...]
    index: int
    seconds: float | None = None

    @property
    def text(self) -> str:
        return " ".join(self.words)


class ParseFailure(ValueError):
    """The sentence does not parse: ``at`` is the token where it stopped (None: the sentence
    ended too early), ``expected`` the word classes that could have come there, ``words`` the
    sentence's tokens."""

    def __init__(self, at: Word | None, expected: frozenset[str], words: tuple[Word, ...]) -> None:
        shown = repr(at.text) if at is not None else "the end"
        super().__init__(f"parse stopped at {shown}; expected one of {sorted(expected)}")
        self.at = at
        self.expected = expected
        self.words = words


def normalise(sentence: str) -> list[str]:
    """The words of ``sentence``: lower case, apostrophes dropped ("what's" → "whats"), other
    punctuation a space, decimal points kept ("1.5")."""
    text = sentence.lower().replace("'", "").replace("’", "")
    text = re.sub(r"[^a-z0-9.\s]+", " ", text)
    text = re.sub(r"(?<![0-9])\.|\.(?![0-9])", " ", text)
    return text.split()


def _deadline(words: list[str], i: int) -> tuple[int, float] | None:
    """At ``words[i]`` == "within": (words used, seconds) of "within [the next] N unit"."""
    j = i + 1
    if words[j : j + 2] == ["the", "next"]:
        j += 2
    amount: float | None = None
    for n in (2, 1):
        key = " ".join(words[j : j + n])
        if len(words[j : j + n]) == n and key in _NUMBERS:
            amount, j = float(_NUMBERS[key]), j + n
            break
    else:
        if j < len(words) and re.fullmatch(r"\d+(?:\.\d+)?", words[j]):
            amount, j = float(words[j]), j + 1
    if amount is None or j >= len(words) or words[j] not in _UNITS:
        return None
    return j + 1 - i, amount * _UNITS[words[j]]


def tag(
    sentence: str, vocabulary: Vocabulary, phrases: Mapping[tuple[str, ...], str] = PHRASES
) -> tuple[Word, ...]:
    """The tokens of ``sentence`` (see the module docstring); ``phrases``: the closed-class
    phrases (default :data:`PHRASES`; a_hi's grammar adds the words of its task frames)."""
    words = normalise(sentence)
    lexicon: dict[tuple[str, ...], str] = {}
    for adj in vocabulary.adjectives:
        lexicon[(adj,)] = "ADJ"
    for noun in vocabulary.nouns:
        lexicon[noun] = "NOUN"
        if len(noun) == 1 and not noun[0].endswith("s"):
            lexicon.setdefault((noun[0] + "s",), "PLURAL")
            lexicon.setdefault((noun[0] + "es",), "PLURAL")
    lexicon.update(phrases)  # a closed-class phrase wins over a vocabulary word of the same length
    longest = max((len(p) for p in lexicon), default=1)
    out: list[Word] = []
    i = 0
    while i < len(words):
        if words[i] == "within":
            found = _deadline(words, i)
            if found is not None:
                n, seconds = found
                out.append(Word("DEADLINE", tuple(words[i : i + n]), len(out), seconds))
                i += n
                continue
            out.append(Word("WITHIN", (words[i],), len(out)))
            i += 1
            continue
        for n in range(min(longest, len(words) - i), 0, -1):
            phrase = tuple(words[i : i + n])
            if phrase in lexicon:
                out.append(Word(lexicon[phrase], phrase, len(out)))
                i += n
                break
        else:
            out.append(Word("WORD", (words[i],), len(out)))
            i += 1
    return tuple(out)


class _Tags(Lexer):
    """lark's lexer for a sequence of :class:`Word`: one token per word, its value the words."""

    def __init__(self, conf: object) -> None:
        pass

    def lex(self, data: tuple[Word, ...]) -> Iterator[Token]:  # type: ignore[override]
        for w in data:
            yield Token(w.kind, w.text, start_pos=w.index)


def build_parser(text: str) -> Lark:
    """The Earley parser of the grammar ``text`` over word classes (readings kept:
    ``ambiguity="explicit"``). Raises lark's GrammarError for a malformed grammar."""
    return Lark(
        text,
        parser="earley",
        lexer=_Tags,
        ambiguity="explicit",
        propagate_positions=False,
    )


@functools.cache
def parser() -> Lark:
    """The Earley parser of grammar.lark alone (built once)."""
    return build_parser(GRAMMAR_FILE.read_text())


def parse(words: tuple[Word, ...], using: Lark | None = None) -> list[Tree[Token]]:
    """Every reading of the tagged sentence ``words`` by the parser ``using`` (default:
    :func:`parser`), at most :data:`MAX_READINGS`. Raises :class:`ParseFailure` where no rule
    goes on."""
    try:
        tree = (using if using is not None else parser()).parse(words)
    except UnexpectedEOF as exc:
        raise ParseFailure(None, frozenset(exc.expected), words) from None
    except UnexpectedToken as exc:
        at = words[exc.token.start_pos] if isinstance(exc.token.start_pos, int) else None
        if exc.token.type == "$END":
            at = None
        raise ParseFailure(at, frozenset(exc.expected), words) from None
    except UnexpectedInput as exc:  # pragma: no cover - the lexer is ours: no other kind
        raise ParseFailure(None, frozenset(), words) from exc
    readings = CollapseAmbiguities().transform(tree)
    return list(readings[:MAX_READINGS])


__all__ = [
    "GRAMMAR_FILE",
    "PHRASES",
    "WORDS",
    "ParseFailure",
    "Word",
    "build_parser",
    "normalise",
    "parse",
    "parser",
    "tag",
]
