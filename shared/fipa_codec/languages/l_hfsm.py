"""L_HFSM: ground task networks (C3 request) and hierarchical plans (C3 inform, C1 request).

A plan is a hierarchical finite state machine (paper §5.4): each :class:`PlanNode` is a state;
a composite state runs its children in order and succeeds when the last one does; a leaf state
runs one :data:`Action` in a_ta. Any failing state fails its parents (a_ta reports Error).
A plan with ``complete=False`` ends in a sensing step after which the planner must be asked
again (interleaved planning and execution, paper §5.7): a_ta then reports Replan.

Safe interruption (paper §3.2, the cup of tea): a_co may cancel a running plan. a_ta has
ag_ex halt the running command at once (mid-pour the jar turned upright first), then makes the
robot safe from where it stopped: inside an ``atomic`` state (a take, a set-down, a pour's
tilt: states that must not be left half-way) it runs the rest of a take or set-down; then it
runs the plan's safe-stop HFSM named by the halted leaf's (or, after the rest of an atomic
state, the next leaf's) ``on_cancel`` (the planner computed it from what the hands hold at that
point: put it down in a safe place), and only then reports Preempted
(services/agents/task_executor/agent.py).
"""

from __future__ import annotations

import functools
import operator
from typing import TYPE_CHECKING, Annotated, cast

import msgspec
from msgspec.structs import force_setattr

from shared.fipa_codec.languages.base import LANGUAGES, Language, register
from shared.fipa_codec.languages.common import CLOCK, Vec3
from shared.fipa_codec.languages.l_ex import L_EX, ExecutorCommand

if TYPE_CHECKING:
    _Command = ExecutorCommand
else:  # decoded as bytes, then as a term of L_EX as it stands (Execute.__post_init__)
    _Command = Annotated[msgspec.Raw, msgspec.Meta(extra={"language": "L_EX"})]
from shared.fipa_codec.languages.l_hc import TaskAtom


class GroundTaskNetwork(msgspec.Struct, frozen=True, tag="gtn", kw_only=True):
    """The planning problem a_co sends to a_pl: the tasks to achieve, in order, for command
    ``task_id``; ``plan_index`` counts the plans requested for it (1, 2, …)."""

    task_id: str
    tasks: tuple[TaskAtom, ...]
    plan_index: int = 1


class Execute(msgspec.Struct, frozen=True, tag="execute"):
    """Leaf action: request ``command`` (an L_EX command) from ag_ex on C5 and wait for its
    result. Decoded, ``command`` is a term of L_EX with the commands added to it since
    (``l_ex.add_command``); a term that is not one fails the decoding as any invalid value."""

    command: _Command

    def __post_init__(self) -> None:
        if isinstance(self.command, msgspec.Raw):
            force_setattr(self, "command", _command(bytes(self.command)))


def _command(raw: bytes) -> ExecutorCommand:
    """The L_EX command in ``raw``: msgpack (content) or JSON (a state file, a record)."""
    language = LANGUAGES[L_EX.name]
    if raw.lstrip()[:1] != b"{":
        return cast(ExecutorCommand, language.decode(raw))
    try:
        return cast(ExecutorCommand, _json_decoder(language.types).decode(raw))
    except msgspec.ValidationError as exc:
        raise language.error(exc) from None


@functools.cache
def _json_decoder(types: tuple[type[msgspec.Struct], ...]) -> msgspec.json.Decoder[msgspec.Struct]:
    return msgspec.json.Decoder(functools.reduce(operator.or_, types))


class ExpectedPosition(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """What the plan assumes: ``object``'s frame is within ``tolerance`` m of ``position``
    (world, m) and, when ``max_tilt`` (rad) is given, stands upright: its z axis within
    ``max_tilt`` of the world's. ``max_sigma`` (m): how well the step after it needs the
    position known (a grasp); an estimate less certain than that is looked at again."""

    object: str
    position: Vec3
    tolerance: float = 0.03
    max_tilt: float | None = None
    max_sigma: float | None = None


class Perceive(msgspec.Struct, frozen=True, tag="perceive", omit_defaults=True):
    """Leaf action: request an Observe from ag_ex and inform a_km of what was seen (C6).
    ``objects`` empty means the whole scene. When an object is not where ``expect`` says (or
    not seen), the world differs from the plan: a_ta reports Replan; when ``judges`` is set,
    the observation judges the task's outcome (the object stands where it was put) and a
    difference ends the plan in Error with the reason instead."""

    objects: tuple[str, ...] = ()
    expect: tuple[ExpectedPosition, ...] = ()
    judges: bool = False


class Assert(msgspec.Struct, frozen=True, tag="assert", kw_only=True):
    """Leaf action: inform a_km (C6) that ``subject`` now stands in ``relation`` (``heldBy``,
    ``on``, ``in``) to ``object`` (an empty object retracts the relation)."""

    subject: str
    relation: str
    object: str


class CheckContent(msgspec.Struct, frozen=True, tag="check_content", kw_only=True):
    """Leaf action: observe ``container`` and fail unless it holds at least ``min_fraction``
    of the scene's content particles."""

    container: str
    min_fraction: float


Action = Execute | Perceive | Assert | CheckContent


class PlanNode(msgspec.Struct, frozen=True, kw_only=True):
    """A state of the plan HFSM: ``name``; either ``children`` (a composite state, run in
    order) or an ``action`` (a leaf state). ``task`` names the HTN task it refines.
    ``atomic``: once entered, the state is not left half-way: a cancel halts its leaf, and
    a_ta then runs its rest (a pour's halt turns the jar upright itself; module docstring).
    ``on_cancel`` (leaves): the key in :attr:`HierarchicalPlan.safe_stops` of the HFSM to run
    when a cancel takes effect before or in this leaf (None: nothing to put down). ``duration``: the
    leaf's expected execution time (s), for a_co's schedule step."""

    name: str
    children: tuple[PlanNode, ...] = ()
    action: Action | None = None
    task: str | None = None
    atomic: bool = False
    on_cancel: str | None = None
    duration: float = 0.0

    def leaves(self, prefix: str = "") -> list[tuple[str, PlanNode]]:
        """All leaf states in execution order, each with its path (``a/b/c``)."""
        path = f"{prefix}/{self.name}" if prefix else self.name
        if not self.children:
            return [(path, self)]
        out: list[tuple[str, PlanNode]] = []
        for child in self.children:
            out.extend(child.leaves(path))
        return out

    def atomic_spans(self, prefix: str = "") -> list[tuple[int, int]]:
        """Leaf index ranges ``[start, end)`` of the atomic states, in execution order (an
        atomic state inside another is covered by the outer one)."""
        spans: list[tuple[int, int]] = []

        def walk(node: PlanNode, start: int) -> int:
            if not node.children:
                return start + 1
            end = start
            for child in node.children:
                end = walk(child, end)
            if node.atomic:
                spans[:] = [s for s in spans if not (start <= s[0] and s[1] <= end)]
                spans.append((start, end))
            return end

        walk(self, 0)
        return sorted(spans)


class HierarchicalPlan(msgspec.Struct, frozen=True, tag="plan", kw_only=True):
    """A plan for ``task_id``: the HFSM ``root``; ``complete`` False when a replan must follow;
    ``cost`` expected execution time (s); ``km_queries`` and ``planning_time_s`` describe how
    it was made. ``safe_stops``: the HFSMs that put held objects down in a safe place, by the
    key the leaves' ``on_cancel`` names."""

    plan_id: str
    task_id: str
    root: PlanNode
    complete: bool = True
    cost: float = 0.0
    km_queries: int = 0
    planning_time_s: Annotated[float, CLOCK] = 0.0
    safe_stops: dict[str, PlanNode] = msgspec.field(default_factory=dict)


class PlanFailure(msgspec.Struct, frozen=True, tag="plan_failure", kw_only=True):
    """Why no plan exists for ``task_id``, in words a person can read."""

    task_id: str
    reason: str


L_HFSM = register(
    Language(
        "L_HFSM",
        "O_RoCo",
        (GroundTaskNetwork, HierarchicalPlan, PlanFailure, Execute, Perceive, Assert, CheckContent),
    )
)
