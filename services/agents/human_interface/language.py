"""From a sentence to an intent: a command (a task of L_HC), a stop, or a status request.

A named simplification (paper §5.2 leaves the human interface open): the understanding is
**pattern-based** — no speech recognition, no statistical language model, no dialogue
memory. A sentence is normalised (case, punctuation, articles, "please" and similar
politeness), urgency and deadline phrases are taken out, and what is left must match one
of a few fixed forms:

=========================================  =======================================
form                                       intent
=========================================  =======================================
``pour X into Y``                          ``Command(TaskAtom("pour", (X, Y)))``
``put X on Y`` / ``place X on Y``          ``Command(TaskAtom("place", (X, Y)))``
``bring X to the table`` / ``bring me X``  ``Command(TaskAtom("bring", (X,)))``
/ ``fetch X``                              (fetch X and put it on the table)
``put X back [in the cabinet]`` /          ``Command(TaskAtom("return", (X,)))``
``return X`` / ``put X away``
``hand me X`` / ``give me X`` /            ``Command(TaskAtom("hand_over", (X,)))``
``hand over X``
``stop`` / ``stop everything`` / ``cancel``  :class:`Stop` (every open command)
``what are you doing?`` / ``status``       :class:`StatusRequest`
=========================================  =======================================

Urgency: "urgently", "now", "quickly", "right away", "immediately", "first", … anywhere in a
command raise its priority to :data:`URGENT_PRIORITY` (default 0); a priority given with the
input (``HumanInput.priority`` > 0) wins. "within N seconds|minutes|hours" sets the
deadline. Object phrases are mapped to the ontology's names by :data:`SYNONYMS` ("glass
jar" → ``jar``, "mug" → ``cup``); a phrase the table does not know is passed on as it is
(words joined by ``_``), so that a_co/a_pl can answer "I know of no X".

:func:`interpret` raises :class:`NotUnderstood` (naming the forms it knows) for anything
else, and its subclass :class:`Incomplete` (a question naming what is missing) for a form
that lacks an object ("pour it into the bowl", "put the jar on").
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from shared.fipa_codec.languages.l_hc import TaskAtom

URGENT_PRIORITY = 5
"""The priority an urgency word gives a command (larger is more urgent; the default is 0)."""

SYNONYMS: dict[str, str] = {
    # jar
    "jar": "jar",
    "glass jar": "jar",
    "jar of beans": "jar",
    "jar of balls": "jar",
    "container": "jar",
    # bowl
    "bowl": "bowl",
    "salad bowl": "bowl",
    "glass bowl": "bowl",
    "dish": "bowl",
    # cup
    "cup": "cup",
    "mug": "cup",
    "coffee mug": "cup",
    "coffee cup": "cup",
    "tea cup": "cup",
    "teacup": "cup",
    # furniture
    "table": "table",
    "kitchen table": "table",
    "dining table": "table",
    "cabinet": "cabinet",
    "cupboard": "cabinet",
    "kitchen cabinet": "cabinet",
}
"""Object phrases (lower case, articles removed) → names in the ontology O_RoCo. Data, not
code: extend it when the kitchen gets new objects."""

EXAMPLES = (
    "'pour the jar into the bowl'",
    "'put the cup on the table'",
    "'bring me the jar'",
    "'put the jar back'",
    "'hand me the cup'",
    "'stop'",
    "'what are you doing?'",
)
"""One example per form, as the polite answers list them."""

_HELP = (
    "I understand only a few fixed sentence forms (no speech, no free conversation): "
    + ", ".join(EXAMPLES)
    + "; add 'urgently' or 'within 2 minutes' to a command to hurry it."
)


@dataclass(frozen=True)
class Command:
    """Do ``goal``; ``priority`` larger is more urgent; ``deadline_s`` seconds from acceptance."""

    goal: TaskAtom
    priority: int = 0
    deadline_s: float | None = None


@dataclass(frozen=True)
class Stop:
    """Stop every command that is still open (the robot first puts down what it holds)."""


@dataclass(frozen=True)
class StatusRequest:
    """ "What are you doing?": the state of every command a_co holds."""


Intent = Command | Stop | StatusRequest
"""What a sentence asks for."""


class NotUnderstood(ValueError):
    """The sentence matches no known form; the message (a polite answer) lists the forms."""


class Incomplete(NotUnderstood):
    """The sentence has a known form but lacks something; the message asks for it
    (``missing`` names it: "object", "destination")."""

    def __init__(self, message: str, missing: str) -> None:
        super().__init__(message)
        self.missing = missing


# ---- normalisation ------------------------------------------------------------------------
_NUMBERS = {
    "a": 1,
    "an": 1,
    "one": 1,
    "two": 2,
    "three": 3,
    "four": 4,
    "five": 5,
    "six": 6,
    "seven": 7,
    "eight": 8,
    "nine": 9,
    "ten": 10,
    "fifteen": 15,
    "twenty": 20,
    "thirty": 30,
    "forty": 40,
    "fifty": 50,
    "sixty": 60,
    "ninety": 90,
}
_UNITS = {"s": 1.0, "sec": 1.0, "second": 1.0, "min": 60.0, "minute": 60.0, "h": 3600.0, "hour": 3600.0}
_DEADLINE = re.compile(
    r"\bwithin (?:the next )?(?P<n>\d+(?:\.\d+)?|" + "|".join(_NUMBERS) + r") "
    r"(?P<unit>s|secs?|seconds?|mins?|minutes?|h|hours?)\b"
)
_URGENCY = re.compile(
    r"\b(?:as soon as possible|asap|right away|right now|at once|immediately|urgently|urgent|"
    r"quickly|quick|fast|hurry up|hurry|now|first)\b"
)
_LEADING_FILLER = re.compile(
    r"^(?:(?:hey|ok|okay|robot|velma|please|kindly|go and|go|"
    r"(?:could|can|would|will) you(?: please)?|i (?:want|need|would like) you to|id like you to)\s+)+"
)
_TRAILING_FILLER = re.compile(r"(?:\s+(?:please|thanks|thank you|robot|velma))+$")
_ARTICLES = frozenset({"the", "a", "an", "some", "my", "your", "this", "that", "these", "those"})
_PRONOUNS = frozenset({"it", "them", "one", "something", "thing", "things", "stuff", "everything"})
_STOP = re.compile(
    r"^(?:stop|cancel|abort|halt|freeze)(?: (?:it|that|this|everything|all|all commands|all tasks|"
    r"what you are doing|whatever you are doing|doing that|all of it))?$"
)
_STATUS = re.compile(
    r"^(?:status|status report|report|progress|"
    r"what are you doing|what are you up to|what are you working on|what are you busy with|"
    r"whats going on|what is going on|whats happening|what is happening|"
    r"how is it going|hows it going|how far are you|what is your status|whats your status|"
    r"are you busy|are you done)$"
)
_BACK_TO_CABINET = frozenset({"cabinet", "its place", "place", "where it belongs", "where it was"})


def _normalise(sentence: str) -> str:
    text = sentence.lower().replace("'", "").replace("’", "")
    text = re.sub(r"[^a-z0-9._\s]+", " ", text)
    text = re.sub(r"(?<![0-9])\.|\.(?![0-9])", " ", text)  # keep decimal points only
    return " ".join(text.split())


def _strip_filler(text: str) -> str:
    text = _LEADING_FILLER.sub("", text)
    text = _TRAILING_FILLER.sub("", text)
    return " ".join(w for w in text.split() if w not in ("please", "kindly"))


def _deadline(text: str) -> tuple[str, float | None]:
    m = _DEADLINE.search(text)
    if m is None:
        if re.search(r"\bwithin\b", text):
            raise NotUnderstood(
                "I did not understand the deadline; say e.g. 'within 30 seconds' or 'within 2 minutes'."
            )
        return text, None
    n = m.group("n")
    amount = float(_NUMBERS[n]) if n in _NUMBERS else float(n)
    unit = m.group("unit")
    scale = next(v for k, v in sorted(_UNITS.items(), key=lambda kv: -len(kv[0])) if unit.startswith(k))
    return " ".join((text[: m.start()] + " " + text[m.end() :]).split()), amount * scale


# ---- objects -------------------------------------------------------------------------------
def object_name(phrase: str) -> str:
    """The ontology name for an object phrase: articles dropped, :data:`SYNONYMS` applied,
    an unknown phrase joined with ``_`` ("tea pot" → ``tea_pot``). Empty for no object."""
    words = [w for w in phrase.split() if w not in _ARTICLES]
    key = " ".join(words)
    if key in SYNONYMS:
        return SYNONYMS[key]
    return "_".join(words)


def _is_missing(words: list[str]) -> bool:
    rest = [w for w in words if w not in _ARTICLES]
    return not rest or (len(rest) == 1 and rest[0] in _PRONOUNS)


def _show(name: str) -> str:
    return "the " + name.replace("_", " ")


def describe(goal: TaskAtom) -> str:
    """The task in words a person reads ("pour the jar into the bowl")."""
    a = [_show(x) for x in goal.args]
    if goal.name == "pour" and len(a) == 2:
        return f"pour {a[0]} into {a[1]}"
    if goal.name == "place" and len(a) == 2:
        return f"put {a[0]} on {a[1]}"
    if goal.name == "bring" and len(a) == 1:
        return f"bring {a[0]} to the table"
    if goal.name == "return" and len(a) == 1:
        return f"put {a[0]} back in the cabinet"
    if goal.name == "hand_over" and len(a) == 1:
        return f"hand you {a[0]}"
    return f"{goal.name}({', '.join(goal.args)})"


def _is_cabinet(words: list[str]) -> bool:
    """True when ``words`` name the cabinet, or "where it belongs"."""
    phrase = " ".join(w for w in words if w not in _ARTICLES)
    return phrase in _BACK_TO_CABINET or object_name(phrase) == "cabinet"


def _split(words: list[str], preps: frozenset[str]) -> tuple[list[str], str | None, list[str]]:
    for i, w in enumerate(words):
        if w in preps:
            return words[:i], w, words[i + 1 :]
    return words, None, []


def _one(words: list[str]) -> str:
    """The object name of ``words``; NotUnderstood for a list of objects."""
    if "and" in words:
        raise NotUnderstood(
            "Please give me one object at a time, e.g. 'bring me the jar', then 'bring me the cup'."
        )
    return object_name(" ".join(words))


_POUR_TO = frozenset({"into", "in", "inside", "to", "onto", "over"})
_ON = frozenset({"on", "onto", "upon", "in", "into", "inside"})
_TO = frozenset({"to", "on", "onto", "in", "into"})
_PUT = frozenset({"put", "place", "set", "lay", "move", "stand"})
_BRING = frozenset({"bring", "fetch", "get", "grab"})
_HAND = frozenset({"hand", "give", "pass"})
_RETURN = frozenset({"return", "store", "stow"})


def _pour(rest: list[str]) -> TaskAtom:
    what, prep, where = _split(rest, _POUR_TO)
    if _is_missing(what):
        target = f" into {_show(_one(where))}" if where and not _is_missing(where) else ""
        raise Incomplete(
            f"Which object should I pour{target}? Say e.g. 'pour the jar into the bowl'.", "object"
        )
    x = _one(what)
    if prep is None or _is_missing(where):
        raise Incomplete(
            f"Into what should I pour {_show(x)}? Say e.g. 'pour {_show(x)} into the bowl'.", "destination"
        )
    return TaskAtom("pour", (x, _one(where)))


def _put(rest: list[str]) -> TaskAtom:
    if rest[:1] == ["away"]:  # "put away X"
        return _return(rest[1:])
    if rest[-1:] == ["away"]:  # "put X away"
        return _return(rest[:-1])
    if "back" in rest:  # "put X back [in the cabinet | on the table]"
        i = rest.index("back")
        what, after = rest[:i], rest[i + 1 :]
        if after and after[0] in _TO:
            after = after[1:]
        if not after or _is_cabinet(after):
            return _return(what)
        rest = [*what, "on", *after]
    what, prep, where = _split(rest, _ON)
    if _is_missing(what):
        target = f" on {_show(_one(where))}" if where and not _is_missing(where) else ""
        raise Incomplete(f"Which object should I put{target}? Say e.g. 'put the cup on the table'.", "object")
    x = _one(what)
    if prep is None or _is_missing(where):
        raise Incomplete(
            f"Where should I put {_show(x)}? Say e.g. 'put {_show(x)} on the table', "
            f"or 'put {_show(x)} back'.",
            "destination",
        )
    y = _one(where)
    if y == "cabinet" and prep in ("in", "into", "inside"):
        return TaskAtom("return", (x,))
    return TaskAtom("place", (x, y))


def _bring(rest: list[str]) -> TaskAtom:
    if rest[:1] == ["me"]:  # "bring me X"
        rest = rest[1:]
    for tail in (["over", "here"], ["for", "me"], ["here"]):
        if rest[-len(tail) :] == tail:
            rest = rest[: -len(tail)]
            break
    what, prep, where = _split(rest, _TO)
    if what[-1:] == ["back"]:  # "bring X back to the cabinet"
        what = what[:-1]
    if _is_missing(what):
        raise Incomplete("What should I bring? Say e.g. 'bring me the jar'.", "object")
    x = _one(what)
    if prep is None or _is_missing(where) or where in (["me"], ["here"]):
        return TaskAtom("bring", (x,))
    if _is_cabinet(where):
        return TaskAtom("return", (x,))
    y = _one(where)
    return TaskAtom("bring", (x,)) if y == "table" else TaskAtom("place", (x, y))


def _return(rest: list[str]) -> TaskAtom:
    if rest[-1:] == ["back"]:
        rest = rest[:-1]
    what, prep, where = _split(rest, _TO)
    if _is_missing(what):
        raise Incomplete("What should I put back? Say e.g. 'put the jar back'.", "object")
    x = _one(what)
    if prep is None or _is_missing(where) or _is_cabinet(where):
        return TaskAtom("return", (x,))
    return TaskAtom("place", (x, _one(where)))


def _hand(rest: list[str]) -> TaskAtom:
    if rest[:1] == ["over"]:
        rest = rest[1:]
    if rest[:1] == ["me"]:
        rest = rest[1:]
    for tail in (["over", "to", "me"], ["to", "me"], ["over"]):
        if rest[-len(tail) :] == tail:
            rest = rest[: -len(tail)]
            break
    if "to" in rest:
        raise NotUnderstood("I can hand things only to you; say e.g. 'hand me the cup'.")
    if _is_missing(rest):
        raise Incomplete("What should I hand you? Say e.g. 'hand me the cup'.", "object")
    return TaskAtom("hand_over", (_one(rest),))


def _goal(text: str) -> TaskAtom | None:
    words = text.split()
    if not words:
        return None
    verb, rest = words[0], words[1:]
    if verb == "pour":
        return _pour(rest)
    if verb in _PUT or (verb == "take" and "back" in rest):
        if not rest:
            raise Incomplete("What should I put where? Say e.g. 'put the cup on the table'.", "object")
        return _put(rest)
    if verb in _BRING:
        return _bring(rest)
    if verb in _RETURN:
        return _return(rest)
    if verb in _HAND:
        return _hand(rest)
    if verb in ("tidy", "clear") and rest[-1:] == ["away"]:
        return _return(rest[:-1])
    return None


def interpret(sentence: str, priority: int = 0) -> Intent:
    """The intent of ``sentence``. ``priority`` > 0 (given with the input) overrides the
    priority urgency words give. Raises :class:`NotUnderstood` (or :class:`Incomplete`) with
    a polite answer for anything else."""
    text = _normalise(sentence)
    text, deadline_s = _deadline(text)
    urgent = _URGENCY.search(text) is not None
    text = " ".join(_URGENCY.sub(" ", text).split())
    text = _strip_filler(text)
    if _STOP.match(text):
        return Stop()
    if _STATUS.match(text):
        return StatusRequest()
    if text.split()[:1] in (["stop"], ["cancel"], ["abort"]):
        raise NotUnderstood("I can only stop all open commands at once: say 'stop'.")
    goal = _goal(text)
    if goal is None:
        shown = repr(sentence.strip()) if sentence.strip() else "an empty sentence"
        raise NotUnderstood(f"Sorry, I did not understand {shown}. {_HELP}")
    if priority <= 0:
        priority = URGENT_PRIORITY if urgent else 0
    return Command(goal, priority, deadline_s)


__all__ = [
    "EXAMPLES",
    "SYNONYMS",
    "URGENT_PRIORITY",
    "Command",
    "Incomplete",
    "Intent",
    "NotUnderstood",
    "StatusRequest",
    "Stop",
    "describe",
    "interpret",
    "object_name",
]
