"""Parsing a sentence with a_hi's grammar (grammar.lark, lark's Earley parser).

A sentence is normalised (:func:`normalise`: lower case, punctuation and apostrophes dropped,
a possessive "'s" split off, decimal points and a minus sign before a number kept), then
**tagged**: at each position the longest phrase known wins, a closed-class phrase
(:data:`PHRASES`, from :data:`WORDS`, plus the words of the task frames task_grammar.py adds)
before a noun or adjective of the :class:`~.vocabulary.Vocabulary` of the same length.
"within N seconds|minutes|hours" and "in N …" become one ``DEADLINE`` token (its value in
seconds, N digits or a number word of :data:`NUMBERS`; a negative or zero value is kept for
language.py to refuse), "within" not followed by one ``WITHIN``, and so is "N unit max" ("two
minutes max", "ten seconds tops"); a first word "now" before others (after an opener at
most: "okay", "so", an address) is a discourse marker ("Now, put the bowl away", "okay now
pour …"), not an urgency; after "would you mind" (or
"how about") a gerund of a closed-class verb is read as the verb ("pouring" as "pour"); a plural of a known
noun is ``PLURAL``; a word a_km does not use but near in meaning to a describing word it uses
("tiny" to "small", similarity.py) is ``ADJ`` (meaning.py reads it as the one the thing has);
any other word is ``WORD``, which no rule accepts, so that the parse stops
at it and :class:`ParseFailure` names it. A run of courtesy words of one class
(:data:`FOLDED`: "please please", "thanks, thank you") is one token: its repeats mean nothing
more, and each token costs the parser a step.

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

from services.agents.human_interface.similarity import near_any
from services.agents.human_interface.vocabulary import Vocabulary

GRAMMAR_FILE = Path(__file__).with_name("grammar.lark")
FOLDED = frozenset({"PLEASE", "THANKS", "ADDRESS"})
"""Word classes whose run in a sentence is tagged as one token (see the module docstring)."""
MAX_READINGS = 64
"""At most this many readings of one sentence are weighed (a short command has a handful)."""

WORDS: dict[str, tuple[str, ...]] = {
    # polite framing (ASK also after a command, as a tag question), address, thanks
    "POLITE": (
        "could you maybe",
        "would you mind",
        "how about",
        "what about",
        "why dont you",
        "why not",
        "do you mind",
        "i want you to",
        "i need you to",
        "i would like you to",
        "i should like you to",
        "id like you to",
        "id love you to",
        "i wish you would",
        "do you think you could",
        "i wonder if you could",
        "would you be so kind as to",
        "would you be so kind and",
        "be so kind and",
        "be a dear and",
        "be a star and",
        "be a love and",
        "be an angel and",
        "be a darling and",
        "be a sweetheart and",
        "be a pal and",
        "be a good robot and",
        "do me a favour and",
        "do me a favor and",
        "would it be possible to",
        "would it be possible for you to",
        "is it possible to",
        "is possible to",
        "is it possible for you to",
        "are you able to",
        "id appreciate it if you could",
        "i would appreciate it if you could",
        "it would be great if you could",
        "it would be nice if you could",
        "id love it if you could",
        "go and",
        "go",
        "come and",
        "hey",
        "hey there",
        "so",
        "well",
        "um",
        "uh",
        "erm",
        "hi",
        "hi there",
        "hello",
        "hello there",
        "now then",
        "then",
        "lets",
        "you should",
        "i would like to ask you to",
        "you can",
        "try to",
        "try and",
        "see if you can",
        "see whether you can",
    ),
    "ASK": (
        "could you",
        "can you",
        "would you",
        "will you",
        "wont you",
        "if you could",
        "if you would",
        "if you can",
        "if you dont mind",
        "if it is not too much trouble",
        "if its not too much trouble",
        "if it isnt too much trouble",
        "if you wouldnt mind",
        "if youd",
        "if you please",
        "if youd be so good",
        "if youd be so kind",
        "if you would be so good",
        "if you would be so kind",
        "if possible",
        "ok",
        "okay",
    ),
    "PLEASE": ("please", "kindly", "pls", "plz", "possibly", "just"),
    "THANKS": (
        "thanks",
        "thank you",
        "thank you very much",
        "thank you so much",
        "thanks a lot",
        "many thanks",
        "cheers",
        "ta",
        "that would be great",
        "that would be lovely",
        "that would be nice",
        "that would be helpful",
        "thatd be great",
        "thatd be lovely",
        "id appreciate it",
        "i would appreciate it",
        "when you have a moment",
        "when you get a chance",
        "when you get a sec",
        "when you get a second",
        "when you get a minute",
        "when you have a sec",
        "when you have a second",
        "when you have a minute",
        "when you can",
        "for me",
        "please and thank you",
        "please and thanks",
    ),
    "ADDRESS": (
        "robot",
        "velma",
        "dear",
        "dearie",
        "love",
        "honey",
        "sweetie",
        "sweetheart",
        "darling",
        "hun",
        "babe",
        "mate",
        "buddy",
        "pal",
        "bro",
        "dude",
        "man",
        "fam",
        "bruh",
        "lol",
        "haha",
        "i guess",
        "i suppose",
        "or something",
        "i think",
        "i reckon",
        "reckon",
        "come on",
        "hmm",
        "hmmm",
        "mm",
        "ah",
        "oh",
        "ah yes",
        "oh yes",
        "let me see",
        "let me think",
        "lets see",
        "no worries",
        "na",
        "innit",
        "eh",
        "yeah",
        "firstly",
        "first of all",
        "do one thing",
        "do the needful and",
    ),
    # (a word of address, or a word said around a command that carries nothing: "… lol")
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
        "as quickly as possible",
        "as quickly as you can",
        "as fast as possible",
        "as fast as you can",
        "as quick as you can",
        "as soon as you can",
        "quick as you can",
        "fast as you can",
        "be quick",
        "be quick about it",
        "make it quick",
        "make it snappy",
        "step on it",
        "get a move on",
        "on the double",
        "chop chop",
        "pronto",
        "sharpish",
        "promptly",
        "swiftly",
        "speedily",
        "rapidly",
        "fastly",
        "hastily",
        "sharp sharp",
        "quick quick",
        "fast fast",
        "quick smart",
        "stat",
        "in a jiffy",
        "lickety split",
        "double time",
        "real quick",
        "really quick",
        "double quick",
        "in a hurry",
        "im in a hurry",
        "i am in a hurry",
        "no time to lose",
        "theres no time to lose",
        "this instant",
        "right this minute",
        "right this second",
        "its an emergency",
        "this is an emergency",
        "emergency",
        "its important",
        "this is important",
        "as a matter of urgency",
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
        "how are you getting along",
        "how are you getting along with it",
        "how are you getting on with it",
        "how are you doing",
        "what is the status",
        "whats the status",
        "what is the state",
        "whats the state",
        "what is your progress",
        "whats your progress",
        "what is the progress",
        "whats the progress",
        "how is the progress",
        "hows the progress",
        "status update",
        "give me an update",
        "an update",
        "any update",
        "any updates",
        "any news",
        "any progress",
        "update me",
        "progress report",
        "report your progress",
        "report progress",
        "show me the status",
        "show the status",
        "tell me the status",
        "how are things going",
        "how are things",
        "hows everything going",
        "how is everything going",
        "is everything going ok",
        "is everything ok",
        "is everything alright",
        "how is it coming along",
        "hows it coming along",
        "hows it coming",
        "how far along are you",
        "how far have you got",
        "what stage are you at",
        "are you finished",
        "are you nearly finished",
        "are you almost finished",
        "are you nearly done",
        "are you almost done",
        "have you finished",
        "have you finished it",
        "did you finish",
        "did you finish it",
        "is it done",
        "is it finished",
        "is it ready",
        "is the task done",
        "is the task finished",
        "are you still working",
        "are you still working on it",
        "are you still busy",
        "how long",
        "how much longer",
        "how much longer will you be",
        "any progress on that",
        "any progress on it",
        "any progress with that",
        "any progress with it",
        "any news on that",
        "any news on it",
        "how much longer will it take",
        "how much longer will it be",
        "how long will it take",
        "how long will you take",
        "how long will you be",
        "how long is it going to take",
        "how long until you are done",
        "how long until youre done",
        "how long till you are done",
        "how long till youre done",
        "when will you be done",
        "when will you be finished",
        "when will it be done",
        "when will it be ready",
        "whats taking so long",
        "what is taking so long",
        "why is it taking so long",
    ),
    # after a status question: "are you done yet?", "what are you doing at the moment?"
    "STATUS_TAIL": (
        "yet",
        "so far",
        "already",
        "by now",
        "at the moment",
        "currently",
        "at this point",
    ),
    # verbs of the tasks whose frames are written in grammar.lark (the others: tasks.toml)
    "POUR": ("pour", "tip", "decant", "transfer", "dump"),
    "EMPTY": ("empty",),
    "FILL": ("fill", "refill"),
    "BRING": ("bring", "fetch", "get", "grab", "carry", "retrieve"),
    "TAKE": ("take", "remove"),
    "PUT": (
        "put",
        "place",
        "set",
        "leave",
        "lay",
        "move",
        "stand",
        "stick",
        "position",
        "pop",
        "rest",
        "plonk",
        "shove",
        "bung",
        "whack",
        "keep",
    ),
    # (not "throw", "toss" or "chuck": "throw it away", "chuck it out" mean to get rid of it)
    "RETURN": ("return", "store", "stow", "replace", "stash"),
    "HAND": ("hand", "give", "pass"),
    # wishes: "I would like the cup" (brought), "can I have the cup" (handed over)
    "WANT": (
        "i want",
        "i would like",
        "i should like",
        "id like",
        "i need",
        "i would love",
        "id love",
        "i want to have",
        "i would like to have",
        "id like to have",
        "i could use",
    ),
    "HAVE": (
        "can i have",
        "could i have",
        "may i have",
        "can i get",
        "could i get",
        "can we have",
        "could we have",
        "may we have",
        "can i please have",
        "could i please have",
        "may i please have",
        "could i trouble you for",
        "can i trouble you for",
        "may i trouble you for",
    ),
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
        "where it lives",
        "where it usually goes",
        "where it is kept",
        "where it is usually kept",
    ),
    "ME": ("me", "us"),
    "HERE": ("here",),
    # a place a_hi cannot see: asked back ("Where should I put the cup?"), not guessed
    "VAGUE": (
        "there",
        "over there",
        "in there",
        "on there",
        "out there",
        "somewhere",
        "somewhere else",
        "some place",
        "anywhere",
        "elsewhere",
        "wherever",
        "wherever you like",
        "wherever you want",
        "anywhere you like",
        "that way",
        "over that way",
    ),
    "FOR": ("for",),
    "OF": ("of",),
    "AND": ("and", "and then", "and also"),
    "REL": ("that is", "thats", "which is", "that stands", "standing", "sitting", "that sits"),
    # references
    "IT": ("it", "them", "this one", "that one"),
    "THAT": ("that", "this"),
    "ONE": (
        "one",
        "thing",
        "thingy",
        "thingamajig",
        "thingamabob",
        "whatsit",
        "whatchamacallit",
        "object",
        "item",
    ),
    "CONTENTS": (
        "contents",
        "content",
        "what is in",
        "whats in",
        "what is inside",
        "whats inside",
        "everything in",
        "everything inside",
        "everything from",
    ),
    "DET": ("the", "a", "an", "my", "your", "our", "these", "those", "some", "all the", "all of the"),
    "POSS": ("s",),  # "the jar's": normalise() splits a possessive "'s" off its noun
}
"""Closed-class words and fixed phrases → word class (a terminal of grammar.lark). Object,
place and adjective words are not here: they come from the vocabulary (the ontology); the
words of the frames in tasks.toml are added by task_grammar.py."""

VERBS = frozenset(
    ("POUR", "EMPTY", "FILL", "BRING", "TAKE", "PUT", "RETURN", "HAND", "WANT", "HAVE", "STOP", "STATUS")
)
"""The word classes a request of grammar.lark begins with (its verbs, stop, status); a sentence
with none of them is no new request (an answer to a question, if anything)."""

_ONES = ("one", "two", "three", "four", "five", "six", "seven", "eight", "nine")
_TEENS = ("ten", "eleven", "twelve", "thirteen", "fourteen", "fifteen", "sixteen", "seventeen",
          "eighteen", "nineteen")  # fmt: skip
_TENS = {"twenty": 20, "thirty": 30, "forty": 40, "fifty": 50}
NUMBERS: dict[str, float] = {
    "zero": 0, "a": 1, "an": 1, "half a": 0.5, "half an": 0.5, "a quarter of an": 0.25,
    "a quarter of a": 0.25, "quarter of an": 0.25, "a couple of": 2, "one and a half": 1.5,
    "sixty": 60, "ninety": 90,
    **{w: n for n, w in enumerate(_ONES, 1)},
    **{w: n for n, w in enumerate(_TEENS, 10)},
    **{t: n for t, n in _TENS.items()},
    **{f"{t} {o}": n + k for t, n in _TENS.items() for k, o in enumerate(_ONES, 1)},
}  # fmt: skip
"""Number words of a deadline ("within twenty five minutes", "in half an hour"): zero to sixty,
"a"/"an" (one), halves and quarters; digits are read as numbers ("within 1.5 min")."""
_LONGEST_NUMBER = max(len(k.split()) for k in NUMBERS)
UNITS = {
    "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
    "min": 60.0, "mins": 60.0, "minute": 60.0, "minutes": 60.0,
    "h": 3600.0, "hr": 3600.0, "hrs": 3600.0, "hour": 3600.0, "hours": 3600.0,
}  # fmt: skip
_DEADLINE_WORDS = ("within", "in")
"""A deadline begins with one of these: "within 2 minutes", "in five minutes"."""
_DEADLINE_FILLERS = (("the", "next"), ("less", "than"), ("under",), ("no", "more", "than"), ("at", "most"))
"""Words that may come between the first word of a deadline and its number ("within the next
ten seconds", "in under a minute")."""
_TIME_STARTS = frozenset({*_DEADLINE_WORDS, *NUMBERS, "you"})
"""Words a deadline may begin with (besides a numeral)."""
_BOUND_WORDS = (("max",), ("maximum",), ("tops",), ("at", "most"), ("at", "the", "most"), ("or", "less"))
"""Words after a duration that make it a deadline: "two minutes max"."""
_NUMERAL = re.compile(r"-?\d+(?:\.\d+)?")
_CONTRACTED = frozenset(
    ("what", "that", "it", "let", "where", "how", "here", "there", "who", "he", "she", "this", "everything")
)
"""Words whose "'s" is "is", "has" or "us" ("what's", "let's"): joined to them ("whats"), not
split off as a possessive."""
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
    """The words of ``sentence``: lower case; a possessive "'s" a word of its own, ``s`` ("the
    jar's" → "the", "jar", "s"), other apostrophes dropped ("what's" → "whats", "don't" →
    "dont"); other punctuation a space; decimal points kept ("1.5") and a minus sign directly
    before a number ("-5"); hyphens between words a space ("twenty-five"); a short form of
    texting or speech as its words (:data:`SHORT_FORMS`: "u" → "you", "gimme" → "give me"), an
    expletive left out ("the damn cup")."""
    text = sentence.lower().replace("’", "'").replace("‘", "'").replace("−", "-")
    text = re.sub(r"([a-z0-9]+)'s\b", lambda m: m[1] + ("s" if m[1] in _CONTRACTED else " s"), text)
    text = text.replace("'", "")
    text = re.sub(r"[^a-z0-9.\s-]+", " ", text)
    text = re.sub(r"(?<![0-9])\.|\.(?![0-9])", " ", text)
    text = re.sub(r"(?<!\S)-+(?=[0-9])", "-", text)
    text = re.sub(r"-(?![0-9])|(?<=\S)-", " ", text)
    return [w for word in text.split() for w in SHORT_FORMS.get(word, (word,))]


EXPLETIVES = (
    "damn", "damned", "darn", "dang", "bloody", "blooming", "flipping", "freaking", "frigging",
    "friggin", "fricking", "effing", "goddamn", "goddamned", "blasted", "stupid",
)  # fmt: skip
"""Words said in impatience that carry nothing ("bring the damn cup"): left out of the words."""


SHORT_FORMS: dict[str, tuple[str, ...]] = {
    short: tuple(words.split())
    for short, words in {
        "u": "you", "ya": "you", "ur": "your", "yer": "your", "r": "are", "n": "and", "da": "the",
        "tha": "the", "wat": "what", "wot": "what", "cud": "could", "wud": "would", "thx": "thanks",
        "thnx": "thanks", "thanx": "thanks", "ty": "thank you", "tysm": "thank you so much",
        "gimme": "give me", "lemme": "let me", "wanna": "want to", "gotta": "got to",
        "rn": "right now", "pls": "please", "plz": "please", "youd": "you would", "cuz": "because",
        "coz": "because", "cos": "because",
        **dict.fromkeys(EXPLETIVES, ""),
    }.items()
}  # fmt: skip
"""Short forms people type or say, read as the words they stand for; an expletive
(:data:`EXPLETIVES`) as none."""


def _deadline(words: list[str], i: int) -> tuple[int, float] | None:
    """At ``words[i]`` in :data:`_DEADLINE_WORDS`: (words used, seconds) of "within [the next]
    N unit" (N a numeral, possibly negative, or a number word of :data:`NUMBERS`), else None."""
    j = i + 1
    for filler in _DEADLINE_FILLERS:
        if tuple(words[j : j + len(filler)]) == filler:
            j += len(filler)
            break
    found = _duration(words, j)
    if found is None:
        return None
    end = found[0]  # "within five minutes at most": the bound words belong to it
    end += next((len(b) for b in _BOUND_WORDS if tuple(words[end : end + len(b)]) == b), 0)
    return end - i, found[1]


def _time_at(words: list[str], i: int) -> tuple[int, float] | None:
    """At ``words[i]``: (words used, seconds) of a deadline said in any of the ways the tagger
    reads ("within N unit", "in N unit", "N unit max", "you have N unit to"), else None."""
    if words[i] == "you":
        return _given_time(words, i)
    return _deadline(words, i) if words[i] in _DEADLINE_WORDS else _bound_after(words, i)


_GIVEN = (("you", "have", "got"), ("you", "have"), ("you", "got"), ("you", "get"))
"""How a time given for a command begins: "you have two minutes to pour …"."""


def _given_time(words: list[str], i: int) -> tuple[int, float] | None:
    """At ``words[i]``: (words used, seconds) of "you have|got N unit [to]" ("u got 30 secs to
    pour the beans …": a deadline before the command), else None."""
    for given in _GIVEN:
        if tuple(words[i : i + len(given)]) == given:
            found = _duration(words, i + len(given))
            if found is not None:
                end = found[0] + (words[found[0] : found[0] + 1] == ["to"])
                return end - i, found[1]
    return None


def _bound_after(words: list[str], i: int) -> tuple[int, float] | None:
    """At ``words[i]``: (words used, seconds) of "N unit max" ("two minutes max", "5 minutes
    at most", "ten seconds tops": :data:`_BOUND_WORDS` after the duration), else None."""
    found = _duration(words, i)
    if found is None:
        return None
    j, seconds = found
    for bound in _BOUND_WORDS:
        if tuple(words[j : j + len(bound)]) == bound:
            return j + len(bound) - i, seconds
    return None


def _duration(words: list[str], j: int) -> tuple[int, float] | None:
    """At ``words[j]``: (the index after it, seconds) of "N unit", else None."""
    amount: float | None = None
    for n in range(_LONGEST_NUMBER, 0, -1):
        key = " ".join(words[j : j + n])
        if len(words[j : j + n]) == n and key in NUMBERS:
            amount, j = float(NUMBERS[key]), j + n
            break
    else:
        if j < len(words) and _NUMERAL.fullmatch(words[j]):
            amount, j = float(words[j]), j + 1
    if amount is None or j >= len(words) or words[j] not in UNITS:
        return None
    return j + 1, amount * UNITS[words[j]]


def _base(word: str, phrases: Mapping[tuple[str, ...], str]) -> str | None:
    """The verb of the gerund ``word`` when it is a closed-class word: "pouring" → "pour",
    "taking" → "take", "putting" → "put", "emptying" → "empty"; else None."""
    if not word.endswith("ing") or len(word) < 5:
        return None
    stem = word[:-3]
    for base in (stem, stem + "e", stem[:-1] if stem[-1] == stem[-2] else ""):
        if base and (base,) in phrases:
            return base
    return None


def tag(
    sentence: str, vocabulary: Vocabulary, phrases: Mapping[tuple[str, ...], str] = PHRASES
) -> tuple[Word, ...]:
    """The tokens of ``sentence`` (see the module docstring); ``phrases``: the closed-class
    phrases (default :data:`PHRASES`; a_hi's grammar adds the words of its task frames)."""
    words = normalise(sentence)
    read = list(words)  # the words as looked up: a gerund after "would you mind" as its verb
    lexicon: dict[tuple[str, ...], str] = {}
    for adj in vocabulary.adjectives:
        lexicon[(adj,)] = "ADJ"
    compared = _comparatives(vocabulary.adjectives)
    for noun in vocabulary.nouns:
        lexicon[noun] = "NOUN"
        if len(noun) == 1 and not noun[0].endswith("s"):
            lexicon.setdefault((noun[0] + "s",), "PLURAL")
            lexicon.setdefault((noun[0] + "es",), "PLURAL")
    lexicon.update(phrases)  # a closed-class phrase wins over a vocabulary word of the same length
    longest = max((len(p) for p in lexicon), default=1)
    out: list[Word] = []
    gerund = False  # after "would you mind": the next gerund of a closed-class verb is that verb
    i = 0
    while i < len(words):
        if gerund and (base := _base(read[i], phrases)) is not None:
            read[i], gerund = base, False
        if read[i] in _TIME_STARTS or _NUMERAL.fullmatch(read[i]):
            found = _time_at(read, i)
            if found is not None:
                n, seconds = found
                out.append(Word("DEADLINE", tuple(words[i : i + n]), len(out), seconds))
                i += n
                continue
            if read[i] == "within" or (
                read[i] in _DEADLINE_WORDS and i + 1 < len(read) and _NUMERAL.fullmatch(read[i + 1])
            ):
                out.append(Word("WITHIN", (words[i],), len(out)))  # a deadline not understood
                i += 1
                continue
        for n in range(min(longest, len(words) - i), 0, -1):
            phrase = tuple(read[i : i + n])
            if phrase in lexicon:
                kind = lexicon[phrase]
                if kind in FOLDED and out and out[-1].kind == kind:  # "please please": one token
                    out[-1] = Word(kind, out[-1].words + tuple(words[i : i + n]), out[-1].index)
                else:
                    out.append(Word(kind, tuple(words[i : i + n]), len(out)))
                gerund = gerund or (lexicon[phrase] == "POLITE" and phrase[-1] in ("mind", "about"))
                i += n
                break
        else:
            base = compared.get(read[i])  # "the smaller bowl": the small one
            if base is None and read[i].isalpha() and near_any(read[i], vocabulary.adjectives):
                base = words[i]  # "the tiny bowl": a describing word meaning one a_km uses (meaning.py)
            out.append(Word("ADJ", (base,), len(out)) if base else Word("WORD", (words[i],), len(out)))
            i += 1
    _discourse_now(out)
    return tuple(out)


OPENING_KINDS = frozenset({"ASK", "POLITE", "ADDRESS", "AND", "PLEASE"})
OPENING_WORDS = frozenset({"alright", "right", "well", "okay", "ok", "so", "oh"})


def _discourse_now(out: list[Word]) -> None:
    """Retag, in place, a first "now" before other words (after openers only) as a discourse
    marker ("(Okay,) now, put the bowl away"), not an urgency."""
    first = next((j for j, w in enumerate(out) if not _opening(w)), len(out))
    if first < len(out) - 1 and out[first].kind == "URGENT" and out[first].words == ("now",):
        out[first] = Word("POLITE", out[first].words, first)


def _opening(word: Word) -> bool:
    """Whether ``word`` may open a line before its first "now" ("okay", "so", "robot", "and")."""
    return word.kind in OPENING_KINDS or word.words[0] in OPENING_WORDS


@functools.cache
def _comparatives(adjectives: frozenset[str]) -> dict[str, str]:
    """The comparative and superlative of each short one of ``adjectives`` ("small": "smaller",
    "smallest"; "big": "bigger", "biggest"; "large": "larger", "largest"; "tiny": "tinier"),
    mapped to it: the person compares with the words a_km describes things with. "The smaller
    bowl" is read as "the small bowl" (a simplification: not compared with the others)."""
    out: dict[str, str] = {}
    for adj in (a for a in adjectives if len(a) <= 6):  # "wooden", "ceramic": compared with "more"
        for stem in _stems(adj):
            out.setdefault(stem + "er", adj)
            out.setdefault(stem + "est", adj)
    return {word: adj for word, adj in out.items() if word not in adjectives}


def _stems(adj: str) -> list[str]:
    """What "-er" and "-est" follow in ``adj``'s comparison: "tini", "larg", "small", and
    "bigg" beside "big" (a short word ending consonant, vowel, consonant)."""
    if adj.endswith("y"):
        return [adj[:-1] + "i"]
    if adj.endswith("e"):
        return [adj[:-1]]
    doubled = (
        len(adj) in (3, 4) and adj[-1] not in "aeiouwy" and adj[-2] in "aeiou" and adj[-3] not in "aeiou"
    )
    return [adj, adj + adj[-1]] if doubled else [adj]


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
    "NUMBERS",
    "PHRASES",
    "UNITS",
    "VERBS",
    "WORDS",
    "ParseFailure",
    "Word",
    "build_parser",
    "normalise",
    "parse",
    "parser",
    "tag",
]
