"""The scripted command sequence of the kitchen experiment (paper §5.3): Velma takes a jar
(left hand) and a bowl (right hand) out of the open cabinet, puts the bowl on the table and
pours the jar's content into it.

``pour_script(observation)`` computes the L_EX commands from the objects' observed poses
(jar, bowl: their positions; orientations are taken as upright, as both are rotationally
symmetric containers standing on a shelf) and the named geometric constants below. A planner
that knows these constants computes the same sequence.

Conventions: a grip pose is the pose of ``{side}_HandGripLink`` (palm + 0.12 m along the
palm normal; the palm normal is the grip frame's z axis, the approach direction). Poses
"in the object frame" are relative to the object's frame (bottom centre, z up) with the
world's axes (objects are rotationally symmetric, so their yaw is ignored). Quaternions are
(w, x, y, z). Lengths in metres, angles in radians, durations in seconds.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

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
    Tilt,
    Wait,
)
from shared.fipa_codec.languages.l_sd import Observation
from velma.rotations import quat_to_rot, quat_wxyz

Array = npt.NDArray[np.float64]

# ----------------------------------------------------------------- geometric constants
# Jar (left hand): side grasp, palm facing +x (into the cabinet), palm x axis up, so the
# fingers close horizontally round the jar; grip frame on the jar's axis at mid height.
JAR_ARM = Arm.LEFT
JAR_GRIP_IN_OBJECT: tuple[Vec3, Quat] = ((0.0, 0.0, 0.06), (0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)))
"""Grip pose in the jar frame: grip axes x = (0, 0, 1), y = (0, −1, 0), z = (1, 0, 0)."""
JAR_APPROACH_IN_OBJECT: Vec3 = (1.0, 0.0, 0.0)
"""Direction the hand moves in while approaching the grasp (unit, jar frame)."""
JAR_APPROACH_DISTANCE = 0.20
JAR_SPREAD = 0.0
JAR_LOAD = 0.3
"""kg, the jar with its content as a_km states it (kitchen.ttl ``roco:mass``): the grasp's payload prior."""
JAR_LIFT = 0.04
"""Lift after grasping (world z), before pulling out along −approach."""
JAR_RETREAT = 0.25

# Bowl (right hand): top grasp, palm facing down, fingers One/Two on the +y side and Three
# on the −y side of the rim; the grip frame is 0.045 m above the bowl bottom.
BOWL_ARM = Arm.RIGHT
BOWL_GRIP_IN_OBJECT: tuple[Vec3, Quat] = ((0.0, 0.0, 0.045), (0.0, 0.0, 1.0, 0.0))
"""Grip pose in the bowl frame: grip axes x = (−1, 0, 0), y = (0, 1, 0), z = (0, 0, −1)."""
BOWL_APPROACH_IN_OBJECT: Vec3 = (0.0, 0.0, -1.0)
BOWL_APPROACH_DISTANCE = 0.06
BOWL_ENTRY_DISTANCE = 0.25
"""The hand enters the cabinet horizontally (along +x) at approach height from this far."""
BOWL_SPREAD = 0.0
BOWL_LOAD = 0.2
"""kg, the bowl as a_km states it (kitchen.ttl ``roco:mass``)."""
BOWL_LIFT = 0.05
BOWL_RETREAT = 0.25

PREGRASP_OPENING = 0.5
"""Proximal finger angle before a grasp (rad; 0 = flat open)."""
RELEASE_OPENING = 0.5

TORSO_PICK = 0.0
"""Torso angle while picking from the cabinet."""
TORSO_PLACE = -0.95
"""Torso angle while placing the bowl (facing the place position)."""
TORSO_POUR = -1.2
"""Torso angle while pouring."""

BOWL_PLACE_POSITION: Vec3 = (0.31, -0.42, 0.75)
"""Where the bowl frame goes on the table (world; table top at 0.75 m; a_km's
``roco:table_bowl_place``, services/agents/knowledge/kitchen.ttl). Near enough to the head
that, from the pour's head pose, the camera sees every sphere along the bowl's near wall
(tests/velma/perception/test_content_count.py); its rim stays 4 mm inside the table's edge,
and the jar set down at its table place beside it (velma/scenario_kitchen.py ``JAR_TABLE``)
leaves it standing where it is (tests/velma/test_velma_kitchen.py)."""
PLACE_CLEARANCE = 0.005
"""The bowl is released this far above the table (it drops onto it)."""
PLACE_APPROACH = 0.08

JAR_POUR_START_IN_BOWL: Vec3 = (0.0, -0.07, 0.08)
"""The jar frame (upright) at the start of the pour, relative to the bowl frame, in the frame
turned by TORSO_POUR about z (x: the torso's forward direction, y: the robot's left): beside
the bowl on the robot's right, its bottom 2 cm above the rim."""
POUR_APPROACH_HEIGHT = 0.08
"""The jar comes down onto its pour-start pose from this far above it."""
POUR_PIVOT_IN_BOWL: Vec3 = (0.0, -0.06, 0.14)
"""The tilt pivot relative to the bowl frame (same turned frame). Rotating about it swings the
jar over the rim and brings its lip to ≈ (−0.02, 0.08–0.12) above the bowl while the content
flows (chosen by a 2-D sweep so that jar and fingers clear the bowl throughout)."""
POUR_AXIS_IN_TORSO: Vec3 = (1.0, 0.0, 0.0)
"""Tilt axis (torso_link0 frame at TORSO_POUR): the hand's approach axis."""
POUR_ANGLE = -2.3
"""Negative about POUR_AXIS_IN_TORSO: the jar's mouth tips to the robot's left."""
POUR_DURATION = 4.0
POUR_WAIT = 2.5
UNTILT_DURATION = 3.0
POUR_CLEAR_VIEW: Vec3 = (0.15, 0.14, 0.14)
"""After the pour the upright jar moves this far (m, the turned frame of JAR_POUR_START_IN_BOWL)
from its pour-start pose, forward, up and to the robot's left, so that the head camera sees the
whole bowl for the content check: beside the bowl the jar and the hand hide half of its floor
(found by rendering the head's view from candidate poses the IK reaches). Forward keeps the
left elbow (left_arm_3_joint) 0.33 rad inside its limit at the IK's solution for the bowl at
BOWL_PLACE_POSITION, outside the controller's joint-limit band (velma/control/limits.py
``LIMIT_BAND``), which otherwise holds the jar over 1 cm short of the pose. Its height lies in
a corridor (tests/velma/test_payload.py): 1 cm higher, the left forearm (left_arm_3_link,
left_arm_4_link) comes down on the cabinet's top board (at (0.12, 0.15, 0.15) it held the jar
5–15 mm short: the clear-view time-outs of ``roco chaos``); 2 cm lower, the torso's turn back
to the cabinet sweeps the hand and the jar through the cup on its shelf."""

RIGHT_PICK_POSTURE: tuple[float, ...] = (1.46, -0.98, -0.15, 1.82, -0.2, 1.26, 2.29)
"""right_arm_0..6_joint (rad) before the bowl approach: the IK solution of the bowl entry
pose (torso 0) from which the right arm's whole path (entry, grasp, lift, retreat, turn,
place) stays continuous and ≥ 0.2 rad inside the joint limits (found offline with
velma.control.ik). It is also the right arm's home posture (velma/model/scene.py): the
palm-down branch cannot be reached by a Cartesian motion from a posture near the body
(joint 3 meets its limit), so the arm starts in it."""
LEFT_PICK_POSTURE: tuple[float, ...] = (-0.1, 1.48, -0.61, -1.7, 2.7, 1.25, -0.94)
"""left_arm_0..6_joint (rad) before the jar approach: the executor's IK solution of the jar
pre-grasp pose (torso 0, the jar where the scene puts it). From it the left arm's whole fetch
(pre-grasp, grasp, lift, withdraw) stays in one branch, its wrist clear of its own forearm
(≥ WRIST_BAND, velma/control/self_collision.py) for jar poses ±2 cm and ±0.2 rad about the
default (scripts/bench_pour_seeds.py). A Cartesian motion from home instead ends the
pre-grasp with joint 1 at its limit (2.09 rad) and the wrist 11 mm from the forearm, and for
some jar poses the withdraw then cannot finish."""
RIGHT_PARK_OFFSET: Vec3 = (-0.05, -0.20, 0.20)
"""Where the right grip frame waits after placing the bowl, relative to its place pose, in
the frame turned by TORSO_PLACE (x forward, y the robot's left, z up)."""

HEAD_LOOK_CABINET: Vec3 = (0.7, 0.0, 0.9)
TORSO_Z = 0.03
"""Height of torso_link0's origin above the world origin (velma/model/README.md "Structure")."""
MOVE_DURATION = 3.0
SHORT_MOVE = 1.5


# ----------------------------------------------------------------- helpers
def _rot_z(angle: float) -> Array:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _pose(p: Array, r: Array) -> Pose:
    return Pose(position=(float(p[0]), float(p[1]), float(p[2])), orientation=quat_wxyz(r))


def _position(obs: Observation, name: str) -> Array:
    for o in obs.objects:
        if o.name == name:
            return np.array(o.pose.position, dtype=float)
    raise KeyError(f"{name} not in the observation")


@dataclass(frozen=True)
class Poses:
    """World poses the script moves through (exposed for tests and the planner's check)."""

    jar_pregrasp: Pose
    jar_grasp: Pose
    jar_lift: Pose
    jar_retreat: Pose
    bowl_entry: Pose
    bowl_pregrasp: Pose
    bowl_grasp: Pose
    bowl_lift: Pose
    bowl_retreat: Pose
    bowl_above_place: Pose
    bowl_place: Pose
    jar_above_pour: Pose
    jar_pour_start: Pose
    right_park: Pose
    pour_pivot: Vec3
    pour_axis: Vec3


def script_poses(obs: Observation, bowl_on_table: Vec3 | None = None) -> Poses:
    """The grip poses of the script for the observed jar and bowl positions; the pour is
    computed for the bowl at ``bowl_on_table`` (its observed position after placing; default
    the nominal BOWL_PLACE_POSITION)."""
    jar = _position(obs, "jar")
    bowl = _position(obs, "bowl")
    up = np.array([0.0, 0.0, 1.0])
    r_jar = quat_to_rot(JAR_GRIP_IN_OBJECT[1])
    jar_grasp = jar + np.array(JAR_GRIP_IN_OBJECT[0])
    jar_app = np.array(JAR_APPROACH_IN_OBJECT)
    jar_lift = jar_grasp + JAR_LIFT * up
    r_bowl = quat_to_rot(BOWL_GRIP_IN_OBJECT[1])
    bowl_grasp = bowl + np.array(BOWL_GRIP_IN_OBJECT[0])
    bowl_app = np.array(BOWL_APPROACH_IN_OBJECT)
    bowl_pre = bowl_grasp - BOWL_APPROACH_DISTANCE * bowl_app
    bowl_entry = bowl_pre - np.array([BOWL_ENTRY_DISTANCE, 0.0, 0.0])
    bowl_lift = bowl_grasp + BOWL_LIFT * up
    turn = _rot_z(TORSO_PLACE)
    place = np.array(BOWL_PLACE_POSITION) + np.array([0.0, 0.0, PLACE_CLEARANCE])
    r_bowl_place = turn @ r_bowl
    bowl_place = place + r_bowl_place @ (r_bowl.T @ np.array(BOWL_GRIP_IN_OBJECT[0]))
    pour = pour_poses(bowl_on_table if bowl_on_table is not None else BOWL_PLACE_POSITION)
    return Poses(
        jar_pregrasp=_pose(jar_grasp - JAR_APPROACH_DISTANCE * jar_app, r_jar),
        jar_grasp=_pose(jar_grasp, r_jar),
        jar_lift=_pose(jar_lift, r_jar),
        jar_retreat=_pose(jar_lift - JAR_RETREAT * jar_app, r_jar),
        bowl_entry=_pose(bowl_entry, r_bowl),
        bowl_pregrasp=_pose(bowl_pre, r_bowl),
        bowl_grasp=_pose(bowl_grasp, r_bowl),
        bowl_lift=_pose(bowl_lift, r_bowl),
        bowl_retreat=_pose(bowl_lift - np.array([BOWL_RETREAT, 0.0, 0.0]), r_bowl),
        bowl_above_place=_pose(bowl_place + PLACE_APPROACH * up, r_bowl_place),
        bowl_place=_pose(bowl_place, r_bowl_place),
        jar_above_pour=pour.jar_above_pour,
        jar_pour_start=pour.jar_pour_start,
        right_park=_pose(bowl_place + turn @ np.array(RIGHT_PARK_OFFSET), r_bowl_place),
        pour_pivot=pour.pour_pivot,
        pour_axis=pour.pour_axis,
    )


@dataclass(frozen=True)
class PourPoses:
    """World poses of the pour into the bowl at a given position (see :func:`pour_poses`)."""

    jar_above_pour: Pose
    jar_pour_start: Pose
    pour_pivot: Vec3
    pour_axis: Vec3


def pour_poses(bowl: Vec3) -> PourPoses:
    """The left grip poses and the tilt of the pour into the bowl standing at ``bowl`` (world,
    m), the jar held with the side grasp (JAR_GRIP_IN_OBJECT turned with the torso)."""
    up = np.array([0.0, 0.0, 1.0])
    pour_turn = _rot_z(TORSO_POUR)
    r_jar_pour = pour_turn @ quat_to_rot(JAR_GRIP_IN_OBJECT[1])
    bowl_now = np.array(bowl, dtype=float)
    jar_origin = bowl_now + pour_turn @ np.array(JAR_POUR_START_IN_BOWL)
    jar_pour_grip = jar_origin + pour_turn @ np.array(JAR_GRIP_IN_OBJECT[0])
    pivot = bowl_now + pour_turn @ np.array(POUR_PIVOT_IN_BOWL)
    axis = pour_turn @ np.array(POUR_AXIS_IN_TORSO)
    return PourPoses(
        jar_above_pour=_pose(jar_pour_grip + POUR_APPROACH_HEIGHT * up, r_jar_pour),
        jar_pour_start=_pose(jar_pour_grip, r_jar_pour),
        pour_pivot=(float(pivot[0]), float(pivot[1]), float(pivot[2])),
        pour_axis=(float(axis[0]), float(axis[1]), float(axis[2])),
    )


def pour_commands(bowl: Vec3) -> list[ExecutorCommand]:
    """The pour part of the experiment, the jar in the left hand (side grasp), into the bowl
    standing at ``bowl`` (world, m): turn to TORSO_POUR, bring the jar over, tilt, wait, tilt
    back, move the jar out of the head's view of the bowl (POUR_CLEAR_VIEW), observe."""
    p = pour_poses(bowl)
    left = JAR_ARM
    clear = np.array(p.jar_pour_start.position) + _rot_z(TORSO_POUR) @ np.array(POUR_CLEAR_VIEW)
    jar_clear_view = Pose((float(clear[0]), float(clear[1]), float(clear[2])), p.jar_pour_start.orientation)
    return [
        MoveJoints(positions={TORSO_JOINT: TORSO_POUR}, duration=SHORT_MOVE),
        MoveTool(arm=left, target=p.jar_above_pour, duration=MOVE_DURATION),
        MoveTool(arm=left, target=p.jar_pour_start, duration=SHORT_MOVE),
        Tilt(arm=left, pivot=p.pour_pivot, axis=p.pour_axis, angle=POUR_ANGLE, duration=POUR_DURATION),
        Wait(duration=POUR_WAIT),
        Tilt(arm=left, pivot=p.pour_pivot, axis=p.pour_axis, angle=-POUR_ANGLE, duration=UNTILT_DURATION),
        MoveTool(arm=left, target=jar_clear_view, duration=SHORT_MOVE),
        Observe(),
    ]


def pour_script(obs: Observation, bowl_on_table: Vec3 | None = None) -> list[ExecutorCommand]:
    """The full L_EX command sequence of the experiment for the observed scene ``obs``, the
    pour aimed at the bowl at ``bowl_on_table`` (see :func:`script_poses`).

    Raises ``KeyError`` if ``obs`` lacks the jar or the bowl."""
    p = script_poses(obs, bowl_on_table)
    left, right = JAR_ARM, BOWL_ARM
    place = np.array(BOWL_PLACE_POSITION)
    left_names = [f"left_arm_{k}_joint" for k in range(7)]
    right_names = [f"right_arm_{k}_joint" for k in range(7)]
    return [
        LookAt(point=HEAD_LOOK_CABINET),
        MoveJoints(positions={TORSO_JOINT: TORSO_PICK}, duration=SHORT_MOVE),
        # --- jar, left hand
        MoveJoints(positions=dict(zip(left_names, LEFT_PICK_POSTURE, strict=True)), duration=SHORT_MOVE),
        Release(arm=left, opening=PREGRASP_OPENING),
        MoveTool(arm=left, target=p.jar_pregrasp, duration=SHORT_MOVE),
        MoveTool(arm=left, target=p.jar_grasp, duration=SHORT_MOVE),
        Grasp(arm=left, spread=JAR_SPREAD, load=JAR_LOAD),
        MoveTool(arm=left, target=p.jar_lift, duration=1.0),
        MoveTool(arm=left, target=p.jar_retreat, duration=SHORT_MOVE),
        # --- bowl, right hand
        MoveJoints(positions=dict(zip(right_names, RIGHT_PICK_POSTURE, strict=True)), duration=SHORT_MOVE),
        Release(arm=right, opening=PREGRASP_OPENING),
        MoveTool(arm=right, target=p.bowl_entry, duration=SHORT_MOVE),
        MoveTool(arm=right, target=p.bowl_pregrasp, duration=SHORT_MOVE),
        MoveTool(arm=right, target=p.bowl_grasp, duration=1.0),
        Grasp(arm=right, spread=BOWL_SPREAD, load=BOWL_LOAD),
        MoveTool(arm=right, target=p.bowl_lift, duration=1.0),
        MoveTool(arm=right, target=p.bowl_retreat, duration=SHORT_MOVE),
        # --- turn to the table, place the bowl
        MoveJoints(positions={TORSO_JOINT: TORSO_PLACE}, duration=MOVE_DURATION),
        LookAt(point=(float(place[0]), float(place[1]), float(place[2]))),
        MoveTool(arm=right, target=p.bowl_above_place, duration=MOVE_DURATION),
        MoveTool(arm=right, target=p.bowl_place, duration=SHORT_MOVE),
        Release(arm=right, opening=RELEASE_OPENING),
        MoveTool(arm=right, target=p.bowl_above_place, duration=1.0),
        MoveTool(arm=right, target=p.right_park, duration=SHORT_MOVE),
        Observe(objects=("bowl", "jar")),
        # --- pour
        *pour_commands(bowl_on_table if bowl_on_table is not None else BOWL_PLACE_POSITION),
    ]


def run_script(
    submit: Callable[[ExecutorCommand, Callable[[CommandResult | Observation], None]], object],
    commands: list[ExecutorCommand],
    *,
    stop_on_failure: bool = True,
    timeout: float = 600.0,
) -> list[CommandResult | Observation]:
    """Submit ``commands`` one by one through ``submit`` (e.g. ``Executor.submit``) and wait
    for each result (threading.Event, no polling). Stops at the first failed command when
    ``stop_on_failure``. Raises ``TimeoutError`` if a result takes longer than ``timeout``
    seconds of wall time."""
    results: list[CommandResult | Observation] = []
    for command in commands:
        done = threading.Event()
        box: list[CommandResult | Observation] = []

        def on_done(
            result: CommandResult | Observation,
            box: list[CommandResult | Observation] = box,
            done: threading.Event = done,
        ) -> None:
            box.append(result)
            done.set()

        submit(command, on_done)
        if not done.wait(timeout):
            raise TimeoutError(f"no result for {type(command).__name__} within {timeout} s")
        results.append(box[0])
        if stop_on_failure and isinstance(box[0], CommandResult) and not box[0].ok:
            break
    return results


def run_pour(
    submit: Callable[[ExecutorCommand, Callable[[CommandResult | Observation], None]], object],
    *,
    timeout: float = 600.0,
) -> tuple[list[ExecutorCommand], list[CommandResult | Observation]]:
    """The whole experiment as the agents' plans run it: observe the scene, run
    ``pour_script`` up to the observation of the placed bowl, then aim the pour at where the
    bowl really is. Returns the commands sent and their results (shorter than the commands
    when one failed). Raises ``TimeoutError`` as ``run_script``; ``KeyError`` if the first
    observation lacks the jar or the bowl."""
    first = run_script(submit, [Observe()], timeout=timeout)[0]
    if not isinstance(first, Observation):
        raise RuntimeError(f"the first observation failed: {first}")
    commands = pour_script(first)
    split = next(i for i, c in enumerate(commands) if isinstance(c, Observe) and c.objects) + 1
    results = run_script(submit, commands[:split], timeout=timeout)
    placed = results[-1]
    if len(results) < split or not isinstance(placed, Observation):
        return commands[: len(results)], results
    bowl_now = next(o for o in placed.objects if o.name == "bowl").pose.position
    commands = commands[:split] + pour_script(first, bowl_on_table=bowl_now)[split:]
    results += run_script(submit, commands[split:], timeout=timeout)
    return commands[: len(results)], results
