"""Estimating how many content spheres a container holds from what the head camera sees.

The content (velma/model/scene.py): spheres of radius ``PARTICLE_RADIUS`` and a known colour
(their geoms' rgba, read from the model as the objects' colours are). Method, for a container
already localised (velma/perception/localise.py):

1. the cloud's points over the container's footprint (within its outer radius + 5 mm of its
   axis, between its bottom and rim) whose colour is the content's: the content's own
   chromaticity for an opaque container (seen over the rim), or, for a transparent one, a
   colour on the segment from the container's chromaticity to the content's (the content seen
   through the glass: MuJoCo's depth is then the glass wall's, so each such pixel's ray is
   followed to where it passes closest to the container's axis);
2. the fill height above the container's inner bottom (the model's highest point on its
   axis): through a side wall the content shows from the bottom up to its level, so twice the
   median height of those points; over the rim only its top surface shows, so their median
   plus a sphere radius;
3. the count: fill height in sphere diameters × the spheres one layer holds, ``LAYER_PACKING``
   × (R_in / r)² × (1 − r / R_in) (random close packing of discs, 0.82, less a ring of width
   r at the wall), R_in the container's inner radius.

Simplification (named): spheres hidden below others are not seen; the estimate assumes the
pile is level, so a partly filled top layer counts as a fraction of a full one, and a heap
counts high. Error bound: measured by scripts/bench_perception.py (docs/bench/perception.md).
An estimate with no content pixels is 0 (the container looks empty); a container not seen
gives no estimate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from velma.perception.cloud import Array
from velma.perception.localise import ObjectEstimate
from velma.perception.objects import ObjectModel
from velma.perception.segment import GREY, chromaticity

LAYER_PACKING = 0.82
"""Area fraction of randomly close-packed equal discs (assumed, the standard 2-D figure)."""
CONTENT_TOLERANCE = 0.02  # chromaticity distance
MIN_CONTENT_POINTS = 5


@dataclass(frozen=True)
class ContentEstimate:
    """``count`` spheres estimated in ``container`` (≥ 0), from ``points`` content-coloured
    points whose top reaches ``fill_height`` (m above the inner bottom)."""

    container: str
    count: int
    fill_height: float
    points: int


def _content_match(
    colours: npt.NDArray[np.uint8], content_rgba: Array, container: ObjectModel, tolerance: float
) -> npt.NDArray[np.bool_]:
    chroma, bright = chromaticity(colours)
    own = np.asarray(content_rgba[:3], dtype=np.float64)
    own = own / own.sum()
    if not container.transparent:
        return bright & (np.linalg.norm(chroma - own, axis=1) <= tolerance)
    glass = container.rgba[:3] / container.rgba[:3].sum()
    d = own - glass
    t = (chroma - glass) @ d / float(d @ d)
    off = np.linalg.norm(chroma - glass - t[:, None] * d[None, :], axis=1)
    # through the glass the content is a blend: at least a third of the way to it, and not grey
    away_from_grey = np.linalg.norm(chroma - GREY, axis=1) > tolerance
    return bright & (t >= 0.3) & (t <= 1.1) & (off <= tolerance) & away_from_grey


def estimate_content(
    estimate: ObjectEstimate,
    model: ObjectModel,
    points: Array,
    colours: npt.NDArray[np.uint8],
    camera_position: Array,
    content_rgba: Array,
    particle_radius: float,
) -> ContentEstimate | None:
    """Content of the container ``estimate`` (seen, else None) with ``model``, from the cloud
    ``points`` (N × 3, m, world), ``colours`` (N × 3, uint8) seen from ``camera_position``
    (3,) m; the content is spheres of ``content_rgba`` (4,) and ``particle_radius`` (m). See
    the module docstring for the method and its limits."""
    if not estimate.seen or estimate.position is None:
        return None
    origin = estimate.position
    rel = points - origin
    radial = np.hypot(rel[:, 0], rel[:, 1])
    near = (radial <= model.radius + 0.005) & (rel[:, 2] > 0.0) & (rel[:, 2] <= model.height)
    idx = np.flatnonzero(near)
    match = idx[_content_match(colours[idx], content_rgba, model, CONTENT_TOLERANCE)]
    axis_pts = model.points[np.hypot(model.points[:, 0], model.points[:, 1]) < 0.005]
    inner_bottom = float(axis_pts[:, 2].max()) if len(axis_pts) else 0.0
    inner_radius = _inner_radius(model)
    if len(match) < MIN_CONTENT_POINTS:
        return ContentEstimate(container=model.name, count=0, fill_height=0.0, points=len(match))
    heights = rel[match, 2]
    if model.transparent:
        cam = np.asarray(camera_position, dtype=np.float64) - origin
        ray = rel[match] - cam
        # parameter of the ray's closest horizontal approach to the axis
        s = -(cam[0] * ray[:, 0] + cam[1] * ray[:, 1]) / np.maximum(ray[:, 0] ** 2 + ray[:, 1] ** 2, 1e-12)
        heights = cam[2] + s * ray[:, 2]
    level = float(np.median(heights)) - inner_bottom
    # through a side wall the content shows from the bottom up to its level: its median is
    # half the level; over the rim only the top surface shows
    fill = max(0.0, 2 * level if model.transparent else level + particle_radius)
    per_layer = LAYER_PACKING * (inner_radius / particle_radius) ** 2 * (1 - particle_radius / inner_radius)
    count = round(per_layer * fill / (2 * particle_radius))
    return ContentEstimate(container=model.name, count=int(count), fill_height=fill, points=len(match))


def _inner_radius(model: ObjectModel) -> float:
    """Radius (m) of the container's inside at mid height: the smallest distance from the
    axis of the model's points in a band around half its height (the inner wall faces)."""
    z = model.points[:, 2]
    band = np.abs(z - model.height / 2) < 0.005
    return float(np.min(np.hypot(model.points[band, 0], model.points[band, 1])))


@dataclass(frozen=True)
class SphereCount:
    """Content spheres in an open opaque ``container``: ``visible`` sphere centres found in
    the content-coloured points over its floor, ``floor_visible`` the share (0..1) of the
    floor's content layer the camera sees (the rest hidden by something nearer: an arm, a
    held object), ``count`` the estimate ``round(visible / floor_visible)`` (the visible
    spheres' density extrapolated over the hidden part; ``visible`` when the whole layer is
    seen, 0 when none of it is), ``points`` content-coloured points used."""

    container: str
    count: int
    visible: int
    floor_visible: float
    points: int


MIN_SPHERE_POINTS = 4
"""Centre estimates (one a pixel) that make a sphere."""
MIN_FLOOR_VISIBLE = 0.15
"""Below this share of the content layer in view the extrapolation is not made (count = visible)."""


def count_spheres(
    estimate: ObjectEstimate,
    model: ObjectModel,
    points: Array,
    colours: npt.NDArray[np.uint8],
    depth: npt.NDArray[np.floating],
    camera_position: Array,
    camera_rotation: Array,
    fx: float,
    cx: float,
    cy: float,
    content_rgba: Array,
    particle_radius: float,
) -> SphereCount | None:
    """Count the spheres (radius ``particle_radius`` m, colour ``content_rgba``) in the open,
    opaque container ``estimate`` (seen, else None) with ``model``, from the cloud ``points``
    (N × 3, m, world) and ``colours`` (N × 3) of a frame whose ``depth`` image (H × W, m, NaN
    missing) was taken from ``camera_position`` (3,) m with ``camera_rotation`` (3 × 3,
    world-from-optical) and focal length ``fx`` (px, square pixels), principal point ``cx``,
    ``cy`` (px).

    Method: (1) the content-coloured points within the container's inner radius, from its
    inner bottom to a sphere diameter above its rim; (2) the spheres resting on the floor, found
    by ``_spheres_on_layer`` (a Hough transform for spheres of the known radius whose centres
    lie one radius above the inner bottom); (3) the share of the content layer (points on a
    grid over the floor at one sphere radius above it) whose pixel's depth is not nearer than
    the layer by more than 1.5 sphere diameters (a sphere in front of it does not hide it, an
    arm does); (4) the count, ring by ring (frictionless spheres settle in rings about the
    axis, the outer one along the wall): the spheres seen at one distance from the axis over
    the share of that ring (one sphere radius wide) in view, at most as many as the ring holds
    touching (named simplification: a ring's hidden arc holds spheres as densely as its seen
    arc; a ring with no sphere in view is not counted). Spheres stacked under others are not seen (a second
    layer counts low)."""
    if not estimate.seen or estimate.position is None:
        return None
    r = particle_radius
    origin = estimate.position
    inner_bottom, inner_radius = _inner_bottom(model), _inner_radius(model)
    rel = points - origin
    radial = np.hypot(rel[:, 0], rel[:, 1])
    near = (radial <= inner_radius + 0.002) & (rel[:, 2] > inner_bottom) & (rel[:, 2] <= model.height + 2 * r)
    idx = np.flatnonzero(near)
    match = idx[_content_match(colours[idx], content_rgba, model, CONTENT_TOLERANCE)]
    cam = np.asarray(camera_position, dtype=np.float64)
    layer = inner_bottom + r
    centres = _spheres_on_layer(points[match], origin + np.array([0.0, 0.0, layer]), inner_radius - r, r)
    visible = len(centres)
    view = (depth, cam, camera_rotation, fx, cx, cy, r)
    share = _floor_visible(origin, layer, inner_radius - r, *view)
    # the hidden part is judged ring by ring: the spheres seen at one distance from the axis,
    # over the share of that ring in view, at most as many as the ring holds touching
    radial = np.hypot(centres[:, 0] - origin[0], centres[:, 1] - origin[1])
    total = 0.0
    for ring in _rings(radial, r):
        at = float(np.median(ring))
        seen = _floor_visible(origin, layer, at + r / 2, *view, max(0.0, at - r / 2))
        holds = max(1, int(2 * np.pi * at / (2 * r))) if at >= r else 1
        total += min(len(ring) / max(seen, MIN_FLOOR_VISIBLE), max(holds, len(ring)))
    count = round(total)
    return SphereCount(
        container=model.name, count=int(count), visible=visible, floor_visible=share, points=len(match)
    )


def _rings(radial: Array, r: float) -> list[Array]:
    """The distances from the axis (m) grouped into rings: sorted, split where two neighbours
    differ by more than ``r``."""
    if len(radial) == 0:
        return []
    order = np.sort(radial)
    cuts = np.flatnonzero(np.diff(order) > r) + 1
    return list(np.split(order, cuts))


SURFACE_BAND = 0.35
"""A point is on a candidate sphere's surface when its distance from the centre is within
this share of the radius of it (noise at ≈ 1 m: a few mm, velma/perception/noise.py)."""
GRID_STEP = 0.002  # m, candidate centres on the layer


def _spheres_on_layer(surface: Array, centre: Array, reach: float, r: float) -> Array:
    """Count spheres of radius ``r`` resting in one layer: their centres lie on the horizontal
    plane through ``centre`` (3,) within ``reach`` of it (m), and ``surface`` (M × 3, m) are
    the visible points of their surfaces. A Hough transform with the radius and the height
    known: every candidate centre on a ``GRID_STEP`` grid scores the points within
    ``SURFACE_BAND`` × r of its sphere's surface; the best is a sphere, candidates closer
    than 1.6 r to it are suppressed (touching spheres' centres are 2 r apart), until the best
    scores fewer than ``MIN_SPHERE_POINTS``. A sphere on a second layer is not counted.
    Returns the centres found (K × 3, m)."""
    if len(surface) < MIN_SPHERE_POINTS:
        return np.zeros((0, 3))
    steps = np.arange(-reach, reach + 1e-12, GRID_STEP)
    gx, gy = np.meshgrid(steps, steps)
    inside = gx**2 + gy**2 <= reach**2
    cand = np.stack([gx[inside], gy[inside], np.zeros(int(inside.sum()))], axis=1) + centre
    dist = np.linalg.norm(surface[None, :, :] - cand[:, None, :], axis=2)
    on = np.abs(dist - r) <= SURFACE_BAND * r
    score = on.sum(axis=1).astype(np.int64)
    alive = np.ones(len(cand), dtype=bool)
    found: list[int] = []
    while alive.any():
        best = int(np.argmax(np.where(alive, score, -1)))
        if score[best] < MIN_SPHERE_POINTS:
            break
        found.append(best)
        near = np.sum((cand[:, :2] - cand[best, :2]) ** 2, axis=1) < (1.6 * r) ** 2
        alive &= ~near
        score = score - on[:, on[best]].sum(axis=1)  # a point belongs to one sphere
        on[:, on[best]] = False
    return cand[found]


def _floor_visible(
    origin: Array,
    layer_z: float,
    radius: float,
    depth: npt.NDArray[np.floating],
    cam: Array,
    rotation: Array,
    fx: float,
    cx: float,
    cy: float,
    r: float,
    inner: float = 0.0,
) -> float:
    """Share of a grid (5 mm) over the ring from ``inner`` to ``radius`` (m) at ``layer_z``
    above ``origin`` whose pixels' depth is not nearer than the grid point by more than 3 ``r``
    (points whose pixel has no depth are left out; points outside the image count as hidden)."""
    g = np.arange(-radius, radius + 1e-9, 0.005)
    xx, yy = np.meshgrid(g, g)
    disc = (np.hypot(xx, yy) <= radius) & (np.hypot(xx, yy) >= inner)
    world = np.column_stack([xx[disc], yy[disc], np.full(int(disc.sum()), layer_z)]) + origin
    optical = (world - cam) @ np.asarray(rotation, dtype=np.float64)
    z = optical[:, 2]
    u = np.floor(fx * optical[:, 0] / z + cx).astype(np.int64)
    v = np.floor(fx * optical[:, 1] / z + cy).astype(np.int64)
    h, w = depth.shape
    inside = (z > 0) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    if not np.any(inside):
        return 0.0
    seen_depth = np.full(len(z), np.nan)
    seen_depth[inside] = depth[v[inside], u[inside]]
    known = ~inside | np.isfinite(seen_depth)  # missing depth says nothing: left out
    with np.errstate(invalid="ignore"):
        clear = inside & (seen_depth >= z - 3 * r)
    return float(np.count_nonzero(clear)) / max(int(np.count_nonzero(known)), 1)


def _inner_bottom(model: ObjectModel) -> float:
    """Height (m) of the container's inner bottom: the model's highest point on its axis."""
    axis_pts = model.points[np.hypot(model.points[:, 0], model.points[:, 1]) < 0.005]
    return float(axis_pts[:, 2].max()) if len(axis_pts) else 0.0
