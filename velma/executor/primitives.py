"""The executor's motion primitives, one per L_EX command (paper §5.3, ag_ex).

Each primitive is a small state machine driven by the loop thread: ``start`` is called once
in the cycle the command begins, ``step`` every cycle after that; either returns the result
(``CommandResult``; for Observe a ``WorldCapture`` for the camera, or with
``ROCO_PERCEPTION=truth`` the ground truth's ``Observation``) to end the command, or None.

Failure reasons: ``unreachable`` (IK finds no arm configuration, a joint target outside its
limits, a look-at point outside the neck's range), ``timeout`` (not converged in time;
MoveTool, Tilt and MoveJoints add in parentheses by how much and MoveJoints what the hands
touch),
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
from typing import Any, NamedTuple, Protocol

import numpy as np
import pinocchio as pin

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    HALTED,
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
    command_name,
)
from shared.fipa_codec.languages.l_sd import Observation
from velma.control.hand import PROXIMAL_MAX, STALL_SPEED
from velma.control.ik import IkSearch
from velma.control.impedance import DEFAULT_CART_STIFFNESS
from velma.control.joints import HEAD_JOINTS, SIDES, TORSO_JOINT, Array, arm_joints
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
ROT_TOL = 0.1  # rad; a held payload (not gravity-compensated) sags the wrist by up to ~0.08 rad
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
HALT_LINEAR_DECEL = 2.0
"""m/s², the peak deceleration of a grip-frame setpoint a halt brakes (chosen: a held jar's
content and friction grasp ride it out; the law stays far inside its torque limits)."""
HALT_ANGULAR_DECEL = 6.0
"""rad/s², the same for the grip frame's rotation."""
HALT_JOINT_DECEL = 5.0
"""rad/s², the same for a joint setpoint (arms in joint or safe mode, the torso)."""
HALT_MIN_S = 0.02
"""s, the shortest braking or turning profile of a halt."""
UPRIGHT_TOL = 0.05
"""rad: a held object that a Tilt turned (``Runtime.tilt_about``) and whose axis, with the grip
at its setpoint, leans further from the vertical is turned upright by a halt (a payload's sag,
≤ ≈ 0.08 rad, is not counted: the axis is taken with the grip at its setpoint, not where the
payload pulls it)."""
UPRIGHT_UNKNOWN_TOL = 0.35
"""rad: the same for a held object no Tilt is known to have turned (after a restart of ag_ex:
``tilt_about`` is not in a checkpoint), which a halt turns about the horizontal through the
grip: only a lean that no grasp's slip explains."""
UPRIGHT_RATE = 1.5
"""rad/s, the peak rate of a halt's turn upright (the pour's own tilt back: 2.3 rad in 3 s,
peak 1.44 rad/s; velma/scenario.py)."""
UPRIGHT_ACCEL = 10.0
"""rad/s², the angular acceleration of a halt's turn upright: the tilt is braked within a few
degrees, before the content that slides in the jar reaches its mouth. (Braked at 1.5–3 rad/s²,
the jar tilts on by 10–20°, stops where its content pours out short of the bowl, and 1–4 of
the 18 spheres land outside: measured on velma/scenario.py's pour, seed 0.)"""
POUR_POINT = 1.4
"""rad: the lean (about the Tilt's axis) of a held container past which a halt no longer turns
it back at once. Standing still past ≈ 1.5 rad (87°) the jar loses its content, short of the
bowl; turned back at once from 1.6–1.8 rad, 2–8 of the 18 spheres flew out of the bowl
(measured on velma/scenario.py's pour, seed 0). So where the brake would stop the lean at or
past this point, the running Tilt goes on along its path to its planned end — the plan aimed
it so that what leaves the jar falls into the target — and the turn upright follows after
``HALT_RUN_OUT``. tests/velma/test_halt.py halts the pour on either side of it."""
HALT_RUN_OUT = 1.0
"""s a halt that ran a Tilt on to its end past ``POUR_POINT`` keeps the jar there before it
turns it upright, for the content still on its way out to leave, as the plan's own wait does
(the pour's let_run_out, 2.5 s). Chosen: turned at once, the content of velma/scenario.py's
pour had left (the last sphere ≈ 0.6 s before the tilt's end), but in one of 16 loaded runs of
scenario tilt_interrupted a sphere still in the jar was thrown 4 m."""


class Primitive(Protocol):
    """One running command."""

    def start(self, rt: Runtime) -> Result | None: ...

    def step(self, rt: Runtime) -> Result | None: ...


def _result(
    rt: Runtime, name: str, ok: bool, reason: str | None = None, err: float | None = None
) -> CommandResult:
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
            return _result(
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
            return _result(rt, self.name, False, "contact lost", self._perr(rt))
        if t >= self.duration:
            cmd.twist = np.zeros(6)
            perr = self._perr(rt)
            rerr = rotation_error(rt.grip(self.side).rotation, self.goal.rotation)
            if perr < POS_TOL and rerr < ROT_TOL:
                return _result(rt, self.name, True, None, perr)
            if t >= self.duration + SETTLE_TIMEOUT:
                reason = f"timeout (position error {perr * 1000:.1f} mm, rotation error {rerr:.3f} rad)"
                return _result(rt, self.name, False, reason, perr)
        return None

    def _perr(self, rt: Runtime) -> float:
        return float(np.linalg.norm(rt.grip(self.side).translation - self.goal.translation))


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
            return _result(rt, self.name, False, str(exc))
        limit = self.cmd.guard
        if limit is not None and not limit > 0.0:
            return _result(rt, self.name, False, "invalid guard")
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
            return _result(rt, self.name, False, "zero axis")
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
                return _result(rt, self.name, False, f"unknown joint: {name}")
            if not model.lowerPositionLimit[i] <= value <= model.upperPositionLimit[i]:
                return _result(rt, self.name, False, "unreachable")
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
                return _result(rt, self.name, False, f"unknown joint: {name}")
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
            return _result(rt, self.name, True)
        if t >= self.duration + SETTLE_TIMEOUT:
            return _result(rt, self.name, False, self._timeout_reason(rt))
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
            held = rt.held[side]
            held_name = rt.model.body(held).name if held is not None else None
            touched = sorted(
                {
                    name
                    for name in (rt.model.body(b).name for b in rt.touch[side])
                    if held_name is None or not (name == held_name or name.startswith(f"{held_name}_"))
                }
            )
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
        self.phase = "spread"
        self.t0 = 0.0
        self.stall_since: float | None = None

    def start(self, rt: Runtime) -> Result | None:
        if self.at is not None:
            if self.at.frame != "world":
                return _result(rt, self.name, False, f"unknown frame: {self.at.frame}")
            expected = np.array(self.at.position, dtype=float)
            away = float(np.linalg.norm(rt.grip(self.side).translation - expected))
            if not away <= self.tolerance:
                return _result(rt, self.name, False, NOT_AT_GRASP_POSE, away)
        hs = rt.hands.set[self.side]
        rt.hands.command(self.side, float(np.max(hs.proximal)), self.spread)
        self.t0 = rt.motion_time
        return None

    def step(self, rt: Runtime) -> Result | None:
        t = rt.motion_time - self.t0
        if t > GRASP_TIMEOUT:
            return _result(rt, self.name, False, "timeout")
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
            return _result(rt, self.name, False, "no contact")
        touch = rt.touching(self.side)
        if not touch:
            return _result(rt, self.name, False, "no contact")
        body = max(touch, key=lambda b: touch[b])
        rt.held[self.side] = body
        rt.lost_cycles[self.side] = 0
        return _result(rt, self.name, True)


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
            return _result(rt, self.name, True)
        if t > RELEASE_TIMEOUT:
            return _result(rt, self.name, False, "timeout")
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
            return _result(rt, self.name, False, "unreachable")
        rt.head_target = self.target.copy()
        rt.gaze = self.point.copy()
        self.t0 = rt.motion_time
        return None

    def step(self, rt: Runtime) -> Result | None:
        q = rt.data.qpos[rt.head_qadr]
        if np.max(np.abs(q - self.target)) < HEAD_TOL:
            return _result(rt, self.name, True)
        if rt.motion_time - self.t0 > HEAD_TIMEOUT:
            return _result(rt, self.name, False, "timeout")
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
            return _result(rt, self.name, True)
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


def brake(t: float, duration: float) -> tuple[float, float]:
    """A setpoint moving at unit speed, braked to rest over ``duration`` (s) with the speed
    falling as 1 − s(t/duration), s the minimum-jerk phase (``min_jerk``): the distance (m per
    m/s, or rad per rad/s) it has gone ``t`` s after the brake began and its speed factor
    (1 → 0). It ends ``duration``/2 on; the peak deceleration is
    ``MIN_JERK_PEAK_RATE``·speed/``duration``, and none at the start or the end."""
    if duration <= 0.0 or t >= duration:
        return 0.5 * max(duration, 0.0), 0.0
    if t <= 0.0:
        return 0.0, 1.0
    x = t / duration
    x4 = x**4
    return duration * (x - 2.5 * x4 + 3.0 * x4 * x - x4 * x * x), 1.0 - x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


def _brake_time(speed: float, decel: float) -> float:
    """s to brake ``speed`` (m/s or rad/s) to rest with a peak deceleration ``decel``."""
    return max(HALT_MIN_S, MIN_JERK_PEAK_RATE * speed / decel)


class _Turn:
    """An arm's halt that turns what it holds upright: its grip setpoint turns about the unit
    ``axis`` (3,) through ``pivot`` (3,, m, world) from ``start``, from the rate ``rate``
    (rad/s) it had about that axis to rest ``angle`` rad further, as fast as ``UPRIGHT_ACCEL``
    and ``UPRIGHT_RATE`` let it (a trapezoidal rate: the tilt's rate braked at once, the turn
    at the peak rate, then braked to rest; a rate above ``UPRIGHT_RATE`` towards upright is
    kept, not raised)."""

    def __init__(self, start: pin.SE3, axis: Array, pivot: Array, rate: float, angle: float) -> None:
        self.axis, self.pivot, self.rate, self.total = axis, pivot, rate, angle
        self.lever = start.translation - pivot
        self.r0 = start.rotation
        a = UPRIGHT_ACCEL
        stop = rate * abs(rate) / (2.0 * a)  # rad the tilt goes on while braked at once
        self.sense = 1.0 if angle >= stop else -1.0
        reach = self.sense * angle  # ≥ the braking distance of the rate in this sense
        ahead = self.sense * rate  # the rate towards the goal (negative: away from it)
        cap = max(UPRIGHT_RATE, ahead)
        peak = math.sqrt(max(0.0, (rate * rate + 2.0 * a * reach) / 2.0))
        cruise = 0.0
        if peak > cap:
            peak = cap
            cruise = (reach - (2.0 * peak * peak - rate * rate) / (2.0 * a)) / peak
        self.peak = self.sense * peak
        self.t1 = abs(self.peak - rate) / a  # to the peak rate
        self.t2 = self.t1 + max(0.0, cruise)  # at it
        self.duration = max(HALT_MIN_S, self.t2 + peak / a)  # braked to rest

    def angle(self, t: float) -> tuple[float, float]:
        """The angle turned (rad) and the rate (rad/s) ``t`` s into the turn."""
        a = UPRIGHT_ACCEL
        up = a if self.peak >= self.rate else -a
        t1 = min(t, self.t1)
        theta, rate = self.rate * t1 + 0.5 * up * t1 * t1, self.rate + up * t1
        if t > self.t1:
            t2 = min(t, self.t2) - self.t1
            theta, rate = theta + self.peak * t2, self.peak
        if t > self.t2:
            t3 = min(t - self.t2, abs(self.peak) / a)
            theta += self.peak * t3 - 0.5 * self.sense * a * t3 * t3
            rate = self.peak - self.sense * a * t3
        return theta, rate

    def share(self, t: float) -> float:
        """How much of the turn (0 → 1) is done ``t`` s into it; 0 while a braked tilt still
        leans further."""
        if abs(self.total) < 1e-9:
            return 1.0
        return min(1.0, max(0.0, self.angle(t)[0] / self.total))

    def sample(self, t: float) -> tuple[pin.SE3, Array]:
        """The grip setpoint and its world twist (6,) ``t`` s into the turn."""
        theta, rate = self.angle(t)
        turn = pin.exp3(self.axis * theta)
        lever = turn @ self.lever
        omega = self.axis * rate
        return pin.SE3(turn @ self.r0, self.pivot + lever), np.concatenate((np.cross(omega, lever), omega))


class Upright(NamedTuple):
    """How a halt turns a held object upright (``upright_turn``): about the unit ``axis``
    (3,) through ``pivot`` (3,, m; world) by ``angle`` rad (signed, about ``axis``)."""

    axis: Array
    pivot: Array
    angle: float


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


def upright_turn(rt: Runtime, side: str) -> Upright | None:
    """How to turn the object ``side``'s hand holds upright: the axis, pivot and angle that
    bring its axis (its body's z) nearest the vertical, taken with the grip at its Cartesian
    setpoint; None when the hand holds nothing, the arm is not in Cartesian impedance, or the
    axis leans less than ``UPRIGHT_TOL``. About the axis and pivot of the Tilt that tipped it
    (``Runtime.tilt_about``: back the way it came, its lip over where it poured), else, when it
    leans more than ``UPRIGHT_UNKNOWN_TOL``, about the horizontal axis through the grip's
    setpoint."""
    z = held_axis(rt, side)
    if z is None:
        return None
    cmd = rt.ctrl.arm[side]
    about = rt.tilt_about[side]
    if z[2] >= math.cos(UPRIGHT_TOL if about is not None else UPRIGHT_UNKNOWN_TOL):
        return None
    if about is not None:
        axis, pivot = about
    else:
        across = np.cross(z, np.array([0.0, 0.0, 1.0]))
        if np.linalg.norm(across) < 1e-9:
            return None  # upside down: no horizontal axis is better than another
        axis, pivot = across / np.linalg.norm(across), cmd.pose.translation
    # z turned by φ about the axis: its height is (z·a)a_z + cos φ (z − (z·a)a)_z + sin φ (a × z)_z
    across_z = float(np.cross(axis, z)[2])
    along_z = float(z[2] - (z @ axis) * axis[2])
    return Upright(axis, pivot, math.atan2(across_z, along_z))


def _pouring(halted: Primitive | None, side: str, upright: Upright, twist: Array) -> bool:
    """``halted`` is ``side``'s Tilt on its path, leaning what it holds further, and a brake at
    ``UPRIGHT_ACCEL`` would stop the lean (about the tilt's axis) at or past ``POUR_POINT``."""
    if not isinstance(halted, TiltPrimitive) or halted.side != side or halted.path is None:
        return False
    away = -float(twist[3:] @ upright.axis) * math.copysign(1.0, upright.angle)  # rad/s, leaning further
    return away > 0.0 and abs(upright.angle) + away * away / (2.0 * UPRIGHT_ACCEL) >= POUR_POINT


class HaltPrimitive:
    """The running command, halted: a_ta cancelled it (velma/executor/loop.py
    ``ControlLoop.cancel``; paper §3.2, FIPA SC00026 §2). Started in the cycle the cancel
    reaches the loop, it ends with ``halted`` (L_EX ``HALTED``) once every setpoint is at rest:

    - each arm's and the torso's setpoint stops where the commanded motion had brought it:
      its velocity falls to zero along ``brake`` (peak deceleration ``HALT_LINEAR_DECEL``,
      ``HALT_ANGULAR_DECEL``, ``HALT_JOINT_DECEL``) while the setpoint goes on with it, so
      neither the impedance law's spring nor its damping jumps; arms a torso turn carries keep
      their pose relative to the torso;
    - an arm holding an object that leans (``upright_turn``: mid-pour) turns it upright instead,
      about the tilt's own axis and pivot, the tilt's rate braked as the turn begins
      (``_Turn``): the jar's mouth rises before its content reaches it. A Tilt that has leant
      the jar so far that its content may be leaving (``POUR_POINT``) first runs on to its
      planned end, so that what leaves falls where the plan aimed it, waits ``HALT_RUN_OUT``
      there and then turns it upright;
      along the turn the null-space posture goes back to the one before the tilt
      (``Runtime.upright_posture``), so the arm ends on the elbow it stood on;
    - the neck stops where its setpoint is (or keeps the gaze of a LookAt while the torso
      brakes); a halted grasp or release keeps the hand as it is (``Hands.keep``); other
      hands keep their grip.
    """

    name = "halt"

    def __init__(self, command: ExecutorCommand, halted: Primitive | None = None) -> None:
        """Halt ``command``, whose primitive ``halted`` was running (None: it never started:
        the robot is halted as it stands)."""
        self.command = command
        self.halted = halted
        self.t0 = 0.0
        self.duration = HALT_MIN_S
        self.cart: dict[str, tuple[Array, Array, Array, Array, float]] = {}
        """Per braked Cartesian arm: start position (m), rotation, linear (m/s) and angular
        (rad/s) velocity, braking time (s)."""
        self.turns: dict[str, tuple[_Turn, float]] = {}
        """Per arm turning what it holds upright: the turn and when it begins (s into the halt)."""
        self.postures: dict[str, tuple[Array, Array]] = {}
        """Per turning arm whose posture before the tilt is known (``Runtime.upright_posture``):
        its null-space posture as the turn begins and that one, reached as the turn ends."""
        self.finishing: dict[str, TiltPrimitive] = {}
        """Per arm pouring past ``POUR_POINT``: the Tilt that runs to its end before the turn."""
        self.joints: dict[str, tuple[Array, Array, float]] = {}
        """Per braked joint-space arm: start (7,) rad, velocity (7,) rad/s, braking time (s)."""
        self.torso = (0.0, 0.0, HALT_MIN_S)
        self.carried: dict[str, pin.SE3] = {}
        self.follow_gaze = False

    def start(self, rt: Runtime) -> Result | None:
        self.t0 = rt.motion_time
        ctrl = rt.ctrl
        if isinstance(self.halted, MoveJointsPrimitive):
            self.carried = dict(self.halted.carried)
        ends = [HALT_MIN_S]
        for side in SIDES:
            cmd = ctrl.arm[side]
            if side in self.carried:
                continue
            if cmd.mode == "cart":
                upright = upright_turn(rt, side)
                if upright is not None and _pouring(self.halted, side, upright, cmd.twist):
                    assert isinstance(self.halted, TiltPrimitive)
                    self.finishing[side] = self.halted
                    continue
                if upright is not None:
                    rate = float(cmd.twist[3:] @ upright.axis)
                    turn = _Turn(cmd.pose.copy(), upright.axis, upright.pivot, rate, upright.angle)
                    self.turns[side] = (turn, 0.0)
                    self._posture_back(rt, side)
                    ends.append(turn.duration)
                    continue
                v, w = cmd.twist[:3].copy(), cmd.twist[3:].copy()
                t = max(
                    _brake_time(float(np.linalg.norm(v)), HALT_LINEAR_DECEL),
                    _brake_time(float(np.linalg.norm(w)), HALT_ANGULAR_DECEL),
                )
                self.cart[side] = (cmd.pose.translation, cmd.pose.rotation, v, w, t)
            else:
                qd = np.array(cmd.qd, dtype=float)
                t = _brake_time(float(np.max(np.abs(qd))), HALT_JOINT_DECEL)
                self.joints[side] = (np.array(cmd.q, dtype=float), qd, t)
            ends.append(t)
        qd_torso = float(ctrl.torso_qd)
        self.torso = (float(ctrl.torso_q), qd_torso, _brake_time(abs(qd_torso), HALT_JOINT_DECEL))
        ends.append(self.torso[2])
        self.duration = max(ends)
        if self.halted is not None and isinstance(self.command, LookAt):
            rt.gaze = None  # the head stops short of the point: it keeps no gaze on it
        self.follow_gaze = rt.gaze is not None and qd_torso != 0.0
        if not self.follow_gaze:
            rt.head_target = rt.head_set.copy()
        if self.halted is not None and isinstance(self.command, Grasp | Release):
            rt.hands.keep(self.command.arm.value)
        return None

    def _posture_back(self, rt: Runtime, side: str) -> None:
        """Bring ``side``'s null-space posture back along its turn upright to the one it had
        before the tilt, when known (``Runtime.upright_posture``): on the tilted pose's elbow
        the arm would end elsewhere, and the IK of the next moves, seeded there, stay on it."""
        upright = rt.upright_posture[side]
        if upright is not None and rt.tilt_about[side] is not None:
            self.postures[side] = (np.array(rt.ctrl.arm[side].posture, dtype=float), upright.copy())

    def step(self, rt: Runtime) -> Result | None:
        t = rt.motion_time - self.t0
        ctrl = rt.ctrl
        for side, (p0, r0, v, w, duration) in self.cart.items():
            b, f = brake(t, duration)
            cmd = ctrl.arm[side]
            cmd.pose = pin.SE3(pin.exp3(w * b) @ r0, p0 + v * b)
            cmd.twist = np.concatenate((v * f, w * f))
        for side, tilt in list(self.finishing.items()):
            if tilt.follow(rt) < tilt.duration:
                continue
            del self.finishing[side]  # at the tilt's end, at rest: turn upright from here
            upright = upright_turn(rt, side)
            if upright is not None:
                turn = _Turn(ctrl.arm[side].pose.copy(), upright.axis, upright.pivot, 0.0, upright.angle)
                self.turns[side] = (turn, t + HALT_RUN_OUT)
                self._posture_back(rt, side)
                self.duration = max(self.duration, t + HALT_RUN_OUT + turn.duration)
        for side, (turn, begin) in self.turns.items():
            if t >= begin:
                cmd = ctrl.arm[side]
                cmd.pose, cmd.twist = turn.sample(t - begin)
                if side in self.postures:
                    p0, p1 = self.postures[side]
                    cmd.posture = p0 + turn.share(t - begin) * (p1 - p0)
        for side, (q0, qd, duration) in self.joints.items():
            b, f = brake(t, duration)
            cmd = ctrl.arm[side]
            cmd.q = q0 + qd * b
            cmd.qd = qd * f
        a, qd_torso, duration = self.torso
        if qd_torso != 0.0:
            b, f = brake(t, duration)
            ctrl.torso_q = a + qd_torso * b
            ctrl.torso_qd = qd_torso * f
            frame = torso_frame(ctrl.torso_q)
            for side, rel in self.carried.items():
                ctrl.arm[side].pose = frame.act(rel)
                ctrl.arm[side].twist = np.zeros(6)
            if self.follow_gaze and rt.gaze is not None:
                rt.head_target = look_angles(rt, rt.gaze)[1]
        if t < self.duration or self.finishing:
            return None
        return _result(rt, command_name(self.command), False, HALTED)


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
