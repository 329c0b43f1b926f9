"""L_EX: low-level commands a_ta requests from ag_ex on C5, and their results.

Poses are in the ``world`` frame; the tool frame of an arm is its BarrettHand grip frame
(``{side}_HandGripLink``, velma-facts.md). Durations in seconds, angles in radians,
stiffness in N/m (translation) and N·m/rad (rotation).
"""

from __future__ import annotations

import enum

import msgspec

from shared.fipa_codec.languages.base import Language, register
from shared.fipa_codec.languages.common import Pose, Vec3


class Arm(enum.StrEnum):
    LEFT = "left"
    RIGHT = "right"


class MoveTool(msgspec.Struct, frozen=True, tag="move_tool", kw_only=True):
    """Move ``arm``'s grip frame to ``target`` along a straight, minimum-jerk path of
    ``duration`` seconds under Cartesian impedance ``stiffness`` (6 values; None: default)."""

    arm: Arm
    target: Pose
    duration: float
    stiffness: tuple[float, float, float, float, float, float] | None = None


class MoveJoints(msgspec.Struct, frozen=True, tag="move_joints", kw_only=True):
    """Move the named joints (``torso_0_joint``, ``left_arm_3_joint``…) to ``positions`` (rad)
    in ``duration`` seconds under joint impedance."""

    positions: dict[str, float]
    duration: float


class Grasp(msgspec.Struct, frozen=True, tag="grasp", kw_only=True):
    """Close ``arm``'s BarrettHand with finger spread ``spread`` (rad) until the fingers meet
    the object; fails with ``no contact`` if they close fully."""

    arm: Arm
    spread: float = 0.0


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


def command_name(command: object) -> str:
    """The L_EX tag of a command (``move_tool``, ``grasp``…), or its class name for anything
    else (used to name the command in its ``CommandResult``)."""
    config = getattr(type(command), "__struct_config__", None)
    tag = getattr(config, "tag", None)
    return str(tag) if tag else type(command).__name__


class CommandResult(msgspec.Struct, frozen=True, tag="result", kw_only=True):
    """The outcome of one executor command: ``ok`` and, when not, a ``reason``
    (``unreachable``, ``contact lost``, ``timeout``, ``no contact``…). ``sim_time`` is the
    simulation time at completion (s); ``tool_error`` the final grip-frame position error (m);
    ``self_contacts`` the pairs of the robot's own geometries (``"a + b"``, sorted) that touched
    each other while the command ran — empty when the robot did not touch itself
    (Velma's links collide with each other in the simulation)."""

    command: str
    ok: bool
    reason: str | None = None
    sim_time: float = 0.0
    tool_error: float | None = None
    self_contacts: tuple[str, ...] = ()


HALTED = "halted"
"""``CommandResult.reason`` of a command ag_ex stopped because a_ta cancelled it (FIPA SC00026
§2 cancel meta-protocol; paper §3.2 safe interruption): the commanded motion was halted
(velma/executor/loop.py ``ControlLoop.cancel``), ``ok`` is False, ``sim_time`` is when the
robot came to rest. It comes in ag_ex's ``inform`` that answers the ``cancel``."""


L_EX = register(
    Language(
        "L_EX",
        "O_Velma",
        (MoveTool, MoveJoints, Grasp, Release, LookAt, Tilt, Observe, Wait, CommandResult),
    )
)
