"""A stop, recognised before a sentence is read: a bounded, linear-time matcher of stop words.

a_hi runs :meth:`StopWords.match` over every line a person sends before anything else (before
the question to a_km, the Earley parse and any refusal); a line it matches is a stop, acted on
at once. It is a small table of phrases and a handful of rules over words, no parser: the work
is linear in the length of the line, and bounded: of a line longer than ``MAX_LINE_CHARS``
(services/runtime/human.py) it reads the first and the last that many characters, one after
the other with a clause break between, so that a stop at the start or the end of a long line is
still acted on. A stop is a stop whatever else its line holds (too many characters, control
characters: a_hi would refuse such a line otherwise).

**Words.** The line is lower-cased; apostrophes are dropped ("don't" → "dont", "that's" →
"thats", "you're" → "youre"); a run of three or more of one letter is one ("stooop" → "stop");
words are runs of letters and digits. The marks ``. , ! ? ; :``, an ellipsis, a dash and a
hyphen between spaces end a **clause**; quotes, brackets and other marks are ignored.

**A clause** is read from its start, after any **fillers** (interjections: "oh no", "hey",
"whoa"; address: "robot"; politeness and urgency: "please", "could you", "I said", "now",
"right away"):

- a **stop word** begins it: stop, cancel, halt, abort, freeze, pause, quit, cease, e-stop,
  never mind / nevermind, that's enough, enough, scratch that — whatever follows ("stop
  pouring", "stop the pour", "cancel the command", "stop what you're doing"), except "enough
  about …" (a change of topic: "anyway, enough about me");
- a **waiting word** begins it: wait, hold on, hang on, hold up, one moment, a second, stand
  still, stay put, forget it / forget about it, cut it out — followed by nothing but fillers,
  "it"/"that"/"everything", or "a minute"-like words ("wait a second", "hold on a sec"). A
  waiting word with more ("wait 5 seconds before pouring", "wait for me", "hold on to the jar")
  is no stop;
- "don't" / "do not" alone, or followed by "do …" or an action ("don't do that", "don't pour
  it", "don't touch that", "don't move");
- or the clause ends with stop, halt, freeze, abort or cancel (after "now", "please", "it", …),
  is no question ("?"), holds no negation and no condition, and does not begin with a question
  word ("oh no you're spilling it stop", "make it stop"; not "what happens if I say stop?").

A clause is the opposite, a **go-on**, when a negation comes before a stop or waiting word
("don't stop", "do not cancel it", "no need to stop", "I didn't say stop", "never stop") or it
begins with "keep going", "carry on", "go on", "continue", "go ahead". A clause is a
**command** when it begins with a command verb of a_hi's grammar (pour, bring, put, …, the
first words of the task frames: :func:`command_openings`).

**The line** is a stop when its first clause that is any of these is not a command, and the
last stop-or-go-on clause is a stop: "stop, you're spilling it", "wait, that's the wrong cup",
"you're spilling it, stop!" are stops; "pour the jar into the bowl, then wait" (a command whose
verb is no stop word), "wait, keep going", "never mind, carry on" and "don't stop" are not. A
line without any of these is no stop: interjections alone ("oh no!", "whoa", "no no no"), a
description ("you're spilling it"), a question ("is that enough?"). "hold it" is a command
(fetch it), not a stop, and "pause" is a stop (a_hi cannot resume a command). What follows a
stop in its line is not read as a command ("stop, then bring me the cup": say the command
again).

What a stop names ("pouring", "the pour") is kept in :attr:`StopMatch.names`; a_hi stops all
open commands whatever it names, and says so.
"""

from __future__ import annotations

import functools
import itertools
import re
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from services.runtime.agent import MAX_LINE_CHARS

if TYPE_CHECKING:
    from services.agents.human_interface.task_grammar import Grammar

WINDOW_CHARS = MAX_LINE_CHARS
"""Of a longer line, :meth:`StopWords.match` reads the first and the last this many characters
(services/runtime/human.py: a_hi reads no longer line)."""
NAMES_MAX_WORDS = 8
"""At most this many words of what a stop names are kept (more: "…")."""

_APOSTROPHES = str.maketrans("", "", "'’‘´`")
_TOKEN = re.compile(r"[^\W_]+|[.,!?;:…—–]|(?<![^\W_])-+(?![^\W_])")
_RUN = re.compile(r"([^\W\d_])\1{2,}")
_SEPARATORS = frozenset(".,!?;:…—–")

# roles of a phrase, in the order a tie (one phrase, several roles) is settled
NEGATION = "negation"
GO_ON = "go-on"
STRONG = "stop"
WEAK = "wait"
DONT = "dont"
COMMAND = "command"
FILLER = "filler"
TAIL = "tail"
_ORDER = (NEGATION, GO_ON, STRONG, WEAK, COMMAND, FILLER, TAIL)
_FILLER = frozenset({FILLER})
_AFTER_WAIT = frozenset({FILLER, TAIL, STRONG, WEAK})

STOP_WORDS = (
    "stop", "stop it", "stop that", "cancel", "halt", "abort", "freeze", "pause", "quit",
    "quit it", "cease", "estop", "e stop", "never mind", "nevermind", "never you mind", "nvm",
    "thats enough", "that is enough", "enough", "enough is enough", "scratch that", "call it off",
)  # fmt: skip
"""Phrases that make a clause they begin a stop, whatever follows."""
WAITING_WORDS = (
    "wait", "wait up", "hold on", "hang on", "hold up", "hang about", "one moment", "one second",
    "one sec", "one minute", "a moment", "a second", "a sec", "a minute", "just a moment",
    "stand still", "stay still", "stay put", "stay there", "forget it", "forget that",
    "forget about it", "forget about that", "forget everything", "forget", "forget about",
    "cut it out", "thatll do", "that will do", "not so fast",
)  # fmt: skip
"""Phrases that make a clause a stop when nothing but :data:`TAIL_WORDS` or fillers follow."""
TAIL_WORDS = (
    "it", "that", "this", "everything", "all", "all of it", "all that", "all of that", "it all",
    "that now", "them", "all of them", "the robot", "a minute", "a moment", "a second", "a sec",
    "a mo", "a bit", "one minute", "one moment", "one second", "one sec", "up", "there",
    "right there", "here", "right here", "what", "about it", "about that", "what you are doing",
    "what youre doing", "whatever you are doing", "whatever youre doing", "doing that",
    "doing this", "doing it", "everything you are doing", "everything youre doing",
    "all commands", "all tasks", "all of your tasks", "do that", "do it", "do this",
    "do anything", "do any of that", "the whole thing", "what i said", "a minute there",
)  # fmt: skip
"""What may follow a waiting word; also what a stop may name without naming anything in particular."""
FILLERS = (
    # interjections
    "oh", "ohh", "oh no", "no", "nope", "hey", "ah", "ahh", "argh", "ugh", "uh", "uh oh", "um",
    "hmm", "er", "erm", "oops", "whoops", "whoa", "woah", "wow", "yikes", "ouch", "ow", "eek",
    "damn", "dammit", "shit", "crap", "oh my god", "omg", "oh god", "god", "jeez", "gosh",
    "careful", "be careful", "look out", "watch out", "sorry", "excuse me",
    "ok", "okay", "alright", "all right", "right", "well", "so", "and", "but", "actually", "yes",
    "yeah", "yep", "seriously", "emergency", "guys", "dude", "man", "mate", "buddy",
    "for gods sake", "for heavens sake", "for the love of god", "again", "already",
    # address and politeness
    "robot", "velma", "please", "pls", "plz", "kindly", "just", "thanks", "thank you", "ta",
    "can you", "could you", "would you", "will you", "cant you", "wont you", "why dont you",
    "why wont you", "can you please", "could you please", "would you please", "i said",
    "i say", "i told you to", "i want you to", "i need you to", "i would like you to",
    "id like you to", "you need to", "you have to", "you must", "you should", "you better",
    "youd better", "you gotta", "you can", "lets", "let us", "go", "go and", "then", "now then",
    "try to",
    # urgency
    "now", "right now", "immediately", "at once", "asap", "quick", "quickly", "urgently",
    "straight away", "right away", "this instant", "this minute", "first",
)  # fmt: skip
"""Words around a stop that say nothing about what to do."""
NEGATIONS = (
    "dont", "do not", "dont you dare", "dont you", "i dont want you to", "i do not want you to",
    "never", "not", "no need to", "theres no need to", "there is no need to", "you dont have to",
    "you dont need to", "you do not have to", "you neednt", "neednt", "didnt", "did not",
    "i didnt say", "i did not say", "cant", "cannot", "can not", "you cant", "you cannot",
    "wont", "shouldnt", "should not", "you shouldnt", "mustnt", "must not", "without",
    "dont ever", "do not ever",
)  # fmt: skip
"""Words that make a stop or waiting word after them a go-on ("don't stop")."""
DONT_WORDS = frozenset(
    {"dont", "do not", "dont you dare", "dont you", "i dont want you to", "i do not want you to"}
)
"""The negations that are a stop when alone or before an action ("don't!", "don't do that")."""
DONT_ACTIONS = (
    "do", "touch", "move", "go", "continue", "keep", "spill", "tip", "let", "even", "drop",
    "knock", "break",
)  # fmt: skip
"""Besides the command verbs: what after "don't" makes it a stop."""
GO_ON_WORDS = (
    "keep going", "keep on", "keep at it", "keep pouring", "keep it up", "carry on", "go on",
    "go ahead", "continue", "proceed", "resume", "as you were", "on you go",
)  # fmt: skip
"""Phrases that begin a go-on clause."""
END_WORDS = frozenset({"stop", "halt", "freeze", "abort", "cancel"})
"""The words that make a stop of a clause they end."""
END_FILLERS = frozenset(
    {"now", "please", "already", "immediately", "robot", "velma", "it", "that", "this", "everything",
     "all", "then", "again", "thanks", "ok", "okay", "right", "quickly", "asap", "too", "there"}
)  # fmt: skip
"""What may come after a stop word that ends a clause ("… stop it now")."""
QUESTION_WORDS = frozenset(
    {"what", "why", "how", "when", "where", "who", "which", "did", "does", "do", "is", "are", "was",
     "were", "if", "whether", "should", "shall", "can", "could", "would", "will", "may", "might"}
)  # fmt: skip
"""Words that, beginning a clause, keep a stop word at its end from making it a stop."""
NEGATION_WORDS = frozenset(
    {"dont", "not", "never", "didnt", "cant", "cannot", "wont", "shouldnt", "mustnt", "without",
     "doesnt", "isnt", "neednt", "wouldnt", "couldnt", "nothing", "noone", "nobody"}
)  # fmt: skip
CONDITION_WORDS = frozenset(
    {"if", "when", "whenever", "until", "till", "unless", "before", "after", "once", "will", "would",
     "should", "could", "can", "might", "may", "whether"}
)  # fmt: skip
"""Words that keep a stop word at the end of their clause from making it a stop ("… stop
when the bowl is full" is a command's condition, no stop now)."""


@dataclass(frozen=True)
class StopMatch:
    """A line that asks to stop: ``said`` the stop phrase as matched ("stop", "hold on",
    "dont"), ``names`` what the stop names ("pouring", "the pour"; "" when nothing in
    particular: "stop", "stop everything", "cancel that")."""

    said: str
    names: str = ""


def _tokens(text: str) -> Iterator[str]:
    """The words of ``text`` (lower case, no apostrophes, letter runs shortened) and its clause
    marks, in order; linear in ``len(text)``."""
    for m in _TOKEN.finditer(text.lower().translate(_APOSTROPHES)):
        word = m.group()
        if word[0] == "-":
            yield "—"
        elif len(word) > 2 and not word.isdigit():
            yield _RUN.sub(r"\1", word)
        else:
            yield word


def _clauses(tokens: Iterable[str]) -> Iterator[tuple[list[str], str]]:
    """Clauses as (words, the mark that ends them: "" at the end of the line)."""
    words: list[str] = []
    for token in tokens:
        if token in _SEPARATORS:
            if words:
                yield words, token
                words = []
        else:
            words.append(token)
    if words:
        yield words, ""


class StopWords:
    """The matcher: the phrase tables above and the command verbs (``commands``, phrases
    of lower-case words: :func:`command_openings`). :meth:`match` reads a line;
    :attr:`examined` counts the phrase look-ups it has made (its work, for tests)."""

    def __init__(self, commands: Iterable[str] = (), *, window: int = WINDOW_CHARS) -> None:
        tables: dict[str, Iterable[str]] = {
            NEGATION: NEGATIONS,
            GO_ON: GO_ON_WORDS,
            STRONG: STOP_WORDS,
            WEAK: WAITING_WORDS,
            COMMAND: commands,
            FILLER: FILLERS,
            TAIL: TAIL_WORDS,
        }
        roles: dict[tuple[str, ...], set[str]] = {}
        for role, phrases in tables.items():
            for phrase in phrases:
                words = tuple(phrase.split())
                if words:
                    roles.setdefault(words, set()).add(role)
        self.phrases: Mapping[tuple[str, ...], tuple[str, ...]] = {
            words: tuple(r for r in _ORDER if r in rs) for words, rs in roles.items()
        }
        """Each phrase's roles, in the order a tie is settled."""
        self.longest = max(len(w) for w in self.phrases)
        self.window = window
        self.examined = 0
        """Phrase look-ups made so far (each at most :attr:`longest` dictionary probes)."""

    # ---- phrases ---------------------------------------------------------------------------
    def _at(self, words: list[str], i: int, wanted: frozenset[str] | None = None) -> tuple[str, int]:
        """The longest phrase at ``words[i]`` with a role in ``wanted`` (None: any): its first
        such role and its length in words; ("", 0) when there is none."""
        self.examined += 1
        for n in range(min(self.longest, len(words) - i), 0, -1):
            roles = self.phrases.get(tuple(words[i : i + n]))
            if roles:
                for role in roles:
                    if wanted is None or role in wanted:
                        return role, n
        return "", 0

    def _skip(self, words: list[str], i: int, over: frozenset[str]) -> int:
        """The index after the phrases from ``i`` on whose longest reading has a role in ``over``."""
        while i < len(words):
            role, n = self._at(words, i)  # the longest reading: "no need to" is no filler "no"
            if role not in over:
                return i
            i += n
        return i

    def _head(self, words: list[str], i: int) -> StopMatch | None:
        """The stop that ``words[i:]`` says: a stop word, or a waiting word followed by nothing
        but :data:`TAIL_WORDS` and fillers; else None."""
        role, n = self._at(words, i, frozenset({STRONG, WEAK}))
        if words[i : i + n] == ["enough"] and words[i + 1 : i + 2] == ["about"]:
            return None  # "enough about me": a change of topic
        if role == STRONG:
            return StopMatch(" ".join(words[i : i + n]), self._names(words, i + n))
        if role == WEAK and self._skip(words, i + n, _AFTER_WAIT) == len(words):
            return StopMatch(" ".join(words[i : i + n]))
        return None

    # ---- a clause --------------------------------------------------------------------------
    def _clause(self, words: list[str], mark: str) -> tuple[str, StopMatch | None]:
        """(kind, match): kind "" (none of these), STRONG (a stop), GO_ON or COMMAND."""
        i = self._skip(words, 0, _FILLER)
        if i == len(words):
            return "", None
        role, n = self._at(words, i)
        if role == GO_ON:
            return GO_ON, None
        if role == NEGATION:
            j = self._skip(words, i + n, _FILLER)
            if j < len(words) and self._head(words, j) is not None:
                return GO_ON, None  # "don't stop", "no need to wait"
            if " ".join(words[i : i + n]) in DONT_WORDS:
                if j == len(words):
                    return STRONG, StopMatch("dont")
                action, _ = self._at(words, j, frozenset({COMMAND}))
                if action or words[j] in DONT_ACTIONS:
                    return STRONG, StopMatch("dont", self._names(words, j))
            return "", None
        if role in (STRONG, WEAK):
            head = self._head(words, i)
            if head is not None:
                return STRONG, head
        command, _ = self._at(words, i, frozenset({COMMAND}))
        if command:
            return COMMAND, None
        return self._ends_with_stop(words, i, mark)

    def _ends_with_stop(self, words: list[str], i: int, mark: str) -> tuple[str, StopMatch | None]:
        """A clause that ends with a stop word: "… you're spilling it, stop" (module docstring)."""
        if mark == "?" or words[i] in QUESTION_WORDS:
            return "", None
        end = len(words)
        while end > i and words[end - 1] in END_FILLERS:
            end -= 1
        if end <= i or words[end - 1] not in END_WORDS:
            return "", None
        for k in range(i, end):
            self.examined += 1
            word = words[k]
            if word in NEGATION_WORDS or word in CONDITION_WORDS:
                return "", None
            if word == "need" and words[k - 1 : k] == ["no"]:  # "there is no need to …"
                return "", None
        return STRONG, StopMatch(words[end - 1])

    def _names(self, words: list[str], j: int) -> str:
        """What a stop names in ``words[j:]``: "" when only fillers and "it"/"everything"-like
        words follow, else those words (at most :data:`NAMES_MAX_WORDS`)."""
        j = self._skip(words, j, _FILLER)
        if self._skip(words, j, _AFTER_WAIT) == len(words):
            return ""
        end = len(words)
        while end > j and words[end - 1] in END_FILLERS:
            end -= 1
        named = words[j:end]
        more = " …" if len(named) > NAMES_MAX_WORDS else ""
        return " ".join(named[:NAMES_MAX_WORDS]) + more

    # ---- a line ----------------------------------------------------------------------------
    def _read(self, tokens: Iterable[str]) -> StopMatch | None:
        first = ""
        stop: StopMatch | None = None
        for words, mark in _clauses(tokens):
            kind, match = self._clause(words, mark)
            if not kind:
                continue
            if not first:
                first = kind
                if kind == COMMAND:
                    return None
            if kind == STRONG:
                stop = match
            elif kind == GO_ON:
                stop = None
        return stop

    def match(self, text: str) -> StopMatch | None:
        """The stop ``text`` asks for, or None (the rule: the module docstring). A line longer
        than :attr:`window` characters is read as its first and its last ``window`` characters
        (each without a word cut in two), one clause after the other. Work: linear in
        ``min(len(text), 2 * window)``; never raises."""
        if len(text) <= self.window:
            return self._read(_tokens(text))
        head, tail = text[: self.window], text[-self.window :]
        if head[-1].isalnum() and text[self.window].isalnum():  # a word cut in two
            head = head[: max(head.rfind(" "), 0)]
        if tail[0].isalnum() and text[-self.window - 1].isalnum():
            tail = tail[tail.find(" ") + 1 :] if " " in tail else ""
        return self._read(itertools.chain(_tokens(head), ["."], _tokens(tail)))


_VERB_CLASSES = frozenset({"POUR", "EMPTY", "FILL", "BRING", "TAKE", "PUT", "RETURN", "HAND"})
"""Word classes of grammar.lark (grammar.py ``WORDS``) that begin a command. Not the wishes
(``WANT``, ``HAVE``): "I want it to stop" is a stop, and "I'd like the jar, wait" stops too."""


def command_openings(grammar: Grammar) -> frozenset[str]:
    """The phrases that begin a command in ``grammar``: the verbs of grammar.lark's frames (the
    word classes of :data:`_VERB_CLASSES`) and the first word of each task frame (tasks.toml)."""
    verbs = {" ".join(words) for words, kind in grammar.phrases.items() if kind in _VERB_CLASSES}
    for saying in grammar.words.sayings:
        for frame in saying.frames:
            first = frame.items[0]
            if first.islower():  # a word, not a slot
                verbs.add(first)
    return frozenset(verbs)


@functools.cache
def default_stop_words() -> StopWords:
    """The matcher with the command verbs of a_hi's default grammar (grammar.lark, tasks.toml)."""
    from services.agents.human_interface.task_grammar import default_grammar

    return StopWords(command_openings(default_grammar()))


__all__ = [
    "STOP_WORDS",
    "WAITING_WORDS",
    "WINDOW_CHARS",
    "StopMatch",
    "StopWords",
    "command_openings",
    "default_stop_words",
]
