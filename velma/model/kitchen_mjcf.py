"""The MJCF writer of ``kitchen.xml``, the scene of the pouring experiment (paper §5.3): an
open cabinet holding a jar, a bowl and a cup, and a table, around Velma (velma.xml, included),
from the numbers in this file (``build_kitchen``); velma/model/generate.py writes it. Sources as
in velma/model/robot_mjcf.py: *everyday size* (a common household item's size or mass),
*derived* (the formula is next to it), *placeholder* (a plausible choice, the reason given).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from velma.model.mjcf import (
    OPTION,
    SCENE_CONAFFINITY,
    SCENE_CONTYPE,
    Vec,
    Writer,
    box_inertia,
    cylinder_inertia,
    f,
)
from velma.rotations import quat_matrix, rpy_to_quat

# World frame: z up, origin on the floor under Velma's torso, x forward (towards the cabinet
# at torso angle 0). Object frames are at the object's bottom centre, z up.
#
# Cabinet (the "shelf"): a kitchen base cabinet whose worktop is the shelf the jar and bowl
# stand on, 0.85 m high (everyday size: kitchen worktops are 0.85–0.95 m high, the standard
# base cabinet is 0.85 m), with an open compartment above (0.46 m clear height, 0.86 m wide
# and 0.38 m deep inside: a wall-cabinet-sized opening, everyday size), 1.35 m high in all.
# Fixed to the world: a cabinet is ≥ 30 kg and fixed to the wall.
CABINET_POS = (0.82, 0.0, 0.0)  # m, placeholder placement in front of Velma (paper §5.3 scene)
CABINET_HALF = (0.2, 0.45)  # m, half depth, half width (outer)
SHELF_HEIGHT = 0.85  # m, top of the base (everyday size)
CABINET_HEIGHT = 1.35  # m, top of the top board (everyday size)
PANEL = 0.01  # m, half thickness of the side/back panels (a 20 mm board)
TOP_HALF = 0.02  # m, half thickness of the top board
# Table to the robot's right: a small kitchen table, top at 0.75 m (everyday size: tables are
# 0.72–0.76 m high), 0.6 × 0.6 m, 40 mm top, 50 mm legs. Fixed to the world (placeholder: a
# table is ≥ 15 kg and is only touched lightly when the bowl is put down).
TABLE_POS = (0.3, -0.65, 0.0)  # m, placeholder placement (paper §5.3 scene)
TABLE_TOP_HEIGHT = 0.75  # m
TABLE_HALF = 0.3  # m
TABLE_TOP_HALF_THICKNESS = 0.02  # m
TABLE_LEG_HALF = 0.025  # m
# Jar: an open glass jar of ≈ 0.6 l: outer ø 0.09 m, 0.12 m high, 0.25 kg (everyday size:
# 0.5–0.7 l glass jars weigh 0.2–0.3 kg). Walls are 4 mm thick (a real jar's 2.5–3 mm, made
# thicker for robust contacts), bottom 6 mm; 16 wall boxes around a disc.
JAR_POS = (0.70, 0.2, 0.85)  # m, on the shelf (placeholder placement)
JAR_RADIUS = 0.045  # m, outer
JAR_HEIGHT = 0.12  # m
JAR_WALL = 0.004  # m
JAR_BOTTOM = 0.006  # m
JAR_MASS = 0.25  # kg
JAR_WALLS = 16
JAR_WALL_HALF_WIDTH = 0.0092  # m: 0.043·tan(π/16) = 0.0086 m closes the polygon; boxes overlap a little
# Bowl: a small ceramic bowl: ø 0.13 m at the rim, 0.061 m high, walls flared 12°, 0.2 kg
# (everyday size: a 0.4 l cereal/dessert bowl weighs 0.2–0.3 kg). 20 wall boxes on a disc.
BOWL_POS = (0.70, -0.2, 0.85)  # m, on the shelf (placeholder placement)
BOWL_MASS = 0.2  # kg
BOWL_BOTTOM_RADIUS = 0.05  # m
BOWL_BOTTOM = 0.006  # m, thickness
BOWL_WALL_RADIUS = 0.0565  # m, radius of the wall boxes' centres
BOWL_WALL_HALF = (0.0025, 0.0101, 0.0305)  # m, 5 mm thick walls
BOWL_FLARE = 0.21  # rad, ≈ 12°
BOWL_WALLS = 20
BOWL_INNER_RADIUS = 0.055  # m, the counting volume's radius (inside the flared walls at mid height)
BOWL_INNER_TOP = 0.06  # m, top of the counting volume (≈ the rim)
# Cup: an open ceramic cup (no handle): outer ø 0.08 m, 0.10 m high, 0.2 kg (everyday size: a
# 0.3 l ceramic cup or small mug without its handle weighs 0.2–0.3 kg). Walls 5 mm, bottom
# 6 mm; 16 wall boxes around a disc, like the jar. It stands midway between jar and bowl, in
# line with them (placeholder placement: the right hand reaches it with the bowl's top grasp;
# the open fingers of the jar's and the bowl's grasps pass it ≥ 2 cm away, ≥ 1.5 cm with the
# ±2 cm pose randomisation of velma/model/scene.py).
CUP_POS = (0.70, 0.0, 0.85)  # m, on the shelf
CUP_RADIUS = 0.04  # m, outer
CUP_HEIGHT = 0.10  # m
CUP_WALL = 0.005  # m
CUP_BOTTOM = 0.006  # m
CUP_MASS = 0.2  # kg
CUP_WALLS = 16
CUP_WALL_HALF_WIDTH = 0.008  # m: 0.0375·tan(π/16) = 0.0075 m closes the polygon; boxes overlap a little
CONTAINER_FRICTION = "0.9 0.02 0.001"  # glass/glazed ceramic against rubber pads (placeholder)
ENV_FRICTION = "0.8 0.02 0.001"  # placeholder


def _box_tensor(mass: float, half: Vec, rot: npt.NDArray[np.float64], pos: Vec) -> npt.NDArray[np.float64]:
    """Inertia tensor (3, 3) about the origin of a uniform box (mass kg, half-sizes m)
    rotated by ``rot`` and centred at ``pos``."""
    local = np.diag(box_inertia(mass, half))
    p = np.asarray(pos, dtype=float)
    out: npt.NDArray[np.float64] = rot @ local @ rot.T + mass * (p @ p * np.eye(3) - np.outer(p, p))
    return out


def _cylinder_tensor(mass: float, radius: float, half_height: float, z: float) -> npt.NDArray[np.float64]:
    """Inertia tensor (3, 3) about the origin of a uniform disc on the z axis at height z."""
    p = np.array([0.0, 0.0, z])
    local = np.diag(cylinder_inertia(mass, radius, 2 * half_height))
    out: npt.NDArray[np.float64] = local + mass * (p @ p * np.eye(3) - np.outer(p, p))
    return out


def ring_inertial(
    total_mass: float,
    bottom: tuple[float, float],
    walls: int,
    wall_pos: Vec,
    wall_half: Vec,
    wall_pitch: float,
) -> tuple[Vec, Vec]:
    """Centre of mass (m) and principal inertia (kg·m², about the centre of mass) of a
    container made of a bottom disc (radius, thickness) and ``walls`` boxes at ``wall_pos``
    (half-sizes ``wall_half``, pitched by ``wall_pitch`` rad about y) repeated about z, with
    ``total_mass`` spread uniformly over the volume (derived from the collision geometry)."""
    v_bottom = math.pi * bottom[0] ** 2 * bottom[1]
    v_wall = 8 * wall_half[0] * wall_half[1] * wall_half[2]
    density = total_mass / (v_bottom + walls * v_wall)
    m_bottom, m_wall = density * v_bottom, density * v_wall
    tensor = _cylinder_tensor(m_bottom, bottom[0], bottom[1] / 2, bottom[1] / 2)
    moment = m_bottom * np.array([0.0, 0.0, bottom[1] / 2])
    pitch = quat_matrix(rpy_to_quat((0.0, wall_pitch, 0.0)))
    for i in range(walls):
        yaw = quat_matrix(rpy_to_quat((0.0, 0.0, 2 * math.pi * i / walls)))
        pos = yaw @ np.asarray(wall_pos, dtype=float)
        tensor += _box_tensor(m_wall, wall_half, yaw @ pitch, (float(pos[0]), float(pos[1]), float(pos[2])))
        moment += m_wall * pos
    com = moment / total_mass
    about_com = tensor - total_mass * (com @ com * np.eye(3) - np.outer(com, com))
    # symmetric about z: the tensor is diagonal (off-diagonal terms vanish to rounding)
    diag = np.diag(about_com)
    return (0.0, 0.0, float(com[2])), (float(diag[0]), float(diag[1]), float(diag[2]))


def jar_inertial() -> tuple[Vec, Vec]:
    """Centre of mass and principal inertia of the jar (derived, see ``ring_inertial``)."""
    wall_z = (JAR_HEIGHT + JAR_BOTTOM) / 2
    half = (JAR_WALL / 2, JAR_WALL_HALF_WIDTH, (JAR_HEIGHT - JAR_BOTTOM) / 2)
    return ring_inertial(
        JAR_MASS, (JAR_RADIUS, JAR_BOTTOM), JAR_WALLS, (JAR_RADIUS - JAR_WALL / 2, 0.0, wall_z), half, 0.0
    )


def cup_inertial() -> tuple[Vec, Vec]:
    """Centre of mass and principal inertia of the cup (derived, see ``ring_inertial``)."""
    wall_z = (CUP_HEIGHT + CUP_BOTTOM) / 2
    half = (CUP_WALL / 2, CUP_WALL_HALF_WIDTH, (CUP_HEIGHT - CUP_BOTTOM) / 2)
    return ring_inertial(
        CUP_MASS, (CUP_RADIUS, CUP_BOTTOM), CUP_WALLS, (CUP_RADIUS - CUP_WALL / 2, 0.0, wall_z), half, 0.0
    )


def bowl_inertial() -> tuple[Vec, Vec]:
    """Centre of mass and principal inertia of the bowl (derived, see ``ring_inertial``)."""
    return ring_inertial(
        BOWL_MASS,
        (BOWL_BOTTOM_RADIUS, BOWL_BOTTOM),
        BOWL_WALLS,
        (BOWL_WALL_RADIUS, 0.0, BOWL_WALL_HALF[2]),
        BOWL_WALL_HALF,
        BOWL_FLARE,
    )


def g(*values: float) -> str:
    """Format numbers for MJCF attributes (6 significant digits: derived inertias)."""
    return " ".join(f"{v + 0.0:.6g}" for v in values)


KITCHEN_HEADER = """<!--
  GENERATED by velma/model/generate.py: edit the generator, not this file.

  The kitchen of the pouring experiment (paper §5.3): Velma (velma.xml), an open cabinet
  holding a jar, a bowl and a cup, and a table. World frame: z up, origin on the floor under
  Velma's torso, x forward (towards the cabinet at torso angle 0).

  Object frames (jar, bowl, cup, table, cabinet) are the body frames, at the object's bottom
  centre, z up. The jar's content (free spheres jar_content_0..N-1) is added at load time by
  velma/model/scene.py (load_kitchen), which also reads the containers' inner volumes from
  the sites jar_inner / bowl_inner / cup_inner (cylinders: radius, half height). Sizes and
  masses, with their sources: velma/model/generate.py.

  Simplifications (named): containers are rings of boxes (polygonal walls) on a disc;
  the cabinet and table are fixed boxes; the content is rigid spheres (no granular cohesion).
-->"""


def build_kitchen() -> str:
    """The full kitchen.xml text."""
    w = Writer()
    for line in KITCHEN_HEADER.splitlines():
        w.lines.append(line)
    w.open('<mujoco model="kitchen">')
    w.add('<include file="velma.xml"/>')
    w.add(OPTION)
    w.add('<size memory="64M"/>')
    w.open("<visual>")
    w.add('<global offwidth="1280" offheight="960"/>')
    w.add('<quality shadowsize="2048"/>')
    w.close("visual")
    w.open("<asset>")
    w.add(
        '<texture name="floor_tex" type="2d" builtin="checker" rgb1="0.55 0.55 0.5" rgb2="0.45 0.45 0.42" '
        'width="256" height="256"/>'
    )
    w.add('<material name="floor_mat" texture="floor_tex" texrepeat="8 8" reflectance="0.05"/>')
    w.add('<material name="wood" rgba="0.62 0.45 0.3 1"/>')
    w.add('<material name="cabinet_mat" rgba="0.85 0.82 0.75 1"/>')
    w.add('<material name="glass" rgba="0.6 0.8 0.9 0.45"/>')
    w.add('<material name="ceramic" rgba="0.9 0.9 0.95 1"/>')
    w.close("asset")
    w.open("<default>")
    w.open('<default class="env">')
    w.add(
        f'<geom contype="{SCENE_CONTYPE}" conaffinity="{SCENE_CONAFFINITY}" condim="3" '
        f'friction="{ENV_FRICTION}"/>'
    )
    w.open('<default class="jar_wall">')
    w.add(f'<geom type="box" material="glass" friction="{CONTAINER_FRICTION}" solref="0.004 1"/>')
    w.close("default")
    w.open('<default class="bowl_wall">')
    w.add(f'<geom type="box" material="ceramic" friction="{CONTAINER_FRICTION}" solref="0.004 1"/>')
    w.close("default")
    w.open('<default class="cup_wall">')
    w.add(f'<geom type="box" material="ceramic" friction="{CONTAINER_FRICTION}" solref="0.004 1"/>')
    w.close("default")
    w.close("default")
    w.close("default")
    w.open("<worldbody>")
    w.add('<light name="sun" pos="0.5 -0.5 3" dir="-0.1 0.2 -1" directional="true" diffuse="0.7 0.7 0.7"/>')
    w.add('<light name="fill" pos="-1.5 0 2.5" dir="1 0 -0.8" diffuse="0.35 0.35 0.35"/>')
    w.add('<geom name="floor" class="env" type="plane" size="4 4 0.05" material="floor_mat"/>')
    for name, pos, axes in (
        ("overview", "-0.7 1.3 1.9", "-0.781 -0.625 0 0.288 -0.361 0.887"),
        ("cabinet_view", "0.1 1.0 1.5", "-0.857 -0.514 0 0.219 -0.366 0.904"),
        ("pour_view", "0.9 0.2 1.3", "-0.800 0.600 0 -0.268 -0.358 0.894"),
        ("cabinet_right", "0.15 -0.9 1.4", "0.824 -0.567 0 0.259 0.377 0.889"),
        ("side_view", "0.4 1.8 1.2", "-1 0 0 0 -0.110 0.994"),
    ):
        w.add(f'<camera name="{name}" pos="{pos}" xyaxes="{axes}"/>')  # viewpoints for rendering only

    # cabinet: open toward -x (toward the robot)
    dx, dy = CABINET_HALF
    zc = (SHELF_HEIGHT + CABINET_HEIGHT) / 2  # side and back panels: from the shelf to the top
    hc = (CABINET_HEIGHT - SHELF_HEIGHT) / 2
    w.add(
        "<!-- Cabinet, open toward -x (the robot): base up to the 0.85 m shelf, a compartment "
        "0.86 x 0.38 m inside, 0.46 m clear. -->"
    )
    w.open(f'<body name="cabinet" pos="{f(*CABINET_POS)}">')
    for part, at, size in (
        ("cabinet_base", (0, 0, SHELF_HEIGHT / 2), (dx, dy, SHELF_HEIGHT / 2)),
        ("cabinet_back", (dx - PANEL, 0, zc), (PANEL, dy, hc)),
        ("cabinet_left", (0, dy - PANEL, zc), (dx, PANEL, hc)),
        ("cabinet_right", (0, -(dy - PANEL), zc), (dx, PANEL, hc)),
        ("cabinet_top", (0, 0, CABINET_HEIGHT - TOP_HALF), (dx, dy, TOP_HALF)),
    ):
        w.add(
            f'<geom name="{part}" class="env" type="box" pos="{f(*at)}" size="{f(*size)}" '
            'material="cabinet_mat"/>'
        )
    w.close("body")

    # table
    top_z = TABLE_TOP_HEIGHT - TABLE_TOP_HALF_THICKNESS
    leg_half_h = (TABLE_TOP_HEIGHT - 2 * TABLE_TOP_HALF_THICKNESS) / 2
    leg_xy = TABLE_HALF - 0.04
    w.add("<!-- Table to the robot's right: top at 0.75 m, 0.6 x 0.6 m. -->")
    w.open(f'<body name="table" pos="{f(*TABLE_POS)}">')
    w.add(
        f'<geom name="table_top" class="env" type="box" pos="{f(0, 0, top_z)}" '
        f'size="{f(TABLE_HALF, TABLE_HALF, TABLE_TOP_HALF_THICKNESS)}" material="wood"/>'
    )
    for i, (sx, sy) in enumerate(((1, 1), (-1, 1), (1, -1), (-1, -1))):
        w.add(
            f'<geom name="table_leg{i}" class="env" type="box" '
            f'pos="{f(sx * leg_xy, sy * leg_xy, leg_half_h)}" '
            f'size="{f(TABLE_LEG_HALF, TABLE_LEG_HALF, leg_half_h)}" material="wood"/>'
        )
    w.close("body")

    # jar
    jar_com, jar_inertia = jar_inertial()
    wall_half_h = (JAR_HEIGHT - JAR_BOTTOM) / 2
    inner_r = JAR_RADIUS - JAR_WALL
    w.add("<!-- Jar: open glass jar, outer diameter 0.09 m, 0.12 m high, 0.25 kg. -->")
    w.open(f'<body name="jar" pos="{f(*JAR_POS)}">')
    w.add('<freejoint name="jar_free"/>')
    w.add(f'<inertial pos="{g(*jar_com)}" mass="{g(JAR_MASS)}" diaginertia="{g(*jar_inertia)}"/>')
    w.add(
        f'<geom name="jar_bottom" class="jar_wall" type="cylinder" pos="{f(0, 0, JAR_BOTTOM / 2)}" '
        f'size="{f(JAR_RADIUS, JAR_BOTTOM / 2)}"/>'
    )
    w.open(f'<replicate count="{JAR_WALLS}" euler="0 0 {f(2 * math.pi / JAR_WALLS)}">')
    w.add(
        f'<geom name="jar_wall" class="jar_wall" '
        f'pos="{f(JAR_RADIUS - JAR_WALL / 2, 0, JAR_BOTTOM + wall_half_h)}" '
        f'size="{f(JAR_WALL / 2, JAR_WALL_HALF_WIDTH, wall_half_h)}"/>'
    )
    w.close("replicate")
    w.add(
        f'<site name="jar_inner" type="cylinder" pos="{f(0, 0, JAR_BOTTOM + wall_half_h)}" '
        f'size="{f(inner_r, wall_half_h)}" rgba="0 0 1 0" group="5"/>'
    )
    w.close("body")

    # bowl
    bowl_com, bowl_inertia = bowl_inertial()
    w.add("<!-- Bowl: ceramic, 0.13 m across the rim, 0.06 m high, walls flared 12 degrees, 0.2 kg. -->")
    w.open(f'<body name="bowl" pos="{f(*BOWL_POS)}">')
    w.add('<freejoint name="bowl_free"/>')
    w.add(f'<inertial pos="{g(*bowl_com)}" mass="{g(BOWL_MASS)}" diaginertia="{g(*bowl_inertia)}"/>')
    w.add(
        f'<geom name="bowl_bottom" class="bowl_wall" type="cylinder" pos="{f(0, 0, BOWL_BOTTOM / 2)}" '
        f'size="{f(BOWL_BOTTOM_RADIUS, BOWL_BOTTOM / 2)}"/>'
    )
    w.open(f'<replicate count="{BOWL_WALLS}" euler="0 0 {f(2 * math.pi / BOWL_WALLS)}">')
    w.add(
        f'<geom name="bowl_wall" class="bowl_wall" pos="{f(BOWL_WALL_RADIUS, 0, BOWL_WALL_HALF[2])}" '
        f'euler="0 {f(BOWL_FLARE)} 0" size="{f(*BOWL_WALL_HALF)}"/>'
    )
    w.close("replicate")
    # inner volume: above the bottom, inside the rim (a sphere whose centre is here is "in the bowl")
    half = (BOWL_INNER_TOP - BOWL_BOTTOM) / 2
    w.add(
        f'<site name="bowl_inner" type="cylinder" pos="{f(0, 0, BOWL_BOTTOM + half)}" '
        f'size="{f(BOWL_INNER_RADIUS, half)}" rgba="0 0 1 0" group="5"/>'
    )
    w.close("body")

    # cup
    cup_com, cup_inertia = cup_inertial()
    cup_half_h = (CUP_HEIGHT - CUP_BOTTOM) / 2
    w.add("<!-- Cup: open ceramic cup, outer diameter 0.08 m, 0.10 m high, 0.2 kg. -->")
    w.open(f'<body name="cup" pos="{f(*CUP_POS)}">')
    w.add('<freejoint name="cup_free"/>')
    w.add(f'<inertial pos="{g(*cup_com)}" mass="{g(CUP_MASS)}" diaginertia="{g(*cup_inertia)}"/>')
    w.add(
        f'<geom name="cup_bottom" class="cup_wall" type="cylinder" pos="{f(0, 0, CUP_BOTTOM / 2)}" '
        f'size="{f(CUP_RADIUS, CUP_BOTTOM / 2)}"/>'
    )
    w.open(f'<replicate count="{CUP_WALLS}" euler="0 0 {f(2 * math.pi / CUP_WALLS)}">')
    w.add(
        f'<geom name="cup_wall" class="cup_wall" '
        f'pos="{f(CUP_RADIUS - CUP_WALL / 2, 0, CUP_BOTTOM + cup_half_h)}" '
        f'size="{f(CUP_WALL / 2, CUP_WALL_HALF_WIDTH, cup_half_h)}"/>'
    )
    w.close("replicate")
    w.add(
        f'<site name="cup_inner" type="cylinder" pos="{f(0, 0, CUP_BOTTOM + cup_half_h)}" '
        f'size="{f(CUP_RADIUS - CUP_WALL, cup_half_h)}" rgba="0 0 1 0" group="5"/>'
    )
    w.close("body")
    w.close("worldbody")
    w.close("mujoco")
    return "\n".join(w.lines) + "\n"
