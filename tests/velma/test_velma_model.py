"""velma.xml: MuJoCo and Pinocchio agree on kinematics and dynamics; the file is generated."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from velma.control.robot_model import SIDES, JointMap, RobotModel, grip_frame
from velma.model import VELMA_XML
from velma.model.generate import build


@pytest.fixture(scope="module")
def models() -> tuple[mujoco.MjModel, RobotModel, JointMap]:
    mj = mujoco.MjModel.from_xml_path(str(VELMA_XML))
    robot = RobotModel()
    return mj, robot, JointMap.build(mj, robot)


def test_velma_xml_is_generated() -> None:
    assert VELMA_XML.read_text() == build()


def test_pinocchio_parses_whole_robot(models: tuple[mujoco.MjModel, RobotModel, JointMap]) -> None:
    mj, robot, _ = models
    assert robot.model.nq == robot.model.nv == mj.nv == 33
    names = {mj.joint(i).name for i in range(mj.njnt)}
    assert set(robot.joint_names) == names
    for side in SIDES:
        for k in range(7):
            assert f"{side}_arm_{k}_joint" in names


def _random_state(mj: mujoco.MjModel, rng: np.random.Generator) -> mujoco.MjData:
    data = mujoco.MjData(mj)
    lo, hi = mj.jnt_range[:, 0], mj.jnt_range[:, 1]
    data.qpos[:] = rng.uniform(lo, hi)
    data.qvel[:] = rng.normal(0.0, 1.0, mj.nv)
    mujoco.mj_forward(mj, data)
    return data


@pytest.mark.parametrize("seed", range(5))
def test_frames_jacobians_mass_bias_agree(
    models: tuple[mujoco.MjModel, RobotModel, JointMap], seed: int
) -> None:
    mj, robot, jmap = models
    data = _random_state(mj, np.random.default_rng(seed))
    q, v = jmap.q(data), jmap.v(data)
    pm, pd = robot.model, robot.data
    pin.computeJointJacobians(pm, pd, q)
    pin.updateFramePlacements(pm, pd)
    for side in SIDES:
        sid = mj.site(grip_frame(side)).id
        oMf = pd.oMf[robot.grip_frame_id[side]]
        assert np.allclose(oMf.translation, data.site_xpos[sid], atol=1e-9)
        assert np.allclose(oMf.rotation, data.site_xmat[sid].reshape(3, 3), atol=1e-9)
        jacp = np.zeros((3, mj.nv))
        jacr = np.zeros((3, mj.nv))
        mujoco.mj_jacSite(mj, data, jacp, jacr, sid)
        jac = pin.getFrameJacobian(pm, pd, robot.grip_frame_id[side], pin.LOCAL_WORLD_ALIGNED)
        assert np.allclose(jac[:3], jacp[:, jmap.dof_adr], atol=1e-9)
        assert np.allclose(jac[3:], jacr[:, jmap.dof_adr], atol=1e-9)
    mass = pin.crba(pm, pd, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    full = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, full)
    assert np.allclose(mass, full[np.ix_(jmap.dof_adr, jmap.dof_adr)], atol=1e-9)
    bias = pin.nonLinearEffects(pm, pd, q, v)
    assert np.allclose(bias, data.qfrc_bias[jmap.dof_adr], atol=1e-9)
