"""Velma's joints by name, and the index map between Pinocchio's joint order and a MuJoCo
model's (``JointMap``). Imports neither MuJoCo nor Pinocchio: the world process maps the
robot's joints without loading Pinocchio (velma/world/hardware.py), the controller with
Pinocchio's model (velma/control/robot_model.py).

The controller never assumes that MuJoCo's qpos/qvel order equals Pinocchio's q/v order: it
maps every Velma joint by name. Pinocchio's MJCF parser numbers the joints of velma.xml in the
order of its body tree, depth first, as MuJoCo numbers the joints of a model that includes it
(``robot_joints``); tests/velma/test_velma_model.py checks that the two orders agree, and a
controller attached to a world process checks it again (velma/executor/runtime.py).

Source: velma/model/README.md ("KUKA LWR4+ arms", "BarrettHand BH8-282": joint names).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from shared.fipa_codec.languages.l_ex import TORSO_JOINT as TORSO_JOINT  # O_Velma's name, stated there

if TYPE_CHECKING:
    import mujoco

Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

SIDES = ("right", "left")
HEAD_JOINTS = ("head_pan_joint", "head_tilt_joint")
FINGERS = ("One", "Two", "Three")
EXPECTED_NV = 33  # torso 1 + head 2 + 2 × (arm 7 + hand 8)
ROBOT_ROOT = "torso_base"
"""The root body of Velma's body tree in velma.xml (velma/model/robot_mjcf.py)."""


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


def robot_joints(mj: mujoco.MjModel) -> tuple[str, ...]:
    """The names of Velma's joints in ``mj`` (a model that includes velma.xml: those of the
    bodies under ``ROBOT_ROOT``), in MuJoCo's order: Pinocchio's v order (module docstring).
    Raises KeyError when ``mj`` has no ``ROBOT_ROOT``, ValueError when the robot has another
    number of joints than ``EXPECTED_NV``."""
    root = mj.body(ROBOT_ROOT).id
    names = tuple(mj.joint(j).name for j in range(mj.njnt) if mj.body_rootid[mj.jnt_bodyid[j]] == root)
    if len(names) != EXPECTED_NV:
        raise ValueError(f"the robot has {len(names)} joints in the MuJoCo model, expected {EXPECTED_NV}")
    return names


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
    def build(mj: mujoco.MjModel, joints: Sequence[str]) -> JointMap:
        """Match by name: ``joints`` are the robot's joint names in Pinocchio's v order
        (``RobotModel.joint_names``, or ``robot_joints(mj)``: all 1-DOF, the v index of each is
        its place). Raises ``KeyError`` if one is missing in MuJoCo."""
        qpos = np.zeros(len(joints), dtype=np.int64)
        dof = np.zeros(len(joints), dtype=np.int64)
        for i, name in enumerate(joints):
            try:
                joint = mj.joint(name)
            except KeyError:
                raise KeyError(f"joint {name} not in the MuJoCo model") from None
            qpos[i] = joint.qposadr[0]
            dof[i] = joint.dofadr[0]
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
