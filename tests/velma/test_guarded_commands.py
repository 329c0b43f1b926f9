"""Two robot-side checks of the hand's whereabouts, in the physics (the jar with its content,
seed 0, in the left hand):

- a guarded MoveTool (L_EX ``MoveTool.guard``) that lowers the held jar towards a target
  below where the jar meets its shelf (the hand holds it lower than planned) ends ``ok`` on
  the contact, the jar resting on the shelf and the arm not pushing on; the same move
  unguarded pushes on and times out short; a guarded lower that meets nothing ends as before.
  The wrist F/T readings these moves see are what ``SET_DOWN_GUARD_N`` was chosen from;
- a Grasp given the grasp pose (``Grasp.at``) fails at once, its fingers unmoved, when the
  hand is elsewhere (``NOT_AT_GRASP_POSE``), and closes as before when the hand is there.

The guarded move runs on both cycles: the compiled plant and the Python one (the primitive
reads the F/T sensor from the same ``mjData`` either way)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from services.agents.planner.domain import SET_DOWN_GUARD_N
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    NOT_AT_GRASP_POSE,
    Arm,
    CommandResult,
    Grasp,
    MoveTool,
    Observe,
    Release,
)
from shared.fipa_codec.languages.l_sd import Observation
from velma.control.compiled import make_controller
from velma.control.robot_model import RobotModel
from velma.executor import checkpoint as ck
from velma.executor.plant import plant_unavailable
from velma.executor.primitives import POS_TOL, make_primitive
from velma.executor.runtime import Runtime
from velma.scenario import JAR_LOAD, script_poses

PLANTS = ["compiled", "python"] if plant_unavailable(make_controller(RobotModel())) is None else ["python"]
DEFAULT = PLANTS[0]
LIFT_M = 0.04
"""How high the grasped jar is lifted above its shelf before it is set down again (m)."""
BELOW_M = 0.02
"""How far below where the jar meets its shelf the set-down's target is (m): the hand holds
the jar this much lower than the plan thinks."""
NOISE_LIMIT_N = SET_DOWN_GUARD_N / 5
"""The most the force resisting a lower may read while the jar meets nothing (measured
≈ 0.2 N): the guard stands well clear of it."""


@dataclass
class Rig:
    """A runtime, the checkpoints of the left hand at the jar's grasp pose (open) and of the
    jar grasped and lifted ``LIFT_M``, the grasp pose and the jar's height standing (m)."""

    rt: Runtime
    reached: bytes
    lifted: bytes
    grasp: Pose
    jar_z: float

    def restore(self, raw: bytes) -> Runtime:
        ck.apply(self.rt, ck.decode(raw, ck.fingerprint(self.rt.model)))
        return self.rt


def run(rt: Runtime, command: object, watch: list[float] | None = None) -> CommandResult:
    """Run ``command`` to its end (no cycle after it: the state is the one it ended in); with
    ``watch``, the left arm's force along −z (N, the change of ``Runtime.ft_force`` since the
    start: a surface bearing the jar) every cycle."""
    prim = make_primitive(command)  # type: ignore[arg-type]
    f0 = rt.ft_force("left").copy()
    result = prim.start(rt)
    while result is None:
        rt.cycle()
        if watch is not None:
            watch.append(float(f0[2] - rt.ft_force("left")[2]))
        result = prim.step(rt)
    assert isinstance(result, CommandResult)
    return result


def shifted(pose: Pose, dz: float) -> Pose:
    x, y, z = pose.position
    return Pose(position=(x, y, z + dz), orientation=pose.orientation)


@pytest.fixture(scope="module", params=PLANTS)
def rig(request: pytest.FixtureRequest) -> Rig:
    rt = Runtime(seed=0, compiled_plant=request.param == "compiled")
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    assert rt.plant_name == request.param
    prim = make_primitive(Observe())
    obs = prim.start(rt)
    assert isinstance(obs, Observation)
    poses = script_poses(obs)
    jar_z = float(rt.data.xpos[rt.model.body("jar").id][2])
    for command in (
        Release(arm=Arm.LEFT, opening=0.5),
        MoveTool(arm=Arm.LEFT, target=poses.jar_pregrasp, duration=3.0),
        MoveTool(arm=Arm.LEFT, target=poses.jar_grasp, duration=1.5),
    ):
        assert run(rt, command).ok, command
    reached = ck.Capture(rt).take(None)
    assert run(rt, Grasp(arm=Arm.LEFT, load=JAR_LOAD)).ok  # the plan gives a_km's mass
    assert run(rt, MoveTool(arm=Arm.LEFT, target=shifted(poses.jar_grasp, LIFT_M), duration=1.5)).ok
    return Rig(rt, reached, ck.Capture(rt).take(None), poses.jar_grasp, jar_z)


def _jar_z(rt: Runtime) -> float:
    return float(rt.data.xpos[rt.model.body("jar").id][2])


def test_a_guarded_lower_ends_on_contact_with_the_jar_resting_on_its_shelf(rig: Rig) -> None:
    rt = rig.restore(rig.lifted)
    carried, t0 = rt.ft_force("left")[2], rt.time  # N, up: the hand and the jar in the air
    target = shifted(rig.grasp, -BELOW_M)
    result = run(rt, MoveTool(arm=Arm.LEFT, target=target, duration=1.5, guard=SET_DOWN_GUARD_N))
    assert result.ok, result
    assert result.contact is not None and result.contact > SET_DOWN_GUARD_N
    assert result.reason is not None and result.reason.startswith("contact (")
    assert result.tool_error is not None and abs(result.tool_error - BELOW_M) < 0.003  # where the jar met it
    cmd, grip = rt.ctrl.arm["left"], rt.grip("left")
    assert cmd.mode == "cart" and np.allclose(cmd.pose.translation, grip.translation)  # no pushing on
    assert np.allclose(cmd.pose.rotation, grip.rotation) and not cmd.twist.any()
    assert result.sim_time - t0 < 1.5  # on the path: before its nominal end
    # the shelf bears the jar (its weight, ≈ 3 N with its content), the hand stays where it
    # stopped and pushes no more (unguarded: ≈ 22 N)
    z_hand = grip.translation[2]
    for _ in range(300):
        rt.cycle()
    assert abs(_jar_z(rt) - rig.jar_z) < 0.001
    assert abs(rt.grip("left").translation[2] - z_hand) < 0.001
    assert 0.0 < carried - rt.ft_force("left")[2] < SET_DOWN_GUARD_N
    assert rt.held["left"] == rt.model.body("jar").id


@pytest.mark.parametrize("rig", [DEFAULT], indirect=True)
def test_the_same_lower_unguarded_pushes_on_and_times_out_short(rig: Rig) -> None:
    rt = rig.restore(rig.lifted)
    forces: list[float] = []
    result = run(rt, MoveTool(arm=Arm.LEFT, target=shifted(rig.grasp, -BELOW_M), duration=1.5), forces)
    assert not result.ok and result.reason is not None and result.reason.startswith("timeout (position error")
    assert result.contact is None and result.tool_error is not None and result.tool_error > POS_TOL
    # the readings the guard was chosen from: noise until the jar meets its shelf, then far above
    readings = np.array(forces)
    touch = int(np.argmax(readings > SET_DOWN_GUARD_N))
    assert readings[touch] > SET_DOWN_GUARD_N and touch > 0
    assert readings[: touch - 1].max() < NOISE_LIMIT_N
    assert readings[-100:].mean() > 3 * SET_DOWN_GUARD_N  # the arm pushes the jar into the shelf


@pytest.mark.parametrize("rig", [DEFAULT], indirect=True)
def test_a_guarded_lower_that_meets_nothing_ends_as_before(rig: Rig) -> None:
    rt = rig.restore(rig.lifted)
    target = shifted(rig.grasp, 0.01)
    forces: list[float] = []
    result = run(rt, MoveTool(arm=Arm.LEFT, target=target, duration=1.5, guard=SET_DOWN_GUARD_N), forces)
    assert result.ok and result.reason is None and result.contact is None, result
    assert result.tool_error is not None and result.tool_error < POS_TOL
    assert max(abs(f) for f in forces) < NOISE_LIMIT_N
    rt = rig.restore(rig.lifted)
    unguarded = run(rt, MoveTool(arm=Arm.LEFT, target=target, duration=1.5))
    assert unguarded == result  # the guard changed nothing


@pytest.mark.parametrize("rig", [DEFAULT], indirect=True)
def test_a_grasp_away_from_its_grasp_pose_fails_at_once_without_closing(rig: Rig) -> None:
    rt = rig.restore(rig.reached)
    hand = rt.hands.set["left"]
    before = (hand.proximal.copy(), hand.target.copy(), rt.hands.proximal(rt.data, "left").copy())
    t0 = rt.time
    prim = make_primitive(Grasp(arm=Arm.LEFT, at=shifted(rig.grasp, 0.05)))
    result = prim.start(rt)  # at once: in the cycle the command begins
    assert isinstance(result, CommandResult), result
    assert not result.ok and result.reason == NOT_AT_GRASP_POSE and result.sim_time == t0
    assert result.tool_error is not None and abs(result.tool_error - 0.05) < 0.005
    for _ in range(500):
        rt.cycle()
    assert np.array_equal(hand.proximal, before[0]) and np.array_equal(hand.target, before[1])
    assert np.allclose(rt.hands.proximal(rt.data, "left"), before[2], atol=0.01)  # the fingers did not close
    assert rt.held["left"] is None


@pytest.mark.parametrize("rig", [DEFAULT], indirect=True)
def test_a_grasp_at_its_grasp_pose_closes_as_before(rig: Rig) -> None:
    rt = rig.restore(rig.reached)
    plain = run(rt, Grasp(arm=Arm.LEFT))
    rt = rig.restore(rig.reached)
    checked = run(rt, Grasp(arm=Arm.LEFT, at=rig.grasp))
    assert checked.ok and checked == plain
    assert rt.held["left"] == rt.model.body("jar").id
