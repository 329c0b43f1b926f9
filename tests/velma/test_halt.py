"""A cancel halts the running command (velma/executor/loop.py ``ControlLoop.cancel``,
velma/executor/halt.py ``HaltPrimitive``): a queued one ends at once, a running motion
brakes to rest within a bounded distance, a second cancel changes nothing, an ended command
cannot be cancelled; and a pour halted at any moment spills nothing — every sphere of the
jar's content ends in the jar or in the bowl, the jar upright in the hand. A hold (ag_ex lost
a_ta: ``ControlLoop.hold``) brings the motion to rest the same way before it holds in joint
impedance: stopped dead half-way through the tilt, at the lean where the content runs out,
the jar poured 1–3 spheres short of the bowl and off the table (scenario tilt_interrupted
under load).

Everything runs the loop in this thread, cycle by cycle (no clock, no sleeps): the simulated
time is the loop's own."""

from __future__ import annotations

import math

import numpy as np
import pytest

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    HALTED,
    Arm,
    CommandResult,
    ExecutorCommand,
    Grasp,
    MoveJoints,
    MoveTool,
    Observe,
    Tilt,
    Wait,
)
from shared.fipa_codec.languages.l_sd import Observation
from velma.control.trajectory import MIN_JERK_PEAK_RATE
from velma.executor import checkpoint as ck
from velma.executor.capture import WorldCapture
from velma.executor.halt import HALT_LINEAR_DECEL, POUR_POINT, HaltPrimitive
from velma.executor.loop import ControlLoop
from velma.executor.runtime import Runtime
from velma.rotations import quat_wxyz
from velma.scenario import SHORT_MOVE, pour_script

Result = CommandResult | Observation


def _loop() -> ControlLoop[int]:
    rt = Runtime()
    rt.observe_by_camera = False  # the ground truth: these tests are about motion
    return ControlLoop(rt)


def _run(loop: ControlLoop[int], command: ExecutorCommand, token: int = 0, limit_s: float = 30.0) -> Result:
    """Run ``command`` to its end; its result."""
    loop.submit(token, command)
    return _until_done(loop, token, limit_s)


def _until_done(loop: ControlLoop[int], token: int, limit_s: float = 30.0) -> Result:
    for _ in range(round(limit_s * 1000)):
        done = loop.cycle()
        if done is not None:
            assert done[0] == token, done
            assert not isinstance(done[1], WorldCapture), done
            return done[1]
    raise AssertionError(f"command {token} did not end in {limit_s} s of simulated time")


def _cycles(loop: ControlLoop[int], seconds: float) -> None:
    for _ in range(round(seconds * 1000)):
        assert loop.cycle() is None, "no command was to end here"


def _left_move(rt: Runtime, dz: float, duration: float) -> MoveTool:
    """The left grip straight up by ``dz`` (m) from where it is, in ``duration`` s."""
    grip = rt.grip("left")
    p = grip.translation
    return MoveTool(
        arm=Arm.LEFT,
        target=Pose((float(p[0]), float(p[1]), float(p[2] + dz)), quat_wxyz(grip.rotation)),
        duration=duration,
    )


def test_a_queued_command_ends_at_once_halted_and_the_running_one_goes_on() -> None:
    loop = _loop()
    loop.submit(1, Wait(duration=0.5))
    loop.submit(2, Wait(duration=0.5))
    _cycles(loop, 0.1)
    assert loop.current is not None and loop.current[0] == 1
    ended = loop.cancel(2)
    assert ended is not None and [t for t, _ in ended] == [2]
    (result,) = (r for _, r in ended)
    assert (result.command, result.ok, result.reason) == ("wait", False, HALTED)
    assert not loop.queue
    first = _until_done(loop, 1)
    assert isinstance(first, CommandResult) and first.ok  # not halted: only 2 was cancelled
    assert loop.cancel(2) is None  # it has ended


def test_a_running_move_brakes_to_rest_within_its_braking_distance() -> None:
    loop = _loop()
    rt = loop.rt
    move = _left_move(rt, 0.25, 1.5)  # peak speed 1.875 × 0.25 m / 1.5 s ≈ 0.31 m/s
    loop.submit(1, move)
    # mid-path: the IK search takes a few cycles, then the setpoint moves at about its peak
    for _ in range(700):
        assert loop.cycle() is None
    cmd = rt.ctrl.arm["left"]
    assert cmd.mode == "cart"
    speed = float(np.linalg.norm(cmd.twist[:3]))
    assert speed > 0.2, speed
    at_cancel = cmd.pose.translation.copy()
    assert loop.cancel(1) == []
    assert isinstance(loop.current[2] if loop.current else None, HaltPrimitive)
    halted_at = rt.time
    # a second cancel changes nothing: the same halt runs on
    halt = loop.current[2] if loop.current else None
    assert loop.cancel(1) == []
    assert loop.current is not None and loop.current[2] is halt
    result = _until_done(loop, 1, limit_s=2.0)
    assert isinstance(result, CommandResult)
    assert (result.command, result.ok, result.reason) == ("move_tool", False, HALTED)
    # braked along 1 − s(t/T), T = 1.875 v / a: it went T/2 · v further, at rest at the end
    brake_s = MIN_JERK_PEAK_RATE * speed / HALT_LINEAR_DECEL
    assert rt.time - halted_at <= brake_s + 0.002
    went = float(np.linalg.norm(cmd.pose.translation - at_cancel))
    assert went == pytest.approx(0.5 * brake_s * speed, rel=0.05)
    assert np.allclose(cmd.twist, 0.0)
    goal = np.array(move.target.position)
    assert float(np.linalg.norm(goal - cmd.pose.translation)) > 0.05  # it stopped short of the goal
    # the arm comes to rest where its setpoint stopped
    _cycles(loop, 0.5)
    assert float(np.linalg.norm(rt.grip("left").translation - cmd.pose.translation)) < 0.01
    assert float(np.linalg.norm(rt.v()[rt.ctrl.arm_slice["left"]])) < 0.05
    assert loop.cancel(1) is None  # ended: nothing to cancel


def test_a_halted_torso_turn_brakes_and_carries_the_arms() -> None:
    loop = _loop()
    rt = loop.rt
    loop.submit(1, MoveJoints(positions={"torso_0_joint": -0.6}, duration=SHORT_MOVE))
    _cycles(loop, 0.6)
    qd = rt.ctrl.torso_qd
    assert abs(qd) > 0.2, qd
    q_at = rt.ctrl.torso_q
    assert loop.cancel(1) == []
    result = _until_done(loop, 1, limit_s=1.0)
    assert isinstance(result, CommandResult) and result.reason == HALTED
    assert rt.ctrl.torso_qd == 0.0
    assert abs(rt.ctrl.torso_q - q_at) < qd * qd  # ≈ 0.94 qd² / HALT_JOINT_DECEL
    assert rt.ctrl.torso_q > -0.5  # short of the target


def test_a_halted_grasp_keeps_the_hand_as_it_is() -> None:
    loop = _loop()
    rt = loop.rt
    loop.submit(1, Grasp(arm=Arm.RIGHT, spread=0.0))
    _cycles(loop, 0.5)  # closing on nothing
    hand = rt.hands.set["right"]
    closing = hand.proximal.copy()
    assert np.all(hand.target > closing)
    assert loop.cancel(1) == []
    result = _until_done(loop, 1, limit_s=1.0)
    assert isinstance(result, CommandResult) and result.reason == HALTED
    _cycles(loop, 0.5)
    assert np.allclose(hand.proximal, closing, atol=0.01)  # it closed no further
    assert rt.held["right"] is None


# ----------------------------------------------------------------------------- mid-pour
TILT_S = 4.0
"""velma/scenario.py POUR_DURATION: the tilt's moments below are seconds from its start."""


@pytest.fixture(scope="module")
def before_tilt() -> tuple[Runtime, bytes, list[ExecutorCommand]]:
    """The experiment of velma/scenario.py run up to the pour's tilt, the jar held above the
    bowl: the world's checkpoint there and the commands from the tilt on (tilt, wait, tilt
    back)."""
    loop = _loop()
    first = _run(loop, Observe())
    assert isinstance(first, Observation)
    commands = pour_script(first)
    split = next(i for i, c in enumerate(commands) if isinstance(c, Observe) and c.objects) + 1
    placed: Result | None = None
    for command in commands[:split]:
        placed = _run(loop, command)
        assert not isinstance(placed, CommandResult) or placed.ok, (command, placed)
    assert isinstance(placed, Observation)
    bowl = next(o for o in placed.objects if o.name == "bowl").pose.position
    pour = pour_script(first, bowl_on_table=bowl)[split:]
    tilt = next(i for i, c in enumerate(pour) if isinstance(c, Tilt))
    for command in pour[:tilt]:
        result = _run(loop, command)
        assert isinstance(result, CommandResult) and result.ok, (command, result)
    return loop.rt, ck.Capture(loop.rt).take(None), pour[tilt : tilt + 3]


def _spheres(rt: Runtime) -> tuple[int, int, int]:
    """Content spheres in the jar, in the bowl, elsewhere."""
    truth = rt.ground_truth
    jar, bowl = truth.particles_inside(rt.data, "jar"), truth.particles_inside(rt.data, "bowl")
    return jar, bowl, int(truth.particle_bodies.size) - jar - bowl


def _lean(rt: Runtime, body: str = "jar") -> float:
    """How far ``body``'s axis leans from the vertical (rad)."""
    z = rt.data.xmat[rt.model.body(body).id].reshape(3, 3)[2, 2]
    return math.acos(max(-1.0, min(1.0, float(z))))


@pytest.mark.slow
@pytest.mark.parametrize(
    ("moment", "where"),
    [
        (1.5, "jar"),  # early in the tilt: back upright, the content never moved
        (2.45, "jar"),  # just short of the pour point: braked and turned back in time
        (2.9, "bowl"),  # past it, the content on its way out: the tilt ends, then upright
        (4.5, "bowl"),  # the most tilted, in the wait while the content runs out
        (7.0, "bowl"),  # tilting back
    ],
)
def test_a_pour_halted_at_any_moment_spills_nothing(
    before_tilt: tuple[Runtime, bytes, list[ExecutorCommand]], moment: float, where: str
) -> None:
    rt, saved, commands = before_tilt
    ck.apply(rt, ck.decode(saved, ck.fingerprint(rt.model)))
    loop: ControlLoop[int] = ControlLoop(rt)
    assert _spheres(rt) == (18, 0, 0)
    arm = rt.ctrl.arm_slice["left"]
    q_before = rt.q()[arm].copy()
    start = rt.time
    queue = list(enumerate(commands))
    token, command = queue.pop(0)
    loop.submit(token, command)
    while rt.time - start < moment:
        done = loop.cycle()
        if done is not None:
            assert isinstance(done[1], CommandResult) and done[1].ok, done
            token, command = queue.pop(0)
            loop.submit(token, command)
    lean_at_cancel = _lean(rt)
    assert loop.cancel(token) == []
    result = _until_done(loop, token, limit_s=6.0)
    assert isinstance(result, CommandResult) and result.reason == HALTED, result
    assert rt.held["left"] is not None, "the jar stays in the hand"
    assert _lean(rt) < 0.1, f"the jar is upright after the halt (it leant {lean_at_cancel:.2f} rad)"
    assert np.allclose(rt.ctrl.arm["left"].twist, 0.0)
    _cycles(loop, 2.0)  # the content settles
    jar, bowl, outside = _spheres(rt)
    assert outside == 0, f"halted {moment} s into the pour: {jar} in the jar, {bowl} in the bowl"
    assert (jar if where == "jar" else bowl) == 18, (jar, bowl)
    if where == "jar":
        assert lean_at_cancel < POUR_POINT
    _assert_elbow_back(rt.q()[arm], q_before)


def _assert_elbow_back(q: np.ndarray, q_before: np.ndarray) -> None:
    """The arm is back on the posture it had before the tilt (within 0.25 rad a joint), not on
    the tilted pose's elbow (0.8–1.2 rad away in four joints when the null-space posture stayed
    the tilt's): the IK of the next moves, seeded there, would keep it."""
    assert float(np.max(np.abs(q - q_before))) < 0.25, np.round(q - q_before, 2)


@pytest.mark.slow
def test_a_cancel_of_the_next_command_halts_the_robot_as_it_stands(
    before_tilt: tuple[Runtime, bytes, list[ExecutorCommand]],
) -> None:
    """Between the tilt and the wait (a_ta cancels the wait it has just sent): nothing runs,
    the wait is the next command; its halt turns the tilted jar upright."""
    rt, saved, commands = before_tilt
    ck.apply(rt, ck.decode(saved, ck.fingerprint(rt.model)))
    loop: ControlLoop[int] = ControlLoop(rt)
    tilt, wait = commands[0], commands[1]
    assert isinstance(tilt, Tilt) and isinstance(wait, Wait)
    result = _run(loop, tilt, 0)
    assert isinstance(result, CommandResult) and result.ok
    assert _lean(rt) > 2.0
    loop.submit(1, wait)
    assert loop.cancel(1) == []  # not dropped: the halt runs in its place
    assert isinstance(loop.current[2] if loop.current else None, HaltPrimitive)
    result = _until_done(loop, 1, limit_s=6.0)
    assert isinstance(result, CommandResult) and (result.command, result.reason) == ("wait", HALTED)
    assert _lean(rt) < 0.1 and rt.held["left"] is not None
    _cycles(loop, 2.0)
    assert _spheres(rt) == (0, 18, 0)


def test_a_hold_brakes_the_running_move_then_holds_in_joint_impedance() -> None:
    """ag_ex loses a_ta mid-move: the command is answered at once, but the setpoint is not
    stopped dead (a jump of its speed to zero): it goes on and brakes along the path; the arm
    switches to joint impedance once at rest, and a command sent meanwhile waits until then."""
    loop = _loop()
    rt = loop.rt
    loop.submit(1, _left_move(rt, 0.25, 1.5))
    for _ in range(700):
        assert loop.cycle() is None
    cmd = rt.ctrl.arm["left"]
    twist = cmd.twist.copy()
    speed = float(np.linalg.norm(twist[:3]))
    assert speed > 0.2, speed
    at_hold = cmd.pose.translation.copy()
    ended = loop.hold("a_ta lost")
    assert [(t, r.reason) for t, r in ended] == [(1, "held: a_ta lost")]
    assert loop.holding == "a_ta lost"
    loop.submit(2, Wait(duration=0.01))
    assert loop.cycle() is None
    assert cmd.mode == "cart"  # still braking
    assert np.allclose(cmd.twist, twist, atol=HALT_LINEAR_DECEL * 0.002)  # no jump of speed
    brake_s = MIN_JERK_PEAK_RATE * speed / HALT_LINEAR_DECEL
    for _ in range(round(brake_s * 1000) - 2):
        assert loop.cycle() is None
        assert loop.holding == "a_ta lost" and loop.queue, "the next command waits for the rest"
    _cycles_until_mode(loop, "joint", limit=10)
    went = float(np.linalg.norm(rt.ctrl.state["left"].grip.translation - at_hold))
    assert went == pytest.approx(0.5 * brake_s * speed, abs=0.01)  # braked along the path
    result = _until_done(loop, 2, limit_s=1.0)
    assert isinstance(result, CommandResult) and result.ok
    assert loop.holding is None


def _cycles_until_mode(loop: ControlLoop[int], mode: str, limit: int) -> None:
    for _ in range(limit):
        if loop.rt.ctrl.arm["left"].mode == mode:
            return
        assert loop.cycle() is None
    assert loop.rt.ctrl.arm["left"].mode == mode


@pytest.mark.slow
@pytest.mark.parametrize(
    ("moment", "where"),
    [
        (2.2, "jar"),  # short of the pour point: braked and turned back
        (2.8, "bowl"),  # ≈ 1.6 rad, where the scenario's hold stopped it and 2 spheres fell off the table
    ],
)
def test_a_pour_held_half_way_through_the_tilt_spills_nothing(
    before_tilt: tuple[Runtime, bytes, list[ExecutorCommand]], moment: float, where: str
) -> None:
    rt, saved, commands = before_tilt
    ck.apply(rt, ck.decode(saved, ck.fingerprint(rt.model)))
    loop: ControlLoop[int] = ControlLoop(rt)
    q_before = rt.q()[rt.ctrl.arm_slice["left"]].copy()
    start = rt.time
    loop.submit(0, commands[0])
    while rt.time - start < moment:
        assert loop.cycle() is None
    ended = loop.hold("a_ta lost")
    assert [(t, r.reason) for t, r in ended] == [(0, "held: a_ta lost")]
    _cycles(loop, 6.0)  # brought to rest (the tilt finished, the jar upright), the content settled
    jar, bowl, outside = _spheres(rt)
    assert outside == 0, f"held {moment} s into the pour: {jar} in the jar, {bowl} in the bowl"
    assert (jar if where == "jar" else bowl) == 18, (jar, bowl)
    assert _lean(rt) < 0.1 and rt.held["left"] is not None
    assert rt.ctrl.arm["left"].mode == "joint" and loop.holding == "a_ta lost"
    _assert_elbow_back(rt.q()[rt.ctrl.arm_slice["left"]], q_before)
