"""The known objects' models: shape, size and appearance, read from the kitchen model's geoms.

A real system has a CAD model and the colour of each object it handles. Here the geometry is
stated once, in kitchen.xml (written from velma/model/kitchen_mjcf.py), so the model of object
``name`` is taken from the geoms of the body ``name`` in their body frame (``geom_pos``,
``geom_quat``, ``geom_size``: the object frame is the body frame, at the bottom centre, z up)
and its colour from their material (``mat_rgba``) or ``geom_rgba``. Nothing here reads where
the body is (``xpos``, ``body_pos`` or any state): that is for perception to find.

The surface is sampled on a grid of ``spacing`` (m) over every face of every box and cylinder
geom; samples inside another geom of the same body (the overlapping wall boxes, the disc's rim
under the walls) are dropped, so the model holds only surface that can be seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt
import small_gicp

from velma.perception.cloud import Array

MODEL_SPACING = 0.0015  # m, grid of the surface samples
INSIDE_MARGIN = 3e-4  # m, a sample this far inside another geom is dropped
SYMMETRY_TEST_ANGLES = (0.37, 1.1, 2.3, 3.9, 5.2)  # rad, turns for the symmetry test (none a 2π/n, n ≤ 20)


@dataclass(frozen=True)
class ObjectModel:
    """Object ``name``: surface samples ``points`` (N × 3, m, object frame), ``rgba`` (4,)
    its colour (alpha < 1: transparent), ``radius`` (m, largest horizontal distance from the
    z axis), ``height`` (m, top above the frame origin) and ``symmetry_deviation`` (m: mean
    distance of the surface turned about z by a few angles from the unturned surface; below
    the sensor's noise a yaw cannot be told)."""

    name: str
    points: Array
    rgba: npt.NDArray[np.float64]
    radius: float
    height: float
    symmetry_deviation: float

    @property
    def transparent(self) -> bool:
        """The material lets light through (alpha < 1)."""
        return bool(self.rgba[3] < 1.0)


def _grid(a: float, n_min: int = 1, spacing: float = MODEL_SPACING) -> npt.NDArray[np.float64]:
    """Cell centres covering [−a, a] at about ``spacing``."""
    n = max(n_min, math.ceil(2 * a / spacing))
    return (np.arange(n) + 0.5) / n * 2 * a - a


def _box_surface(half: Array) -> Array:
    out = []
    for axis in range(3):
        u, v = [k for k in range(3) if k != axis]
        gu, gv = np.meshgrid(_grid(half[u]), _grid(half[v]))
        for sign in (-1.0, 1.0):
            p = np.zeros((gu.size, 3))
            p[:, axis] = sign * half[axis]
            p[:, u] = gu.ravel()
            p[:, v] = gv.ravel()
            out.append(p)
    return np.concatenate(out)


def _cylinder_surface(radius: float, half_height: float) -> Array:
    n_a = max(12, math.ceil(2 * math.pi * radius / MODEL_SPACING))
    ang = (np.arange(n_a) + 0.5) / n_a * 2 * math.pi
    ga, gz = np.meshgrid(ang, _grid(half_height))
    side = np.stack([radius * np.cos(ga.ravel()), radius * np.sin(ga.ravel()), gz.ravel()], axis=1)
    caps = []
    for r in (np.arange(math.ceil(radius / MODEL_SPACING)) + 0.5) * MODEL_SPACING:
        k = max(6, math.ceil(2 * math.pi * r / MODEL_SPACING))
        a = (np.arange(k) + 0.5) / k * 2 * math.pi
        ring = np.stack([r * np.cos(a), r * np.sin(a), np.zeros(k)], axis=1)
        for sign in (-1.0, 1.0):
            c = ring.copy()
            c[:, 2] = sign * half_height
            caps.append(c)
    return np.concatenate([side, *caps])


def _inside(points: Array, gtype: int, size: Array) -> npt.NDArray[np.bool_]:
    """Points (in the geom frame) strictly inside a box or cylinder by ``INSIDE_MARGIN``."""
    m = INSIDE_MARGIN
    if gtype == mujoco.mjtGeom.mjGEOM_BOX:
        return np.all(np.abs(points) < size - m, axis=1)
    return (np.hypot(points[:, 0], points[:, 1]) < size[0] - m) & (np.abs(points[:, 2]) < size[1] - m)


def _geom_frame(model: mujoco.MjModel, g: int) -> tuple[Array, Array]:
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[g])
    return model.geom_pos[g].copy(), rot.reshape(3, 3)


def _geom_surface(model: mujoco.MjModel, name: str, g: int) -> Array:
    """Points on the surface of geom ``g`` of body ``name``, in the geom's frame; ValueError
    unless it is a box or a cylinder."""
    gtype = int(model.geom_type[g])
    if gtype not in (mujoco.mjtGeom.mjGEOM_BOX, mujoco.mjtGeom.mjGEOM_CYLINDER):
        raise ValueError(f"{name}: geom {g} is neither a box nor a cylinder")
    size = model.geom_size[g]
    return _box_surface(size) if gtype == mujoco.mjtGeom.mjGEOM_BOX else _cylinder_surface(size[0], size[1])


def object_model(model: mujoco.MjModel, name: str) -> ObjectModel:
    """The model of object ``name`` from body ``name``'s geoms (module docstring). Raises
    ``KeyError`` for an unknown body and ``ValueError`` for a body with no geoms or with a geom
    other than a box or a cylinder."""
    body = model.body(name).id
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]
    if not geoms:
        raise ValueError(f"body {name!r} has no geoms")
    frames = [_geom_frame(model, g) for g in geoms]
    samples = []
    colours = []
    for g, (pos, rot) in zip(geoms, frames, strict=True):
        pts = _geom_surface(model, name, g) @ rot.T + pos
        keep = np.ones(len(pts), dtype=bool)
        for h, (hpos, hrot) in zip(geoms, frames, strict=True):
            if h != g:
                keep &= ~_inside((pts - hpos) @ hrot, int(model.geom_type[h]), model.geom_size[h])
        samples.append(pts[keep])
        mat = int(model.geom_matid[g])
        colours.append(model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g])
    points = np.concatenate(samples)
    rgba = np.mean(colours, axis=0).astype(np.float64)
    return ObjectModel(
        name=name,
        points=points,
        rgba=rgba,
        radius=float(np.max(np.hypot(points[:, 0], points[:, 1]))),
        height=float(np.max(points[:, 2])),
        symmetry_deviation=_symmetry_deviation(points),
    )


def _symmetry_deviation(points: Array) -> float:
    """Mean distance (m) from the surface turned about z by ``SYMMETRY_TEST_ANGLES`` to the
    nearest sample of the unturned one, the largest over the angles."""
    tree = small_gicp.KdTree(points)
    worst = 0.0
    for a in SYMMETRY_TEST_ANGLES:
        c, s = math.cos(a), math.sin(a)
        turned = points @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
        _, sq = tree.batch_nearest_neighbor_search(turned)
        worst = max(worst, float(np.mean(np.sqrt(np.asarray(sq)))))
    return worst
