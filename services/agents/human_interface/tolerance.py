"""Other readings of a person's line that a_hi did not understand as said: what people add to a
command and what they correct in it, taken out so that the command is read (grammar.lark stays a
grammar of commands, not of everything said around them).

:func:`readings` gives, in order, the texts to read instead of the line, each at most once:

1. **A self-correction** ("bring me the jar, sorry, I mean the bowl", "put the cup, er, the bowl
   on the table"): what follows the last marker (:data:`CORRECTION`) replaces the one noun
   phrase before the first one, or, when it begins with a verb of its own, the whole command.
   With two noun phrases before it ("put the cup on the table, sorry, the bowl") which one is
   corrected is not known: the line is not read otherwise.
2. **An opener of a follow-up** ("and then bring me the cup", "also …", "after that …"):
   left out (:data:`OPENERS`).
3. **Clauses that carry nothing a_hi needs** ("Hiya robot!", "I'm thirsty,", ", would you,
   love?"): a clause (between punctuation) is left out when it holds no word of a command
   (a verb, an object or its describing word, a deadline, an urgency, a stop, "it", "one") and
   no negation (:data:`NEGATIONS`), so that "don't, bring me the cup" is never read as a
   command. The longest run of the clauses that is kept is read first.
4. **Word order of another language** ("Put please the bowl on table", "give to me the jar"):
   a courtesy word inside the command left out, "the" put before an object named bare, "to
   me" after the verb moved to the end.

Each reading is read as a whole line is (language.py :func:`~.language.interpret`) and the
first that gives an intent is taken; the intent says what was read (``read_as``: the line and
the text read), so the person hears it. A reading never adds a word that changes what is
meant: it only leaves words out, moves "to me" or adds "the".

The work is bounded: the line is at most ``MAX_LINE_CHARS`` characters (services/runtime/
human.py), at most :data:`MAX_CLAUSES` clauses are looked at and at most :data:`MAX_READINGS`
readings given."""

from __future__ import annotations

import re
from collections.abc import Callable

from services.agents.human_interface.grammar import Word

MAX_CLAUSES = 6
"""A line of more clauses is not shortened by clause (its runs grow with the square)."""
MAX_READINGS = 8
"""At most this many other readings of one line are given."""
CORRECTION = re.compile(
    r"[\s,;.!-]*\b(?:sorry|oops|er+m?|um+|uh+|no wait|wait|i mean|i meant|or rather|rather|"
    r"actually|correction)\b[\s,;.!-]*",
    re.IGNORECASE,
)
"""A marker of a self-correction, with the punctuation around it."""
DETERMINER = re.compile(r"\b(?:the|my|a|an|that|this|your|its)\b", re.IGNORECASE)
OPENERS = re.compile(
    r"^\s*(?:and then|and also|and|then|also|after that|next|afterwards)\b[\s,]*", re.IGNORECASE
)
"""How a follow-up command may begin."""
NEGATIONS = frozenset(
    {"no", "not", "dont", "never", "nothing", "without", "instead", "except", "neither", "nor", "but", "wait"}
)
"""Words that make a clause mean something: a clause holding one is never left out."""
CLAUSE = re.compile(r"[,;.!?:]+")
MEANINGFUL = frozenset(
    {
        "NOUN", "ADJ", "PLURAL", "IT", "ONE", "CONTENTS", "DEADLINE", "WITHIN", "URGENT",
        "EVERYTHING", "STATUS", "STATUS_TAIL", "STOP", "AND", "DOWN", "UP", "OUT", "AWAY", "BACK",
        "HOME", "HERE",
    }
)  # fmt: skip
"""Kinds of word (grammar.py's tags) that carry a command's meaning; "and" or "then" begins
another request, which is not left out unread."""
COURTESY = frozenset({"PLEASE", "POLITE", "THANKS"})
"""Kinds of word a command holds only as courtesy."""

Tagger = Callable[[str], tuple[Word, ...]]
"""The tags of a text (a_hi's grammar and vocabulary: task_grammar.py ``Grammar.tag``)."""


def readings(line: str, tag: Tagger, verbs: frozenset[str]) -> list[str]:
    """The other texts to read for ``line``, best first (module docstring); ``verbs``: the
    kinds of word that begin a command (``Grammar.verb_kinds``). Empty when there is none."""
    out: list[str] = []

    def add(text: str) -> None:
        text = " ".join(text.split())
        if text and text.lower() != " ".join(line.split()).lower() and text not in out:
            out.append(text)

    corrected = self_corrected(line, tag, verbs)
    if corrected is not None:
        add(corrected)
    for base in [line, *out]:
        opened = OPENERS.sub("", base, count=1)
        if opened != base:
            add(opened)
    for base in [line, *out]:
        for kept in kept_clauses(base, tag, verbs):
            add(kept)
    for base in [line, *out]:
        add(reordered(base, tag, verbs))
    return out[:MAX_READINGS]


def _is_verb(text: str, tag: Tagger, verbs: frozenset[str]) -> bool:
    words = tag(text)
    return bool(words) and words[0].kind in verbs


def self_corrected(line: str, tag: Tagger, verbs: frozenset[str]) -> str | None:
    """``line`` with its self-correction made, or None when it has none (module docstring 1)."""
    markers = list(CORRECTION.finditer(line))
    if not markers:
        return None
    before, after = line[: markers[0].start()], line[markers[-1].end() :]
    if not before.strip() or not after.strip():
        return None
    if _is_verb(after, tag, verbs):
        return after  # a new command instead of the first
    phrases = list(DETERMINER.finditer(before))
    if len(phrases) != 1 or not DETERMINER.match(after.strip()):
        return None  # with two objects named before, which one is corrected is not known
    return before[: phrases[0].start()] + after.strip()


def _droppable(clause: str, tag: Tagger, verbs: frozenset[str]) -> bool:
    """Whether ``clause`` carries nothing of a command and no negation."""
    for word in tag(clause):
        if word.kind in MEANINGFUL or word.kind in verbs:
            return False
        if any(w in NEGATIONS for w in word.words):
            return False
    return True


def kept_clauses(line: str, tag: Tagger, verbs: frozenset[str]) -> list[str]:
    """The runs of ``line``'s clauses to read without the rest, longest first: each run whose
    left-out clauses are all :func:`_droppable` (module docstring 3)."""
    clauses = [c for c in CLAUSE.split(line) if c.strip()]
    if not 1 < len(clauses) <= MAX_CLAUSES:
        return []
    droppable = [_droppable(c, tag, verbs) for c in clauses]
    runs = []
    n = len(clauses)
    for length in range(n - 1, 0, -1):
        for start in range(n - length + 1):
            left_out = droppable[:start] + droppable[start + length :]
            if all(left_out):
                runs.append(", ".join(c.strip() for c in clauses[start : start + length]))
    return runs


def reordered(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` in the order a_hi's grammar reads (module docstring 4): courtesy words after the
    first word left out, "the" before a bare object, "VERB to me X" as "VERB X to me"."""
    words = list(tag(line))
    tail: list[str] = []
    if len(words) > 3 and words[0].kind in verbs and (words[1].kind, words[2].kind) == ("TO", "ME"):
        words, tail = [words[0], *words[3:]], ["to", "me"]
    out: list[str] = []
    for i, word in enumerate(words):
        if i > 0 and word.kind in COURTESY:
            continue
        before = words[i - 1].kind if i > 0 else ""
        if word.kind in ("NOUN", "ADJ") and before not in ("DET", "ADJ", "POSS", "NOUN", "OF"):
            out.append("the")
        out.append(word.text)
    return " ".join(out + tail)
