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
cannot see ("over there") gets a question back. Progress is asked in the common wordings ("what
is the status?", "are you done yet?", "how long will it take?": a :class:`StatusRequest`).

Typos: a word a_hi does not know is read as one of its words when one reading is clearly meant
(:func:`_corrected`, candidates from spelling.py), and said back ("I read 'doimg' as 'doing'.");
a word as near two meanings is named with its candidates (:class:`Misspelt`).

Pipeline: :meth:`~.task_grammar.Grammar.tag` → typos corrected, if any →
:meth:`~.task_grammar.Grammar.parse` (every reading) → :class:`~.meaning.Reader` per reading →
the best: a command over a question over a refusal, then the reading whose prepositions are the
verb's arguments rather than an object's location.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
import math
import re
from dataclasses import dataclass

from services.agents.human_interface.dialogue import (
    OTHER_ONE,
    Answered,
    Dialogue,
    Offer,
    Pending,
    answer_to_offer,
    odd_literal,
    two_ways,
)
from services.agents.human_interface.grammar import ParseFailure, Word, normalise
from services.agents.human_interface.inflection import verb_lemmas
from services.agents.human_interface.intents import (
    STORAGE,
    URGENT_PRIORITY,
    Ambiguous,
    Command,
    Incomplete,
    Intent,
    Misspelt,
    NotUnderstood,
    ReadAs,
    StatusRequest,
    Stop,
    UnknownReference,
    WorldQuestion,
    describe,
    said_back,
    show,
)
from services.agents.human_interface.meaning import Context, Reader, Reply, loc_count, loc_depth
from services.agents.human_interface.questions import Resolve, read_question
from services.agents.human_interface.script import other_language, unreadable
from services.agents.human_interface.similarity import is_word
from services.agents.human_interface.spelling import candidates, correctable, known_words
from services.agents.human_interface.steps import Said, bare_bring, one_goal
from services.agents.human_interface.stop import StopWords, command_openings
from services.agents.human_interface.task_grammar import Grammar, default_grammar
from services.agents.human_interface.tolerance import (
    MAX_SENTENCES,
    NEGATING,
    OPENING,
    TYPO,
    readings,
    sentences,
)
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


class TooLong(NotUnderstood):
    """A line of more than :data:`MAX_READ_TOKENS` tokens: refused unparsed, and not read in
    any other way (tolerance.py)."""


def _within_bound(words: tuple[Word, ...]) -> tuple[Word, ...]:
    """``words``, when there are at most :data:`MAX_READ_TOKENS`; raises :class:`TooLong`
    (one line for the person) otherwise, before any parse."""
    if len(words) > MAX_READ_TOKENS:
        raise TooLong(
            f"That is too long for one request ({len(words)} words and phrases, at most "
            f"{MAX_READ_TOKENS}); say one thing at a time, e.g. {EXAMPLES[0]}."
        )
    return words


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
    :class:`Ambiguous` (a question: the next sentence may answer it),
    :class:`UnknownReference` or :class:`Misspelt` — with one line for the person;
    :class:`NotUnderstood` also for more than :data:`MAX_READ_TOKENS` tokens, a control
    character other than :data:`ALLOWED_CONTROLS` or a
    negative or zero deadline. While a question is open, a sentence with no verb (no new request)
    that does not answer it raises :class:`Ambiguous` with the question again, which stays open.

    A sentence holding words a_hi does not know is read with its typos corrected when one
    reading is clearly meant (:func:`_corrected`); the intent's ``read_as`` and the first words
    of a refusal or question say so ("I read 'doimg' as 'doing'.")."""
    vocab = vocabulary if vocabulary is not None else default_vocabulary()
    talk = dialogue if dialogue is not None else Dialogue()
    rules = grammar if grammar is not None else default_grammar()
    control = _control(sentence)
    if control is not None:
        raise control  # a refused line: the question asked, if any, stays open
    other = unreadable(sentence)
    if other is not None:
        raise NotUnderstood(f"{other}; I understand English only, e.g. {EXAMPLES[0]}.")
    try:
        return _interpret_line(sentence, priority, vocab, talk, rules)
    except (Ambiguous, Incomplete, Misspelt, TooLong):
        raise  # a question back, a typo named (the person answers it) or a line too long
    except NotUnderstood as exc:
        intent = _read_otherwise(sentence, priority, vocab, talk, rules)
        if intent is None:
            raise _in_other_language(sentence, vocab, rules) or exc from None
        return intent


MIN_UNKNOWN_SHARE = 0.5
"""A line is given to the language identifier only when at least this share of its words are
words a_hi does not know."""


def _in_other_language(sentence: str, vocab: Vocabulary, rules: Grammar) -> NotUnderstood | None:
    """The refusal of a line a_hi did not understand that is likely in another language
    (script.py :func:`~.script.other_language`), or None."""
    words = rules.tag(sentence, vocab)
    if not words or sum(w.kind == "WORD" for w in words) < MIN_UNKNOWN_SHARE * len(words):
        return None
    language = other_language(sentence)
    if language is None:
        return None
    return NotUnderstood(f"That looks like {language}; I understand English only, e.g. {EXAMPLES[0]}.")


def _read_otherwise(
    sentence: str, priority: int, vocab: Vocabulary, talk: Dialogue, rules: Grammar
) -> Intent | None:
    """The intent of the first other reading of ``sentence`` (tolerance.py) that is understood,
    saying what was read (``read_as``), or None; the dialogue as it was when none is. When no
    reading is an intent but one asks which thing is meant (which of two bowls; "should I pour
    …?"), that question is raised, saying what was read. A line of more than
    :data:`MAX_CORRECTED_TOKENS` tokens is not read otherwise (each reading is a parse)."""
    tagged = rules.tag(sentence, vocab)
    if len(tagged) > MAX_CORRECTED_TOKENS:
        return None
    said = (talk.last, talk.pending, talk.answered)
    typos = _possible_typos(tagged, vocab, rules)

    def tag(text: str) -> tuple[Word, ...]:  # a word that may be a typo marked (tolerance.py TYPO)
        return tuple(
            Word(TYPO, w.words, w.index) if w.kind == "WORD" and w.text in typos else w
            for w in rules.tag(text, vocab)
        )

    asked: tuple[NotUnderstood, Pending | None] | None = None
    for text in readings(sentence, tag, rules.verb_kinds, verb_lemmas):
        try:
            intent = _interpret_line(text, priority, vocab, talk, rules)
        except Ambiguous as exc:  # which thing, or "should I pour …?": asked if no reading is an intent
            if asked is None:
                asked = (_prefixed(exc, said_back(((sentence.strip(), text),))), talk.pending)
            talk.last, talk.pending, talk.answered = said
            continue
        except NotUnderstood:
            talk.last, talk.pending, talk.answered = said
            continue
        return dataclasses.replace(intent, read_as=((sentence.strip(), text), *intent.read_as))
    again = _said_again(sentence, priority, vocab, talk, rules)
    if again is None and asked is not None:
        talk.pending = asked[1]
        raise asked[0]
    return again


def _said_again(
    sentence: str, priority: int, vocab: Vocabulary, talk: Dialogue, rules: Grammar
) -> Intent | None:
    """The command of a line of several sentences, or of requests joined by "and", that each
    ask for it or only prepare it (steps.py: "I want the bowl. Bring it to me!": "it" the bowl
    the first names; "pick up the jar and pour it into the bowl"), the most urgent priority and
    the nearest deadline said; None when one of them reads as anything else (the dialogue
    unchanged)."""
    parts = _requests_said(sentence, vocab, rules)
    if not 1 < len(parts) <= MAX_SENTENCES:
        return None
    turn = dataclasses.replace(talk)
    said = _requests(parts, priority, vocab, turn, rules)
    commands = None if said is None else one_goal(said)
    if commands is None:
        return None
    talk.last, talk.pending, talk.answered = turn.last, None, turn.answered
    merged = _merged(commands)
    if len({c.goal for c in commands}) == 1:
        return merged
    return dataclasses.replace(merged, read_as=((sentence.strip(), parts[-1].strip()), *merged.read_as))


def _requests_said(sentence: str, vocab: Vocabulary, rules: Grammar) -> list[str]:
    """The sentences of ``sentence``, or its parts joined by "and" (:data:`AND`) when it is one,
    without those that only thank or open ("Thanks.", "Hmm.", "Okay.")."""
    parts = sentences(sentence)
    if len(parts) == 1:  # "pick up the bowl and hold it": one command said twice
        parts = [p for p in AND.split(sentence) if p.strip()]
    if len(parts) > 1:  # "First find the jar, then …": an order of steps, no urgency
        parts[0] = FIRST.sub("", parts[0], count=1)
    return [p for p in parts if not all(w.kind in OPENING or w.kind == "ASK" for w in rules.tag(p, vocab))]


FIRST = re.compile(r"^\s*(?:first(?:ly| of all)?|to start with)\b[\s,]*", re.IGNORECASE)
"""How the first of several steps may begin ("First take the jar. Then …")."""


AND = re.compile(r",?\s+\band(?:\s+then)?\s+|,\s*then\s+", re.IGNORECASE)
"""Where a sentence joins two requests with "and" or ", then" ("…, and then …", "first find
the jar, then bring it to me")."""


def _merged(commands: list[Command]) -> Command:
    """The last of ``commands`` (all of one goal) with the most urgent priority, the nearest
    deadline and every reading said back of them all."""
    deadlines = [c.deadline_s for c in commands if c.deadline_s is not None]
    return dataclasses.replace(
        commands[-1],
        priority=max(c.priority for c in commands),
        deadline_s=min(deadlines, default=None),
        read_as=tuple(pair for c in commands for pair in c.read_as),
    )


def _requests(
    parts: list[str], priority: int, vocab: Vocabulary, turn: Dialogue, rules: Grammar
) -> list[Said] | None:
    """The command (or yes-or-no question back) each of ``parts`` reads as, in order, in the
    dialogue ``turn``; None when one reads as anything else or is not understood."""
    said: list[Said] = []
    for part in parts:
        try:
            intent = _interpret_line(part, priority, vocab, turn, rules)
        except Offer as offer:
            said.append(offer)
            continue
        except NotUnderstood:
            return None
        if isinstance(intent, WorldQuestion):  # "Where is the jar? … Bring it.": it names the jar
            continue
        if not isinstance(intent, Command):
            return None
        said.append(_bare_bring(intent, part, vocab, rules))
    return said


def _bare_bring(intent: Command, part: str, vocab: Vocabulary, rules: Grammar) -> Said:
    """``intent``; a bring said with no one to bring it to ("take the cup and put it away") as
    either it or only taking the thing in a hand (steps.py: a step of what follows)."""
    if intent.goal.name != "bring" or any(w.kind in ("ME", "HERE", "TO") for w in rules.tag(part, vocab)):
        return intent
    return bare_bring(intent)


CRITICAL_KINDS = frozenset({"STOP", "URGENT", "EVERYTHING"})
"""Kinds of word whose misspelling must keep a clause (with the verbs and the negations)."""


def _possible_typos(words: tuple[Word, ...], vocab: Vocabulary, rules: Grammar) -> frozenset[str]:
    """The words of ``words`` a_hi does not know that may be typos of a word that changes what a
    command means (a verb, a stop, an urgency, a negation: "dnot"), so that no other reading
    leaves them out (tolerance.py ``TYPO``): no common English word (similarity.py ``is_word``:
    "cant", "hands" are words), and, for at most :data:`MAX_TYPO_WORDS` of them, with such a
    candidate (spelling.py); of more, every one that is no common word (the work of the
    candidates is bounded as the corrections' is)."""
    unknown = [w.text for w in words if w.kind == "WORD" and not is_word(w.text)]
    if len(unknown) > MAX_TYPO_WORDS:
        return frozenset(unknown)
    return frozenset(u for u in unknown if correctable(u) and candidates(u, _critical_words(rules)))


@functools.cache
def _critical_words(rules: Grammar) -> frozenset[str]:
    """The words of ``rules`` a misspelling of which must keep a clause (:func:`_possible_typos`)."""
    kinds = rules.verb_kinds | CRITICAL_KINDS
    return frozenset(w for phrase, kind in rules.phrases.items() if kind in kinds for w in phrase) | NEGATING


def _interpret_line(
    sentence: str, priority: int, vocab: Vocabulary, talk: Dialogue, rules: Grammar
) -> Intent:
    """:func:`interpret` of a line that holds no control character and is in Latin letters."""
    if OTHER_ONE.match(" ".join(normalise(sentence))):
        return _the_other_one(vocab, talk, rules)
    offered = answer_to_offer(sentence, talk)
    if offered is not None:
        return offered
    corrected: list[tuple[str, str]] = []
    question = read_question(sentence, _resolver(vocab, talk, rules, corrected))
    if question is not None:  # a question about the kitchen: any question asked back is dropped
        talk.pending = None
        if question.thing is not None:
            talk.last = question.thing
        return dataclasses.replace(question, read_as=tuple(corrected))
    words = _within_bound(rules.tag(sentence, vocab))
    fixed = _corrected(sentence, words, priority, vocab, talk, rules)
    if fixed is None:
        return _interpret_words(sentence, words, priority, vocab, talk, rules)
    text, words, read_as = fixed
    if not words:  # a stop, once corrected ("stpo"): acted on, whatever else the line holds
        talk.pending = None
        return Stop(read_as=read_as)
    try:
        intent = _interpret_words(text, words, priority, vocab, talk, rules)
    except NotUnderstood as exc:
        raise _prefixed(exc, said_back(read_as)) from None
    return dataclasses.replace(intent, read_as=(*read_as, *intent.read_as))


MAX_READ_TOKENS = 48
"""A sentence of more tokens (grammar.py's tags: a word, a phrase, a run of courtesy words) is
not parsed but refused: it bounds the parser's work, which grows with the tokens (a command
has at most about 20)."""
MAX_CORRECTED_TOKENS = 24
"""A sentence of more tokens is not corrected (it bounds the work: each reading tried is a parse)."""
MAX_TYPO_WORDS = 3
"""A sentence with more unknown words that could be typos is not corrected (nonsense, most
likely); the first unknown word is named, as for any sentence not understood."""
MAX_READINGS_TRIED = 8
"""At most this many corrected readings of one sentence are tried (one per combination of the
candidates of its unknown words); with more, it is not corrected."""


@functools.cache
def _stop_words(grammar: Grammar) -> StopWords:
    """a_hi's stop matcher (stop.py) for ``grammar``'s command words, built once per grammar."""
    return StopWords(command_openings(grammar))


def _corrected(
    sentence: str,
    words: tuple[Word, ...],
    priority: int,
    vocab: Vocabulary,
    talk: Dialogue,
    grammar: Grammar,
) -> tuple[str, tuple[Word, ...], ReadAs] | None:
    """``sentence`` with its typos corrected, when one reading is clearly meant: (the corrected
    words as text, their tokens, the corrections), the tokens empty when the corrected line is
    a stop (stop.py); None when it needs no correction or none reads.

    The unknown words (``WORD`` tokens) that may be typos (:func:`~.spelling.correctable`) get
    their candidates (spelling.py); each combination of candidates is a reading, kept when the
    corrected line is a stop or parses (a command, a status request, a question back, an answer
    to the question open). The readings kept all mean the same: the one taken is the one whose
    corrected words end with the letter they were written with ("minuts": "minutes"). They mean
    different things: :class:`Misspelt` names the first word they differ in and its candidates.
    Bounded: :data:`MAX_CORRECTED_TOKENS`, :data:`MAX_TYPO_WORDS`, :data:`MAX_READINGS_TRIED`."""
    if len(words) > MAX_CORRECTED_TOKENS:
        return None
    options = _typo_options(words, vocab, grammar)
    readings = [
        reading
        for chosen in _choices(options)
        for reading in _reading(sentence, words, chosen, priority, vocab, talk, grammar)
    ]
    if not readings:
        return None
    if len({r.meaning for r in readings}) > 1:
        raise _misspelt(readings, words)
    written = {w.index: w.text for w in words}
    best = min(  # of equal meanings, the one whose words end as written ("minuts": "minutes")
        readings, key=lambda r: sum(c[-1] != written[i][-1] for i, c in r.chosen.items())
    )
    return best.text, best.words, tuple((written[i], c) for i, c in sorted(best.chosen.items()))


@dataclass(frozen=True)
class _Reading:
    """A sentence read with typos corrected: ``chosen`` (token index → the word read), the
    corrected ``text`` and its tokens (``words``, empty for a stop), and its ``meaning`` (a key
    equal for equal meanings)."""

    chosen: dict[int, str]
    text: str
    words: tuple[Word, ...]
    meaning: str


def _typo_options(
    words: tuple[Word, ...], vocab: Vocabulary, grammar: Grammar
) -> list[tuple[Word, tuple[str, ...]]]:
    """The unknown words of ``words`` that may be typos, each with its candidates (spelling.py);
    empty when there is none, or more than :data:`MAX_TYPO_WORDS`, or more than
    :data:`MAX_READINGS_TRIED` combinations of candidates."""
    typos = [w for w in words if w.kind == "WORD" and correctable(w.text)]
    if len(typos) > MAX_TYPO_WORDS:
        return []
    known = known_words(grammar.phrases, vocab)
    options = [(w, found) for w in typos if (found := candidates(w.text, known))]
    return options if math.prod(len(c) for _, c in options) <= MAX_READINGS_TRIED else []


def _choices(options: list[tuple[Word, tuple[str, ...]]]) -> list[dict[int, str]]:
    """Each combination of the candidates in ``options``: token index → the word read (none
    when there are no options)."""
    if not options:
        return []
    combinations = itertools.product(*(c for _, c in options))
    return [{w.index: c for (w, _), c in zip(options, choice, strict=True)} for choice in combinations]


def _reading(
    sentence: str,
    words: tuple[Word, ...],
    chosen: dict[int, str],
    priority: int,
    vocab: Vocabulary,
    talk: Dialogue,
    grammar: Grammar,
) -> list[_Reading]:
    """``sentence`` read with the words ``chosen``: a stop (stop.py), or what its tokens mean
    (:func:`_meaning`); none when it reads as neither."""
    text = " ".join(chosen.get(w.index, w.text) for w in words)
    if _stop_words(grammar).match(_replaced(sentence, words, chosen) or text) is not None:
        return [_Reading(chosen, text, (), "a stop")]
    fixed = grammar.tag(text, vocab)
    meaning = _meaning(fixed, priority, vocab, talk, grammar)
    return [_Reading(chosen, text, fixed, meaning)] if meaning is not None else []


def _misspelt(readings: list[_Reading], words: tuple[Word, ...]) -> Misspelt:
    """The first word the ``readings`` differ in, named with the words it was read as."""
    at = next(i for i in sorted(readings[0].chosen) if len({r.chosen[i] for r in readings}) > 1)
    said = next(w.text for w in words if w.index == at)
    options = tuple(sorted({r.chosen[at] for r in readings}))
    quoted = [f"'{o}'" for o in options]
    meant = ", ".join(quoted[:-1]) + " or " + quoted[-1]
    return Misspelt(
        f"I do not know '{said}': did you mean {meant}? Say it again with the word you meant.", said, options
    )


def _replaced(sentence: str, words: tuple[Word, ...], chosen: dict[int, str]) -> str | None:
    """``sentence`` as written, each corrected word replaced (its marks kept, for stop.py's
    clauses); None when a word is not found as written ("what's": normalised)."""
    out = sentence
    for w in words:
        if w.index in chosen:
            pattern = re.compile(rf"(?<![^\W_]){re.escape(w.text)}(?![^\W_])", re.IGNORECASE)
            out, n = pattern.subn(chosen[w.index], out, count=1)
            if n == 0:
                return None
    return out


def _meaning(
    words: tuple[Word, ...], priority: int, vocab: Vocabulary, talk: Dialogue, grammar: Grammar
) -> str | None:
    """What the tokens ``words`` mean, as a key that is equal for equal meanings ("within two
    minute" and "within two minutes"), when they parse and mean something: an intent, a question
    back or a refusal of what they name — an answer only while a question is open; else None.
    Changes nothing."""
    ctx = Context(
        vocab,
        last=talk.last,
        among=talk.pending.candidates if talk.pending else (),
        token_seconds={w.index: w.seconds for w in words if w.seconds is not None},
        frames=grammar.frames,
    )
    try:
        outcome = _read(words, priority, ctx, grammar)
    except ParseFailure:
        return None
    except NotUnderstood as exc:
        return f"{type(exc).__name__}: {exc}"
    if isinstance(outcome, Reply) and talk.pending is None:
        return None
    return repr(outcome)


MAX_NAMED = 3
"""At most this many more unknown words are named in a refusal (:func:`_also_unknown`)."""


def _also_unknown(exc: NotUnderstood, words: tuple[Word, ...], known: frozenset[str]) -> NotUnderstood:
    """``exc`` naming also the sentence's other unknown words, up to :data:`MAX_NAMED` ("I do
    not know the word 'or' here; … I do not know 'jra' either."): a typo the refusal does not
    stop at is named too. A word a_hi knows elsewhere (``known``: :func:`known_words`; a
    number) but not where it stands is not named: it is not unknown ("2 minutes" after a
    misspelt "within")."""
    said = str(exc)
    others = [
        w.text
        for w in words
        if w.kind == "WORD" and f"'{w.text}'" not in said and w.text not in known and not w.text.isdigit()
    ]
    others = list(dict.fromkeys(others))[:MAX_NAMED]
    if not others:
        return exc
    quoted = [f"'{o}'" for o in others]
    listed = quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " or " + quoted[-1]
    return _prefixed(exc, "", f" I do not know {listed} either.")


def _prefixed(exc: NotUnderstood, prefix: str, suffix: str = "") -> NotUnderstood:
    """``exc`` with ``prefix`` before its message and ``suffix`` after it (its kind and data kept)."""
    text = f"{prefix} {exc}{suffix}".lstrip()
    if isinstance(exc, Ambiguous):
        return Ambiguous(text, exc.at, exc.candidates)
    if isinstance(exc, Incomplete):
        return Incomplete(text, exc.missing)
    if isinstance(exc, Misspelt):
        return Misspelt(text, exc.word, exc.candidates)
    return type(exc)(text)


def _interpret_words(
    sentence: str,
    words: tuple[Word, ...],
    priority: int,
    vocab: Vocabulary,
    talk: Dialogue,
    rules: Grammar,
) -> Intent:
    """:func:`interpret` of the tagged ``words`` of ``sentence``."""
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
        known = known_words(rules.phrases, vocab)
        raise _also_unknown(_failure(exc, vocab, priority, ctx, rules), words, known) from None
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
        if pending.offer is not None:
            talk.pending = pending
            raise _again(pending, "Please say 'yes' or 'no'.")
        if intent.name not in pending.candidates:
            talk.pending = pending
            options = ", ".join(show(c) for c in pending.candidates)
            raise Ambiguous(
                f"I asked about {options}; which of them do you mean?", pending.at, pending.candidates
            )
        chosen = {**pending.chosen, pending.at: intent.name}
        resumed = _with_reply(_resume(pending, chosen, vocab, talk, rules), intent)
        if isinstance(resumed, Command):
            talk.answered = Answered(pending, chosen, resumed.goal)
        return resumed
    if isinstance(intent, Command):
        talk.answered = None  # a new command: "the other one" no longer refers to an answer
        if intent.goal.args:
            talk.last = intent.goal.args[0]
        verb = next((w.text for w in words if w.kind in ("BRING", "TAKE")), "")
        odd = odd_literal(intent, vocab) or two_ways(intent, [w.kind for w in words], verb)
        if odd is not None:
            talk.pending = Pending(sentence, priority, -1, (), question=str(odd), offer=odd.offer)
            raise odd
    return intent


def _resolver(
    vocab: Vocabulary, talk: Dialogue, grammar: Grammar, corrected: list[tuple[str, str]] | None = None
) -> Resolve:
    """How a question's reference is resolved (questions.py): read with the command grammar as a
    bare reference, against ``vocab`` and the person's last object ("it"); None when the words
    read as something else (a stop, a command). A word it does not know with exactly one
    candidate (spelling.py: "jsr", "jar") is read as that word when the reference then names a
    thing, the correction added to ``corrected`` (said back)."""

    def resolve(words: str) -> str | None:
        tagged = grammar.tag(words, vocab)
        ctx = Context(vocab, last=talk.last, frames=grammar.frames)
        try:
            outcome = _read(tagged, 0, ctx, grammar)
        except ParseFailure:
            fixed = _one_candidate_each(tagged, vocab, grammar)
            if not fixed:
                raise  # a word with no candidate, or with several: not guessed
            outcome = _read(
                grammar.tag(" ".join(fixed.get(w.text, w.text) for w in tagged), vocab), 0, ctx, grammar
            )
            if corrected is not None and isinstance(outcome, Reply):
                corrected.extend(fixed.items())
        return outcome.name if isinstance(outcome, Reply) else None

    return resolve


def _one_candidate_each(words: tuple[Word, ...], vocab: Vocabulary, grammar: Grammar) -> dict[str, str]:
    """Each unknown word of ``words`` with the one word it may be a typo of (:func:`_typo_options`);
    empty when one has none or several."""
    options = _typo_options(words, vocab, grammar)
    if len(options) != sum(w.kind == "WORD" for w in words) or any(len(found) != 1 for _, found in options):
        return {}
    return {w.text: found[0] for w, found in options}


def _the_other_one(vocab: Vocabulary, talk: Dialogue, grammar: Grammar) -> Intent:
    """The command of the person's last answer, with the other of the two things a_hi's
    question offered ("no, the other one"), replacing it (``instead_of``). Raises
    :class:`NotUnderstood` when no question of two was answered last, or one is open."""
    answered = talk.answered
    if talk.pending is not None:
        raise _again(talk.pending, "Please say which one you mean.")
    if answered is None or len(answered.pending.candidates) != 2:
        raise NotUnderstood(
            "I did not offer you a choice of two just now; say which one you mean, "
            "e.g. 'bring me the cup on the table'."
        )
    at = answered.pending.at
    other = next(c for c in answered.pending.candidates if c != answered.chosen.get(at))
    chosen = {**answered.chosen, at: other}
    intent = _resume(answered.pending, chosen, vocab, talk, grammar)
    if not isinstance(intent, Command):  # pragma: no cover - a pending sentence is a command
        return intent
    talk.answered = Answered(answered.pending, chosen, intent.goal)
    return dataclasses.replace(intent, instead_of=answered.goal)


def _again(pending: Pending, why: str) -> Ambiguous:
    """The pending question asked again after an answer that names none of its candidates."""
    question = pending.question or "Which of " + ", ".join(show(c) for c in pending.candidates) + "?"
    return Ambiguous(f"{why} {question}", pending.at, pending.candidates)


def _with_reply(intent: Intent, reply: Reply) -> Intent:
    """``intent`` (the command an answer completed) with the urgency and deadline said in the
    answer ("the small one, and make it quick"); a deadline said in the answer wins."""
    if not isinstance(intent, Command):
        return intent
    priority = max(intent.priority, URGENT_PRIORITY) if reply.urgent else intent.priority
    deadline = reply.deadline_s if reply.deadline_s is not None else intent.deadline_s
    return dataclasses.replace(intent, priority=priority, deadline_s=deadline)


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
    "Misspelt",
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
