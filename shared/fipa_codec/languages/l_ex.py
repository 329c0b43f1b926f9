"""L_EX: low-level commands a_ta requests from ag_ex on C5, and their results.

Poses are in the ``world`` frame; the tool frame of an arm is its BarrettHand grip frame
(``{side}_HandGripLink``, velma/model/README.md "KUKA LWR4+ arms"). Durations in seconds,
angles in radians, stiffness in N/m (translation) and N·m/rad (rotation). Its ontology is
O_Velma (the robot's frames and joints), not O_RoCo.
"""

from __future__ import annotations

import enum
import functools
import operator
import typing

import msgspec

from shared.fipa_codec.languages.base import Language, extend, register
from shared.fipa_codec.languages.common import Pose, Vec3

TORSO_JOINT = "torso_0_joint"
"""O_Velma's name of the torso's one joint (a hinge about the vertical, velma/model/README.md
"Structure"), as in ``MoveJoints.positions`` and ``RobotSnapshot.joints``."""


class Arm(enum.StrEnum):
    LEFT = "left"
    RIGHT = "right"


class MoveTool(msgspec.Struct, frozen=True, tag="move_tool", kw_only=True):
    """Move ``arm``'s grip frame to ``target`` along a straight, minimum-jerk path of
    ``duration`` seconds under Cartesian impedance ``stiffness`` (6 values; None: default).

    ``guard`` (N, positive; None: unguarded) makes it a guarded move, e.g. lowering a held
    object onto a surface. While the path runs, the contact force is the external force that
    resists the motion: the change, since the command began, of the force the arm exerts on
    the hand as the wrist F/T sensor measures it (``{arm}_ft_sensor``, velma/model/README.md
    "KUKA LWR4+ arms"; so the hand's and the held object's weight cancel), projected on the
    motion's direction, from the start to ``target`` (its magnitude for a move that only
    turns). When its mean over the last 5 ms exceeds ``guard`` the move ends at once, ``ok``:
    the Cartesian setpoint is set to the measured grip pose (the arm does not push on) and the
    result says so (``CommandResult.contact``; ``reason`` ``contact (F N, D mm from the
    target)``). Without such a contact it ends as an unguarded move does; a ``guard`` ≤ 0
    fails at once (``invalid guard``)."""

    arm: Arm
    target: Pose
    duration: float
    stiffness: tuple[float, float, float, float, float, float] | None = None
    guard: float | None = None


class MoveJoints(msgspec.Struct, frozen=True, tag="move_joints", kw_only=True):
    """Move the named joints (``TORSO_JOINT``, ``left_arm_3_joint``…) to ``positions`` (rad)
    in ``duration`` seconds under joint impedance."""

    positions: dict[str, float]
    duration: float


GRASP_AT_TOLERANCE_M = 0.02
"""Default ``Grasp.tolerance`` (m): how far the measured grip frame may be from the grasp pose
``Grasp.at``. The reach that brings the hand there ends within 1 cm of it (a MoveTool's
convergence, velma/executor/primitives.py ``POS_TOL``), and the BarrettHand's pre-grasp
opening leaves ≈ 1 cm either way around the object (services/agents/planner/hfsm.py
``GRASP_MAX_SIGMA_M``); a hand further off closes beside the object, or on its rim."""

NOT_AT_GRASP_POSE = "not at the grasp pose"
"""``CommandResult.reason`` of a Grasp given ``at`` whose measured grip frame was farther than
its ``tolerance`` from there (e.g. a hand left elsewhere by a restart): it fails at once, the
fingers unmoved; ``tool_error`` says how far (m). The world differs from the plan."""


class Grasp(msgspec.Struct, frozen=True, tag="grasp", kw_only=True):
    """Close ``arm``'s BarrettHand with finger spread ``spread`` (rad) until the fingers meet
    the object; fails with ``no contact`` if they close fully.

    ``at`` (world; None: anywhere) is the grasp pose the hand is expected at, the target of
    the reach before it: when the measured grip frame's position is farther than
    ``tolerance`` (m, default ``GRASP_AT_TOLERANCE_M``) from ``at``'s position, the grasp
    fails at once with ``NOT_AT_GRASP_POSE`` without moving the fingers (its orientation is
    not compared).

    ``load`` (kg; None: not known) is the object's mass as the knowledge base gives it: once the
    hand holds the object, the arm's impedance law compensates that weight at once, then the
    weight the wrist F/T sensor measures after the lift (velma/model/README.md "Payload"). A
    load the hand cannot carry fails at once (``invalid load``), the fingers unmoved."""

    arm: Arm
    spread: float = 0.0
    at: Pose | None = None
    tolerance: float = GRASP_AT_TOLERANCE_M
    load: float | None = None


class Release(msgspec.Struct, frozen=True, tag="release", kw_only=True):
    """Open ``arm``'s hand (proximal joints to ``opening`` rad)."""

    arm: Arm
    opening: float = 0.0


class LookAt(msgspec.Struct, frozen=True, tag="look_at", kw_only=True):
    """Point the head (pan, tilt) at ``point`` (world, m); it keeps looking there while the
    torso turns, until a MoveJoints gives the head's joint angles."""

    point: Vec3


class Tilt(msgspec.Struct, frozen=True, tag="tilt", kw_only=True):
    """Rotate the object held by ``arm`` by ``angle`` rad about ``axis`` through ``pivot``
    (world) in ``duration`` seconds: the pouring motion."""

    arm: Arm
    pivot: Vec3
    axis: Vec3
    angle: float
    duration: float


class Observe(msgspec.Struct, frozen=True, tag="observe", kw_only=True):
    """Report the scene as perceived (L_SD Observation) for ``objects`` (empty: all known)."""

    objects: tuple[str, ...] = ()


class Wait(msgspec.Struct, frozen=True, tag="wait", kw_only=True):
    """Hold the current setpoints for ``duration`` seconds (lets content settle)."""

    duration: float


ExecutorCommand = MoveTool | MoveJoints | Grasp | Release | LookAt | Tilt | Observe | Wait
"""The L_EX commands, a table: a new command is a row here (docs/executor.md, "Adding a robot
primitive")."""

COMMANDS: dict[str, type[msgspec.Struct]] = {
    str(t.__struct_config__.tag): t for t in typing.get_args(ExecutorCommand)
}
"""The L_EX commands by tag: ag_ex takes a request whose content is one of them.
:func:`add_command` adds one at run time (a test's)."""


def command_name(command: object) -> str:
    """The L_EX tag of a command (``move_tool``, ``grasp``…), or its class name for anything
    else (used to name the command in its ``CommandResult``)."""
    config = getattr(type(command), "__struct_config__", None)
    tag = getattr(config, "tag", None)
    return str(tag) if tag else type(command).__name__


class CommandResult(msgspec.Struct, frozen=True, tag="result", kw_only=True):
    """The outcome of one executor command: ``ok`` and, when not, a ``reason``
    (``unreachable``, ``contact lost``, ``timeout``, ``no contact``, ``NOT_AT_GRASP_POSE``…);
    a guarded MoveTool that ended on contact is ``ok`` with the reason
    ``contact (F N, D mm from the target)``. ``sim_time`` is the simulation time at completion
    (s); ``tool_error`` the final grip-frame position error (m; for a Grasp that was not at its
    grasp pose, how far it was); ``self_contacts`` the pairs of the robot's own geometries
    (``"a + b"``, sorted) that touched each other while the command ran — empty when the robot
    did not touch itself (Velma's links collide with each other in the simulation);
    ``contact`` the external force along the motion (N, ``MoveTool.guard``'s measure) that
    ended a guarded MoveTool early, None for any other ending; ``world`` which power-on of the
    robot (the world process's run: velma/world/) the command ran in, "" when not known: a
    different one than before means the robot was power-cycled, its kitchen started anew."""

    command: str
    ok: bool
    reason: str | None = None
    sim_time: float = 0.0
    tool_error: float | None = None
    self_contacts: tuple[str, ...] = ()
    contact: float | None = None
    world: str = ""


HALTED = "halted"
"""``CommandResult.reason`` of a command ag_ex stopped because a_ta cancelled it (FIPA SC00026
§2 cancel meta-protocol; paper §3.2 safe interruption): the commanded motion was halted
(velma/executor/loop.py ``ControlLoop.cancel``), ``ok`` is False, ``sim_time`` is when the
robot came to rest. It comes in ag_ex's ``inform`` that answers the ``cancel``."""


class PowerOns(msgspec.Struct, frozen=True, tag="power_ons"):
    """a_ta's fipa-subscribe to ag_ex (C5; FIPA SC00035): tell each power-on of the robot
    ag_ex's loop is attached to (:class:`PowerOn`), the current one at once."""


class PowerOn(msgspec.Struct, frozen=True, tag="power_on", kw_only=True):
    """ag_ex's inform in a_ta's :class:`PowerOns` subscription: its loop is attached to the
    robot's power-on ``world`` (the world process's link name, as ``CommandResult.world``); a
    new one means the robot was power-cycled, its kitchen started anew."""

    world: str


class Watch(msgspec.Struct, frozen=True, tag="watch", kw_only=True):
    """a_ta's fipa-subscribe to ag_ex (C5; FIPA SC00035): see continuously — every
    ``period_s`` s of robot time ag_ex informs an L_SD ``Observation`` of ``objects`` (empty:
    every object the camera knows) from one head-camera frame, the content not counted
    (velma/executor/watch.py). At most one watch at ag_ex (a later one replaces it); while it
    is on, a simulation that runs as fast as possible runs at most at the camera's pace."""

    objects: tuple[str, ...] = ()
    period_s: float


L_EX = register(
    Language(
        "L_EX",
        "O_Velma",
        (*COMMANDS.values(), CommandResult, PowerOns, PowerOn, Watch),
    )
)


def add_command(command: type[msgspec.Struct]) -> None:
    """Make ``command`` (a msgspec Struct type with its own ``tag``) an L_EX command: a term of
    L_EX (``base.extend``) and a row of ``COMMANDS``. Raises ValueError as ``extend`` does
    (no tag, a tag or name taken, a term of another language)."""
    extend(L_EX.name, command)
    COMMANDS[str(command.__struct_config__.tag)] = command


def command_decoder() -> typing.Callable[[bytes], ExecutorCommand]:
    """A decoder of one L_EX command from its msgpack bytes, for the commands ``COMMANDS`` holds
    now (those of ``ExecutorCommand`` and any :func:`add_command` added in this process). The
    decoder raises msgspec.ValidationError for a command it does not know, msgspec.DecodeError
    for bytes that are no msgpack."""
    commands: typing.Any = functools.reduce(operator.or_, COMMANDS.values())
    return msgspec.msgpack.Decoder(commands).decode
