"""The robot state that ag_ex publishes (``roco/state/ag_ex``) and the executor hosts return
from ``snapshot``: joint positions, grip-frame poses, what each hand holds, whether the loop
holds position and why, the loop's timing (velma.executor.timing), the world poses of Velma's
main links, the commanded grip frames and the wrist force/torque readings (for viewers).
Data only: reading them from a running ``Runtime`` is velma/executor/gather.py's job."""

from __future__ import annotations

import msgspec
import numpy as np

from shared.fipa_codec.languages.common import Pose
from velma.control.joints import SIDES
from velma.executor.timing import TimingStats
from velma.rotations import quat_wxyz

# The MuJoCo bodies whose world poses the snapshot carries (20): torso, head, each arm's 7
# links and each hand's palm (velma/model/robot_mjcf.py).
LINK_BODIES: tuple[str, ...] = (
    "torso_base",
    "torso_link0",
    "head_pan_link",
    "head_tilt_link",
    *(f"{s}_arm_{k}_link" for s in SIDES for k in range(1, 8)),
    *(f"{s}_HandPalmLink" for s in SIDES),
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


class RawState(msgspec.Struct, frozen=True, kw_only=True, array_like=True):
    """What the loop hands off every ``STATE_PERIOD`` cycles (the loop copies
    numbers, the communication side builds the :class:`RobotSnapshot`): ``values`` float64
    (native byte order) laid out by :func:`raw_layout` — joint positions in ``joints`` order, per
    side (``SIDES``: right, left) the grip site's position (3) and rotation matrix (9,
    row-major), per link of ``LINK_BODIES`` position (3) and quaternion (4), per side a Cartesian setpoint
    flag (1), position (3) and rotation (9), per side the wrench (6)."""

    sim_time: float
    joints: tuple[str, ...]
    values: bytes
    held_object: tuple[str | None, str | None]
    holding: str | None = None


def raw_layout(n_joints: int) -> tuple[int, int, int, int, int]:
    """Offsets of the grip, link, setpoint and wrench blocks in ``RawState.values``, and its length."""
    grip = n_joints
    links = grip + 2 * 12
    setpoint = links + 7 * len(LINK_BODIES)
    ft = setpoint + 2 * 13
    return grip, links, setpoint, ft, ft + 12


def snapshot_of(raw: RawState) -> RobotSnapshot:
    """The :class:`RobotSnapshot` of a :class:`RawState` (on the communication side: numpy
    only, no Pinocchio or MuJoCo). Raises ValueError when ``values`` has another length than
    its joints give (a block from another layout)."""
    v = np.frombuffer(raw.values, dtype=np.float64)
    grip_at, links_at, setpoint_at, ft_at, size = raw_layout(len(raw.joints))
    if len(v) != size:
        raise ValueError(f"a raw state of {len(v)} values, not {size}")
    q = v[:grip_at].tolist()
    joints = dict(zip(raw.joints, q, strict=True))
    grip: dict[str, Pose] = {}
    setpoint: dict[str, Pose | None] = {}
    ft: dict[str, Wrench] = {}
    for k, side in enumerate(SIDES):
        at = grip_at + 12 * k
        p = v[at : at + 3].tolist()
        grip[side] = Pose(
            position=(p[0], p[1], p[2]), orientation=quat_wxyz(v[at + 3 : at + 12].reshape(3, 3))
        )
        at = setpoint_at + 13 * k
        if v[at] == 1.0:
            t = v[at + 1 : at + 4].tolist()
            setpoint[side] = Pose(
                position=(t[0], t[1], t[2]), orientation=quat_wxyz(v[at + 4 : at + 13].reshape(3, 3))
            )
        else:
            setpoint[side] = None
        w = v[ft_at + 6 * k : ft_at + 6 * k + 6].tolist()
        ft[side] = (w[0], w[1], w[2], w[3], w[4], w[5])
    rows = v[links_at:setpoint_at].reshape(len(LINK_BODIES), 7).tolist()
    links = {
        name: Pose(position=(r[0], r[1], r[2]), orientation=(r[3], r[4], r[5], r[6]))
        for name, r in zip(LINK_BODIES, rows, strict=True)
    }
    held_object = dict(zip(SIDES, raw.held_object, strict=True))
    return RobotSnapshot(
        sim_time=raw.sim_time,
        joints=joints,
        grip=grip,
        held={s: held_object[s] is not None for s in SIDES},
        held_object=held_object,
        holding=raw.holding,
        links=links,
        setpoint=setpoint,
        ft=ft,
    )
