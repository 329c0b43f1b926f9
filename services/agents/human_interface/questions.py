"""A person's question about the kitchen, or about a_hi itself: a small, bounded reader of the
forms below, tried before the command grammar (language.py ``interpret``; a stop is found
before both, stop.py).

==========================================================  ===========================
question (after grammar.py ``normalise``: "what's" is        :class:`~.intents.WorldQuestion`
"whats", punctuation dropped)                                ``kind``
==========================================================  ===========================
where is X, wheres X, where are X, where is X now            ``where``
where did you put X, where have you left X                   ``where``
what is in X, whats inside X, what does X hold/contain,      ``contents``
is there anything in X
what is on X, whats on X, is there anything on X             ``on``
is X empty, is X full                                        ``empty``, ``full``
is X in/inside/on Y                                          ``located``
how many (spheres|balls|beans|things|objects …) are in X,    ``count``
how much is in X, how full is X
what did you see, what have you seen, what do you see        ``seen``
what can you do, what are you able to do, help               ``abilities``
==========================================================  ===========================

Each may open with "robot,"/"velma,", "please", "so", "and", "hey", "ok", "quickly", and end
with "please" or "now"; "where is" alone asks back which object is meant. A reference X (or Y)
is resolved as a_hi resolves a command's ("the small cup", "the cup on the table", "the jar's
beans", "it"): by the ``resolve`` callback (language.py reads it with the command grammar as a
bare reference). A reference that names nothing a_km knows gets "I have not seen a spoon; …"
(:class:`~.intents.UnknownReference`); a line matching a form whose reference is no reference
("what is in the jar into the bowl": the rest of a command) is not a question, and is left to
the command grammar. The reader is bounded: a line over :data:`MAX_QUESTION_CHARS` is not read
as a question.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from services.agents.human_interface.grammar import ParseFailure, normalise
from services.agents.human_interface.intents import Incomplete, UnknownReference, WorldQuestion

MAX_QUESTION_CHARS = 200
"""The longest line (characters) read as a question; a longer one goes to the command grammar."""

Resolve = Callable[[str], str | None]
"""A reference's words → its O_RoCo name; None when the words are no reference (another kind of
sentence). Raises :class:`~.grammar.ParseFailure` when they do not parse, and
:class:`~.intents.NotUnderstood` (:class:`~.intents.Ambiguous`, ...) as a command's reference does."""

_OPENING = re.compile(r"^(?:(?:robot|velma|please|so|and|hey|ok|okay|well|quickly|quick)\s+)+")
_CUT = re.compile(r"where(?: is| are|s)?")
"""A "where" question cut short: it asks which object is meant."""
_CLOSING = re.compile(
    r"(?:\s+(?:please|now|right now|at the moment|then|robot|velma|yet|still|already|so far|anymore))+$"
)
_WHICH = "Which object do you ask about? Say e.g. 'where is the jar?'."
_COUNTED_THINGS = frozenset({"things", "objects", "items"})

_FORMS: tuple[tuple[str, re.Pattern[str]], ...] = tuple(
    (kind, re.compile(pattern))
    for kind, pattern in (
        (
            "abilities",
            r"what (?:else )?can you do(?: for me)?|what are you able to do|what do you know how to do|help"
            r"|what can i (?:ask|say|tell)(?: you)?",
        ),
        (
            "seen",
            r"what (?:did|do|have|had|can) you (?:see|seen|saw|looked at)"
            r"(?: last| so far| recently| lately)?",
        ),
        ("where", r"where (?:did|have) you (?:put|left|leave|placed|place|set) (?P<x>.+)"),
        ("where", r"(?:where is|wheres|where are) (?P<x>.+)"),
        ("empty", r"is (?P<x>.+?) (?:still |already |now )?empty"),
        ("full", r"is (?P<x>.+?) (?:still |already |now )?full"),
        (
            "count",
            r"how many(?: (?P<what>[a-z]+))? (?:are |is |do you see )?(?:there )?(?:left )?"
            r"(?:in|inside) (?P<x>.+)",
        ),
        ("count", r"(?:how much is|how full is) (?:there )?(?:in |inside )?(?P<x>.+)"),
        ("contents", r"(?:what is|whats|what are) (?:there )?(?:in|inside) (?P<x>.+)"),
        ("contents", r"what (?:does|do) (?P<x>.+) (?:hold|contain|have in it)"),
        ("contents", r"is there (?:anything|something) (?:in|inside) (?P<x>.+)"),
        ("on", r"(?:what is|whats|what are) (?:there )?(?:standing |lying )?on (?P<x>.+)"),
        ("on", r"is there (?:anything|something) on (?P<x>.+)"),
        ("on", r"how many (?:things|objects|items) (?:are )?(?:there )?on (?P<x>.+)"),
        ("located", r"is (?P<x>.+?) (?P<rel>in|inside|on) (?P<y>.+)"),
    )
)


def question_words(sentence: str) -> str:
    """``sentence`` as the reader matches it: normalised (grammar.py ``normalise``), without its
    opening address or "please" and its closing "please"/"now"."""
    text = " ".join(normalise(sentence))
    text = _OPENING.sub("", text)
    return _CLOSING.sub("", text)


def _article(words: str) -> str:
    """ "a spoon", "an egg": the reference's noun phrase with an indefinite article."""
    bare = re.sub(r"^(?:the|a|an|my|your|this|that|these|those|some)\s+", "", words)
    return ("an " if bare[:1] in "aeiou" else "a ") + bare


def _thing(words: str, resolve: Resolve) -> str | None:
    """The O_RoCo name ``words`` refer to; None: the words are no reference (see the module
    docstring). Raises :class:`UnknownReference` ("I have not seen a spoon") for an unknown
    word, :class:`Incomplete` for a reference cut short, and what ``resolve`` raises."""
    try:
        return resolve(words)
    except ParseFailure as exc:
        if exc.at is None:
            raise Incomplete(
                "Which object do you ask about? Say e.g. 'where is the jar?'.", "object"
            ) from None
        if exc.at.kind == "WORD":
            raise UnknownReference(
                f"I have not seen {_article(words)}; ask me about e.g. 'the bowl' or 'the jar'."
            ) from None
        return None


def _question(kind: str, m: re.Match[str], resolve: Resolve) -> WorldQuestion | None:
    """The question of ``kind`` a form matched (``m``), or None when its reference is none."""
    if kind in ("abilities", "seen"):
        return WorldQuestion(kind)
    thing = _thing(m["x"], resolve)
    if thing is None:
        return None
    if kind == "located":
        place = _thing(m["y"], resolve)
        if place is None:
            return None
        return WorldQuestion(kind, thing, place=place, relation="on" if m["rel"] == "on" else "in")
    if kind == "count":
        what = m.groupdict().get("what")
        return WorldQuestion(kind, thing, counted="things" if what in _COUNTED_THINGS else "spheres")
    return WorldQuestion(kind, thing)


def read_question(sentence: str, resolve: Resolve) -> WorldQuestion | None:
    """The question ``sentence`` asks (see the module docstring), or None when it is none of
    the forms (it goes to the command grammar). Raises what resolving its reference raises:
    :class:`~.intents.UnknownReference`, :class:`~.intents.Ambiguous`,
    :class:`~.intents.Incomplete` (each a line for the person)."""
    if len(sentence) > MAX_QUESTION_CHARS:
        return None
    text = question_words(sentence)
    if _CUT.fullmatch(text):
        raise Incomplete(_WHICH, "object")
    for kind, form in _FORMS:
        m = form.fullmatch(text)
        if m is None:
            continue
        question = _question(kind, m, resolve)
        if question is not None:
            return question
    return None


__all__ = ["MAX_QUESTION_CHARS", "Resolve", "question_words", "read_question"]
