"""Pinocchio model of Velma built from ``velma.xml``.

Both models come from the same velma.xml (kitchen.xml includes it), so kinematics and dynamics
agree to rounding (see tests/velma/test_velma_model.py); the joints are matched by name
(velma/control/joints.py ``JointMap``, built with ``RobotModel.joint_names``).

Source: velma/model/README.md (joint names, tool chain). Pinocchio's ``buildModelFromMJCF``
reads only the first body tree under ``<worldbody>`` and drops the rest silently: the number
of joints is checked after loading.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from velma.control.joints import EXPECTED_NV, SIDES, IntArray
from velma.model import VELMA_XML, grip_frame


class RobotModel:
    """Pinocchio model and data of Velma (33 DOF, all revolute, nq == nv).

    Raises ``RuntimeError`` if the parsed model does not have the expected 33 joints (e.g.
    when the MJCF file had another body tree first).
    """

    def __init__(self, path: Path = VELMA_XML) -> None:
        self.model: pin.Model = pin.buildModelFromMJCF(str(path))
        if self.model.nv != EXPECTED_NV or self.model.nq != EXPECTED_NV:
            raise RuntimeError(f"{path}: Pinocchio parsed nq={self.model.nq}, expected {EXPECTED_NV}")
        self.data: pin.Data = self.model.createData()
        self.joint_names: tuple[str, ...] = tuple(self.model.names[1:])
        """The joints' names in v order (each 1-DOF: the v index of each is its place)."""
        self.grip_frame_id = {s: self.model.getFrameId(grip_frame(s)) for s in SIDES}

    def v_index(self, joint: str) -> int:
        """Index of ``joint`` in Pinocchio's v (== q index: all joints are 1-DOF revolute)."""
        return int(self.model.joints[self.model.getJointId(joint)].idx_v)

    def v_indices(self, joints: tuple[str, ...]) -> IntArray:
        """Indices of ``joints`` in v, in the order given."""
        return np.array([self.v_index(j) for j in joints], dtype=np.int64)
