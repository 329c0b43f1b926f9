"""What a person's sentence asks a_hi for (an L_HC command, a stop, a status request, a question
about the kitchen), and the
ways it can fail to: not understood, incomplete, or naming an object ambiguously or not at all.

These are a_hi's own terms; a :class:`Command` becomes an L_HC ``HumanCommand`` (its goal a
``TaskAtom`` of a task a_pl knows: services/agents/planner/domain.py ``TASKS``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from services.agents.human_interface.task_words import TaskWords, default_task_words
from shared.fipa_codec.languages.l_hc import TaskAtom

URGENT_PRIORITY = 5
"""The priority an urgency word gives a command (larger is more urgent; the default is 0)."""

STORAGE = "cabinet"
"""Where things are put back (a_pl's ``return`` puts them there: planner/domain.py STORAGE);
"put X in the cabinet" is read as ``return(X)``."""

SURFACE = "table"
"""Where "put X down" sets X: the surface a_pl's safe stop puts things down on (planner/domain.py
SAFE_SURFACE); "put the cup down" is read as ``place(cup, table)``."""


ReadAs = tuple[tuple[str, str], ...]
"""Typos corrected in a sentence: (the word as written, the word a_hi read), in order."""


@dataclass(frozen=True)
class Read:
    """What every intent carries: ``read_as``, the typos corrected to read it (said back; not
    part of its equality)."""

    read_as: ReadAs = field(default=(), compare=False, kw_only=True)

    @property
    def said(self) -> str:
        """The typos corrected, said back (:func:`said_back`; "" when there are none)."""
        return said_back(self.read_as)


@dataclass(frozen=True)
class Command(Read):
    """Do ``goal``; ``priority`` larger is more urgent; ``deadline_s`` seconds from acceptance;
    ``instead_of``: the command it replaces, when the person corrected a_hi's reading of an
    answer ("no, the other one": that command is stopped first)."""

    goal: TaskAtom
    priority: int = 0
    deadline_s: float | None = None
    instead_of: TaskAtom | None = None


@dataclass(frozen=True)
class Stop(Read):
    """Stop every command that is still open (the robot first puts down what it holds)."""


@dataclass(frozen=True)
class StatusRequest(Read):
    """ "What are you doing?", "are you done yet?", "how long will it take?": the state of every
    command a_co holds."""


@dataclass(frozen=True)
class WorldQuestion(Read):
    """A question about the kitchen, or about a_hi itself, answered in one sentence
    (questions.py reads it, answers.py words the answer). ``kind``: one of
    :data:`QUESTION_KINDS`; ``thing``: the O_RoCo name of the object asked about (None for
    ``seen`` and ``abilities``); ``place`` and ``relation`` ("in"/"on"): for ``located`` ("is the
    cup on the table?"), where the thing is asked to be; ``counted``: for ``count``, "spheres"
    (the content) or "things" (the objects in it)."""

    kind: str
    thing: str | None = None
    place: str | None = None
    relation: str | None = None
    counted: str = "spheres"


QUESTION_KINDS = ("where", "contents", "on", "empty", "full", "located", "count", "seen", "abilities")
"""What a :class:`WorldQuestion` asks: where a thing is; what is in it, on it; whether it is empty,
full, in or on a place; how many spheres or things are in it; what a_hi's robot saw; what a_hi
can do (answered from its own task words, without a_km)."""


Intent = Command | Stop | StatusRequest | WorldQuestion
"""What a sentence asks for."""


class NotUnderstood(ValueError):
    """The sentence is not understood; the message is one line for the person: what was not
    understood (a word, a missing part) and what could be said instead."""


class Incomplete(NotUnderstood):
    """The sentence has a known form but lacks something; the message asks for it
    (``missing`` names it: "object", "destination", "source")."""

    def __init__(self, message: str, missing: str) -> None:
        super().__init__(message)
        self.missing = missing


class Misspelt(NotUnderstood):
    """A word a_hi does not know is as near to two or more of its words, each making a sentence
    of it ("pout": "pour" or "put"); the message names the word and the candidates, which are
    ``word`` and ``candidates``, rather than guessing."""

    def __init__(self, message: str, word: str, candidates: tuple[str, ...]) -> None:
        super().__init__(message)
        self.word = word
        self.candidates = candidates


class Ambiguous(NotUnderstood):
    """A reference names more than one thing; the message asks which ("Which cup: the one in
    the cabinet or the one on the table?"). ``at`` is the reference's first token, ``candidates``
    the individuals it could name (O_RoCo names)."""

    def __init__(self, message: str, at: int, candidates: tuple[str, ...]) -> None:
        super().__init__(message)
        self.at = at
        self.candidates = candidates


class UnknownReference(NotUnderstood):
    """A reference names nothing the knowledge base holds ("the small jar", "the cup on the
    table" when the only cup is in the cabinet); the message says what there is."""


def said_back(read_as: ReadAs) -> str:
    """The typos corrected, said back: "I read 'doimg' as 'doing'." ("" when there are none)."""
    if not read_as:
        return ""
    pairs = [f"'{written}' as '{read}'" for written, read in read_as]
    said = pairs[0] if len(pairs) == 1 else ", ".join(pairs[:-1]) + " and " + pairs[-1]
    return f"I read {said}."


def show(name: str) -> str:
    """An O_RoCo name as a person reads it: ``tea_pot`` → "the tea pot"."""
    return "the " + name.replace("_", " ")


def describe(goal: TaskAtom, words: TaskWords | None = None) -> str:
    """The task in words a person reads ("pour the jar into the bowl"): a_hi's phrase for a task
    of grammar.lark's frames, else the first frame of the task's entry in ``words`` (default:
    tasks.toml's) said with its arguments ("find the jar"), else ``name(args)``."""
    a = [show(x) for x in goal.args]
    if goal.name == "pour" and len(a) == 2:
        return f"pour {a[0]} into {a[1]}"
    if goal.name == "place" and len(a) == 2:
        return f"put {a[0]} on {a[1]}"
    if goal.name == "bring" and len(a) == 1:
        return f"bring {a[0]} to the table"
    if goal.name == "return" and len(a) == 1:
        return f"put {a[0]} back in the {STORAGE}"
    if goal.name == "hand_over" and len(a) == 1:
        return f"hand you {a[0]}"
    saying = (words if words is not None else default_task_words()).saying(goal.name)
    if saying is not None and len(saying.args) == len(a):
        return saying.frames[0].fill(dict(zip(saying.args, a, strict=True)))
    return f"{goal.name}({', '.join(goal.args)})"


__all__ = [
    "QUESTION_KINDS",
    "STORAGE",
    "SURFACE",
    "URGENT_PRIORITY",
    "Ambiguous",
    "Command",
    "Incomplete",
    "Intent",
    "Misspelt",
    "NotUnderstood",
    "Read",
    "ReadAs",
    "StatusRequest",
    "Stop",
    "UnknownReference",
    "WorldQuestion",
    "describe",
    "said_back",
    "show",
]
