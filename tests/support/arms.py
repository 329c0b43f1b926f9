"""Both arms commanded to a Cartesian pose a little above where they are: the free-space
motion that tests comparing two implementations of the cycle run on both
(tests/velma/test_compiled_law.py, tests/velma/test_plant.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from velma.control.joints import SIDES
from velma.executor.runtime import Runtime


def lift_both_arms(rt: Runtime, dz: float = 0.02) -> None:
    """Both arms of ``rt`` in Cartesian impedance, their setpoint ``dz`` (m) above the grip
    frames' poses now, holding their current posture in the null space."""
    for side in SIDES:
        cmd = rt.ctrl.arm[side]
        grip = rt.grip(side)
        cmd.mode = "cart"
        cmd.pose = pin.SE3(grip.rotation, grip.translation + np.array([0.0, 0.0, dz]))
        cmd.posture = rt.arm_q(side)
        cmd.twist = np.zeros(6)
