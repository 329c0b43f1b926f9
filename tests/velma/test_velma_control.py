"""Cartesian impedance converges; a friction grasp lifts the jar (no welds); the control law
equals a slow reference implementation of its documentation; the safety terms (joint-limit
and singularity bands, velocity limit, torque and rate limits), safe mode and hold act."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import Arm, CommandResult, Grasp, MoveTool, Observe, Release
from shared.fipa_codec.languages.l_sd import Observation
from velma.control import limits
from velma.control.impedance import (
    ARM_TORQUE_LIMIT,
    DAMPING_RATIO,
    LAMBDA_REGULARISATION,
    NULLSPACE_DAMPING,
    NULLSPACE_STIFFNESS,
    SAFE_DAMPING_RATIO,
    SAFE_STIFFNESS,
    TORQUE_RATE_LIMIT,
    TORSO_STIFFNESS,
    VelmaController,
    diagonal_double_diagonalisation_damping,
    double_diagonalisation_damping,
    pose_error,
)
from velma.control.joints import SIDES
from velma.control.robot_model import RobotModel
from velma.executor.primitives import make_primitive
from velma.executor.runtime import Runtime
from velma.rotations import quat_wxyz
from velma.scenario import script_poses


def run(rt: Runtime, command: object) -> CommandResult | Observation:
    prim = make_primitive(command)  # type: ignore[arg-type]
    result = prim.start(rt)
    while result is None:
        result = prim.step(rt)
        rt.cycle()
    return result


def test_double_diagonalisation_gives_damping_ratio() -> None:
    rng = np.random.default_rng(0)
    a = rng.normal(size=(6, 6))
    lam = a @ a.T + 6 * np.eye(6)
    k = np.diag([1000.0, 1000, 1000, 150, 150, 150])
    d = double_diagonalisation_damping(k, lam, 0.7)
    # modal check: with Λ = Q Qᵀ, K = Q S Qᵀ, D must be Q 2ξ√S Qᵀ
    chol = np.linalg.cholesky(lam)
    li = np.linalg.inv(chol)
    s, u = np.linalg.eigh(li @ k @ li.T)
    modal = u.T @ li @ d @ li.T @ u
    assert np.allclose(modal, np.diag(2 * 0.7 * np.sqrt(s)), atol=1e-8)


def test_cartesian_impedance_converges() -> None:
    rt = Runtime(seed=0, n_particles=0)
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    start = rt.grip("left").copy()
    target = pin.SE3(
        start.rotation @ pin.exp3(np.array([0.0, 0.0, 0.3])),
        start.translation + np.array([0.08, -0.05, 0.06]),
    )
    result = run(
        rt,
        MoveTool(
            arm=Arm.LEFT,
            target=Pose(position=tuple(target.translation), orientation=quat_wxyz(target.rotation)),
            duration=1.5,
        ),
    )
    assert isinstance(result, CommandResult) and result.ok, result
    for _ in range(500):
        rt.cycle()
    grip = rt.grip("left")
    assert np.linalg.norm(grip.translation - target.translation) < 2e-3
    assert np.linalg.norm(pin.log3(grip.rotation.T @ target.rotation)) < 1e-2


def test_unreachable_target_is_refused() -> None:
    rt = Runtime(seed=0, n_particles=0)
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    result = run(rt, MoveTool(arm=Arm.RIGHT, target=Pose(position=(2.0, 0.0, 1.0)), duration=1.0))
    assert isinstance(result, CommandResult) and not result.ok and result.reason == "unreachable"


@pytest.mark.requirement("R3.1")
def test_grasp_lifts_jar_by_friction() -> None:
    rt = Runtime(seed=0, n_particles=0)
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    obs = run(rt, Observe())
    assert isinstance(obs, Observation)
    poses = script_poses(obs)
    jar_id = rt.model.body("jar").id
    assert rt.model.neq == 0  # no weld or other equality constraint anywhere
    z0 = float(rt.data.xpos[jar_id][2])
    for command in (
        Release(arm=Arm.LEFT, opening=0.5),
        MoveTool(arm=Arm.LEFT, target=poses.jar_pregrasp, duration=3.0),
        MoveTool(arm=Arm.LEFT, target=poses.jar_grasp, duration=1.5),
        Grasp(arm=Arm.LEFT, spread=0.0),
    ):
        result = run(rt, command)
        assert isinstance(result, CommandResult) and result.ok, (command, result)
    hand_z0 = rt.grip("left").translation[2]
    lift = Pose(
        position=(
            poses.jar_grasp.position[0],
            poses.jar_grasp.position[1],
            poses.jar_grasp.position[2] + 0.1,
        ),
        orientation=poses.jar_grasp.orientation,
    )
    result = run(rt, MoveTool(arm=Arm.LEFT, target=lift, duration=1.5))
    assert isinstance(result, CommandResult) and result.ok, result
    for _ in range(500):
        rt.cycle()
    hand_rise = rt.grip("left").translation[2] - hand_z0
    jar_rise = float(rt.data.xpos[jar_id][2]) - z0
    assert hand_rise > 0.09
    assert jar_rise > 0.08 and math.isclose(jar_rise, hand_rise, abs_tol=0.02)
    assert rt.held["left"] == jar_id


# ---------------------------------------------------------------- the law against a reference

# arm configurations with every joint outside the joint-limit and singularity bands
Q_RIGHT = np.array([1.46, -0.98, -0.15, 1.7, -0.2, 1.26, 2.29])
Q_LEFT = np.array([0.3, 1.6, -1.25, -0.85, 0.1, 0.7, 0.2])


def _reference_damping(stiffness: np.ndarray, inertia: np.ndarray, xi: float) -> np.ndarray:
    """Double diagonalisation written out: Λ = L Lᵀ, L⁻¹ K L⁻ᵀ = U S Uᵀ, D = L U 2ξ√S Uᵀ Lᵀ."""
    chol = np.linalg.cholesky(inertia)
    li = np.linalg.inv(chol)
    s, u = np.linalg.eigh(li @ stiffness @ li.T)
    q = chol @ u
    return q @ np.diag(2.0 * xi * np.sqrt(np.clip(s, 0.0, None))) @ q.T


def _reference_torques(
    ctrl: VelmaController, q: np.ndarray, v: np.ndarray
) -> tuple[dict[str, np.ndarray], float]:
    """The documented law (impedance.py module docstring), slowly, without safety terms or
    limits, on a Pinocchio data of its own."""
    robot = ctrl.robot
    data = robot.model.createData()
    pin.computeJointJacobians(robot.model, data, q)
    pin.updateFramePlacements(robot.model, data)
    mass = pin.crba(robot.model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    nle = pin.nonLinearEffects(robot.model, data, q, v)
    out = {}
    for side in SIDES:
        sl = ctrl.arm_slice[side]
        cmd = ctrl.arm[side]
        m_arm = mass[sl, sl]
        if cmd.mode == "cart":
            fid = robot.grip_frame_id[side]
            cur = data.oMf[fid]
            jac = pin.getFrameJacobian(robot.model, data, fid, pin.LOCAL)[:, sl]
            quat = pin.Quaternion(cur.rotation.T @ cmd.pose.rotation)
            vec = np.array([quat.x, quat.y, quat.z]) * (1.0 if quat.w >= 0 else -1.0)
            p = np.concatenate([cur.rotation.T @ (cmd.pose.translation - cur.translation), vec])
            twist_d = np.concatenate([cur.rotation.T @ cmd.twist[:3], cur.rotation.T @ cmd.twist[3:]])
            m_inv = np.linalg.inv(m_arm)
            lam = np.linalg.inv(jac @ m_inv @ jac.T + LAMBDA_REGULARISATION * np.eye(6))
            kmat = np.diag(cmd.stiffness)
            dmat = _reference_damping(kmat, lam, DAMPING_RATIO)
            null = np.eye(7) - jac.T @ lam @ jac @ m_inv
            tau_ns = NULLSPACE_STIFFNESS * (cmd.posture - q[sl]) - NULLSPACE_DAMPING * v[sl]
            out[side] = jac.T @ (kmat @ p + dmat @ (twist_d - jac @ v[sl])) + null @ tau_ns + nle[sl]
        else:
            k, xi = (
                (SAFE_STIFFNESS, SAFE_DAMPING_RATIO)
                if cmd.mode == "safe"
                else (cmd.joint_stiffness, DAMPING_RATIO)
            )
            kmat = np.diag(np.full(7, k))
            dmat = _reference_damping(kmat, m_arm, xi)
            out[side] = kmat @ (cmd.q - q[sl]) + dmat @ (cmd.qd - v[sl]) + nle[sl]
    t = ctrl.torso_idx
    d_t = 2.0 * DAMPING_RATIO * math.sqrt(TORSO_STIFFNESS * mass[t, t])
    torso = TORSO_STIFFNESS * (ctrl.torso_q - q[t]) + d_t * (ctrl.torso_qd - v[t]) + nle[t]
    return out, float(torso)


def _controller(seed: int) -> tuple[VelmaController, np.ndarray, np.ndarray]:
    """A controller with q, v in which no safety term acts (|q̇| < 2 rad/s, no band)."""
    rng = np.random.default_rng(seed)
    ctrl = VelmaController(RobotModel(), 0.001)
    q = rng.normal(0.0, 0.1, 33)
    q[ctrl.arm_slice["right"]] = Q_RIGHT + rng.normal(0.0, 0.03, 7)
    q[ctrl.arm_slice["left"]] = Q_LEFT + rng.normal(0.0, 0.03, 7)
    v = rng.normal(0.0, 0.4, 33)
    v[ctrl.torso_idx] = 0.2
    ctrl.kinematics(q, v)
    ctrl.torso_q, ctrl.torso_qd = 0.05, 0.1
    return ctrl, q, v


def _cartesian_setpoint(
    ctrl: VelmaController, side: str, q: np.ndarray, rng: np.random.Generator, angle: float = 0.15
) -> None:
    """A pose near the grip (rotated by ``angle`` rad), a setpoint twist, a posture near q."""
    cmd = ctrl.arm[side]
    grip = ctrl.grip_pose(side)
    axis = rng.normal(size=3)
    cmd.mode = "cart"
    cmd.pose = pin.SE3(
        grip.rotation @ pin.exp3(angle * axis / np.linalg.norm(axis)),
        grip.translation + rng.normal(0, 0.02, 3),
    )
    cmd.twist = rng.normal(0.0, 0.1, 6)
    cmd.stiffness = np.array([1000.0, 700.0, 1300.0, 150.0, 90.0, 120.0])
    cmd.posture = q[ctrl.arm_slice[side]] + rng.normal(0.0, 0.1, 7)


def _assert_no_safety_term(ctrl: VelmaController, q: np.ndarray, v: np.ndarray) -> None:
    for side in SIDES:
        sl = ctrl.arm_slice[side]
        qa = q[sl]
        assert np.all(np.abs(v[sl]) < limits.ARM_VELOCITY_LIMIT)
        dist = np.minimum(
            ctrl.robot.model.upperPositionLimit[sl] - qa, qa - ctrl.robot.model.lowerPositionLimit[sl]
        )
        assert np.all(dist > limits.LIMIT_BAND)
        singular = np.abs(qa[list(limits.SINGULAR_JOINTS)])
        assert np.all(singular > limits.SINGULARITY_HALF_WIDTH + limits.SINGULARITY_BAND)
    assert abs(v[ctrl.torso_idx]) < limits.TORSO_VELOCITY_LIMIT


@pytest.mark.parametrize("seed", range(3))
def test_cartesian_law_equals_the_documented_law(seed: int) -> None:
    ctrl, q, v = _controller(seed)
    rng = np.random.default_rng(100 + seed)
    for side in SIDES:
        _cartesian_setpoint(ctrl, side, q, rng)
    _assert_no_safety_term(ctrl, q, v)
    expected, torso = _reference_torques(ctrl, q, v)
    for side in SIDES:
        assert np.all(np.abs(expected[side]) < ARM_TORQUE_LIMIT)  # no clipping in this case
    torques, tau_torso = ctrl.update(q, v)
    for side in SIDES:
        np.testing.assert_allclose(torques[side], expected[side], rtol=0, atol=1e-9)
    assert tau_torso == pytest.approx(torso, abs=1e-9)


def test_cartesian_bands_act_through_the_null_space_but_the_elbow() -> None:
    """In Cartesian mode the band torques join τ_ns (projected by N, scaled by 0.25), joint
    3's act in full."""
    ctrl, q, v = _controller(8)
    sl = ctrl.arm_slice["left"]
    q[sl.start + 5] = 0.3  # wrist: 0.16 rad into the singularity band (|q| < 0.46)
    q[sl.start + 3] = ctrl.robot.model.lowerPositionLimit[sl][3] + 0.1  # elbow: in its limit band
    ctrl.kinematics(q, v)
    rng = np.random.default_rng(12)
    for side in SIDES:
        _cartesian_setpoint(ctrl, side, q, rng)
    lim = ctrl.limits
    wrist = lim.singularity_band_torque * ((0.46 - 0.3) / 0.26) ** 2  # pushes up, away from 0
    elbow = lim.limit_band_torque * (0.16 / 0.26) ** 2  # pushes up, away from the lower limit
    # the bands' damping, with the joint's inertia and the band stiffness peak / width
    mass = pin.crba(ctrl.robot.model, ctrl.robot.model.createData(), q)
    xi = lim.band_damping_ratio
    wrist -= (
        2
        * xi
        * math.sqrt(lim.singularity_band_torque / 0.26 * mass[sl.start + 5, sl.start + 5])
        * v[sl.start + 5]
    )
    elbow -= (
        2 * xi * math.sqrt(lim.limit_band_torque / 0.26 * mass[sl.start + 3, sl.start + 3]) * v[sl.start + 3]
    )
    plain, _ = _reference_torques(ctrl, q, v)
    # the reference again with the wrist band added to the posture torque (i.e. through N)
    posture = ctrl.arm["left"].posture.copy()
    scale = lim.null_space_band_scale
    ctrl.arm["left"].posture = posture + np.eye(7)[5] * scale * wrist / NULLSPACE_STIFFNESS
    through_null, _ = _reference_torques(ctrl, q, v)
    ctrl.arm["left"].posture = posture
    expected = through_null["left"].copy()
    expected[3] += elbow
    torques, _ = ctrl.update(q, v)
    np.testing.assert_allclose(torques["right"], plain["right"], atol=1e-9)
    np.testing.assert_allclose(torques["left"], expected, atol=1e-9)
    assert not np.allclose(torques["left"], plain["left"] + np.eye(7)[5] * wrist, atol=1e-3)
    assert scale == 0.25


@pytest.mark.parametrize("angle", [0.0, 1.0, 2.9, 3.1])
def test_cartesian_error_is_the_quaternion_error_in_the_grip_frame(angle: float) -> None:
    ctrl, q, v = _controller(7)
    rng = np.random.default_rng(3)
    for side in SIDES:
        _cartesian_setpoint(ctrl, side, q, rng, angle=angle)
    ctrl.update(q, v)
    for side in SIDES:
        expected = pose_error(ctrl.grip_pose(side), ctrl.arm[side].pose)
        np.testing.assert_allclose(ctrl.state[side].error, expected, atol=1e-12)


def test_joint_and_safe_law_equal_the_documented_law() -> None:
    ctrl, q, v = _controller(11)
    v[ctrl.arm_slice["left"]] *= 0.2  # safe mode is soft: keep its torques small and exact
    ctrl.arm["right"].mode = "joint"
    ctrl.arm["right"].q = q[ctrl.arm_slice["right"]] + 0.05
    ctrl.arm["right"].qd = np.full(7, 0.1)
    ctrl.safe("left", q[ctrl.arm_slice["left"]] - 0.1)
    _assert_no_safety_term(ctrl, q, v)
    expected, torso = _reference_torques(ctrl, q, v)
    torques, tau_torso = ctrl.update(q, v)
    for side in SIDES:
        np.testing.assert_allclose(torques[side], expected[side], rtol=0, atol=1e-9)
    assert tau_torso == pytest.approx(torso, abs=1e-9)


def test_safe_mode_gains() -> None:
    """K = 5 N·m/rad on every arm joint and damping ratio 1.9 on every mode of M."""
    ctrl, q, v = _controller(5)
    sl = ctrl.arm_slice["left"]
    data = ctrl.robot.data
    v0 = v.copy()
    v0[sl] = 0.0
    ctrl.safe("left", q[sl] + 0.1)  # a 0.1 rad spring deflection on each joint, at rest
    torques, _ = ctrl.update(q, v0)
    gravity = data.nle[sl].copy()
    np.testing.assert_allclose(torques["left"] - gravity, np.full(7, 5.0 * 0.1), atol=1e-9)
    # at the setpoint, moving: τ − nle = −D q̇, D of modal damping ratio 1.9
    ctrl2 = VelmaController(ctrl.robot, 0.001)
    ctrl2.safe("left", q[sl])
    v1 = v0.copy()
    v1[sl] = np.linspace(-0.5, 0.5, 7)
    torques, _ = ctrl2.update(q, v1)
    mass = np.triu(data.M) + np.triu(data.M, 1).T
    m_arm = mass[sl, sl]
    dmat_v = -(torques["left"] - data.nle[sl])
    # recover D from several velocities, then check it modally against K = 5 I and M
    cols = []
    for k in range(7):
        vk = v0.copy()
        vk[sl] = np.eye(7)[k] * 0.3
        ctrl_k = VelmaController(ctrl.robot, 0.001)
        ctrl_k.safe("left", q[sl])
        tk, _ = ctrl_k.update(q, vk)
        cols.append(-(tk["left"] - data.nle[sl]) / 0.3)
    dmat = np.array(cols).T
    np.testing.assert_allclose(dmat @ v1[sl], dmat_v, atol=1e-9)
    chol = np.linalg.cholesky(m_arm)
    li = np.linalg.inv(chol)
    s, u = np.linalg.eigh(li @ (SAFE_STIFFNESS * np.eye(7)) @ li.T)
    modal = u.T @ li @ dmat @ li.T @ u
    np.testing.assert_allclose(modal, np.diag(2 * SAFE_DAMPING_RATIO * np.sqrt(s)), atol=1e-8)
    assert SAFE_STIFFNESS == 5.0 and SAFE_DAMPING_RATIO == 1.9


def test_fast_double_diagonalisation_equals_the_cholesky_form() -> None:
    rng = np.random.default_rng(1)
    for n in (6, 7):
        a = rng.normal(size=(n, n))
        inertia = a @ a.T + n * np.eye(n)
        k = rng.uniform(5.0, 1500.0, n)
        np.testing.assert_allclose(
            diagonal_double_diagonalisation_damping(k, inertia, 0.7),
            double_diagonalisation_damping(np.diag(k), inertia, 0.7),
            rtol=1e-9,
            atol=1e-9,
        )
    with pytest.raises(ValueError):
        diagonal_double_diagonalisation_damping(np.array([1.0, 0.0]), np.eye(2), 0.7)


def test_zero_stiffness_falls_back_to_the_general_form() -> None:
    ctrl, q, v = _controller(2)
    rng = np.random.default_rng(9)
    for side in SIDES:
        _cartesian_setpoint(ctrl, side, q, rng)
    ctrl.arm["left"].stiffness = np.array([1000.0, 0.0, 1000.0, 150.0, 150.0, 0.0])
    expected, _ = _reference_torques(ctrl, q, v)
    torques, _ = ctrl.update(q, v)
    np.testing.assert_allclose(torques["left"], expected["left"], atol=1e-9)


def test_torque_and_rate_limits() -> None:
    ctrl, q, v = _controller(4)
    for side in SIDES:
        ctrl.arm[side].mode = "joint"
        ctrl.arm[side].q = q[ctrl.arm_slice[side]] + 2.0  # 400 N·m of spring: clipped
    first, _ = ctrl.update(q, v)
    for side in SIDES:
        assert np.all(np.abs(first[side]) <= ARM_TORQUE_LIMIT + 1e-12)
        assert np.any(np.isclose(np.abs(first[side]), ARM_TORQUE_LIMIT))
        ctrl.arm[side].q = q[ctrl.arm_slice[side]] - 2.0
    second, _ = ctrl.update(q, v)
    step = TORQUE_RATE_LIMIT * ctrl.dt
    for side in SIDES:
        assert np.all(np.abs(second[side] - first[side]) <= step + 1e-12)
        assert np.allclose(np.abs(second[side] - first[side]), step)


# ---------------------------------------------------------------- safety terms, in simulation


def _runtime_with(**limit_changes: float) -> Runtime:
    rt = Runtime(seed=0, n_particles=0)
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    rt.ctrl.limits = dataclasses.replace(rt.ctrl.limits, **limit_changes)
    return rt


def test_band_torque_is_the_documented_profile() -> None:
    ctrl, q, v = _controller(6)
    sl = ctrl.arm_slice["left"]
    upper = ctrl.robot.model.upperPositionLimit[sl]
    q[sl.start + 1] = upper[1] - 0.1  # 0.16 rad into the 0.26 rad band of joint 1
    v[sl] = 0.0
    ctrl.hold("left", q[sl])
    torques, _ = ctrl.update(q, v)
    band = -limits.LIMIT_BAND_TORQUE * ((0.26 - 0.1) / 0.26) ** 2
    expected = ctrl.robot.data.nle[sl].copy()
    expected[1] += band
    np.testing.assert_allclose(torques["left"], expected, atol=1e-9)
    assert band < -5.0  # pushes down, away from the upper limit


@pytest.mark.parametrize("band_torque", [limits.LIMIT_BAND_TORQUE, 0.0])
def test_limit_band_pushes_a_joint_away_from_its_limit(band_torque: float) -> None:
    rt = _runtime_with(limit_band_torque=band_torque)
    side = "left"
    upper = rt.robot.model.upperPositionLimit[rt.ctrl.arm_slice[side]][1]
    target = rt.arm_q(side)
    target[1] = upper - 0.02  # the joint impedance pulls joint 1 almost onto its limit
    target[0] = 0.8  # the arm turned out: from home, its fingers would meet the torso first
    rt.ctrl.hold(side, target)
    rt.ctrl.arm[side].joint_stiffness = 20.0
    for _ in range(3000):
        rt.cycle()
    distance = upper - rt.arm_q(side)[1]
    if band_torque > 0:
        assert distance > 0.1  # held off by the band
    else:
        assert distance < 0.04  # without it the joint goes where it is pulled


@pytest.mark.parametrize("band_torque", [limits.SINGULARITY_BAND_TORQUE, 0.0])
def test_singularity_band_keeps_the_elbow_out_of_the_stretch(band_torque: float) -> None:
    """A Cartesian target 0.4 m beyond the grip, away from the shoulder, asks for a stretched
    arm (joint 3 → 0); the band keeps joint 3 outside ±0.2 rad."""
    rt = _runtime_with(singularity_band_torque=band_torque)
    side = "left"
    model, data = rt.robot.model, rt.robot.data
    shoulder = data.oMi[model.getJointId(f"{side}_arm_1_joint")].translation.copy()
    grip = rt.grip(side).copy()
    away = (grip.translation - shoulder) / np.linalg.norm(grip.translation - shoulder)
    cmd = rt.ctrl.arm[side]
    cmd.mode = "cart"
    cmd.posture = rt.arm_q(side)
    duration = 3.0
    q3 = []
    for i in range(5000):
        s = min(1.0, i * rt.ctrl.dt / duration)
        cmd.pose = pin.SE3(grip.rotation, grip.translation + s * 0.4 * away)
        cmd.twist = np.concatenate([away * 0.4 / duration if s < 1.0 else np.zeros(3), np.zeros(3)])
        rt.cycle()
        q3.append(rt.arm_q(side)[3])
    closest = float(np.min(np.abs(q3)))
    if band_torque > 0:
        assert closest > limits.SINGULARITY_HALF_WIDTH
    else:
        assert closest < 0.15  # the target does ask for a stretched elbow


@pytest.mark.parametrize("velocity_limit", [limits.ARM_VELOCITY_LIMIT, math.inf])
def test_velocity_limit_brakes_a_fast_joint(velocity_limit: float) -> None:
    """A 1 rad step of the shoulder (joint 1) under joint impedance K = 200 N·m/rad."""
    rt = _runtime_with(arm_velocity=velocity_limit)
    side = "left"
    target = rt.arm_q(side)
    target[1] -= 1.0
    rt.ctrl.hold(side, target)
    sl = rt.ctrl.arm_slice[side]
    peak = 0.0
    for _ in range(1500):
        rt.cycle()
        peak = max(peak, float(np.abs(rt.v()[sl]).max()))
    assert np.abs(rt.arm_q(side) - target).max() < 0.01  # the step is still made
    if math.isfinite(velocity_limit):
        assert peak < velocity_limit + 0.2
    else:
        assert peak > limits.ARM_VELOCITY_LIMIT + 0.8  # without the limit it moves faster


def test_hold_keeps_position_under_gravity() -> None:
    rt = Runtime(seed=0, n_particles=0)
    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    start = rt.grip("left").copy()
    cmd = rt.ctrl.arm["left"]
    cmd.mode = "cart"
    cmd.posture = rt.arm_q("left")
    cmd.pose = pin.SE3(start.rotation, start.translation + np.array([0.05, 0.0, 0.08]))
    for _ in range(1500):  # away from the initial rest configuration
        rt.cycle()
    for side in SIDES:
        rt.ctrl.hold(side)  # at the configuration measured in the last update
        assert rt.ctrl.arm[side].mode == "joint" and rt.ctrl.arm[side].joint_stiffness == 200.0
    held = {s: rt.ctrl.arm[s].q.copy() for s in SIDES}
    for _ in range(2000):
        rt.cycle()
    for side in SIDES:
        assert np.abs(rt.arm_q(side) - held[side]).max() < 2e-3
    # gravity is there: the shoulder carries a large torque while the arm does not move
    assert abs(rt.ctrl.state["left"].torque[1]) > 5.0


def test_hold_and_safe_arguments() -> None:
    ctrl = VelmaController(RobotModel(), 0.001)
    with pytest.raises(RuntimeError):
        ctrl.hold("left")
    with pytest.raises(ValueError):
        ctrl.safe("left", np.zeros(6))
    ctrl.arm["right"].mode = "relax"
    with pytest.raises(ValueError):
        ctrl.update(np.zeros(33), np.zeros(33))


def test_the_head_keeps_looking_at_its_point_while_the_torso_turns() -> None:
    """LookAt sets a gaze; a torso turn afterwards re-aims the head at the same world point
    (the planner looks at the furniture, then faces it). Head angles given by MoveJoints end
    the gaze: the head then holds them through a turn."""
    from shared.fipa_codec.languages.l_ex import LookAt, MoveJoints
    from velma.executor.primitives import look_angles

    rt = Runtime(seed=0, n_particles=0)

    rt.observe_by_camera = False  # ground-truth poses: this test is about control, not perception
    point = np.array([0.7, 0.0, 0.9])  # the cabinet's view point
    assert isinstance(r := run(rt, LookAt(point=tuple(point))), CommandResult) and r.ok
    assert run(rt, MoveJoints(positions={"torso_0_joint": -0.8}, duration=1.0)).ok  # type: ignore[union-attr]
    for _ in range(1500):  # the head servo catches up (≤ 1.04 rad/s)
        rt.cycle()
    wanted, _ = look_angles(rt, point)
    head = rt.data.qpos[rt.head_qadr]
    assert abs(wanted[0]) > 0.7  # the point is now off to the side ...
    assert np.max(np.abs(head - wanted)) < 0.03  # ... and the head looks at it
    held = head.copy()
    assert run(rt, MoveJoints(positions={"head_pan_joint": float(held[0])}, duration=0.2)).ok  # type: ignore[union-attr]
    assert rt.gaze is None
    assert run(rt, MoveJoints(positions={"torso_0_joint": 0.0}, duration=1.0)).ok  # type: ignore[union-attr]
    assert abs(rt.data.qpos[rt.head_qadr][0] - held[0]) < 0.03
