"""velma.xml: the files are generated; the model matches velma/model/README.md; MuJoCo and
Pinocchio agree on kinematics and dynamics (every body and site frame, the Jacobians and
velocities of the frames the controllers and sensors use, mass matrix, bias forces), and that
comparison is sharp enough to catch a small disagreement; the wrist F/T sensors read the hand's
weight.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from velma.control.joints import SIDES, JointMap, robot_joints
from velma.control.robot_model import RobotModel
from velma.model import KITCHEN_XML, VELMA_XML, grip_frame
from velma.model.kitchen_mjcf import build_kitchen
from velma.model.robot_mjcf import build, effort_limits, velocity_limits

TOL = 1e-9  # the agreement asked for; the models agree to ≈ 1e-14
SEEDS = range(8)


@pytest.fixture(scope="module")
def models() -> tuple[mujoco.MjModel, RobotModel, JointMap]:
    mj = mujoco.MjModel.from_xml_path(str(VELMA_XML))
    robot = RobotModel()
    return mj, robot, JointMap.build(mj, robot.joint_names)


def test_model_files_are_generated() -> None:
    assert VELMA_XML.read_text() == build()
    assert KITCHEN_XML.read_text() == build_kitchen()


def test_pinocchio_parses_whole_robot(models: tuple[mujoco.MjModel, RobotModel, JointMap]) -> None:
    mj, robot, _ = models
    assert robot.model.nq == robot.model.nv == mj.nv == 33
    names = {mj.joint(i).name for i in range(mj.njnt)}
    assert set(robot.joint_names) == names
    for side in SIDES:
        for k in range(7):
            assert f"{side}_arm_{k}_joint" in names


def test_mujoco_numbers_the_robot_joints_in_pinocchio_order(
    models: tuple[mujoco.MjModel, RobotModel, JointMap],
) -> None:
    """The world process maps the joints without Pinocchio (velma/control/joints.py
    ``robot_joints``): MuJoCo's order, in velma.xml alone and in the kitchen, is Pinocchio's v
    order, and the map built from it is the controller's."""
    from velma.model.scene import load_kitchen

    mj, robot, _ = models
    assert robot_joints(mj) == robot.joint_names
    assert [robot.v_index(n) for n in robot.joint_names] == list(range(robot.model.nv))
    kitchen = load_kitchen(4)
    assert robot_joints(kitchen) == robot.joint_names
    mapped = JointMap.build(kitchen, robot_joints(kitchen))
    by_pinocchio = JointMap.build(kitchen, robot.joint_names)
    assert np.array_equal(mapped.qpos_adr, by_pinocchio.qpos_adr)
    assert np.array_equal(mapped.dof_adr, by_pinocchio.dof_adr)
    two = "<body name='torso_base'><joint/><geom size='.1'/><body><joint/><geom size='.1'/></body></body>"
    with pytest.raises(ValueError, match="2 joints"):  # not Velma
        robot_joints(mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{two}</worldbody></mujoco>"))


# ------------------------------------------------------------------ the facts (velma/model/README.md)
ARM_FACTS = (  # velma/model/README.md, KUKA LWR4+: z offset, axis, limit °, velocity °/s
    (0.11, (0, 0, 1), 170, 110),
    (0.2005, (0, 1, 0), 120, 110),
    (0.20, (0, 0, 1), 170, 130),
    (0.20, (0, -1, 0), 120, 130),
    (0.20, (0, 0, 1), 170, 130),
    (0.19, (0, 1, 0), 120, 180),
    (0.078, (0, 0, 1), 170, 180),
)


def test_arms_torso_head_match_the_facts(models: tuple[mujoco.MjModel, RobotModel, JointMap]) -> None:
    mj, robot, _ = models
    vel, eff = velocity_limits(), effort_limits()
    assert set(vel) == set(eff) == set(robot.joint_names)
    for side in SIDES:
        arm_mass = mj.body(f"{side}_arm_base_link").mass[0]
        for k, (dz, axis, limit, speed) in enumerate(ARM_FACTS):
            name = f"{side}_arm_{k}_joint"
            j = mj.joint(name)
            assert mj.body(f"{side}_arm_{k + 1}_link").pos.tolist() == [0, 0, dz]
            assert j.axis.tolist() == list(axis)
            assert np.allclose(j.range, [-math.radians(limit), math.radians(limit)])
            assert math.isclose(vel[name], math.radians(speed))
            torque = 100.0 if k < 5 else 60.0
            assert eff[name] == torque
            assert mj.actuator(f"{side}_arm_{k}_motor").forcerange.tolist() == [-torque, torque]
            assert mj.jnt_actfrcrange[j.id].tolist() == [-torque, torque]
            assert robot.model.effortLimit[robot.v_index(name)] == torque
            arm_mass += mj.body(f"{side}_arm_{k + 1}_link").mass[0]
        assert math.isclose(arm_mass, 16.0)  # the real LWR4+
    torso = mj.joint("torso_0_joint")
    assert torso.axis.tolist() == [0, 0, 1] and np.allclose(torso.range, [-1.57, 1.57])
    assert mj.body("torso_link0").pos.tolist() == [0, 0, 0.03] and torso.damping[0] == 10.0
    assert mj.body("torso_base").mass[0] == 30.0 and mj.body("torso_link0").mass[0] == 30.0
    assert np.allclose(mj.body("head_base").pos, [0.0105, -0.001, 1.3117])
    assert mj.joint("head_pan_joint").axis.tolist() == [0, 0, 1]
    assert mj.joint("head_tilt_joint").axis.tolist() == [0, 1, 0]
    assert np.allclose(mj.joint("head_tilt_joint").range, [-1.0, 1.3])
    assert mj.ncam == 1 and mj.camera("head_camera").bodyid[0] == mj.body("head_tilt_link").id


def test_hand_matches_the_facts(models: tuple[mujoco.MjModel, RobotModel, JointMap]) -> None:
    mj, _, _ = models
    data = mujoco.MjData(mj)
    mujoco.mj_forward(mj, data)
    for side in SIDES:
        palm = mj.body(f"{side}_HandPalmLink").id
        mount = mj.body(f"{side}_gripper_mount_link").id
        assert math.isclose(mj.body_subtreemass[palm], 0.6335 + 2 * 0.1625 + 3 * (0.058 + 0.0342))
        total = mj.body_subtreemass[palm] + mj.body_mass[mount]
        assert math.isclose(total, 1.53)
        com = (
            mj.body_subtreemass[palm] * data.subtree_com[palm] + mj.body_mass[mount] * data.xipos[mount]
        ) / total
        rot = data.xmat[mount].reshape(3, 3)
        assert np.allclose(rot.T @ (com - data.xpos[mount]), [0.152, 0.011, -0.069], atol=1e-9)
        for finger in ("One", "Two", "Three"):
            assert np.allclose(mj.joint(f"{side}_HandFinger{finger}KnuckleTwoJoint").range, [0, 2.4434])
            assert np.allclose(mj.joint(f"{side}_HandFinger{finger}KnuckleThreeJoint").range, [0, 0.8377])
        for finger in ("One", "Two"):
            assert np.allclose(mj.joint(f"{side}_HandFinger{finger}KnuckleOneJoint").range, [0, math.pi])


def test_wrist_ft_sensors_read_the_hand_weight(models: tuple[mujoco.MjModel, RobotModel, JointMap]) -> None:
    """Held still (qacc = 0) in random postures, each wrist sensor measures the weight of the
    palm and fingers (1.235 kg · g ≈ 12.1 N, upwards) and the matching gravity moment. Contacts
    are off: a random posture may put the hand against the robot's own links (self-collision)."""
    mj, _, _ = models
    g = -mj.opt.gravity[2]
    disabled = mj.opt.disableflags
    mj.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    try:
        _weights_measured(mj, g)
    finally:
        mj.opt.disableflags = disabled


def _weights_measured(mj: mujoco.MjModel, g: float) -> None:
    rng = np.random.default_rng(0)
    for _ in range(3):
        data = mujoco.MjData(mj)
        data.qpos[:] = rng.uniform(mj.jnt_range[:, 0], mj.jnt_range[:, 1])
        mujoco.mj_forward(mj, data)
        data.qacc[:] = 0.0
        mujoco.mj_inverse(mj, data)
        for side in SIDES:
            site = mj.site(f"{side}_ft_sensor").id
            rot = data.site_xmat[site].reshape(3, 3)
            force = rot @ data.sensor(f"{side}_ft_force").data
            torque = rot @ data.sensor(f"{side}_ft_torque").data
            palm = mj.body(f"{side}_HandPalmLink").id
            weight = mj.body_subtreemass[palm] * g
            assert 12.0 < weight < 12.2
            assert np.allclose(force, [0.0, 0.0, weight], atol=1e-9)
            lever = data.subtree_com[palm] - data.site_xpos[site]
            assert np.allclose(torque, np.cross(lever, [0.0, 0.0, weight]), atol=1e-9)
            assert np.linalg.norm(torque) > 0.05  # the hand's centre of mass is off the sensor


def test_head_camera_is_the_camera_site(models: tuple[mujoco.MjModel, RobotModel, JointMap]) -> None:
    mj, _, _ = models
    data = mujoco.MjData(mj)
    data.qpos[:] = np.random.default_rng(1).uniform(mj.jnt_range[:, 0], mj.jnt_range[:, 1])
    mujoco.mj_forward(mj, data)
    cam, site = mj.camera("head_camera").id, mj.site("head_camera_site").id
    assert np.allclose(data.cam_xpos[cam], data.site_xpos[site], atol=1e-12)
    assert np.allclose(data.cam_xmat[cam], data.site_xmat[site], atol=1e-12)
    # the camera looks along the head's +x (MuJoCo cameras look along their −z)
    tilt = data.xmat[mj.body("head_tilt_link").id].reshape(3, 3)
    assert np.allclose(-data.cam_xmat[cam].reshape(3, 3)[:, 2], tilt[:, 0], atol=1e-12)


# ------------------------------------------------------------------ MuJoCo vs Pinocchio
KEY_SITES = (*(f"{s}_{n}" for s in SIDES for n in ("HandGripLink", "ft_sensor")), "head_camera_site")
KEY_BODIES = tuple(f"{s}_{n}" for s in SIDES for n in ("arm_7_link", "HandPalmLink", "gripper_mount_link"))


def _random_state(mj: mujoco.MjModel, rng: np.random.Generator) -> mujoco.MjData:
    """A configuration uniform within the joint limits, velocities ~ N(0, 1) rad/s."""
    data = mujoco.MjData(mj)
    lo, hi = mj.jnt_range[:, 0], mj.jnt_range[:, 1]
    data.qpos[:] = rng.uniform(lo, hi)
    data.qvel[:] = rng.normal(0.0, 1.0, mj.nv)
    mujoco.mj_forward(mj, data)
    return data


def disagreement(
    mj: mujoco.MjModel, data: mujoco.MjData, pm: pin.Model, jmap: JointMap
) -> tuple[dict[str, float], dict[str, float]]:
    """Largest absolute differences between MuJoCo (``data``) and Pinocchio model ``pm`` at
    the same state, per quantity, and the largest magnitudes of what was compared."""
    pd = pm.createData()
    q, v = jmap.q(data), jmap.v(data)
    pin.forwardKinematics(pm, pd, q, v)
    pin.computeJointJacobians(pm, pd, q)
    pin.updateFramePlacements(pm, pd)
    err = {"pose": 0.0, "jacobian": 0.0, "velocity": 0.0}
    size = {"pose": 0.0, "jacobian": 0.0, "velocity": 0.0}

    def frame(name: str, is_site: bool) -> None:
        fid = pm.getFrameId(name)
        assert fid < len(pm.frames), name
        if is_site:
            i = mj.site(name).id
            pos, rot = data.site_xpos[i], data.site_xmat[i].reshape(3, 3)
        else:
            i = mj.body(name).id
            pos, rot = data.xpos[i], data.xmat[i].reshape(3, 3)
        m = pd.oMf[fid]
        err["pose"] = max(err["pose"], np.abs(m.translation - pos).max(), np.abs(m.rotation - rot).max())
        size["pose"] = max(size["pose"], np.abs(pos).max())
        if name not in KEY_SITES + KEY_BODIES:
            return
        jacp, jacr = np.zeros((3, mj.nv)), np.zeros((3, mj.nv))
        if is_site:
            mujoco.mj_jacSite(mj, data, jacp, jacr, i)
        else:
            mujoco.mj_jacBody(mj, data, jacp, jacr, i)
        jac = pin.getFrameJacobian(pm, pd, fid, pin.LOCAL_WORLD_ALIGNED)
        mj_jac = np.vstack([jacp, jacr])[:, jmap.dof_adr]
        err["jacobian"] = max(err["jacobian"], np.abs(jac - mj_jac).max())
        size["jacobian"] = max(size["jacobian"], np.abs(mj_jac).max())
        vel6 = np.zeros(6)  # MuJoCo: [angular; linear] at the frame origin, world axes
        obj = mujoco.mjtObj.mjOBJ_SITE if is_site else mujoco.mjtObj.mjOBJ_XBODY  # body frame, not its CoM
        mujoco.mj_objectVelocity(mj, data, obj, i, vel6, 0)
        pv = pin.getFrameVelocity(pm, pd, fid, pin.LOCAL_WORLD_ALIGNED)
        err["velocity"] = max(
            err["velocity"], np.abs(pv.linear - vel6[3:]).max(), np.abs(pv.angular - vel6[:3]).max()
        )
        size["velocity"] = max(size["velocity"], np.abs(vel6).max())

    for b in range(1, mj.nbody):
        frame(mj.body(b).name, is_site=False)
    for s in range(mj.nsite):
        frame(mj.site(s).name, is_site=True)
    mass = pin.crba(pm, pd, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    full = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, data, full)
    mj_mass = full[np.ix_(jmap.dof_adr, jmap.dof_adr)]
    err["mass"] = np.abs(mass - mj_mass).max()
    size["mass"] = np.abs(mj_mass).max()
    mj_bias = data.qfrc_bias[jmap.dof_adr]
    err["bias"] = np.abs(pin.nonLinearEffects(pm, pd, q, v) - mj_bias).max()
    size["bias"] = np.abs(mj_bias).max()
    return err, size


@pytest.mark.parametrize("seed", SEEDS)
def test_frames_jacobians_velocities_mass_bias_agree(
    models: tuple[mujoco.MjModel, RobotModel, JointMap], seed: int
) -> None:
    mj, robot, jmap = models
    data = _random_state(mj, np.random.default_rng(seed))
    assert np.all(data.qpos >= mj.jnt_range[:, 0]) and np.all(data.qpos <= mj.jnt_range[:, 1])
    err, size = disagreement(mj, data, robot.model, jmap)
    assert max(err.values()) < TOL, err
    # what was compared is not trivially small: a relative error of 1e-9 would be caught
    assert min(size.values()) > 0.1, size
    assert grip_frame("right") in KEY_SITES and mj.nsite == 5


@pytest.mark.parametrize(
    ("change", "caught"),
    [
        ("joint_offset", ("pose", "jacobian", "velocity", "mass", "bias")),
        ("link_mass", ("mass", "bias")),
        ("armature", ("mass",)),
    ],
)
def test_a_small_disagreement_is_caught(
    models: tuple[mujoco.MjModel, RobotModel, JointMap], change: str, caught: tuple[str, ...]
) -> None:
    """Changing Pinocchio's model by 1e-6 (m, kg or kg·m²) in one place fails the check."""
    mj, robot, jmap = models
    pm = robot.model.copy()
    jid = pm.getJointId("left_arm_5_joint")
    if change == "joint_offset":
        pm.jointPlacements[jid].translation += np.array([1e-6, 0.0, 0.0])
    elif change == "link_mass":
        inertia = pm.inertias[jid]
        pm.inertias[jid] = pin.Inertia(inertia.mass + 1e-6, inertia.lever, inertia.inertia)
    else:
        pm.armature[robot.v_index("left_arm_5_joint")] += 1e-6
    data = _random_state(mj, np.random.default_rng(0))
    err, _ = disagreement(mj, data, pm, jmap)
    for quantity in caught:
        assert err[quantity] > 10 * TOL, (quantity, err)
    baseline, _ = disagreement(mj, data, robot.model, jmap)
    assert max(baseline.values()) < TOL
