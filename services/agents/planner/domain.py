"""The kitchen HTN domain of a_pl, on GTPyhop (Nau et al.'s Python HTN planner).

Tasks: ``pour(src, dst)``, ``move_to(obj, furniture)`` (fetch if needed, then place: "bring
the cup to the table", "put the bowl back in the cabinet"), ``fetch(obj, arm)``,
``place(obj, furniture, arm)``, ``localise(obj)``, ``pour_into(src, dst, arm)`` and
``safe_stop()`` (put whatever the hands hold down in a free place on the table: the HFSM a_ta
runs when cancelled, paper §3.2; in an order whose turns and carries pass clear of what already
stands, ``clearance.py``). Primitive actions are the leaf states of the HFSM a_ta runs
(L_HFSM). Each task and action carries the path of the HFSM state it becomes, so the plan
keeps its hierarchy (``pour(jar,bowl)/fetch_jar/take/grasp``). States named in
``ATOMIC_STATES`` must not be left half-way (a grasp, setting an object down, the tilt of a
pour): a cancel halts the running leaf, and a_ta then runs the rest of a take or set-down (a
pour's halt turns the jar upright itself) before the safe stop
(services/agents/task_executor/agent.py).

Grasp affordances are defined for objects standing in the cabinet (facing ``GRASP_FACING``);
for an object standing elsewhere the planner turns the grasp about the vertical by the
facing of the furniture it stands on, and turns the torso to that facing: Velma stands to
every piece of furniture as to the cabinet. The frame a grasp is relative to ("grasp frame")
is the object's position with the yaw of the facing it was taken at; a held object keeps the
hand's relative pose, so it is put down with the yaw of the facing where it is put down.

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
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from services.agents.planner.clearance import Body, carry_meets, turn_meets
from services.agents.planner.knowledge import ARMS, Knowledge
from shared.fipa_codec.languages.common import Pose, Vec3
from shared.fipa_codec.languages.l_hc import CONTENT_SHARE_REQUIRED
from shared.fipa_codec.languages.l_wm import GraspAffordance
from velma import frames as geo

with contextlib.redirect_stdout(io.StringIO()):  # GTPyhop prints a banner on import
    import gtpyhop

LONG_MOVE_S = 3.0
"""Duration of a move between work places, or a torso turn (s)."""
SHORT_MOVE_S = 1.5
"""Duration of a move out of or along a cabinet shelf, or down to a placement (s)."""
CONTACT_SPEED_M_S = 0.133
"""Speed of the final approach to a grasp (m/s); at least 1 s."""
GRASP_FACING = 0.0
"""Torso facing (rad) for which grasp affordances are given (the cabinet's)."""
FREE_RADIUS_M = 0.12
"""A placement position is free when no other object's frame is this close (horizontal, m)."""
ATOMIC_STATES = frozenset({"take", "set_down", "tilt_pour"})
"""HFSM states a cancel does not interrupt (see module docstring)."""
SAFE_SURFACE = "table"
"""Where the safe stop puts held objects down."""
SET_DOWN_GUARD_N = 5.0
"""Contact-force guard (N) of a set-down's lower (L_EX ``MoveTool.guard``): the lower ends where
the hand is once the surface bears what it holds, also when the hand holds it lower than
planned (unguarded, the move pushes on and times out some mm short of its target). The force
resisting the motion (wrist F/T sensor, change since the move began) read at most 0.34 N in
lowers that met nothing, mostly the hand's own acceleration (the scripted pour, seed 0: the
jar with its content onto its pour-start pose 0.34 N, the bowl until it touched the table
0.31 N; the jar towards its shelf until it met it 0.21 N), and at most 1.2 N in the scripted
pour's other moves that neither touched nor lifted anything; a contact read 18 N (the jar
meeting its shelf) and 35 N (the bowl meeting the table) in its first ms
(tests/velma/test_guarded_commands.py). 5 N is 15 times the lowers' noise; a gentler contact
reaches it within ≈ 5 mm more of the setpoint's travel at the default Cartesian stiffness
(1000 N/m)."""

DOMAIN_NAME = "roco_kitchen"


class PlanningFailure(Exception):
    """No plan exists; the message says why in words a person can read."""


# ------------------------------------------------------------------ state helpers
def _k(s: Any) -> Knowledge:
    k: Knowledge = s.k
    return k


def _rot_z(angle: float) -> Pose:
    return geo.about_z(angle)


def _turned(pose: Pose, angle: float) -> Pose:
    """``pose`` rotated by ``angle`` about the torso axis (world z through the origin)."""
    return geo.compose(_rot_z(angle), pose)


def _scaled(v: Vec3, k: float) -> Vec3:
    return (v[0] * k, v[1] * k, v[2] * k)


def _grasp_pose(grasp: GraspAffordance) -> Pose:
    return Pose(grasp.grip_in_object.position, grasp.grip_in_object.orientation)


def _best_grasp(s: Any, obj: str, arm: str) -> GraspAffordance | None:
    """The first of a_km's grasps of ``obj`` by ``arm`` meant for the furniture ``obj`` is on
    or in (``GraspAffordance.on``), else the first (e.g. for an object held)."""
    found = _k(s).grasps.get((obj, arm), ())
    where = s.where.get(obj, ("", ""))[1]
    return next((g for g in found if where in g.on), found[0] if found else None)


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


def a_move(s: Any, path: str, arm: str, target: Pose, duration: float, guard: float | None = None) -> Any:
    """Move ``arm``'s grip frame to ``target``; ``guard`` (N): end early on a contact this
    strong (L_EX ``MoveTool.guard``; the hand then stands a few mm short of ``target``)."""
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


def a_grasp(s: Any, path: str, arm: str, obj: str, spread: float, at: Pose, load: float | None = None) -> Any:
    """Close ``arm``'s hand on ``obj``; ``at``: the grasp pose the reach brought the hand to
    (L_EX ``Grasp.at``: ag_ex does not close a hand that is not there); ``load``: ``obj``'s
    mass as a_km knows it (kg; L_EX ``Grasp.load``, the arm's payload prior)."""
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


def a_put(s: Any, path: str, obj: str, furniture: str, relation: str, position: Vec3) -> Any:
    """``obj`` now stands ``relation`` (in/on) ``furniture`` at ``position``; it must be seen
    again before its pose counts as localised."""
    s.where[obj] = (relation, furniture)
    s.localised[obj] = False
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


def a_perceive(s: Any, path: str, obj: str, expect: tuple[str, Vec3] | None, placed: bool = False) -> Any:
    """Observe the objects named in ``obj`` (comma-separated; "" the whole scene);
    ``expect`` (object, position) is checked by a_ta before the plan goes on. ``placed``: the
    object was just put at that position, and this observation judges the placement (it must
    stand there, upright: hfsm.py's tolerances)."""
    s.observed.add(obj)
    return _step(s)


def a_tilt(s: Any, path: str, arm: str, pivot: Vec3, axis: Vec3, angle: float, duration: float) -> Any:
    return _step(s) if s.holding[arm] is not None else False


def a_wait(s: Any, path: str, duration: float) -> Any:
    return _step(s)


def a_check(s: Any, path: str, container: str, share: float) -> Any:
    """Observe ``container`` and fail unless it holds ``share`` of the content: a test of the
    world; it changes nothing in the plan's state."""
    return _step(s)


def a_poured(s: Any, path: str, src: str, dst: str, amount: int | None, into: int) -> Any:
    """The pour's effect on the knowledge (paper §5.7, the hypothetical state): the ``amount``
    particles ``src`` held (a_km's last count; None: not known) join the ``into`` that
    ``dst`` held, and ``src`` is empty. A knowledge-only step: a_ta does not execute it
    (hfsm.py); the world is judged by the ``a_check`` that follows."""
    if src not in s.holding.values():
        return False
    if amount is not None:
        s.content[dst] = into + amount
        s.content[src] = 0
    else:
        s.content.pop(dst, None)  # the target's count is no longer known
    return _step(s)


def a_replan(s: Any, path: str) -> Any:
    s.partial = True
    return _step(s)


# ------------------------------------------------------------------ methods
def m_pour_locate(s: Any, path: str, src: str, dst: str) -> Any:
    """Where src or dst has never been seen: observe the scene as the head sees it, then look
    at each furniture with a view point (a_km's ``roco:viewPoint``: the cabinet) and observe
    it, then plan again. After a power cycle a_km's renewed picture holds only what the robot
    saw from where it then stood; the kitchen's objects start in the cabinet."""
    missing = [o for o in (src, dst) if s.pose.get(o) is None]
    if not missing:
        return False
    viewed = sorted(n for n, o in _k(s).objects.items() if o.view_point is not None)
    looks = [
        step
        for name in viewed
        for step in (*_face(s, path, name), ("a_perceive", f"{path}/observe_{name}", "", None))
    ]
    return [("a_perceive", f"{path}/observe_scene", "", None), *looks, ("a_replan", f"{path}/replan")]


def m_pour_done(s: Any, path: str, src: str, dst: str) -> Any:
    """src is known empty and dst stands localised on a surface (a pour interrupted after its
    content ran out: nothing is left to pour, and a_km refuses a plan that pours an empty
    source): a held src is brought upright to its clear-view pose beside dst, then dst's content
    is checked."""
    if s.content.get(src) != 0 or not (s.where.get(dst, ("",))[0] == "on" and s.localised.get(dst)):
        return False
    todo: list[tuple[Any, ...]] = []
    arm = next((a for a in ARMS if s.holding[a] == src), None)
    pour, dst_pose = _k(s).pours.get((src, dst)), s.pose.get(dst)
    if arm is not None:
        if pour is None or dst_pose is None or src not in s.grip:
            return False
        turn = _rot_z(pour.facing)
        origin = geo.translated(Pose(dst_pose.position), geo.rotate(pour.source_in_target, turn))
        grip = geo.compose(Pose(origin.position, turn.orientation), s.grip[src])
        view = geo.translated(grip, geo.rotate(pour.clear_view, turn))
        todo += [
            *_face_steps(s, path, "pour", pour.facing),
            ("a_move", f"{path}/clear_view", arm, view, LONG_MOVE_S),
        ]
    todo.append(("a_check", f"{path}/check_{dst}", dst, CONTENT_SHARE_REQUIRED))
    return todo


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


def m_pour_relocate(s: Any, path: str, src: str, dst: str) -> Any:
    """dst was put on a surface but not seen there since (a stop came between its set-down and
    its look): look where it was put, observe it, then plan again."""
    pose = s.pose.get(dst)
    where = s.where.get(dst, ("", ""))
    if where[0] != "on" or s.localised.get(dst) or pose is None:
        return False
    facing = _place_facing(s, dst, where[1], pose.position)
    return [
        *(_face_steps(s, path, where[1], facing) if facing is not None else []),
        ("a_look", f"{path}/look_at_{dst}", pose.position),
        ("localise", f"{path}/localise_{dst}", dst),
        ("a_replan", f"{path}/replan"),
    ]


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
    todo.append(("place", f"{path}/place_{dst}", dst, "table", dst_arm))  # ends by localising it
    todo.append(("a_replan", f"{path}/replan"))
    return todo


def _face_steps(s: Any, path: str, name: str, angle: float) -> list[tuple[Any, ...]]:
    """Turn the torso to ``angle`` unless it is there already: a long turn slowly."""
    if s.torso is not None and abs(s.torso - angle) < 1e-9:
        return []
    duration = LONG_MOVE_S if s.torso is not None and abs(s.torso - angle) > 0.5 else SHORT_MOVE_S
    return [("a_face", f"{path}/face_{name}", angle, duration)]


def _facing(s: Any, furniture: str) -> float | None:
    info = _k(s).objects.get(furniture)
    return info.facing if info is not None else None


def _face(s: Any, path: str, furniture: str, facing: float | None = None) -> list[tuple[Any, ...]]:
    """Look at ``furniture``'s view point and turn to ``facing`` (default: the furniture's)."""
    info = _k(s).objects.get(furniture)
    angle = facing if facing is not None else (info.facing if info is not None else None)
    if info is None or angle is None:
        return []
    look = [("a_look", f"{path}/look_at_{furniture}", info.view_point)] if info.view_point is not None else []
    return [*look, *_face_steps(s, path, furniture, angle)]


def _relation(s: Any, furniture: str) -> str:
    """``in`` for containers (the cabinet), ``on`` for surfaces."""
    info = _k(s).objects.get(furniture)
    return "in" if info is not None and info.type == "Cabinet" else "on"


def m_fetch(s: Any, path: str, obj: str, arm: str) -> Any:
    """Face the furniture ``obj`` stands on or in, look at the object and check it is where it
    should be, (take the grasp's arm posture,) open the hand, (enter,) go to the pre-grasp pose
    and take it: approach, grasp, lift, withdraw (atomic). The posture and the entry are taken
    only at the grasp's own facing (the cabinet's, ``GRASP_FACING``): into the cabinet the hand
    enters horizontally; elsewhere (the table) it goes straight to the pre-grasp pose above the
    object (an entry point 0.25 m back from the bowl at its table place folds the right wrist
    onto itself)."""
    pose = s.pose.get(obj)
    grasp = _best_grasp(s, obj, arm)
    if pose is None or grasp is None or s.holding[arm] is not None:
        return False
    where = s.where.get(obj, ("", ""))[1]
    facing = _place_facing(s, obj, where, pose.position)
    turn = (facing if facing is not None else GRASP_FACING) - GRASP_FACING
    # containers are rotationally symmetric: a grasp ignores their yaw (the grasp frame)
    obj_frame = Pose(pose.position, _rot_z(turn).orientation)
    grip = geo.compose(obj_frame, _grasp_pose(grasp))
    approach = geo.rotate(grasp.approach, obj_frame)
    pre = geo.translated(grip, _scaled(approach, -grasp.distance))
    lifted = geo.translated(grip, (0.0, 0.0, grasp.lift))
    out = geo.translated(lifted, _scaled(geo.rotate(grasp.retreat, obj_frame), grasp.retreat_distance))
    steps: list[tuple[Any, ...]] = _face(s, path, where, facing)
    # the head looks at the object (after returning something to the cabinet it still looks
    # there) before the hand comes near it (the head camera perceives)
    steps += [
        ("a_look", f"{path}/look_at_{obj}", pose.position),
        ("a_perceive", f"{path}/see_{obj}", obj, (obj, pose.position)),
    ]
    own_facing = abs(turn) < 1e-9  # the posture and the entry are given for it
    if grasp.posture and own_facing:
        steps.append(("a_posture", f"{path}/arm_posture", arm, grasp.posture, SHORT_MOVE_S))
    steps.append(("a_preshape", f"{path}/open_hand", arm, grasp.preshape))
    steps += _to_pregrasp(path, arm, grasp, pre, obj_frame, own_facing)
    reach_s = round(max(1.0, grasp.distance / CONTACT_SPEED_M_S), 2)
    take = f"{path}/take"
    return [
        *steps,
        ("a_move", f"{take}/reach", arm, grip, reach_s),
        ("a_grasp", f"{take}/grasp", arm, obj, grasp.spread, grip, _mass(s, obj)),
        ("a_held", f"{take}/held", obj, arm, where),
        ("a_move", f"{take}/lift", arm, lifted, 1.0),
        ("a_move", f"{take}/withdraw", arm, out, SHORT_MOVE_S),
    ]


def _to_pregrasp(
    path: str, arm: str, grasp: Any, pre: Pose, obj_frame: Pose, own_facing: bool
) -> list[tuple[Any, ...]]:
    """The moves of ``m_fetch`` to the pre-grasp pose ``pre``: through the grasp's entry point
    (``grasp.entry_distance`` m back along ``grasp.entry`` in ``obj_frame``) when it has one and
    the torso is at the grasp's own facing, else straight there; the first move short after the
    grasp's posture, long without one."""
    first_move = SHORT_MOVE_S if grasp.posture else LONG_MOVE_S
    if grasp.entry is None or grasp.entry_distance <= 0 or not own_facing:
        return [("a_move", f"{path}/pregrasp", arm, pre, first_move)]
    entry = geo.translated(pre, _scaled(geo.rotate(grasp.entry, obj_frame), -grasp.entry_distance))
    return [
        ("a_move", f"{path}/enter", arm, entry, first_move),
        ("a_move", f"{path}/pregrasp", arm, pre, SHORT_MOVE_S),
    ]


def _place_facing(s: Any, obj: str, furniture: str, position: Vec3) -> float | None:
    """The torso angle to work at ``obj`` standing at ``position`` on ``furniture``: that of
    the place it stands on (the nearest within FREE_RADIUS_M), else the furniture's."""
    placement = _k(s).placements.get((obj, furniture))
    if placement is not None:
        for i, (x, y, _z) in enumerate(placement.positions):
            if (
                math.hypot(x - position[0], y - position[1]) < FREE_RADIUS_M
                and placement.facing(i) is not None
            ):
                return placement.facing(i)
    return _facing(s, furniture)


def _where_put(s: Any, obj: str, furniture: str) -> Pose | None:
    """Where ``obj``, put on or in ``furniture`` and not seen there since (a stop came between
    its set-down and its look), most likely stands: its place there (a_km's placements) that no
    other object occupies, when its last seen pose is at none of them (it is from before the
    move); None when that pose is at one, or there is no such place."""
    placement = _k(s).placements.get((obj, furniture))
    pose = s.pose.get(obj)
    if placement is None or pose is None:
        return None
    x, y, _ = pose.position
    if any(math.hypot(px - x, py - y) < FREE_RADIUS_M for px, py, _ in placement.positions):
        return None
    free = _free_place(s, obj, furniture)
    return Pose(free[1]) if free is not None else None


def _free_place(s: Any, obj: str, furniture: str) -> tuple[int, Vec3, float] | None:
    """The first place for ``obj`` on ``furniture`` (in a_km's order of preference) no other
    object occupies: its index, position and the torso angle to work there."""
    placement = _k(s).placements.get((obj, furniture))
    default = _facing(s, furniture)
    if placement is None:
        return None
    others = [
        p.position
        for o, p in s.pose.items()
        if o != obj and p is not None and s.where.get(o, ("", ""))[1] == furniture
    ]
    for i, (x, y, z) in enumerate(placement.positions):
        facing = placement.facing(i)
        facing = default if facing is None else facing
        if facing is not None and all(math.hypot(x - ox, y - oy) >= FREE_RADIUS_M for ox, oy, _ in others):
            return i, (x, y, z), facing
    return None


def m_place(s: Any, path: str, obj: str, furniture: str, arm: str) -> Any:
    """Face the place, bring ``obj`` above a free place, set it down (lower, release, clear:
    atomic), park the hand out of the way, and look at where it stands. The lower is guarded
    (``SET_DOWN_GUARD_N``): it ends where the surface bears the object, which the last look
    judges by where it stands (hfsm.py ``PLACED_TOLERANCE_M``), not by where the hand got to."""
    if s.holding[arm] != obj:
        return False
    placement = _k(s).placements.get((obj, furniture))
    free = _free_place(s, obj, furniture)
    if placement is None or free is None:
        return False
    i, (x, y, z), facing = free
    # the held object keeps the hand's relative pose: its grasp frame turns with the torso
    target = Pose((x, y, z + placement.clearance), _rot_z(facing).orientation)
    grip = geo.compose(target, s.grip[obj])
    above = geo.translated(grip, (0.0, 0.0, placement.approach_at(i)))
    if not _passes_clear(s, obj, facing, geo.compose(above, geo.inverse(s.grip[obj])).position):
        return False  # another order of put-downs may pass (m_safe_stop_reversed)
    park = geo.translated(grip, geo.rotate(placement.park_at(i), _rot_z(facing)))
    grasp = _best_grasp(s, obj, arm)
    opening = grasp.preshape if grasp is not None else 0.5
    down = f"{path}/set_down"
    return [
        *_face_steps(s, path, furniture, facing),
        ("a_look", f"{path}/look_at_place", (x, y, z)),
        ("a_move", f"{path}/carry", arm, above, LONG_MOVE_S),
        ("a_move", f"{down}/lower", arm, grip, SHORT_MOVE_S, SET_DOWN_GUARD_N),
        ("a_release", f"{down}/release", arm, obj, opening),
        ("a_put", f"{down}/put", obj, furniture, _relation(s, furniture), (x, y, z)),
        ("a_move", f"{down}/clear", arm, above, 1.0),
        ("a_move", f"{path}/park", arm, park, SHORT_MOVE_S),
        ("localise_placed", f"{path}/localise_{obj}", obj, (x, y, z)),
    ]


def m_move_to(s: Any, path: str, obj: str, furniture: str) -> Any:
    """Take ``obj`` if no hand holds it, then place it on or in ``furniture``."""
    if s.where.get(obj, ("", ""))[1] == furniture and s.localised.get(obj):
        return []  # already there
    arm = next((a for a in ARMS if s.holding[a] == obj), None)
    todo: list[tuple[Any, ...]] = []
    if arm is None:
        arm = _free_arm_for(s, obj)
        if arm is None:
            return False
        todo.append(("fetch", f"{path}/fetch_{obj}", obj, arm))
    todo.append(("place", f"{path}/place_{obj}", obj, furniture, arm))
    return todo


def m_safe_stop(s: Any, path: str) -> Any:
    """Put everything the hands hold down in free places on the table, the left hand's first."""
    held = [(arm, o) for arm, o in s.holding.items() if o is not None]
    return [("place", f"{path}/put_down_{o}", o, SAFE_SURFACE, arm) for arm, o in held]


def m_safe_stop_reversed(s: Any, path: str) -> Any:
    """The same, the right hand's first: for when the first put-down would leave its object
    where the other hand's turn or carry passes (``_passes_clear``)."""
    held = [(arm, o) for arm, o in s.holding.items() if o is not None]
    if len(held) < 2:
        return False
    return [("place", f"{path}/put_down_{o}", o, SAFE_SURFACE, arm) for arm, o in reversed(held)]


def _mass(s: Any, name: str) -> float | None:
    """``name``'s mass (kg) as a_km states it (None: not stated)."""
    info = _k(s).objects.get(name)
    return None if info is None else info.mass


def _body(s: Any, name: str) -> Body | None:
    """``name`` as an upright cylinder where the state has it (None: no pose or size known)."""
    info, pose = _k(s).objects.get(name), s.pose.get(name)
    if info is None or info.size is None or pose is None:
        return None
    return Body.of(name, pose.position, info.size)


def _standing(s: Any) -> list[Body]:
    """The objects standing on or in furniture whose pose and size a_km knows."""
    bodies = (_body(s, name) for name, (relation, _) in s.where.items() if relation in ("on", "in"))
    return [b for b in bodies if b is not None]


def _held(s: Any) -> list[Body]:
    """What the hands hold, as upright cylinders where the state has them."""
    bodies = (_body(s, o) for o in s.holding.values() if o is not None)
    return [b for b in bodies if b is not None]


def _passes_clear(s: Any, obj: str, facing: float, to: Vec3) -> bool:
    """Whether turning the torso from ``s.torso`` to ``facing`` keeps everything the hands hold
    clear of the standing objects, and so does carrying ``obj`` from there to ``to`` (its
    bottom centre, world, m): services/agents/planner/clearance.py."""
    standing, held = _standing(s), _held(s)
    turn = facing - s.torso if s.torso is not None else 0.0
    if turn and any(turn_meets(b, turn, standing) is not None for b in held):
        return False
    for b in held:
        if b.name == obj:
            turned = _turned(Pose(b.at), turn).position
            return carry_meets(b.moved(turned), to, standing) is None
    return True


def m_localise(s: Any, path: str, obj: str) -> Any:
    """Observe ``obj`` (and what the hands hold: their poses changed with every move)."""
    if s.pose.get(obj) is None:
        return False
    held = [o for o in s.holding.values() if o is not None and o != obj]
    return [("a_perceive", f"{path}/perceive", ",".join([obj, *held]), None)]


def m_localise_placed(s: Any, path: str, obj: str, position: Vec3) -> Any:
    """Observe ``obj`` just put at ``position`` (and what the hands hold): the observation
    judges the placement, which succeeded only if the object stands there upright."""
    held = [o for o in s.holding.values() if o is not None and o != obj]
    return [("a_perceive", f"{path}/perceive", ",".join([obj, *held]), (obj, position), True)]


def m_pour_into(s: Any, path: str, src: str, dst: str, arm: str) -> Any:
    """Turn to pour, bring the source upright beside the target, then (atomic) tilt it about
    the pivot, wait for the content to run out, tilt back. The lower is not guarded: it ends in
    the air beside the target, its bottom above the target's rim, where the tilt's pivot is
    planned; a hand stopped short by a contact would pour from elsewhere."""
    pour = _k(s).pours.get((src, dst))
    dst_pose = s.pose.get(dst)
    if pour is None or dst_pose is None or s.holding[arm] != src or src not in s.grip:
        return False
    turn = _rot_z(pour.facing)
    origin = geo.translated(Pose(dst_pose.position), geo.rotate(pour.source_in_target, turn))
    src_target = Pose(origin.position, turn.orientation)
    grip = geo.compose(src_target, s.grip[src])
    above = geo.translated(grip, (0.0, 0.0, pour.approach_height))
    pivot = geo.translated(Pose(dst_pose.position), geo.rotate(pour.pivot_in_target, turn)).position
    axis = geo.rotate(pour.axis, turn)
    tilt = f"{path}/tilt_pour"
    return [
        *_face_steps(s, path, "pour", pour.facing),
        ("a_move", f"{path}/bring_over", arm, above, LONG_MOVE_S),
        ("a_move", f"{path}/lower", arm, grip, SHORT_MOVE_S),
        ("a_tilt", f"{tilt}/tilt", arm, pivot, axis, pour.angle, pour.duration),
        ("a_wait", f"{tilt}/let_run_out", pour.wait),
        ("a_tilt", f"{tilt}/tilt_back", arm, pivot, axis, -pour.angle, pour.untilt_duration),
        ("a_poured", f"{tilt}/poured", src, dst, s.content.get(src), s.content.get(dst, 0)),
        (
            "a_move",
            f"{path}/clear_view",
            arm,
            geo.translated(grip, geo.rotate(pour.clear_view, turn)),
            SHORT_MOVE_S,
        ),
    ]


ACTIONS: dict[str, Callable[..., Any]] = {
    "a_move": a_move,
    "a_posture": a_posture,
    "a_face": a_face,
    "a_preshape": a_preshape,
    "a_grasp": a_grasp,
    "a_held": a_held,
    "a_release": a_release,
    "a_put": a_put,
    "a_look": a_look,
    "a_perceive": a_perceive,
    "a_tilt": a_tilt,
    "a_wait": a_wait,
    "a_check": a_check,
    "a_poured": a_poured,
    "a_replan": a_replan,
}
"""The planner actions by name, a table (GTPyhop's primitive actions: each takes the state, the
leaf's path and its arguments, and returns the state it leads to or False). An action with a
leaf in the plan a_ta runs has its row in services/agents/planner/hfsm.py ``LEAVES`` too
(docs/executor.md, "Adding a robot primitive")."""


def declare() -> None:
    """Create (once) and select the GTPyhop domain."""
    if gtpyhop.is_domain_created(DOMAIN_NAME):
        domain = gtpyhop.find_domain_by_name(DOMAIN_NAME)
        gtpyhop.set_current_domain(domain)
        if ACTIONS.keys() - domain._action_dict.keys():  # a row added since it was created
            gtpyhop.declare_actions(*ACTIONS.values())
        return
    with contextlib.redirect_stdout(io.StringIO()):
        gtpyhop.Domain(DOMAIN_NAME)
        gtpyhop.declare_actions(*ACTIONS.values())
        gtpyhop.declare_task_methods(
            "pour", m_pour_locate, m_pour_done, m_pour_now, m_pour_relocate, m_pour_prepare
        )
        gtpyhop.declare_task_methods("move_to", m_move_to)
        gtpyhop.declare_task_methods("fetch", m_fetch)
        gtpyhop.declare_task_methods("place", m_place)
        gtpyhop.declare_task_methods("localise", m_localise)
        gtpyhop.declare_task_methods("pour_into", m_pour_into)
        gtpyhop.declare_task_methods("localise_placed", m_localise_placed)
        gtpyhop.declare_task_methods("safe_stop", m_safe_stop, m_safe_stop_reversed)
        gtpyhop.set_verbose_level(0)
        gtpyhop.set_recursive_planning(True)


def initial_state(k: Knowledge, tool_poses: dict[str, Pose | None]) -> Any:
    """The planning state from a_km's knowledge: poses, where things are, what is held. A held
    object not seen since it was taken is where the hand, seen since, holds it
    (:func:`_held_by_hand`): its pose from before the grasp would put it where it no longer is
    (the clearance checks, services/agents/planner/clearance.py, would meet it there)."""
    s = gtpyhop.State("kitchen")
    s.k = k
    s.pose = {n: o.pose for n, o in k.objects.items()}
    s.localised = {n: o.localised for n, o in k.objects.items()}
    s.content = {n: o.particles for n, o in k.objects.items() if o.particles is not None}
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
    for n, (relation, furniture) in list(s.where.items()):
        if relation not in ("on", "in") or s.localised.get(n):
            continue  # held, or seen where it stands
        put = _where_put(s, n, furniture)
        if put is not None:
            s.pose[n] = put
    for arm in ARMS:
        held = s.holding[arm]
        if held is not None and not s.localised.get(held):  # not seen since it was taken:
            s.pose[held] = _held_by_hand(s, held, arm) or s.pose.get(held)  # where the hand is
        if held is not None and s.tool.get(arm) is None and s.pose.get(held) is not None and held in s.grip:
            s.tool[arm] = geo.compose(s.pose[held], s.grip[held])
    return s


TASKS: dict[str, tuple[int, str]] = {
    "pour": (2, "pour X into Y"),
    "place": (2, "put X on/in Y"),
    "bring": (1, "bring X to the table"),
    "hand_over": (1, "hand X over (put on the table in front of you)"),
    "return": (1, "put X back in the cabinet"),
    "fetch": (1, "take X in a hand"),
    "localise": (1, "look where X is"),
}
"""Goal tasks a_pl accepts: number of arguments and what they mean."""
STORAGE = "cabinet"
"""Where ``return`` puts things back."""


@dataclass
class PlanActions:
    """A plan as GTPyhop actions ``(name, path, *args)``; ``on_cancel[i]`` names the safe
    stop (a key of ``safe_stops``) to run when a cancel takes effect before action i."""

    actions: list[tuple[Any, ...]]
    on_cancel: list[str | None]
    safe_stops: dict[str, list[tuple[Any, ...]]]
    task: str = ""
    args: list[Any] = field(default_factory=list)
    """the domain task the goal became, and its arguments"""


def _goal(s: Any, name: str, args: list[str]) -> tuple[str, list[Any]]:
    """The domain task for a goal task, with its arguments; PlanningFailure if impossible."""
    k = _k(s)
    if name not in TASKS:
        known = "; ".join(v[1] for v in TASKS.values())
        raise PlanningFailure(f"I know no way to {name}; I can: {known}")
    if len(args) != TASKS[name][0]:
        raise PlanningFailure(f"{name} needs {TASKS[name][0]} object(s): {TASKS[name][1]}")
    for obj in args:
        if obj not in k.objects:
            raise PlanningFailure(f"I know of no {obj}")
    movable = lambda o: any(k.grasps.get((o, a)) for a in ARMS)  # noqa: E731
    if name in ("bring", "hand_over", "return", "fetch", "place") and not movable(args[0]):
        raise PlanningFailure(f"I cannot pick up the {args[0]}")
    if name == "pour":
        src, dst = args
        if k.pours.get((src, dst)) is None:
            raise PlanningFailure(f"I do not know how to pour the {src} into the {dst}")
        return "pour", args
    if name == "fetch":
        arm = _free_arm_for(s, args[0])
        if arm is None:
            raise PlanningFailure(f"no free hand can grasp the {args[0]}")
        return "fetch", [args[0], arm]
    if name == "localise":
        return "localise", args
    obj = args[0]
    furniture = {"place": args[-1], "return": STORAGE}.get(name, "table")
    if (obj, furniture) not in k.placements:
        raise PlanningFailure(f"I know no place to put the {obj} {_relation(s, furniture)} the {furniture}")
    if s.where.get(obj, ("", ""))[1] == furniture:
        raise PlanningFailure(f"the {obj} is already {_relation(s, furniture)} the {furniture}")
    return "move_to", [obj, furniture]


UNFINISHED_TAKE_SHARE = 0.8
"""A held object still within this share of its grasp's retreat distance of a place where it
stands in the furniture it was picked from has not been withdrawn (see ``finish_takes``)."""


def finish_takes(s: Any, root: str) -> list[tuple[Any, ...]]:
    """Actions that finish takes an earlier plan left half done, applied to ``s``.

    A take (lift, withdraw; paper §3.2: an atomic state) is interrupted when a_ta or ag_ex is
    lost inside it: the hand then holds the object where it stood, inside a cabinet, and a
    torso turn would drag it against the cabinet. A held object picked from a container whose
    position (a_km's last observation, made since the grasp: a_km unlocalises a pose when the
    object is taken, and the pose before the grasp is where the object stood, not where the
    hand is) is within ``UNFINISHED_TAKE_SHARE`` × the grasp's
    retreat distance of one of its places in that container (where it is not seen, the hand
    hides it: where the hand's grip frame, observed since, holds it) is lifted to the grasp's lift
    height above that place, then withdrawn along the retreat to the retreat distance from the
    place: the same poses ``m_fetch`` ends at. Each becomes an atomic ``take`` state under
    ``{root}/finish_take_{obj}``. Returns [] when every take was finished."""
    out: list[tuple[Any, ...]] = []
    for arm in ARMS:
        obj = s.holding[arm]
        furniture = s.picked_from.get(obj) if obj is not None else None
        if obj is None or furniture is None or _relation(s, furniture) != "in":
            continue
        pose, grasp = s.pose.get(obj), _best_grasp(s, obj, arm)
        placement = _k(s).placements.get((obj, furniture))
        if pose is None or grasp is None or placement is None or not placement.positions:
            continue
        if not s.localised.get(obj) and _held_by_hand(s, obj, arm) is None:
            continue  # not seen since it was taken, nor the hand since (initial_state)
        x, y, z = pose.position
        place = min(placement.positions, key=lambda p: math.hypot(p[0] - x, p[1] - y))
        if math.hypot(place[0] - x, place[1] - y) >= UNFINISHED_TAKE_SHARE * grasp.retreat_distance:
            continue
        facing = _place_facing(s, obj, furniture, place)
        frame = _rot_z((facing if facing is not None else GRASP_FACING) - GRASP_FACING)
        retreat = geo.rotate(grasp.retreat, frame)
        # the hand keeps the grasp's orientation (containers are symmetric about z: their yaw
        # is not observed reliably); height: at least the lift above the place
        height = max(z, place[2] + grasp.lift)
        lifted = geo.compose(Pose((x, y, height), frame.orientation), _grasp_pose(grasp))
        done = (x - place[0]) * retreat[0] + (y - place[1]) * retreat[1]
        withdrawn = geo.translated(lifted, _scaled(retreat, max(0.0, grasp.retreat_distance - done)))
        take = f"{root}/finish_take_{obj}/take"
        moves: list[tuple[Any, ...]] = [
            ("a_move", f"{take}/lift", arm, lifted, 1.0),
            ("a_move", f"{take}/withdraw", arm, withdrawn, SHORT_MOVE_S),
        ]
        for name, path, *args in moves:
            ACTIONS[name](s, path, *args)
        out += moves
    return out


def _held_by_hand(s: Any, obj: str, arm: str) -> Pose | None:
    """Where ``arm``'s hand holds ``obj`` (world pose of the object frame): its grip frame's
    pose, observed no earlier than the object's pose (a_km's ``{arm}_gripper``), with the
    grasp's grip undone; None when there is no such observation."""
    hand, held = _k(s).objects.get(f"{arm}_gripper"), _k(s).objects.get(obj)
    if hand is None or hand.pose is None or hand.pose_stamp is None or obj not in s.grip:
        return None
    if held is not None and held.pose_stamp is not None and hand.pose_stamp < held.pose_stamp:
        return None
    return geo.compose(hand.pose, geo.inverse(s.grip[obj]))


def _run(s: Any, task: list[Any]) -> list[tuple[Any, ...]] | None:
    with contextlib.redirect_stdout(io.StringIO()):
        plan = gtpyhop.find_plan(s, [tuple(task)])
    return None if plan is None or plan is False else list(plan)


def safe_stops(s0: Any, actions: list[tuple[Any, ...]]) -> tuple[list[str | None], dict[str, list[Any]]]:
    """For every action boundary, the safe stop for what the hands hold there (None: empty
    hands); the same holding and torso angle share one safe stop. Replays ``actions`` from
    state ``s0`` (not modified)."""
    s = s0.copy()
    keys: list[str | None] = []
    stops: dict[str, list[Any]] = {}
    seen: dict[tuple[Any, ...], str] = {}
    for name, path, *args in actions:
        held = tuple(sorted((a, o) for a, o in s.holding.items() if o is not None))
        key: str | None = None
        if held:
            signature = (held, None if s.torso is None else round(s.torso, 6))
            key = seen.get(signature)
            if key is None:
                key = f"safe_stop_{len(seen) + 1}"
                found = _run(s.copy(), ["safe_stop", key])
                if found is not None:
                    seen[signature] = key
                    stops[key] = found
                else:
                    key = None  # nowhere to put it down: a cancel then stops in place
        keys.append(key)
        ACTIONS[name](s, path, *args)
    return keys, stops


def find_plan(k: Knowledge, task: tuple[str, ...], root: str) -> list[tuple[Any, ...]]:
    """A list of action tuples ``(name, path, *args)`` achieving ``task`` (see ``TASKS``).
    Raises PlanningFailure with a readable reason when there is none."""
    return plan_task(k, task, root, with_safe_stops=False).actions


def plan_task(k: Knowledge, task: tuple[str, ...], root: str, *, with_safe_stops: bool = True) -> PlanActions:
    """The plan for goal ``task`` from a_km's knowledge ``k``, with the safe stop of every
    step. Raises PlanningFailure with a reason a person can read."""
    declare()
    s0 = initial_state(k, {})
    name, *args = task
    domain_task, domain_args = _goal(s0, name, list(args))
    s = s0.copy()
    first = finish_takes(s, root)
    found = _run(s, [domain_task, root, *domain_args])
    if found is None:
        raise PlanningFailure(f"no way to {name} {' '.join(map(str, args))} from what I know")
    actions = [*first, *found]
    if not actions:
        raise PlanningFailure(f"no way to {name} {' '.join(map(str, args))} from what I know")
    if not with_safe_stops:
        return PlanActions(actions, [None] * len(actions), {}, domain_task, domain_args)
    keys, stops = safe_stops(s0, actions)
    return PlanActions(actions, keys, stops, domain_task, domain_args)
