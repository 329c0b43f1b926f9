"""The executor's motion primitives, one per L_EX command (paper §5.3, ag_ex).

Each primitive is a small state machine driven by the loop thread: ``start`` is called once
in the cycle the command begins, ``step`` every cycle after that; either returns the result
(``CommandResult``; for Observe a ``WorldCapture`` for the camera, or with
``ROCO_PERCEPTION=truth`` the ground truth's ``Observation``) to end the command, or None.

Failure reasons: ``unreachable`` (IK finds no arm configuration, a joint target outside its
limits, a look-at point outside the neck's range), ``timeout`` (not converged in time;
MoveTool, Tilt and MoveJoints add in parentheses by how much and what holds them: MoveJoints
what the hands touch, MoveTool and Tilt what the arm touches, joints in their limit band, what
the hand touches, a contradicted payload prior), ``invalid load`` (a Grasp's ``load`` the hand
cannot carry),
``no contact`` (fingers closed fully), ``contact lost`` (a held object left the hand during
a motion), ``not at the grasp pose`` (L_EX ``NOT_AT_GRASP_POSE``: a Grasp given ``at`` found
the hand farther than its tolerance from there; it did not close), ``invalid guard`` (a
MoveTool guard ≤ 0 N), ``unknown joint: NAME``, ``unknown frame: NAME``.

A guarded MoveTool (``MoveTool.guard``, ``_Guard``) that meets a contact ends ``ok``, its
reason ``contact (F N, D mm from the target)`` and ``CommandResult.contact`` F.

Grasps hold by contact and friction only (no welds, no attachment).

``HaltPrimitive`` is no L_EX command: it replaces a running primitive that a_ta cancelled
(velma/executor/loop.py ``ControlLoop.cancel``; paper §3.2) and ends with ``halted``.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
import pinocchio as pin

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    NOT_AT_GRASP_POSE,
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
from velma.control.hand import PROXIMAL_MAX, STALL_SPEED
from velma.control.ik import IkSearch
from velma.control.impedance import DEFAULT_CART_STIFFNESS
from velma.control.joints import HEAD_JOINTS, SIDES, TORSO_JOINT, Array, arm_joints
from velma.control.limits import LIMIT_BAND, SINGULAR_JOINTS, SINGULARITY_BAND, SINGULARITY_HALF_WIDTH
from velma.control.payload import Payload
from velma.control.trajectory import (
    MIN_JERK_PEAK_RATE,
    PosePath,
    RotationPath,
    min_jerk,
    rotation_error,
)
from velma.executor.capture import WorldCapture
from velma.executor.runtime import Runtime, torso_frame
from velma.frames import rot_from_wxyz

Result = CommandResult | Observation | WorldCapture

POS_TOL = 0.01  # m, MoveTool/Tilt convergence
ROT_TOL = 0.1
"""rad, MoveTool/Tilt convergence: set when a held object's weight was not compensated and sagged
the wrist by up to ≈ 0.08 rad (velma/executor/payloads.py compensates it now); not tightened."""
SETTLE_TIMEOUT = 2.0  # s after the nominal duration
JOINT_TOL = 0.03  # rad, MoveJoints convergence
TORSO_VEL = 0.52  # rad/s (velma/model/README.md "Structure")
HEAD_VEL = 1.04  # rad/s
ARM_VEL = 2.0  # rad/s, arm joint velocity limit in control (velma/model/README.md)
GRASP_SETTLE = 0.1  # s of stall that ends a grasp
GRASP_TIMEOUT = 5.0  # s
RELEASE_TIMEOUT = 2.5  # s
CLOSED = PROXIMAL_MAX - 0.1  # rad: a finger this far closed has met nothing
HEAD_TOL = 0.02  # rad
GUARD_WINDOW = 5
"""Cycles (1 ms each) over which a guarded MoveTool averages its contact force: a single
reading ends it only when it is 5 times the guard (a jolt of one cycle is no contact); a
contact ends it ≤ 5 ms late, ≤ 0.5 mm at a set-down lower's peak speed (≈ 0.1 m/s)."""
GUARD_MIN_TRAVEL = 0.001
"""m: a guarded MoveTool that moves the grip frame less than this only turns it, and its
contact force is the magnitude of the force's change, not its part along the motion."""
HEAD_TIMEOUT = 4.0  # s
IK_ITERATIONS_PER_CYCLE = 4
"""IK search steps per 1 ms cycle while a target is solved (warm: a compiled DLS iteration
≈ 4 µs, in Python ≈ 28 µs; a self-collision slice ≈ 8 µs)."""
CAMERA_HEIGHT = 0.06  # m, camera above the tilt axis (velma.xml head_camera)
UPRIGHT_TOL = 0.05
"""rad: a held object that a Tilt turned (``Runtime.tilt_about``) and whose axis, with the grip
at its setpoint, leans further from the vertical is turned upright by a halt (a payload's sag,
≤ ≈ 0.08 rad, is not counted: the axis is taken with the grip at its setpoint, not where the
payload pulls it)."""


class Primitive(Protocol):
    """One running command."""

    def start(self, rt: Runtime) -> Result | None: ...

    def step(self, rt: Runtime) -> Result | None: ...


def ended(
    rt: Runtime, name: str, ok: bool, reason: str | None = None, err: float | None = None
) -> CommandResult:
    """The result of command ``name`` ending now (``rt.time``): ``ok``, with the ``reason`` it
    failed and the grip frame's error ``err`` (m) at its end."""
    return CommandResult(command=name, ok=ok, reason=reason, sim_time=rt.time, tool_error=err)


def pose_to_se3(pose: Pose) -> pin.SE3:
    """A world ``Pose`` as SE3. Raises ValueError for another frame or a zero quaternion."""
    if pose.frame != "world":
        raise ValueError(f"unknown frame: {pose.frame}")
    return pin.SE3(rot_from_wxyz(pose.orientation), np.array(pose.position, dtype=float))


class _CartesianMotion:
    """Shared part of MoveTool and Tilt: follow a path, then wait for convergence."""

    name = "move_tool"

    def __init__(self, side: str, duration: float, stiffness: tuple[float, ...] | None) -> None:
        self.side = side
        self.duration = max(0.0, float(duration))
        self.stiffness = np.array(stiffness if stiffness is not None else DEFAULT_CART_STIFFNESS, dtype=float)
        self.path: PosePath | RotationPath | None = None
        self.pending: PosePath | RotationPath | None = None
        self.search: IkSearch | None = None
        self.goal = pin.SE3.Identity()
        self.q0 = np.zeros(7)
        self.q_goal = np.zeros(7)
        self.t0 = 0.0

    def _begin(self, rt: Runtime, path: PosePath | RotationPath, goal: pin.SE3) -> None:
        """Start the IK search for ``goal``; ``path`` is followed once it has succeeded. The
        arm keeps its current setpoint while the search runs (a few ms)."""
        self.goal = goal
        self.pending = path
        self.search = IkSearch(
            rt.robot,
            self.side,
            goal,
            rt.q(),
            data=rt.ik_data,
            self_collision=rt.self_collision,
            kernel=rt.ik_kernel,
        )

    def _solve(self, rt: Runtime) -> Result | None:
        """Advance the IK search by ``IK_ITERATIONS_PER_CYCLE``; when it has converged,
        switch the arm to Cartesian impedance on the path. Returns a failure if unreachable."""
        assert self.search is not None and self.pending is not None
        ik = self.search.advance(IK_ITERATIONS_PER_CYCLE)
        if ik is None:
            return None
        if not ik.ok:
            start = self.pending.sample(0.0)[0]
            touching = ik.self_collision
            return ended(
                rt,
                self.name,
                False,
                "unreachable" if touching is None else f"unreachable (self-collision: {', '.join(touching)})",
                float(np.linalg.norm(self.goal.translation - start.translation)),
            )
        idx = rt.ctrl.arm_slice[self.side]
        self.q0 = rt.q()[idx].copy()
        self.q_goal = ik.q[idx].copy()
        cmd = rt.ctrl.arm[self.side]
        start, _ = self.pending.sample(0.0)
        cmd.pose = start  # the setpoint must be valid before the law switches to it
        cmd.twist = np.zeros(6)
        cmd.stiffness = self.stiffness
        cmd.posture = self.q0.copy()
        cmd.mode = "cart"
        self.path = self.pending
        self.t0 = rt.motion_time
        return None

    def start_pose(self, rt: Runtime) -> pin.SE3:
        """The current Cartesian setpoint, or the measured grip pose if not in Cartesian mode."""
        cmd = rt.ctrl.arm[self.side]
        if cmd.mode == "cart":
            return cmd.pose.copy()
        return rt.grip(self.side).copy()

    def follow(self, rt: Runtime) -> float:
        """Set the arm's setpoint (pose, twist, null-space posture) to the path's at the time
        now; returns the time (s) since the path began. Only once the path runs (after
        ``_solve`` succeeded)."""
        assert self.path is not None
        t = rt.motion_time - self.t0
        pose, twist = self.path.sample(t)
        cmd = rt.ctrl.arm[self.side]
        cmd.pose = pose
        cmd.twist = twist
        s, _ = min_jerk(t, self.duration)
        cmd.posture = self.q0 + s * (self.q_goal - self.q0)
        return t

    def step(self, rt: Runtime) -> Result | None:
        if self.path is None:
            return self._solve(rt)
        t = self.follow(rt)
        cmd = rt.ctrl.arm[self.side]
        if rt.hold_lost(self.side):
            cmd.pose = rt.grip(self.side).copy()
            cmd.twist = np.zeros(6)
            return ended(rt, self.name, False, "contact lost", self._perr(rt))
        if t >= self.duration:
            cmd.twist = np.zeros(6)
            perr = self._perr(rt)
            rerr = rotation_error(rt.grip(self.side).rotation, self.goal.rotation)
            if perr < POS_TOL and rerr < ROT_TOL:
                return ended(rt, self.name, True, None, perr)
            if t >= self.duration + SETTLE_TIMEOUT:
                return ended(rt, self.name, False, self._timeout_reason(rt, perr, rerr), perr)
        return None

    def _perr(self, rt: Runtime) -> float:
        return float(np.linalg.norm(rt.grip(self.side).translation - self.goal.translation))

    def _timeout_reason(self, rt: Runtime, perr: float, rerr: float) -> str:
        """``timeout (position error P mm, rotation error R rad[; why])``, why: what holds the
        arm (:func:`what_holds`). Computed once, at the timeout."""
        error = f"position error {perr * 1000:.1f} mm, rotation error {rerr:.3f} rad"
        return f"timeout ({'; '.join([error, *what_holds(rt, self.side)])})"


def what_holds(rt: Runtime, side: str) -> list[str]:
    """Why ``side``'s grip frame may stay short of its setpoint, one phrase each: what the arm
    links touch (``left arm touches left_arm_4_link on cabinet_top``), the joints in their limit
    band (``at its limit: left_arm_3_joint``) or in a singularity's band (``near a singularity:
    left_arm_5_joint``, velma/control/limits.py), what the hand touches besides what it holds,
    the payload prior the wrist F/T sensor contradicts."""
    parts = []
    touches = rt.arm_touches(side)
    if touches:
        parts.append(f"{side} arm touches {', '.join(touches)}")
    parts += _joint_bands(rt, side)
    others = _touched_besides_held(rt, side)
    if others:
        parts.append(f"{side} hand touches {', '.join(others)}")
    verdict = rt.loads.verdict(side)
    return parts if verdict is None else [*parts, verdict]


def _joint_bands(rt: Runtime, side: str) -> list[str]:
    """The phrases of ``side``'s joints in their limit band and, for joints 1, 3 and 5, in the
    band of their singularity at 0 rad (where the law pushes them back: velma/control/limits.py)."""
    q = rt.arm_q(side)
    lower, upper = rt.ctrl.joint_limits(side)
    names = [f"{side}_arm_{k}_joint" for k in range(7)]
    at_limit = [names[k] for k in range(7) if not lower[k] + LIMIT_BAND <= q[k] <= upper[k] - LIMIT_BAND]
    edge = SINGULARITY_HALF_WIDTH + SINGULARITY_BAND
    singular = [names[k] for k in SINGULAR_JOINTS if abs(q[k]) < edge]
    phrases = [f"at its limit: {', '.join(at_limit)}"] if at_limit else []
    return phrases + ([f"near a singularity: {', '.join(singular)}"] if singular else [])


def _touched_besides_held(rt: Runtime, side: str) -> list[str]:
    """The bodies ``side``'s hand touches (its last contact scan) other than what it holds and
    that object's parts (the jar's content spheres, ``jar_content_*``), sorted."""
    held = rt.held[side]
    mine = rt.model.body(held).name if held is not None else None
    names = {rt.model.body(b).name for b in rt.touch[side]}
    return sorted(n for n in names if mine is None or not (n == mine or n.startswith(f"{mine}_")))


class _Guard:
    """A guarded MoveTool's contact force (L_EX ``MoveTool.guard``): the external force (N)
    that resists the motion, i.e. the change of the force the arm exerts on the hand
    (``Runtime.ft_force``, world axes) since ``start``, projected on the unit direction of the
    motion ``travel`` (m, (3,): from the start to the target; its magnitude when the motion
    moves the grip frame less than ``GUARD_MIN_TRAVEL``), averaged over the last
    ``GUARD_WINDOW`` cycles. The weight of the hand and of what it holds is in the force at the
    start too, and cancels; the hand's own acceleration along the path stays in it (≈ 0.3 N in
    a set-down's lower)."""

    def __init__(self, rt: Runtime, side: str, travel: Array, limit: float) -> None:
        self.side = side
        self.limit = limit
        """N: the contact force that ends the move (``MoveTool.guard``)."""
        self.start = rt.ft_force(side).copy()
        length = float(np.linalg.norm(travel))
        self.direction: Array | None = travel / length if length >= GUARD_MIN_TRAVEL else None
        self.recent: deque[float] = deque([0.0] * GUARD_WINDOW, maxlen=GUARD_WINDOW)
        """The last readings (N); zero before the first: the change since the start."""

    def force(self, rt: Runtime) -> float:
        """Take this cycle's reading; the mean contact force (N) over the last
        ``GUARD_WINDOW`` cycles."""
        change = rt.ft_force(self.side) - self.start
        along = (
            float(change @ self.direction) if self.direction is not None else float(np.linalg.norm(change))
        )
        self.recent.append(along)
        return sum(self.recent) / GUARD_WINDOW


class MoveToolPrimitive(_CartesianMotion):
    """Minimum-jerk straight line + slerp of the grip frame to ``target`` (world). With a
    ``guard`` (N) it ends at once, ``ok``, when the contact force (``_Guard``) exceeds it: the
    setpoint stops at the measured grip pose."""

    name = "move_tool"

    def __init__(self, cmd: MoveTool) -> None:
        super().__init__(cmd.arm.value, cmd.duration, cmd.stiffness)
        self.cmd = cmd
        self.guard: _Guard | None = None

    def start(self, rt: Runtime) -> Result | None:
        try:
            goal = pose_to_se3(self.cmd.target)
        except ValueError as exc:
            return ended(rt, self.name, False, str(exc))
        limit = self.cmd.guard
        if limit is not None and not limit > 0.0:
            return ended(rt, self.name, False, "invalid guard")
        rt.tilt_about[self.side] = None
        start = self.start_pose(rt)
        if limit is not None:
            self.guard = _Guard(rt, self.side, goal.translation - start.translation, limit)
        self._begin(rt, PosePath(start, goal, self.duration), goal)
        return None

    def step(self, rt: Runtime) -> Result | None:
        if self.guard is not None and self.path is not None:
            force = self.guard.force(rt)
            if force > self.guard.limit:
                return self._stop_on_contact(rt, force)
        return super().step(rt)

    def _stop_on_contact(self, rt: Runtime, force: float) -> CommandResult:
        """End the motion where the hand is: the setpoint to the measured grip pose, at rest."""
        cmd = rt.ctrl.arm[self.side]
        cmd.pose = rt.grip(self.side).copy()
        cmd.twist = np.zeros(6)
        perr = self._perr(rt)
        return CommandResult(
            command=self.name,
            ok=True,
            reason=f"contact ({force:.1f} N, {perr * 1000:.1f} mm from the target)",
            sim_time=rt.time,
            tool_error=perr,
            contact=force,
        )


class TiltPrimitive(_CartesianMotion):
    """Rotation of the grip frame by ``angle`` about ``axis`` through ``pivot`` (world)."""

    name = "tilt"

    def __init__(self, cmd: Tilt) -> None:
        super().__init__(cmd.arm.value, cmd.duration, None)
        self.cmd = cmd

    def start(self, rt: Runtime) -> Result | None:
        axis = np.array(self.cmd.axis, dtype=float)
        if np.linalg.norm(axis) < 1e-9:
            return ended(rt, self.name, False, "zero axis")
        start = self.start_pose(rt)
        pivot = np.array(self.cmd.pivot, dtype=float)
        path = RotationPath(start, pivot, axis, float(self.cmd.angle), self.duration)
        if rt.tilt_about[self.side] is None:
            rt.upright_posture[self.side] = None  # no earlier tilt of what it holds
        rt.tilt_about[self.side] = (axis / np.linalg.norm(axis), pivot)
        self._begin(rt, path, path.goal)
        return None

    def step(self, rt: Runtime) -> Result | None:
        solving = self.path is None
        result = super().step(rt)
        if solving and self.path is not None:  # the path begins: remember an upright start's posture
            z = held_axis(rt, self.side)
            if z is None or z[2] >= math.cos(UPRIGHT_TOL):
                rt.upright_posture[self.side] = self.q0.copy()
        return result


class MoveJointsPrimitive:
    """Joint-space minimum-jerk motion of the named joints under joint impedance. The
    duration is stretched if needed so that no joint exceeds its velocity limit (torso
    0.52, head 1.04, arms 2.0 rad/s)."""

    name = "move_joints"

    def __init__(self, cmd: MoveJoints) -> None:
        self.cmd = cmd
        self.duration = 0.0
        self.t0 = 0.0
        self.arm_start: dict[str, Array] = {}
        self.arm_goal: dict[str, Array] = {}
        self.torso: tuple[float, float] | None = None
        self.carried: dict[str, pin.SE3] = {}

    def start(self, rt: Runtime) -> Result | None:
        model = rt.robot.model
        q = rt.q()
        peak = 0.0
        arm_targets: dict[str, dict[int, float]] = {s: {} for s in SIDES}
        head = rt.head_target.copy()
        for name, value in self.cmd.positions.items():
            try:
                i = rt.joint_index(name)
            except KeyError:
                return ended(rt, self.name, False, f"unknown joint: {name}")
            if not model.lowerPositionLimit[i] <= value <= model.upperPositionLimit[i]:
                return ended(rt, self.name, False, "unreachable")
            side = next((s for s in SIDES if name in arm_joints(s)), None)
            if side is not None:
                rt.tilt_about[side] = None
                arm_targets[side][arm_joints(side).index(name)] = value
                peak = max(peak, abs(value - q[i]) / ARM_VEL)
            elif name == TORSO_JOINT:
                rt.tilt_about = {s: None for s in SIDES}  # a pivot is a point of the world
                self.torso = (rt.ctrl.torso_q, value)
                peak = max(peak, abs(value - rt.ctrl.torso_q) / TORSO_VEL)
            elif name in HEAD_JOINTS:
                head[HEAD_JOINTS.index(name)] = value
                peak = max(peak, abs(value - q[i]) / HEAD_VEL)
                rt.gaze = None  # the head's angles are given: it no longer holds a gaze
            else:
                return ended(rt, self.name, False, f"unknown joint: {name}")
        self.duration = max(float(self.cmd.duration), MIN_JERK_PEAK_RATE * peak)
        for side, targets in arm_targets.items():
            cmd = rt.ctrl.arm[side]
            if targets:
                start = q[rt.ctrl.arm_slice[side]].copy()
                goal = start.copy()
                for k, value in targets.items():
                    goal[k] = value
                self.arm_start[side], self.arm_goal[side] = start, goal
                cmd.mode = "joint"
                cmd.q = start.copy()
                cmd.qd = np.zeros(7)
            elif cmd.mode == "cart" and self.torso is not None:
                self.carried[side] = torso_frame(self.torso[0]).actInv(cmd.pose)
        rt.head_target = head
        self.t0 = rt.motion_time
        return None

    def step(self, rt: Runtime) -> Result | None:
        t = rt.motion_time - self.t0
        s, ds = min_jerk(t, self.duration)
        for side, start in self.arm_start.items():
            goal = self.arm_goal[side]
            cmd = rt.ctrl.arm[side]
            cmd.q = start + s * (goal - start)
            cmd.qd = ds * (goal - start)
        if self.torso is not None:
            a, b = self.torso
            rt.ctrl.torso_q = a + s * (b - a)
            rt.ctrl.torso_qd = ds * (b - a)
            frame = torso_frame(rt.ctrl.torso_q)
            for side, rel in self.carried.items():
                rt.ctrl.arm[side].pose = frame.act(rel)
                rt.ctrl.arm[side].twist = np.zeros(6)
            if rt.gaze is not None:  # the head keeps looking where LookAt aimed it
                rt.head_target = look_angles(rt, rt.gaze)[1]
        if t < self.duration:
            return None
        rt.ctrl.torso_qd = 0.0
        for side in self.arm_start:
            rt.ctrl.arm[side].qd = np.zeros(7)
        err = self._error(rt)
        if err < JOINT_TOL:
            return ended(rt, self.name, True)
        if t >= self.duration + SETTLE_TIMEOUT:
            return ended(rt, self.name, False, self._timeout_reason(rt))
        return None

    def _error(self, rt: Runtime) -> float:
        q = rt.q()
        err = 0.0
        for name, value in self.cmd.positions.items():
            err = max(err, abs(float(q[rt.joint_index(name)]) - value))
        return err

    def _timeout_reason(self, rt: Runtime) -> str:
        """``timeout (J E rad from its target[; SIDE hand touches A, B])``: the joint
        furthest from its target and what each hand touches besides what it holds (a joint
        move that stalls is usually blocked by a contact). Computed once, at the timeout."""
        q = rt.q()
        worst, err = max(
            (
                (name, abs(float(q[rt.joint_index(name)]) - value))
                for name, value in self.cmd.positions.items()
            ),
            key=lambda item: item[1],
        )
        parts = [f"{worst} {err:.3f} rad from its target"]
        for side in SIDES:
            touched = _touched_besides_held(rt, side)
            if touched:
                parts.append(f"{side} hand touches {', '.join(touched)}")
        return f"timeout ({'; '.join(parts)})"


class GraspPrimitive:
    """Set the spread, then close the three fingers (distal = proximal / 3) until every
    finger has stalled on the object or closed fully. Given ``at``, first check the measured
    grip frame is within ``tolerance`` of it, else fail at once with ``NOT_AT_GRASP_POSE``
    (``tool_error``: how far, m), the fingers unmoved."""

    name = "grasp"

    def __init__(self, cmd: Grasp) -> None:
        self.side = cmd.arm.value
        self.spread = float(cmd.spread)
        self.at = cmd.at
        self.tolerance = float(cmd.tolerance)
        self.load = cmd.load
        self.phase = "spread"
        self.t0 = 0.0
        self.stall_since: float | None = None

    def start(self, rt: Runtime) -> Result | None:
        if self.load is not None:
            try:
                Payload(self.load)
            except ValueError as exc:
                return ended(rt, self.name, False, f"invalid load: {exc}")
        if self.at is not None:
            if self.at.frame != "world":
                return ended(rt, self.name, False, f"unknown frame: {self.at.frame}")
            expected = np.array(self.at.position, dtype=float)
            away = float(np.linalg.norm(rt.grip(self.side).translation - expected))
            if not away <= self.tolerance:
                return ended(rt, self.name, False, NOT_AT_GRASP_POSE, away)
        hs = rt.hands.set[self.side]
        rt.hands.command(self.side, float(np.max(hs.proximal)), self.spread)
        self.t0 = rt.motion_time
        return None

    def step(self, rt: Runtime) -> Result | None:
        t = rt.motion_time - self.t0
        if t > GRASP_TIMEOUT:
            return ended(rt, self.name, False, "timeout")
        if self.phase == "spread":
            if rt.hands.ramp_done(self.side):
                rt.hands.command(self.side, PROXIMAL_MAX)
                self.phase = "close"
                self.t0 = rt.motion_time
            return None
        if t < 0.2:
            return None
        prox = rt.hands.proximal(rt.data, self.side)
        speed = np.abs(rt.hands.proximal_speed(rt.data, self.side))
        settled = bool(np.all((speed < STALL_SPEED) | (prox > CLOSED)))
        if not settled:
            self.stall_since = None
            return None
        if self.stall_since is None:
            self.stall_since = rt.motion_time
            return None
        if rt.motion_time - self.stall_since < GRASP_SETTLE:
            return None
        if bool(np.all(prox > CLOSED)):
            return ended(rt, self.name, False, "no contact")
        touch = rt.touching(self.side)
        if not touch:
            return ended(rt, self.name, False, "no contact")
        body = max(touch, key=lambda b: touch[b])
        rt.held[self.side] = body
        rt.loads.grasped(self.side, body, rt.grip(self.side), rt.data.xipos[body], self.load)
        rt.lost_cycles[self.side] = 0
        return ended(rt, self.name, True)


class ReleasePrimitive:
    """Open the hand to ``opening`` (proximal, rad; distal = opening / 3)."""

    name = "release"

    def __init__(self, cmd: Release) -> None:
        self.side = cmd.arm.value
        self.opening = float(cmd.opening)
        self.t0 = 0.0

    def start(self, rt: Runtime) -> Result | None:
        rt.hands.command(self.side, self.opening)
        rt.held[self.side] = None
        self.t0 = rt.motion_time
        return None

    def step(self, rt: Runtime) -> Result | None:
        t = rt.motion_time - self.t0
        prox = rt.hands.proximal(rt.data, self.side)
        if rt.hands.ramp_done(self.side) and bool(np.all(np.abs(prox - self.opening) < 0.05)):
            return ended(rt, self.name, True)
        if t > RELEASE_TIMEOUT:
            return ended(rt, self.name, False, "timeout")
        return None


def look_angles(rt: Runtime, point: Array) -> tuple[Array, Array]:
    """Pan and tilt (rad, shape (2,)) that aim the head camera at ``point`` (world, m) with the
    torso where it is now, and the same clipped to the head joints' limits."""
    base = rt.data.xpos[rt.head_pan_body]
    angle = float(rt.data.qpos[rt.torso_qadr])
    c, s = math.cos(angle), math.sin(angle)
    dx, dy, dz = (float(x) for x in point - base)
    x, y = c * dx + s * dy, -s * dx + c * dy  # in the torso frame (turned about z)
    wanted = np.array([math.atan2(y, x), math.atan2(-(dz - 0.048 - CAMERA_HEIGHT), math.hypot(x, y))])
    return wanted, np.clip(wanted, rt.head_range[:, 0], rt.head_range[:, 1])


class LookAtPrimitive:
    """Pan and tilt the head so that the camera looks at ``point`` (world); the head keeps
    looking at it while the torso turns (``Runtime.gaze``, followed by MoveJoints)."""

    name = "look_at"

    def __init__(self, cmd: LookAt) -> None:
        self.point = np.array(cmd.point, dtype=float)
        self.t0 = 0.0
        self.target = np.zeros(2)

    def start(self, rt: Runtime) -> Result | None:
        wanted, self.target = look_angles(rt, self.point)
        if np.max(np.abs(self.target - wanted)) > 0.05:
            return ended(rt, self.name, False, "unreachable")
        rt.head_target = self.target.copy()
        rt.gaze = self.point.copy()
        self.t0 = rt.motion_time
        return None

    def step(self, rt: Runtime) -> Result | None:
        q = rt.data.qpos[rt.head_qadr]
        if np.max(np.abs(q - self.target)) < HEAD_TOL:
            return ended(rt, self.name, True)
        if rt.motion_time - self.t0 > HEAD_TIMEOUT:
            return ended(rt, self.name, False, "timeout")
        return None


class WaitPrimitive:
    """Hold the current setpoints for ``duration`` seconds."""

    name = "wait"

    def __init__(self, cmd: Wait) -> None:
        self.duration = float(cmd.duration)
        self.t0 = 0.0

    def start(self, rt: Runtime) -> Result | None:
        self.t0 = rt.motion_time
        for side in SIDES:
            rt.ctrl.arm[side].twist = np.zeros(6)
        return None

    def step(self, rt: Runtime) -> Result | None:
        if rt.motion_time - self.t0 >= self.duration - 1e-9:
            return ended(rt, self.name, True)
        return None


class ObservePrimitive:
    """End at once with what an Observe needs (the loop never renders or fits):
    with the camera (``rt.observe_by_camera``) a ``WorldCapture`` of the world
    now (a copy of ``qpos``, ≈ 1.4 kB), which the host turns into the camera's Observation
    outside the loop (velma/executor/delivery.py); with ``ROCO_PERCEPTION=truth`` the ground
    truth's Observation (velma/executor/ground_truth.py; for tests, named as such)."""

    name = "observe"

    def __init__(self, cmd: Observe) -> None:
        self.objects = tuple(cmd.objects)

    def start(self, rt: Runtime) -> Result | None:
        if rt.observe_by_camera:
            return WorldCapture.of(self.objects, rt.time, rt.data.qpos)
        return rt.ground_truth.observe(rt.data, self.objects)

    def step(self, rt: Runtime) -> Result | None:  # pragma: no cover - never reached
        return self.start(rt)


def held_axis(rt: Runtime, side: str) -> Array | None:
    """The axis (its body's z, unit (3,), world) of the object ``side``'s hand holds, taken
    with the grip at its Cartesian setpoint (a payload's sag not counted); None when the hand
    holds nothing or the arm is not in Cartesian impedance."""
    body, cmd = rt.held[side], rt.ctrl.arm[side]
    if body is None or cmd.mode != "cart":
        return None
    grip = rt.grip(side).rotation
    z: Array = cmd.pose.rotation @ (grip.T @ rt.data.xmat[body].reshape(3, 3)[:, 2])
    return z


PRIMITIVES: dict[type, Callable[[Any], Primitive]] = {
    MoveTool: MoveToolPrimitive,
    MoveJoints: MoveJointsPrimitive,
    Grasp: GraspPrimitive,
    Release: ReleasePrimitive,
    LookAt: LookAtPrimitive,
    Tilt: TiltPrimitive,
    Observe: ObservePrimitive,
    Wait: WaitPrimitive,
}
"""The primitive class of each L_EX command type, a table: a new command adds its row
(docs/executor.md, "Adding a robot primitive")."""


def make_primitive(command: ExecutorCommand) -> Primitive:
    """The primitive that executes ``command`` (``PRIMITIVES``). Raises TypeError for a command
    with no row in ``PRIMITIVES``."""
    make = PRIMITIVES.get(type(command))
    if make is None:
        raise TypeError(f"not an executor command: {type(command).__name__}")
    return make(command)
