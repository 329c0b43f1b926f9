"""The kitchen HTN domain of a_pl, on GTPyhop (Nau et al.'s Python HTN planner).

Tasks: ``pour(src, dst)``, ``fetch(obj, arm)``, ``place(obj, surface, arm)``,
``localise(obj)``, ``pour_into(src, dst, arm)``. Primitive actions are the leaf states of
the HFSM a_ta runs (L_HFSM). Each task and action carries the path of the HFSM state it
becomes, so the plan keeps its hierarchy (``pour(jar,bowl)/fetch_jar/grasp``).

Interleaved planning and execution (paper §5.7): pouring needs the target's pose observed
where it stands. While the bowl is still in the cabinet, ``pour`` refines into getting both
objects out, putting the bowl on the table and localising it, and ends with ``a_replan``:
the plan is partial and a_co asks for plan #2 once it has run.

Geometry is computed from a_km's knowledge only: object poses, where Velma faces each piece
of furniture, grasp affordances (grip frame in the object frame, approach, entry, lift and
retreat), placement positions and pouring parameters; plus the move durations below. Turning
the torso turns the hands and what they hold about the torso axis (world z through the
origin).
"""

from __future__ import annotations

import contextlib
import io
from typing import Any

import numpy as np
import pinocchio as pin

from services.planner import geometry as geo
from services.planner.knowledge import ARMS, Knowledge
from shared.fipa_codec.languages.common import Pose, Vec3
from shared.fipa_codec.languages.l_wm import GraspAffordance

with contextlib.redirect_stdout(io.StringIO()):  # GTPyhop prints a banner on import
    import gtpyhop

LONG_MOVE_S = 3.0
"""Duration of a move between work places, or a torso turn (s)."""
SHORT_MOVE_S = 1.5
"""Duration of a move out of or along a cabinet shelf, or down to a placement (s)."""
CONTACT_SPEED_M_S = 0.133
"""Speed of the final approach to a grasp (m/s); at least 1 s."""
CONTENT_SHARE_REQUIRED = 0.9
"""Share of the content that must end in the target for a pour to count as done."""

DOMAIN_NAME = "roco_kitchen"


class PlanningFailure(Exception):
    """No plan exists; the message says why in words a person can read."""


# ------------------------------------------------------------------ state helpers
def _k(s: Any) -> Knowledge:
    k: Knowledge = s.k
    return k


def _rot_z(angle: float) -> Pose:
    return geo.from_se3(pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, angle), np.zeros(3)))


def _turned(pose: Pose, angle: float) -> Pose:
    """``pose`` rotated by ``angle`` about the torso axis (world z through the origin)."""
    return geo.compose(_rot_z(angle), pose)


def _scaled(v: Vec3, k: float) -> Vec3:
    return (v[0] * k, v[1] * k, v[2] * k)


def _grasp_pose(grasp: GraspAffordance) -> Pose:
    return Pose(grasp.grip_in_object.position, grasp.grip_in_object.orientation)


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


def a_posture(s: Any, path: str, arm: str, positions: tuple[float, ...], duration: float) -> Any:
    s.tool[arm] = None  # the grip pose after a joint move is not tracked
    return _step(s)


def a_preshape(s: Any, path: str, arm: str, opening: float) -> Any:
    return _step(s) if s.holding[arm] is None else False


def a_grasp(s: Any, path: str, arm: str, obj: str, spread: float) -> Any:
    if s.holding[arm] is not None:
        return False
    return _step(s)


def a_held(s: Any, path: str, obj: str, arm: str, picked_from: str) -> Any:
    grasp = _best_grasp(s, obj, arm)
    if grasp is None:
        return False
    s.holding[arm] = obj
    s.where[obj] = ("heldBy", f"{arm}_gripper")
    s.picked_from[obj] = picked_from
    s.grip[obj] = Pose(grasp.grip_in_object.position, grasp.grip_in_object.orientation)
    return _step(s)


def a_release(s: Any, path: str, arm: str, obj: str, opening: float) -> Any:
    if s.holding[arm] != obj:
        return False
    s.holding[arm] = None
    return _step(s)


def a_put(s: Any, path: str, obj: str, surface: str) -> Any:
    s.where[obj] = ("on", surface)
    return _step(s)


def a_face(s: Any, path: str, angle: float, duration: float) -> Any:
    """Turn the torso to ``angle``; hands and what they hold turn with it."""
    if s.torso is not None and abs(s.torso - angle) > 1e-9:
        delta = angle - s.torso
        for arm in ARMS:
            if s.tool[arm] is not None:
                s.tool[arm] = _turned(s.tool[arm], delta)
            held = s.holding[arm]
            if held is not None and s.pose.get(held) is not None:
                s.pose[held] = _turned(s.pose[held], delta)
    s.torso = angle
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


def _face_steps(s: Any, path: str, name: str, angle: float) -> list[tuple[Any, ...]]:
    """Turn the torso to ``angle`` unless it is there already: a long turn slowly."""
    if s.torso is not None and abs(s.torso - angle) < 1e-9:
        return []
    duration = LONG_MOVE_S if s.torso is not None and abs(s.torso - angle) > 0.5 else SHORT_MOVE_S
    return [("a_face", f"{path}/face_{name}", angle, duration)]


def _face(s: Any, path: str, furniture: str) -> list[tuple[Any, ...]]:
    """Look at ``furniture``'s view point and turn to it."""
    info = _k(s).objects.get(furniture)
    if info is None or info.facing is None:
        return []
    look = [("a_look", f"{path}/look_at_{furniture}", info.view_point)] if info.view_point is not None else []
    return [*look, *_face_steps(s, path, furniture, info.facing)]


def _grasp_facing(s: Any, obj: str) -> float:
    """The torso angle at which ``obj`` was grasped (the facing of where it was picked)."""
    where = s.picked_from.get(obj)
    info = _k(s).objects.get(where) if where else None
    return info.facing if info is not None and info.facing is not None else 0.0


def m_fetch(s: Any, path: str, obj: str, arm: str) -> Any:
    """Face the furniture ``obj`` is in, (take the grasp's arm posture,) open the hand,
    (enter,) approach, grasp, lift, withdraw."""
    pose = s.pose.get(obj)
    grasp = _best_grasp(s, obj, arm)
    if pose is None or grasp is None or s.holding[arm] is not None:
        return False
    where = s.where.get(obj, ("", ""))[1]
    # containers are rotationally symmetric: a grasp ignores their yaw (world axes)
    obj_frame = Pose(pose.position)
    grip = geo.compose(obj_frame, _grasp_pose(grasp))
    approach = geo.rotate(grasp.approach, obj_frame)
    pre = geo.translated(grip, _scaled(approach, -grasp.distance))
    lifted = geo.translated(grip, (0.0, 0.0, grasp.lift))
    out = geo.translated(lifted, _scaled(geo.rotate(grasp.retreat, obj_frame), grasp.retreat_distance))
    steps: list[tuple[Any, ...]] = _face(s, path, where)
    if grasp.posture:
        steps.append(("a_posture", f"{path}/arm_posture", arm, grasp.posture, SHORT_MOVE_S))
    steps.append(("a_preshape", f"{path}/open_hand", arm, grasp.preshape))
    first_move = SHORT_MOVE_S if grasp.posture else LONG_MOVE_S
    if grasp.entry is not None and grasp.entry_distance > 0:
        entry = geo.translated(pre, _scaled(geo.rotate(grasp.entry, obj_frame), -grasp.entry_distance))
        steps += [
            ("a_move", f"{path}/enter", arm, entry, first_move),
            ("a_move", f"{path}/pregrasp", arm, pre, SHORT_MOVE_S),
        ]
    else:
        steps.append(("a_move", f"{path}/pregrasp", arm, pre, first_move))
    reach_s = round(max(1.0, grasp.distance / CONTACT_SPEED_M_S), 2)
    return [
        *steps,
        ("a_move", f"{path}/reach", arm, grip, reach_s),
        ("a_grasp", f"{path}/grasp", arm, obj, grasp.spread),
        ("a_held", f"{path}/held", obj, arm, where),
        ("a_move", f"{path}/lift", arm, lifted, 1.0),
        ("a_move", f"{path}/withdraw", arm, out, SHORT_MOVE_S),
    ]


def m_place(s: Any, path: str, obj: str, surface: str, arm: str) -> Any:
    """Face ``surface``, bring ``obj`` above a free place, lower it, release, lift the hand
    and park it out of the way."""
    if s.holding[arm] != obj:
        return False
    placement = _k(s).placements.get((obj, surface))
    info = _k(s).objects.get(surface)
    if placement is None or not placement.positions or info is None or info.facing is None:
        return False
    x, y, z = placement.positions[0]
    # the held object turned with the torso: facing the surface it has this yaw
    yaw = _rot_z(info.facing - _grasp_facing(s, obj))
    target = Pose((x, y, z + placement.clearance), yaw.orientation)
    grip = geo.compose(target, s.grip[obj])
    above = geo.translated(grip, (0.0, 0.0, placement.approach))
    park = geo.translated(grip, geo.rotate(placement.park, _rot_z(info.facing)))
    grasp = _best_grasp(s, obj, arm)
    opening = grasp.preshape if grasp is not None else 0.5
    return [
        *_face_steps(s, path, surface, info.facing),
        ("a_look", f"{path}/look_at_place", (x, y, z)),
        ("a_move", f"{path}/carry", arm, above, LONG_MOVE_S),
        ("a_move", f"{path}/lower", arm, grip, SHORT_MOVE_S),
        ("a_release", f"{path}/release", arm, obj, opening),
        ("a_put", f"{path}/put", obj, surface),
        ("a_move", f"{path}/clear", arm, above, 1.0),
        ("a_move", f"{path}/park", arm, park, SHORT_MOVE_S),
    ]


def m_localise(s: Any, path: str, obj: str) -> Any:
    """Observe ``obj`` (and what the hands hold: their poses changed with every move)."""
    if s.pose.get(obj) is None:
        return False
    held = [o for o in s.holding.values() if o is not None and o != obj]
    return [("a_perceive", f"{path}/perceive", ",".join([obj, *held]))]


def m_pour_into(s: Any, path: str, src: str, dst: str, arm: str) -> Any:
    """Turn to pour, bring the source upright beside the target, tilt it about the pivot,
    wait for the content to run out, tilt back."""
    pour = _k(s).pours.get((src, dst))
    dst_pose = s.pose.get(dst)
    if pour is None or dst_pose is None or s.holding[arm] != src or src not in s.grip:
        return False
    turn = _rot_z(pour.facing)
    origin = geo.translated(Pose(dst_pose.position), geo.rotate(pour.source_in_target, turn))
    src_target = Pose(origin.position, _rot_z(pour.facing - _grasp_facing(s, src)).orientation)
    grip = geo.compose(src_target, s.grip[src])
    above = geo.translated(grip, (0.0, 0.0, pour.approach_height))
    pivot = geo.translated(Pose(dst_pose.position), geo.rotate(pour.pivot_in_target, turn)).position
    axis = geo.rotate(pour.axis, turn)
    return [
        *_face_steps(s, path, "pour", pour.facing),
        ("a_move", f"{path}/bring_over", arm, above, LONG_MOVE_S),
        ("a_move", f"{path}/lower", arm, grip, SHORT_MOVE_S),
        ("a_tilt", f"{path}/tilt", arm, pivot, axis, pour.angle, pour.duration),
        ("a_wait", f"{path}/let_run_out", pour.wait),
        ("a_tilt", f"{path}/tilt_back", arm, pivot, axis, -pour.angle, pour.untilt_duration),
    ]


ACTIONS = (
    a_move,
    a_posture,
    a_face,
    a_preshape,
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
    s.torso = None
    s.picked_from = {n: o.picked_from for n, o in k.objects.items() if o.picked_from}
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
