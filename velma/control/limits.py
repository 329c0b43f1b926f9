"""Joint-space safety terms added to Velma's arm and torso control laws, as on the real robot.

All functions are vectorised: ``q``, ``v`` and the other per-joint arguments broadcast to
the same shape (``(n,)`` or ``(arms, n)``); they return new arrays of that shape.

Terms (velma/model/README.md, "Control" and "KUKA LWR4+ arms"; what departs from the real
robot: its "Where the model departs from the real robot"):

- **Joint-limit avoidance band** (``position_band_torque``): inside a band of width ``b``
  before a joint limit the joint gets a repulsive torque that grows quadratically from 0 at
  the band edge to ``τ_b`` at the limit (and beyond it):

      τ = τ_b ((q_lo + b − q) / b)²  if q < q_lo + b,   τ = −τ_b ((q − q_hi + b) / b)²  if q > q_hi − b.

  This is the profile of RCPRG's ``JointLimitAvoidance`` component (the joint-limit
  avoidance of Velma's and the LWR's OROCOS controllers, 2014), which also damps the joints
  it acts on with the stiffness ``τ_b / b`` and damping ratio 0.7 (``band_damping``).
- **Singularity avoidance band** (``singularity_band_torque``): in Cartesian impedance,
  arm joints 1, 3, 5 stay outside ±0.2 rad of the stretched (singular) configuration q = 0,
  with an avoidance band of 0.26 rad (Velma's ``cart_imp``). The interval [−0.2, 0.2] is
  treated as a pseudo-limit with the same quadratic band: the torque pushes away from 0, from 0 at
  |q| = 0.46 rad to ``τ_s`` at |q| = 0.2 rad, growing further inside.
- **Joint velocity limit** (``velocity_limit_torque``): arms 2 rad/s, torso 0.52 rad/s
  (Velma's limits in control). Only the excess over the limit is damped, with the joint-space
  inertia as gain: τ = −M (q̇ − sat(q̇)) / T_v, so that, with nothing else acting, the excess decays
  with time constant ``T_v``; against a sustained driving torque τ_d the excess settles near
  τ_d T_v / M_jj (a damper, not a hard clamp; the torque limit bounds τ_d). The controller
  adds it after the torque rate limit (why: docs/executor.md "How the law is computed").
- **Torque limit and torque rate limit** (applied in ``VelmaController.update``): 100 N·m for arm
  joints 0–4, 60 N·m for 5–6 (Velma's limits); change per cycle at most 1 N·m per 1 ms tick
  (borrowed from franka_ros's Cartesian impedance example, not Velma's).

Where the band torques act (velma/control/impedance.py): in full in joint and safe mode; in
Cartesian mode through the task's null space, as RCPRG's ``JointLimitAvoidance`` component
feeds the ``NullSpaceTorqueCommand`` input of its ``CartesianImpedance`` (orocos_controllers,
controller_common), scaled by ``NULL_SPACE_BAND_SCALE``, except for the joints of
``FULL_BAND_JOINTS`` (in full). So in Cartesian mode the bands of joints 0–2 and 4–6 use the
arm's redundancy and never pull the grip off its target: a target that can only be reached
through a band (e.g. a wrist turn through q5 = 0) is still reached, and joints 1 and 5 are
kept off their singularity only as far as the redundancy allows.

The peak band torques (``LIMIT_BAND_TORQUE``, ``SINGULARITY_BAND_TORQUE``) and ``T_v`` are
not in the public sources (RCPRG's component takes them as parameters): the values here are
chosen for this simulation and named as such.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from velma.control.joints import Array

BoolArray = npt.NDArray[np.bool_]

# --- torque limits (velma/model/README.md, KUKA LWR4+ arms; franka_ros for the rate)
ARM_TORQUE_LIMIT = np.array([100.0, 100.0, 100.0, 100.0, 100.0, 60.0, 60.0])
"""N·m, arm joints 0–6 (Velma's limits: 100 N·m joints 0–4, 60 N·m joints 5–6)."""
TORSO_TORQUE_LIMIT = 300.0
"""N·m (placeholder: not public; velma/model/README.md "Placeholders")."""
TORQUE_RATE_LIMIT = 1000.0
"""N·m/s: 1 N·m per 1 ms tick, as franka_ros."""

# --- joint-limit avoidance band (the width of Velma's singularity band, 0.26 rad; RCPRG profile)
LIMIT_BAND = 0.26
"""rad, width of the joint-limit avoidance band of every arm joint."""
LIMIT_BAND_TORQUE = 20.0
"""N·m, repulsive torque at the limit (chosen for this simulation; RCPRG's ``max_trq``)."""
BAND_DAMPING_RATIO = 0.7
"""Damping ratio of a joint inside a band, with stiffness peak torque / band (RCPRG: 0.7)."""

# --- singularity avoidance band (joints 1, 3, 5 in Velma's cart_imp)
SINGULAR_JOINTS = (1, 3, 5)
"""Arm joints kept away from their stretched (singular) value 0 in Cartesian impedance."""
SINGULARITY_HALF_WIDTH = 0.2
"""rad, the forbidden interval [−0.2, 0.2] around q = 0 (Velma's cart_imp)."""
SINGULARITY_BAND = 0.26
"""rad, avoidance band outside the forbidden interval (Velma's cart_imp)."""
SINGULARITY_BAND_TORQUE = 20.0
"""N·m at |q| = 0.2 rad (chosen for this simulation, as ``LIMIT_BAND_TORQUE``)."""

NULL_SPACE_BAND_SCALE = 0.25
"""Factor on the band torques (and their damping) that act through the null space in
Cartesian impedance (peak 5 N·m instead of 20). Chosen: with the full 20 N·m the null-space
push of the wrist band swung the elbow until joint 1 met its limit and joint 3 its band, and
the jar retreat of scripts/bench_pour_seeds.py seed 3 ended 32 mm off target; with 0.25 the
default scene and seeds 1–8 pass. The price: in the default pour the left shoulder (joint 1)
again reaches its hard limit while pouring (held 0.2 rad off with the full torque)."""

FULL_BAND_JOINTS = (3,)
"""Arm joints whose band torques act in full in Cartesian impedance; the other joints' band
torques act through the task's null space. The self-motion of the S-R-S LWR (elbow swivel)
keeps the shoulder–wrist distance, hence joint 3: a null-space torque cannot move it."""

# --- joint velocity limits (velma/model/README.md, "Structure" and "KUKA LWR4+ arms")
ARM_VELOCITY_LIMIT = 2.0
"""rad/s, arm joints in Velma's control."""
TORSO_VELOCITY_LIMIT = 0.52
"""rad/s (the torso's 30 °/s)."""
VELOCITY_LIMIT_TIME_CONSTANT = 0.005
"""s, decay time of a velocity excess under ``velocity_limit_torque`` (chosen: 5 cycles)."""


def position_band_torque(
    q: Array, lower: Array, upper: Array, band: float, peak: float
) -> tuple[Array, BoolArray]:
    """Joint-limit avoidance torque (N·m) and the mask of joints inside a band.

    ``q``, ``lower``, ``upper`` in rad (broadcastable); ``band`` rad (> 0); ``peak`` N·m, the
    torque at the limit. Positive torque pushes up (away from ``lower``). See the module
    docstring for the law (RCPRG ``JointLimitAvoidance`` profile)."""
    below = np.maximum(lower + band - q, 0.0)
    above = np.maximum(q - upper + band, 0.0)
    tau: Array = (peak / (band * band)) * (below * below - above * above)
    active: BoolArray = (below + above) > 0.0
    return tau, active


def singularity_band_torque(
    q: Array, mask: BoolArray, half_width: float, band: float, peak: float
) -> tuple[Array, BoolArray]:
    """Torque (N·m) pushing the joints selected by ``mask`` (bool, broadcastable to ``q``)
    away from q = 0, and the mask of joints inside the band.

    Zero for |q| ≥ ``half_width`` + ``band``; ``peak`` at |q| = ``half_width``; quadratic in
    between and growing further inside (rad, rad, N·m). At q = +0.0 the push is upwards."""
    depth = np.maximum(half_width + band - np.abs(q), 0.0) * mask
    tau: Array = np.copysign((peak / (band * band)) * depth * depth, q)
    active: BoolArray = depth > 0.0
    return tau, active


def band_damping(active: BoolArray, stiffness: float, inertia_diag: Array, v: Array, xi: float) -> Array:
    """Damping torque (N·m) of the joints inside a band: −2 ξ √(k M_jj) q̇ where ``active``.

    ``stiffness`` N·m/rad (the band's peak torque / width), ``inertia_diag`` the diagonal of
    the joint-space inertia (kg·m²), ``v`` rad/s. A per-joint simplification of RCPRG's double
    diagonalisation with M (the band rarely holds more than one joint of an arm)."""
    out: Array = (-2.0 * xi) * np.sqrt(stiffness * inertia_diag) * v * active
    return out


def velocity_limit_torque(v: Array, limit: float, inertia: Array, time_constant: float) -> Array:
    """Braking torque (N·m) on the velocity excess over ``limit``: −M (q̇ − sat(q̇)) / T_v.

    ``v`` (..., n) rad/s; ``inertia`` (..., n, n) kg·m², the joint-space inertia of the same
    joints (symmetric positive definite); ``time_constant`` s. Zero while |q̇| ≤ ``limit``."""
    excess = v - np.clip(v, -limit, limit)
    out: Array = (inertia @ excess[..., None])[..., 0] * (-1.0 / time_constant)
    return out
