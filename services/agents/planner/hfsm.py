"""From GTPyhop's action list to the L_HFSM plan a_ta runs (paper §5.4: plans as HFSMs)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from shared.fipa_codec.languages.common import Pose, Vec3
from shared.fipa_codec.languages.l_ex import (
    TORSO_JOINT,
    Arm,
    Grasp,
    LookAt,
    MoveJoints,
    MoveTool,
    Release,
    Tilt,
    Wait,
)
from shared.fipa_codec.languages.l_hfsm import (
    Action,
    Assert,
    CheckContent,
    Execute,
    ExpectedPosition,
    Perceive,
    PlanNode,
)

KNOWLEDGE_ONLY = frozenset({"a_poured"})
"""Planner actions that only model an effect on the knowledge (the hypothetical state of
goals.py); they have no leaf in the plan a_ta runs."""
OBSERVE_COST_S = 1.0
EXPECT_TOLERANCE_M = 0.03
"""How far an object may be from where a Perceive step expects it (m)."""
PLACED_TOLERANCE_M = 0.03
"""How far a placed object may stand from its place for the placement to count as done (m):
the set-down lowers it to within the place's clearance and lets go."""
PLACED_MAX_TILT = 0.26
"""How far (rad, ≈ 15°) a placed object's axis may lean for it to count as standing upright."""
GRASP_MAX_SIGMA_M = 0.005
"""How uncertain (1-σ, m) an object's observed position may be for the grasp that follows the
observation: the hand's pre-grasp opening leaves ≈ 1 cm either way; a larger σ makes a_ta look
again (a second view) before it reaches."""


Leaf = tuple[Action | None, float]
"""A planner action's L_HFSM leaf action (None: no leaf, a replan marker) and its expected
duration (s)."""


def _move(arm: str, target: Pose, duration: float, guard: float | None = None) -> Leaf:
    return Execute(MoveTool(arm=Arm(arm), target=target, duration=duration, guard=guard)), duration


def _face(angle: float, duration: float) -> Leaf:
    return Execute(MoveJoints(positions={TORSO_JOINT: angle}, duration=duration)), duration


def _preshape(arm: str, opening: float) -> Leaf:
    return Execute(Release(arm=Arm(arm), opening=opening)), 1.0


def _grasp(arm: str, _obj: str, spread: float, at: Pose, load: float | None = None) -> Leaf:
    return Execute(Grasp(arm=Arm(arm), spread=spread, at=at, load=load)), 1.5


def _posture(arm: str, positions: tuple[float, ...], duration: float) -> Leaf:
    joints = {f"{arm}_arm_{i}_joint": float(q) for i, q in enumerate(positions)}
    return Execute(MoveJoints(positions=joints, duration=duration)), duration


def _held(obj: str, arm: str, _picked_from: str) -> Leaf:
    return Assert(subject=obj, relation="heldBy", object=f"{arm}_gripper"), 0.0


def _release(arm: str, _obj: str, opening: float) -> Leaf:
    return Execute(Release(arm=Arm(arm), opening=opening)), 1.0


def _put(obj: str, furniture: str, relation: str, _position: Vec3) -> Leaf:
    return Assert(subject=obj, relation=relation, object=furniture), 0.0


def _look(point: Vec3) -> Leaf:
    x, y, z = point  # a list when it came through the plan's arguments
    return Execute(LookAt(point=(x, y, z))), 1.0


def _perceive(names: str, expect: tuple[str, Vec3] | None, placed: bool = False) -> Leaf:
    judges = bool(placed)
    expected = (
        (
            ExpectedPosition(
                object=expect[0],
                position=(expect[1][0], expect[1][1], expect[1][2]),
                tolerance=PLACED_TOLERANCE_M if judges else EXPECT_TOLERANCE_M,
                max_tilt=PLACED_MAX_TILT if judges else None,
                max_sigma=None if judges else GRASP_MAX_SIGMA_M,
            ),
        )
        if expect is not None
        else ()
    )
    objects = tuple(names.split(",")) if names else ()
    return Perceive(objects=objects, expect=expected, judges=judges), OBSERVE_COST_S


def _tilt(arm: str, pivot: Vec3, axis: Vec3, angle: float, duration: float) -> Leaf:
    return Execute(Tilt(arm=Arm(arm), pivot=pivot, axis=axis, angle=angle, duration=duration)), duration


def _wait(duration: float) -> Leaf:
    return Execute(Wait(duration=duration)), duration


def _check(container: str, share: float) -> Leaf:
    return CheckContent(container=container, min_fraction=share), OBSERVE_COST_S


def _replan() -> Leaf:
    return None, 0.0


LEAVES: dict[str, Callable[..., Leaf]] = {
    "a_move": _move,
    "a_face": _face,
    "a_preshape": _preshape,
    "a_grasp": _grasp,
    "a_posture": _posture,
    "a_held": _held,
    "a_release": _release,
    "a_put": _put,
    "a_look": _look,
    "a_perceive": _perceive,
    "a_tilt": _tilt,
    "a_wait": _wait,
    "a_check": _check,
    "a_replan": _replan,
}
"""The L_HFSM leaf of each planner action (services/agents/planner/domain.py ``ACTIONS``) but
those in ``KNOWLEDGE_ONLY``, a table: called with the action's arguments (after its path), a
row gives its ``Leaf`` (docs/executor.md, "Adding a robot primitive")."""


def leaf_action(name: str, args: tuple[Any, ...]) -> Leaf:
    """The L_HFSM leaf action of one planner action, and its expected duration (s)
    (``LEAVES``). Raises ValueError for an action name the HFSM does not know."""
    make = LEAVES.get(name)
    if make is None:
        raise ValueError(f"unknown planner action {name}")
    return make(*args)


def to_hfsm(
    actions: list[tuple[Any, ...]],
    *,
    on_cancel: list[str | None] | None = None,
    atomic: frozenset[str] = frozenset(),
) -> tuple[PlanNode, bool, float]:
    """Build the plan HFSM from ``(name, path, *args)`` actions.

    ``on_cancel[i]`` becomes the ``on_cancel`` of action i's leaf; composite states whose
    name is in ``atomic`` are marked atomic. Returns (root state, complete, cost):
    ``complete`` is False when the plan ends with a replan marker; ``cost`` is the sum of
    expected leaf durations (s). Raises ValueError when actions do not share one root.
    """
    order: dict[str, list[str]] = {}
    complete, cost = True, 0.0
    root_name: str | None = None
    leaves: dict[str, PlanNode] = {}
    for i, (name, path, *args) in enumerate(actions):
        if name in KNOWLEDGE_ONLY:
            continue
        action, duration = leaf_action(name, tuple(args))
        cost += duration
        if action is None:
            complete = False
            continue
        parts = path.split("/")
        if root_name is None:
            root_name = parts[0]
        elif parts[0] != root_name:
            raise ValueError(f"action {path} outside root {root_name}")
        for depth in range(1, len(parts)):
            parent, child = "/".join(parts[:depth]), "/".join(parts[: depth + 1])
            kids = order.setdefault(parent, [])
            if child not in kids:
                kids.append(child)
        leaves[path] = PlanNode(
            name=parts[-1],
            action=action,
            duration=round(duration, 3),
            on_cancel=on_cancel[i] if on_cancel is not None else None,
        )
    if root_name is None:
        raise ValueError("empty plan")

    def build(path: str) -> PlanNode:
        if path in leaves:
            return leaves[path]
        name = path.rsplit("/", 1)[-1]
        return PlanNode(
            name=name,
            children=tuple(build(c) for c in order.get(path, [])),
            task=name,
            atomic=name in atomic,
        )

    return build(root_name), complete, round(cost, 2)
