"""The left hand's grasp of the jar that tests (and scripts/bench_checkpoint.py) drive the
simulated robot through, as tests/velma/test_velma_control.py first did it: open the hand,
pre-grasp, reach, close on the jar; then lift it 10 cm."""

from __future__ import annotations

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Arm, ExecutorCommand, Grasp, MoveTool, Release
from velma.scenario import Poses

LIFT_M = 0.1


def left_jar_grasp(poses: Poses) -> tuple[ExecutorCommand, ...]:
    """The commands, in order, that leave the jar in the closed left hand."""
    return (
        Release(arm=Arm.LEFT, opening=0.5),
        MoveTool(arm=Arm.LEFT, target=poses.jar_pregrasp, duration=3.0),
        MoveTool(arm=Arm.LEFT, target=poses.jar_grasp, duration=1.5),
        Grasp(arm=Arm.LEFT, spread=0.0),
    )


def left_jar_lift(poses: Poses) -> MoveTool:
    """After :func:`left_jar_grasp`: the left hand straight up by :data:`LIFT_M` in 1.5 s."""
    g = poses.jar_grasp
    up = Pose(position=(g.position[0], g.position[1], g.position[2] + LIFT_M), orientation=g.orientation)
    return MoveTool(arm=Arm.LEFT, target=up, duration=1.5)
