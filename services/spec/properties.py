"""The property language of the requirement tree: what must have happened in a run for a leaf
requirement to be met (``roco spec trace``; the evaluator over records is
services/spec_check/properties.py). The manual, key by key with examples: docs/spec.md
"The property language".

A requirement's ``properties`` are all to hold in one run. A property is a sequence of event
patterns (:class:`EventPattern`), matched *in order* ("then") by recorded communicates in
causal order (services/recorder/causal.py). A step matches a communicate by what it is
(channel, protocol, performative, content term, sender, receiver, content ``fields`` and
``minimum``) and by how it relates to earlier steps' events, named by ``name``
(``same_conversation``, ``other_conversation``: FIPA SC00061 §2.4 conversation-id;
``answers``, ``while_open``, ``refers``, ``above``), plus ``within_s`` (s), ``next``,
``at_least`` and ``absent`` (a forbidden order: binds nothing; neither first nor last, no name,
no ``at_least``, ``within_s`` or ``next``). A content field is a path (``goal.verb``,
``objects[bowl].particles_inside``, a variable ``objects[$held]`` in ``fields`` and
``minimum``). ``exercised`` counts the leading steps that describe the situation: once a run
matched them the rest must follow, else the run *violates* the property (unset: all steps).
"""

from __future__ import annotations

import re

import msgspec

FieldValue = str | int | float | bool
"""A value a content field is compared with."""
Expected = FieldValue | list[FieldValue]
"""What ``fields`` gives for a path: a value, or a list of values any one of which fits."""

_PATH = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\[[^\]]+\])?(\.[A-Za-z_][A-Za-z0-9_]*(\[[^\]]+\])?)*$")
"""``name``, ``name[key]``, joined by dots."""


class EventPattern(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """One event pattern of a property (each field: docs/spec.md, "The property language")."""

    channel: str
    name: str | None = None
    protocol: str | None = None
    performative: str | None = None
    content: str | None = None
    sender: str | None = None
    receiver: str | None = None
    fields: dict[str, Expected] = {}
    minimum: dict[str, float] = {}
    at_least: int = 1
    same_conversation: str | None = None
    other_conversation: str | None = None
    answers: str | None = None
    while_open: str | None = None
    refers: dict[str, str] = {}
    above: dict[str, str] = {}
    within_s: float | None = None
    next: bool = False
    absent: bool = False

    def names(self) -> list[str]:
        """The earlier steps this one names, in field order (repeats kept)."""
        single = (self.same_conversation, self.other_conversation, self.answers, self.while_open)
        return [n for n in single if n is not None] + list(self.refers.values()) + list(self.above.values())

    def describe(self) -> str:
        """``C1 coordinate inform SWStatus state=Preempted`` (only what is given)."""
        parts = [self.channel, self.protocol, self.performative, self.content]
        if self.sender is not None or self.receiver is not None:
            parts.append(f"{self.sender or '*'}→{self.receiver or '*'}")
        parts += [f"{k}={_shown(v)}" for k, v in self.fields.items()]
        parts += [f"{k}≥{v:g}" for k, v in self.minimum.items()]
        words = " ".join(p for p in parts if p is not None)
        return ("no " * self.absent) + (f"{words} ≥{self.at_least}" if self.at_least > 1 else words)


def _shown(value: Expected) -> str:
    """A field's value as a pattern shows it (the empty text as ``""``, a list as ``a|b``)."""
    if isinstance(value, list):
        return "|".join(_shown(v) for v in value)
    return '""' if value == "" else str(value)


class Property(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """What must have happened, in words (``text``) and as ``steps`` matched in order; the
    first ``exercised`` steps are the situation (None: all of them)."""

    text: str
    steps: tuple[EventPattern, ...]
    exercised: int | None = None

    @property
    def situation(self) -> int:
        """How many leading steps make the run exercise the property."""
        return len(self.steps) if self.exercised is None else self.exercised

    @property
    def binding(self) -> tuple[EventPattern, ...]:
        """The steps that bind an event (all but the ``absent`` ones), in order."""
        return tuple(s for s in self.steps if not s.absent)


def property_problems(prop: Property) -> list[str]:
    """What is wrong in ``prop`` itself, as sentences (its steps' patterns are checked against
    the channels by services/spec/requirements.py): no steps; ``exercised`` outside 1..steps;
    a name used twice; a step naming no earlier step; ``at_least`` below 1; ``within_s`` not
    positive; a field path that is not ``a``, ``a[key]``, ``a.b``…, or a variable in a path of
    ``refers`` or ``above``; an empty list of values; an ``absent`` step first,
    last, named, or with ``at_least``, ``within_s`` or ``next``."""
    if not prop.steps:
        return ["no steps"]
    problems: list[str] = []
    if not 1 <= prop.situation <= len(prop.steps):
        problems.append(f"exercised must be 1 to {len(prop.steps)}, not {prop.situation}")
    seen: set[str] = set()
    for n, step in enumerate(prop.steps, 1):
        where = f"step {n} ({step.describe()})"
        problems += [f"{where}: {p}" for p in _step_problems(step, seen)]
        if step.absent:
            problems += [f"{where}: {p}" for p in _absent_problems(step, n, len(prop.steps))]
        if step.name is not None:
            if step.name in seen:
                problems.append(f"{where}: name {step.name} used twice")
            seen.add(step.name)
    return problems


def _step_problems(step: EventPattern, earlier: set[str]) -> list[str]:
    problems = [f"names {n}, which no earlier step is" for n in step.names() if n not in earlier]
    if step.at_least < 1:
        problems.append(f"at_least must be 1 or more, not {step.at_least}")
    if step.within_s is not None and step.within_s <= 0:
        problems.append(f"within_s must be positive, not {step.within_s}")
    return problems + _path_problems(step)


def _path_problems(step: EventPattern) -> list[str]:
    """Malformed field paths, variables in ``refers`` or ``above``, empty lists of values."""
    paths = [*step.fields, *step.minimum, *step.refers, *step.above]
    problems = [f"field path {p!r} is not a, a[key], a.b, …" for p in paths if not _PATH.match(p)]
    named = [p for p in (*step.refers, *step.above) if "[$" in p]
    problems += [f"field path {p!r} of refers/above names a variable" for p in named]
    return problems + [f"field {p!r} lists no value" for p, v in step.fields.items() if v == []]


def _absent_problems(step: EventPattern, n: int, steps: int) -> list[str]:
    """What an ``absent`` step (the ``n``-th of ``steps``) may not be or carry."""
    problems = ["an absent step cannot be the first or the last"] if n in (1, steps) else []
    if step.name is not None:
        problems.append("an absent step binds nothing, so it cannot be named")
    if step.at_least != 1 or step.within_s is not None or step.next:
        problems.append("an absent step cannot carry at_least, within_s or next")
    return problems
