"""Writes ``velma.xml``, the MJCF model of the Velma robot, from the facts in velma-facts.md.

Run ``python -m velma.model.generate`` after changing a number here; ``velma.xml`` is the
output and is kept in the repository (a test checks that it is up to date). The generator
exists so that every number (offsets, rpy → quaternions, inertias) is computed once, from the
facts, rather than copied by hand into two arms and two hands.

Sources: velma-facts.md (kinematics, limits, masses, tool chain, hand geometry, contact
advice). Simplifications (named):

- Geometry is capsules, cylinders, boxes and spheres instead of meshes.
- LWR4+ link masses: the public URDF has placeholders (2 kg links 1–5, 0.2 kg link 6); here
  a plausible split of the real 16 kg arm is used (base 1.6, links 2.7/2.7/2.7/2.7/1.7/1.6/0.3
  kg), with the inertia of uniform cylinders. Placeholder, not identified data.
- Joint armature (reflected motor inertia) and arm joint damping are plausible values, not
  data: the facts give damping only for the torso (10 N·m·s/rad).
- The F/T sensor, gripper mount and BarrettHand are one rigid hand assembly of 1.53 kg whose
  centre of mass is near the facts' (0.152, 0.011, −0.069) m in the link-7 frame.
- The hand's breakaway clutch is not modelled: proximal and distal joints have their own
  force-limited position servos and the controller commands distal = proximal / 3.
- Robot self-collision is off (robot geoms only collide with the environment).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt

MODEL_DIR = Path(__file__).resolve().parent
VELMA_XML = MODEL_DIR / "velma.xml"

Vec = tuple[float, float, float]

# ----------------------------------------------------------------- facts (velma-facts.md)
TORSO_JOINT_Z = 0.03
TORSO_LIMIT = 1.57
TORSO_DAMPING = 10.0
HEAD_BASE = (0.0105, -0.001, 1.3117)
HEAD_PAN_Z = 0.087
HEAD_TILT_Z = 0.048
ARM_MOUNT = {
    "right": ((-0.0004, -0.000889, 1.17335), (-0.00045, -1.04747, 1.57047)),
    "left": ((-0.0006, -0.001311, 1.17335), (0.00087, 1.04750, 1.57243)),
}
# (z offset from the previous joint, axis, limit in degrees)
ARM_JOINTS: tuple[tuple[float, Vec, float], ...] = (
    (0.11, (0, 0, 1), 170.0),
    (0.2005, (0, 1, 0), 120.0),
    (0.20, (0, 0, 1), 170.0),
    (0.20, (0, -1, 0), 120.0),
    (0.20, (0, 0, 1), 170.0),
    (0.19, (0, 1, 0), 120.0),
    (0.078, (0, 0, 1), 170.0),
)
# Masses of arm_1_link … arm_7_link (placeholder split of the real 16 kg arm, see docstring).
ARM_LINK_MASS = (2.7, 2.7, 2.7, 2.7, 1.7, 1.6, 0.3)
ARM_BASE_MASS = 1.6
ARM_RADIUS = 0.06
ARM_ARMATURE = (0.2, 0.2, 0.1, 0.1, 0.05, 0.03, 0.03)  # kg·m², plausible reflected inertia
ARM_DAMPING = 0.5  # N·m·s/rad, plausible (not in the facts)
FT_IN_LINK7 = ((0.115, 0.0, -0.078), (0.0, math.pi / 2, 0.0))
PALM_IN_FT_Z = 0.005
GRIP_IN_PALM_Z = 0.12
HAND_MASS = 1.53  # total hand assembly load on the wrist
PALM_MASS = 0.6335
KNUCKLE_ONE_MASS = 0.1625
PROXIMAL_MASS = 0.058
DISTAL_MASS = 0.0342
FINGER_SPREAD_RANGE = (0.0, math.pi)
PROXIMAL_RANGE = (0.0, 2.4434)
DISTAL_RANGE = (0.0, 0.8377)
DISTAL_BEND = -0.690452252
FINGER_ARMATURE = 0.01  # kg·m², the hand's geared motors (plausible)
FINGER_DAMPING = 0.05

# Contacts of the hand pads (velma-facts.md "MuJoCo notes": elliptic cones, impratio 10
# are set in <option>; pads soft-but-stiff, friction ≈ 1).
PAD_FRICTION = "1.0 0.02 0.001"
PAD_SOLREF = "0.004 1"
PAD_SOLIMP = "0.95 0.99 0.001"


# ----------------------------------------------------------------- small math helpers
def rpy_to_quat(rpy: Vec) -> tuple[float, float, float, float]:
    """URDF roll-pitch-yaw (fixed axes X, Y, Z; R = Rz·Ry·Rx) → MuJoCo quaternion (w, x, y, z)."""
    r, p, y = rpy
    cr, sr = math.cos(r / 2), math.sin(r / 2)
    cp, sp = math.cos(p / 2), math.sin(p / 2)
    cy, sy = math.cos(y / 2), math.sin(y / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def quat_mul(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    """Hamilton product of two (w, x, y, z) quaternions."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_rotate(q: tuple[float, ...], v: Vec) -> Vec:
    """Rotate vector ``v`` by unit quaternion ``q`` (w, x, y, z)."""
    w, x, y, z = q
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    out: npt.NDArray[np.float64] = r @ np.asarray(v, dtype=float)
    return (float(out[0]), float(out[1]), float(out[2]))


def f(*values: float) -> str:
    """Format numbers for MJCF attributes (12 significant digits, no '-0')."""
    return " ".join(f"{v + 0.0:.12g}" for v in values)


def cylinder_inertia(mass: float, radius: float, length: float) -> Vec:
    """Principal inertia (Ixx, Iyy, Izz) of a uniform solid cylinder along z, kg·m²."""
    ixx = mass * (3 * radius**2 + length**2) / 12
    return (ixx, ixx, mass * radius**2 / 2)


def box_inertia(mass: float, half: Vec) -> Vec:
    """Principal inertia of a uniform box with half-sizes ``half`` (m), kg·m²."""
    a, b, c = (2 * h for h in half)
    return (mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12, mass * (a * a + b * b) / 12)


def inertial(pos: Vec, mass: float, diag: Vec) -> str:
    return f'<inertial pos="{f(*pos)}" mass="{f(mass)}" diaginertia="{f(*diag)}"/>'


# ----------------------------------------------------------------- model pieces
class Writer:
    """Accumulates indented XML lines."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.depth = 0

    def add(self, line: str) -> None:
        self.lines.append("  " * self.depth + line)

    def open(self, line: str) -> None:
        self.add(line)
        self.depth += 1

    def close(self, tag: str) -> None:
        self.depth -= 1
        self.add(f"</{tag}>")


def finger(w: Writer, side: str, finger_name: str) -> None:
    """Proximal (KnuckleTwo) and distal (KnuckleThree) links of one finger; the caller has
    opened the body that holds the proximal joint's origin."""
    prox_inertia = box_inertia(PROXIMAL_MASS, (0.035, 0.01, 0.012))
    dist_inertia = box_inertia(DISTAL_MASS, (0.025, 0.01, 0.01))
    w.add(inertial((0.035, 0.0, 0.0), PROXIMAL_MASS, prox_inertia))
    w.add(
        f'<joint name="{side}_HandFinger{finger_name}KnuckleTwoJoint" class="finger" '
        f'axis="0 0 -1" range="{f(*PROXIMAL_RANGE)}"/>'
    )
    w.add(f'<geom name="{side}_f{finger_name}_prox" class="pad" fromto="0.012 0 0 0.062 0 0" size="0.011"/>')
    w.open(
        f'<body name="{side}_HandFinger{finger_name}KnuckleThreeLink" pos="0.07 0 0" '
        f'quat="{f(*rpy_to_quat((0.0, 0.0, DISTAL_BEND)))}">'
    )
    w.add(inertial((0.025, 0.0, 0.0), DISTAL_MASS, dist_inertia))
    w.add(
        f'<joint name="{side}_HandFinger{finger_name}KnuckleThreeJoint" class="finger" '
        f'axis="0 0 -1" range="{f(*DISTAL_RANGE)}"/>'
    )
    w.add(f'<geom name="{side}_f{finger_name}_dist" class="pad" fromto="0.008 0 0 0.045 0 0" size="0.01"/>')
    w.close("body")


def hand(w: Writer, side: str) -> None:
    """F/T sensor site, palm, grip-frame site and the three fingers of a BarrettHand BH8-282,
    attached to ``{side}_arm_7_link`` (the caller has that body open)."""
    mount_yaw = 0.0 if side == "right" else math.pi  # gripper_mount (velma-facts.md)
    q_mount = rpy_to_quat((0.0, 0.0, mount_yaw))
    ft_pos = quat_rotate(q_mount, FT_IN_LINK7[0])
    q_ft = quat_mul(q_mount, rpy_to_quat(FT_IN_LINK7[1]))
    palm_pos = tuple(a + b for a, b in zip(ft_pos, quat_rotate(q_ft, (0.0, 0.0, PALM_IN_FT_Z)), strict=True))
    fingers_mass = 2 * KNUCKLE_ONE_MASS + 3 * (PROXIMAL_MASS + DISTAL_MASS)
    bracket_mass = HAND_MASS - PALM_MASS - fingers_mass
    # Bracket (gripper mount + F/T sensor): in link 7, between flange and palm.
    bx = 0.5 * ft_pos[0]
    w.add(
        f'<geom name="{side}_hand_bracket" class="robot" type="box" pos="{f(bx, 0, -0.078)}" '
        f'size="{f(abs(bx) + 0.03, 0.035, 0.03)}" rgba="0.3 0.3 0.32 1"/>'
    )
    w.open(f'<body name="{side}_HandPalmLink" pos="{f(*palm_pos)}" quat="{f(*q_ft)}">')
    # Palm + bracket mass lumped in the palm body: bracket mass sits ~0.06 m behind the palm.
    palm_com_z = (PALM_MASS * 0.035 + bracket_mass * (-0.02)) / (PALM_MASS + bracket_mass)
    w.add(
        inertial(
            (0.0, 0.011, palm_com_z),
            PALM_MASS + bracket_mass,
            cylinder_inertia(PALM_MASS + bracket_mass, 0.045, 0.09),
        )
    )
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
    spread_joints = (("One", 0.02497, "0 0 -1"), ("Two", -0.02497, "0 0 1"))
    for name, x, axis in spread_joints:
        w.open(
            f'<body name="{side}_HandFinger{name}KnuckleOneLink" pos="{f(x, 0, 0.0587966)}" '
            f'quat="{f(*rpy_to_quat((0.0, 0.0, math.pi / 2)))}">'
        )
        w.add(
            inertial(
                (0.025, 0.0, 0.008), KNUCKLE_ONE_MASS, box_inertia(KNUCKLE_ONE_MASS, (0.025, 0.012, 0.01))
            )
        )
        w.add(
            f'<joint name="{side}_HandFinger{name}KnuckleOneJoint" class="finger" axis="{axis}" '
            f'range="{f(*FINGER_SPREAD_RANGE)}"/>'
        )
        w.add(
            f'<geom name="{side}_f{name}_knuckle" class="robot" type="box" pos="0.03 0 0.004" '
            'size="0.022 0.012 0.008" rgba="0.2 0.2 0.2 1"/>'
        )
        w.open(
            f'<body name="{side}_HandFinger{name}KnuckleTwoLink" pos="0.05 0 0.0166034" '
            f'quat="{f(*rpy_to_quat((-math.pi / 2, 0.0, 0.0)))}">'
        )
        finger(w, side, name)
        w.close("body")
        w.close("body")
    w.open(
        f'<body name="{side}_HandFingerThreeKnuckleTwoLink" pos="0 -0.05 0.0754" '
        f'quat="{f(*rpy_to_quat((-math.pi / 2, 0.0, -math.pi / 2)))}">'
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
    for k, (dz, axis, limit) in enumerate(ARM_JOINTS):
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
            f'armature="{f(ARM_ARMATURE[k])}"/>'
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
    link's +x."""
    w.open(f'<body name="head_base" pos="{f(*HEAD_BASE)}">')
    w.add(inertial((0, 0, 0.04), 0.8, cylinder_inertia(0.8, 0.05, 0.08)))
    w.add('<geom class="robot" type="cylinder" pos="0 0 0.04" size="0.05 0.04" rgba="0.3 0.3 0.3 1"/>')
    w.open(f'<body name="head_pan_link" pos="0 0 {f(HEAD_PAN_Z)}">')
    w.add(inertial((0, 0, 0.02), 0.5, cylinder_inertia(0.5, 0.04, 0.04)))
    w.add('<joint name="head_pan_joint" class="head" axis="0 0 1" range="-1.57 1.57"/>')
    w.open(f'<body name="head_tilt_link" pos="0 0 {f(HEAD_TILT_Z)}">')
    w.add(inertial((0.02, 0, 0.06), 1.5, box_inertia(1.5, (0.06, 0.12, 0.06))))
    w.add('<joint name="head_tilt_joint" class="head" axis="0 1 0" range="-1.0 1.3"/>')
    w.add('<geom class="robot" type="box" pos="0.02 0 0.06" size="0.06 0.12 0.06" rgba="0.8 0.8 0.8 1"/>')
    w.add('<geom class="robot" type="box" pos="0.085 0 0.05" size="0.015 0.09 0.02" rgba="0.1 0.1 0.1 1"/>')
    w.add('<camera name="head_camera" pos="0.1 0 0.06" xyaxes="0 -1 0 0 0 1" fovy="58"/>')
    w.add('<site name="head_camera_site" pos="0.1 0 0.06" size="0.01"/>')
    for _ in range(3):
        w.close("body")


def build() -> str:
    """The full velma.xml text."""
    w = Writer()
    w.add(
        "<!-- GENERATED by velma/model/generate.py from velma-facts.md: edit the generator, "
        "not this file. -->"
    )
    w.open('<mujoco model="velma">')
    w.add('<compiler angle="radian" autolimits="true"/>')
    w.add(
        '<option timestep="0.001" integrator="implicitfast" cone="elliptic" impratio="10" '
        'solver="CG" iterations="60" tolerance="1e-8"/>'
    )
    w.open("<default>")
    w.open('<default class="velma">')
    w.add('<geom contype="2" conaffinity="1" condim="3" friction="0.8 0.02 0.001"/>')
    w.open('<default class="robot">')
    w.add('<geom contype="2" conaffinity="1"/>')
    w.close("default")
    w.open('<default class="pad">')
    w.add(
        f'<geom type="capsule" contype="2" conaffinity="1" condim="4" friction="{PAD_FRICTION}" '
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
    w.add('<joint type="hinge" damping="0.5" armature="0.01" limited="true"/>')
    w.close("default")
    w.close("default")
    w.close("default")
    w.open("<worldbody>")
    w.open('<body name="torso_base" childclass="velma">')
    w.add(inertial((0, 0, 0.25), 30.0, cylinder_inertia(30.0, 0.25, 0.5)))
    w.add('<geom class="robot" type="cylinder" pos="0 0 0.015" size="0.3 0.015" rgba="0.25 0.25 0.25 1"/>')
    w.open(f'<body name="torso_link0" pos="0 0 {f(TORSO_JOINT_Z)}">')
    w.add(inertial((0, 0, 0.7), 30.0, box_inertia(30.0, (0.12, 0.18, 0.6))))
    w.add(
        f'<joint name="torso_0_joint" type="hinge" axis="0 0 1" range="{f(-TORSO_LIMIT, TORSO_LIMIT)}" '
        f'damping="{f(TORSO_DAMPING)}" armature="0.5"/>'
    )
    w.add('<geom class="robot" type="cylinder" pos="0 0 0.55" size="0.11 0.55" rgba="0.6 0.6 0.62 1"/>')
    w.add('<geom class="robot" type="box" pos="-0.03 0 1.16" size="0.1 0.14 0.09" rgba="0.6 0.6 0.62 1"/>')
    head(w)
    arm(w, "right")
    arm(w, "left")
    w.close("body")
    w.close("body")
    w.close("worldbody")
    w.open("<actuator>")
    for side in ("right", "left"):
        for k in range(7):
            lim = 100.0 if k < 5 else 60.0
            w.add(
                f'<motor name="{side}_arm_{k}_motor" joint="{side}_arm_{k}_joint" '
                f'ctrlrange="{f(-lim, lim)}"/>'
            )
    w.add('<motor name="torso_0_motor" joint="torso_0_joint" ctrlrange="-300 300"/>')
    w.add(
        '<position name="head_pan_servo" joint="head_pan_joint" kp="40" dampratio="1" ctrlrange="-1.57 1.57" '
        'forcerange="-10 10"/>'
    )
    w.add(
        '<position name="head_tilt_servo" joint="head_tilt_joint" kp="60" dampratio="1" ctrlrange="-1.0 1.3" '
        'forcerange="-15 15"/>'
    )
    for side in ("right", "left"):
        for name in ("One", "Two"):
            w.add(
                f'<position name="{side}_HandFinger{name}KnuckleOneServo" '
                f'joint="{side}_HandFinger{name}KnuckleOneJoint" kp="10" dampratio="1" '
                f'ctrlrange="{f(*FINGER_SPREAD_RANGE)}" forcerange="-2 2"/>'
            )
        for name in ("One", "Two", "Three"):
            w.add(
                f'<position name="{side}_HandFinger{name}KnuckleTwoServo" '
                f'joint="{side}_HandFinger{name}KnuckleTwoJoint" kp="20" dampratio="1" '
                f'ctrlrange="{f(*PROXIMAL_RANGE)}" forcerange="-1.5 1.5"/>'
            )
            w.add(
                f'<position name="{side}_HandFinger{name}KnuckleThreeServo" '
                f'joint="{side}_HandFinger{name}KnuckleThreeJoint" kp="10" dampratio="1" '
                f'ctrlrange="{f(*DISTAL_RANGE)}" forcerange="-0.6 0.6"/>'
            )
    w.close("actuator")
    w.open("<sensor>")
    for side in ("right", "left"):
        w.add(f'<force name="{side}_ft_force" site="{side}_ft_sensor"/>')
        w.add(f'<torque name="{side}_ft_torque" site="{side}_ft_sensor"/>')
    w.close("sensor")
    w.close("mujoco")
    return "\n".join(w.lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write velma.xml (or ``--check``: exit 1 when it differs from the generator's output)."""
    args = sys.argv[1:] if argv is None else argv
    text = build()
    if "--check" in args:
        return 0 if VELMA_XML.read_text() == text else 1
    VELMA_XML.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
