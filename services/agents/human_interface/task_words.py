"""The words of the tasks a person can ask a_hi for, as data: ``tasks.toml`` beside this module.

Each ``[[tasks]]`` entry names a task of a_pl (its goal tasks, restated here as data: a_pl's
``TASKS``, docs/agents.md) and the **frames** a person says it with — lower-case words and the
slots ``THEME``, ``GOAL``, ``SOURCE``, which are the grammar's argument roles (grammar.lark's
rules ``theme``, ``goal``, ``source``)::

    [[tasks]]
    task = "localise"
    frames = ["find THEME", "look for THEME", "where is THEME", "locate THEME"]
    ask = { THEME = "What should I look for?" }      # optional: the question for a missing slot
    example = "find the jar"                          # optional: the sentence a question suggests

Every slot of a frame is an argument of the task: ``args`` (optional) gives their order in the
``TaskAtom`` (default: the first frame's slots in the order THEME, GOAL, SOURCE), and every frame
names each of them once. A frame begins with a word and has a word between two slots. An
``ask`` text may name the other arguments as ``{THEME}``, ``{GOAL}``, ``{SOURCE}``.
task_grammar.py turns the frames into grammar rules and refuses a frame that reads like another
or like one of grammar.lark's.

:func:`read_task_words` checks the file's form and raises :class:`TaskWordsError` — one line
naming the file, the entry and what is wrong. The file's size and the number of entries, frames
and words are bounded (:data:`MAX_BYTES`, :data:`MAX_ENTRIES`, :data:`MAX_FRAMES`,
:data:`MAX_ITEMS`): they bound the grammar generated from it, and so the work of every parse.
"""

from __future__ import annotations

import functools
import itertools
import re
import string
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import msgspec

from services.spec.model import one_line, read_text

TASKS_FILE = Path(__file__).with_name("tasks.toml")
"""The task words a_hi reads at start."""

SLOTS = ("THEME", "GOAL", "SOURCE")
"""The slots of a frame, in their default argument order."""
ROLE_RULES = {"THEME": "theme", "GOAL": "goal", "SOURCE": "source"}
"""Slot → the grammar.lark rule that parses it (a reference: "the small cup on the table", "it")."""
MISSING = {"THEME": "object", "GOAL": "destination", "SOURCE": "source"}
"""Slot → what an :class:`~.intents.Incomplete` question names as missing."""

MAX_BYTES = 64 * 1024
"""Largest task words file read."""
MAX_ENTRIES = 64
"""Most entries in the file."""
MAX_FRAMES = 32
"""Most frames of one entry."""
MAX_ITEMS = 8
"""Most words and slots in one frame."""
MAX_TEXT = 200
"""Longest ``ask`` or ``example`` text (characters)."""

_TASK_NAME = re.compile(r"[a-z][a-z0-9_]*")
_WORD = re.compile(r"[a-z]+")


class TaskWordsError(ValueError):
    """A task words file that is missing, too large, malformed, or whose frames collide; the
    message is one line naming the file and the entry."""


class TaskEntry(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """One ``[[tasks]]`` entry as written (see the module docstring)."""

    task: str
    frames: tuple[str, ...]
    args: tuple[str, ...] | None = None
    ask: dict[str, str] = {}
    example: str | None = None


class TaskWordsFile(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """The file: its ``[[tasks]]`` entries."""

    tasks: tuple[TaskEntry, ...] = ()


@dataclass(frozen=True)
class Frame:
    """One way to say a task: its ``text`` as written and its ``items`` in order, each a
    lower-case word or a slot (``("look", "for", "THEME")``); ``entry`` its place in the file."""

    text: str
    items: tuple[str, ...]
    entry: int

    @property
    def slots(self) -> tuple[str, ...]:
        """The frame's slots, in the order they are said."""
        return tuple(i for i in self.items if i in SLOTS)

    def fill(self, names: dict[str, str]) -> str:
        """The frame with each slot replaced by ``names[slot]`` ("find the jar")."""
        return " ".join(names.get(i, i) for i in self.items)


@dataclass(frozen=True)
class TaskSaying:
    """An entry, checked: the ``task``, its ``frames``, the slots of its arguments in order
    (``args``), the question per missing slot (``ask``), an ``example`` sentence (or None),
    and its ``entry`` index in the file."""

    task: str
    frames: tuple[Frame, ...]
    args: tuple[str, ...]
    ask: tuple[tuple[str, str], ...]
    example: str | None
    entry: int

    def question(self, slot: str) -> str | None:
        """The entry's question for ``slot`` missing, or None."""
        return dict(self.ask).get(slot)


@dataclass(frozen=True)
class TaskWords:
    """The checked entries of a task words file (``source``: where they were read, for messages)."""

    sayings: tuple[TaskSaying, ...] = ()
    source: str = "<no file>"

    def saying(self, task: str) -> TaskSaying | None:
        """The first entry for ``task``, or None."""
        return next((s for s in self.sayings if s.task == task), None)

    def where(self, entry: int) -> str:
        """``file: tasks[i] ('task')`` for a message about entry ``entry``."""
        task = next((s.task for s in self.sayings if s.entry == entry), None)
        named = f" ({task!r})" if task is not None else ""
        return f"{self.source}: tasks[{entry}]{named}"


def read_task_words(path: Path = TASKS_FILE) -> TaskWords:
    """The task words in ``path``, their form checked (the collisions of frames are checked
    when the grammar is built: task_grammar.py). Raises :class:`TaskWordsError`."""
    try:
        size = path.stat().st_size
    except OSError:
        size = 0  # read_text names the problem
    if size > MAX_BYTES:
        raise TaskWordsError(f"{path}: {size} bytes; a task words file has at most {MAX_BYTES}")
    text = read_text(path, "task words file", TaskWordsError)
    try:
        written = msgspec.toml.decode(text, type=TaskWordsFile)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise TaskWordsError(f"{path}: {one_line(exc)}") from None
    return check(written, str(path))


@functools.cache
def default_task_words() -> TaskWords:
    """The task words of :data:`TASKS_FILE`, read once per process. Raises :class:`TaskWordsError`."""
    return read_task_words(TASKS_FILE)


def check(written: TaskWordsFile, source: str) -> TaskWords:
    """``written`` checked entry by entry. Raises :class:`TaskWordsError` naming ``source``,
    the entry and the problem."""
    if len(written.tasks) > MAX_ENTRIES:
        raise TaskWordsError(f"{source}: {len(written.tasks)} entries; at most {MAX_ENTRIES}")
    sayings = tuple(_saying(e, i, source) for i, e in enumerate(written.tasks))
    for s in sayings:
        first = next(f for f in sayings if f.task == s.task)
        if len(s.args) != len(first.args):
            raise TaskWordsError(
                f"{source}: tasks[{s.entry}] ({s.task!r}): {len(s.args)} argument(s), but "
                f"tasks[{first.entry}] gives the same task {len(first.args)}: a task has one "
                "number of arguments"
            )
    return TaskWords(sayings, source)


def _saying(e: TaskEntry, i: int, source: str) -> TaskSaying:
    where = f"{source}: tasks[{i}]" + (f" ({e.task!r})" if e.task else "")

    def bad(problem: str) -> TaskWordsError:
        return TaskWordsError(f"{where}: {problem}")

    if not _TASK_NAME.fullmatch(e.task):
        raise bad(
            f"task {e.task!r} is not an identifier: lower-case letters, digits and _, "
            "beginning with a letter, as a_pl names its tasks"
        )
    if not e.frames:
        raise bad('no frames: give at least one, e.g. frames = ["find THEME"]')
    if len(e.frames) > MAX_FRAMES:
        raise bad(f"{len(e.frames)} frames; at most {MAX_FRAMES}")
    frames = tuple(_frame(text, n, i, bad) for n, text in enumerate(e.frames))
    seen: dict[tuple[str, ...], str] = {}
    for f in frames:
        if f.items in seen:
            raise bad(f"frame {f.text!r} is given twice")
        seen[f.items] = f.text
    first = frames[0].slots
    if e.args is None:
        args = tuple(s for s in SLOTS if s in first)
    else:
        args = e.args
        for s in args:
            if s not in SLOTS:
                raise bad(f"args names an unknown slot {s!r}; the slots are {', '.join(SLOTS)}")
        if len(set(args)) != len(args):
            raise bad("args names a slot twice")
    for f in frames:
        if set(f.slots) != set(args):
            said = ", ".join(f.slots) or "no slot"
            raise bad(
                f"frame {f.text!r} names {said}; every frame names each argument of the task "
                f"once: {', '.join(args) or 'no slot'}"
            )
    for slot, text in e.ask.items():
        if slot not in args:
            raise bad(f"ask names {slot!r}, which is not an argument of the task ({', '.join(args)})")
        _text(text, f"ask.{slot}", bad)
        try:
            fields = [f for _, f, _, _ in string.Formatter().parse(text) if f is not None]
        except ValueError as exc:
            raise bad(f"ask.{slot}: {exc}; name an argument as {{THEME}}") from None
        for field in fields:
            if field not in args or field == slot:
                raise bad(
                    f"ask.{slot} names {{{field}}}; it may name only the task's other arguments "
                    f"({', '.join(a for a in args if a != slot) or 'none'})"
                )
    if e.example is not None:
        _text(e.example, "example", bad)
    ask = tuple((s, e.ask[s]) for s in args if s in e.ask)
    return TaskSaying(e.task, frames, args, ask, e.example, i)


def _frame(text: str, n: int, entry: int, bad: Callable[[str], TaskWordsError]) -> Frame:
    items = tuple(text.split())
    if not items:
        raise bad(f"frame {n} ({text!r}) is empty")
    if len(items) > MAX_ITEMS:
        raise bad(f"frame {text!r} has {len(items)} words and slots; at most {MAX_ITEMS}")
    for item in items:
        if item.isupper() and item.isalpha():
            if item not in SLOTS:
                raise bad(f"frame {text!r} names an unknown slot {item!r}; the slots are {', '.join(SLOTS)}")
        elif not _WORD.fullmatch(item):
            raise bad(
                f"frame {text!r}: {item!r} is neither a slot ({', '.join(SLOTS)}) nor a lower-case word"
            )
    frame = Frame(text, items, entry)
    if len(set(frame.slots)) != len(frame.slots):
        raise bad(f"frame {text!r} names a slot twice")
    if any(a in SLOTS and b in SLOTS for a, b in itertools.pairwise(items)):
        raise bad(f"frame {text!r} has two slots side by side; put a word between them")
    if items[0] in SLOTS:
        raise bad(f"frame {text!r} begins with a slot; a frame begins with a word")
    return frame


def _text(text: str, what: str, bad: Callable[[str], TaskWordsError]) -> None:
    if not text.strip() or "\n" in text or len(text) > MAX_TEXT:
        raise bad(f"{what} must be one non-empty line of at most {MAX_TEXT} characters")


__all__ = [
    "MISSING",
    "ROLE_RULES",
    "SLOTS",
    "TASKS_FILE",
    "Frame",
    "TaskEntry",
    "TaskSaying",
    "TaskWords",
    "TaskWordsError",
    "TaskWordsFile",
    "check",
    "default_task_words",
    "read_task_words",
]
