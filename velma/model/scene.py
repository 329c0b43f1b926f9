"""Loading the kitchen scene: kitchen.xml plus the jar's content generated at load time.

``load_kitchen`` compiles kitchen.xml (which includes velma.xml) through ``mujoco.MjSpec``
and adds ``n_particles`` free spheres named ``jar_content_0`` … ``jar_content_{n-1}`` on a
helix inside the jar; ``seed`` jitters their start positions by up to ±1.5 mm so that
different seeds give different (but always valid) piles. ``initial_state`` puts the robot in
its home posture and lets the content settle.

Simplification (named): the content is rigid spheres of ø18 mm, 3 g each (density
≈ 1000 kg/m³, like dried peas or beans in size class), with plain Coulomb friction.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from velma.model import KITCHEN_XML

N_PARTICLES = 27
PARTICLE_RADIUS = 0.009  # m
PARTICLE_MASS = 0.003  # kg
PARTICLE_PREFIX = "jar_content_"
HELIX_RADIUS = 0.022  # m, in the jar frame
HELIX_PER_TURN = 7
HELIX_PITCH = 0.021  # m per turn
HELIX_Z0 = 0.017  # m above the jar frame (bottom centre)

# Home posture (rad), hands open. Left arm bent in front of the torso; right arm in the
# palm-down "ready" posture above the shelf (velma/scenario.py RIGHT_PICK_POSTURE explains
# why). Elbow/wrist joints 1, 3, 5 stay clear of the singular stretch (|q| ≥ 0.2).
HOME_POSTURE: dict[str, float] = {
    "torso_0_joint": 0.0,
    "head_pan_joint": 0.0,
    "head_tilt_joint": 0.6,
    "right_arm_0_joint": 1.46,
    "right_arm_1_joint": -0.98,
    "right_arm_2_joint": -0.15,
    "right_arm_3_joint": 1.82,
    "right_arm_4_joint": -0.2,
    "right_arm_5_joint": 1.26,
    "right_arm_6_joint": 2.29,
    "left_arm_0_joint": 0.3,
    "left_arm_1_joint": 1.8,
    "left_arm_2_joint": -1.25,
    "left_arm_3_joint": -0.85,
    "left_arm_4_joint": 0.0,
    "left_arm_5_joint": 0.5,
    "left_arm_6_joint": 0.0,
}


def particle_names(n: int = N_PARTICLES) -> list[str]:
    """``jar_content_0`` … ``jar_content_{n-1}``."""
    return [f"{PARTICLE_PREFIX}{i}" for i in range(n)]


def build_spec(n_particles: int = N_PARTICLES, seed: int = 0) -> mujoco.MjSpec:
    """kitchen.xml as an MjSpec with the jar content added (see module docstring).

    Raises ``ValueError`` if ``n_particles`` does not fit the helix (more than 35)."""
    if not 0 <= n_particles <= 35:
        raise ValueError(f"n_particles={n_particles}: the jar holds 0..35 spheres")
    spec = mujoco.MjSpec.from_file(str(KITCHEN_XML))
    jar = spec.body("jar")
    jar_pos = np.array(jar.pos, dtype=float)
    rng = np.random.default_rng(seed)
    for i, name in enumerate(particle_names(n_particles)):
        angle = 2 * math.pi * i / HELIX_PER_TURN
        local = np.array(
            [
                HELIX_RADIUS * math.cos(angle),
                HELIX_RADIUS * math.sin(angle),
                HELIX_Z0 + HELIX_PITCH * i / HELIX_PER_TURN,
            ]
        )
        local[:2] += rng.uniform(-0.0015, 0.0015, size=2)
        body = spec.worldbody.add_body(name=name, pos=jar_pos + local)
        body.add_freejoint()
        body.add_geom(
            name=f"{name}_geom",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[PARTICLE_RADIUS, 0, 0],
            mass=PARTICLE_MASS,
            contype=1,
            conaffinity=3,
            condim=3,
            friction=[0.6, 0.01, 0.001],
            solref=[0.004, 1.0],
            rgba=[0.85, 0.55, 0.1, 1.0],
        )
    return spec


def load_kitchen(n_particles: int = N_PARTICLES, seed: int = 0) -> mujoco.MjModel:
    """Compiled kitchen model with ``n_particles`` content spheres (see ``build_spec``)."""
    return build_spec(n_particles, seed).compile()


def set_posture(model: mujoco.MjModel, data: mujoco.MjData, posture: dict[str, float]) -> None:
    """Write joint positions (rad) by name into ``data.qpos``; also sets the matching
    position-servo controls. Raises ``KeyError`` for an unknown joint name."""
    for name, value in posture.items():
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise KeyError(name)
        data.qpos[model.jnt_qposadr[jid]] = value


def initial_state(model: mujoco.MjModel, settle_steps: int = 300) -> mujoco.MjData:
    """MjData in the home posture with the content settled (``settle_steps`` steps with the
    robot's joints frozen in place, 1 ms each)."""
    data = mujoco.MjData(model)
    set_posture(model, data, HOME_POSTURE)
    mujoco.mj_forward(model, data)
    robot_dofs = [
        model.jnt_dofadr[j] for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]
    robot_qpos = [
        model.jnt_qposadr[j] for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]
    q_hold = data.qpos[robot_qpos].copy()
    for _ in range(settle_steps):
        mujoco.mj_step(model, data)
        data.qpos[robot_qpos] = q_hold
        data.qvel[robot_dofs] = 0.0
    data.time = 0.0
    mujoco.mj_forward(model, data)
    return data
