"""a_hi's grammar: grammar.lark plus a rule per frame of the task words (tasks.toml).

A frame ("look for THEME") becomes the symbols ``W_LOOK FOR theme?``: each run of its words is
tagged as a sentence's words are (grammar.py :func:`~.grammar.tag`), so a word that is one of
grammar.lark's closed classes is that class ("for" is ``FOR``; "into" is ``IN``, which also
reads "in" and "inside"), and every other word gets a terminal of its own (``W_LOOK``), added
to the tagger's closed-class phrases; each slot is the role's rule (``theme``, ``goal``,
``source``: a reference, resolved as any other), optional, so that a sentence without it gets a
question back. The frames are grouped by their first word, so that where a command may begin
the Earley parser predicts one item per first word, not one per frame and optional slot (the
frames add little to the parse of a sentence that is none of them)::

    said: W_LOOK after_w_look | W_FIND after_w_find | ...
    ?after_w_look: said_12 | said_16
    said_12: FOR theme?                 // localise: look for THEME
    said_16: W_WHERE theme? W_IS        // localise: look where THEME is

``said`` joins ``command`` with lark's ``%extend``; a frame's node is ``said_<n>``
(:func:`frame_node`). The parse stays lark's Earley over the same tags.

:func:`build` also reads each frame said with "it" in its slots ("look for it") and refuses the
file (:class:`~.task_words.TaskWordsError`, one line naming the entry) when that sentence
reads differently: as a rule of grammar.lark (a frame colliding with a built-in one), as
another frame, or not as written (its words run into a fixed phrase of grammar.lark).

:func:`default_grammar` is built once per process from :data:`~.task_words.TASKS_FILE`;
:func:`load_grammar` builds one from another file (tests, a researcher's copy).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from lark import Lark, Token, Tree
from lark.exceptions import GrammarError

from services.agents.human_interface.grammar import (
    GRAMMAR_FILE,
    PHRASES,
    VERBS,
    ParseFailure,
    Word,
    build_parser,
    parse,
    tag,
)
from services.agents.human_interface.task_words import (
    ROLE_RULES,
    SLOTS,
    TASKS_FILE,
    Frame,
    TaskSaying,
    TaskWords,
    TaskWordsError,
    default_task_words,
    read_task_words,
)
from services.agents.human_interface.vocabulary import Vocabulary

SAID_RULE = "said"
"""The generated alternative of ``command``: a frame's first word, then the rest of the frame."""
RULE_PREFIX = "said_"
"""Name of a frame's node: ``said_<n>``, n counting the frames of the file in order."""
TERMINAL_PREFIX = "W_"
"""Name of a generated terminal: ``W_<WORD>`` ("look" → ``W_LOOK``)."""
PROBE = "it"
"""What fills a frame's slots when the frames are checked."""
BUILT_IN_VERBS = ("pour", "empty", "fill", "bring", "take", "put", "put back", "hand over")
"""The verbs of grammar.lark's frames, as an answer names them."""


@dataclass(frozen=True)
class SaidFrame:
    """A generated rule's frame and the entry (``saying``) it belongs to."""

    saying: TaskSaying
    frame: Frame


@dataclass(frozen=True, eq=False)
class Grammar:
    """a_hi's grammar: the ``words`` it was built from, the Earley ``parser`` of grammar.lark
    with the generated rules (their lark ``text``), the closed-class ``phrases`` the tagger
    uses, the frame of each generated rule (``frames``, by rule name), and the word classes a
    request begins with (``verb_kinds``: grammar.py's :data:`~.grammar.VERBS` and each frame's
    first word)."""

    words: TaskWords
    parser: Lark
    text: str
    phrases: Mapping[tuple[str, ...], str]
    frames: Mapping[str, SaidFrame]
    verb_kinds: frozenset[str] = VERBS

    def tag(self, sentence: str, vocabulary: Vocabulary) -> tuple[Word, ...]:
        """The tokens of ``sentence`` (grammar.py :func:`~.grammar.tag` with this grammar's phrases)."""
        return tag(sentence, vocabulary, self.phrases)

    def parse(self, words: tuple[Word, ...]) -> list[Tree[Token]]:
        """Every reading of ``words``; raises :class:`~.grammar.ParseFailure`."""
        return parse(words, self.parser)

    def verbs(self) -> str:
        """The verbs a person can use, for an answer naming an unknown one ("pour, …, find, stop,
        or ask what I am doing"): grammar.lark's, then the first words of each task's first frame."""
        said: list[str] = []
        for s in self.words.sayings:
            first = s.frames[0].items
            lead = " ".join(first[: next((k for k, i in enumerate(first) if i in SLOTS), len(first))])
            if lead not in said and lead not in BUILT_IN_VERBS:
                said.append(lead)
        return ", ".join([*BUILT_IN_VERBS, *said]) + ", stop, or ask what I am doing"


def _rule_name(n: int) -> str:
    return f"{RULE_PREFIX}{n}"


def _after(first: str) -> str:
    """The rule of the rests of the frames beginning with the word class ``first``."""
    return f"after_{first.lower()}"


def _rule_number(name: str) -> int:
    return int(name.removeprefix(RULE_PREFIX))


def frame_node(request: Tree[Token]) -> Tree[Token]:
    """The node of the frame in a request node: the ``said_<n>`` child of a ``said`` node (its
    first word is beside it), else ``request`` itself."""
    if request.data == SAID_RULE:
        return next(c for c in request.children if isinstance(c, Tree))
    return request


def _reading_rule(tree: Tree[Token]) -> str:
    """The rule of the request in the reading ``tree`` (a ``start``): "bring", "said_3", "reply"."""
    request = next(c for c in tree.children if isinstance(c, Tree) and c.data not in ("pre", "post"))
    return str(frame_node(request).data)


def _phrases(words: TaskWords) -> dict[tuple[str, ...], str]:
    """grammar.py's closed-class phrases plus a terminal for each frame word no class has."""
    phrases = dict(PHRASES)
    empty = Vocabulary()
    for s in words.sayings:
        for f in s.frames:
            for item in f.items:
                if item not in SLOTS and tag(item, empty)[0].kind == "WORD":
                    phrases[(item,)] = TERMINAL_PREFIX + item.upper()
    return phrases


def _rule(frame: Frame, phrases: Mapping[tuple[str, ...], str]) -> list[str]:
    """The symbols of ``frame``'s rule: the word classes of each run of its words, a role's rule
    (optional) for each slot; after a slot, the words leading to a later slot open an optional
    group that runs to the end ("wipe GOAL with THEME": ``W_WIPE goal? ( WITH theme? )?``), so
    that "wipe the table" is read, and asked "with what?"."""
    runs: list[list[str]] = [[]]  # runs[k]: the words before slot k (the last: after the last slot)
    slots: list[str] = []
    for item in frame.items:
        if item in SLOTS:
            slots.append(item)
            runs.append([])
        else:
            runs[-1].append(item)
    symbols: list[str] = []
    for k, run in enumerate(runs):
        if 0 < k < len(slots):
            symbols.append("(")
        if run:
            symbols.extend(w.kind for w in tag(" ".join(run), Vocabulary(), phrases))
        if k < len(slots):
            symbols.append(ROLE_RULES[slots[k]] + "?")
    symbols.extend([")?"] * max(len(slots) - 1, 0))
    return symbols


def build(words: TaskWords) -> Grammar:
    """grammar.lark with a rule per frame of ``words``, checked (module docstring). Raises
    :class:`~.task_words.TaskWordsError` naming the entry of a frame that collides."""
    phrases = _phrases(words)
    frames: dict[str, SaidFrame] = {}
    after: dict[str, list[str]] = {}  # first word's class → the frames going on after it
    alone: list[str] = []  # frames of one word
    rules: list[str] = []
    for s in words.sayings:
        for f in s.frames:
            name = _rule_name(len(frames))
            frames[name] = SaidFrame(s, f)
            first, *rest = _rule(f, phrases)
            if rest:
                after.setdefault(first, []).append(name)
                rules.append(f"{name}: {' '.join(rest)}  // {s.task}: {f.text}")
            else:
                alone.append(name)
                rules.append(f"{name}: {first}  // {s.task}: {f.text}")
    lines = [GRAMMAR_FILE.read_text(), "// generated from the task words (task_grammar.py)"]
    alternatives = [f"{first} {_after(first)}" for first in after] + alone
    if alternatives:
        lines.append(f"{SAID_RULE}: {' | '.join(alternatives)}")
        lines.extend(f"?{_after(first)}: {' | '.join(names)}" for first, names in after.items())
        lines.extend(rules)
        lines.append(f"%extend command: {SAID_RULE}")
    terminals = sorted({k for k in phrases.values() if k.startswith(TERMINAL_PREFIX)})
    if terminals:
        lines.append(f"%declare {' '.join(terminals)}")
    text = "\n".join(lines) + "\n"
    try:
        parser = build_parser(text)
    except GrammarError as exc:  # pragma: no cover - task_words.py refuses what would cause one
        first_line = str(exc).strip().splitlines()[0]
        raise TaskWordsError(f"{words.source}: its frames make no grammar: {first_line}") from None
    firsts = {_rule(f.frame, phrases)[0] for f in frames.values()}
    grammar = Grammar(words, parser, text, phrases, frames, VERBS | firsts)
    for name, said in frames.items():
        _check(grammar, name, said)
    return grammar


def _check(grammar: Grammar, name: str, said: SaidFrame) -> None:
    """Refuse ``said``'s frame when its sentence with "it" in the slots is read otherwise."""
    frame = said.frame
    where = grammar.words.where(said.saying.entry)
    probe = frame.fill(dict.fromkeys(SLOTS, PROBE))
    tokens = grammar.tag(probe, Vocabulary())
    try:
        readings = grammar.parse(tokens)
    except ParseFailure:
        readings = []
    rules = {_reading_rule(r) for r in readings}
    others = sorted(r for r in rules if r != name)
    for other in others:
        if other in grammar.frames:  # named from the later frame of the two
            first, then = (grammar.frames[r] for r in sorted((name, other), key=_rule_number))
            raise TaskWordsError(
                f"{grammar.words.where(then.saying.entry)}: frame {then.frame.text!r} reads the same "
                f"as frame {first.frame.text!r} of tasks[{first.saying.entry}] ({first.saying.task!r}): "
                f"{probe!r} is read by both"
            )
        raise TaskWordsError(
            f"{where}: frame {frame.text!r} collides with a built-in frame: {probe!r} already "
            f"reads as grammar.lark's rule {other!r}"
        )
    if name not in rules:
        phrases = " | ".join(w.text for w in tokens)
        raise TaskWordsError(
            f"{where}: frame {frame.text!r} cannot be read as written: {probe!r} is tagged "
            f"{phrases!r}, its words running into a fixed phrase of a_hi's grammar"
        )


def load_grammar(path: Path = TASKS_FILE) -> Grammar:
    """The grammar with the task words of ``path``. Raises :class:`~.task_words.TaskWordsError`."""
    return build(read_task_words(path))


@functools.cache
def default_grammar() -> Grammar:
    """The grammar with the task words of :data:`~.task_words.TASKS_FILE`, built once per
    process. Raises :class:`~.task_words.TaskWordsError`."""
    return build(default_task_words())


__all__ = [
    "BUILT_IN_VERBS",
    "SAID_RULE",
    "Grammar",
    "SaidFrame",
    "build",
    "default_grammar",
    "frame_node",
    "load_grammar",
]
