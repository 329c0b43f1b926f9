"""The robot state that ag_ex publishes (``roco/state/ag_ex``) and the executor hosts return
from ``snapshot``: joint positions, grip-frame poses, what each hand holds, whether the loop
holds position and why, and the loop's timing (velma.executor.timing)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import msgspec

from shared.fipa_codec.languages.common import Pose
from velma.executor.timing import TimingStats

if TYPE_CHECKING:
    from velma.executor.runtime import Runtime


class RobotSnapshot(msgspec.Struct, frozen=True, kw_only=True):
    """The robot's state at ``sim_time`` (s): ``joints`` (rad, by joint name), the world
    pose of each grip frame (``grip`` keyed ``right``/``left``), whether each hand holds an
    object (``held``) and which (``held_object``, body name or None); ``holding`` is the
    reason the loop holds position in joint impedance (None while it serves commands);
    ``timing`` the loop's deadline statistics when the host attaches them."""

    sim_time: float
    joints: dict[str, float]
    grip: dict[str, Pose]
    held: dict[str, bool]
    held_object: dict[str, str | None]
    holding: str | None = None
    timing: TimingStats | None = None


def robot_snapshot(rt: Runtime, holding: str | None = None) -> RobotSnapshot:
    """The state of ``rt`` now (reads MuJoCo's data; call from the loop's thread)."""
    from velma.control.robot_model import SIDES
    from velma.control.trajectory import quat_wxyz

    q = rt.q()
    joints = {name: float(q[i]) for name, i in zip(rt.robot.joint_names, rt.joint_v_index, strict=True)}
    grip = {}
    for side in SIDES:
        site = rt.grip_site[side]
        p = rt.data.site_xpos[site]
        rot = rt.data.site_xmat[site].reshape(3, 3)
        grip[side] = Pose(position=(float(p[0]), float(p[1]), float(p[2])), orientation=quat_wxyz(rot))
    held_obj = {s: (rt.model.body(b).name if (b := rt.held[s]) is not None else None) for s in SIDES}
    return RobotSnapshot(
        sim_time=rt.time,
        joints=joints,
        grip=grip,
        held={s: held_obj[s] is not None for s in SIDES},
        held_object=held_obj,
        holding=holding,
    )
