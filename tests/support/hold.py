"""A robot primitive a test adds (tests/agents/test_new_primitive.py; docs/executor.md, "Adding a
robot primitive"): ``Hold(duration)``, the robot keeps its setpoints for ``duration`` s, and its
row for each table of each layer — the L_EX command, the executor's primitive, the planner's
action, method and HFSM leaf, a_ta's expected duration — and the specification's text with Hold
among the contents of C5's requests. roco itself never adds it.

:func:`register` puts the rows a_ta's and ag_ex's processes dispatch through into this process
for good (tests/support/hold_agent.py, the fleet's entry module); the test's own process adds and
takes back its rows with ``monkeypatch``."""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

import msgspec

from shared.fipa_codec.languages.l_ex import CommandResult, add_command
from shared.fipa_codec.languages.l_hfsm import Execute
from velma.executor.runtime import Runtime


class Hold(msgspec.Struct, frozen=True, tag="hold", kw_only=True):
    """Keep the current setpoints for ``duration`` s."""

    duration: float


class HoldPrimitive:
    """Hold's primitive: ends ``ok`` once ``duration`` s of robot time have passed."""

    def __init__(self, command: Hold) -> None:
        self.command = command
        self.end = 0.0

    def start(self, rt: Runtime) -> CommandResult | None:
        self.end = rt.time + self.command.duration
        return None

    def step(self, rt: Runtime) -> CommandResult | None:
        return CommandResult(command="hold", ok=True, sim_time=rt.time) if rt.time >= self.end else None


def a_hold(s: Any, path: str, duration: float) -> Any:
    """The planner action (GTPyhop): the state, one step on."""
    s.steps += 1
    return s


def hold_leaf(duration: float) -> tuple[Execute, float]:
    """The action's HFSM leaf (services/agents/planner/hfsm.py ``LEAVES``): the command and its
    expected duration (s)."""
    return Execute(Hold(duration=duration)), duration  # type: ignore[arg-type]  # added at run time


def m_hold_still(s: Any, path: str, duration: float) -> list[tuple[Any, ...]]:
    """A task method that uses the action."""
    return [("a_hold", f"{path}/hold", duration)]


def hold_s(command: Hold) -> float:
    """a_ta's expected duration of ``command`` (s; services/agents/task_executor/expected.py)."""
    return command.duration


def with_hold(spec_text: str) -> str:
    """The specification's text with Hold among the contents of a_ta's requests on C5. Raises
    ValueError when the text does not list C5's contents as the shipped specification does."""
    listed = '"Observe", "Wait"]'
    if spec_text.count(listed) != 1:
        raise ValueError(f"the specification lists {listed!r} {spec_text.count(listed)} times, not once")
    return spec_text.replace(listed, '"Observe", "Wait", "Hold"]')


LEFT_OUT = "HOLD_ROWS_LEFT_OUT"
"""The environment variable that names (comma-separated, of :data:`TABLES`) the tables whose row
the entry module tests/support/hold_agent.py leaves out of its process: a test's planted fault."""

TABLES = ("COMMANDS", "PRIMITIVES", "EXPECTED_S")
"""The tables :func:`register` adds a row to: L_EX's commands (and the language's vocabulary),
the executor's primitives, a_ta's expected durations."""


def register(left_out: Collection[str] = ()) -> None:
    """Add Hold's row to each of :data:`TABLES` but those named in ``left_out``, in this process,
    for good. Raises ValueError for a name not in :data:`TABLES`, or as ``add_command`` does
    (Hold registered already)."""
    unknown = set(left_out) - set(TABLES)
    if unknown:
        raise ValueError(f"no table {', '.join(sorted(unknown))} (tables: {', '.join(TABLES)})")
    if "COMMANDS" not in left_out:
        add_command(Hold)
    if "PRIMITIVES" not in left_out:
        from velma.executor.primitives import PRIMITIVES

        PRIMITIVES[Hold] = HoldPrimitive
    if "EXPECTED_S" not in left_out:
        from services.agents.task_executor.expected import EXPECTED_S

        EXPECTED_S[Hold] = hold_s
