"""The kitchen HTN domain of a_pl, on GTPyhop (Nau et al.'s Python HTN planner).

Tasks: ``pour(src, dst)``, ``fetch(obj, arm)``, ``place(obj, surface, arm)``,
``localise(obj)``, ``pour_into(src, dst, arm)``. Primitive actions are the leaf states of
the HFSM a_ta runs (L_HFSM). Each task and action carries the path of the HFSM state it
becomes, so the plan keeps its hierarchy (``pour(jar,bowl)/fetch_jar/grasp``).

Interleaved planning and execution (paper §5.7): pouring needs the target's pose observed
where it stands. While the bowl is still in the cabinet, ``pour`` refines into getting both
objects out, putting the bowl on the table and localising it, and ends with ``a_replan``:
the plan is partial and a_co asks for plan #2 once it has run.

Geometry is computed from a_km's knowledge only: object poses, grasp affordances (grip frame
in the object frame, approach direction and distance), placement positions and pouring
parameters; plus the motion constants below (lift height, retreat distance, durations).
"""

from __future__ import annotations

import contextlib
import io
import math
from typing import Any

from services.planner import geometry as geo
from services.planner.knowledge import ARMS, Knowledge
from shared.fipa_codec.languages.common import Pose, Vec3
from shared.fipa_codec.languages.l_wm import GraspAffordance

with contextlib.redirect_stdout(io.StringIO()):  # GTPyhop prints a banner on import
    import gtpyhop

LIFT_M = 0.04
"""Height an object is lifted off its support before it is moved (m)."""
RETREAT_M = 0.30
"""Distance an object is pulled out of the cabinet towards the robot (m)."""
CARRY_HEIGHT_M = 0.12
"""Height above the placement/pour pose the object travels at (m)."""
SPEED_M_S = 0.15
"""Nominal tool speed used to choose move durations (m/s)."""
MIN_MOVE_S = 1.5
CONTENT_SHARE_REQUIRED = 0.9
"""Share of the content that must end in the target for a pour to count as done."""

DOMAIN_NAME = "roco_kitchen"


class PlanningFailure(Exception):
    """No plan exists; the message says why in words a person can read."""


# ------------------------------------------------------------------ state helpers
def _k(s: Any) -> Knowledge:
    k: Knowledge = s.k
    return k


def _duration(a: Pose, b: Pose) -> float:
    d = math.dist(a.position, b.position)
    return round(max(MIN_MOVE_S, d / SPEED_M_S), 2)


def _grip_target(obj_pose: Pose, grasp: GraspAffordance) -> Pose:
    return geo.compose(obj_pose, Pose(grasp.grip_in_object.position, grasp.grip_in_object.orientation))


def _best_grasp(s: Any, obj: str, arm: str) -> GraspAffordance | None:
    found = _k(s).grasps.get((obj, arm), ())
    return found[0] if found else None


def _free_arm_for(s: Any, obj: str, exclude: str | None = None) -> str | None:
    pose = s.pose.get(obj)
    side = "left" if pose is not None and pose.position[1] > 0 else "right"
    order = (side, *(a for a in ARMS if a != side))
    for arm in order:
        if arm != exclude and s.holding[arm] is None and _best_grasp(s, obj, arm) is not None:
            return arm
    return None


def _move(s: Any, path: str, arm: str, target: Pose) -> tuple[Any, ...]:
    return ("a_move", path, arm, target, _duration(s.tool[arm], target) if s.tool[arm] else 3.0)


def _retreat_vector(pose: Pose, distance: float) -> Vec3:
    """Horizontal unit vector from ``pose`` towards the robot (world origin), times distance."""
    x, y, _ = pose.position
    n = math.hypot(x, y) or 1.0
    return (-x / n * distance, -y / n * distance, 0.0)


# ------------------------------------------------------------------ actions (operators)
# GTPyhop leaves out of the plan an action whose result equals its input state, so every
# action counts itself in ``s.steps``: a sensing or waiting step is still a step of the HFSM.
def _step(s: Any) -> Any:
    s.steps += 1
    return s


def a_move(s: Any, path: str, arm: str, target: Pose, duration: float) -> Any:
    s.tool[arm] = target
    held = s.holding[arm]
    if held is not None:
        s.pose[held] = geo.compose(target, geo.inverse(s.grip[held]))
        s.localised[held] = False
    return _step(s)


def a_open(s: Any, path: str, arm: str) -> Any:
    return _step(s) if s.holding[arm] is None else False


def a_grasp(s: Any, path: str, arm: str, obj: str, spread: float) -> Any:
    if s.holding[arm] is not None:
        return False
    return _step(s)


def a_held(s: Any, path: str, obj: str, arm: str) -> Any:
    grasp = _best_grasp(s, obj, arm)
    if grasp is None:
        return False
    s.holding[arm] = obj
    s.where[obj] = ("heldBy", f"{arm}_gripper")
    s.grip[obj] = Pose(grasp.grip_in_object.position, grasp.grip_in_object.orientation)
    return _step(s)


def a_release(s: Any, path: str, arm: str, obj: str) -> Any:
    if s.holding[arm] != obj:
        return False
    s.holding[arm] = None
    return _step(s)


def a_put(s: Any, path: str, obj: str, surface: str) -> Any:
    s.where[obj] = ("on", surface)
    return _step(s)


def a_look(s: Any, path: str, point: Vec3) -> Any:
    return _step(s)


def a_perceive(s: Any, path: str, obj: str) -> Any:
    s.observed.add(obj)
    return _step(s)


def a_tilt(s: Any, path: str, arm: str, pivot: Vec3, axis: Vec3, angle: float, duration: float) -> Any:
    return _step(s) if s.holding[arm] is not None else False


def a_wait(s: Any, path: str, duration: float) -> Any:
    return _step(s)


def a_check(s: Any, path: str, container: str, share: float) -> Any:
    return _step(s)


def a_replan(s: Any, path: str) -> Any:
    s.partial = True
    return _step(s)


# ------------------------------------------------------------------ methods
def m_pour_locate(s: Any, path: str, src: str, dst: str) -> Any:
    """Where src or dst has never been seen: observe the scene, then plan again."""
    missing = [o for o in (src, dst) if s.pose.get(o) is None]
    if not missing:
        return False
    return [("a_perceive", f"{path}/observe_scene", ""), ("a_replan", f"{path}/replan")]


def m_pour_now(s: Any, path: str, src: str, dst: str) -> Any:
    """dst stands localised on a surface: fetch src if needed, pour, check."""
    if not (s.where.get(dst, ("",))[0] == "on" and s.localised.get(dst)):
        return False
    if _k(s).pours.get((src, dst)) is None:
        return False
    arm = next((a for a in ARMS if s.holding[a] == src), None)
    todo: list[tuple[Any, ...]] = []
    if arm is None:
        arm = _free_arm_for(s, src)
        if arm is None:
            return False
        todo.append(("fetch", f"{path}/fetch_{src}", src, arm))
    todo.append(("pour_into", f"{path}/pour_into_{dst}", src, dst, arm))
    todo.append(("a_check", f"{path}/check_{dst}", dst, CONTENT_SHARE_REQUIRED))
    return todo


def m_pour_prepare(s: Any, path: str, src: str, dst: str) -> Any:
    """dst is not yet on a surface: take both out, put dst on the table, localise it, replan."""
    if s.where.get(dst, ("",))[0] == "on":
        return False
    todo: list[tuple[Any, ...]] = []
    src_arm = next((a for a in ARMS if s.holding[a] == src), None)
    if src_arm is None:
        src_arm = _free_arm_for(s, src)
        if src_arm is None:
            return False
        todo.append(("fetch", f"{path}/fetch_{src}", src, src_arm))
    dst_arm = next((a for a in ARMS if s.holding[a] == dst), None)
    if dst_arm is None:
        dst_arm = _free_arm_for(s, dst, exclude=src_arm)
        if dst_arm is None:
            return False
        todo.append(("fetch", f"{path}/fetch_{dst}", dst, dst_arm))
    todo.append(("place", f"{path}/place_{dst}", dst, "table", dst_arm))
    todo.append(("localise", f"{path}/localise_{dst}", dst))
    todo.append(("a_replan", f"{path}/replan"))
    return todo


def m_fetch(s: Any, path: str, obj: str, arm: str) -> Any:
    """Approach, grasp, lift and pull ``obj`` out towards the robot."""
    pose = s.pose.get(obj)
    grasp = _best_grasp(s, obj, arm)
    if pose is None or grasp is None or s.holding[arm] is not None:
        return False
    grip = _grip_target(pose, grasp)
    approach_world = geo.rotate(grasp.approach, pose)
    pre = geo.translated(grip, tuple(-grasp.distance * c for c in approach_world))  # type: ignore[arg-type]
    lifted = geo.translated(grip, (0.0, 0.0, LIFT_M))
    out = geo.translated(lifted, _retreat_vector(pose, RETREAT_M))
    s_pre = pre
    return [
        ("a_open", f"{path}/open_hand", arm),
        ("a_move", f"{path}/pregrasp", arm, s_pre, _duration(s.tool[arm], s_pre) if s.tool[arm] else 4.0),
        ("a_move", f"{path}/reach", arm, grip, _duration(pre, grip)),
        ("a_grasp", f"{path}/grasp", arm, obj, grasp.spread),
        ("a_held", f"{path}/held", obj, arm),
        ("a_move", f"{path}/lift", arm, lifted, _duration(grip, lifted)),
        ("a_move", f"{path}/pull_out", arm, out, _duration(lifted, out)),
    ]


def m_place(s: Any, path: str, obj: str, surface: str, arm: str) -> Any:
    """Carry ``obj`` above a free place on ``surface``, lower it, release, retreat."""
    if s.holding[arm] != obj:
        return False
    placement = _k(s).placements.get((obj, surface))
    if placement is None or not placement.positions:
        return False
    current = s.pose[obj]
    target_obj = Pose(placement.positions[0], geo.upright(current).orientation)
    grip = geo.compose(target_obj, s.grip[obj])
    above = geo.translated(grip, (0.0, 0.0, CARRY_HEIGHT_M))
    back = geo.translated(above, _retreat_vector(target_obj, 0.10))
    return [
        ("a_move", f"{path}/carry", arm, above, _duration(s.tool[arm], above)),
        ("a_move", f"{path}/lower", arm, grip, _duration(above, grip)),
        ("a_release", f"{path}/release", arm, obj),
        ("a_put", f"{path}/put", obj, surface),
        ("a_move", f"{path}/retreat", arm, above, _duration(grip, above)),
        ("a_move", f"{path}/clear", arm, back, _duration(above, back)),
    ]


def m_localise(s: Any, path: str, obj: str) -> Any:
    pose = s.pose.get(obj)
    if pose is None:
        return False
    return [("a_look", f"{path}/look", pose.position), ("a_perceive", f"{path}/perceive", obj)]


def m_pour_into(s: Any, path: str, src: str, dst: str, arm: str) -> Any:
    """Bring ``src`` (held by ``arm``) over ``dst``, tilt to pour, wait, tilt back."""
    pour = _k(s).pours.get((src, dst))
    dst_pose = s.pose.get(dst)
    if pour is None or dst_pose is None or s.holding[arm] != src:
        return False
    src_now = geo.upright(s.pose[src])
    x, y, z = dst_pose.position
    src_target = Pose((x + pour.offset[0], y + pour.offset[1], z + pour.offset[2]), src_now.orientation)
    grip = geo.compose(src_target, s.grip[src])
    above = geo.translated(grip, (0.0, 0.0, CARRY_HEIGHT_M))
    size = _k(s).objects[src].size or (0.0, 0.0, 0.0)
    pivot = (src_target.position[0], src_target.position[1], src_target.position[2] + size[2])
    return [
        ("a_move", f"{path}/carry", arm, above, _duration(s.tool[arm], above)),
        ("a_move", f"{path}/approach", arm, grip, _duration(above, grip)),
        ("a_tilt", f"{path}/tilt", arm, pivot, pour.axis, pour.angle, pour.duration),
        ("a_wait", f"{path}/empty", 2.0),
        ("a_tilt", f"{path}/tilt_back", arm, pivot, pour.axis, -pour.angle, pour.duration),
    ]


ACTIONS = (
    a_move,
    a_open,
    a_grasp,
    a_held,
    a_release,
    a_put,
    a_look,
    a_perceive,
    a_tilt,
    a_wait,
    a_check,
    a_replan,
)


def declare() -> None:
    """Create (once) and select the GTPyhop domain."""
    if gtpyhop.is_domain_created(DOMAIN_NAME):
        gtpyhop.set_current_domain(gtpyhop.find_domain_by_name(DOMAIN_NAME))
        return
    with contextlib.redirect_stdout(io.StringIO()):
        gtpyhop.Domain(DOMAIN_NAME)
        gtpyhop.declare_actions(*ACTIONS)
        gtpyhop.declare_task_methods("pour", m_pour_locate, m_pour_now, m_pour_prepare)
        gtpyhop.declare_task_methods("fetch", m_fetch)
        gtpyhop.declare_task_methods("place", m_place)
        gtpyhop.declare_task_methods("localise", m_localise)
        gtpyhop.declare_task_methods("pour_into", m_pour_into)
        gtpyhop.set_verbose_level(0)
        gtpyhop.set_recursive_planning(True)


def initial_state(k: Knowledge, tool_poses: dict[str, Pose | None]) -> Any:
    """The planning state from a_km's knowledge: poses, where things are, what is held."""
    s = gtpyhop.State("kitchen")
    s.k = k
    s.pose = {n: o.pose for n, o in k.objects.items()}
    s.localised = {n: o.localised for n, o in k.objects.items()}
    s.where = {}
    s.holding = {arm: None for arm in ARMS}
    s.grip = {}
    s.tool = {arm: tool_poses.get(arm) for arm in ARMS}
    s.observed = set()
    s.partial = False
    s.steps = 0
    for n, o in k.objects.items():
        if o.held_by:
            arm = o.held_by.removesuffix("_gripper")
            s.where[n] = ("heldBy", o.held_by)
            s.holding[arm] = n
            grasp = _best_grasp(s, n, arm)
            if grasp is not None:
                s.grip[n] = Pose(grasp.grip_in_object.position, grasp.grip_in_object.orientation)
        elif o.location:
            s.where[n] = (o.relation or "in", o.location)
    for arm in ARMS:
        held = s.holding[arm]
        if held is not None and s.tool.get(arm) is None and s.pose.get(held) is not None and held in s.grip:
            s.tool[arm] = geo.compose(s.pose[held], s.grip[held])
    return s


def find_plan(k: Knowledge, task: tuple[str, ...], root: str) -> list[tuple[Any, ...]]:
    """A list of action tuples ``(name, path, *args)`` achieving ``task``.
    Raises PlanningFailure with a readable reason when there is none."""
    declare()
    s = initial_state(k, {})
    name, *args = task
    if name not in ("pour", "fetch", "place", "localise"):
        # other tasks would need their own methods; say so rather than guess
        raise PlanningFailure(f"I know no way to {name}")
    for obj in args:
        if obj not in k.objects:
            raise PlanningFailure(f"I know of no {obj}")
    if name == "fetch":
        arm = _free_arm_for(s, args[0])
        if arm is None:
            raise PlanningFailure(f"no free hand can grasp the {args[0]}")
        args = [args[0], arm]
    elif name == "place":
        arm = next((a for a in ARMS if s.holding[a] == args[0]), None)
        if arm is None:
            raise PlanningFailure(f"the {args[0]} is not in a hand")
        args = [args[0], args[1], arm]
    with contextlib.redirect_stdout(io.StringIO()):
        plan = gtpyhop.find_plan(s, [(name, root, *args)])
    if not plan:
        raise PlanningFailure(f"no way to {name} {' '.join(map(str, args))} from what I know")
    return list(plan)
