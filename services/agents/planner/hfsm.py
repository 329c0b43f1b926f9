"""From GTPyhop's action list to the L_HFSM plan a_ta runs (paper §5.4: plans as HFSMs)."""

from __future__ import annotations

from typing import Any

from shared.fipa_codec.languages.l_ex import Arm, Grasp, LookAt, MoveJoints, MoveTool, Release, Tilt, Wait
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


def leaf_action(name: str, args: tuple[Any, ...]) -> tuple[Action | None, float]:
    """The L_HFSM leaf action of one planner action, and its expected duration (s).
    Raises ValueError for an action name the HFSM does not know."""
    if name == "a_move":
        arm, target, duration, *guard = args
        move = MoveTool(arm=Arm(arm), target=target, duration=duration, guard=guard[0] if guard else None)
        return Execute(move), duration
    if name == "a_face":
        angle, duration = args
        return Execute(MoveJoints(positions={"torso_0_joint": angle}, duration=duration)), duration
    if name == "a_preshape":
        arm, opening = args
        return Execute(Release(arm=Arm(arm), opening=opening)), 1.0
    if name == "a_grasp":
        arm, _obj, spread, at = args
        return Execute(Grasp(arm=Arm(arm), spread=spread, at=at)), 1.5
    if name == "a_posture":
        arm, positions, duration = args
        joints = {f"{arm}_arm_{i}_joint": float(q) for i, q in enumerate(positions)}
        return Execute(MoveJoints(positions=joints, duration=duration)), duration
    if name == "a_held":
        obj, arm, _picked_from = args
        return Assert(subject=obj, relation="heldBy", object=f"{arm}_gripper"), 0.0
    if name == "a_release":
        arm, _obj, opening = args
        return Execute(Release(arm=Arm(arm), opening=opening)), 1.0
    if name == "a_put":
        obj, furniture, relation, _position = args
        return Assert(subject=obj, relation=relation, object=furniture), 0.0
    if name == "a_look":
        (point,) = args
        return Execute(LookAt(point=tuple(point))), 1.0
    if name == "a_perceive":
        names, expect, *placed = args
        judges = bool(placed and placed[0])
        expected = (
            (
                ExpectedPosition(
                    object=expect[0],
                    position=tuple(expect[1]),
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
    if name == "a_tilt":
        arm, pivot, axis, angle, duration = args
        return Execute(Tilt(arm=Arm(arm), pivot=pivot, axis=axis, angle=angle, duration=duration)), duration
    if name == "a_wait":
        return Execute(Wait(duration=args[0])), args[0]
    if name == "a_check":
        container, share = args
        return CheckContent(container=container, min_fraction=share), OBSERVE_COST_S
    if name == "a_replan":
        return None, 0.0
    raise ValueError(f"unknown planner action {name}")


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
