"""From a sentence to an intent: an L_HC command, a stop, a status request, a question about the
kitchen (questions.py, read first) — or one line back.

Named simplifications (paper §5.2 leaves the human interface open): the understanding is a
**hand-written grammar** of English kitchen commands (grammar.lark, parsed by lark's Earley
parser) — English only, typed text only (no speech), no statistical language model. What it
covers: the verbs and frames of every task a_pl knows (those with rich particle structure in
grammar.lark and meaning.py; the others as data, tasks.toml, made into rules by
task_grammar.py), prepositions and particles, also before the object ("out of", "onto", "back
in", "take out the jar", "put down the bowl"), determiners, adjectives and owners ("the small
cup", "the jar's contents"), "the contents of the jar", polite framing before or after a command
("could you …?", "would you mind pouring …", "I need you to …", "…, will you?", "please",
"thanks"), wishes ("I'd like the cup", "can I have the cup"), urgency ("urgently", "right
away", … → :data:`URGENT_PRIORITY`) and deadlines ("within 2 minutes", "in twenty seconds",
"in half an hour"), and "it"/"that" for the last object the same person named.

The words for things are not listed here: they are the vocabulary a_km gives (vocabulary.py:
labels and adjectives in O_RoCo and the knowledge base), so a thing a_km learns about can be
named at once. A reference naming more than one thing gets a question back ("Which cup: the one
in the cabinet or the one on the table?"); the person's next sentence may answer it ("the one on
the table"), and the command goes on — a :class:`Dialogue` per person keeps that and the last
object named; an answer naming none of the candidates ("hmm", "I don't know") gets the question
again. A sentence not understood gets one line naming the word or the missing part and what
could be said instead (:class:`NotUnderstood` and its subclasses, intents.py); so does one with a
control character (:data:`ALLOWED_CONTROLS`) or a negative or zero deadline, and a place a_hi
cannot see ("over there") gets a question back.

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
    WorldQuestion,
    describe,
    show,
)
from services.agents.human_interface.meaning import Context, Reader, Reply, loc_count, loc_depth
from services.agents.human_interface.questions import Resolve, read_question
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
    settled by earlier answers; ``question`` the question as asked (asked again when an answer
    names nothing)."""

    sentence: str
    priority: int
    at: int
    candidates: tuple[str, ...]
    chosen: dict[int, str] = field(default_factory=dict)
    question: str = ""


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


ALLOWED_CONTROLS = frozenset("\t\n\r")
"""Control characters a sentence may hold (read as spaces); any other C0 or C1 control
character (U+0000–U+001F, U+007F–U+009F) gets the sentence refused."""


def _control(sentence: str) -> NotUnderstood | None:
    """The refusal of a sentence holding a control character other than :data:`ALLOWED_CONTROLS`, or None."""
    for i, c in enumerate(sentence):
        code = ord(c)
        if (code < 0x20 or 0x7F <= code <= 0x9F) and c not in ALLOWED_CONTROLS:
            return NotUnderstood(
                f"Your sentence holds a control character (U+{code:04X}, character {i + 1}); "
                f"type it again without it, e.g. {EXAMPLES[0]}."
            )
    return None


def _bad_deadline(words: tuple[Word, ...]) -> NotUnderstood | None:
    """The refusal of a negative or zero deadline ("within -5 seconds"), or None."""
    for w in words:
        if w.kind == "DEADLINE" and w.seconds is not None and w.seconds <= 0:
            wrong = "is negative" if w.seconds < 0 else "leaves no time"
            return NotUnderstood(
                f"The deadline '{w.text}' {wrong}; give a time from now, e.g. 'within 30 seconds'."
            )
    return None


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


def _said(words: tuple[Word, ...]) -> str:
    """Tagged words as the person wrote them, near enough: "the jar's", not "the jar s"."""
    return "".join("'s" if w.kind == "POSS" else (" " if i else "") + w.text for i, w in enumerate(words))


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
    before = _said(words[: at.index]) or "the start"
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
    :class:`UnknownReference` — with one line for the person; :class:`NotUnderstood` also for a
    control character other than :data:`ALLOWED_CONTROLS` or a negative or zero deadline. While a
    question is open, a sentence with no verb (no new request) that does not answer it raises
    :class:`Ambiguous` with the question again, which stays open."""
    vocab = vocabulary if vocabulary is not None else default_vocabulary()
    talk = dialogue if dialogue is not None else Dialogue()
    rules = grammar if grammar is not None else default_grammar()
    control = _control(sentence)
    if control is not None:
        raise control  # a refused line: the question asked, if any, stays open
    question = read_question(sentence, _resolver(vocab, talk, rules))
    if question is not None:  # a question about the kitchen: any question asked back is dropped
        talk.pending = None
        if question.thing is not None:
            talk.last = question.thing
        return question
    words = rules.tag(sentence, vocab)
    bad = _bad_deadline(words)
    if bad is not None:
        raise bad
    pending, talk.pending = talk.pending, None
    ctx = Context(
        vocab,
        last=talk.last,
        among=pending.candidates if pending else (),
        token_seconds={w.index: w.seconds for w in words if w.seconds is not None},
        frames=rules.frames,
    )
    answering = pending is not None and not any(w.kind in rules.verb_kinds for w in words)
    try:
        intent = _read(words, priority, ctx, rules)
    except ParseFailure as exc:
        if words and words[0].kind == "STOP":  # "stop the pouring": a stop is never refused
            return Stop()
        if answering and pending is not None:  # "hmm", "I don't know": the question again
            talk.pending = pending
            raise _again(pending, "That does not answer my question.") from None
        raise _failure(exc, vocab, priority, ctx, rules) from None
    except Ambiguous as exc:
        if answering and pending is not None:  # "the cup", when both were asked about
            talk.pending = pending
            raise _again(pending, "That fits more than one.") from None
        talk.pending = Pending(sentence, priority, exc.at, exc.candidates, question=str(exc))
        raise
    except NotUnderstood as exc:
        if answering and pending is not None:  # "it" with nothing named, "the large jar"
            talk.pending = pending
            why = str(exc) if isinstance(exc, UnknownReference) else "That does not answer my question."
            raise _again(pending, why) from None
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


def _resolver(vocab: Vocabulary, talk: Dialogue, grammar: Grammar) -> Resolve:
    """How a question's reference is resolved (questions.py): read with the command grammar as a
    bare reference, against ``vocab`` and the person's last object ("it"); None when the words
    read as something else (a stop, a command)."""

    def resolve(words: str) -> str | None:
        tagged = grammar.tag(words, vocab)
        ctx = Context(vocab, last=talk.last, frames=grammar.frames)
        outcome = _read(tagged, 0, ctx, grammar)
        return outcome.name if isinstance(outcome, Reply) else None

    return resolve


def _again(pending: Pending, why: str) -> Ambiguous:
    """The pending question asked again after an answer that names none of its candidates."""
    question = pending.question or "Which of " + ", ".join(show(c) for c in pending.candidates) + "?"
    return Ambiguous(f"{why} {question}", pending.at, pending.candidates)


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
        talk.pending = Pending(pending.sentence, pending.priority, exc.at, exc.candidates, chosen, str(exc))
        raise
    if isinstance(intent, Reply):  # pragma: no cover - a pending sentence is a command
        raise NotUnderstood("I lost track of the question; please say the whole command again.")
    if isinstance(intent, Command) and intent.goal.args:
        talk.last = intent.goal.args[0]
    return intent


__all__ = [
    "ALLOWED_CONTROLS",
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
    "WorldQuestion",
    "default_grammar",
    "default_vocabulary",
    "describe",
    "interpret",
]
