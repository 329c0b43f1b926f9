"""Loading the kitchen scene: kitchen.xml plus the jar's content generated at load time.

``load_kitchen`` compiles kitchen.xml (which includes velma.xml) through ``mujoco.MjSpec``
and adds ``n_particles`` spheres named ``jar_content_0`` … ``jar_content_{n-1}`` on a
helix inside the jar; ``seed`` jitters their start positions by up to ±1.5 mm so that
different seeds give different (but always valid) piles. ``initial_state`` puts the robot in
its home posture and lets the content settle.

Pose randomisation (for robustness benchmarks): ``pose_seed`` (None by default: the poses of
kitchen.xml, exactly) moves the jar and the bowl on the shelf by independent uniform offsets
within ±``POSE_OFFSET_MAX`` (2 cm) in x and y and turns each about its vertical axis by a
uniform angle within ±``POSE_YAW_MAX`` (10°), deterministically from the seed. The jar's
content is placed in the moved jar's frame, so it starts inside it. ``scene_perturbation``
returns what a seed applies, for benchmarks to print.

Content removed (for benchmarks of the pour's verdict): ``initial_state(model, removed=k)``
takes the top ``k`` spheres of the helix out of the jar before the content settles and lays
them on the floor behind the robot (``remove_content``: from ``REMOVED_AT`` along y, ø18 mm
apart by ``REMOVED_SPACING``), out of the arms' reach and the head camera's view. The model
is unchanged (still ``n_particles`` spheres, so the content the camera judges by is still all
of them): a pour then cannot put more than ``n_particles − k`` of them in the bowl. The world
process does so with ``ROCO_CONTENT_REMOVED`` (shared/settings.py).

Simplification (named): the content is rigid spheres of ø18 mm, 3 g each (density
≈ 1000 kg/m³, like dried peas or beans in size class), and every contact they make (with each
other, the jar, the bowl, the table and the hand) is frictionless: a normal force only
(``condim`` 1; the spheres' geom ``priority`` 1 makes their condim win over the walls' 3).
A frictionless contact's force passes through the sphere's centre, so nothing can turn a
sphere: its rotation is exactly decoupled from the rest of the world, and each sphere moves
on three slide joints (x, y, z of the world) instead of a free joint, which is the same motion
with 3 instead of 6 degrees of freedom (nv 159 → 105). The flow is the granular flow of
frictionless hard spheres; a real granular content (peas, rice) has friction, which makes it
pile at an angle where this content levels out.

What the frictionless content saves in the physics step, measured against wall friction with
scripts/bench_physics.py: docs/bench/physics.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from shared.fipa_codec.languages.l_ex import TORSO_JOINT
from velma.model import KITCHEN_XML
from velma.model.mjcf import SCENE_CONAFFINITY, SCENE_CONTYPE

N_PARTICLES = 18
"""Content spheres in the jar. The physics step's cost grows with the contacts: with 27 the
1 kHz loop overran 2–4 % of its cycles on the 2-core development machine, with 18 0.3–0.7 %
(scripts/bench_loop.py; docs/executor.md): the count is what keeps the loop at its rate."""
PARTICLE_RADIUS = 0.009  # m
PARTICLE_MASS = 0.003  # kg
PARTICLE_PREFIX = "jar_content_"
PARTICLE_CONDIM = 1
"""Contact dimension of a sphere geom: frictionless in every contact (module docstring)."""
PARTICLE_PRIORITY = 1
"""Geom priority of a sphere: above the scene's (0), so its condim decides its contacts."""
PARTICLE_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
"""The slide joints ``{name}_{axis}`` of each sphere, world axes (module docstring)."""
HELIX_RADIUS = 0.022  # m, in the jar frame
HELIX_PER_TURN = 7
HELIX_PITCH = 0.021  # m per turn
HELIX_Z0 = 0.017  # m above the jar frame (bottom centre)
PERTURBED_OBJECTS = ("jar", "bowl")
POSE_OFFSET_MAX = 0.02  # m, |dx|, |dy| bound of the pose randomisation
POSE_YAW_MAX = math.radians(10.0)  # rad, |yaw| bound of the pose randomisation
REMOVED_AT = (-1.5, -0.2)  # m, world x, y on the floor (behind the robot) of the first removed sphere
REMOVED_SPACING = 0.05  # m along world y between removed spheres

# Home posture (rad), hands open. Left arm bent in front of the torso; right arm in the
# palm-down "ready" posture above the shelf (velma/scenario.py RIGHT_PICK_POSTURE explains
# why). Elbow/wrist joints 1, 3, 5 stay clear of the singular stretch (|q| ≥ 0.2).
HOME_POSTURE: dict[str, float] = {
    TORSO_JOINT: 0.0,
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


@dataclass(frozen=True)
class ObjectPerturbation:
    """Offset of one object from its kitchen.xml pose: ``dx``, ``dy`` (m, world x/y) and
    ``yaw`` (rad, about the object's vertical axis, applied before its own rotation)."""

    dx: float = 0.0
    dy: float = 0.0
    yaw: float = 0.0


@dataclass(frozen=True)
class ScenePerturbation:
    """The pose randomisation applied to the kitchen: one ``ObjectPerturbation`` per object
    of ``PERTURBED_OBJECTS`` (jar, bowl); ``seed`` is the pose seed (None: no perturbation)."""

    seed: int | None
    jar: ObjectPerturbation
    bowl: ObjectPerturbation

    def as_dict(self) -> dict[str, dict[str, float]]:
        """{object: {"dx": m, "dy": m, "yaw": rad}}, for printing and reports."""
        return {n: {"dx": p.dx, "dy": p.dy, "yaw": p.yaw} for n, p in self.objects().items()}

    def objects(self) -> dict[str, ObjectPerturbation]:
        """{object name: its perturbation}."""
        return {"jar": self.jar, "bowl": self.bowl}


def scene_perturbation(pose_seed: int | None) -> ScenePerturbation:
    """The perturbation that ``build_spec(..., pose_seed=pose_seed)`` applies: for each of jar
    and bowl (in that order) dx, dy uniform in ±``POSE_OFFSET_MAX`` m and yaw uniform in
    ±``POSE_YAW_MAX`` rad, drawn from ``numpy.random.default_rng(pose_seed)``; all zero for
    None. Raises ``ValueError`` for a negative seed (as numpy does)."""
    if pose_seed is None:
        return ScenePerturbation(seed=None, jar=ObjectPerturbation(), bowl=ObjectPerturbation())
    rng = np.random.default_rng(pose_seed)
    draws = []
    for _ in PERTURBED_OBJECTS:
        dx, dy = rng.uniform(-POSE_OFFSET_MAX, POSE_OFFSET_MAX, size=2)
        yaw = rng.uniform(-POSE_YAW_MAX, POSE_YAW_MAX)
        draws.append(ObjectPerturbation(dx=float(dx), dy=float(dy), yaw=float(yaw)))
    return ScenePerturbation(seed=pose_seed, jar=draws[0], bowl=draws[1])


def _yaw_quat(yaw: float) -> npt.NDArray[np.float64]:
    """Quaternion (w, x, y, z) of a rotation by ``yaw`` rad about z."""
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def build_spec(n_particles: int = N_PARTICLES, seed: int = 0, pose_seed: int | None = None) -> mujoco.MjSpec:
    """kitchen.xml as an MjSpec with the jar content added (see module docstring).

    ``seed`` jitters the content's start positions; ``pose_seed`` randomises the jar and bowl
    poses (``scene_perturbation``; None keeps kitchen.xml's poses exactly). Raises
    ``ValueError`` if ``n_particles`` does not fit the helix (more than 35)."""
    if not 0 <= n_particles <= 35:
        raise ValueError(f"n_particles={n_particles}: the jar holds 0..35 spheres")
    spec = mujoco.MjSpec.from_file(str(KITCHEN_XML))
    perturbation = scene_perturbation(pose_seed)
    if pose_seed is not None:
        for name, p in perturbation.objects().items():
            body = spec.body(name)
            body.pos = np.array(body.pos, dtype=float) + np.array([p.dx, p.dy, 0.0])
            quat = np.zeros(4)
            mujoco.mju_mulQuat(quat, _yaw_quat(p.yaw), np.array(body.quat, dtype=float))
            body.quat = quat
    jar = spec.body("jar")
    jar_pos = np.array(jar.pos, dtype=float)
    jar_mat = np.zeros(9)
    mujoco.mju_quat2Mat(jar_mat, np.array(jar.quat, dtype=float))
    jar_rot = jar_mat.reshape(3, 3)
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
        body = spec.worldbody.add_body(name=name, pos=jar_pos + jar_rot @ local)  # in the jar frame
        for axis, direction in PARTICLE_AXES.items():
            body.add_joint(name=f"{name}_{axis}", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=list(direction))
        body.add_geom(
            name=f"{name}_geom",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[PARTICLE_RADIUS, 0, 0],
            mass=PARTICLE_MASS,
            contype=SCENE_CONTYPE,  # the content collides as the scene does (mjcf.py)
            conaffinity=SCENE_CONAFFINITY,
            condim=PARTICLE_CONDIM,
            priority=PARTICLE_PRIORITY,
            solref=[0.004, 1.0],
            rgba=[0.85, 0.55, 0.1, 1.0],
        )
    return spec


def load_kitchen(
    n_particles: int = N_PARTICLES, seed: int = 0, pose_seed: int | None = None
) -> mujoco.MjModel:
    """Compiled kitchen model with ``n_particles`` content spheres and, for a ``pose_seed``,
    randomised jar and bowl poses (see ``build_spec``; same errors)."""
    return build_spec(n_particles, seed, pose_seed).compile()


def set_posture(model: mujoco.MjModel, data: mujoco.MjData, posture: dict[str, float]) -> None:
    """Write joint positions (rad) by name into ``data.qpos``; also sets the matching
    position-servo controls. Raises ``KeyError`` for an unknown joint name."""
    for name, value in posture.items():
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if jid < 0:
            raise KeyError(name)
        data.qpos[model.jnt_qposadr[jid]] = value


def remove_content(model: mujoco.MjModel, data: mujoco.MjData, count: int) -> list[str]:
    """Lay the top ``count`` content spheres of ``data`` (the last of the helix) on the floor
    behind the robot, at rest (module docstring); their names. Raises ``ValueError`` for a
    ``count`` outside 0 … the spheres the model has."""
    names = [model.body(b).name for b in range(model.nbody) if model.body(b).name.startswith(PARTICLE_PREFIX)]
    if not 0 <= count <= len(names):
        raise ValueError(f"cannot remove {count} spheres: the jar holds 0..{len(names)}")
    removed = sorted(names, key=lambda n: int(n[len(PARTICLE_PREFIX) :]))[len(names) - count :]
    for k, name in enumerate(removed):
        target = (REMOVED_AT[0], REMOVED_AT[1] + k * REMOVED_SPACING, PARTICLE_RADIUS)
        start = model.body(name).pos
        for (axis, _), to, at in zip(PARTICLE_AXES.items(), target, start, strict=True):
            joint = model.joint(f"{name}_{axis}")
            data.qpos[joint.qposadr[0]] = to - at
            data.qvel[joint.dofadr[0]] = 0.0
    return removed


def initial_state(model: mujoco.MjModel, settle_steps: int = 300, removed: int = 0) -> mujoco.MjData:
    """MjData in the home posture with the content settled (``settle_steps`` steps with the
    robot's joints frozen in place, 1 ms each); ``removed``: that many spheres taken out of the
    jar first (``remove_content``; same error)."""
    data = mujoco.MjData(model)
    set_posture(model, data, HOME_POSTURE)
    remove_content(model, data, removed)
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
