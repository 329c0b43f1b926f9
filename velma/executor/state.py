"""The robot state that ag_ex publishes (``roco/state/ag_ex``) and the executor hosts return
from ``snapshot``: joint positions, grip-frame poses, what each hand holds, whether the loop
holds position and why, the loop's timing (velma.executor.timing), the world poses of Velma's
main links, the commanded grip frames and the wrist force/torque readings (for viewers)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import msgspec

from shared.fipa_codec.languages.common import Pose
from velma.executor.timing import TimingStats

if TYPE_CHECKING:
    from velma.executor.runtime import Runtime

SNAPSHOT_SIDES = ("right", "left")  # = velma.control.robot_model.SIDES (not imported: no Pinocchio here)
# The MuJoCo bodies whose world poses the snapshot carries (20): torso, head, each arm's 7
# links and each hand's palm (velma/model/generate.py).
LINK_BODIES: tuple[str, ...] = (
    "torso_base",
    "torso_link0",
    "head_pan_link",
    "head_tilt_link",
    *(f"{s}_arm_{k}_link" for s in SNAPSHOT_SIDES for k in range(1, 8)),
    *(f"{s}_HandPalmLink" for s in SNAPSHOT_SIDES),
)
FT_AXES = ("fx", "fy", "fz", "tx", "ty", "tz")  # the order of a wrench in ``RobotSnapshot.ft``

Wrench = tuple[float, float, float, float, float, float]


class RobotSnapshot(msgspec.Struct, frozen=True, kw_only=True):
    """The robot's state at ``sim_time`` (s): ``joints`` (rad, by joint name), the world
    pose of each grip frame (``grip`` keyed ``right``/``left``), whether each hand holds an
    object (``held``) and which (``held_object``, body name or None); ``holding`` is the
    reason the loop holds position in joint impedance (None while it serves commands);
    ``timing`` the loop's deadline statistics when the host attaches them.

    For viewers: ``links`` the world pose of each body of ``LINK_BODIES`` (body frame, m and
    unit quaternion w, x, y, z); ``setpoint`` the commanded grip-frame pose (world) of each
    side whose arm is in Cartesian impedance, None in joint or safe mode; ``ft`` each wrist
    sensor's wrench (fx, fy, fz N, tx, ty, tz N·m) in the sensor frame (``<side>_ft_sensor``,
    axes as the palm's, z towards the fingers): MuJoCo's force and torque sensors, the
    interaction between the palm subtree (palm, fingers, what they carry) and arm_7_link, as
    of the last physics step. The three are empty when the builder does not fill them (older hosts, tests)."""

    sim_time: float
    joints: dict[str, float]
    grip: dict[str, Pose]
    held: dict[str, bool]
    held_object: dict[str, str | None]
    holding: str | None = None
    timing: TimingStats | None = None
    links: dict[str, Pose] = msgspec.field(default_factory=dict)
    setpoint: dict[str, Pose | None] = msgspec.field(default_factory=dict)
    ft: dict[str, Wrench] = msgspec.field(default_factory=dict)


def robot_snapshot(rt: Runtime, holding: str | None = None) -> RobotSnapshot:
    """The state of ``rt`` now (reads MuJoCo's data; call from the loop's thread)."""
    from velma.control.robot_model import SIDES
    from velma.frames import quat_wxyz

    q = rt.q()
    joints = {name: float(q[i]) for name, i in zip(rt.robot.joint_names, rt.joint_v_index, strict=True)}
    grip = {}
    for side in SIDES:
        site = rt.grip_site[side]
        p = rt.data.site_xpos[site]
        rot = rt.data.site_xmat[site].reshape(3, 3)
        grip[side] = Pose(position=(float(p[0]), float(p[1]), float(p[2])), orientation=quat_wxyz(rot))
    held_obj = {s: (rt.model.body(b).name if (b := rt.held[s]) is not None else None) for s in SIDES}
    xpos = rt.data.xpos[rt.link_ids].tolist()
    xquat = rt.data.xquat[rt.link_ids].tolist()
    links = {
        name: Pose(position=tuple(p), orientation=tuple(o))
        for name, p, o in zip(LINK_BODIES, xpos, xquat, strict=True)
    }
    setpoint: dict[str, Pose | None] = {}
    for side in SIDES:
        cmd = rt.ctrl.arm[side]
        if cmd.mode == "cart":
            t = cmd.pose.translation
            setpoint[side] = Pose(
                position=(float(t[0]), float(t[1]), float(t[2])), orientation=quat_wxyz(cmd.pose.rotation)
            )
        else:
            setpoint[side] = None
    sensors = rt.data.sensordata
    ft: dict[str, Wrench] = {}
    for side in SIDES:
        fa, ta = rt.ft_adr[side]
        ft[side] = (*sensors[fa : fa + 3].tolist(), *sensors[ta : ta + 3].tolist())
    return RobotSnapshot(
        sim_time=rt.time,
        joints=joints,
        grip=grip,
        held={s: held_obj[s] is not None for s in SIDES},
        held_object=held_obj,
        holding=holding,
        links=links,
        setpoint=setpoint,
        ft=ft,
    )
