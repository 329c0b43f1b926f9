"""Evaluate a requirement's properties (services/spec/properties.py) over a recorded run, one
communicate at a time, so that the same evaluator serves a record read after the run and
traffic as it arrives.

:class:`Monitor` keeps every partial match of a property's steps (the events bound so far);
:meth:`Monitor.feed` takes the next communicate in causal order (services/recorder/causal.py)
and advances them. A property is *shown* once a partial match bound all its steps; it is
*violated* as soon as a communicate an ``absent`` step forbids comes in a partial match that
bound the situation (:attr:`Monitor.violation`: the communicate, while the run goes on), or
when the run ended (:meth:`Monitor.verdict` with ``final``) after a partial match bound its
first ``exercised`` steps but none bound them all; else *not exercised*. A violation stands
whatever else matched; a property with an absent step is followed after it was shown (a
later situation may still violate it).

A step that no later step names, and that is not followed by an ``absent`` step or by a
``within_s`` or ``next`` step, binds the earliest communicate that fits (a later one cannot
help a later step); any other binds each fitting communicate in turn (one partial match
each). At most
:data:`MAX_PARTIALS` partial matches are kept per property (the earliest ones); the monitor
says so in :attr:`Monitor.capped`.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Iterable
from dataclasses import dataclass
from functools import partial
from typing import Any

from services.report.load import Message
from services.spec.properties import EventPattern, Expected, FieldValue, Property

__all__ = ["MAX_PARTIALS", "Monitor", "Outcome", "Verdict", "Violation", "evaluate", "field_value"]

MAX_PARTIALS = 10_000
"""Partial matches kept per property."""

CLOSING = frozenset({"inform", "inform-ref", "failure", "refuse"})
"""Performatives that answer a request or query for good (FIPA SC00026, SC00027)."""

_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[([^\]]+)\])?$")


class Verdict(enum.StrEnum):
    """What a run (or runs) say of a property or a requirement."""

    SHOWN = "shown"
    NOT_EXERCISED = "not exercised"
    VIOLATED = "violated"


Vars = tuple[tuple[str, str], ...]
"""The variables a partial match bound (services/spec/properties.py), in binding order:
(variable without its ``$``, the element's name)."""


def field_value(content: object, path: str) -> Any:
    """The value at ``path`` (``a``, ``a[key]``, ``a.b``; ``[key]`` picks the element whose
    ``name`` is ``key``; ``[$var]`` the first element) in ``content``; an enum as its value;
    None when a part is missing."""
    found = _values(content, path, ())
    return found[0][0] if found else None


def _values(content: object, path: str, bound: Vars) -> list[tuple[Any, Vars]]:
    """Every value at ``path`` in ``content`` with the variables it binds on top of
    ``bound``: one for a path without an unbound variable (None when a part is missing), one
    per element for each ``[$var]`` not in ``bound``; an enum as its value."""
    found: list[tuple[Any, Vars]] = [(content, bound)]
    for segment in path.split("."):
        m = _SEGMENT.match(segment)
        if m is None:
            return [(None, bound)]
        found = [x for value, vs in found for x in _step_into(value, m.group(1), m.group(2), vs)]
    return [(v.value if isinstance(v, enum.Enum) else v, vs) for v, vs in found]


def _step_into(value: Any, attribute: str, key: str | None, vs: Vars) -> list[tuple[Any, Vars]]:
    """``value.attribute``, then the element named ``key`` of it (a variable: each element)."""
    value = getattr(value, attribute, None) if value is not None else None
    if key is None or value is None:
        return [(value, vs)]
    if not key.startswith("$"):
        return [(_named(value, key), vs)]
    bound = dict(vs).get(key[1:])
    if bound is not None:
        return [(_named(value, bound), vs)]
    elements = [(x, getattr(x, "name", None)) for x in value]
    return [(x, (*vs, (key[1:], n))) for x, n in elements if isinstance(n, str)]


def _named(elements: Any, name: str) -> Any:
    """The element of ``elements`` whose ``name`` is ``name``; None when there is none."""
    return next((x for x in elements if getattr(x, "name", None) == name), None)


def _fits_value(value: Any, expected: Expected) -> bool:
    """``value`` is ``expected``, or one of them when it is a list."""
    if isinstance(expected, list):
        return any(_equal(value, e) for e in expected)
    return _equal(value, expected)


def _equal(value: Any, expected: FieldValue) -> bool:
    if isinstance(expected, bool) or isinstance(value, bool):
        return value is expected
    if isinstance(expected, int | float):
        return isinstance(value, int | float) and value == expected
    return value is not None and str(value) == expected


def _fits(step: EventPattern, m: Message, bound: Vars = ()) -> list[Vars]:
    """The ways ``m`` is what ``step`` describes, leaving aside the earlier events: the
    variables bound then, on top of ``bound`` (none: it is not)."""
    rec = m.rec
    if not (
        rec.channel == step.channel
        and step.protocol in (None, rec.protocol)
        and step.performative in (None, rec.performative)
        and step.sender in (None, rec.sender)
        and (step.receiver is None or step.receiver in rec.receivers)
    ):
        return []
    return _content_fits(step, m.content, bound)


def _content_fits(step: EventPattern, content: object, bound: Vars) -> list[Vars]:
    """The ways ``content`` is the term ``step`` names, with its ``fields`` and ``minimum``:
    the variables bound then, each way once."""
    if step.content is not None and type(content).__name__ != step.content:
        return []
    tests = [(p, partial(_fits_value, expected=v)) for p, v in step.fields.items()]
    tests += [(p, partial(_at_least, minimum=v)) for p, v in step.minimum.items()]
    ways = [bound]
    for path, test in tests:
        ways = [vs2 for vs in ways for v, vs2 in _values(content, path, vs) if test(v)]
    return list(dict.fromkeys(ways))


def _at_least(value: Any, minimum: float) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and value >= minimum


def _reply_with(m: Message) -> str | None:
    return m.comm.reply_with if m.comm is not None else None


def _in_reply_to(m: Message) -> str | None:
    return m.comm.in_reply_to if m.comm is not None else None


@dataclass(frozen=True)
class _Partial:
    """The steps before ``step`` matched (``bound``: the first event of each that binds one;
    absent steps bind none; ``vars``: the variables bound), ``count`` communicates matched of
    step ``step``, the next step that binds (an absent step is never waited on: the ones just
    before ``step`` watch)."""

    step: int
    count: int
    bound: tuple[Message, ...]
    vars: Vars = ()


@dataclass(frozen=True)
class Violation:
    """Where a property was violated as it happened: its ``absent`` step ``step`` (index in
    the property's steps) was matched by ``by`` after the ``events`` bound before it."""

    step: int
    by: Message
    events: tuple[Message, ...]


@dataclass(frozen=True)
class Outcome:
    """A property in one run: its ``verdict``; ``events`` the communicates bound to its steps
    by the match that got furthest (all of them when shown); ``capped``: partial matches were
    dropped (:data:`MAX_PARTIALS`), so a match may have been missed."""

    prop: Property
    verdict: Verdict
    events: tuple[Message, ...]
    capped: bool = False
    violation: Violation | None = None

    def describe(self) -> str:
        """``shown: 18.3 s, 18.4 s``, ``not exercised: steps 1–2 matched, then no C1 …`` or
        ``violated at 21.3 s: C1 … came while waiting for C6 …``."""
        steps = self.prop.binding
        capped = f" (partial matches capped at {MAX_PARTIALS})" if self.capped else ""
        if self.violation is not None:
            return f"{self.verdict} at {self.violation.by.t:.1f} s: {self.forbidden()}{capped}"
        if self.verdict == Verdict.SHOWN:
            return f"{self.verdict}: events at " + ", ".join(f"{m.t:.1f} s" for m in self.events) + capped
        got = len(self.events)
        matched = "no step matched" if got == 0 else f"steps 1–{got} matched" if got > 1 else "step 1 matched"
        return f"{self.verdict}: {matched}, then no {steps[got].describe()}{capped}"

    def forbidden(self) -> str:
        """What the violating communicate was and what was awaited: ``C1 … came while waiting
        for C6 …`` (empty without a violation)."""
        if self.violation is None:
            return ""
        steps = self.prop.steps
        awaited = next((s for s in steps[self.violation.step :] if not s.absent), None)
        came = steps[self.violation.step].describe().removeprefix("no ")
        return f"{came} came while waiting for {awaited.describe() if awaited else 'the end'}"


Closed = dict[tuple[str, str | None], set[str]]
"""(channel, conversation-id) → the agents that answered in it for good."""
Events = dict[str, Message]
"""The events bound so far, by their step's name."""


class Monitor:
    """One property evaluated over one run's communicates, fed one by one in causal order."""

    def __init__(self, prop: Property) -> None:
        self.prop = prop
        steps = prop.steps
        slots = [sum(1 for s in steps[:i] if not s.absent) for i in range(len(steps))]
        self._names = {s.name: slots[i] for i, s in enumerate(steps) if s.name is not None}
        self._after = [_next_binding(steps, i + 1) for i in range(len(steps))]
        """Step index → the index of the first binding step after it (len(steps): none)."""
        self._guards = [_guards_before(steps, i) for i in range(len(steps))]
        """Step index → the absent steps just before it (they watch while it waits)."""
        self._branch = _branches(steps, self._after)
        self._guarded = any(s.absent for s in steps)
        self._partials: list[_Partial] = [_Partial(0, 0, ())]
        self._closed: Closed = {}
        self._furthest: tuple[Message, ...] = ()
        self.shown_by: tuple[Message, ...] | None = None
        self.violation: Violation | None = None
        self.exercised = False
        self.capped = False

    def feed(self, m: Message) -> None:
        """Take the next communicate of the run (copies should be left out)."""
        if self.violation is None and (self.shown_by is None or self._guarded):
            self._advance_all(m)
        if m.performative in CLOSING:
            self._closed.setdefault((m.channel, m.conversation), set()).add(m.sender)

    def verdict(self, final: bool = True) -> Verdict:
        """Violated once a forbidden communicate came (:attr:`violation`); else shown once
        matched; violated when ``final`` (the run ended) and the situation happened but the
        property did not follow; else not exercised."""
        if self.violation is not None:
            return Verdict.VIOLATED
        if self.shown_by is not None:
            return Verdict.SHOWN
        return Verdict.VIOLATED if final and self.exercised else Verdict.NOT_EXERCISED

    def outcome(self, final: bool = True) -> Outcome:
        """The verdict with the events of the violating match, else of the furthest match."""
        if self.violation is not None:
            events = self.violation.events
        else:
            events = self.shown_by if self.shown_by is not None else self._furthest
        return Outcome(self.prop, self.verdict(final), events, self.capped, self.violation)

    # -----------------------------------------------------------------------------------------

    def _advance_all(self, m: Message) -> None:
        """Every partial match advanced by ``m`` (repeats merged, complete ones let go)."""
        advanced: dict[tuple[int, int, tuple[int, ...], Vars], _Partial] = {}
        for p in self._partials:
            for q in self._advance(p, m):
                advanced.setdefault((q.step, q.count, tuple(id(x) for x in q.bound), q.vars), q)
        self._partials = [q for q in advanced.values() if q.step < len(self.prop.steps)]
        if len(self._partials) > MAX_PARTIALS:
            self._partials, self.capped = self._partials[:MAX_PARTIALS], True

    def _advance(self, p: _Partial, m: Message) -> list[_Partial]:
        """``p`` and what ``m`` makes of it: kept, advanced (and kept, when the step branches),
        or dropped (a ``next`` step whose first fitting communicate is not related)."""
        step = self.prop.steps[p.step]
        ways = _fits(step, m, p.vars)
        if not ways:
            return self._guard(p, m)
        if not self._related(step, m, p.bound):
            return [] if step.next and p.count == 0 else self._guard(p, m)
        qs = [self._step(p, m, step.at_least, vs) for vs in ways]
        keep = p.count == 0 and self._branch[p.step] and not step.next
        return [p, *qs] if keep else qs

    def _guard(self, p: _Partial, m: Message) -> list[_Partial]:
        """``p``, unless ``m`` is what an absent step before its next step forbids: then the
        partial match ends, and when it had bound the situation, the property is violated."""
        if p.count:
            return [p]
        for g in self._guards[p.step]:
            guard = self.prop.steps[g]
            if _fits(guard, m, p.vars) and self._related(guard, m, p.bound):
                if g >= self.prop.situation and self.violation is None:
                    self.violation = Violation(g, m, p.bound)
                return []
        return [p]

    def _step(self, p: _Partial, m: Message, at_least: int, vs: Vars) -> _Partial:
        """``p`` with ``m`` counted for its step (and bound, when it is the first), with the
        variables ``vs``."""
        bound = (*p.bound, m) if p.count == 0 else p.bound
        if p.count + 1 < at_least:
            return _Partial(p.step, p.count + 1, bound, vs)
        q = _Partial(self._after[p.step], 0, bound, vs)
        if len(q.bound) > len(self._furthest):
            self._furthest = q.bound
        self.exercised = self.exercised or p.step + 1 >= self.prop.situation
        if q.step == len(self.prop.steps) and self.shown_by is None:
            self.shown_by = q.bound
        return q

    def _related(self, step: EventPattern, m: Message, bound: tuple[Message, ...]) -> bool:
        """``m`` stands to the events ``bound`` as ``step`` asks."""
        ev = {name: bound[i] for name, i in self._names.items() if i < len(bound)}
        return all(rule(step, m, ev, self._closed) for rule in _RELATIONS) and (
            step.within_s is None or not bound or m.t - bound[-1].t <= step.within_s
        )


def _next_binding(steps: tuple[EventPattern, ...], i: int) -> int:
    """The index of the first step from ``i`` on that binds an event (len(steps): none)."""
    while i < len(steps) and steps[i].absent:
        i += 1
    return i


def _guards_before(steps: tuple[EventPattern, ...], i: int) -> tuple[int, ...]:
    """The indices of the absent steps just before step ``i``."""
    j = i
    while j > 0 and steps[j - 1].absent:
        j -= 1
    return tuple(range(j, i)) if not steps[i].absent else ()


def _branches(steps: tuple[EventPattern, ...], after: list[int]) -> list[bool]:
    """Per step, whether it binds each fitting communicate in turn (module docstring): a later
    step names it, or it is followed closely (:func:`_followed_closely`)."""
    named = {n for s in steps for n in s.names()}
    return [
        (s.name is not None and s.name in named) or _followed_closely(steps, i, after[i])
        for i, s in enumerate(steps)
    ]


def _followed_closely(steps: tuple[EventPattern, ...], i: int, after: int) -> bool:
    """Step ``i`` must bind each fitting communicate in turn: an absent step follows it (a
    forbidden communicate ends a match, and a later one may start again), or the next binding
    step is ``within_s`` or ``next`` of it."""
    if i + 1 < len(steps) and steps[i + 1].absent:
        return True
    return after < len(steps) and (steps[after].within_s is not None or steps[after].next)


def _same(step: EventPattern, m: Message, ev: Events, closed: Closed) -> bool:
    return step.same_conversation is None or m.conversation == ev[step.same_conversation].conversation


def _other(step: EventPattern, m: Message, ev: Events, closed: Closed) -> bool:
    return step.other_conversation is None or m.conversation != ev[step.other_conversation].conversation


def _answers(step: EventPattern, m: Message, ev: Events, closed: Closed) -> bool:
    if step.answers is None:
        return True
    asked = ev[step.answers]
    offered = _reply_with(asked)
    return m.conversation == asked.conversation and offered is not None and _in_reply_to(m) == offered


def _open(step: EventPattern, m: Message, ev: Events, closed: Closed) -> bool:
    if step.while_open is None:
        return True
    opened = ev[step.while_open]
    return not closed.get((opened.channel, opened.conversation), set()) - {opened.sender}


def _refers(step: EventPattern, m: Message, ev: Events, closed: Closed) -> bool:
    return all(field_value(m.content, f) == ev[n].conversation for f, n in step.refers.items())


def _is_above(step: EventPattern, m: Message, ev: Events, closed: Closed) -> bool:
    return all(
        _above(field_value(m.content, f), field_value(ev[n].content, f)) for f, n in step.above.items()
    )


_RELATIONS = (_same, _other, _answers, _open, _refers, _is_above)
"""How a communicate must stand to the earlier events (services/spec/properties.py)."""


def _above(value: Any, than: Any) -> bool:
    numbers = (int, float)
    return isinstance(value, numbers) and isinstance(than, numbers) and value > than


def evaluate(prop: Property, messages: Iterable[Message]) -> Outcome:
    """``prop`` over a whole run's communicates (causal order, copies left out)."""
    monitor = Monitor(prop)
    for m in messages:
        monitor.feed(m)
    return monitor.outcome(final=True)
