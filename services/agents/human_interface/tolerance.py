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
   love?"): a clause (between punctuation) before the command is left out when it holds no
   word of a command (a verb, an object or its describing word, a deadline, an urgency, a
   stop, "it", "one") and no negation (:data:`NEGATIONS`), so that "don't, bring me the cup"
   is never read as a command; a clause after it also when it holds "it" or a negation of
   something else ("…, I can't see it anywhere"), not when it names an object, an urgency or
   another request ("…, not the jar", "…, and the cup"). The longest run of the clauses that
   is kept is read first. Words before the first word a command begins with ("Mummy says put
   the jar away") are left out on the same terms as a clause before it, an object named in
   them also keeping them.
4. **Word order of another language** ("Put please the bowl on table", "give to me the jar"):
   a courtesy word inside the command left out, "the" put before an object named bare, "to
   me" after the verb moved to the end; "you" before the verb left out ("please, you pour
   the beans …", "I need that you bring …"), "to" after "please" too; an object said before
   its verb put after it ("the jar, please put on the table", "the bowl you put on table").
5. **A reason, a beneficiary or a courtesy after the command** ("… for the kids", "… before
   the baby knocks it over", "… when you're done"): left out from the word that begins it
   (:data:`TAIL_OPENERS`) to the end, when what it holds names no object a_km knows, no verb,
   stop, urgency or deadline, and no negation or condition (:data:`CONDITIONS`).
6. **Terse commands without a verb** ("Bowl on table.", "Cup back in cabinet.", "Beans into
   the bowl, quick.", "Bowl to me, now!"): read with "put" before them when the line names a
   place (on, in, back, away), with "bring" when it says "to me" or "here", and is no question
   ("?").
7. **When, said apart** ("pour the jar into the bowl, I need it within a minute"): a clause
   that holds only a deadline or an urgency and words of a wish ("I need it") is joined to the
   command.

Before these, a line of several sentences (:func:`sentences`) is read as each one of them
alone whose other sentences are asides: they hold no command word (a verb, a stop, an
urgency, a deadline, a progress question) and, when they hold a negation, no object either
("I'm so tired. Could you bring me the cup?", "I lost the bowl. Can you find it?"). "it" in the
sentence read is the one object the asides name, if they name one ("find the bowl").

Each reading is read as a whole line is (language.py :func:`~.language.interpret`) and the
first that gives an intent is taken; the intent says what was read (``read_as``: the line and
the text read), so the person hears it. A reading never adds a word that changes what is
meant: it only leaves words out, moves words, adds "the", names what "it" is, or adds "put" to
a line that has no verb.

The work is bounded: the line is at most ``MAX_LINE_CHARS`` characters (services/runtime/
human.py), at most :data:`MAX_CLAUSES` clauses are looked at and at most :data:`MAX_READINGS`
readings given."""

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
        add(verbless(base, tag, verbs))
        add(time_joined(base, tag))
    return out[:MAX_READINGS]


TIME_KINDS = frozenset({"DEADLINE", "URGENT"})
WISH_WORDS = frozenset({"i", "we", "need", "want", "it", "that", "this", "done", "ready", "by", "please"})
"""Words a clause that only says when may hold besides the time ("I need it within a minute")."""


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


TAIL_OPENERS = frozenset({"for", "before", "because", "cause", "so", "when", "whenever", "once"})
"""Words that begin a reason, a beneficiary or a courtesy after a command (module docstring 5)."""
CONDITIONS = frozenset({"if", "unless", "until", "only", "after", "while", "then"})
"""Words that make what follows a command a condition on it: never left out."""
TAIL_KEEPS = OBJECT | ASIDE_STOPPERS | {"HERE", "AND"}


def without_tail(line: str, tag: Tagger, verbs: frozenset[str]) -> str:
    """``line`` without what follows its first :data:`TAIL_OPENERS` word after a command word,
    when that carries nothing a_hi needs (module docstring 5); else ``line``."""
    words = tag(line)
    at = next((i for i, w in enumerate(words) if i > 1 and w.words[0] in TAIL_OPENERS), None)
    if at is None or not any(w.kind in verbs for w in words[:at]):
        return line
    if any(_keeps(w, verbs) for w in words[at:]):
        return line
    return " ".join(w.text for w in words[:at])


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
    asked = _asked_aloud(sentence, words)
    stated = [w for w in words if not (asked and w.kind in verbs)]
    if _looks_like_request(words) or any(_carries(w, verbs) for w in stated):
        return False
    return not (_negated(words) and any(w.kind in OBJECT for w in words))


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
            out.append(_it_named(parts[i], parts[:i] + parts[i + 1 :], tag))
    return out


def _it_named(sentence: str, others: list[str], tag: Tagger) -> str:
    """``sentence`` with its "it" replaced by the one object ``others`` name ("the bowl"), if
    they name exactly one; else as it is."""
    named = [w for other in others for w in tag(other) if w.kind in ("NOUN", "PLURAL", "CONTENTS")]
    if len(named) != 1 or not any(w.kind == "IT" for w in tag(sentence)):
        return sentence
    return re.sub(r"\b(?:it|that)\b", f"the {named[0].text}", sentence, count=1, flags=re.IGNORECASE)


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
    """The verb a terse line means: "put" when it names a place, "bring" when it says "to me"
    or "here", else ""."""
    if any(w.kind in PLACES for w in words):
        return "put"
    return "bring" if _to_me(words) else ""


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
    }
)  # fmt: skip
"""Words a remark may begin with (pronouns, interjections, words of address, comments): a
clause or sentence that begins with another word a_hi does not know and what may be its object
may be a request for something a_hi cannot do ("burn the house down"), so it is never left
out."""
FOLLOW_UP = frozenset({"then", "also", "next", "and", "afterwards"})
"""Words that begin another request."""


OBJECT_SHAPES = frozenset({"DET", "IT", "ME", "NOUN", "PLURAL", "ONE", "EVERYTHING", "CONTENTS", "W_YOU"})
"""Kinds of word that may follow an imperative verb as its object ("burn the house", "feed
it", "tell me")."""


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
    return not _looks_like_request(words) and not keeps


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
    words = _fronted(_without_you(list(tag(line)), verbs), verbs)
    tail: list[str] = []
    if len(words) > 3 and words[0].kind in verbs and (words[1].kind, words[2].kind) == ("TO", "ME"):
        words, tail = [words[0], *words[3:]], ["to", "me"]
    out: list[str] = []
    for i, word in enumerate(words):
        if _left_out(words, i):
            continue
        before = words[i - 1].kind if i > 0 else ""
        if word.kind in ("NOUN", "ADJ") and before not in ("DET", "ADJ", "POSS", "NOUN", "OF"):
            out.append("the")
        out.append(word.text)
    return " ".join(out + tail)


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
    start = next((i for i, w in enumerate(words) if w.kind not in OPENING), len(words))
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
