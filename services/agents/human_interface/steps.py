"""One goal said in steps: a line of several requests whose earlier ones only prepare the last
("take the jar and pour it into the bowl", "find the cup and bring it to me", "grab the jar and
hold it") asks for the last; a_pl plans the steps itself (paper §5: a_pl decomposes a task).

An earlier request prepares the last when it asks for the same command, or for a step
(:data:`STEPS`: taking a thing in a hand or to the table, finding it) on a thing the last command is about. A
yes-or-no question an earlier request raised ("grab the jar": bring it, or only take it?), or a
bring said with no one to bring it to ("take the cup and put it in the cabinet"), counts by
either of the commands it may mean. Anything else (two goals: "bring me the cup and pour the jar
into the bowl") is no single goal, and the line is not read as one."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from services.agents.human_interface.dialogue import Offer
from services.agents.human_interface.intents import Command
from shared.fipa_codec.languages.l_hc import TaskAtom

STEPS: dict[str, frozenset[str] | None] = {"fetch": None, "localise": None, "bring": frozenset({"pour"})}
"""Tasks of a_pl (planner/domain.py TASKS) that prepare others on the same thing, with those
they prepare (None: any): "take" and "grab" say "bring" as often as "take in a hand" ("take the
jar and pour it"); a bring before a task that moves the thing away ("bring me the jar and put it
back") is a goal of its own."""


@dataclass(frozen=True)
class Either:
    """A request that may mean either of two commands: a bring said with no one to bring it to
    ("take the cup and put it away": bring it, or only take it in a hand)."""

    offer: Command
    other: Command


def bare_bring(intent: Command) -> Either:
    """``intent`` (a bring) as either it or taking the thing in a hand only (``fetch``)."""
    return Either(intent, dataclasses.replace(intent, goal=TaskAtom("fetch", intent.goal.args)))


Said = Command | Offer | Either
"""What one request of the line reads as: a command, a yes-or-no question back, or either of
two commands."""


def _goals(said: Said) -> list[TaskAtom]:
    """The goals ``said`` may mean: a command's own; both commands a question names."""
    if isinstance(said, Command):
        return [said.goal]
    return [c.goal for c in (said.offer, said.other) if c is not None]


def _prepares(goal: TaskAtom, last: TaskAtom) -> bool:
    """Whether ``goal`` is ``last`` or a step towards it (:data:`STEPS`, on its things)."""
    if goal == last or goal.name not in STEPS:
        return goal == last
    prepared = STEPS[goal.name]
    return (prepared is None or last.name in prepared) and set(goal.args) <= set(last.args)


def one_goal(said: list[Said]) -> list[Command] | None:
    """The commands of ``said`` (one per request, in order) when the earlier ones only prepare
    the last (module docstring), the last read as a command; None otherwise. A question the
    last raised is read as its ``offer`` only when an earlier request names that command."""
    *earlier, said_last = said
    last = _last(earlier, said_last)
    if last is None or not all(any(_prepares(g, last.goal) for g in _goals(s)) for s in earlier):
        return None
    return [_as_command(s, last) for s in earlier] + [last]


def _last(earlier: list[Said], last: Said) -> Command | None:
    """The command the last request asks for: its own (a bring as said); of a question back,
    the one of the two it names that an ``earlier`` request names too (None when not exactly
    one)."""
    if isinstance(last, Command):
        return last
    if isinstance(last, Either):  # a bring, as said: it is no step of anything after it
        return last.offer
    named = [g for s in earlier for g in _goals(s)]
    choices = [c for c in (last.offer, last.other) if c is not None and c.goal in named]
    return choices[0] if len(choices) == 1 else None


def _as_command(said: Said, last: Command) -> Command:
    """``said`` as a command: a question back read as the command it names that prepares
    ``last``."""
    if isinstance(said, Command):
        return said
    goal = next(g for g in _goals(said) if _prepares(g, last.goal))
    return dataclasses.replace(said.offer, goal=goal)


__all__ = ["STEPS", "Either", "Said", "bare_bring", "one_goal"]
