"""One person's conversation with a_hi (language.py): the question a_hi asked and is waiting
for an answer to, the last one answered ("no, the other one"), the last object named ("it"),
and the yes-or-no questions a_hi asks when a sentence read literally asks for what a_pl cannot
do (:func:`odd_literal`) or its verb means two tasks (:func:`two_ways`)."""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field

from services.agents.human_interface.grammar import normalise
from services.agents.human_interface.intents import (
    STORAGE,
    SURFACE,
    Ambiguous,
    Command,
    Intent,
    NotUnderstood,
    show,
)
from services.agents.human_interface.vocabulary import Vocabulary
from shared.fipa_codec.languages.l_hc import TaskAtom


@dataclass(frozen=True)
class Pending:
    """A question a_hi asked: the ``sentence`` it was about (with its ``priority``), the token
    index ``at`` of the ambiguous reference, and its ``candidates``; ``chosen`` the references
    settled by earlier answers; ``question`` the question as asked (asked again when an answer
    names nothing); ``offer``, for a yes-or-no question, the command a "yes" gives."""

    sentence: str
    priority: int
    at: int
    candidates: tuple[str, ...]
    chosen: dict[int, str] = field(default_factory=dict)
    question: str = ""
    offer: Command | None = None
    """For a yes-or-no question (:func:`odd_literal`): the command a "yes" gives."""


@dataclass(frozen=True)
class Answered:
    """A question a_hi asked and the person answered: the question (``pending``), the
    references settled (``chosen``) and the command they completed (``goal``)."""

    pending: Pending
    chosen: dict[int, str]
    goal: TaskAtom


@dataclass
class Dialogue:
    """One person's conversation with a_hi: the last object named (for "it"/"that"), the
    question waiting for an answer, if any, and the last question answered (for "no, the
    other one")."""

    last: str | None = None
    pending: Pending | None = None
    answered: Answered | None = None


OTHER_ONE = re.compile(
    r"^(?:(?:no|nope|oops|sorry|actually|no no|not that one|not that|wrong one|the wrong one|"
    r"thats the wrong one|i meant|i mean|i said)\s+)*(?:i meant\s+|i mean\s+|i want\s+)?"
    r"the other(?: one| [a-z]+)?(?:\s+(?:please|instead|i meant|i mean|thanks))*$"
)
"""A correction of a_hi's reading of the person's last answer: "no, the other one", "the
other bowl, please", "sorry, I meant the other one" (normalised words, grammar.py)."""


class Offer(Ambiguous):
    """A yes-or-no question back: the sentence read literally asks for what a_pl cannot do (the
    jar put inside the bowl); ``offer`` is what it most likely means (pour the jar's content
    into the bowl), done on a "yes"; ``other``, the other command the question names, if any
    (only take it in a hand)."""

    def __init__(self, message: str, offer: Command, other: Command | None = None) -> None:
        super().__init__(message, -1, ())
        self.offer = offer
        self.other = other


def odd_literal(intent: Command, vocab: Vocabulary) -> Offer | None:
    """The question back for a ``place`` of a container holding content into another
    container ("put the jar into the bowl"): a_pl places things on furniture, not inside a
    bowl, so the person most likely means the pour; None for any other command."""
    if intent.goal.name != "place":
        return None
    x, y = intent.goal.args
    dest = vocab.thing(y)
    holds = any(t.content and t.place == x for t in vocab.things)
    if not holds or dest is None or y in (STORAGE, SURFACE) or ("container",) not in dest.nouns:
        return None
    pour = Command(TaskAtom("pour", (x, y)), intent.priority, intent.deadline_s)
    return Offer(
        f"Should I pour what is in {show(x)} into {show(y)}? I cannot put {show(x)} itself in "
        f"{show(y)}. Say 'yes', or tell me what to do instead.",
        pour,
    )


TWO_WAYS = frozenset({"grab", "take"})
"""Verbs of bringing that as often mean only taking in a hand ("grab the bowl", "take it":
bring it, or pick it up?): said bare, without a recipient or a place, they are asked back."""
BARE_ONLY = frozenset(
    {"BRING", "TAKE", "DET", "ADJ", "NOUN", "PLURAL", "ONE", "IT", "PLEASE", "ADDRESS", "ASK", "POLITE"}
)
"""Word kinds a bare "grab X" holds: anything else ("me", "here", "for me", "to the table")
says where it goes."""


def two_ways(intent: Command, kinds: list[str], verb: str) -> Offer | None:
    """The question back for a ``bring`` said with a verb of :data:`TWO_WAYS` and nothing
    saying where ("grab the bowl": ``kinds`` the line's word kinds, ``verb`` its bring verb);
    a "yes" brings it, "pick it up" only takes it; None for any other command."""
    if intent.goal.name != "bring" or verb not in TWO_WAYS or not set(kinds) <= BARE_ONLY:
        return None
    x = show(intent.goal.args[0])
    take = dataclasses.replace(intent, goal=TaskAtom("fetch", intent.goal.args))
    return Offer(
        f"Should I bring you {x}? Say 'yes', or 'pick it up' to only take it in my hand.", intent, take
    )


YES = re.compile(
    r"^(?:yes|yeah|yep|yup|sure|ok|okay|please|correct|right|exactly|do it|do that|go ahead|pour it)"
    r"(?: (?:please|thanks|thank you|do it|do that|go ahead|pour it|that is right|thats right))*$"
)
"""A yes to a yes-or-no question (normalised words)."""
NO = re.compile(
    r"^(?:no|nope|nah|no thanks|no thank you|dont|do not)(?: (?:thanks|thank you|dont|never mind))*$"
)
"""A no to a yes-or-no question (normalised words)."""


def answer_to_offer(sentence: str, talk: Dialogue) -> Intent | None:
    """The offered command when ``sentence`` says yes to a_hi's yes-or-no question; raises
    :class:`NotUnderstood` when it says no (the question is dropped); None for anything else
    (read as any sentence: a new command drops the question)."""
    pending = talk.pending
    if pending is None or pending.offer is None:
        return None
    said = " ".join(normalise(sentence))
    if YES.match(said):
        talk.pending = None
        return pending.offer
    if NO.match(said):
        talk.pending = None
        raise NotUnderstood("All right, I will not. What should I do instead?")
    return None


__all__ = [
    "NO",
    "OTHER_ONE",
    "TWO_WAYS",
    "YES",
    "Answered",
    "Dialogue",
    "Offer",
    "Pending",
    "answer_to_offer",
    "odd_literal",
    "two_ways",
]
