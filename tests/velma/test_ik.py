"""Inverse kinematics of the arms (velma/control/ik.py), as the 1 kHz loop uses it."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from velma.control.ik import IkSearch, solve_ik_multi
from velma.control.robot_model import RobotModel, arm_joints


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
