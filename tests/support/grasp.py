"""The left hand's grasp of the jar that tests drive the
simulated robot through, as tests/velma/test_velma_control.py first did it: open the hand,
pre-grasp, reach, close on the jar; then lift it 10 cm; and the loop that runs them."""

from __future__ import annotations

from collections.abc import Callable

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    Arm,
    CommandResult,
    ExecutorCommand,
    Grasp,
    MoveTool,
    Observe,
    Release,
)
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.loop import ControlLoop
from velma.scenario import Poses, script_poses

Result = CommandResult | Observation

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


def run_command(loop: ControlLoop[int], command: ExecutorCommand, cycles: int = 20000) -> Result:
    """Submit ``command`` to ``loop`` and cycle it until the command ends (at most ``cycles``
    cycles: an AssertionError then); its result."""
    loop.submit(0, command)
    for _ in range(cycles):
        done = loop.cycle()
        if done is not None:
            return done[1]
    raise AssertionError(f"{command} did not end in {cycles} cycles")


def grasp_the_jar(run: Callable[[ExecutorCommand], Result] | ControlLoop[int]) -> Poses:
    """Observe the scene and run :func:`left_jar_grasp`, each command succeeding (else an
    AssertionError), with ``run`` (a command → its result) or on a ``ControlLoop``; the poses
    the grasp used."""
    if isinstance(run, ControlLoop):
        loop = run

        def run(command: ExecutorCommand) -> Result:
            return run_command(loop, command)

    obs = run(Observe())
    assert isinstance(obs, Observation)
    poses = script_poses(obs)
    for command in left_jar_grasp(poses):
        result = run(command)
        assert isinstance(result, CommandResult) and result.ok, (command, result)
    return poses
