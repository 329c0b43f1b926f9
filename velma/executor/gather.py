"""Reading the robot state of velma/executor/state.py from a running ``Runtime`` (the loop's
thread): the numbers of a ``RawState`` gathered from MuJoCo's data and the controller's
setpoints, and the ``RobotSnapshot`` built from them."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from velma.control.joints import SIDES
from velma.executor.state import LINK_BODIES, RawState, RobotSnapshot, raw_layout, snapshot_of

if TYPE_CHECKING:
    from velma.executor.runtime import Runtime


def raw_state(rt: Runtime, holding: str | None = None) -> RawState:
    """The state of ``rt`` now as numbers (reads MuJoCo's data; call from the loop's thread):
    copies, no per-value objects."""
    out = np.empty(raw_layout(len(rt.joint_v_index))[-1])
    if rt.plant is not None:
        rt.plant.gather(out)  # the same numbers, read in C++ (velma/executor/plant.py)
        _setpoints(rt, out)
    else:
        python_gather(rt, out)
    right, left = rt.held[SIDES[0]], rt.held[SIDES[1]]
    return RawState(
        sim_time=rt.time,
        joints=rt.robot.joint_names,
        values=out.tobytes(),
        held_object=(
            None if right is None else rt.model.body(right).name,
            None if left is None else rt.model.body(left).name,
        ),
        holding=holding,
    )


def python_gather(rt: Runtime, out: npt.NDArray[np.float64]) -> None:
    """The numbers of ``raw_state`` into ``out`` in Python (the reference of ``CompiledPlant.gather``)."""
    data = rt.data
    grip_at, links_at, setpoint_at, ft_at, _ = raw_layout(len(rt.joint_v_index))
    out[:grip_at] = rt.q()[rt.snapshot_index]
    for k, side in enumerate(SIDES):
        site = rt.grip_site[side]
        at = grip_at + 12 * k
        out[at : at + 3] = data.site_xpos[site]
        out[at + 3 : at + 12] = data.site_xmat[site]
        fa, ta = rt.ft_adr[side]
        at = ft_at + 6 * k
        out[at : at + 3] = data.sensordata[fa : fa + 3]
        out[at + 3 : at + 6] = data.sensordata[ta : ta + 3]
    link_block = out[links_at:setpoint_at].reshape(len(LINK_BODIES), 7)
    link_block[:, :3] = data.xpos[rt.link_ids]
    link_block[:, 3:] = data.xquat[rt.link_ids]
    _setpoints(rt, out)


def _setpoints(rt: Runtime, out: npt.NDArray[np.float64]) -> None:
    """The setpoint block of ``raw_state``: per side a Cartesian flag (1), the commanded grip
    position (3) and rotation (9, row-major), zeros outside Cartesian mode."""
    setpoint_at = raw_layout(len(rt.joint_v_index))[2]
    for k, side in enumerate(SIDES):
        cmd = rt.ctrl.arm[side]
        at = setpoint_at + 13 * k
        if cmd.mode == "cart":
            out[at] = 1.0
            out[at + 1 : at + 4] = cmd.pose.translation
            out[at + 4 : at + 13] = cmd.pose.rotation.reshape(9)
        else:
            out[at : at + 13] = 0.0


def robot_snapshot(rt: Runtime, holding: str | None = None) -> RobotSnapshot:
    """The state of ``rt`` now (reads MuJoCo's data; call from the loop's thread)."""
    return snapshot_of(raw_state(rt, holding))
