"""Inverse kinematics of the arms (velma/control/ik.py), as the 1 kHz loop uses it."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from velma.control.compiled import compiled_available
from velma.control.ik import IkSearch, solve_ik_multi
from velma.control.joints import arm_joints
from velma.control.robot_model import RobotModel


def test_ik_search_is_resumable_and_agrees_with_solve_ik_multi() -> None:
    """The loop's IK search runs a bounded number of iterations per call and finds what the
    one-shot solver finds."""
    robot = RobotModel()
    q0 = pin.neutral(robot.model)
    q0[robot.v_indices(arm_joints("right"))] = [1.2, -1.0, 0.0, 1.6, 0.0, 1.0, 0.0]
    pin.framesForwardKinematics(robot.model, robot.data, q0)
    start = robot.data.oMf[robot.grip_frame_id["right"]].copy()
    turn = pin.exp3(np.array([0.0, 0.0, 0.6]))
    target = pin.SE3(turn @ start.rotation, start.translation + np.array([0.15, -0.2, 0.1]))
    search = IkSearch(robot, "right", target, q0)
    calls = 0
    result = None
    while result is None:
        before = search.iterations
        result = search.advance(3)
        assert search.iterations - before <= 3
        calls += 1
    assert calls >= 2 and result.ok  # it took more than one call
    once = solve_ik_multi(robot, "right", target, q0)
    assert once.ok and np.allclose(once.q, result.q)


@pytest.mark.skipif(not compiled_available(), reason="the compiled law is not built")
def test_the_compiled_iteration_finds_what_the_python_one_finds() -> None:
    """With the compiled law's ``dls_step`` (velma/control/_impedance.cpp) the search takes
    the same steps as the Python iteration, its reference: per target (reachable from the
    first start, reachable only after a restart, unreachable; each arm) the same outcome,
    the same number of iterations and the same posture to 1e-9 rad."""
    from velma.control.compiled import CompiledController

    robot = RobotModel()
    kernel = CompiledController(robot).ik_kernel
    checked = 0
    for side, sign in (("right", 1.0), ("left", -1.0)):
        idx = robot.v_indices(arm_joints(side))
        q0 = pin.neutral(robot.model)
        q0[idx] = [sign * 1.2, -1.0, 0.0, sign * 1.6, 0.0, sign * 1.0, 0.0]
        pin.framesForwardKinematics(robot.model, robot.data, q0)
        start = robot.data.oMf[robot.grip_frame_id[side]].copy()
        for shift, turn in (((0.15, -0.2, 0.1), 0.6), ((0.0, sign * 0.5, -0.3), 2.0), ((2.0, 0.0, 0.0), 0.0)):
            target = pin.SE3(pin.exp3(np.array([0.0, 0.0, turn])) @ start.rotation, start.translation + shift)
            python = IkSearch(robot, side, target, q0)
            compiled = IkSearch(robot, side, target, q0, kernel=kernel)
            a = python.advance(1_000_000)
            b = compiled.advance(1_000_000)
            assert a is not None and b is not None
            assert (a.ok, python.iterations) == (b.ok, compiled.iterations)
            assert np.allclose(a.q, b.q, atol=1e-9, rtol=0.0)
            assert abs(a.position_error - b.position_error) < 1e-9
            checked += a.ok
    assert 2 <= checked <= 4  # reachable and unreachable targets both ran
