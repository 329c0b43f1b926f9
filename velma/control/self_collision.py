"""Velma's self-collision check: the robot's own collision geometry, the pairs MuJoCo collides.

The geometry is velma.xml's (Pinocchio's ``buildGeomFromMJCF``; distances and collisions by
coal, Pinocchio's collision library), so the controller's check and the simulation's contacts
come from one description. The pairs are those MuJoCo collides (velma/model/robot_mjcf.py,
"Self-collision"): every two robot geoms except

- geoms on the same Pinocchio joint (one rigid body: MuJoCo's welded bodies) or on a joint and
  its parent joint (MuJoCo's parent–child filter);
- the pairs of ``SELF_COLLISION_EXCLUDES`` (overlap by construction);

and, for the check, not two geoms of the same hand: the fingers close onto the palm and onto
each other by design, and their motion is the hand's, not the arm's.

Used by the IK (velma/control/ik.py): a posture whose geoms come closer than ``MARGIN`` is
rejected; the search swivels the elbow to a free posture, else goes on from its other starts.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Generator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from velma.control.joints import SIDES, arm_joints
from velma.control.robot_model import RobotModel
from velma.model import VELMA_XML
from velma.model.robot_mjcf import SELF_COLLISION_EXCLUDES

MARGIN = 0.003
"""m: two geoms closer than this count as colliding (coal's security margin)."""
CHECK_STEPS = 8
"""Steps of :meth:`SelfCollision.colliding_steps`: the pairs of a side in this many consecutive
slices, so that one step costs about a damped-least-squares iteration of the IK (the
whole check, ≈ 64 µs warm and ≈ 270 µs in the loop's cycle, was one step of the search)."""


def _hand(frame: str) -> str | None:
    """The side whose hand a body frame belongs to, or None."""
    for side in SIDES:
        if frame.startswith(f"{side}_Hand"):
            return side
    return None


def _side(frame: str) -> str | None:
    """The side whose arm or hand a body frame belongs to, or None (torso, head)."""
    for side in SIDES:
        if frame.startswith(f"{side}_") and not frame.startswith(f"{side}_arm_base"):
            return side
    return None


class SelfCollision:
    """The robot's collision pairs (module docstring) with their coal data, per arm.

    ``colliding(data, side)`` checks the pairs with at least one geom on ``side``'s arm or hand
    (what an IK of that arm can change: a contact elsewhere does not block it); it needs
    ``data.oMi`` of the configuration to check (e.g. after ``pinocchio.forwardKinematics``) and
    returns the names of the first colliding pair's geoms or None. ≈ 64 µs warm on the 2-core
    development machine when no pair collides (659 pairs per side, stopping at the first
    collision). ``colliding_steps`` is the same check in ``CHECK_STEPS`` slices of the pairs."""

    def __init__(self, robot: RobotModel, path: Path = VELMA_XML, margin: float = MARGIN) -> None:
        model = robot.model
        self.model = model
        base = pin.buildGeomFromMJCF(model, str(path), pin.COLLISION)
        excluded = {frozenset(pair) for pair in SELF_COLLISION_EXCLUDES}
        objects = base.geometryObjects
        pairs: dict[str, list[tuple[int, int]]] = {side: [] for side in SIDES}
        for i in range(len(objects)):
            for j in range(i + 1, len(objects)):
                a, b = objects[i], objects[j]
                ja, jb = a.parentJoint, b.parentJoint
                if ja == jb or model.parents[ja] == jb or model.parents[jb] == ja:
                    continue
                fa, fb = model.frames[a.parentFrame].name, model.frames[b.parentFrame].name
                if frozenset((fa, fb)) in excluded:
                    continue
                hand = _hand(fa)
                if hand is not None and hand == _hand(fb):
                    continue
                for side in {_side(fa), _side(fb)} - {None}:
                    pairs[str(side)].append((i, j))
        self.geometry = {side: _with_pairs(objects, pairs[side]) for side in SIDES}
        """Per side, the geometry with every pair of the side (no data: the check runs on
        ``slices``)."""
        self.slices: dict[str, list[tuple[pin.GeometryModel, pin.GeometryData]]] = {}
        """Per side, ``CHECK_STEPS`` geometries with consecutive parts of its pairs, each with
        its own data. A GeometryData holds ≈ 5 kB per pair of its model, so the pairs are
        split among models, not deactivated in copies of the whole (≈ 6 MiB
        instead of ≈ 65 MiB in the loop's process)."""
        for side in SIDES:
            n = len(pairs[side])
            bounds = [n * k // CHECK_STEPS for k in range(CHECK_STEPS + 1)]
            self.slices[side] = []
            for lo, hi in itertools.pairwise(bounds):
                part = _with_pairs(objects, pairs[side][lo:hi])
                gdata = pin.GeometryData(part)
                for request in gdata.collisionRequests:
                    request.security_margin = margin
                self.slices[side].append((part, gdata))

    def pairs(self, side: str) -> int:
        """How many geom pairs are checked for ``side``."""
        return len(self.geometry[side].collisionPairs)

    def colliding(
        self, data: pin.Data, side: str, q_arm: npt.NDArray[np.float64] | None = None
    ) -> tuple[str, str] | None:
        """The first pair with a geom of ``side`` closer than the margin at ``data``'s
        placements, or None. With the arm's configuration ``q_arm`` (7,) rad, a wrist inside
        its band (``WRIST_BAND``) counts too, as the pair (palm, forearm). Raises ``KeyError``
        for an unknown side."""
        if q_arm is not None:
            d, _, _ = wrist_field().sample(SIDES.index(side), float(q_arm[5]), float(q_arm[6]))
            if d < WRIST_BAND:
                return f"{side}_HandPalmLink", f"{side}_arm_5_link"
        for part, gdata in self.slices[side]:
            hit = self._first(part, gdata, data)
            if hit is not None:
                return hit
        return None

    def colliding_steps(
        self, data: pin.Data, side: str, q_arm: npt.NDArray[np.float64] | None = None
    ) -> Generator[None, None, tuple[str, str] | None]:
        """:meth:`colliding` as a generator that yields between its ``CHECK_STEPS`` slices of
        the pairs (for the IK's resumable search); its return value is ``colliding``'s answer,
        the same pair. ``data`` must keep its placements while the generator runs."""
        if q_arm is not None:
            d, _, _ = wrist_field().sample(SIDES.index(side), float(q_arm[5]), float(q_arm[6]))
            if d < WRIST_BAND:
                return f"{side}_HandPalmLink", f"{side}_arm_5_link"
        parts = self.slices[side]
        for k, (part, gdata) in enumerate(parts):
            hit = self._first(part, gdata, data)
            if hit is not None:
                return hit
            if k + 1 < len(parts):
                yield None
        return None

    def _first(
        self, geometry: pin.GeometryModel, gdata: pin.GeometryData, data: pin.Data
    ) -> tuple[str, str] | None:
        """The first active pair of ``gdata`` closer than the margin at ``data``'s placements."""
        pin.updateGeometryPlacements(self.model, data, geometry, gdata)
        if not pin.computeCollisions(geometry, gdata, True):
            return None
        objects = geometry.geometryObjects
        for k, result in enumerate(gdata.collisionResults):
            if result.isCollision() and gdata.activeCollisionPairs[k]:
                pair = geometry.collisionPairs[k]
                return objects[pair.first].name, objects[pair.second].name
        return None  # pragma: no cover - computeCollisions said there was one


def _with_pairs(objects: list[pin.GeometryObject], pairs: list[tuple[int, int]]) -> pin.GeometryModel:
    """A geometry with ``objects`` (their shapes shared, not copied) and the collision
    ``pairs`` (indices into ``objects``), in that order."""
    geometry = pin.GeometryModel()
    for obj in objects:
        geometry.addGeometryObject(obj)
    for i, j in pairs:
        geometry.addCollisionPair(pin.CollisionPair(i, j))
    return geometry


# ------------------------------------------------------------------ the wrist's own band
WRIST_BAND = 0.015
"""m: the hand's rigid parts (palm, F/T housing, pad) and its own forearm (link 5) are pushed
apart once closer than this (the F/T housing is 20 mm from the forearm with a straight wrist).
The IK takes no posture inside the band, so the band acts only on the way to a posture."""
WRIST_BAND_TORQUE = 20.0
"""N·m at contact, on the wrist joints 5 and 6 (as the joint-limit band's peak, limits.py)."""
WRIST_BAND_DAMPING = 2.0
"""N·m·s/rad at contact, on the wrist's approach velocity (chosen for this simulation)."""
WRIST_GRID_STEP = 0.05
"""rad, the distance table's step in joints 5 and 6."""


@dataclass(frozen=True)
class WristField:
    """The distance (m, negative when overlapping) between each hand's rigid parts and its own
    forearm as a table over arm joints 5 and 6 (the only joints between the two), per side:
    ``distance[k, i, j]`` at q5 = ``lower[0]`` + i·``step``, q6 = ``lower[1]`` + j·``step``
    (k: the index in ``SIDES``). Read by bilinear interpolation (``sample``)."""

    lower: tuple[float, float]
    step: float
    distance: npt.NDArray[np.float64]

    def sample(self, k: int, q5: float, q6: float) -> tuple[float, float, float]:
        """(d, ∂d/∂q5, ∂d/∂q6) of side ``k`` at (q5, q6) rad, from the bilinear interpolant
        (clamped to the table); m and m/rad."""
        table = self.distance[k]
        n5, n6 = table.shape
        x = min(max((q5 - self.lower[0]) / self.step, 0.0), n5 - 1.000001)
        y = min(max((q6 - self.lower[1]) / self.step, 0.0), n6 - 1.000001)
        i, j = int(x), int(y)
        f, g = x - i, y - j
        d00, d10, d01, d11 = table[i, j], table[i + 1, j], table[i, j + 1], table[i + 1, j + 1]
        d = (1.0 - f) * (1.0 - g) * d00 + f * (1.0 - g) * d10 + (1.0 - f) * g * d01 + f * g * d11
        grad5 = ((1.0 - g) * (d10 - d00) + g * (d11 - d01)) / self.step
        grad6 = ((1.0 - f) * (d01 - d00) + f * (d11 - d10)) / self.step
        return float(d), float(grad5), float(grad6)


def wrist_band_torque(
    field: WristField, k: int, q: npt.NDArray[np.float64], v: npt.NDArray[np.float64]
) -> tuple[float, float] | None:
    """The wrist band's torques (N·m) on joints 5 and 6 of side ``k`` at the arm's ``q``,
    ``v`` (7,), or None outside the band: along the distance's gradient in (q5, q6),
    ``WRIST_BAND_TORQUE`` s² with s = (d₀ − d)/d₀, less ``WRIST_BAND_DAMPING`` s times the
    approach velocity along it."""
    d, g5, g6 = field.sample(k, float(q[5]), float(q[6]))
    if d >= WRIST_BAND:
        return None
    norm = math.hypot(g5, g6)
    if norm < 1e-9:
        return None
    n5, n6 = g5 / norm, g6 / norm
    s = (WRIST_BAND - d) / WRIST_BAND
    rate = n5 * float(v[5]) + n6 * float(v[6])
    magnitude = WRIST_BAND_TORQUE * s * s - (WRIST_BAND_DAMPING * s * rate if rate < 0.0 else 0.0)
    return magnitude * n5, magnitude * n6


@functools.lru_cache(maxsize=4)
def wrist_field(path: Path = VELMA_XML) -> WristField:
    """The ``WristField`` of velma.xml at ``path`` (computed once per process: ≈ 1 s, with
    coal's distances between the forearm's capsule and the palm's geoms)."""
    robot = RobotModel(path)
    model = robot.model
    data = model.createData()
    geometry = pin.buildGeomFromMJCF(model, str(path), pin.COLLISION)
    objects = geometry.geometryObjects
    lo5 = float(model.lowerPositionLimit[robot.v_index(arm_joints(SIDES[0])[5])])
    lo6 = float(model.lowerPositionLimit[robot.v_index(arm_joints(SIDES[0])[6])])
    n5 = round(-2.0 * lo5 / WRIST_GRID_STEP) + 1
    n6 = round(-2.0 * lo6 / WRIST_GRID_STEP) + 1
    table = np.empty((len(SIDES), n5, n6))
    for k, side in enumerate(SIDES):
        frames = [model.frames[g.parentFrame].name for g in objects]
        forearm = [i for i, name in enumerate(frames) if name == f"{side}_arm_5_link"]
        hand = [i for i, name in enumerate(frames) if name == f"{side}_HandPalmLink"]
        first = len(geometry.collisionPairs)
        for a in forearm:
            for b in hand:
                geometry.addCollisionPair(pin.CollisionPair(a, b))
        pairs = range(first, len(geometry.collisionPairs))
        gdata = pin.GeometryData(geometry)
        joints = [robot.v_index(j) for j in arm_joints(side)[5:]]
        q = pin.neutral(model)
        for i in range(n5):
            for j in range(n6):
                q[joints[0]] = lo5 + i * WRIST_GRID_STEP
                q[joints[1]] = lo6 + j * WRIST_GRID_STEP
                pin.forwardKinematics(model, data, q)
                pin.updateGeometryPlacements(model, data, geometry, gdata)
                table[k, i, j] = min(pin.computeDistance(geometry, gdata, p).min_distance for p in pairs)
    return WristField(lower=(lo5, lo6), step=WRIST_GRID_STEP, distance=table)
