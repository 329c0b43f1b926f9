"""L_HC: human commands (C2, a_hi → a_co, fipa-request) and their outcome."""

from __future__ import annotations

import msgspec

from shared.fipa_codec.languages.base import Language, register


class TaskAtom(msgspec.Struct, frozen=True, array_like=True):
    """A task in a ground task network: ``name`` and object arguments, e.g. ("pour", ("jar", "bowl"))."""

    name: str
    args: tuple[str, ...] = ()


class HumanCommand(msgspec.Struct, frozen=True, tag="command", kw_only=True):
    """An interpreted human command. ``text`` is what the person said; ``goal`` the task it
    names; ``priority`` larger is more urgent; ``deadline_s`` seconds from acceptance."""

    text: str
    goal: TaskAtom
    priority: int = 0
    deadline_s: float | None = None


class CommandOutcome(msgspec.Struct, frozen=True, tag="outcome", kw_only=True):
    """How a command ended: ``succeeded`` and a one-line ``detail`` for the person."""

    command_id: str
    succeeded: bool
    detail: str = ""


L_HC = register(Language("L_HC", "O_RoCo", (HumanCommand, CommandOutcome)))
