"""Impedance control laws of Velma's arms and torso, computed with Pinocchio.

Cartesian impedance, per arm (velma-facts.md "Control on the real robot", paper §5.3):

    τ = Jᵀ (K p + D (J q̇_d − J q̇)) + N τ_ns + g(q) + C(q, q̇) q̇

- ``J`` (6 × 7) is the grip frame's Jacobian in that frame (Pinocchio ``LOCAL``) for the
  seven arm joints; ``p`` = (R⁻¹ (p_cmd − p), vec(quat(R⁻¹ R_cmd))): translation error and
  the vector part of the error quaternion, both in the current end-effector frame, as on the
  real robot (so the rotational stiffness acts on ≈ half the angle).
- ``Λ = (J M⁻¹ Jᵀ)⁻¹``; damping by double diagonalisation of K and Λ with damping ratio ξ
  (0.7 by default, the "calmer simulation" value of the facts).
- ``N = I − Jᵀ Λ J M⁻¹`` (dynamically consistent null space); ``τ_ns`` is a joint-space
  posture spring-damper.
- ``g + C q̇`` is Pinocchio's ``nonLinearEffects``.
- The desired twist (feed-forward of the setpoint velocity) enters the damping term, so a
  moving setpoint is tracked without lag from D.

Joint impedance (MoveJoints, torso): τ = K (q_d − q) + D (q̇_d − q̇) + g + C q̇, D from the
generalised eigenproblem of K and M (double diagonalisation), ξ = 0.7.

Simplifications (named):
- Each arm's law uses the 7 × 7 arm block of the full 33-DOF mass matrix: the coupling to the
  torso, head and finger joints is neglected in Λ and N (the torso is held by its own stiff
  joint impedance; the fingers are light).
- The torso is not part of the Cartesian chain (the real robot stacks 15 DOF); it is held by
  joint impedance K = 1200 N·m/rad.
- The payload (a held object) is not compensated; the impedance absorbs it as a small sag.
- Torques are clipped to the joint limits (100 N·m joints 0–4, 60 N·m joints 5–6) and their
  change per cycle to ``TORQUE_RATE_LIMIT`` × dt.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from velma.control.robot_model import SIDES, TORSO_JOINT, Array, RobotModel, arm_joints

DEFAULT_CART_STIFFNESS = (1000.0, 1000.0, 1000.0, 150.0, 150.0, 150.0)
"""N/m (x, y, z) and N·m/rad (rx, ry, rz), in the grip frame (velma-facts.md, tests value)."""
DAMPING_RATIO = 0.7
ARM_JOINT_STIFFNESS = 200.0  # N·m/rad (Velma jnt_imp for the arms)
TORSO_STIFFNESS = 1200.0  # N·m/rad
NULLSPACE_STIFFNESS = 10.0  # N·m/rad
NULLSPACE_DAMPING = 2.0  # N·m·s/rad
ARM_TORQUE_LIMIT = np.array([100.0, 100.0, 100.0, 100.0, 100.0, 60.0, 60.0])  # N·m
TORSO_TORQUE_LIMIT = 300.0  # N·m (placeholder: not in the facts)
TORQUE_RATE_LIMIT = 1000.0  # N·m/s (1 N·m per 1 ms tick, as franka_ros)
LAMBDA_REGULARISATION = 1e-3  # 1/kg, bounds Λ near singularities


def double_diagonalisation_damping(stiffness: Array, inertia: Array, xi: float) -> Array:
    """Damping matrix D (n × n) giving every mode of ``inertia`` ẍ + D ẋ + ``stiffness`` x = 0
    the damping ratio ``xi``.

    ``stiffness`` (n × n, symmetric positive semi-definite) and ``inertia`` (n × n, symmetric
    positive definite). With Λ = L Lᵀ (Cholesky) and L⁻¹ K L⁻ᵀ = U S Uᵀ, Q = L U gives
    Λ = Q Qᵀ, K = Q S Qᵀ and D = Q (2 ξ √S) Qᵀ. Raises ``numpy.linalg.LinAlgError`` if
    ``inertia`` is not positive definite.
    """
    chol = np.linalg.cholesky(inertia)
    linv = np.linalg.inv(chol)
    ktilde = linv @ stiffness @ linv.T
    s, u = np.linalg.eigh(0.5 * (ktilde + ktilde.T))
    q = chol @ u
    out: Array = q @ np.diag(2.0 * xi * np.sqrt(np.clip(s, 0.0, None))) @ q.T
    return out


def pose_error(current: pin.SE3, target: pin.SE3) -> Array:
    """Impedance error p (6,) in the current frame: (R⁻¹ (p_t − p), vec(quat(R⁻¹ R_t)) with
    w ≥ 0). Units m and (dimensionless ≈ half-angle)."""
    rot_err = current.rotation.T @ target.rotation
    q = pin.Quaternion(rot_err)
    vec = np.array([q.x, q.y, q.z])
    if q.w < 0:
        vec = -vec
    return np.concatenate([current.rotation.T @ (target.translation - current.translation), vec])


@dataclass
class ArmCommand:
    """Setpoint of one arm. ``mode`` is ``"cart"`` (pose ``pose``: world SE3, twist
    ``twist`` (6,) world (v, ω), stiffness ``stiffness`` (6,), null-space posture
    ``posture`` (7,) rad) or ``"joint"`` (``q`` (7,) rad, ``qd`` (7,) rad/s, joint stiffness
    ``joint_stiffness`` N·m/rad)."""

    mode: str = "joint"
    pose: pin.SE3 = field(default_factory=pin.SE3.Identity)
    twist: Array = field(default_factory=lambda: np.zeros(6))
    stiffness: Array = field(default_factory=lambda: np.array(DEFAULT_CART_STIFFNESS))
    posture: Array = field(default_factory=lambda: np.zeros(7))
    q: Array = field(default_factory=lambda: np.zeros(7))
    qd: Array = field(default_factory=lambda: np.zeros(7))
    joint_stiffness: float = ARM_JOINT_STIFFNESS


@dataclass
class ArmState:
    """Quantities of one arm computed each cycle (for monitoring): grip pose (world), the
    Cartesian error (6,) and the commanded torque (7,)."""

    grip: pin.SE3 = field(default_factory=pin.SE3.Identity)
    error: Array = field(default_factory=lambda: np.zeros(6))
    torque: Array = field(default_factory=lambda: np.zeros(7))


class VelmaController:
    """Computes arm and torso torques each cycle from Pinocchio's q, v (rad, rad/s, (33,)).

    Call ``update`` once per control cycle; it runs forward kinematics, the joint Jacobians,
    CRBA and the non-linear effects on the full model, then both arm laws and the torso law.
    """

    def __init__(self, robot: RobotModel, dt: float = 0.001) -> None:
        self.robot = robot
        self.dt = dt
        self.arm_idx = {s: robot.v_indices(arm_joints(s)) for s in SIDES}
        self.arm_slice = {s: slice(int(i[0]), int(i[-1]) + 1) for s, i in self.arm_idx.items()}
        for side, idx in self.arm_idx.items():
            if not np.array_equal(idx, np.arange(idx[0], idx[0] + 7)):
                raise RuntimeError(f"{side} arm joints are not contiguous in Pinocchio's v")
        self.torso_idx = robot.v_index(TORSO_JOINT)
        self.arm = {s: ArmCommand() for s in SIDES}
        self.torso_q = 0.0
        self.torso_qd = 0.0
        self.state = {s: ArmState() for s in SIDES}
        self.prev_arm_tau = {s: np.zeros(7) for s in SIDES}
        self.prev_torso_tau = 0.0
        self._first = True

    def kinematics(self, q: Array, v: Array) -> None:
        """Forward kinematics, Jacobians, M (upper triangle) and nle for ``q``, ``v``."""
        model, data = self.robot.model, self.robot.data
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        pin.crba(model, data, q)
        pin.nonLinearEffects(model, data, q, v)

    def grip_pose(self, side: str) -> pin.SE3:
        """World pose of ``side``'s grip frame after ``kinematics``."""
        out: pin.SE3 = self.robot.data.oMf[self.robot.grip_frame_id[side]]
        return out.copy()

    def update(self, q: Array, v: Array) -> tuple[dict[str, Array], float]:
        """Torques: per side (7,) N·m and the torso's N·m, limited (see module docstring)."""
        self.kinematics(q, v)
        data = self.robot.data
        torques: dict[str, Array] = {}
        for side in SIDES:
            sl = self.arm_slice[side]
            m_upper = data.M[sl, sl]
            m_arm = np.triu(m_upper) + np.triu(m_upper, 1).T
            cmd = self.arm[side]
            if cmd.mode == "cart":
                tau = self._cartesian(side, cmd, q[sl], v[sl], m_arm)
            else:
                self.state[side].grip = self.grip_pose(side)
                kq = np.full(7, cmd.joint_stiffness)
                dmat = double_diagonalisation_damping(np.diag(kq), m_arm, DAMPING_RATIO)
                tau = kq * (cmd.q - q[sl]) + dmat @ (cmd.qd - v[sl])
            tau = tau + data.nle[sl]
            tau = self._limit(tau, self.prev_arm_tau[side], ARM_TORQUE_LIMIT)
            self.prev_arm_tau[side] = tau
            self.state[side].torque = tau
            torques[side] = tau
        t = self.torso_idx
        m_tt = float(data.M[t, t])
        d_t = 2.0 * DAMPING_RATIO * np.sqrt(TORSO_STIFFNESS * m_tt)
        tau_t = TORSO_STIFFNESS * (self.torso_q - q[t]) + d_t * (self.torso_qd - v[t]) + float(data.nle[t])
        tau_t = float(
            self._limit(np.array([tau_t]), np.array([self.prev_torso_tau]), np.array([TORSO_TORQUE_LIMIT]))[0]
        )
        self.prev_torso_tau = tau_t
        self._first = False
        return torques, tau_t

    def _cartesian(self, side: str, cmd: ArmCommand, q_arm: Array, v_arm: Array, m_arm: Array) -> Array:
        model, data = self.robot.model, self.robot.data
        fid = self.robot.grip_frame_id[side]
        cur: pin.SE3 = data.oMf[fid]
        jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL)[:, self.arm_slice[side]]
        err = pose_error(cur, cmd.pose)
        rt = cur.rotation.T
        twist_d = np.concatenate([rt @ cmd.twist[:3], rt @ cmd.twist[3:]])
        m_inv = np.linalg.inv(m_arm)
        a = jac @ m_inv @ jac.T
        lam = np.linalg.inv(a + LAMBDA_REGULARISATION * np.eye(6))
        kmat = np.diag(cmd.stiffness)
        dmat = double_diagonalisation_damping(kmat, lam, DAMPING_RATIO)
        wrench = kmat @ err + dmat @ (twist_d - jac @ v_arm)
        tau = jac.T @ wrench
        null = np.eye(7) - jac.T @ lam @ jac @ m_inv
        tau_ns = NULLSPACE_STIFFNESS * (cmd.posture - q_arm) - NULLSPACE_DAMPING * v_arm
        st = self.state[side]
        st.grip = cur.copy()
        st.error = err
        out: Array = tau + null @ tau_ns
        return out

    def _limit(self, tau: Array, prev: Array, limit: Array) -> Array:
        rate = np.inf if self._first else TORQUE_RATE_LIMIT * self.dt
        out: Array = np.clip(np.clip(tau, prev - rate, prev + rate), -limit, limit)
        return out
