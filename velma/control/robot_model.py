"""Pinocchio model of Velma built from ``velma.xml``, and the index map to a MuJoCo model.

The controller never assumes that MuJoCo's qpos/qvel order equals Pinocchio's q/v order: it
maps every Velma joint by name (``JointMap``). Both models come from the same velma.xml
(kitchen.xml includes it), so kinematics and dynamics agree to rounding (see
tests/velma/test_velma_model.py).

Source: velma-facts.md (joint names, tool chain); platform-notes.md (``buildModelFromMJCF``
reads only the first body tree: the number of joints is checked after loading).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt
import pinocchio as pin

from velma.model import VELMA_XML, grip_frame

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

SIDES = ("right", "left")
TORSO_JOINT = "torso_0_joint"
HEAD_JOINTS = ("head_pan_joint", "head_tilt_joint")
FINGERS = ("One", "Two", "Three")
EXPECTED_NV = 33  # torso 1 + head 2 + 2 × (arm 7 + hand 8)


def arm_joints(side: str) -> tuple[str, ...]:
    """The seven LWR4+ joint names of ``side`` (``right``/``left``), base to wrist."""
    return tuple(f"{side}_arm_{k}_joint" for k in range(7))


def spread_joints(side: str) -> tuple[str, str]:
    """Spread joints of fingers One and Two (one shared command)."""
    return (f"{side}_HandFingerOneKnuckleOneJoint", f"{side}_HandFingerTwoKnuckleOneJoint")


def proximal_joints(side: str) -> tuple[str, ...]:
    """Proximal (KnuckleTwo) joints of fingers One, Two, Three."""
    return tuple(f"{side}_HandFinger{n}KnuckleTwoJoint" for n in FINGERS)


def distal_joints(side: str) -> tuple[str, ...]:
    """Distal (KnuckleThree) joints of fingers One, Two, Three."""
    return tuple(f"{side}_HandFinger{n}KnuckleThreeJoint" for n in FINGERS)


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
        self.grip_frame_id = {s: self.model.getFrameId(grip_frame(s)) for s in SIDES}

    def v_index(self, joint: str) -> int:
        """Index of ``joint`` in Pinocchio's v (== q index: all joints are 1-DOF revolute)."""
        return int(self.model.joints[self.model.getJointId(joint)].idx_v)

    def v_indices(self, joints: tuple[str, ...]) -> IntArray:
        """Indices of ``joints`` in v, in the order given."""
        return np.array([self.v_index(j) for j in joints], dtype=np.int64)


@dataclass(frozen=True)
class JointMap:
    """Index arrays between a MuJoCo model and Pinocchio, matched by joint name.

    ``qpos_adr[i]`` / ``dof_adr[i]`` are the MuJoCo qpos / qvel addresses of Pinocchio's
    joint with v index ``i``; ``ctrl`` maps actuator names to MuJoCo actuator indices.
    """

    qpos_adr: IntArray
    dof_adr: IntArray
    ctrl: dict[str, int]

    @staticmethod
    def build(mj: mujoco.MjModel, robot: RobotModel) -> JointMap:
        """Match by name; raises ``KeyError`` if a Pinocchio joint is missing in MuJoCo."""
        qpos = np.zeros(robot.model.nv, dtype=np.int64)
        dof = np.zeros(robot.model.nv, dtype=np.int64)
        for name in robot.joint_names:
            jid = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)
            if jid < 0:
                raise KeyError(f"joint {name} not in the MuJoCo model")
            i = robot.v_index(name)
            qpos[i] = mj.jnt_qposadr[jid]
            dof[i] = mj.jnt_dofadr[jid]
        ctrl = {mj.actuator(i).name: i for i in range(mj.nu)}
        return JointMap(qpos_adr=qpos, dof_adr=dof, ctrl=ctrl)

    def q(self, data: mujoco.MjData) -> Array:
        """Pinocchio q (rad, shape (33,)) from MuJoCo ``data.qpos``."""
        out: Array = data.qpos[self.qpos_adr]
        return out

    def v(self, data: mujoco.MjData) -> Array:
        """Pinocchio v (rad/s, shape (33,)) from MuJoCo ``data.qvel``."""
        out: Array = data.qvel[self.dof_adr]
        return out
