"""Other readings of a person's line that a_hi did not understand as said: what people add to a
command and what they correct in it, taken out so that the command is read (grammar.lark stays a
grammar of commands, not of everything said around them; docs/agents.md, "Around a command",
has the examples).

:func:`readings` gives, in order, the texts to read instead of the line, each at most once:

1. **A self-correction** ("…, sorry, I mean the bowl"): what follows the last marker
   (:data:`CORRECTION`) replaces the one noun phrase before it, or the whole command when it
   begins with a verb; with two noun phrases before it, the line is not read otherwise.
2. **An opener of a follow-up** ("and then …", "also …"): left out (:data:`OPENERS`).
3. **Clauses that carry nothing a_hi needs** ("Hiya robot!", ", would you, love?"): a clause
   before the command that holds no word of a command and no negation (:data:`NEGATIONS`); one
   after it also when it holds "it" or a negation of something else, never one that names an
   object, an urgency, another request or offers another choice ("…, or maybe not"); words
   before the command's first word on the same terms.
4. **Word order of another language**: courtesy inside the command left out, "the" before a
   bare object, "to me" moved to the end, "you" before the verb left out, an object said before
   its verb put after it, the word of the verb's frame put between two bare objects
   ("pour(jar, bowl)"), a "me" after a verb of pouring or putting left out.
5. **A tail after the command** ("… for the kids", "… pls my mom is coming"): from the word that
   begins it (:data:`TAIL_OPENERS`) to the end, when it names no object, verb, stop, urgency or
   deadline and holds no negation or condition (:data:`CONDITIONS`); a last "already" too.
6. **No verb** ("Bowl on table.", "Bowl to me, now!", "Beans to bowl."): "put" before a line
   that names a place or where to, "bring" before one that says "to me" or "here"; no question.
7. **When, said apart** ("…, I need it within a minute"): joined to the command.
8. **A wish with the verb after the thing** ("I need the beans poured into the bowl", "the cup
   should be in the cabinet"): the verb's base form first (inflection.py; "go" and "be" before
   a place as "put"), only words of a wish before and modal words between, no negation or
   condition; a participle with no wish is said, not asked.
9. **Words a_hi does not know, left out**, when the line asks for one task with no negation,
   condition, stop or question word first, and each names no thing, acts on none and none ends
   the line.

A line that tells of the robot doing something ("I'm watching you pour the jar …") is read no
other way. Before these, a line of several sentences (:func:`sentences`) is read as each one
alone whose other sentences are asides (no verb, stop, urgency, deadline or progress question,
and, with a negation, no object; the verbs of a question asked aloud, of what the person says of
themselves and of a word after "is" ask for nothing): "it" is the one object the asides name,
"them" the one in the plural, else the subject of the aside just before.

Each reading is read as a whole line is (language.py :func:`~.language.interpret`) and the first
that gives an intent is taken and said back (``read_as``). A reading never adds a word that
changes what is meant: it leaves words out, moves them, adds "the", names what "it" is, adds
"put" or "bring" to a line with no verb, or says a verb in its base form. The work is bounded:
the line is at most ``MAX_LINE_CHARS`` characters (services/runtime/human.py), at most
:data:`MAX_CLAUSES` clauses are looked at and at most :data:`MAX_READINGS` readings given."""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable

from services.agents.human_interface.grammar import UNITS, Word

MAX_CLAUSES = 6
"""A line of more clauses is not shortened by clause (its runs grow with the square)."""
MAX_READINGS = 12
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
CONTRACTED_NEGATIONS = frozenset(
    {
        "cant", "wont", "isnt", "arent", "wasnt", "werent", "didnt", "doesnt", "dont", "hasnt",
        "havent", "hadnt", "wouldnt", "shouldnt", "couldnt", "mustnt", "neednt", "shant", "aint",
    }
)  # fmt: skip
"""Negations said with "n't" (apostrophes dropped: grammar.py ``normalise``)."""
NEGATING = NEGATIONS | CONTRACTED_NEGATIONS
"""Every word that negates: what holds one is left out only where a negation of something else
cannot change the command (:func:`_negation`)."""
TYPO = "TYPO"
"""The kind the tagger given to :func:`readings` gives a word a_hi does not know that may be a
typo of one it knows (spelling.py): it may be a negation or a verb misspelt ("dnot"), so what
holds it is never left out."""
CLAUSE = re.compile(r"[,;.!?:]+")
MEANINGFUL = frozenset(
    {
        "NOUN", "ADJ", "PLURAL", "IT", "ONE", "CONTENTS", "DEADLINE", "WITHIN", "URGENT",
        "EVERYTHING", "STATUS", "STATUS_TAIL", "STOP", "AND", "DOWN", "UP", "OUT", "AWAY", "BACK",
        "HOME", "HERE", TYPO,
    }
)  # fmt: skip
"""Kinds of word (grammar.py's tags) that carry a command's meaning; "and" or "then" begins
another request, which is not left out unread."""
COURTESY = frozenset({"PLEASE", "POLITE", "THANKS"})
"""Kinds of word a command holds only as courtesy."""
ASIDE_STOPPERS = frozenset(
    {"STOP", "URGENT", "DEADLINE", "WITHIN", "STATUS", "STATUS_TAIL", "EVERYTHING", TYPO}
)
"""Kinds of word an aside never holds: it would carry a command's meaning."""
OBJECT = frozenset({"NOUN", "ADJ", "PLURAL", "ONE", "CONTENTS"})
"""Kinds of word that name an object."""

Tagger = Callable[[str], tuple[Word, ...]]
"""The tags of a text (a_hi's grammar and vocabulary: task_grammar.py ``Grammar.tag``)."""


def readings(
    line: str, tag: Tagger, verbs: frozenset[str], lemmas: Callable[[str], tuple[str, ...]] = lambda w: ()
) -> list[str]:
    """The other texts to read for ``line``, best first (module docstring); ``verbs``: the
    kinds of word that begin a command (``Grammar.verb_kinds``); ``lemmas``: a word's base
    forms as a verb (inflection.py ``verb_lemmas``; none by default). Empty when there is none,
    and for a line that tells of the robot doing something (:func:`_told_of_you`)."""
    return [] if _told_of_you(tag(line), verbs, lemmas) else _readings(line, tag, verbs, lemmas)


def _readings(
    line: str, tag: Tagger, verbs: frozenset[str], lemmas: Callable[[str], tuple[str, ...]]
) -> list[str]:
    out: list[str] = []

    def add(text: str) -> None:
        text = " ".join(text.split())
        if text and text.lower() != " ".join(line.split()).lower() and text not in out:
            out.append(text)

    corrected = self_corrected(line, tag, verbs)
    if corrected is not None:
        add(corrected)
    for alone in one_sentence(line, tag, verbs):
        add(alone)
    for base in [line, *out]:
        opened = OPENERS.sub("", base, count=1)
        if opened != base:
            add(opened)
    for base in [line, *out]:
        for kept in kept_clauses(base, tag, verbs):
            add(kept)
    for base in [line, *out]:
        add(after_prefix(base, tag, verbs))
    for base in [line, *out]:
        add(reordered(base, tag, verbs))
        add(without_tail(base, tag, verbs))
        add(without_impatience(base, tag, verbs))
        add(verbless(base, tag, verbs))
        add(time_joined(base, tag))
        add(wished(base, tag, verbs, lemmas))
    for base in [line, *out]:
        add(without_unknown(base, tag, verbs))
    return out[:MAX_READINGS]


def _told_of_you(
    words: tuple[Word, ...], verbs: frozenset[str], lemmas: Callable[[str], tuple[str, ...]]
) -> bool:
    """Whether ``words`` tell of the robot doing something rather than ask it: a verb a_hi does
    not know, then "you", then a command's verb ("I'm watching you pour the jar …", "I saw you
    bring …"): no other reading may leave the words before "you" out."""
    return any(
        words[i].kind == "W_YOU"
        and words[i + 1].kind in verbs
        and words[i - 1].kind == "WORD"
        and bool(lemmas(words[i - 1].text))
        for i in range(1, len(words) - 1)
    )


UNKNOWN_THING_BEFORE = frozenset({"DET", "ADJ", "POSS", "OF"})
"""Kinds of word after which an unknown word names a thing a_hi does not know ("the school")."""
ACTED_ON = frozenset({"DET", "NOUN", "PLURAL", "CONTENTS", "IT", "ME", "ONE", "ADJ", "EVERYTHING"})
"""Kinds of word before which an unknown word may act on a thing ("burn the jar", "next to it"
is "next" before "to": see :func:`_harmless`)."""


def without_unknown(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` without the words a_hi does not know, when each is harmless (:func:`_harmless`),
    none ends the line (it may say how soon) and the line asks for one task with no negation,
    condition or question word first ("could you kindly just pour the beans into the bowl real
    quick mate"); else ``line``."""
    words = tag(line)
    if not _plain_request(line, words, verbs) or words[-1].kind == "WORD":  # "… sharp sharp": how, maybe when
        return line
    if not all(_harmless(words, i) for i, w in enumerate(words) if w.kind == "WORD"):
        return line
    return " ".join(w.text for w in words if w.kind != "WORD")


def _plain_request(line: str, words: tuple[Word, ...], verbs: frozenset[str]) -> bool:
    """Whether ``words`` hold one verb of a task (said once or again), no negation, condition,
    stop, progress question or possible typo, and begin with no question word."""
    tasks = {w.kind for w in words if w.kind in verbs and w.kind not in NOT_TASKS}
    if len(tasks) != 1 or (words and words[0].words[0] in QUESTION_WORDS):
        return False
    blocked = ("STOP", "STATUS", "STATUS_TAIL", TYPO)
    return not any(_negation(w) or w.words[0] in CONDITIONS or w.kind in blocked for w in words)


def _harmless(words: tuple[Word, ...], i: int) -> bool:
    """Whether the unknown ``words[i]`` can be left out without changing what is asked: it
    names no thing (no determiner or describing word before it), acts on none (no object after
    it, nor a "to"/"in"/"on" with one: "next to it") and is no time ("a minute ago")."""
    before = words[i - 1].kind if i > 0 else ""
    after = words[i + 1].kind if i + 1 < len(words) else ""
    then = words[i + 2].kind if i + 2 < len(words) else ""
    if before in UNKNOWN_THING_BEFORE or after in ACTED_ON or _timed(words[i]):
        return False
    return not (after in ("TO", "IN", "ON") and then in ACTED_ON)


TIME_KINDS = frozenset({"DEADLINE", "URGENT"})
WISH_WORDS = frozenset({"i", "we", "need", "want", "it", "that", "this", "done", "ready", "by", "please"})
"""Words a clause that only says when may hold besides the time ("I need it within a minute")."""


NOT_TASKS = frozenset({"STATUS", "STOP", "WANT", "W_DO", "W_HAVE", "HAVE", "W_SHOW", "W_TELL", "W_CHECK"})
"""Verb kinds that begin no task of a_pl's ("stopped", "wanted", "done", "shown")."""
GO = frozenset({"go", "goes"})
""""The beans go in the bowl": the thing is to be put there ("went" says where it was)."""
MODALS = frozenset(
    {"need", "needs", "to", "should", "must", "has", "have", "got", "can", "could", "will", "would", "shall"}
)
"""Words between the thing and what is to be done to it ("the bowl needs to go …", "the beans
should be poured …")."""
WISHING = MODALS | {"i", "we", "want", "wants", "wanna", "like", "id", "get", "make", "let"}
"""Words of a wish before the thing wished done ("I need the beans poured …", "make the beans
go …", "can the bowl go …")."""
WISH_KINDS = frozenset({"PLEASE", "POLITE", "ADDRESS", "THANKS", "ASK", "WANT", "W_HAVE", "HAVE"})
PHRASE = frozenset({"DET", "ADJ", "NOUN", "PLURAL", "CONTENTS", "ONE", "IT", "POSS", "OF"})
"""Kinds of word of a noun phrase."""


def wished(line: str, tag: Tagger, verbs: frozenset[str], lemmas: Callable[[str], tuple[str, ...]]) -> str:
    """``line`` as a command when it wishes a thing done with a task's verb after the thing
    ("I need the beans poured into the bowl" → "pour the beans into the bowl", "can you get the
    cup brought to me", "make the beans go in the bowl" → "put the beans in the bowl", "the cup
    should be in the cabinet" → "put the cup in the cabinet"; module docstring 8): ``lemmas``
    gives a word's base forms as a verb (inflection.py). Else ``line``; also when the line holds
    a negation or a condition."""
    words = tag(line)
    if any(_negation(w) or w.words[0] in CONDITIONS for w in words):
        return line
    done = ((i, v) for i in range(len(words)) if (v := _done_verb(words, i, tag, verbs, lemmas)))
    at, verb = next(done, (0, ""))
    thing = _wished_thing(words, at) if verb else None
    if thing is None:
        return line
    return " ".join([verb, *(w.text for w in words[thing[0] : thing[1]]), *(w.text for w in words[at + 1 :])])


def _wished_thing(words: tuple[Word, ...], at: int) -> tuple[int, int] | None:
    """Where the thing wished done by the verb ``words[at]`` stands (start, end), when only
    modal words stand between them and only words of a wish before it; None otherwise, also
    for a participle with no wish ("the beans poured into …" is said, not asked)."""
    end = _before(words, at, lambda w: w.words[0] in MODALS or w.words == ("be",))
    start = _before(words, end, lambda w: w.kind in PHRASE)
    if start == end or not all(_wishing(w) for w in words[:start]):
        return None
    return (start, end) if start > 0 or end < at or words[at].words[0] in GO else None


def _before(words: tuple[Word, ...], i: int, keep: Callable[[Word], bool]) -> int:
    """The index of the first of the words before ``i`` that all ``keep`` (``i`` when none)."""
    while i > 0 and keep(words[i - 1]):
        i -= 1
    return i


def _done_verb(
    words: tuple[Word, ...],
    at: int,
    tag: Tagger,
    verbs: frozenset[str],
    lemmas: Callable[[str], tuple[str, ...]],
) -> str:
    """The task verb ``words[at]`` says done ("poured" → "pour", "goes" → "put", "be" before a
    place → "put"), or ""."""
    word = words[at]
    if word.words[0] in GO:
        return "put"
    if word.words == ("be",):
        return "put" if at + 1 < len(words) and words[at + 1].kind in PLACES else ""
    if word.kind != "WORD":
        return ""
    tasks = verbs - NOT_TASKS
    return next(
        (lemma for lemma in lemmas(word.text) if [w.kind for w in tag(lemma)] in ([k] for k in tasks)), ""
    )


def _wishing(word: Word) -> bool:
    """Whether ``word`` may stand before the thing wished done (:data:`WISHING`, courtesy)."""
    return word.kind in WISH_KINDS or set(word.words) <= WISHING


def time_joined(line: str, tag: Tagger) -> str:
    """``line`` with a clause that only says when the command is wanted joined to the command
    ("pour the jar into the bowl, I need it within a minute" → "… within a minute"; module
    docstring 7); else ``line``."""
    clauses = [c for c in CLAUSE.split(line) if c.strip()]
    for i, clause in enumerate(clauses[1:MAX_CLAUSES], start=1):
        times = _only_when(tag(clause))
        if times:
            kept = clauses[:i] + clauses[i + 1 :]
            return ", ".join(c.strip() for c in kept) + " " + times
    return line


def _only_when(words: tuple[Word, ...]) -> str:
    """The deadline and urgency words of a clause that says nothing else but a wish ("I need it
    within a minute" → "within a minute"); "" for any other clause."""
    if not all(w.kind in TIME_KINDS or set(w.words) <= WISH_WORDS for w in words):
        return ""
    return " ".join(w.text for w in words if w.kind in TIME_KINDS)


TAIL_OPENERS = frozenset(
    {
        "for", "before", "because", "cause", "so", "when", "whenever", "once",
        "i", "im", "ive", "id", "my", "we", "were", "our", "youre", "thats",
    }
)  # fmt: skip
"""Words that begin a reason, a beneficiary, a courtesy or a remark after a command, said
without a comma ("… pls my mom is coming", "… and then you're all set"; module docstring 5)."""
TAIL_JOINS = frozenset({"and", "then", "so"})
"""Words that joined the command to a tail left out: they go with it."""
CONDITIONS = frozenset({"if", "unless", "until", "only", "after", "while", "then"})
"""Words that make what follows a command a condition on it: never left out."""
TAIL_KEEPS = OBJECT | ASIDE_STOPPERS | {"HERE", "AND"}


def without_tail(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` without what follows its first :data:`TAIL_OPENERS` word after a command word,
    when that carries nothing a_hi needs (module docstring 5); else ``line``."""
    words = tag(line)
    at = next((i for i, w in enumerate(words) if i > 1 and w.words[0] in TAIL_OPENERS), None)
    if (
        at is None
        or not any(w.kind in verbs for w in words[:at])
        or any(_keeps(w, verbs) for w in words[at:])
    ):
        return line
    return " ".join(w.text for w in words[: _before(words, at, lambda w: set(w.words) <= TAIL_JOINS)])


def without_impatience(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` without a last "already" said in impatience after a command ("bring me the cup
    already"; module docstring 5); else ``line``."""
    words = tag(line)
    if len(words) > 2 and words[-1].words == ("already",) and any(w.kind in verbs for w in words):
        return " ".join(w.text for w in words[:-1])
    return line


def _keeps(word: Word, verbs: frozenset[str]) -> bool:
    """Whether ``word`` in a tail makes it mean something (:func:`without_tail`)."""
    if word.kind in TAIL_KEEPS or word.kind in verbs or _timed(word) or _negation(word):
        return True
    return any(x in CONDITIONS for x in word.words)


SENTENCE = re.compile(r"(?<=[.!?])\s+")
MAX_SENTENCES = 4
"""A line of more sentences is not read one sentence at a time."""


def sentences(line: str) -> list[str]:
    """The sentences of ``line``: split after ". ", "! ", "? " (and their runs)."""
    return [part for part in SENTENCE.split(line.strip()) if part.strip()]


QUESTION_WORDS = frozenset({"where", "what", "whats", "how", "hows", "why", "who", "when", "which"})
"""Words a question the person asks aloud begins with ("Where did I leave my cup?")."""


def _aside(sentence: str, tag: Tagger, verbs: frozenset[str]) -> bool:
    """Whether ``sentence`` carries nothing of a command (module docstring): a remark, or a
    question the person asks aloud, whatever its verb ("Where did I leave my cup?")."""
    words = tag(sentence)
    negated = _negated(words)
    stated = _stated(sentence, words, verbs, negated)
    if _looks_like_request(words) or any(_carries(w, verbs) for w in stated):
        return False
    return not (negated and any(w.kind in OBJECT for w in words))


def _stated(sentence: str, words: tuple[Word, ...], verbs: frozenset[str], negated: bool) -> list[Word]:
    """The words of ``sentence`` that may ask for something: not the verbs of a question asked
    aloud or of what the person says of themselves, not a time said past, not an urgency
    negated ("I'm not as quick as I was")."""
    told = _asked_aloud(sentence, words) or _said_of_oneself(words)
    past = _past(words) | _described(words)
    return [
        w
        for i, w in enumerate(words)
        if not (told and w.kind in verbs) and i not in past and not (negated and w.kind == "URGENT")
    ]


COPULA = frozenset({"is", "are", "was", "were", "s", "looks", "seems"})
"""Words after which a verb's word describes ("the bowl is empty")."""


def _described(words: tuple[Word, ...]) -> frozenset[int]:
    """The indices of the words said of a thing after "is" ("the bowl is empty": "empty" is no
    verb there)."""
    return frozenset(i for i in range(1, len(words)) if words[i - 1].words[-1] in COPULA)


AGO = "ago"


def _past(words: tuple[Word, ...]) -> frozenset[int]:
    """The indices of the words of a time said past ("a minute ago", "5 mins ago"): it says when
    something was, not when a command is due."""
    return frozenset(
        j
        for i, w in enumerate(words)
        if w.words == (AGO,)
        for j in range(max(0, i - 2), i)
        if _timed(words[j])
    )


FIRST_PERSON = frozenset({"i", "im", "ive"})
"""Words a sentence the person says of themselves begins with ("I have a bowl here.")."""
WISH_VERBS = frozenset({"WANT", "HAVE"})
"""Verb kinds of a wish: a sentence of oneself holding one asks ("I'd like the cup.")."""


def _said_of_oneself(words: tuple[Word, ...]) -> bool:
    """Whether ``words`` begin with "I" and wish nothing: what their verbs say is told, not
    asked ("I have a bowl here.", "I put the cup somewhere.")."""
    return bool(words) and words[0].words[0] in FIRST_PERSON and not any(w.kind in WISH_VERBS for w in words)


def _asked_aloud(sentence: str, words: tuple[Word, ...]) -> bool:
    """Whether ``sentence`` is a question beginning with a question word (:data:`QUESTION_WORDS`)."""
    return sentence.rstrip().endswith("?") and bool(words) and words[0].words[0] in QUESTION_WORDS


def _negated(words: tuple[Word, ...]) -> bool:
    """Whether ``words`` hold a negation ("no", "not", "don't", "can't", …)."""
    return any(_negation(w) for w in words)


def _negation(word: Word) -> bool:
    """Whether ``word`` negates (:data:`NEGATING`)."""
    return any(x in NEGATING for x in word.words)


def one_sentence(line: str, tag: Tagger, verbs: frozenset[str]) -> list[str]:
    """Each sentence of ``line`` whose other sentences are all asides, last first, with "it"
    named when the asides name one object (module docstring)."""
    parts = sentences(line)
    if not 1 < len(parts) <= MAX_SENTENCES:
        return []
    asides = [_aside(p, tag, verbs) for p in parts]
    out = []
    for i in range(len(parts) - 1, -1, -1):
        if all(asides[:i] + asides[i + 1 :]):
            out.append(_it_named(parts[i], parts[:i], parts[i + 1 :], tag))
    return out


NAMES = frozenset({"NOUN", "PLURAL", "CONTENTS"})
PLURAL_PRONOUNS = frozenset({"them", "they", "those", "these"})


def _it_named(sentence: str, before: list[str], after: list[str], tag: Tagger) -> str:
    """``sentence`` with its "it" ("them") replaced by the object the asides ``before`` and
    ``after`` it name: the one they name (of "them", the one named in the plural: "The beans are
    in the jar. I want them in the bowl."), else the subject of the aside just before it ("The
    cup is on the table. Put it back."); as it is when none is found."""
    pronoun = next((w for w in tag(sentence) if w.kind == "IT"), None)
    if pronoun is None:
        return sentence
    named = _named(pronoun, before + after, tag)
    if len({w.text for w in named}) != 1:
        named = _subject(before[-1], tag) if before else []
    if not named:
        return sentence
    word = re.escape(pronoun.text)
    return re.sub(rf"\b{word}\b", f"the {named[0].text}", sentence, count=1, flags=re.IGNORECASE)


def _named(pronoun: Word, others: list[str], tag: Tagger) -> list[Word]:
    """The objects ``others`` name that ``pronoun`` may stand for (of "them", those named in the
    plural)."""
    named = [w for other in others for w in tag(other) if w.kind in NAMES]
    if pronoun.words[0] in PLURAL_PRONOUNS:
        return [w for w in named if w.text.endswith("s") and not w.text.endswith("ss")]
    return named


SUBJECT_OPENERS = frozenset({"theres", "there", "is", "heres", "here", "you", "see", "do", "can", "know"})
"""Words before the thing a sentence is about ("There's a jar …", "You see the bowl …?")."""


def _subject(sentence: str, tag: Tagger) -> list[Word]:
    """The noun ``sentence`` begins with, as its subject ("The cup is …", "There's a jar …",
    "You see the bowl …?"), as a list of one; else empty."""
    words = list(tag(sentence))
    while words and words[0].words[0] in SUBJECT_OPENERS:
        words = words[1:]
    i = _after(words, 0, ("DET", "ADJ"))
    return [words[i]] if 0 < i < len(words) and words[i].kind in NAMES else []


OPENING = frozenset({"PLEASE", "POLITE", "ADDRESS", "THANKS"})
"""Kinds of word before a command that it holds only as courtesy or address."""
PLACES = frozenset({"ON", "IN", "BACK", "AWAY"})


def verbless(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` with "put" or "bring" before it when it has no verb, names a place or "to me"
    and is no question ("Bowl on table." → "put Bowl on table."; module docstring 6); else
    ``line``."""
    words = tag(line)
    first = next((w.kind for w in words if w.kind not in OPENING), "")
    verb = _terse_verb(words)
    terse = first in ("DET", "NOUN", "ADJ", "CONTENTS") and verb
    if not terse or line.rstrip().endswith("?") or any(w.kind in verbs for w in words):
        return line
    return verb + " " + " ".join(w.text for w in words)


def _terse_verb(words: tuple[Word, ...]) -> str:
    """The verb a terse line means: "bring" when it says "to me" or "here", "put" when it names
    a place or where to ("Beans to bowl."), else ""."""
    if _to_me(words):
        return "bring"
    return "put" if any(w.kind in PLACES or w.kind == "TO" for w in words) else ""


def _to_me(words: tuple[Word, ...]) -> bool:
    """Whether ``words`` say "to me" or "here" ("Bowl to me, now!": a terse bring)."""
    kinds = [w.kind for w in words]
    return "HERE" in kinds or any(a == "TO" and b == "ME" for a, b in itertools.pairwise(kinds))


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


COMMENT_STARTS = frozenset(
    {
        "i", "im", "id", "ive", "ill", "m", "my", "me", "we", "were", "our", "us", "you", "youre",
        "your", "he", "she", "they", "theyre", "it", "its", "this", "thats", "that", "there",
        "theres", "these", "those", "what", "whats", "how", "hows", "oh", "ah", "aw", "hi", "hiya",
        "hello", "wow", "oops", "phew", "whew", "ugh", "gosh", "lovely", "great", "good", "nice",
        "brilliant", "perfect", "wonderful", "such", "cant", "dont", "isnt", "no", "sorry",
        "cheers", "ta", "anyway", "anyways", "well", "okay", "ok", "alright", "right", "honey",
        "dear", "love", "sweetie", "darling", "mummy", "mum", "mom", "daddy", "dad", "big", "bless",
        "see",
    }
)  # fmt: skip
"""Words a remark may begin with (pronouns, interjections, words of address, comments): a
clause or sentence that begins with another word a_hi does not know and what may be its object
may be a request for something a_hi cannot do ("burn the house down"), so it is never left
out."""
FOLLOW_UP = frozenset({"then", "also", "next", "and", "afterwards"})
"""Words that begin another request."""


OBJECT_SHAPES = frozenset(
    {"DET", "IT", "ME", "NOUN", "PLURAL", "ONE", "EVERYTHING", "CONTENTS", "W_YOU", "THAT"}
)
"""Kinds of word that may follow an imperative verb as its object ("burn the house", "feed
it", "tell me", "speedrun this")."""


def _timed(word: Word) -> bool:
    """Whether ``word`` is a number or a unit of time a_hi's grammar did not take as a deadline
    ("u got 30 secs to …"): what holds it may set when the command is due, so it is kept."""
    return any(x[:1].isdigit() or (x in UNITS and len(x) > 1) for x in word.words)


def _carries(word: Word, verbs: frozenset[str]) -> bool:
    """Whether ``word`` carries a command's meaning wherever it stands: a verb, a stop, an
    urgency, a deadline, a progress question, a possible typo, a time (:func:`_timed`)."""
    return word.kind in verbs or word.kind in ASIDE_STOPPERS or _timed(word)


def _looks_like_request(words: tuple[Word, ...]) -> bool:
    """Whether ``words`` may ask for something: they begin (after courtesy) with a follow-up
    word, or with a word a_hi does not know that no remark begins with (:data:`COMMENT_STARTS`)
    followed by what may be its object ("burn the house down", not "lovely day")."""
    for i, word in enumerate(words):
        if word.words[0] in FOLLOW_UP:
            return True
        if word.kind not in OPENING:
            unknown = word.kind in ("WORD", TYPO) and word.words[0] not in COMMENT_STARTS
            after = words[i + 1].kind if i + 1 < len(words) else ""
            return unknown and after in OBJECT_SHAPES
    return False


def _droppable(clause: str, tag: Tagger, verbs: frozenset[str]) -> bool:
    """Whether ``clause`` carries nothing of a command and no negation."""
    if _looks_like_request(tag(clause)):
        return False
    return not any(w.kind in MEANINGFUL or w.kind in verbs or _timed(w) or _negation(w) for w in tag(clause))


AFTER_KEEPS = OBJECT | ASIDE_STOPPERS | {"AND"}
"""Kinds of word that keep a clause after the command: what it holds would change the command."""


def _droppable_after(clause: str, tag: Tagger, verbs: frozenset[str]) -> bool:
    """Whether ``clause``, after the command, carries nothing of it: as :func:`_droppable`, but
    "it" and a negation of something else may stand in it ("…, I can't see it anywhere")."""
    words = tag(clause)
    keeps = any(w.kind in AFTER_KEEPS or w.kind in verbs or _timed(w) for w in words)
    offered = bool(words) and words[0].words[0] == "or"  # "…, or maybe not": another choice
    return not _looks_like_request(words) and not keeps and not offered


def kept_clauses(line: str, tag: Tagger, verbs: frozenset[str]) -> list[str]:
    """The runs of ``line``'s clauses to read without the rest, longest first: each run whose
    left-out clauses before it are all :func:`_droppable` and those after it
    :func:`_droppable_after` (module docstring 3)."""
    clauses = [c for c in CLAUSE.split(line) if c.strip()]
    if not 1 < len(clauses) <= MAX_CLAUSES:
        return []
    before = [_droppable(c, tag, verbs) for c in clauses]
    after = [_droppable_after(c, tag, verbs) for c in clauses]
    kept = [(start, end) for start, end in _runs(len(clauses)) if all(before[:start]) and all(after[end:])]
    return [", ".join(c.strip() for c in clauses[start:end]) for start, end in kept]


def _runs(n: int) -> list[tuple[int, int]]:
    """The (start, end) of every run of fewer than ``n`` of ``n`` clauses, longest first."""
    return [(start, start + length) for length in range(n - 1, 0, -1) for start in range(n - length + 1)]


COMMAND_START = frozenset({"POLITE", "ASK", "PLEASE"})
"""Kinds of word a command may begin with besides its verb ("could you …", "please …")."""
PREFIX_KEEPS = frozenset({"NOUN", "PLURAL", "ONE", "CONTENTS", "IT"}) | ASIDE_STOPPERS


def after_prefix(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` from the first word a command may begin with, when what comes before carries
    nothing of a command and no negation ("Mummy says put the jar away", "So I was thinking
    about dinner, and, um, could you …"; module docstring 3); else ``line``."""
    words = tag(line)
    k = next((i for i, w in enumerate(words) if w.kind in verbs), 0)
    while k > 0 and words[k - 1].kind in COMMAND_START:  # "could you", "please" before the verb
        k -= 1
    if k == 0 or _looks_like_request(words[:k]) or any(_keeps_prefix(w) for w in words[:k]):
        return line
    return " ".join(w.text for w in words[k:])


def _keeps_prefix(word: Word) -> bool:
    """Whether ``word`` before a command makes what it stands in mean something: an object,
    a command word, a negation (:func:`after_prefix`)."""
    return word.kind in PREFIX_KEEPS or _negation(word) or _timed(word)


def reordered(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` in the order a_hi's grammar reads (module docstring 4): courtesy words after the
    first word left out, "the" before a bare object, "VERB to me X" as "VERB X to me"."""
    words = _fronted(_with_place(_without_you(list(tag(line)), verbs)), verbs)
    tail: list[str] = []
    if len(words) > 3 and words[0].kind in verbs and (words[1].kind, words[2].kind) == ("TO", "ME"):
        words, tail = [words[0], *words[3:]], ["to", "me"]
    words = _without_dative(words)
    out: list[str] = []
    for i, word in enumerate(words):
        if _left_out(words, i):
            continue
        before = words[i - 1].kind if i > 0 else ""
        if word.kind in ("NOUN", "ADJ") and before not in ("DET", "ADJ", "POSS", "NOUN", "OF"):
            out.append("the")
        out.append(word.text)
    return " ".join(out + tail)


FRAME_PLACES = {"POUR": ("into", "IN"), "EMPTY": ("into", "IN"), "PUT": ("in", "IN")}
"""The word that joins the second object of a verb's frame to the first ("pour X into Y")."""
AFTER_FRAME = OPENING | TIME_KINDS | {"WITHIN"}


def _with_place(words: list[Word]) -> list[Word]:
    """``words`` with the word of the verb's frame put between its two bare objects ("pour jar
    bowl", "pour(jar, bowl)", "place cup cabinet" → "pour jar into bowl", "place cup in
    cabinet"; a_hi's grammar reads "in the table" as on it), when nothing but courtesy or a
    time follows them; else as they are."""
    if not words or words[0].kind not in FRAME_PLACES:
        return words
    first = _after(words, 1, ("DET", "ADJ"))
    second = _after(words, first + 1, ("DET", "ADJ"))
    if second >= len(words) or words[first].kind != "NOUN" or words[second].kind != "NOUN":
        return words
    if not all(w.kind in AFTER_FRAME for w in words[second + 1 :]):
        return words
    text, kind = FRAME_PLACES[words[0].kind]
    return [*words[: first + 1], Word(kind, (text,), words[first + 1].index), *words[first + 1 :]]


def _without_dative(words: list[Word]) -> list[Word]:
    """``words`` without a "me" right after a verb of putting or pouring that has its object
    after it ("can you pour me the beans in the bowl?"): the person is not where it goes."""
    at = next((i for i, w in enumerate(words) if w.kind in FRAME_PLACES), None)
    if at is None or at + 2 >= len(words) or words[at + 1].kind != "ME" or words[at + 2].kind not in PHRASE:
        return words
    return [*words[: at + 1], *words[at + 2 :]]


def _left_out(words: list[Word], i: int) -> bool:
    """Whether :func:`reordered` leaves ``words[i]`` out: a courtesy word after the first, "over"
    before "to" ("bring the bowl over to the table")."""
    if i > 0 and words[i].kind in COURTESY:
        return True
    return words[i].words == ("over",) and i + 1 < len(words) and words[i + 1].kind == "TO"


def _without_you(words: list[Word], verbs: frozenset[str]) -> list[Word]:
    """``words`` without "you" (and a "that" before it, "to" after "please") directly before a
    verb: "please, you pour …", "I need that you bring …", "please to find …"."""
    out: list[Word] = []
    for i, word in enumerate(words):
        before_verb = i + 1 < len(words) and words[i + 1].kind in verbs
        after = out[-1].kind if out else ""
        if before_verb and word.kind == "W_YOU" and after == "THAT":
            out[-1:] = [Word("W_YOU", ("you",), out[-1].index), Word("TO", ("to",), word.index)]
        elif not (before_verb and (word.kind, after) in (("W_YOU", after), ("TO", "PLEASE"))):
            out.append(word)
    return out


def _fronted(words: list[Word], verbs: frozenset[str]) -> list[Word]:
    """``words`` with an object said before its verb put after it: "the jar please put on the
    table" → "put the jar on the table", "jar on table put please" → "put jar on table please"
    (courtesy before the object stays first)."""
    start = next((i for i, w in enumerate(words) if w.kind not in OPENING and w.kind != "ASK"), len(words))
    end = _after(words, start, ("DET", "ADJ", "NOUN"))
    if end < len(words) and words[end].kind in ("ON", "IN", "TO"):  # its place, said before the verb
        end = _after(words, end + 1, ("DET", "ADJ", "NOUN"))
    verb = _after(words, end, (*OPENING, "W_YOU"))
    if end == start or words[end - 1].kind != "NOUN" or verb == len(words) or words[verb].kind not in verbs:
        return words
    return [*words[:start], words[verb], *words[start:end], *words[verb + 1 :]]


def _after(words: list[Word], i: int, kinds: tuple[str, ...]) -> int:
    """The index of the first word from ``i`` on whose kind is not among ``kinds``."""
    while i < len(words) and words[i].kind in kinds:
        i += 1
    return i
