"""The MJCF writer of ``velma.xml`` (the Velma robot), from the numbers in this file
(``build``); velma/model/generate.py writes it. Every number (offsets, rpy → quaternions,
inertias) is computed once, from its source, rather than copied by hand into two arms and two
hands.

Sources. Every constant below names one of:

- *facts*: velma/model/README.md, the numbers of the real robot with their public sources
  (RCPRG's velma_robot, lwr_robot and barrett_hand_robot descriptions, the KUKA and Barrett
  documents; the section is named where it helps, e.g. "facts, KUKA LWR4+");
- *derived*: computed here from facts (the formula is next to it);
- *placeholder*: no public number exists (or the public model had a placeholder too); a
  physically plausible value is chosen and the reason is given;
- *everyday size*: for kitchen objects, the size or mass of a common household item.

Masses and inertias (what was chosen and why):

- torso_base and torso_link0: 30 kg each (facts), inertia of a uniform cylinder / box of the
  drawn size (placeholder shape).
- LWR4+ arm: the public URDF has placeholders (2.0 kg links 1–5, 0.2 kg link 6); the real arm
  weighs 16 kg (facts). The 16 kg are split as base 1.6 kg, links 1–4 2.7 kg each (they hold
  the large drive modules of joints 1–4, which give 100 N·m), link 5 1.7 kg and link 6 1.6 kg
  (the smaller 60 N·m wrist drives), link 7 (flange) 0.3 kg: sum 16.0 kg. Inertia: uniform
  cylinders of the link's length. Placeholder, not identified data.
- BarrettHand BH8-282: palm 0.6335, knuckle-one 0.1625, proximal 0.058, distal 0.0342 kg
  (facts), 1.235 kg in all. The hand assembly load on the wrist is 1.53 kg (facts); the
  remaining 0.295 kg (derived) is the gripper mount and F/T sensor housing, a separate
  jointless body between the flange and the palm. The palm's centre of mass is solved for so
  that the whole assembly (spread 0, fingers open) has its centre of mass at the facts'
  (0.152, 0.011, −0.069) m in the gripper-mount frame (derived). The wrist F/T sensor measures
  the palm and fingers only (everything beyond its measuring plane): hanging still, it reads
  ≈ 1.235 kg × g ≈ 12.1 N.
- Head: 0.8 + 0.5 + 1.5 kg for neck base, pan link and head with cameras (placeholder: a
  pan-tilt unit and a Kinect-class sensor head).

Simplifications (named):

- Geometry is capsules, cylinders, boxes and spheres instead of meshes.
- Joint armature (reflected motor inertia), arm joint damping and the servo gains of the
  hand and neck are plausible values, not data: the facts give damping only for the torso.
- Velocity limits have no MJCF field. ``velocity_limits()`` lists the real robot's per joint
  (tests compare them with the facts); the controllers enforce the limits in control instead,
  not the physics: 2 rad/s on every arm joint (``ARM_CONTROL_VELOCITY``), 0.52 rad/s on the
  torso, 1.04 rad/s on both neck joints (velma/control/limits.py, velma/world/hardware.py).
- The hand's breakaway clutch is modelled in the hand controller (velma/control/hand.py),
  with independent position servos on the proximal and distal joints here.
- Robot self-collision is on: the robot's geoms collide with each other as with the scene,
  except the pairs of ``SELF_COLLISION_EXCLUDES`` ("Self-collision" below).

Numbers written inline in the ``<geom>`` elements (shape sizes and positions, colours) and
the inertial offsets of the torso and head bodies are drawing geometry: placeholder shapes
sized to the link lengths above, not data.
"""

from __future__ import annotations

import math

import numpy as np

from shared.fipa_codec.languages.l_ex import TORSO_JOINT
from velma.model.mjcf import (
    OPTION,
    ROBOT_CONAFFINITY,
    ROBOT_CONTYPE,
    Quat,
    Vec,
    Writer,
    add,
    box_inertia,
    cylinder_inertia,
    f,
    inertial,
)
from velma.rotations import quat_matrix, quat_mul, quat_rotate, rpy_to_quat

# ----------------------------------------------------------------- torso (facts, "Structure")
TORSO_JOINT_Z = 0.03  # m, TORSO_JOINT above torso_base (facts)
TORSO_LIMIT = 1.57  # rad (facts)
TORSO_VELOCITY = 0.52  # rad/s, 30 °/s (facts)
TORSO_DAMPING = 10.0  # N·m·s/rad (facts)
TORSO_BASE_MASS = 30.0  # kg (facts)
TORSO_LINK0_MASS = 30.0  # kg (facts)
TORSO_ARMATURE = 0.5  # kg·m², placeholder (reflected inertia of a large geared drive)
TORSO_TORQUE = 300.0  # N·m, placeholder (not in the facts; ≥ what joint impedance K = 1200 asks)

# ----------------------------------------------------------------- head (facts, "Structure")
HEAD_BASE = (0.0105, -0.001, 1.3117)  # m, head_base on torso_link0 (facts)
HEAD_PAN_Z = 0.087  # m (facts)
HEAD_TILT_Z = 0.048  # m (facts)
HEAD_PAN_RANGE = (-1.57, 1.57)  # rad (facts)
HEAD_TILT_RANGE = (-1.0, 1.3)  # rad (facts)
HEAD_PAN_VELOCITY = 1.57  # rad/s (facts)
NECK_VELOCITY = 1.04  # rad/s, the neck's velocity limit in control, both joints (facts)
HEAD_MASSES = (0.8, 0.5, 1.5)  # kg: head_base, pan link, tilt link (placeholder, see docstring)
HEAD_ARMATURE = 0.01  # kg·m², placeholder
HEAD_DAMPING = 0.5  # N·m·s/rad, placeholder
HEAD_SERVO_KP = (40.0, 60.0)  # N·m/rad, pan, tilt: placeholder position-servo gains
HEAD_SERVO_TORQUE = (10.0, 15.0)  # N·m, pan, tilt: placeholder servo torque limits
# Head camera: a Kinect-class RGB-D camera on the head ("Cameras and a Kinect sit on the head",
# facts). Its field of view is the Kinect (v1) RGB camera's 57° × 43° (everyday size: the
# sensor's data sheet); MJCF's fovy is the vertical one. Position on the head: placeholder
# (0.1 m ahead of and 0.06 m above the tilt axis; velma/executor/primitives.py uses 0.06).
HEAD_CAMERA_POS = (0.1, 0.0, 0.06)  # m, in head_tilt_link
HEAD_CAMERA_FOVY = 43.0  # degrees

# ----------------------------------------------------------------- arms (facts, "Structure")
ARM_MOUNT = {  # (xyz m, rpy rad) of {side}_arm_base_link in torso_link0 (facts)
    "right": ((-0.0004, -0.000889, 1.17335), (-0.00045, -1.04747, 1.57047)),
    "left": ((-0.0006, -0.001311, 1.17335), (0.00087, 1.04750, 1.57243)),
}
# KUKA LWR4+ (facts, "KUKA LWR4+" table): per joint k = 0..6 the z offset of its origin from the
# previous link (m), its axis, its limit (±degrees), its velocity limit (degrees/s) and the
# torque limit used on Velma (N·m: 100 for joints 0–4, 60 for 5–6).
ARM_JOINTS: tuple[tuple[float, Vec, float, float, float], ...] = (
    (0.11, (0, 0, 1), 170.0, 110.0, 100.0),
    (0.2005, (0, 1, 0), 120.0, 110.0, 100.0),
    (0.20, (0, 0, 1), 170.0, 130.0, 100.0),
    (0.20, (0, -1, 0), 120.0, 130.0, 100.0),
    (0.20, (0, 0, 1), 170.0, 130.0, 100.0),
    (0.19, (0, 1, 0), 120.0, 180.0, 60.0),
    (0.078, (0, 0, 1), 170.0, 180.0, 60.0),
)
ARM_CONTROL_VELOCITY = 2.0  # rad/s, arm joint velocity limit in control (facts)
ARM_MASS = 16.0  # kg, the real LWR4+ (facts)
ARM_BASE_MASS = 1.6  # kg, placeholder split of ARM_MASS (see docstring)
ARM_LINK_MASS = (2.7, 2.7, 2.7, 2.7, 1.7, 1.6, 0.3)  # kg, arm_1_link … arm_7_link, placeholder split
ARM_RADIUS = 0.06  # m, LWR4+ links are ≈ 0.12 m thick (placeholder shape)
ARM_ARMATURE = (0.2, 0.2, 0.1, 0.1, 0.05, 0.03, 0.03)  # kg·m², placeholder reflected motor inertia
ARM_DAMPING = 0.5  # N·m·s/rad, placeholder (the facts give damping for the torso only)

# ----------------------------------------------------------------- tool chain (facts, "KUKA LWR4+")
MOUNT_YAW = {"right": 0.0, "left": math.pi}  # rad, gripper_mount in arm_7_link (facts)
FT_IN_MOUNT = ((0.115, 0.0, -0.078), (0.0, math.pi / 2, 0.0))  # F/T sensor (xyz m, rpy rad) (facts)
PALM_IN_FT_Z = 0.005  # m (facts)
GRIP_IN_PALM_Z = 0.12  # m, {side}_HandGripLink (facts)
HAND_ASSEMBLY_MASS = 1.53  # kg, total load on the wrist (facts)
HAND_ASSEMBLY_COM = (0.152, 0.011, -0.069)  # m, in the gripper-mount (link-7) frame (facts)
# Gripper mount + F/T sensor housing (a box between flange and palm): its centre, placeholder.
BRACKET_COM = (0.0575, 0.0, -0.078)  # m, in the gripper-mount frame

# ----------------------------------------------------------------- BarrettHand BH8-282 (facts)
PALM_MASS = 0.6335  # kg (facts)
KNUCKLE_ONE_MASS = 0.1625  # kg (facts)
PROXIMAL_MASS = 0.058  # kg (facts)
DISTAL_MASS = 0.0342  # kg (facts)
SPREAD_ORIGIN_X = 0.02497  # m, ± for fingers One/Two (facts)
SPREAD_ORIGIN_Z = 0.0587966  # m (facts)
SPREAD_YAW = math.pi / 2  # rad, rpy yaw of both knuckle-one frames (facts give it for F1; F2
# needs the same yaw for fingers One and Two to oppose finger Three, as on the real hand)
PROXIMAL_IN_KNUCKLE = (0.05, 0.0, 0.0166034)  # m, F1/F2 (facts)
PROXIMAL_RPY = (-math.pi / 2, 0.0, 0.0)  # rad, F1/F2 (facts)
F3_PROXIMAL_IN_PALM = ((0.0, -0.05, 0.0754), (-math.pi / 2, 0.0, -math.pi / 2))  # (facts)
DISTAL_IN_PROXIMAL_X = 0.07  # m (facts)
DISTAL_BEND = -0.690452252  # rad, rpy yaw of the distal origin (facts: −0.69045, more digits kept)
FINGER_SPREAD_RANGE = (0.0, math.pi)  # rad (facts)
PROXIMAL_RANGE = (0.0, 2.4434)  # rad (facts)
DISTAL_RANGE = (0.0, 0.8377)  # rad (facts)
FINGER_VELOCITY = 3.27  # rad/s (facts)
DISTAL_HALF = (0.025, 0.01, 0.01)  # m, distal collision box ≈ 0.05 × 0.02 × 0.02 (facts)
PROXIMAL_HALF = (0.035, 0.01, 0.012)  # m, placeholder (0.07 m long link)
FINGER_ARMATURE = 0.01  # kg·m², placeholder (the hand's geared motors)
FINGER_DAMPING = 0.05  # N·m·s/rad, placeholder
# Position servos (kp N·m/rad, torque limit N·m), placeholders: the real hand is position
# controlled (facts); the limits give ≈ 10 N at the fingertip, enough to hold the 0.33 kg jar
# by friction. The breakaway torque of the proximal clutch (≈ 1 N·m, facts) is applied by the
# hand controller (velma/control/hand.py), below the proximal servo's limit.
SPREAD_SERVO = (10.0, 2.0)
PROXIMAL_SERVO = (20.0, 1.5)
DISTAL_SERVO = (10.0, 0.6)

# Contacts of the hand pads (facts, "MuJoCo notes": impratio ≈ 10; it is 30 in <option>, where
# the cones are pyramidal; pads soft-but-stiff (solref ≈ 0.004), friction ≈ 0.7–1.0).
PAD_FRICTION = "1.0 0.02 0.001"
PAD_SOLREF = "0.004 1"
PAD_SOLIMP = "0.95 0.99 0.001"  # placeholder (stiff once in contact)
ROBOT_FRICTION = "0.8 0.02 0.001"  # placeholder (rubber/aluminium on wood or glass)

# Self-collision. Contact bits: robot geoms contype 2, conaffinity 3; scene geoms
# contype 1, conaffinity 3. MuJoCo collides two geoms when (contype₁ & conaffinity₂) or
# (contype₂ & conaffinity₁) is non-zero, so robot–robot (2 & 3), robot–scene and scene–scene
# pairs all collide. Pairs left out, by the rules of MoveIt's Setup Assistant (the "adjacent",
# "default" and "always" rules of an SRDF):
# - adjacent: a body and its parent, by MuJoCo's own parent–child filter (welded bodies count
#   as one: the gripper mount and the palm are one body with arm_7_link), and, as MoveIt counts
#   them, two bodies joined through a body without collision geometry: the head's base and its
#   tilt link, joined through the pan link (their boxes meet when the head looks down at the
#   table; the real neck's range is its joint limits);
# - default and always: pairs that touch in the zero configuration or in ≥ 95 % of random
#   configurations within the joint limits, i.e. that overlap by construction of the
#   simplified geometry. Only the wrist pair below does: the gripper mount's bracket box
#   spans the wrist's centre, where the forearm capsule ends (3000 random configurations).
SELF_COLLISION_EXCLUDES = (
    *((f"{side}_arm_5_link", f"{side}_gripper_mount_link") for side in ("right", "left")),
    ("head_base", "head_tilt_link"),
)


def velocity_limits() -> dict[str, float]:
    """Joint velocity limits of the real robot, rad/s, by joint name (33 joints).

    Sources: facts (torso 0.52, head pan 1.57, neck 1.04 for the tilt joint, LWR4+ table,
    finger joints 3.27). MJCF has no velocity-limit field; the controllers enforce them (the
    arms are further limited to ``ARM_CONTROL_VELOCITY`` = 2 rad/s in control)."""
    out = {
        TORSO_JOINT: TORSO_VELOCITY,
        "head_pan_joint": HEAD_PAN_VELOCITY,
        "head_tilt_joint": NECK_VELOCITY,
    }
    for side in ("right", "left"):
        for k, joint in enumerate(ARM_JOINTS):
            out[f"{side}_arm_{k}_joint"] = math.radians(joint[3])
        for finger_name in ("One", "Two", "Three"):
            for link in ("One", "Two", "Three"):
                if link == "One" and finger_name == "Three":
                    continue  # finger Three has no spread joint
                out[f"{side}_HandFinger{finger_name}Knuckle{link}Joint"] = FINGER_VELOCITY
    return out


def effort_limits() -> dict[str, float]:
    """Actuator torque limits, N·m, by joint name (33 joints), as written into velma.xml
    (``forcerange`` of each actuator and ``actuatorfrcrange`` of each joint).

    Sources: facts for the arms (100 N·m joints 0–4, 60 N·m joints 5–6); placeholders for the
    torso, neck and hand servos (see the constants)."""
    out = {TORSO_JOINT: TORSO_TORQUE}
    out["head_pan_joint"], out["head_tilt_joint"] = HEAD_SERVO_TORQUE
    for side in ("right", "left"):
        for k, joint in enumerate(ARM_JOINTS):
            out[f"{side}_arm_{k}_joint"] = joint[4]
        for finger_name in ("One", "Two", "Three"):
            if finger_name != "Three":
                out[f"{side}_HandFinger{finger_name}KnuckleOneJoint"] = SPREAD_SERVO[1]
            out[f"{side}_HandFinger{finger_name}KnuckleTwoJoint"] = PROXIMAL_SERVO[1]
            out[f"{side}_HandFinger{finger_name}KnuckleThreeJoint"] = DISTAL_SERVO[1]
    return out


# ----------------------------------------------------------------- hand geometry (derived)
PROXIMAL_COM = (0.035, 0.0, 0.0)  # m, in the proximal link frame (middle of the 0.07 m link)
DISTAL_COM = (0.025, 0.0, 0.0)  # m, in the distal link frame (middle of the collision box)
KNUCKLE_COM = (0.025, 0.0, 0.008)  # m, in the knuckle-one frame (placeholder: middle of the link)


def palm_frame_in_mount() -> tuple[Vec, Quat]:
    """Pose (position m, quaternion) of the palm in the gripper-mount frame (facts)."""
    q_ft = rpy_to_quat(FT_IN_MOUNT[1])
    return add(FT_IN_MOUNT[0], quat_rotate(q_ft, (0.0, 0.0, PALM_IN_FT_Z))), q_ft


def fingers_mass_moment() -> tuple[float, Vec]:
    """Mass (kg) and first moment Σ m·c (kg·m) of the knuckle, proximal and distal links of
    the three fingers in the palm frame, at spread 0 with the fingers open (derived)."""
    q_knuckle = rpy_to_quat((0.0, 0.0, SPREAD_YAW))
    q_distal = rpy_to_quat((0.0, 0.0, DISTAL_BEND))
    total = 0.0
    moment = np.zeros(3)

    def link(pos: Vec, q: Quat) -> None:
        nonlocal total, moment
        prox_c = add(pos, quat_rotate(q, PROXIMAL_COM))
        d_pos = add(pos, quat_rotate(q, (DISTAL_IN_PROXIMAL_X, 0.0, 0.0)))
        dist_c = add(d_pos, quat_rotate(quat_mul(q, q_distal), DISTAL_COM))
        moment += PROXIMAL_MASS * np.array(prox_c) + DISTAL_MASS * np.array(dist_c)
        total += PROXIMAL_MASS + DISTAL_MASS

    for sign in (1.0, -1.0):
        k_pos = (sign * SPREAD_ORIGIN_X, 0.0, SPREAD_ORIGIN_Z)
        moment += KNUCKLE_ONE_MASS * np.array(add(k_pos, quat_rotate(q_knuckle, KNUCKLE_COM)))
        total += KNUCKLE_ONE_MASS
        link(
            add(k_pos, quat_rotate(q_knuckle, PROXIMAL_IN_KNUCKLE)),
            quat_mul(q_knuckle, rpy_to_quat(PROXIMAL_RPY)),
        )
    link(F3_PROXIMAL_IN_PALM[0], rpy_to_quat(F3_PROXIMAL_IN_PALM[1]))
    return total, (float(moment[0]), float(moment[1]), float(moment[2]))


def bracket_mass() -> float:
    """Gripper mount + F/T sensor mass, kg (derived: assembly minus palm and fingers)."""
    return HAND_ASSEMBLY_MASS - PALM_MASS - fingers_mass_moment()[0]


def palm_com() -> Vec:
    """Centre of mass of the palm link in the palm frame, m (derived: puts the centre of mass
    of bracket + palm + open fingers at ``HAND_ASSEMBLY_COM``)."""
    palm_pos, q_palm = palm_frame_in_mount()
    r = quat_matrix(q_palm)
    target = r.T @ (np.array(HAND_ASSEMBLY_COM) - np.array(palm_pos))  # in the palm frame
    bracket = r.T @ (np.array(BRACKET_COM) - np.array(palm_pos))
    _, moment = fingers_mass_moment()
    c = (HAND_ASSEMBLY_MASS * target - bracket_mass() * bracket - np.array(moment)) / PALM_MASS
    return (float(c[0]), float(c[1]), float(c[2]))


# ----------------------------------------------------------------- model pieces
def finger(w: Writer, side: str, finger_name: str) -> None:
    """Proximal (KnuckleTwo) and distal (KnuckleThree) links of one finger; the caller has
    opened the body that holds the proximal joint's origin."""
    w.add(inertial(PROXIMAL_COM, PROXIMAL_MASS, box_inertia(PROXIMAL_MASS, PROXIMAL_HALF)))
    w.add(
        f'<joint name="{side}_HandFinger{finger_name}KnuckleTwoJoint" class="finger" '
        f'axis="0 0 -1" range="{f(*PROXIMAL_RANGE)}" '
        f'actuatorfrcrange="{f(-PROXIMAL_SERVO[1], PROXIMAL_SERVO[1])}"/>'
    )
    w.add(f'<geom name="{side}_f{finger_name}_prox" class="pad" fromto="0.012 0 0 0.062 0 0" size="0.011"/>')
    w.open(
        f'<body name="{side}_HandFinger{finger_name}KnuckleThreeLink" pos="{f(DISTAL_IN_PROXIMAL_X, 0, 0)}" '
        f'quat="{f(*rpy_to_quat((0.0, 0.0, DISTAL_BEND)))}">'
    )
    w.add(inertial(DISTAL_COM, DISTAL_MASS, box_inertia(DISTAL_MASS, DISTAL_HALF)))
    w.add(
        f'<joint name="{side}_HandFinger{finger_name}KnuckleThreeJoint" class="finger" '
        f'axis="0 0 -1" range="{f(*DISTAL_RANGE)}" '
        f'actuatorfrcrange="{f(-DISTAL_SERVO[1], DISTAL_SERVO[1])}"/>'
    )
    # capsule 0.008–0.045 m, radius 0.01: ≈ the facts' 0.05 × 0.02 × 0.02 m box, rounded
    w.add(f'<geom name="{side}_f{finger_name}_dist" class="pad" fromto="0.008 0 0 0.045 0 0" size="0.01"/>')
    w.close("body")


def hand(w: Writer, side: str) -> None:
    """Gripper mount (with the F/T sensor housing), palm with the F/T sensor site and the
    grip-frame site, and the three fingers of a BarrettHand BH8-282, attached to
    ``{side}_arm_7_link`` (the caller has that body open).

    The mount and the palm are both jointless children of arm_7_link (siblings), not a chain:
    Pinocchio 4.1's MJCF parser misplaces sites of a body nested two jointless levels deep
    (it drops the middle body's rotation; tests/velma/test_velma_model.py checks every site)."""
    q_mount = rpy_to_quat((0.0, 0.0, MOUNT_YAW[side]))
    w.open(f'<body name="{side}_gripper_mount_link" quat="{f(*q_mount)}">')
    half = (abs(0.5 * FT_IN_MOUNT[0][0]) + 0.03, 0.035, 0.03)  # placeholder bracket shape
    w.add(inertial(BRACKET_COM, bracket_mass(), box_inertia(bracket_mass(), half)))
    w.add(
        f'<geom name="{side}_hand_bracket" class="robot" type="box" pos="{f(*BRACKET_COM)}" '
        f'size="{f(*half)}" rgba="0.3 0.3 0.32 1"/>'
    )
    w.close("body")
    palm_pos, q_palm = palm_frame_in_mount()
    w.open(
        f'<body name="{side}_HandPalmLink" pos="{f(*quat_rotate(q_mount, palm_pos))}" '
        f'quat="{f(*quat_mul(q_mount, q_palm))}">'
    )
    w.add(inertial(palm_com(), PALM_MASS, cylinder_inertia(PALM_MASS, 0.045, 0.09)))
    # The F/T sensor frame (facts: palm = F/T + 0.005 z); MuJoCo's force/torque sensors on
    # this site measure the wrench that the mount exerts on the palm body's subtree.
    w.add(f'<site name="{side}_ft_sensor" pos="0 0 {f(-PALM_IN_FT_Z)}" size="0.01" rgba="1 0.5 0 1"/>')
    w.add(f'<site name="{side}_HandGripLink" pos="0 0 {f(GRIP_IN_PALM_Z)}" size="0.008" rgba="0 1 0 0.6"/>')
    w.add(
        f'<geom name="{side}_ft_geom" class="robot" type="cylinder" pos="0 0 -0.02" size="0.04 0.02" '
        'rgba="0.5 0.5 0.5 1"/>'
    )
    w.add(
        f'<geom name="{side}_palm" class="robot" type="cylinder" pos="0 0 0.03" size="0.045 0.03" '
        'rgba="0.15 0.15 0.15 1"/>'
    )
    w.add(f'<geom name="{side}_palm_pad" class="pad" type="box" pos="0 0 0.066" size="0.04 0.04 0.006"/>')
    spread_joints = (("One", SPREAD_ORIGIN_X, "0 0 -1"), ("Two", -SPREAD_ORIGIN_X, "0 0 1"))  # (facts)
    for name, x, axis in spread_joints:
        w.open(
            f'<body name="{side}_HandFinger{name}KnuckleOneLink" pos="{f(x, 0, SPREAD_ORIGIN_Z)}" '
            f'quat="{f(*rpy_to_quat((0.0, 0.0, SPREAD_YAW)))}">'
        )
        w.add(inertial(KNUCKLE_COM, KNUCKLE_ONE_MASS, box_inertia(KNUCKLE_ONE_MASS, (0.025, 0.012, 0.01))))
        w.add(
            f'<joint name="{side}_HandFinger{name}KnuckleOneJoint" class="finger" axis="{axis}" '
            f'range="{f(*FINGER_SPREAD_RANGE)}" actuatorfrcrange="{f(-SPREAD_SERVO[1], SPREAD_SERVO[1])}"/>'
        )
        w.add(
            f'<geom name="{side}_f{name}_knuckle" class="robot" type="box" pos="0.03 0 0.004" '
            'size="0.022 0.012 0.008" rgba="0.2 0.2 0.2 1"/>'
        )
        w.open(
            f'<body name="{side}_HandFinger{name}KnuckleTwoLink" pos="{f(*PROXIMAL_IN_KNUCKLE)}" '
            f'quat="{f(*rpy_to_quat(PROXIMAL_RPY))}">'
        )
        finger(w, side, name)
        w.close("body")
        w.close("body")
    w.open(
        f'<body name="{side}_HandFingerThreeKnuckleTwoLink" pos="{f(*F3_PROXIMAL_IN_PALM[0])}" '
        f'quat="{f(*rpy_to_quat(F3_PROXIMAL_IN_PALM[1]))}">'
    )
    finger(w, side, "Three")
    w.close("body")
    w.close("body")


def arm(w: Writer, side: str) -> None:
    """LWR4+ arm ``side`` from its mount on torso_link0 to link 7 and the hand."""
    pos, rpy = ARM_MOUNT[side]
    w.open(f'<body name="{side}_arm_base_link" pos="{f(*pos)}" quat="{f(*rpy_to_quat(rpy))}">')
    w.add(inertial((0, 0, 0.055), ARM_BASE_MASS, cylinder_inertia(ARM_BASE_MASS, ARM_RADIUS, 0.11)))
    w.add(
        f'<geom class="robot" type="cylinder" pos="0 0 0.055" size="{f(ARM_RADIUS)} 0.055" '
        'rgba="0.9 0.5 0.1 1"/>'
    )
    opened = 1
    for k, (dz, axis, limit, _velocity, torque) in enumerate(ARM_JOINTS):
        w.open(f'<body name="{side}_arm_{k + 1}_link" pos="0 0 {f(dz)}">')
        opened += 1
        next_dz = ARM_JOINTS[k + 1][0] if k + 1 < len(ARM_JOINTS) else 0.02
        mass = ARM_LINK_MASS[k]
        if k < 6:
            length = next_dz
            w.add(inertial((0, 0, length / 2), mass, cylinder_inertia(mass, ARM_RADIUS * 0.9, length)))
        else:
            w.add(inertial((0, 0, -0.01), mass, cylinder_inertia(mass, 0.04, 0.02)))
        lim = math.radians(limit)
        w.add(
            f'<joint name="{side}_arm_{k}_joint" class="arm" axis="{f(*axis)}" range="{f(-lim, lim)}" '
            f'armature="{f(ARM_ARMATURE[k])}" actuatorfrcrange="{f(-torque, torque)}"/>'
        )
        rgba = "0.9 0.5 0.1 1" if k % 2 == 0 else "0.85 0.85 0.85 1"
        if k < 5:
            w.add(
                f'<geom class="robot" type="capsule" fromto="0 0 0.0 0 0 {f(next_dz)}" '
                f'size="{f(ARM_RADIUS)}" '
                f'rgba="{rgba}"/>'
            )
        elif k == 5:
            w.add(f'<geom class="robot" type="sphere" size="0.055" rgba="{rgba}"/>')
            w.add(
                '<geom class="robot" type="cylinder" pos="0 0 0.04" size="0.04 0.04" rgba="0.3 0.3 0.3 1"/>'
            )
        else:
            w.add(
                '<geom class="robot" type="cylinder" pos="0 0 -0.005" size="0.045 0.008" '
                'rgba="0.3 0.3 0.3 1"/>'
            )
            hand(w, side)
    for _ in range(opened):
        w.close("body")


def head(w: Writer) -> None:
    """Neck (pan, tilt) and head with the camera ``head_camera`` looking along the tilt
    link's +x (image x = −y, image up = +z of head_tilt_link); the site ``head_camera_site``
    has the camera's pose (for Pinocchio, which does not read cameras)."""
    m_base, m_pan, m_tilt = HEAD_MASSES
    w.open(f'<body name="head_base" pos="{f(*HEAD_BASE)}">')
    w.add(inertial((0, 0, 0.04), m_base, cylinder_inertia(m_base, 0.05, 0.08)))
    w.add('<geom class="robot" type="cylinder" pos="0 0 0.04" size="0.05 0.04" rgba="0.3 0.3 0.3 1"/>')
    w.open(f'<body name="head_pan_link" pos="0 0 {f(HEAD_PAN_Z)}">')
    w.add(inertial((0, 0, 0.02), m_pan, cylinder_inertia(m_pan, 0.04, 0.04)))
    w.add(
        f'<joint name="head_pan_joint" class="head" axis="0 0 1" range="{f(*HEAD_PAN_RANGE)}" '
        f'actuatorfrcrange="{f(-HEAD_SERVO_TORQUE[0], HEAD_SERVO_TORQUE[0])}"/>'
    )
    w.open(f'<body name="head_tilt_link" pos="0 0 {f(HEAD_TILT_Z)}">')
    w.add(inertial((0.02, 0, 0.06), m_tilt, box_inertia(m_tilt, (0.06, 0.12, 0.06))))
    w.add(
        f'<joint name="head_tilt_joint" class="head" axis="0 1 0" range="{f(*HEAD_TILT_RANGE)}" '
        f'actuatorfrcrange="{f(-HEAD_SERVO_TORQUE[1], HEAD_SERVO_TORQUE[1])}"/>'
    )
    w.add('<geom class="robot" type="box" pos="0.02 0 0.06" size="0.06 0.12 0.06" rgba="0.8 0.8 0.8 1"/>')
    w.add('<geom class="robot" type="box" pos="0.085 0 0.05" size="0.015 0.09 0.02" rgba="0.1 0.1 0.1 1"/>')
    w.add(
        f'<camera name="head_camera" pos="{f(*HEAD_CAMERA_POS)}" xyaxes="0 -1 0 0 0 1" '
        f'fovy="{f(HEAD_CAMERA_FOVY)}"/>'
    )
    w.add(f'<site name="head_camera_site" pos="{f(*HEAD_CAMERA_POS)}" xyaxes="0 -1 0 0 0 1" size="0.01"/>')
    for _ in range(3):
        w.close("body")


def build() -> str:
    """The full velma.xml text.

    Raises ``ValueError`` if the arm's link masses do not add up to ``ARM_MASS`` or the hand
    parts weigh more than the assembly (inconsistent constants)."""
    _check_masses()
    w = Writer()
    w.add(
        "<!-- GENERATED by velma/model/generate.py (sources: velma/model/README.md; placeholders "
        "named in the generator): edit the generator, not this file. -->"
    )
    w.open('<mujoco model="velma">')
    w.add('<compiler angle="radian" autolimits="true"/>')
    w.add(OPTION)
    for section in (_defaults, _worldbody, _contact, _actuators, _sensors):
        section(w)
    w.close("mujoco")
    return "\n".join(w.lines) + "\n"


def _check_masses() -> None:
    """ValueError when the arm's link masses do not add up to ``ARM_MASS`` or the hand parts
    weigh more than the assembly."""
    if not math.isclose(ARM_BASE_MASS + sum(ARM_LINK_MASS), ARM_MASS):
        raise ValueError(f"arm link masses add up to {ARM_BASE_MASS + sum(ARM_LINK_MASS)} kg, not {ARM_MASS}")
    if bracket_mass() <= 0.0:
        raise ValueError("BarrettHand parts weigh more than the hand assembly")


def _defaults(w: Writer) -> None:
    """The default classes: velma's geoms, robot, pad, and the arm's, finger and head joints."""
    w.open("<default>")
    w.open('<default class="velma">')
    robot_bits = f'contype="{ROBOT_CONTYPE}" conaffinity="{ROBOT_CONAFFINITY}"'
    w.add(f'<geom {robot_bits} condim="3" friction="{ROBOT_FRICTION}"/>')
    w.open('<default class="robot">')
    w.add(f"<geom {robot_bits}/>")
    w.close("default")
    w.open('<default class="pad">')
    w.add(
        f'<geom type="capsule" {robot_bits} condim="4" friction="{PAD_FRICTION}" '
        f'solref="{PAD_SOLREF}" solimp="{PAD_SOLIMP}" rgba="0.25 0.25 0.25 1"/>'
    )
    w.close("default")
    w.open('<default class="arm">')
    w.add(f'<joint type="hinge" damping="{f(ARM_DAMPING)}" limited="true"/>')
    w.close("default")
    w.open('<default class="finger">')
    w.add(
        f'<joint type="hinge" damping="{f(FINGER_DAMPING)}" armature="{f(FINGER_ARMATURE)}" limited="true"/>'
    )
    w.close("default")
    w.open('<default class="head">')
    w.add(f'<joint type="hinge" damping="{f(HEAD_DAMPING)}" armature="{f(HEAD_ARMATURE)}" limited="true"/>')
    w.close("default")
    w.close("default")
    w.close("default")


def _worldbody(w: Writer) -> None:
    """The robot's bodies: torso, head, both arms."""
    w.open("<worldbody>")
    w.open('<body name="torso_base" childclass="velma">')
    w.add(inertial((0, 0, 0.25), TORSO_BASE_MASS, cylinder_inertia(TORSO_BASE_MASS, 0.25, 0.5)))
    w.add('<geom class="robot" type="cylinder" pos="0 0 0.015" size="0.3 0.015" rgba="0.25 0.25 0.25 1"/>')
    w.open(f'<body name="torso_link0" pos="0 0 {f(TORSO_JOINT_Z)}">')
    w.add(inertial((0, 0, 0.7), TORSO_LINK0_MASS, box_inertia(TORSO_LINK0_MASS, (0.12, 0.18, 0.6))))
    w.add(
        f'<joint name="{TORSO_JOINT}" type="hinge" axis="0 0 1" range="{f(-TORSO_LIMIT, TORSO_LIMIT)}" '
        f'damping="{f(TORSO_DAMPING)}" armature="{f(TORSO_ARMATURE)}" '
        f'actuatorfrcrange="{f(-TORSO_TORQUE, TORSO_TORQUE)}"/>'
    )
    w.add('<geom class="robot" type="cylinder" pos="0 0 0.55" size="0.11 0.55" rgba="0.6 0.6 0.62 1"/>')
    w.add('<geom class="robot" type="box" pos="-0.03 0 1.16" size="0.1 0.14 0.09" rgba="0.6 0.6 0.62 1"/>')
    head(w)
    arm(w, "right")
    arm(w, "left")
    w.close("body")
    w.close("body")
    w.close("worldbody")


def _contact(w: Writer) -> None:
    """The pairs of the robot's own bodies that do not collide."""
    w.open("<contact>")
    for body1, body2 in SELF_COLLISION_EXCLUDES:
        w.add(f'<exclude body1="{body1}" body2="{body2}"/>')
    w.close("contact")


def _actuators(w: Writer) -> None:
    """The arm and torso motors, the head servos and the fingers' servos."""
    w.open("<actuator>")
    for side in ("right", "left"):
        for k in range(7):
            lim = ARM_JOINTS[k][4]
            w.add(
                f'<motor name="{side}_arm_{k}_motor" joint="{side}_arm_{k}_joint" '
                f'ctrlrange="{f(-lim, lim)}" forcerange="{f(-lim, lim)}"/>'
            )
    w.add(
        f'<motor name="torso_0_motor" joint="{TORSO_JOINT}" ctrlrange="{f(-TORSO_TORQUE, TORSO_TORQUE)}" '
        f'forcerange="{f(-TORSO_TORQUE, TORSO_TORQUE)}"/>'
    )
    for joint, kp, torque, lo_hi in (
        ("head_pan", HEAD_SERVO_KP[0], HEAD_SERVO_TORQUE[0], HEAD_PAN_RANGE),
        ("head_tilt", HEAD_SERVO_KP[1], HEAD_SERVO_TORQUE[1], HEAD_TILT_RANGE),
    ):
        w.add(
            f'<position name="{joint}_servo" joint="{joint}_joint" kp="{f(kp)}" dampratio="1" '
            f'ctrlrange="{f(*lo_hi)}" forcerange="{f(-torque, torque)}"/>'
        )
    _hand_servos(w)
    w.close("actuator")


def _hand_servos(w: Writer) -> None:
    """The fingers' position servos (spread, proximal and distal) of both hands."""
    for side in ("right", "left"):
        for name in ("One", "Two"):
            w.add(
                f'<position name="{side}_HandFinger{name}KnuckleOneServo" '
                f'joint="{side}_HandFinger{name}KnuckleOneJoint" kp="{f(SPREAD_SERVO[0])}" dampratio="1" '
                f'ctrlrange="{f(*FINGER_SPREAD_RANGE)}" forcerange="{f(-SPREAD_SERVO[1], SPREAD_SERVO[1])}"/>'
            )
        for name in ("One", "Two", "Three"):
            w.add(
                f'<position name="{side}_HandFinger{name}KnuckleTwoServo" '
                f'joint="{side}_HandFinger{name}KnuckleTwoJoint" kp="{f(PROXIMAL_SERVO[0])}" dampratio="1" '
                f'ctrlrange="{f(*PROXIMAL_RANGE)}" forcerange="{f(-PROXIMAL_SERVO[1], PROXIMAL_SERVO[1])}"/>'
            )
            w.add(
                f'<position name="{side}_HandFinger{name}KnuckleThreeServo" '
                f'joint="{side}_HandFinger{name}KnuckleThreeJoint" kp="{f(DISTAL_SERVO[0])}" dampratio="1" '
                f'ctrlrange="{f(*DISTAL_RANGE)}" forcerange="{f(-DISTAL_SERVO[1], DISTAL_SERVO[1])}"/>'
            )


def _sensors(w: Writer) -> None:
    """A 6-axis F/T sensor at each wrist (facts)."""
    w.open("<sensor>")
    for side in ("right", "left"):  # 6-axis F/T sensor at each wrist (facts)
        w.add(f'<force name="{side}_ft_force" site="{side}_ft_sensor"/>')
        w.add(f'<torque name="{side}_ft_torque" site="{side}_ft_sensor"/>')
    w.close("sensor")
