"""From a sentence to an intent: an L_HC command, a stop, a status request — or one line back.

Named simplifications (paper §5.2 leaves the human interface open): the understanding is a
**hand-written grammar** of English kitchen commands (grammar.lark, parsed by lark's Earley
parser) — English only, typed text only (no speech), no statistical language model. What it
covers: the verbs and frames of every task a_pl knows (those with rich particle structure in
grammar.lark and meaning.py; the others as data, tasks.toml, made into rules by
task_grammar.py), prepositions and particles ("out of", "onto", "back in"), determiners and
adjectives ("the small cup"), "the contents of the jar", polite framing ("could you …?",
"please", "thanks"), urgency ("urgently", "right away", … → :data:`URGENT_PRIORITY`) and
deadlines ("within 2 minutes"), and "it"/"that" for the last object the same person named.

The words for things are not listed here: they are the vocabulary a_km gives (vocabulary.py:
labels and adjectives in O_RoCo and the knowledge base), so a thing a_km learns about can be
named at once. A reference naming more than one thing gets a question back ("Which cup: the one
in the cabinet or the one on the table?"); the person's next sentence may answer it ("the one on
the table"), and the command goes on — a :class:`Dialogue` per person keeps that and the last
object named. A sentence not understood gets one line naming the word or the missing part and
what could be said instead (:class:`NotUnderstood` and its subclasses, intents.py).

Pipeline: :meth:`~.task_grammar.Grammar.tag` → :meth:`~.task_grammar.Grammar.parse` (every
reading) → :class:`~.meaning.Reader` per reading → the best: a command over a question over a
refusal, then the reading whose prepositions are the verb's arguments rather than an object's
location.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

from services.agents.human_interface.grammar import ParseFailure, Word
from services.agents.human_interface.intents import (
    STORAGE,
    URGENT_PRIORITY,
    Ambiguous,
    Command,
    Incomplete,
    Intent,
    NotUnderstood,
    StatusRequest,
    Stop,
    UnknownReference,
    describe,
    show,
)
from services.agents.human_interface.meaning import Context, Reader, Reply, loc_count, loc_depth
from services.agents.human_interface.task_grammar import Grammar, default_grammar
from services.agents.human_interface.vocabulary import KNOWLEDGE_FILES, Vocabulary

EXAMPLES = (
    "'pour the jar into the bowl'",
    "'fill the bowl from the jar'",
    "'bring me the cup'",
    "'put the cup on the table'",
    "'put the jar back'",
    "'hand me the cup'",
    "'stop'",
    "'what are you doing?'",
)
"""Example sentences, as the answers list them."""


@dataclass(frozen=True)
class Pending:
    """A question a_hi asked: the ``sentence`` it was about (with its ``priority``), the token
    index ``at`` of the ambiguous reference, and its ``candidates``; ``chosen`` the references
    settled by earlier answers."""

    sentence: str
    priority: int
    at: int
    candidates: tuple[str, ...]
    chosen: dict[int, str] = field(default_factory=dict)


@dataclass
class Dialogue:
    """One person's conversation with a_hi: the last object named (for "it"/"that") and the
    question waiting for an answer, if any."""

    last: str | None = None
    pending: Pending | None = None


@functools.cache
def default_vocabulary() -> Vocabulary:
    """The vocabulary of O_RoCo and the kitchen as a_km first loads them (a_hi's words before
    a_km answers; tests). Raises OSError when the files are missing."""
    return Vocabulary.from_files(KNOWLEDGE_FILES)


_RANK = {Command: 0, Stop: 0, StatusRequest: 0, Reply: 0, Ambiguous: 1, Incomplete: 2, UnknownReference: 3}


def _rank(outcome: object) -> int:
    return next((r for t, r in _RANK.items() if isinstance(outcome, t)), 4)


def _read(words: tuple[Word, ...], priority: int, ctx: Context, grammar: Grammar) -> Intent | Reply:
    """The best reading of tagged ``words``; raises the best failure when none is an intent."""
    readings = grammar.parse(words)
    outcomes: list[tuple[int, int, int, int, Intent | Reply | NotUnderstood]] = []
    for tree in readings:
        try:
            outcome: Intent | Reply | NotUnderstood = Reader(ctx).sentence(tree, priority)
        except NotUnderstood as exc:
            outcome = exc
        many = len(outcome.candidates) if isinstance(outcome, Ambiguous) else 0
        outcomes.append((_rank(outcome), many, loc_count(tree), -loc_depth(tree), outcome))
    outcomes.sort(key=lambda o: o[:4])
    best = outcomes[0][4]
    if isinstance(best, NotUnderstood):
        raise best
    return best


def _failure(
    exc: ParseFailure, vocabulary: Vocabulary, priority: int, ctx: Context, grammar: Grammar
) -> NotUnderstood:
    """One line for a sentence that does not parse: the word, or the missing part, and what to say."""
    words = exc.words
    if not words:
        return NotUnderstood(f"I heard an empty sentence; say e.g. {EXAMPLES[0]}.")
    if exc.at is None:  # the sentence ended too early: read it without its dangling end
        for cut in range(len(words) - 1, 0, -1):
            try:
                _read(words[:cut], priority, ctx, grammar)
            except ParseFailure:
                continue
            except Incomplete as inc:
                return inc
            except NotUnderstood:
                break
            break
        last = words[-1].text
        return Incomplete(
            f"What should I do? Your sentence stops after '{last}'; say e.g. {EXAMPLES[0]}.", "object"
        )
    at = exc.at
    if words[0].kind == "STOP":
        return NotUnderstood("I can only stop all open commands at once: say 'stop'.")
    if at.kind == "WITHIN":
        return NotUnderstood(
            "I did not understand the deadline; say e.g. 'within 30 seconds' or 'within 2 minutes'."
        )
    verbs = {"POUR", "BRING", "PUT", "HAND", "STOP", "STATUS"}
    if at.kind == "WORD":
        if verbs & exc.expected and not ({"NOUN", "IT"} & exc.expected and at.index > 0):
            return NotUnderstood(
                f"I do not know '{at.text}' as a command; I can: {grammar.verbs()} (e.g. {EXAMPLES[0]})."
            )
        if "NOUN" in exc.expected:
            return UnknownReference(
                f"I do not know '{at.text}': I know {vocabulary.examples()} (e.g. {EXAMPLES[2]})."
            )
        return NotUnderstood(f"I do not know the word '{at.text}' here; say e.g. {EXAMPLES[0]}.")
    before = " ".join(w.text for w in words[: at.index]) or "the start"
    return NotUnderstood(f"I did not expect '{at.text}' after '{before}'; say e.g. {EXAMPLES[3]}.")


def interpret(
    sentence: str,
    priority: int = 0,
    *,
    vocabulary: Vocabulary | None = None,
    dialogue: Dialogue | None = None,
    grammar: Grammar | None = None,
) -> Intent:
    """The intent of ``sentence``. ``priority`` > 0 (given with the input) overrides the
    priority urgency words give. ``vocabulary``: the things that can be named (default: O_RoCo
    and the kitchen, :func:`default_vocabulary`). ``dialogue``: the person's conversation; it is
    updated (the last object named, a question asked or answered). ``grammar``: grammar.lark with
    the frames of the task words (default: those of tasks.toml,
    :func:`~.task_grammar.default_grammar`). Raises :class:`NotUnderstood` — :class:`Incomplete`,
    :class:`Ambiguous` (a question: the next sentence may answer it) or
    :class:`UnknownReference` — with one line for the person."""
    vocab = vocabulary if vocabulary is not None else default_vocabulary()
    talk = dialogue if dialogue is not None else Dialogue()
    rules = grammar if grammar is not None else default_grammar()
    pending, talk.pending = talk.pending, None
    words = rules.tag(sentence, vocab)
    ctx = Context(
        vocab,
        last=talk.last,
        among=pending.candidates if pending else (),
        token_seconds={w.index: w.seconds for w in words if w.seconds is not None},
        frames=rules.frames,
    )
    try:
        intent = _read(words, priority, ctx, rules)
    except ParseFailure as exc:
        raise _failure(exc, vocab, priority, ctx, rules) from None
    except Ambiguous as exc:
        talk.pending = Pending(sentence, priority, exc.at, exc.candidates)
        raise
    if isinstance(intent, Reply):
        if pending is None:
            talk.last = intent.name
            raise NotUnderstood(
                f"What should I do with {show(intent.name)}? Say e.g. 'bring me {show(intent.name)}'."
            )
        if intent.name not in pending.candidates:
            talk.pending = pending
            options = ", ".join(show(c) for c in pending.candidates)
            raise Ambiguous(
                f"I asked about {options}; which of them do you mean?", pending.at, pending.candidates
            )
        chosen = {**pending.chosen, pending.at: intent.name}
        return _resume(pending, chosen, vocab, talk, rules)
    if isinstance(intent, Command) and intent.goal.args:
        talk.last = intent.goal.args[0]
    return intent


def _resume(
    pending: Pending, chosen: dict[int, str], vocab: Vocabulary, talk: Dialogue, grammar: Grammar
) -> Intent:
    """The pending sentence again, its references settled by the answers so far."""
    words = grammar.tag(pending.sentence, vocab)
    ctx = Context(
        vocab,
        last=talk.last,
        chosen=chosen,
        token_seconds={w.index: w.seconds for w in words if w.seconds is not None},
        frames=grammar.frames,
    )
    try:
        intent = _read(words, pending.priority, ctx, grammar)
    except Ambiguous as exc:  # another reference of the same sentence is ambiguous too
        talk.pending = Pending(pending.sentence, pending.priority, exc.at, exc.candidates, chosen)
        raise
    if isinstance(intent, Reply):  # pragma: no cover - a pending sentence is a command
        raise NotUnderstood("I lost track of the question; please say the whole command again.")
    if isinstance(intent, Command) and intent.goal.args:
        talk.last = intent.goal.args[0]
    return intent


__all__ = [
    "EXAMPLES",
    "STORAGE",
    "URGENT_PRIORITY",
    "Ambiguous",
    "Command",
    "Dialogue",
    "Grammar",
    "Incomplete",
    "Intent",
    "NotUnderstood",
    "Pending",
    "StatusRequest",
    "Stop",
    "UnknownReference",
    "default_grammar",
    "default_vocabulary",
    "describe",
    "interpret",
]
