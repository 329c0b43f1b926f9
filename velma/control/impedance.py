"""Impedance control laws of Velma's arms and torso, computed with Pinocchio (paper §5.3,
velma/model/README.md "Control"; torques in N·m, q in rad, q̇ in rad/s, poses in m).

Cartesian impedance, per arm: τ = Jᵀ (K p + D (J q̇_d − J q̇)) + N τ_ns + g(q) + C(q, q̇) q̇ +
τ_safety, with ``J`` (6 × 7) the grip frame's Jacobian in that frame (Pinocchio ``LOCAL``),
``p`` = (R⁻¹ (p_cmd − p), vec(quat(R⁻¹ R_cmd))) (translation error and the error quaternion's
vector part, w ≥ 0, in the current end-effector frame, as on the real robot), ``Λ = (J M⁻¹ Jᵀ
+ εI)⁻¹`` (ε = ``LAMBDA_REGULARISATION``), D by double diagonalisation of K and Λ with damping
ratio ξ (0.7 by default; Velma: 0.35), ``N = I − Jᵀ Λ J M⁻¹`` (dynamically consistent null
space), ``τ_ns`` a joint-space posture spring-damper and ``g + C q̇`` Pinocchio's
``nonLinearEffects``, plus in every mode the weight of what the hand holds, τ_load
(velma/control/payload.py). The setpoint's twist enters the damping term, so a moving setpoint is
tracked without lag from D.

Joint impedance (mode ``"joint"``: MoveJoints and ``hold``; mode ``"safe"``; the torso):
τ = K (q_d − q) + D (q̇_d − q̇) + g + C q̇ + τ_safety, D from the generalised eigenproblem of K
and M. Gains: ``"joint"`` K = 200 N·m/rad, ξ = 0.7 (Velma: 0.5); ``"safe"`` K = 5 N·m/rad,
ξ = 1.9; torso K = 1200 N·m/rad, ξ = 0.7.

``τ_safety`` (velma/control/limits.py): the joint-limit band (all modes) and the singularity
band of joints 1, 3, 5 (Cartesian mode), in full in joint and safe mode, in Cartesian mode
through the null space scaled by ``NULL_SPACE_BAND_SCALE`` (joint 3 in full); braking of
joint velocity over 2 rad/s (arms) or 0.52 rad/s (torso), τ = −M (q̇ − sat(q̇)) / T_v, after
the torque rate limit (``TORQUE_RATE_LIMIT`` × dt per cycle, not on the first) and before the
torque limits (100 N·m joints 0–4, 60 N·m joints 5–6, torso 300 N·m); the wrist's
self-collision band (velma/control/self_collision.py, all modes, in full).

How each term is computed (Pinocchio calls, Eigen decompositions, what is never formed):
docs/executor.md "How the law is computed"; where the law departs from the real robot's:
velma/model/README.md "Where the model departs from the real robot".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import eigenpy  # Eigen's decompositions, installed with (and imported by) pinocchio
import numpy as np
import pinocchio as pin

from velma.control.joints import SIDES, TORSO_JOINT, Array, arm_joints
from velma.control.limits import (
    ARM_TORQUE_LIMIT,
    ARM_VELOCITY_LIMIT,
    BAND_DAMPING_RATIO,
    FULL_BAND_JOINTS,
    LIMIT_BAND,
    LIMIT_BAND_TORQUE,
    NULL_SPACE_BAND_SCALE,
    SINGULAR_JOINTS,
    SINGULARITY_BAND,
    SINGULARITY_BAND_TORQUE,
    SINGULARITY_HALF_WIDTH,
    TORQUE_RATE_LIMIT,
    TORSO_TORQUE_LIMIT,
    TORSO_VELOCITY_LIMIT,
    VELOCITY_LIMIT_TIME_CONSTANT,
    BoolArray,
    band_damping,
    position_band_torque,
    singularity_band_torque,
    velocity_limit_torque,
)
from velma.control.payload import NO_PAYLOAD, Payload, payload_torque
from velma.control.robot_model import RobotModel
from velma.control.self_collision import WristField, wrist_band_torque, wrist_field

__all__ = [
    "ARM_JOINT_STIFFNESS",
    "ARM_TORQUE_LIMIT",
    "DAMPING_RATIO",
    "DEFAULT_CART_STIFFNESS",
    "HOLD_STIFFNESS",
    "SAFE_DAMPING_RATIO",
    "SAFE_STIFFNESS",
    "TORQUE_RATE_LIMIT",
    "TORSO_TORQUE_LIMIT",
    "ArmCommand",
    "ArmState",
    "SafetyLimits",
    "VelmaController",
    "diagonal_double_diagonalisation_damping",
    "double_diagonalisation_damping",
    "pose_error",
]

DEFAULT_CART_STIFFNESS = (1000.0, 1000.0, 1000.0, 150.0, 150.0, 150.0)
"""N/m (x, y, z) and N·m/rad (rx, ry, rz), in the grip frame (the value of Velma's tests)."""
DAMPING_RATIO = 0.7
"""ξ of the Cartesian and joint impedance (Velma: 0.35 and 0.5; 0.7 for a calmer simulation)."""
ARM_JOINT_STIFFNESS = 200.0
"""N·m/rad, Velma's jnt_imp for the arms."""
HOLD_STIFFNESS = ARM_JOINT_STIFFNESS
"""N·m/rad of ``VelmaController.hold`` (Velma's jnt_imp; ξ = ``DAMPING_RATIO``)."""
SAFE_STIFFNESS = 5.0
"""N·m/rad, Velma's safe mode, every arm joint."""
SAFE_DAMPING_RATIO = 1.9
"""ξ of Velma's safe mode."""
TORSO_STIFFNESS = 1200.0
"""N·m/rad, Velma's jnt_imp for the torso."""
NULLSPACE_STIFFNESS = 10.0
"""N·m/rad, null-space posture spring of the Cartesian law."""
NULLSPACE_DAMPING = 2.0
"""N·m·s/rad, null-space posture damper of the Cartesian law."""
LAMBDA_REGULARISATION = 1e-3
"""1/kg, added to J M⁻¹ Jᵀ before inversion: bounds Λ near singularities."""
MODES = ("cart", "joint", "safe")
"""Valid ``ArmCommand.mode`` values."""


def _cholesky(lower: Array) -> eigenpy.LLT:
    """Eigen's LLT of a symmetric positive-definite matrix given by its lower triangle (the
    upper one is not read). Raises ``numpy.linalg.LinAlgError`` if it is not positive
    definite."""
    llt = eigenpy.LLT(lower)
    if llt.info() != eigenpy.ComputationInfo.Success:
        raise np.linalg.LinAlgError("mass matrix is not positive definite")
    return llt


def _symmetric(lower: Array) -> Array:
    """The symmetric matrix whose lower triangle is that of ``lower``."""
    out: Array = np.tril(lower) + np.tril(lower, -1).T
    return out


def double_diagonalisation_damping(stiffness: Array, inertia: Array, xi: float) -> Array:
    """Damping matrix D (n × n) giving every mode of ``inertia`` ẍ + D ẋ + ``stiffness`` x = 0
    the damping ratio ``xi``.

    ``stiffness`` (n × n, symmetric positive semi-definite) and ``inertia`` (n × n, symmetric
    positive definite). With Λ = L Lᵀ (Cholesky) and L⁻¹ K L⁻ᵀ = U S Uᵀ, Q = L U gives
    Λ = Q Qᵀ, K = Q S Qᵀ and D = Q (2 ξ √S) Qᵀ. Raises ``numpy.linalg.LinAlgError`` if
    ``inertia`` is not positive definite. Source: velma/model/README.md "Control" (double
    diagonalisation, as RCPRG's controllers).
    """
    chol = np.linalg.cholesky(inertia)
    linv_k = np.linalg.solve(chol, stiffness)  # L⁻¹ K
    ktilde = np.linalg.solve(chol, linv_k.T)  # L⁻¹ (L⁻¹ K)ᵀ = L⁻¹ K L⁻ᵀ
    s, u = np.linalg.eigh(ktilde)
    q = chol @ u
    out: Array = (q * (2.0 * xi * np.sqrt(np.clip(s, 0.0, None)))) @ q.T
    return out


def diagonal_double_diagonalisation_damping(stiffness: Array, inertia: Array, xi: float) -> Array:
    """The same D as ``double_diagonalisation_damping`` for a diagonal stiffness, from one
    eigendecomposition: D = 2ξ K^½ (K^-½ Λ K^-½)^½ K^½.

    ``stiffness`` (..., n) the diagonal of K (all > 0, N/m or N·m/rad); ``inertia``
    (..., n, n) symmetric positive definite. Returns (..., n, n). Raises ``ValueError`` for a
    non-positive stiffness."""
    k = np.asarray(stiffness, dtype=float)
    if np.any(k <= 0.0):
        raise ValueError("diagonal_double_diagonalisation_damping needs a positive stiffness")
    s = np.sqrt(k)
    c = inertia / (s[..., :, None] * s[..., None, :])
    w, v = np.linalg.eigh(c)
    root = (v * np.sqrt(w)[..., None, :]) @ np.swapaxes(v, -1, -2)
    out: Array = (2.0 * xi) * root * s[..., :, None] * s[..., None, :]
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
    ``twist`` (6,) world (v m/s, ω rad/s), stiffness ``stiffness`` (6,) N/m and N·m/rad,
    null-space posture ``posture`` (7,) rad), ``"joint"`` (``q`` (7,) rad, ``qd`` (7,) rad/s,
    joint stiffness ``joint_stiffness`` N·m/rad, a float or (7,), ξ = ``DAMPING_RATIO``) or
    ``"safe"`` (``q``, ``qd`` as in joint mode with K = ``SAFE_STIFFNESS``, ξ =
    ``SAFE_DAMPING_RATIO``). See ``VelmaController.hold`` and ``VelmaController.safe``."""

    mode: str = "joint"
    pose: pin.SE3 = field(default_factory=pin.SE3.Identity)
    twist: Array = field(default_factory=lambda: np.zeros(6))
    stiffness: Array = field(default_factory=lambda: np.array(DEFAULT_CART_STIFFNESS))
    posture: Array = field(default_factory=lambda: np.zeros(7))
    q: Array = field(default_factory=lambda: np.zeros(7))
    qd: Array = field(default_factory=lambda: np.zeros(7))
    joint_stiffness: float | Array = ARM_JOINT_STIFFNESS


@dataclass
class ArmState:
    """Quantities of one arm computed each cycle (for monitoring): grip pose (world), the
    Cartesian error (6,) (m, quaternion vector; updated in Cartesian mode only) and the
    commanded torque (7,) N·m."""

    grip: pin.SE3 = field(default_factory=pin.SE3.Identity)
    error: Array = field(default_factory=lambda: np.zeros(6))
    torque: Array = field(default_factory=lambda: np.zeros(7))


@dataclass(frozen=True)
class SafetyLimits:
    """The safety terms' parameters (defaults and sources: velma/control/limits.py). Set a
    band torque to 0 or a velocity limit to ``inf`` to switch that term off."""

    limit_band: float = LIMIT_BAND
    limit_band_torque: float = LIMIT_BAND_TORQUE
    singularity_half_width: float = SINGULARITY_HALF_WIDTH
    singularity_band: float = SINGULARITY_BAND
    singularity_band_torque: float = SINGULARITY_BAND_TORQUE
    band_damping_ratio: float = BAND_DAMPING_RATIO
    null_space_band_scale: float = NULL_SPACE_BAND_SCALE
    arm_velocity: float = ARM_VELOCITY_LIMIT
    torso_velocity: float = TORSO_VELOCITY_LIMIT
    velocity_time_constant: float = VELOCITY_LIMIT_TIME_CONSTANT


class VelmaController:
    """Computes arm and torso torques each cycle from Pinocchio's q, v (rad, rad/s, (33,)).

    Call ``update`` once per control cycle (see the module docstring for the laws). Uses and
    overwrites ``robot.data``. Raises ``RuntimeError`` at construction if an arm's joints are
    not contiguous in Pinocchio's v.
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
        self.limits = SafetyLimits()
        self.payload: dict[str, Payload] = {s: NO_PAYLOAD for s in SIDES}
        """What each hand holds, compensated in every mode (velma/control/payload.py)."""
        self.wrist: WristField | None = wrist_field()
        """The wrist band's distance table; None switches the band off."""
        model = robot.model
        self._idx = np.stack([self.arm_idx[s] for s in SIDES])  # (2, 7)
        i = np.arange(7)
        self._arm_sl = (self.arm_slice[SIDES[0]], self.arm_slice[SIDES[1]])
        self._lower = np.array(model.lowerPositionLimit)[self._idx]
        self._upper = np.array(model.upperPositionLimit)[self._idx]
        self._abs_limit = np.minimum(self._upper, -self._lower)  # (2, 7) rad
        self._singular = np.isin(i, SINGULAR_JOINTS)
        self._in_full = np.isin(i, FULL_BAND_JOINTS).astype(float)  # Cartesian mode
        self._via_null_space = 1.0 - self._in_full
        self._fid = tuple(robot.grip_frame_id[s] for s in SIDES)
        self._reg = LAMBDA_REGULARISATION * np.eye(6)
        self._coef = np.array([2.0 * DAMPING_RATIO, -1.0])
        self._rot_buf = np.empty((2, 3, 3))  # grip rotations of the current cycle
        self._prev_arm: Array | None = None
        self._edges_limits: SafetyLimits | None = None  # _band_edges' cache
        self._edges_cart: list[bool] = []
        self._edges: tuple[Array, Array, BoolArray, Array, Array] = (
            np.zeros((2, 7)),
            np.zeros((2, 7)),
            np.zeros((2, 7), bool),
            np.zeros((2, 7)),
            np.zeros((2, 7)),
        )
        self._prev_torso: float | None = None
        self._q_arm: Array | None = None  # last measured arm q (2, 7)

    # ------------------------------------------------------------------ kinematics
    def kinematics(self, q: Array, v: Array) -> None:
        """Forward kinematics, all frame placements, Jacobians, M (upper triangle) and nle for
        ``q``, ``v`` (33,) into ``robot.data``."""
        model, data = self.robot.model, self.robot.data
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        pin.crba(model, data, q)
        pin.nonLinearEffects(model, data, q, v)

    def grip_pose(self, side: str) -> pin.SE3:
        """World pose of ``side``'s grip frame after ``kinematics`` or ``update``."""
        out: pin.SE3 = self.robot.data.oMf[self.robot.grip_frame_id[side]]
        return out.copy()

    def joint_limits(self, side: str) -> tuple[Array, Array]:
        """``side``'s arm joint limits, lower and upper (7,) each, rad (velma.xml)."""
        k = SIDES.index(side)
        return self._lower[k], self._upper[k]

    # ------------------------------------------------------------------ modes
    def hold(self, side: str, q_arm: Array | None = None) -> None:
        """Switch ``side`` to joint impedance (K = ``HOLD_STIFFNESS`` = 200 N·m/rad, Velma's
        jnt_imp, ξ = ``DAMPING_RATIO``) at ``q_arm`` (7,) rad, by default the configuration
        measured in the last ``update``. Raises ``ValueError`` for a wrong shape,
        ``RuntimeError`` if there is no measurement yet."""
        cmd = self.arm[side]
        cmd.q = self._setpoint(side, q_arm)
        cmd.qd = np.zeros(7)
        cmd.joint_stiffness = HOLD_STIFFNESS
        cmd.mode = "joint"

    def safe(self, side: str, q_arm: Array | None = None) -> None:
        """Switch ``side`` to safe mode: joint impedance K = 5 N·m/rad, ξ = 1.9 for every
        joint, plus gravity compensation (velma/model/README.md "Control"), about ``q_arm``
        (7,) rad, by default the last measured configuration. Errors as ``hold``."""
        cmd = self.arm[side]
        cmd.q = self._setpoint(side, q_arm)
        cmd.qd = np.zeros(7)
        cmd.mode = "safe"

    def _setpoint(self, side: str, q_arm: Array | None) -> Array:
        if q_arm is None:
            if self._q_arm is None:
                raise RuntimeError("no measured configuration yet: call update first or pass q_arm")
            return self._q_arm[SIDES.index(side)].copy()
        out = np.array(q_arm, dtype=float)
        if out.shape != (7,):
            raise ValueError(f"q_arm must have shape (7,), got {out.shape}")
        return out

    # ------------------------------------------------------------------ the cycle
    def update(self, q: Array, v: Array) -> tuple[dict[str, Array], float]:
        """Torques for one cycle: per side (7,) N·m and the torso's N·m, from q, v (33,) rad
        and rad/s (see the module docstring). Raises ``ValueError`` for an unknown mode and
        ``numpy.linalg.LinAlgError`` if a mass matrix is not positive definite."""
        model, data = self.robot.model, self.robot.data
        pin.crba(model, data, q, pin.Convention.WORLD)  # also data.J and data.oMi
        pin.nonLinearEffects(model, data, q, v)
        m_full = data.M  # upper triangle valid (crba)
        # arm blocks as views whose lower triangle is valid: all that Eigen's LLT and
        # SelfAdjointEigenSolver read (no symmetrisation copy)
        mb = (m_full[self._arm_sl[0], self._arm_sl[0]].T, m_full[self._arm_sl[1], self._arm_sl[1]].T)
        idx = self._idx
        qa: Array = q[idx]
        va: Array = v[idx]
        self._q_arm = qa
        cmds = (self.arm[SIDES[0]], self.arm[SIDES[1]])
        grips = []
        for k in (0, 1):
            grip = pin.updateFramePlacement(model, data, self._fid[k]).copy()
            self._rot_buf[k] = grip.rotation
            self.state[SIDES[k]].grip = grip
            grips.append(grip)
        cart = [cmds[0].mode == "cart", cmds[1].mode == "cart"]
        bands, braking = self._safety(qa, va, mb, cart)
        tau = np.empty((2, 7))
        if cart[0] and cart[1]:
            self._cartesian(slice(0, 2), cmds, grips, qa, va, mb, bands, tau)
        elif cart[0] or cart[1]:
            c = 0 if cart[0] else 1
            self._cartesian(slice(c, c + 1), cmds, grips, qa, va, mb, bands, tau)
            self._joint(slice(1 - c, 2 - c), cmds, qa, va, mb, tau)
            if bands is not None:
                tau[1 - c] += bands[1 - c]
        else:
            self._joint(slice(0, 2), cmds, qa, va, mb, tau)
            if bands is not None:
                tau += bands
        if self.wrist is not None:
            for k in (0, 1):
                push = wrist_band_torque(self.wrist, k, qa[k], va[k])
                if push is not None:
                    tau[k, 5] += push[0]
                    tau[k, 6] += push[1]
        tau += data.nle[idx]
        for k in (0, 1):
            load = self.payload[SIDES[k]]
            if not load.empty:
                jac = pin.getFrameJacobian(model, data, self._fid[k], pin.LOCAL)[:, self._arm_sl[k]]
                tau[k] += payload_torque(load, jac, self._rot_buf[k], model.gravity.linear)
        # torque rate limit, then magnitude limit; as the previous torque is within the
        # magnitude limit, both are one clip to [max(prev − rate, −L), min(prev + rate, L)]
        rate = TORQUE_RATE_LIMIT * self.dt
        prev = self._prev_arm
        if prev is None:
            np.maximum(tau, -ARM_TORQUE_LIMIT, out=tau)
            np.minimum(tau, ARM_TORQUE_LIMIT, out=tau)
        else:
            np.maximum(tau, np.maximum(prev - rate, -ARM_TORQUE_LIMIT), out=tau)
            np.minimum(tau, np.minimum(prev + rate, ARM_TORQUE_LIMIT), out=tau)
        self._prev_arm = tau
        if braking is not None:  # exempt from the rate limit (limits.py), not the magnitude
            tau = np.clip(tau + braking, -ARM_TORQUE_LIMIT, ARM_TORQUE_LIMIT)
        torques = {}
        for k, side in enumerate(SIDES):
            torques[side] = tau[k]
            self.state[side].torque = tau[k]
        return torques, self._torso(q, v, float(m_full[self.torso_idx, self.torso_idx]), rate)

    def _cartesian(
        self,
        sl: slice,
        cmds: tuple[ArmCommand, ArmCommand],
        grips: list[pin.SE3],
        qa: Array,
        va: Array,
        mb: tuple[Array, Array],
        bands: Array | None,
        out: Array,
    ) -> None:
        """Cartesian impedance (module docstring) of the arms ``sl`` into ``out[sl]``; the
        band torques ``bands`` (2, 7) join τ_ns (they act in the null space)."""
        model, data = self.robot.model, self.robot.data
        arms = range(2)[sl]
        n = len(arms)
        err = np.empty((n, 7))  # R⁻¹ (p_cmd − p), then quat(R⁻¹ R_cmd) as (x, y, z, w)
        twist = np.empty((n, 6))
        kst = np.empty((n, 6))
        posture = np.empty((n, 7))
        jac = np.empty((n, 6, 7))
        for i, k in enumerate(arms):
            cmd = cmds[k]
            err[i] = pin.SE3ToXYZQUAT(grips[k].actInv(cmd.pose))
            if err[i, 6] < 0.0:  # the quaternion with w ≥ 0
                err[i, 3:6] *= -1.0
            twist[i] = cmd.twist
            kst[i] = cmd.stiffness
            posture[i] = cmd.posture
            jac[i] = pin.getFrameJacobian(model, data, self._fid[k], pin.LOCAL)[:, self.arm_slice[SIDES[k]]]
        p_err = err[:, :6]
        q_s, v_s = qa[sl], va[sl]
        tau_ns = NULLSPACE_STIFFNESS * (posture - q_s) - NULLSPACE_DAMPING * v_s
        if bands is not None:  # through the null space, scaled, but the elbow's in full (limits.py)
            tau_ns += bands[sl] * (self.limits.null_space_band_scale * self._via_null_space)
        # setpoint twist in the grip frame (rotated only), minus J q̇
        ev = (twist.reshape(n, 2, 3) @ self._rot_buf[sl]).reshape(n, 6)  # rows: Rᵀ v, Rᵀ ω
        ev -= (jac @ v_s[:, :, None])[:, :, 0]
        if kst.min() > 0.0:
            s = np.sqrt(kst)
            # G = [K^½-scaled Jᵀ | τ_ns]; P = K^½ J M⁻¹ G = [K^½ J M⁻¹ Jᵀ K^½ | K^½ J M⁻¹ τ_ns]
            js = jac * s[:, :, None]
            g_t = np.empty((n, 7, 7))  # Gᵀ, so that each G = g_t[i].T is column-major for Eigen
            g_t[:, :6, :] = js
            g_t[:, 6, :] = tau_ns
            m_inv_g = np.empty((n, 7, 7))
            for i, k in enumerate(arms):
                m_inv_g[i] = _cholesky(mb[k]).solve(g_t[i].T)
            prod = js @ m_inv_g
            # K^½ (J M⁻¹ Jᵀ + εI) K^½ = K^½ Λ⁻¹ K^½: ε k_j added in place on the diagonal of the
            # leading 6 × 6 block of each (6 × 7) product (flat stride 8)
            prod.reshape(n, 42)[:, ::8] += LAMBDA_REGULARISATION * kst
            b = prod[:, :, :6]
            w_b = np.empty((n, 6))
            v_b = np.empty((n, 6, 6))
            for i in range(n):
                eig = eigenpy.SelfAdjointEigenSolver(b[i])  # B = V W Vᵀ
                w_b[i] = eig.eigenvalues()
                v_b[i] = eig.eigenvectors()
            y = np.empty((n, 6, 2))
            y[:, :, 0] = s * ev
            y[:, :, 1] = prod[:, :, 6]
            z = v_b.transpose(0, 2, 1) @ y
            z[:, :, 0] /= np.sqrt(w_b)
            z[:, :, 1] /= w_b
            # Jᵀ (K p + D ev − Λ J M⁻¹ τ_ns) with D = 2ξ K^½ V W^-½ Vᵀ K^½, Λ = K^½ V W⁻¹ Vᵀ K^½,
            # written (K^½ J)ᵀ (K^½ p + V W^-½ Vᵀ K^½ ev 2ξ − V W⁻¹ Vᵀ K^½ J M⁻¹ τ_ns)
            scaled = s * p_err + (v_b @ z) @ self._coef
            out[sl] = (js.transpose(0, 2, 1) @ scaled[:, :, None])[:, :, 0] + tau_ns
        else:  # a zero stiffness: the general (Cholesky) double diagonalisation
            jac_t = jac.transpose(0, 2, 1)
            wrench = np.empty((n, 6))
            for i, k in enumerate(arms):
                m_inv = np.linalg.inv(_symmetric(mb[k]))
                lam = np.linalg.inv(jac[i] @ m_inv @ jac_t[i] + self._reg)
                dmat = double_diagonalisation_damping(np.diag(kst[i]), lam, DAMPING_RATIO)
                wrench[i] = kst[i] * p_err[i] + dmat @ ev[i] - lam @ (jac[i] @ (m_inv @ tau_ns[i]))
            out[sl] = (jac_t @ wrench[:, :, None])[:, :, 0] + tau_ns
        if bands is not None:
            out[sl] += bands[sl] * self._in_full
        for i, k in enumerate(arms):
            self.state[SIDES[k]].error = p_err[i]

    def _joint(
        self,
        sl: slice,
        cmds: tuple[ArmCommand, ArmCommand],
        qa: Array,
        va: Array,
        mb: tuple[Array, Array],
        out: Array,
    ) -> None:
        """Joint impedance (modes "joint" and "safe") of the arms ``sl`` into ``out[sl]``."""
        arms = range(2)[sl]
        n = len(arms)
        kq = np.empty((n, 7))
        xi = np.empty((n, 1))
        q_set = np.empty((n, 7))
        qd_set = np.empty((n, 7))
        for i, k in enumerate(arms):
            cmd = cmds[k]
            if cmd.mode == "joint":
                kq[i] = cmd.joint_stiffness
                xi[i] = DAMPING_RATIO
            elif cmd.mode == "safe":
                kq[i] = SAFE_STIFFNESS
                xi[i] = SAFE_DAMPING_RATIO
            else:
                raise ValueError(f"{SIDES[k]} arm: unknown mode {cmd.mode!r} (expected one of {MODES})")
            q_set[i] = cmd.q
            qd_set[i] = cmd.qd
        ve = qd_set - va[sl]
        if kq.min() > 0.0:
            s = np.sqrt(kq)
            w_c = np.empty((n, 7))
            v_c = np.empty((n, 7, 7))
            for i, k in enumerate(arms):
                eig = eigenpy.SelfAdjointEigenSolver(mb[k] / np.outer(s[i], s[i]))  # C = K^-½ M K^-½
                w_c[i] = eig.eigenvalues()  # C = V W Vᵀ
                v_c[i] = eig.eigenvectors()
            z = (v_c.transpose(0, 2, 1) @ (s * ve)[:, :, None])[:, :, 0] * np.sqrt(w_c)
            damp = (2.0 * xi) * s * (v_c @ z[:, :, None])[:, :, 0]  # D = 2ξ K^½ V W^½ Vᵀ K^½
        else:
            damp = np.empty((n, 7))
            for i, k in enumerate(arms):
                dmat = double_diagonalisation_damping(np.diag(kq[i]), _symmetric(mb[k]), float(xi[i, 0]))
                damp[i] = dmat @ ve[i]
        out[sl] = kq * (q_set - qa[sl]) + damp

    def _safety(
        self, qa: Array, va: Array, mb: tuple[Array, Array], cart: list[bool]
    ) -> tuple[Array | None, Array | None]:
        """The safety torques of both arms, (2, 7) each or None when zero: the band torques
        (joint-limit band in all modes, singularity band in Cartesian mode, with their
        damping) and the velocity-limit braking (velma/control/limits.py)."""
        lim = self.limits
        bands: Array | None = None
        aq = np.abs(qa)
        limit_edge, singular_edge, singular_mask, centre, half = self._band_edges(cart)
        # cheap test first: a joint may be in the limit band only if |q| is beyond the band's
        # inner edge for the nearer limit, in the singularity band only if |q| is below its
        # edge; both at once: | |q| − centre | > half
        if (np.abs(aq - centre) > half).any():
            near_limit = bool((aq > limit_edge).any())
            near_singular = bool((aq < singular_edge).any())
            m_diag = np.array([np.diagonal(mb[0]), np.diagonal(mb[1])])
            xi = lim.band_damping_ratio
            if near_limit:
                bands, active = position_band_torque(
                    qa, self._lower, self._upper, lim.limit_band, lim.limit_band_torque
                )
                bands += band_damping(active, lim.limit_band_torque / lim.limit_band, m_diag, va, xi)
            if near_singular:
                tau_s, active_s = singularity_band_torque(
                    qa,
                    singular_mask,
                    lim.singularity_half_width,
                    lim.singularity_band,
                    lim.singularity_band_torque,
                )
                k_sing = lim.singularity_band_torque / lim.singularity_band
                tau_s += band_damping(active_s, k_sing, m_diag, va, xi)
                bands = tau_s if bands is None else bands + tau_s
        braking = None
        if np.abs(va).max() > lim.arm_velocity:
            inertia = np.array([_symmetric(mb[0]), _symmetric(mb[1])])
            braking = velocity_limit_torque(va, lim.arm_velocity, inertia, lim.velocity_time_constant)
        return bands, braking

    def _band_edges(self, cart: list[bool]) -> tuple[Array, Array, BoolArray, Array, Array]:
        """(2, 7) edges on |q| of the limit band (inner edge for the nearer limit) and of the
        singularity band (−1 where it does not apply), the singularity band's joint mask, and
        the centre and half-width of the interval between the edges; cached while ``limits``
        and the Cartesian arms stay the same."""
        lim = self.limits
        if lim is not self._edges_limits or cart != self._edges_cart:
            mask = self._singular & np.array(cart)[:, None]
            limit_edge = self._abs_limit - lim.limit_band
            singular_edge = np.where(mask, lim.singularity_half_width + lim.singularity_band, -1.0)
            self._edges = (
                limit_edge,
                singular_edge,
                mask,
                0.5 * (limit_edge + singular_edge),
                0.5 * (limit_edge - singular_edge),
            )
            self._edges_limits, self._edges_cart = lim, list(cart)
        return self._edges

    def _torso(self, q: Array, v: Array, m_tt: float, rate: float) -> float:
        """Torso joint impedance (K = 1200 N·m/rad, ξ = 0.7), torque rate and magnitude
        limits, velocity-limit braking (exempt from the rate limit, as the arms')."""
        t = self.torso_idx
        qt, vt = float(q[t]), float(v[t])
        d_t = 2.0 * DAMPING_RATIO * math.sqrt(TORSO_STIFFNESS * m_tt)
        tau = (
            TORSO_STIFFNESS * (self.torso_q - qt) + d_t * (self.torso_qd - vt) + float(self.robot.data.nle[t])
        )
        if self._prev_torso is not None:
            tau = min(max(tau, self._prev_torso - rate), self._prev_torso + rate)
        tau = min(max(tau, -TORSO_TORQUE_LIMIT), TORSO_TORQUE_LIMIT)
        self._prev_torso = tau
        vmax = self.limits.torso_velocity
        if abs(vt) > vmax:
            tau -= m_tt * (vt - math.copysign(vmax, vt)) / self.limits.velocity_time_constant
            tau = min(max(tau, -TORSO_TORQUE_LIMIT), TORSO_TORQUE_LIMIT)
        return tau
