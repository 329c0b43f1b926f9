"""What an Observation says of the robot itself: each hand's grip frame where the forward
kinematics of the measured joint angles puts it (L_SD ``Observation.grips``).

A real Velma knows where its hands are from its joint encoders, also when the camera cannot
see them or what they hold (a jar in a hand inside the cabinet). Here the kinematics is
MuJoCo's (``mj_kinematics`` of the observed state's joint angles: only the robot's joints
move the grip sites), not a measurement of any object.
"""

from __future__ import annotations

import mujoco
import numpy as np

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_sd import ObjectObservation
from velma.model import grip_frame

GRIPPER = "{side}_gripper"
"""a_km's name of a side's gripper (services/agents/knowledge/o_roco.ttl)."""
SIDES = ("left", "right")


class GripFrames:
    """The grip sites of ``model`` (an ``mujoco.MjModel`` of Velma). Raises ``KeyError``
    when the model has no grip-frame site (velma.model.grip_frame)."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.sites = {side: model.site(grip_frame(side)).id for side in SIDES}

    def observe(self, data: mujoco.MjData) -> tuple[ObjectObservation, ...]:
        """Each gripper's grip frame in ``data`` (its kinematics computed): world pose,
        position in m, orientation a unit quaternion (w, x, y, z); ``position_sigma`` None."""
        out = []
        for side, site in self.sites.items():
            p = data.site_xpos[site]
            q = np.empty(4)
            mujoco.mju_mat2Quat(q, data.site_xmat[site])
            out.append(
                ObjectObservation(
                    name=GRIPPER.format(side=side),
                    pose=Pose(
                        position=(float(p[0]), float(p[1]), float(p[2])),
                        orientation=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
                    ),
                )
            )
        return tuple(out)
