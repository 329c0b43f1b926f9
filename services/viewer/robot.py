"""The robot and the scene in Rerun: what ag_ex logs from its state snapshots and its
observations.

Entities (timelines ``wall``, POSIX s, shared with the traffic, and ``sim_time``, s):

- ``world`` — view coordinates, z up (static); ``world/table``, ``world/cabinet`` — boxes
  (static, sizes and placement from velma/model/kitchen_mjcf.py);
- ``world/objects/<name>`` — ``Transform3D`` of jar, bowl and cup (object frame: bottom
  centre, z up), with a static cylinder ``world/objects/<name>/shape``; the poses come from
  ag_ex's L_SD observations, and while a hand holds an object from its grip frame (the
  object keeps the grip-relative pose it had at the last observation before the grasp: the
  snapshot has no object poses, so between observations this is an estimate);
- ``world/robot/grip/<side>`` — ``Transform3D`` and axes of each grip frame (actual, from the
  snapshot);
- ``world/robot/links/<body>`` — ``Transform3D`` of each of Velma's main links (the bodies of
  ``velma.executor.state.LINK_BODIES``: torso, head, the arms' 7 links, the palms), with its
  rough shape (static capsules, cylinders, spheres and boxes ``.../geom<i>`` in the body frame,
  from the MJCF's collision geoms: ``LINK_SHAPES``);
- ``world/robot/links/<side>_HandPalmLink/finger_{one,two,three}[/proximal][/distal]`` — the
  BarrettHand's finger links, nested as in the MJCF (fingers one and two: knuckle, proximal,
  distal; finger three: proximal, distal), each a ``Transform3D`` in its parent link's frame
  computed from the finger joint angles of the snapshot (``FINGER_LINKS``, the constants of
  velma/model/robot_mjcf.py), logged for a hand only when one of its angles moved by more than
  ``FINGER_EPS``, with a static shape ``.../shape``;
- ``world/robot/setpoint/<side>`` — ``Transform3D`` and axes of the commanded grip frame while
  that arm is in Cartesian impedance; cleared when it leaves it;
- ``robot/ft/<side>/{fx,fy,fz,tx,ty,tz}`` — the wrist F/T sensor's wrench (N, N·m, sensor
  frame) as scalars;
- ``robot/joints`` — all joint positions (rad) as one multi-series ``Scalars`` row;
- ``robot/timing/{compute,lateness}/{p50,p99,max}`` — the control loop's compute time per
  cycle and lateness (µs, percentiles over the monitor's window of the last 120 000 cycles,
  velma/executor/timing.py), ``robot/timing/overruns/{count,share_percent,max_consecutive}``
  — overrunning cycles since start, their share of all cycles (%) and the longest run of
  them: logged when the statistics attached to a snapshot change (ag_ex recomputes them
  about once a second, off the loop);
- ``robot/held`` — text when what a hand holds changes; ``robot/holding`` — text when the
  loop starts or stops holding position;
- ``scene/content/<name>`` — particles inside each container (from observations);
  ``scene/content/total``.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np
import rerun as rr

from services.viewer.recording import Recording
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_sd import Observation
from velma import frames as geometry
from velma.control.joints import SIDES
from velma.executor.state import FT_AXES, RobotSnapshot
from velma.executor.timing import TimingStats
from velma.model import kitchen_mjcf as kitchen
from velma.model import robot_mjcf as velma
from velma.rotations import quat_mul, rpy_to_quat

WALL = "wall"
SIM = "sim_time"
OBJECTS = "world/objects"
GRIP = "world/robot/grip"
LINKS = "world/robot/links"
SETPOINT = "world/robot/setpoint"
FT = "robot/ft"
JOINTS = "robot/joints"
TIMING = "robot/timing"
CONTENT = "scene/content"

# object name -> (radius, height) of the cylinder drawn for it, and its colour
OBJECT_SHAPES: dict[str, tuple[float, float, tuple[int, int, int]]] = {
    "jar": (kitchen.JAR_RADIUS, kitchen.JAR_HEIGHT, (120, 200, 230)),
    "bowl": (
        kitchen.BOWL_WALL_RADIUS + 2 * kitchen.BOWL_WALL_HALF[2] * np.sin(kitchen.BOWL_FLARE),
        0.061,
        (230, 230, 220),
    ),
    "cup": (kitchen.CUP_RADIUS, kitchen.CUP_HEIGHT, (200, 120, 90)),
}
NOMINAL_POSITIONS = {"jar": kitchen.JAR_POS, "bowl": kitchen.BOWL_POS, "cup": kitchen.CUP_POS}


Vec3 = tuple[float, float, float]


class LinkShape(NamedTuple):
    """A rough link shape in its body's frame (m): ``kind`` "capsule" or "cylinder" (``size``
    = radius, half-length, 0; axis along the body's z), "capsule_x" (the same along the
    body's x), "sphere" (radius, 0, 0) or "box" (half sizes); ``centre`` its centre."""

    kind: str
    size: Vec3
    centre: Vec3


# Copied from the collision geoms of velma.xml (velma/model/robot_mjcf.py), so that the viewer
# needs no MuJoCo model.
_ARM: dict[int, list[LinkShape]] = {
    **{k: [LinkShape("capsule", (0.06, 0.1, 0.0), (0.0, 0.0, 0.1))] for k in range(1, 5)},
    5: [LinkShape("capsule", (0.06, 0.095, 0.0), (0.0, 0.0, 0.095))],
    6: [
        LinkShape("sphere", (0.055, 0.0, 0.0), (0.0, 0.0, 0.0)),
        LinkShape("cylinder", (0.04, 0.04, 0.0), (0.0, 0.0, 0.04)),
    ],
    7: [LinkShape("cylinder", (0.045, 0.008, 0.0), (0.0, 0.0, -0.005))],
}
_PALM = [
    LinkShape("cylinder", (0.04, 0.02, 0.0), (0.0, 0.0, -0.02)),
    LinkShape("cylinder", (0.045, 0.03, 0.0), (0.0, 0.0, 0.03)),
    LinkShape("box", (0.04, 0.04, 0.006), (0.0, 0.0, 0.066)),
]
LINK_SHAPES: dict[str, list[LinkShape]] = {
    "torso_base": [LinkShape("cylinder", (0.3, 0.015, 0.0), (0.0, 0.0, 0.015))],
    "torso_link0": [
        LinkShape("cylinder", (0.11, 0.55, 0.0), (0.0, 0.0, 0.55)),
        LinkShape("box", (0.1, 0.14, 0.09), (-0.03, 0.0, 1.16)),
    ],
    "head_pan_link": [],
    "head_tilt_link": [
        LinkShape("box", (0.06, 0.12, 0.06), (0.02, 0.0, 0.06)),
        LinkShape("box", (0.015, 0.09, 0.02), (0.085, 0.0, 0.05)),
    ],
    **{f"{side}_arm_{k}_link": list(shapes) for side in ("right", "left") for k, shapes in _ARM.items()},
    **{f"{side}_HandPalmLink": list(_PALM) for side in ("right", "left")},
}
LINK_COLOUR = (235, 140, 40)
PALM_COLOUR = (90, 90, 100)


class FingerLink(NamedTuple):
    """A BarrettHand finger link as the viewer draws it: ``path`` its entity below the palm's,
    ``joint`` the joint that turns it (name after ``<side>_``), ``axis`` +1 or −1 (the joint
    turns it about its frame's +z or −z), ``position`` (m) and ``orientation`` (w, x, y, z)
    its frame in the parent link's at joint angle 0, ``shape`` in its own frame."""

    path: str
    joint: str
    axis: float
    position: Vec3
    orientation: tuple[float, float, float, float]
    shape: LinkShape


# From velma/model/robot_mjcf.py (hand, finger): the chain MuJoCo builds, checked against its
# body poses in tests/viewer/test_fingers.py
_KNUCKLE = LinkShape("box", (0.022, 0.012, 0.008), (0.03, 0.0, 0.004))
_PROXIMAL = LinkShape("capsule_x", (0.011, 0.025, 0.0), (0.037, 0.0, 0.0))  # 0.012–0.062 m
_DISTAL = LinkShape("capsule_x", (0.01, 0.0185, 0.0), (0.0265, 0.0, 0.0))  # 0.008–0.045 m
_DISTAL_ORIGIN = (
    (velma.DISTAL_IN_PROXIMAL_X, 0.0, 0.0),
    rpy_to_quat((0.0, 0.0, velma.DISTAL_BEND)),
)
FINGER_LINKS: tuple[FingerLink, ...] = (
    *(
        link
        for name, sign in (("One", 1.0), ("Two", -1.0))
        for link in (
            FingerLink(
                f"finger_{name.lower()}",
                f"HandFinger{name}KnuckleOneJoint",
                -sign,  # the spread joints turn the two fingers in opposite senses
                (sign * velma.SPREAD_ORIGIN_X, 0.0, velma.SPREAD_ORIGIN_Z),
                rpy_to_quat((0.0, 0.0, velma.SPREAD_YAW)),
                _KNUCKLE,
            ),
            FingerLink(
                f"finger_{name.lower()}/proximal",
                f"HandFinger{name}KnuckleTwoJoint",
                -1.0,
                velma.PROXIMAL_IN_KNUCKLE,
                rpy_to_quat(velma.PROXIMAL_RPY),
                _PROXIMAL,
            ),
            FingerLink(
                f"finger_{name.lower()}/proximal/distal",
                f"HandFinger{name}KnuckleThreeJoint",
                -1.0,
                *_DISTAL_ORIGIN,
                _DISTAL,
            ),
        )
    ),
    FingerLink(
        "finger_three",
        "HandFingerThreeKnuckleTwoJoint",
        -1.0,
        velma.F3_PROXIMAL_IN_PALM[0],
        rpy_to_quat(velma.F3_PROXIMAL_IN_PALM[1]),
        _PROXIMAL,
    ),
    FingerLink("finger_three/distal", "HandFingerThreeKnuckleThreeJoint", -1.0, *_DISTAL_ORIGIN, _DISTAL),
)
FINGER_EPS = 0.01  # rad: a hand's fingers are logged again when one angle moved by more


def finger_pose(link: FingerLink, angle: float) -> Pose:
    """``link``'s frame in its parent link's frame at joint angle ``angle`` (rad)."""
    h = 0.5 * angle * link.axis
    q = quat_mul(link.orientation, (math.cos(h), 0.0, 0.0, math.sin(h)))
    return Pose(position=link.position, orientation=(q[0], q[1], q[2], q[3]))


def relative(parent: Pose, child: Pose) -> Pose:
    """``child`` expressed in ``parent``'s frame (both given in the same frame; Pinocchio SE3)."""
    return geometry.compose(geometry.inverse(parent), child)


compose = geometry.compose  # the world pose of a pose given in the frame ``parent``


def transform(pose: Pose) -> rr.Transform3D:
    """A Rerun transform for ``pose`` (quaternion w, x, y, z → Rerun's x, y, z, w)."""
    w, x, y, z = pose.orientation
    return rr.Transform3D(translation=pose.position, quaternion=rr.Quaternion(xyzw=[x, y, z, w]))


def log_scene(stream: rr.RecordingStream) -> None:
    """The fixed scene (static): view coordinates, table, cabinet, object shapes."""
    stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    tx, ty, tz = kitchen.TABLE_POS
    top_z = kitchen.TABLE_TOP_HEIGHT - kitchen.TABLE_TOP_HALF_THICKNESS
    leg_half_h = (kitchen.TABLE_TOP_HEIGHT - 2 * kitchen.TABLE_TOP_HALF_THICKNESS) / 2
    leg_xy = kitchen.TABLE_HALF - 0.04
    centers = [(tx, ty, tz + top_z)]
    halves = [(kitchen.TABLE_HALF, kitchen.TABLE_HALF, kitchen.TABLE_TOP_HALF_THICKNESS)]
    for sx, sy in ((1, 1), (-1, 1), (1, -1), (-1, -1)):
        centers.append((tx + sx * leg_xy, ty + sy * leg_xy, tz + leg_half_h))
        halves.append((kitchen.TABLE_LEG_HALF, kitchen.TABLE_LEG_HALF, leg_half_h))
    stream.log(
        "world/table",
        rr.Boxes3D(centers=centers, half_sizes=halves, colors=[(150, 110, 70)], fill_mode="solid"),
        static=True,
    )
    cx, cy, cz = kitchen.CABINET_POS
    dx, dy = kitchen.CABINET_HALF
    zc = (kitchen.SHELF_HEIGHT + kitchen.CABINET_HEIGHT) / 2
    hc = (kitchen.CABINET_HEIGHT - kitchen.SHELF_HEIGHT) / 2
    parts = (
        ((0, 0, kitchen.SHELF_HEIGHT / 2), (dx, dy, kitchen.SHELF_HEIGHT / 2)),
        ((dx - kitchen.PANEL, 0, zc), (kitchen.PANEL, dy, hc)),
        ((0, dy - kitchen.PANEL, zc), (dx, kitchen.PANEL, hc)),
        ((0, -(dy - kitchen.PANEL), zc), (dx, kitchen.PANEL, hc)),
        ((0, 0, kitchen.CABINET_HEIGHT - kitchen.TOP_HALF), (dx, dy, kitchen.TOP_HALF)),
    )
    stream.log(
        "world/cabinet",
        rr.Boxes3D(
            centers=[(cx + a[0], cy + a[1], cz + a[2]) for a, _ in parts],
            half_sizes=[h for _, h in parts],
            colors=[(190, 190, 200)],
            fill_mode="solid",
        ),
        static=True,
    )
    for name, (radius, height, colour) in OBJECT_SHAPES.items():
        stream.log(
            f"{OBJECTS}/{name}/shape",
            rr.Cylinders3D(
                lengths=[height],
                radii=[radius],
                centers=[(0.0, 0.0, height / 2)],
                colors=[colour],
                labels=[name],
            ),
            static=True,
        )
    for side in ("left", "right"):
        stream.log(f"{GRIP}/{side}", rr.TransformAxes3D(0.1), static=True)
    log_link_shapes(stream)


def _shape(shape: LinkShape, colour: tuple[int, int, int]) -> rr.AsComponents:
    """The Rerun archetype of one ``LINK_SHAPES`` entry (body frame, m)."""
    (a, b, _), (x, y, z) = shape.size, shape.centre
    if shape.kind == "box":
        return rr.Boxes3D(centers=[shape.centre], half_sizes=[shape.size], colors=[colour], fill_mode="solid")
    if shape.kind == "capsule":  # Rerun's capsule starts at its translation and runs along +z
        return rr.Capsules3D(lengths=[2 * b], radii=[a], translations=[(x, y, z - b)], colors=[colour])
    if shape.kind == "capsule_x":  # … turned by +90° about y: +z onto +x
        s = math.sqrt(0.5)
        return rr.Capsules3D(
            lengths=[2 * b],
            radii=[a],
            translations=[(x - b, y, z)],
            quaternions=[rr.Quaternion(xyzw=[0.0, s, 0.0, s])],
            colors=[colour],
        )
    if shape.kind == "cylinder":
        return rr.Cylinders3D(
            lengths=[2 * b], radii=[a], centers=[shape.centre], colors=[colour], fill_mode="solid"
        )
    if shape.kind == "sphere":
        return rr.Ellipsoids3D(
            half_sizes=[(a, a, a)], centers=[shape.centre], colors=[colour], fill_mode="solid"
        )
    raise ValueError(f"unknown link shape {shape.kind!r}")


def log_link_shapes(stream: rr.RecordingStream) -> None:
    """The links' shapes (static), each in its body's frame ``world/robot/links/<body>``, and
    the fingers' below each palm."""
    for body, shapes in LINK_SHAPES.items():
        colour = PALM_COLOUR if body.endswith("HandPalmLink") else LINK_COLOUR
        for i, shape in enumerate(shapes):
            stream.log(f"{LINKS}/{body}/geom{i}", _shape(shape, colour), static=True)
    for side in SIDES:
        for link in FINGER_LINKS:
            path = f"{LINKS}/{side}_HandPalmLink/{link.path}/shape"
            stream.log(path, _shape(link.shape, PALM_COLOUR), static=True)


def _finger_angles(joints: dict[str, float], side: str) -> list[float] | None:
    """Hand ``side``'s finger angles, in :data:`FINGER_LINKS`' order (None: not all there)."""
    angles = [joints.get(f"{side}_{link.joint}") for link in FINGER_LINKS]
    if any(a is None for a in angles):
        return None
    return [float(a) for a in angles if a is not None]


class RobotLogger:
    """Logs ag_ex's robot snapshots and observations to one recording part; keeps the last
    observed object poses and the grip-relative poses of held objects."""

    def __init__(self, recording: Recording) -> None:
        self.stream = recording.stream
        self.objects: dict[str, Pose] = {n: Pose(position=p) for n, p in NOMINAL_POSITIONS.items()}
        self._in_hand: dict[str, tuple[str, Pose]] = {}  # side -> (object, pose in the grip frame)
        self._held: dict[str, str | None] = {}
        self._holding: str | None = None
        self._joint_names: tuple[str, ...] = ()
        self._grips: dict[str, Pose] = {}
        self._setpoints: set[str] = set()  # sides whose commanded frame is shown
        self._timing_cycles = -1  # ``cycles`` of the last timing logged
        self._fingers: dict[str, list[float]] = {}  # side -> finger angles last logged
        log_scene(self.stream)

    def _time(self, sim_time: float, wall: float | None) -> None:
        self.stream.set_time(WALL, timestamp=time.time() if wall is None else wall)
        self.stream.set_time(SIM, duration=sim_time)

    def snapshot(self, snap: RobotSnapshot, *, wall: float | None = None) -> None:
        """Log one robot state: grip frames, link poses, commanded grip frames, wrist F/T,
        joints, held objects (moved with their grips), changes of what is held and of the
        loop's holding, and the loop's timing when it changed."""
        self._time(snap.sim_time, wall)
        self._grips = dict(snap.grip)
        self._log_poses(snap)
        self._log_fingers(snap.joints)
        self._log_setpoints(snap.setpoint)
        self._log_ft(snap)
        self._log_joints(snap.joints)
        self._log_held(snap)
        self._move_held(snap)
        self._log_holding(snap.holding)
        if snap.timing is not None and snap.timing.cycles != self._timing_cycles:
            self._timing_cycles = snap.timing.cycles
            self.timing(snap.timing)

    def _log_poses(self, snap: RobotSnapshot) -> None:
        """The grip frames and link poses."""
        for side, pose in snap.grip.items():
            self.stream.log(f"{GRIP}/{side}", transform(pose))
        for body, pose in snap.links.items():
            self.stream.log(f"{LINKS}/{body}", transform(pose))

    def _log_ft(self, snap: RobotSnapshot) -> None:
        """Each wrist's force/torque, one series per axis."""
        for side, wrench in snap.ft.items():
            for axis, value in zip(FT_AXES, wrench, strict=True):
                self.stream.log(f"{FT}/{side}/{axis}", rr.Scalars(value))

    def _log_joints(self, joints: dict[str, float]) -> None:
        """The joint angles (their series' names, statically, when the joints changed)."""
        names = tuple(joints)
        if names != self._joint_names:
            self._joint_names = names
            self.stream.log(JOINTS, rr.SeriesLines(names=list(names)), static=True)
        self.stream.log(JOINTS, rr.Scalars(np.fromiter(joints.values(), dtype=float, count=len(names))))

    def _log_held(self, snap: RobotSnapshot) -> None:
        """A change of what a hand holds; a known object taken in hand moves with its grip."""
        for side, obj in snap.held_object.items():
            if obj == self._held.get(side):
                continue
            self.stream.log("robot/held", rr.TextLog(f"{side} hand: {obj or 'empty'}"))
            self._held[side] = obj
            self._in_hand.pop(side, None)
            if obj is not None and obj in self.objects and side in snap.grip:
                self._in_hand[side] = (obj, relative(snap.grip[side], self.objects[obj]))

    def _move_held(self, snap: RobotSnapshot) -> None:
        """The objects in hand, where their grips are now."""
        for side, (obj, rel) in self._in_hand.items():
            if side in snap.grip:
                self.objects[obj] = compose(snap.grip[side], rel)
                self.stream.log(f"{OBJECTS}/{obj}", transform(self.objects[obj]))

    def _log_holding(self, holding: str | None) -> None:
        """A change of the loop's holding (what it holds for, or serving again)."""
        if holding == self._holding:
            return
        self._holding = holding
        self.stream.log(
            "robot/holding",
            rr.TextLog(f"holding: {holding}" if holding else "serving", level="WARN"),
        )

    def timing(self, t: TimingStats) -> None:
        """Log the loop's deadline statistics as scalars (``robot/timing/…``, see module
        docstring) at the current times."""
        s = self.stream
        for name, value in (
            ("compute/p50", t.compute_p50_us),
            ("compute/p99", t.compute_p99_us),
            ("compute/max", t.compute_max_us),
            ("lateness/p50", t.lateness_p50_us),
            ("lateness/p99", t.lateness_p99_us),
            ("lateness/max", t.lateness_max_us),
            ("overruns/count", float(t.overruns)),
            ("overruns/share_percent", 100.0 * t.overrun_share),
            ("overruns/max_consecutive", float(t.max_consecutive_overruns)),
            *(
                (f"parts/{p.name}/{q}", value)
                for p in t.parts
                for q, value in (("p50", p.p50_us), ("p99", p.p99_us), ("max", p.max_us))
            ),
        ):
            s.log(f"{TIMING}/{name}", rr.Scalars(value))

    def _fingers_moved(self, side: str, now: list[float]) -> bool:
        """Whether a finger angle of hand ``side`` moved by more than ``FINGER_EPS`` since they
        were last logged (or they never were)."""
        last = self._fingers.get(side)
        return last is None or max(abs(a - b) for a, b in zip(now, last, strict=True)) > FINGER_EPS

    def _log_fingers(self, joints: dict[str, float]) -> None:
        """Each hand's finger links when one of its finger angles moved by more than
        ``FINGER_EPS`` since they were last logged (a snapshot without them: nothing)."""
        for side in SIDES:
            now = _finger_angles(joints, side)
            if now is None or not self._fingers_moved(side, now):
                continue
            self._fingers[side] = now
            for link, angle in zip(FINGER_LINKS, now, strict=True):
                self.stream.log(
                    f"{LINKS}/{side}_HandPalmLink/{link.path}", transform(finger_pose(link, angle))
                )

    def _log_setpoints(self, setpoints: dict[str, Pose | None]) -> None:
        """The commanded grip frames present in this snapshot; a frame that is no longer
        commanded (joint or safe mode) is cleared once."""
        s = self.stream
        for side, pose in setpoints.items():
            path = f"{SETPOINT}/{side}"
            if pose is not None:
                s.log(path, transform(pose), rr.TransformAxes3D(0.15))
                self._setpoints.add(side)
            elif side in self._setpoints:
                s.log(path, rr.Clear(recursive=False))
                self._setpoints.discard(side)

    def initial_objects(self) -> None:
        """Log the nominal object poses (before any observation), at simulation time 0."""
        self._time(0.0, None)
        for name, pose in self.objects.items():
            self.stream.log(f"{OBJECTS}/{name}", transform(pose))

    def observation(self, obs: Observation, *, wall: float | None = None) -> None:
        """Log the observed object poses and container contents. A held object's grip-relative
        pose is re-anchored to the observation."""
        s = self.stream
        self._time(obs.stamp, wall)
        in_hand = {obj: side for side, (obj, _) in self._in_hand.items()}
        for o in obs.objects:
            self.objects[o.name] = o.pose
            s.log(f"{OBJECTS}/{o.name}", transform(o.pose))
            if o.particles_inside is not None:
                s.log(f"{CONTENT}/{o.name}", rr.Scalars(float(o.particles_inside)))
            side = in_hand.get(o.name)
            grip = self._grips.get(side) if side is not None else None
            if side is not None and grip is not None:
                self._in_hand[side] = (o.name, relative(grip, o.pose))
        s.log(f"{CONTENT}/total", rr.Scalars(float(obs.total_particles)))
