"""How long a_ta expects each L_EX command to run, a table: a request to ag_ex waits twice that
plus a margin for its answer (services/agents/task_executor/agent.py ``COMMAND_MARGIN_S``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from shared.fipa_codec.languages.l_ex import MoveJoints, MoveTool, Tilt, Wait

UNTIMED_S = 10.0
"""The expected run (s) of a command with no row in ``EXPECTED_S`` (a grasp, a release, a
look, an observation: none states its duration)."""


def _own(command: Any) -> float:
    return float(command.duration)


EXPECTED_S: dict[type, Callable[[Any], float]] = {
    MoveTool: _own,
    MoveJoints: _own,
    Tilt: _own,
    Wait: _own,
}
"""The expected run (s) of each timed L_EX command type, from the command (docs/executor.md,
"Adding a robot primitive")."""


def expected_s(command: object) -> float:
    """How long ``command`` is expected to run (s): its row of ``EXPECTED_S``, else
    ``UNTIMED_S``."""
    row = EXPECTED_S.get(type(command))
    return row(command) if row is not None else UNTIMED_S
