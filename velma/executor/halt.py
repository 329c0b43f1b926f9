"""The halt: what replaces a running primitive that a_ta cancelled (velma/executor/loop.py
``ControlLoop.cancel``; paper §3.2), or that a hold stops, and ends with ``halted``: its setpoints
brake to rest within the deceleration limits, a held container a Tilt turned is turned upright
(past the pour point the Tilt runs on to its end first), and the head and hands stay as they are.
``HaltPrimitive`` is no L_EX command; the motion primitives it brakes are in
velma/executor/primitives.py."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from shared.fipa_codec.languages.l_ex import HALTED, ExecutorCommand, Grasp, LookAt, Release, command_name
from velma.control.joints import SIDES, Array
from velma.control.trajectory import MIN_JERK_PEAK_RATE
from velma.executor.primitives import (
    UPRIGHT_TOL,
    MoveJointsPrimitive,
    Primitive,
    Result,
    TiltPrimitive,
    ended,
    held_axis,
    look_angles,
)
from velma.executor.runtime import Runtime, torso_frame

HALT_LINEAR_DECEL = 2.0
"""m/s², the peak deceleration of a grip-frame setpoint a halt brakes (chosen: a held jar's
content and friction grasp ride it out; the law stays far inside its torque limits)."""
HALT_ANGULAR_DECEL = 6.0
"""rad/s², the same for the grip frame's rotation."""
HALT_JOINT_DECEL = 5.0
"""rad/s², the same for a joint setpoint (arms in joint or safe mode, the torso)."""
HALT_MIN_S = 0.02
"""s, the shortest braking or turning profile of a halt."""
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
        return ended(rt, command_name(self.command), False, HALTED)
