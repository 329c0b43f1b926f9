"""Scripted kitchen tasks around the pour (paper §3.2, safe interruption): Velma holds the jar
(left hand) after putting the bowl on the table when a person asks for the cup. She sets the
jar down upright on the table, fetches the cup from the cabinet and puts it on the table,
grasps the jar again and pours; and she can put the bowl (and the jar) back in the cabinet.

The commands are computed from observed object positions by the same rules as the planner
(services/agents/planner/domain.py ``m_fetch`` / ``m_place``), so the constants below are what the
kitchen knowledge (services/agents/knowledge/kitchen.ttl) must say for the planner to produce the
same motions:

- a grasp affordance (``Grasp``) gives the grip pose in the object frame (bottom centre, world
  axes) for the object standing where Velma works at torso angle 0 (the cabinet). For an
  object standing elsewhere, worked on at torso angle ``facing``, the grip pose, approach,
  entry and retreat directions are turned about z by ``facing`` and the torso turns to
  ``facing`` first (:func:`fetch_commands`);
- a placement (``Placement``) puts the object frame at a position plus ``clearance`` with
  the yaw the held object turned through (``facing`` − the facing it was grasped at),
  coming down from ``approach`` above; the hand opens to the grasp's preshape, rises by
  ``approach`` and moves to ``park`` (an offset in the frame turned by ``facing``)
  (:func:`place_commands`).

Conventions as velma/scenario.py: grip frame ``{side}_HandGripLink``; quaternions (w, x, y,
z); metres, radians, seconds; "turned frame": world axes turned about z by the torso angle
(x forward, y the robot's left).

Each placement's and grasp's geometry was found by simulation (IK scans of velma.control.ik
with collision checks, then runs on the executor; scripts/bench_kitchen_tasks.py repeats the
runs over seeds); why each value is what it is, is said at its constant. The grip of a held
object in the object frame is the affordance's turned by the facing at which it was grasped
(:func:`place_poses`); the world grip at a placement is then the affordance's turned by the
placement's facing.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from shared.fipa_codec.languages.common import Pose, Quat, Vec3
from shared.fipa_codec.languages.l_ex import (
    TORSO_JOINT,
    Arm,
    CommandResult,
    ExecutorCommand,
    Grasp,
    LookAt,
    MoveJoints,
    MoveTool,
    Observe,
    Release,
)
from shared.fipa_codec.languages.l_sd import Observation
from velma import scenario as sc
from velma.rotations import quat_to_rot
from velma.scenario import Array, run_script

# ----------------------------------------------------------------- planner durations
LONG_MOVE = 3.0
"""A move between work places or a torso turn of more than 0.5 rad (s; planner LONG_MOVE_S)."""
SHORT_MOVE = 1.5
"""A move out of or along a shelf, down to a placement, or a short turn (s; SHORT_MOVE_S)."""
CONTACT_SPEED = 0.133
"""Speed of the final approach to a grasp (m/s, planner CONTACT_SPEED_M_S); at least 1 s."""
CLEAR_DURATION = 1.0
"""Rising from a released object (s)."""
LIFT_DURATION = 1.0

# ----------------------------------------------------------------- facings (torso angles)
CABINET_FACING = sc.TORSO_PICK
"""Torso angle at the cabinet (rad): the grasp affordances are given for it."""
TABLE_FACING = sc.TORSO_PLACE
"""Torso angle at the table (rad): bowl and cup (right hand, palm down)."""
JAR_TABLE_FACING = -1.5
"""Torso angle for the jar on the table (rad; left hand, side grasp); 0.07 rad inside the
torso's limit. At the table's facing −0.95 no free table spot works: the left arm reaches the
palm-forward orientation at table height only left of the torso's centre line (turned
y ≥ 0.05 m), and the wrist (flange 0.08 m below and 0.24 m behind the grip frame, 0.05 m thick)
must hang beyond a table edge or it hits the table top; the spots that satisfy both (by the
edge nearest the cabinet, x ≈ 0.5 m) put the bowl in the way of the open fingers on the
horizontal approach."""


@dataclass(frozen=True)
class GraspSpec:
    """A grasp affordance (object frame = bottom centre, world axes, at facing 0).

    ``grip``: grip pose in the object frame (position m, quaternion w, x, y, z); the hand
    opens to ``preshape`` (rad), comes to a pre-grasp ``approach_distance`` (m) back along
    ``approach`` (unit), optionally from an entry point ``entry_distance`` back along
    ``entry`` from there; closes with ``spread`` (rad); lifts ``lift`` (m, world z) and
    withdraws ``retreat_distance`` along ``retreat``. A non-empty ``posture`` (the arm's
    seven joint angles, rad) is taken first, by a joint move."""

    arm: Arm
    grip: tuple[Vec3, Quat]
    approach: Vec3
    approach_distance: float
    spread: float = 0.0
    preshape: float = sc.PREGRASP_OPENING
    entry: Vec3 | None = None
    entry_distance: float = 0.0
    lift: float = 0.04
    retreat: Vec3 = (-1.0, 0.0, 0.0)
    retreat_distance: float = 0.25
    posture: tuple[float, ...] = field(default=())


@dataclass(frozen=True)
class Placement:
    """Where an object goes on a surface: its frame at ``position`` (world, m) plus
    ``clearance`` (m) above, worked on at torso angle ``facing`` (rad); the object comes down
    from ``approach`` (m) above; the hand parks at ``park`` (m, turned frame) from the release
    pose."""

    position: Vec3
    facing: float
    clearance: float = sc.PLACE_CLEARANCE
    approach: float = sc.PLACE_APPROACH
    park: Vec3 = (0.0, 0.0, 0.1)


# ----------------------------------------------------------------- grasp affordances
JAR_SIDE_GRASP = GraspSpec(
    arm=sc.JAR_ARM,
    grip=sc.JAR_GRIP_IN_OBJECT,
    approach=sc.JAR_APPROACH_IN_OBJECT,
    approach_distance=sc.JAR_APPROACH_DISTANCE,
    spread=sc.JAR_SPREAD,
    lift=sc.JAR_LIFT,
    retreat_distance=sc.JAR_RETREAT,
    posture=sc.LEFT_PICK_POSTURE,
)
"""The jar's side grasp (velma/scenario.py, kitchen.ttl ``jar_side_grasp_left``), in the
cabinet."""

JAR_TABLE_GRASP = GraspSpec(
    arm=sc.JAR_ARM,
    grip=sc.JAR_GRIP_IN_OBJECT,
    approach=(0.0, 0.0, -1.0),
    approach_distance=0.12,
    spread=sc.JAR_SPREAD,
    lift=sc.JAR_LIFT,
    retreat=(0.0, 0.0, 1.0),
    retreat_distance=0.10,
)
"""The jar on the table (kitchen.ttl ``jar_side_grasp_left_from_above``): the side grip,
reached from 0.12 m above — the way the open hand left the jar when it put it down — and lifted
straight up. On the table the side grasp's horizontal approach and withdraw, along the torso's
forward direction, bring the left forearm into the torso (the robot's links collide
with each other; found with the executor's IK and its self-collision check)."""

BOWL_RIM_GRASP = GraspSpec(
    arm=sc.BOWL_ARM,
    grip=sc.BOWL_GRIP_IN_OBJECT,
    approach=sc.BOWL_APPROACH_IN_OBJECT,
    approach_distance=sc.BOWL_APPROACH_DISTANCE,
    spread=sc.BOWL_SPREAD,
    entry=(1.0, 0.0, 0.0),
    entry_distance=sc.BOWL_ENTRY_DISTANCE,
    lift=sc.BOWL_LIFT,
    retreat_distance=sc.BOWL_RETREAT,
    posture=sc.RIGHT_PICK_POSTURE,
)
"""The bowl's rim grasp (velma/scenario.py, kitchen.ttl ``bowl_rim_grasp_right``)."""

BOWL_TABLE_GRASP = replace(BOWL_RIM_GRASP, retreat=(-0.6, -0.8, 0.0))
"""The rim grasp for the bowl on the table (the tidy-up): BOWL_RIM_GRASP withdrawing back and
to the robot's right (turned frame) instead of straight back. Straight back, the withdraw bends
the right wrist until ``right_arm_5_link`` and ``right_arm_7_link`` all but touch (the least
MuJoCo geom distance over the move 0.6 µm with seed 0; 0.10–0.25 mm over runs whose command
start times varied; a self contact in some runs in CI); this way their least distance over
the whole tidy-up is 5.0 mm, as in the pick posture. Measured with ``mj_geomDistance`` every
5th cycle of ``run_tidy_up`` on the threaded executor (seed 0, no idle steps). The planner
has it from kitchen.ttl (``bowl_rim_grasp_right_on_table``): the L_EX requests of a fleet's
``roco scenario tidy_up``, run again on the in-process executor and measured every cycle, came
within 0.02 mm with the straight withdraw and 5.00 mm with this one."""

CUP_TOP_GRASP = GraspSpec(
    arm=Arm.RIGHT,
    grip=((0.0, 0.0, 0.065), (0.0, 0.0, 1.0, 0.0)),
    approach=(0.0, 0.0, -1.0),
    approach_distance=0.04,
    spread=0.0,
    entry=(1.0, 0.0, 0.0),
    entry_distance=0.25,
    lift=0.04,
    retreat_distance=0.25,
    posture=sc.RIGHT_PICK_POSTURE,
)
"""The cup, right hand: top grasp, palm down (grip axes x = (−1, 0, 0), y = (0, 1, 0),
z = (0, 0, −1)), fingers One/Two on the +y side and Three on the −y side of the cup; the grip
frame 0.065 m above the cup bottom (the palm pad 1.3 cm above the rim), so the fingers close
round the upper wall and their tips end at the shelf. Like the bowl, the arm first takes
RIGHT_PICK_POSTURE and the hand enters the cabinet horizontally. The low grip, the short
approach (0.04 m) and lift (0.04 m) keep the forearm ≥ 14 mm below the cabinet's top board:
reaching palm down into the middle of the cabinet raises it (the bowl's grasp passes it by
2 mm)."""


# ----------------------------------------------------------------- placements
JAR_TABLE = Placement(
    position=(0.11, -0.46, 0.75), facing=JAR_TABLE_FACING, approach=0.12, park=(-0.05, 0.20, 0.13)
)
"""The jar on the table: in the table's corner nearest the robot, 0.22 m from the bowl (to its
right, seen from the robot at the table), its wall 6.5 cm from the table's edges at x = 0
and y = −0.35; the wrist hangs beyond the y = −0.35 edge (the edge nearest the cabinet). The
jar comes down from 0.12 m above, so that the open hand, back there after the release, clears
the jar's rim when it parks. The left hand parks up and to the robot's left (turned frame),
clear of the torso: straight back, its forearm would meet the torso; and the hand
must stay out of the right arm's way at the cabinet once the torso turns there."""
CUP_TABLE = Placement(position=(0.25, -0.70, 0.75), facing=TABLE_FACING, park=(-0.25, 0.0, 0.20))
"""The cup on the table, right of the bowl and beyond it (seen from the robot), 0.25 m from
the bowl and 0.28 m from the jar's table spot, ≥ 0.21 m from the table's edges. The hand
parks back towards the body (not sideways like after the bowl): turning to the cabinet
would otherwise carry it into the cabinet's side panel."""
BOWL_CABINET = Placement(
    position=(0.70, -0.20, 0.85), facing=CABINET_FACING, approach=0.04, park=(-0.30, 0.0, 0.0)
)
"""The bowl back in the cabinet, where it started. It comes down from only 0.04 m above: the
palm-down right arm's forearm rises towards the cabinet's top board as the hand rises (at
0.08 m it meets it; at 0.04 m it passes 13 mm below). The hand withdraws horizontally (its
open fingers pass beside the rim)."""
JAR_CABINET = Placement(position=(0.70, 0.20, 0.85), facing=CABINET_FACING, park=(-0.30, 0.15, 0.0))
"""The jar back in the cabinet, where it started; the hand withdraws horizontally and to the
robot's left: straight back, its fingers meet the right hand's when the torso turns to the
table and the right hand enters towards the bowl."""


# ----------------------------------------------------------------- helpers
def _v(p: Array) -> Vec3:
    return (float(p[0]), float(p[1]), float(p[2]))


def _turn_duration(current: float | None, target: float) -> float:
    return LONG_MOVE if current is None or abs(current - target) > 0.5 else SHORT_MOVE


def face(current: float | None, target: float) -> list[ExecutorCommand]:
    """Turn the torso to ``target`` (rad) unless it is there already (``current``, rad; None:
    unknown)."""
    if current is not None and abs(current - target) < 1e-9:
        return []
    return [MoveJoints(positions={TORSO_JOINT: target}, duration=_turn_duration(current, target))]


def arm_joint_names(arm: Arm) -> list[str]:
    """The seven joint names of ``arm``."""
    return [f"{arm.value}_arm_{k}_joint" for k in range(7)]


def grasp_poses(grasp: GraspSpec, position: Vec3, facing: float) -> dict[str, Pose]:
    """World grip poses of ``grasp`` for the object at ``position`` (world, m) worked on at
    torso angle ``facing`` (rad): ``entry`` (if any), ``pregrasp``, ``grasp``, ``lift``,
    ``withdraw``."""
    turn = sc._rot_z(facing)
    rot = turn @ quat_to_rot(grasp.grip[1])
    grip = np.asarray(position, dtype=float) + turn @ np.asarray(grasp.grip[0], dtype=float)
    approach = turn @ np.asarray(grasp.approach, dtype=float)
    pre = grip - grasp.approach_distance * approach
    lifted = grip + np.array([0.0, 0.0, grasp.lift])
    out = lifted + grasp.retreat_distance * (turn @ np.asarray(grasp.retreat, dtype=float))
    poses = {
        "pregrasp": sc._pose(pre, rot),
        "grasp": sc._pose(grip, rot),
        "lift": sc._pose(lifted, rot),
        "withdraw": sc._pose(out, rot),
    }
    if grasp.entry is not None and grasp.entry_distance > 0:
        entry = pre - grasp.entry_distance * (turn @ np.asarray(grasp.entry, dtype=float))
        poses["entry"] = sc._pose(entry, rot)
    return poses


def fetch_commands(
    grasp: GraspSpec,
    position: Vec3,
    facing: float,
    torso: float | None,
    look: Vec3 | None = None,
) -> list[ExecutorCommand]:
    """Take the object at ``position`` (world, m) with ``grasp``, working at torso angle
    ``facing`` (rad; the torso is at ``torso`` now): look at ``look`` (if given), face,
    (posture,) open the hand, (enter,) approach, grasp, lift, withdraw (planner ``m_fetch``).
    The posture and the entry are taken only at the grasp's own facing (the cabinet's), as the
    planner does; elsewhere the arm is already in the grasp's branch (it parked there) and
    goes straight to the pre-grasp pose: the bowl is taken from the table either way."""
    p = grasp_poses(grasp, position, facing)
    arm = grasp.arm
    cmds: list[ExecutorCommand] = [LookAt(point=look)] if look is not None else []
    cmds += face(torso, facing)
    if grasp.posture and abs(facing - CABINET_FACING) < 1e-9:
        names = arm_joint_names(arm)
        cmds.append(MoveJoints(positions=dict(zip(names, grasp.posture, strict=True)), duration=SHORT_MOVE))
    cmds.append(Release(arm=arm, opening=grasp.preshape))
    first = SHORT_MOVE if grasp.posture else LONG_MOVE
    if "entry" in p and abs(facing - CABINET_FACING) < 1e-9:
        cmds += [
            MoveTool(arm=arm, target=p["entry"], duration=first),
            MoveTool(arm=arm, target=p["pregrasp"], duration=SHORT_MOVE),
        ]
    else:
        cmds.append(MoveTool(arm=arm, target=p["pregrasp"], duration=first))
    reach = round(max(1.0, grasp.approach_distance / CONTACT_SPEED), 2)
    return [
        *cmds,
        MoveTool(arm=arm, target=p["grasp"], duration=reach),
        Grasp(arm=arm, spread=grasp.spread),
        MoveTool(arm=arm, target=p["lift"], duration=LIFT_DURATION),
        MoveTool(arm=arm, target=p["withdraw"], duration=SHORT_MOVE),
    ]


def place_poses(grasp: GraspSpec, place: Placement, grasp_facing: float) -> dict[str, Pose]:
    """World grip poses for putting an object held with ``grasp`` (taken at torso angle
    ``grasp_facing``, rad) at ``place``: ``above``, ``release``, ``park``.

    The object turned with the torso from ``grasp_facing`` to ``place.facing``: it stands at
    yaw ``place.facing − grasp_facing``, and the grip in its frame is the one it was grasped
    with, the affordance's turned by ``grasp_facing``; so the world grip is the affordance's
    turned by ``place.facing``."""
    turn = sc._rot_z(place.facing)
    yaw = sc._rot_z(place.facing - grasp_facing)
    held = sc._rot_z(grasp_facing)  # the grip in the object frame as grasped
    rot = yaw @ held @ quat_to_rot(grasp.grip[1])
    target = np.asarray(place.position, dtype=float) + np.array([0.0, 0.0, place.clearance])
    grip = target + yaw @ held @ np.asarray(grasp.grip[0], dtype=float)
    above = grip + np.array([0.0, 0.0, place.approach])
    park = grip + turn @ np.asarray(place.park, dtype=float)
    return {"above": sc._pose(above, rot), "release": sc._pose(grip, rot), "park": sc._pose(park, rot)}


def place_commands(
    grasp: GraspSpec, place: Placement, grasp_facing: float, torso: float | None
) -> list[ExecutorCommand]:
    """Put the object held with ``grasp`` (taken at torso angle ``grasp_facing``) at
    ``place`` (the torso is at ``torso`` now): face, look, carry above, lower, release, clear,
    park (planner ``m_place``)."""
    p = place_poses(grasp, place, grasp_facing)
    arm = grasp.arm
    return [
        *face(torso, place.facing),
        LookAt(point=place.position),
        MoveTool(arm=arm, target=p["above"], duration=LONG_MOVE),
        MoveTool(arm=arm, target=p["release"], duration=SHORT_MOVE),
        Release(arm=arm, opening=grasp.preshape),
        MoveTool(arm=arm, target=p["above"], duration=CLEAR_DURATION),
        MoveTool(arm=arm, target=p["park"], duration=SHORT_MOVE),
    ]


def position_of(obs: Observation, name: str) -> Vec3:
    """Observed position of ``name`` (world, m). Raises KeyError if it was not observed."""
    return _v(sc._position(obs, name))


def particles_in(obs: Observation, name: str) -> int:
    """Content spheres observed inside ``name`` (0 if not a container)."""
    for o in obs.objects:
        if o.name == name:
            return o.particles_inside or 0
    raise KeyError(f"{name} not in the observation")


Submit = Callable[[ExecutorCommand, Callable[[CommandResult | Observation], None]], None]


def _ok(results: list[CommandResult | Observation], n: int) -> bool:
    return len(results) == n and all(not isinstance(r, CommandResult) or r.ok for r in results)


# ----------------------------------------------------------------- the task sequences
def set_jar_down(torso: float = TABLE_FACING) -> list[ExecutorCommand]:
    """Put the jar held in the left hand (side grasp, taken in the cabinet) upright on the
    table at JAR_TABLE and observe (the torso is at ``torso``, rad)."""
    return [*place_commands(JAR_SIDE_GRASP, JAR_TABLE, CABINET_FACING, torso), Observe()]


def cup_to_table(obs: Observation, torso: float = JAR_TABLE_FACING) -> list[ExecutorCommand]:
    """Take the cup from the cabinet (right hand, top grasp) at its observed position, put it
    on the table at CUP_TABLE and observe (the torso is at ``torso``, rad)."""
    fetch = fetch_commands(
        CUP_TOP_GRASP, position_of(obs, "cup"), CABINET_FACING, torso, look=sc.HEAD_LOOK_CABINET
    )
    return [*fetch, *place_commands(CUP_TOP_GRASP, CUP_TABLE, CABINET_FACING, CABINET_FACING), Observe()]


def regrasp_jar_and_pour(obs: Observation, torso: float = TABLE_FACING) -> list[ExecutorCommand]:
    """Grasp the jar again where it was observed on the table (left hand, JAR_TABLE_GRASP
    turned by JAR_TABLE_FACING), lift it, and pour it into the bowl where the
    bowl was observed (velma/scenario.py ``pour_commands``; ends with an observation)."""
    fetch = fetch_commands(JAR_TABLE_GRASP, position_of(obs, "jar"), JAR_TABLE_FACING, torso)
    return [*fetch, *sc.pour_commands(position_of(obs, "bowl"))]


def jar_to_cabinet(grasp_facing: float, torso: float) -> list[ExecutorCommand]:
    """Put the jar held in the left hand (grasped at torso angle ``grasp_facing``) back in the
    cabinet at JAR_CABINET and observe (the torso is at ``torso``, rad)."""
    return [*place_commands(JAR_SIDE_GRASP, JAR_CABINET, grasp_facing, torso), Observe()]


def bowl_to_cabinet(obs: Observation, torso: float) -> list[ExecutorCommand]:
    """Take the bowl from the table where it was observed (right hand, BOWL_TABLE_GRASP turned
    by TABLE_FACING), put it back in the cabinet at BOWL_CABINET and observe."""
    fetch = fetch_commands(BOWL_TABLE_GRASP, position_of(obs, "bowl"), TABLE_FACING, torso)
    return [*fetch, *place_commands(BOWL_TABLE_GRASP, BOWL_CABINET, TABLE_FACING, TABLE_FACING), Observe()]


Stage = Callable[[Observation], list[ExecutorCommand]]
"""Commands computed from the latest observation; a stage ends with an Observe."""


def run_stages(
    submit: Submit, stages: list[Stage], *, timeout: float = 600.0
) -> tuple[list[ExecutorCommand], list[CommandResult | Observation]]:
    """Observe, then run each stage on the latest observation (as the agents interleave
    planning and execution). Stops at the first failed command; returns the commands sent
    and their results (shorter than the commands when one failed). Raises ``TimeoutError``
    as ``velma.scenario.run_script``; ``RuntimeError`` if the first observation fails."""
    first = run_script(submit, [Observe()], timeout=timeout)[0]
    if not isinstance(first, Observation):
        raise RuntimeError(f"the first observation failed: {first}")
    commands: list[ExecutorCommand] = [Observe()]
    results: list[CommandResult | Observation] = [first]
    latest = first
    for stage in stages:
        todo = stage(latest)
        done = run_script(submit, todo, timeout=timeout)
        commands += todo[: len(done)]
        results += done
        if not _ok(done, len(todo)):
            break
        last = done[-1]
        if isinstance(last, Observation):
            latest = last
    return commands, results


def _first_part(obs: Observation) -> list[ExecutorCommand]:
    """pour_script up to and including the observation of the placed bowl."""
    commands = sc.pour_script(obs)
    split = next(i for i, c in enumerate(commands) if isinstance(c, Observe) and c.objects) + 1
    # observe everything (the cup too): the next stage plans from it
    return [*commands[: split - 1], Observe()]


def run_interrupted_pour(
    submit: Submit, *, timeout: float = 600.0
) -> tuple[list[ExecutorCommand], list[CommandResult | Observation]]:
    """The pour interrupted by "bring the cup to the table" (paper §3.2): take the jar and the
    bowl out, put the bowl on the table; then set the jar down on the table, take the cup to
    the table, grasp the jar again and pour it into the bowl. Returns as :func:`run_stages`;
    the last result is the final observation."""
    return run_stages(
        submit,
        [
            _first_part,
            lambda obs: set_jar_down(sc.TORSO_PLACE),
            lambda obs: cup_to_table(obs, JAR_TABLE_FACING),
            lambda obs: regrasp_jar_and_pour(obs, TABLE_FACING),
        ],
        timeout=timeout,
    )


def run_tidy_up(
    submit: Submit, *, timeout: float = 600.0
) -> tuple[list[ExecutorCommand], list[CommandResult | Observation]]:
    """Take the jar and the bowl out and put the bowl on the table (the pour's first part),
    then "put the bowl back in the cabinet": the jar back first (it is in the left hand, in
    the right hand's way), then the bowl. Returns as :func:`run_stages`."""
    return run_stages(
        submit,
        [
            _first_part,
            lambda obs: jar_to_cabinet(CABINET_FACING, sc.TORSO_PLACE),
            lambda obs: bowl_to_cabinet(obs, CABINET_FACING),
        ],
        timeout=timeout,
    )
