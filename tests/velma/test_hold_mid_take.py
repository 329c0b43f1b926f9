"""A hold in the middle of taking the jar out of the cabinet (chaos runs seed 4 and
seed 2: a_ta killed during fetch_jar/take/lift or take/withdraw).

The loop held position with the jar grasped and the hand still in the cabinet. The recovery
plan then turned the torso before the hand had left the cabinet: the hand and the jar were
swept along the shelf (knocking the cup off it) and finally jammed against the cabinet's side
panel, and the pour's torso turn ended with a bare ``timeout``. The hold itself leaves nothing
behind that makes later commands fail: finishing the take from where the hand holds (lift,
withdraw) lets every turn succeed with the jar carried. A joint move that stalls now says how
far it stayed and what the hands touch."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    Arm,
    CommandResult,
    Grasp,
    MoveJoints,
    MoveTool,
    Observe,
    Release,
)
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor import checkpoint as ck
from velma.executor.loop import ControlLoop
from velma.executor.runtime import Runtime
from velma.model.kitchen_mjcf import CUP_POS
from velma.scenario import JAR_LIFT, JAR_RETREAT, script_poses

Result = CommandResult | Observation
HOLD_AFTER = 85
"""Cycles of the lift before a_ta was lost (the chaos run of seed 4: 85 ms into the lift)."""
STALL_TURN = -1.2
"""rad, the torso target of the stalled turn."""


def _run(loop: ControlLoop[int], command: object) -> Result:
    loop.submit(0, command)  # type: ignore[arg-type]
    for _ in range(20000):
        done = loop.cycle()
        if done is not None:
            return done[1]
    raise AssertionError(f"{command} did not end in 20 s of simulated time")


def _ok(loop: ControlLoop[int], command: object) -> CommandResult:
    result = _run(loop, command)
    assert isinstance(result, CommandResult) and result.ok, (command, result)
    return result


def _shifted(pose: Pose, dx: float = 0.0, dz: float = 0.0) -> Pose:
    x, y, z = pose.position
    return Pose(position=(x + dx, y, z + dz), orientation=pose.orientation)


@pytest.fixture(scope="module")
def held_mid_lift() -> tuple[bytes, Pose]:
    """The world after a_ta was lost 85 ms into lifting the grasped jar (as the plan does it:
    look, open the hand, pre-grasp, reach, grasp, lift), as a checkpoint; and the grasp pose."""
    rt = Runtime()
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    loop: ControlLoop[int] = ControlLoop(rt)
    obs = _run(loop, Observe())
    assert isinstance(obs, Observation)
    poses = script_poses(obs)
    for command in (
        Release(arm=Arm.LEFT, opening=0.5),
        MoveTool(arm=Arm.LEFT, target=poses.jar_pregrasp, duration=3.0),
        MoveTool(arm=Arm.LEFT, target=poses.jar_grasp, duration=1.5),
        Grasp(arm=Arm.LEFT, spread=0.0),
    ):
        _ok(loop, command)
    loop.submit(1, MoveTool(arm=Arm.LEFT, target=_shifted(poses.jar_grasp, dz=JAR_LIFT), duration=1.0))
    for _ in range(HOLD_AFTER):
        assert loop.cycle() is None
    ended = loop.hold("a_ta lost")
    assert [(t, r.reason) for t, r in ended] == [(1, "held: a_ta lost")]
    for _ in range(500):  # the hold's halt brakes the lift (tens of ms), then the arm holds
        loop.cycle()
        if loop.stopping is None:
            break
    for _ in range(20):
        loop.cycle()
    assert rt.ctrl.arm["left"].mode == "joint" and rt.held["left"] == rt.model.body("jar").id
    return ck.Capture(rt).take(loop.holding), poses.jar_grasp


def _restore(raw: bytes) -> tuple[Runtime, ControlLoop[int]]:
    rt = Runtime()
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    ck.apply(rt, ck.decode(raw, ck.fingerprint(rt.model)))
    loop: ControlLoop[int] = ControlLoop(rt)
    loop.holding = "a_ta lost"
    return rt, loop


def _position(rt: Runtime, body: str) -> np.ndarray:
    out: np.ndarray = rt.data.xpos[rt.model.body(body).id].copy()
    return out


def test_a_stalled_joint_move_says_how_far_and_what_the_hands_touch(
    held_mid_lift: tuple[bytes, Pose],
) -> None:
    """Turning the torso towards the table with the hand still in the cabinet (what the
    recovery plan of the chaos run did, here 0.25 rad further than its face_table turn, so
    that the jam does not hinge on how far the contacts let the bowl slide) sweeps the jar
    along the shelf until the hand jams against the bowl or the cabinet: the timeout names the
    joint, how far it stayed from its target, and what the hand touches besides the jar it
    holds."""
    rt, loop = _restore(held_mid_lift[0])
    result = _run(loop, MoveJoints(positions={"torso_0_joint": STALL_TURN}, duration=3.0))
    assert isinstance(result, CommandResult) and not result.ok
    reason = result.reason or ""
    match = re.fullmatch(
        r"timeout \(torso_0_joint ([0-9.]+) rad from its target; left hand touches ([^;]+)\)", reason
    )
    assert match is not None, reason
    assert math.isclose(float(match[1]), abs(STALL_TURN - rt.q()[rt.ctrl.torso_idx]), abs_tol=2e-3)
    touched = match[2].split(", ")
    # what the hand jams against depends on how the contacts let the jar and the bowl slide
    assert touched and set(touched) <= {"bowl", "cabinet", "cup"}, reason


def test_after_a_hold_mid_take_the_take_finishes_and_the_torso_turns_with_the_jar(
    held_mid_lift: tuple[bytes, Pose],
) -> None:
    """The commands after the hold start from where the hand holds: lift and withdraw (the
    rest of the take), then the recovery plan's turns to the table and to the pour succeed,
    the jar still in the hand and the cup untouched on the shelf."""
    raw, grasp = held_mid_lift
    rt, loop = _restore(raw)
    lifted = _shifted(grasp, dz=JAR_LIFT)
    _ok(loop, MoveTool(arm=Arm.LEFT, target=lifted, duration=1.0))
    assert loop.holding is None
    _ok(loop, MoveTool(arm=Arm.LEFT, target=_shifted(lifted, dx=-JAR_RETREAT), duration=1.5))
    _ok(loop, MoveJoints(positions={"torso_0_joint": -0.95}, duration=3.0))  # face_table
    _ok(loop, MoveJoints(positions={"torso_0_joint": -1.2}, duration=1.5))  # face_pour
    jar = rt.model.body("jar").id
    assert rt.held["left"] == jar and not rt.hold_lost("left")
    assert _position(rt, "jar")[2] > 0.87  # carried, off the shelf
    assert math.dist(_position(rt, "cup"), CUP_POS) < 2e-3
