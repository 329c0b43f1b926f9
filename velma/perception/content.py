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

In an open opaque container (the bowl, the cup) the spheres are counted one by one
(``count_spheres``): a Hough transform for spheres of the known radius on the floor layer
finds them in the depth cloud, a joint least-squares fit places them, the colour image
finds those along the near wall of which only a sliver over the rim shows, seen at a
grazing angle where the Kinect returns no depth, and the ring along the wall is completed
over the arc the wall hides. Its named simplifications are in its docstring.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from velma.perception.cloud import Array
from velma.perception.localise import ObjectEstimate
from velma.perception.noise import MAX_INCIDENCE
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
    the content-coloured points over its floor, ``hidden`` the spheres inferred in the part of
    the ring along its wall the camera cannot see (``count_spheres``), ``count`` = ``visible``
    + ``hidden``; ``floor_visible`` the share (0..1) of the floor's content layer in view and
    ``ring_visible`` the share of the wall ring's sphere positions in view; ``points``
    content-coloured points used."""

    container: str
    count: int
    visible: int
    hidden: int
    floor_visible: float
    ring_visible: float
    points: int


MIN_SPHERE_POINTS = 4
"""Centre estimates (one a pixel) that make a sphere."""
MIN_INNER_SHARE = 0.3
"""A sphere found off the wall ring must take at least this share of the median points the
spheres found took (``count_spheres``)."""
RING_STEP_DEG = 1.0
"""Angular resolution (°) of the wall ring's visibility test."""
SEE_THROUGH_SHARE = 0.5
"""A candidate centre of ``spheres_on_layer`` is no sphere when more than this share of the
pixels inside ``SEE_THROUGH_CORE`` of its silhouette that are not hidden behind something
nearer show a depth beyond its surface: the camera sees through where the sphere would be
(``_silhouette_pixels``). A sphere there shows its own surface in those pixels; two
neighbours along the near wall, of which only the tops show, leave a notch between them
that a candidate halfway between them would fill."""
SEE_THROUGH_CORE = 0.8
"""Share of a sphere's radius: the pixels whose rays pass this close to a candidate's centre
make its core, away from its outline, where a pixel's depth mixes the sphere's and the
background's."""
CAP_DEPTH_TOLERANCE = 0.006
"""m: a pixel shows a sphere's surface when its depth is within this of it, something nearer
or the background beyond when it is further off (the averaged Kinect depth's noise at ≈ 1 m
is ≈ 1–2 mm, velma/perception/noise.py)."""


@dataclass(frozen=True)
class DepthView:
    """A frame's ``depth`` image (H × W, m along the optical axis, NaN missing) and the camera
    that took it: at ``camera`` (3,) m with ``rotation`` (3 × 3, world-from-optical), focal
    length ``fx`` (px, square pixels), principal point ``cx``, ``cy`` (px)."""

    depth: npt.NDArray[np.floating]
    camera: Array
    rotation: Array
    fx: float
    cx: float
    cy: float

    def optical(self, points: Array) -> Array:
        """``points`` (K × 3, m, world) in the optical frame (K × 3, m; z along the axis)."""
        return np.asarray((np.asarray(points, dtype=np.float64) - self.camera) @ self.rotation)

    def pixel(self, optical: Array) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """The pixel (column u, row v) of each optical-frame point (K × 3, m, z > 0)."""
        u = np.floor(self.fx * optical[:, 0] / optical[:, 2] + self.cx).astype(np.int64)
        v = np.floor(self.fx * optical[:, 1] / optical[:, 2] + self.cy).astype(np.int64)
        return u, v

    def in_image(self, u: npt.NDArray[np.int64], v: npt.NDArray[np.int64]) -> npt.NDArray[np.bool_]:
        """Whether pixels (``u``, ``v``: same shape) lie in the image."""
        h, w = self.depth.shape
        return np.asarray((u >= 0) & (u < w) & (v >= 0) & (v < h))


def count_spheres(
    estimate: ObjectEstimate,
    model: ObjectModel,
    points: Array,
    colours: npt.NDArray[np.uint8],
    depth: npt.NDArray[np.floating],
    rgb: npt.NDArray[np.uint8],
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
    missing) and colour image ``rgb`` (H × W × 3, uint8) were taken from ``camera_position``
    (3,) m with ``camera_rotation`` (3 × 3, world-from-optical) and focal length ``fx`` (px,
    square pixels), principal point ``cx``, ``cy`` (px).

    Method: (1) the content-coloured points within the container's inner radius, from its
    inner bottom to a sphere diameter above its rim; (2) the spheres resting on the floor,
    found by ``spheres_on_layer`` (a Hough transform for spheres of the known radius whose
    centres lie one radius above the inner bottom; a candidate centre the camera sees through
    is none, ``SEE_THROUGH_SHARE``: of a sphere against the near wall only its top shows,
    which a candidate a few mm off, or halfway to its neighbour, fits as well), less those
    off the wall ring (3) that took fewer than ``MIN_INNER_SHARE`` of the median points (off
    the ring the floor is in view, so a sphere there shows most of its cap), then refined
    jointly by least squares (``_refine_centres``: each point fits the sphere whose surface
    it lies nearest to); (3) the ring along the wall: the container's shape (its model) gives
    the distance ``_ring_radius`` from the axis at which a sphere on the floor touches the
    wall, where the frictionless spheres settle (velma/model/scene.py); the spheres found
    beyond one radius inside it are the ring's; (4) the ring's spheres that show in colour
    but not in depth (``_ring_spheres_in_colour``: of a sphere along the near wall only a
    sliver over the rim may show, seen at a grazing angle, where the Kinect returns no
    depth; the ring's spheres found in (2) put on the ring for it); (2) and (4) make
    ``visible``; (5) the ring's positions the camera cannot see
    (``_ring_hidden``: a sphere there would show fewer pixels than a sphere found takes, the
    rest of it behind something nearer in the depth image: the bowl's near wall, an arm, a
    neighbour); (6) ``hidden``:
    for each gap between neighbouring ring spheres that reaches into positions out of view,
    the spheres that fit it at the spacing of the ring's neighbours in view (the median of
    the gaps shorter than 1.5 touching spacings; touching when there are none), at most as
    many as its hidden positions hold touching; a gap wholly in view is empty (the floor is
    seen there). From the head's pour view of the bowl at velma/scenario.py
    BOWL_PLACE_POSITION every place of the ring shows (step 4 for the least visible, along
    the near wall); from 7 cm further three are hidden (tests/velma/perception/test_content_count.py).

    Named simplifications: a hidden arc of the ring (the bowl seen from further away than
    its pour place) is assumed as full as its neighbours make it (a vacancy that happens to
    lie in it, or a sphere taken from it, is counted full); so is a gap of two or more
    neighbouring ring spheres that reaches a few hidden degrees; spheres hidden elsewhere
    than along the wall are not inferred, and spheres stacked on others (a second layer) are
    not counted. ag_ex's Observation caps the count at
    what the content seen outside every container leaves (velma/perception/spill.py), so a
    sphere spilled in view is not counted in the bowl; one gone out of view from the hidden arc
    still is, so the Observation says how many it inferred (L_SD ``particles_inferred``). a_ta
    judges on the seen and the inferred together, told apart: when the share its check asks for
    is reached only with the inferred, it looks again, of the two looks the one that saw more
    spheres decides, and a success that still rests on the inferred says so
    (services/agents/task_executor/verdict.py).
    Measured (scripts/bench_perception.py ``--pours --remove``, docs/bench/observe.md)."""
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
    view = DepthView(
        depth,
        np.asarray(camera_position, dtype=np.float64),
        np.asarray(camera_rotation, dtype=np.float64),
        fx,
        cx,
        cy,
    )
    layer = inner_bottom + r
    centre = origin + np.array([0.0, 0.0, layer])

    def seen_through(cand: Array) -> npt.NDArray[np.bool_]:
        return _seen_through(cand, view, r)

    found, took = spheres_on_layer(points[match], centre, inner_radius - r, r, seen_through)
    ring = _ring_radius(model, layer, r)
    at_ring = np.hypot(found[:, 0] - origin[0], found[:, 1] - origin[1]) > ring - r
    # off the ring the floor is in view: a real sphere there shows much of its cap; a weak
    # peak there is what its neighbours' stray points left over
    strong = took >= MIN_INNER_SHARE * (float(np.median(took)) if len(took) else 0.0)
    keep = at_ring | strong
    centres = _refine_centres(points[match], found[keep], r)
    at_ring = at_ring[keep]
    theta = np.radians(np.arange(0.0, 360.0, RING_STEP_DEG))
    ring_centres = centre + ring * np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    h, w = depth.shape
    content_pixels = _content_match(rgb.reshape(-1, 3), content_rgba, model, CONTENT_TOLERANCE).reshape(h, w)
    # the spheres along the wall touch it (3): of one along the near wall only the top shows,
    # which the fit places a few mm inward; put on the ring it shows where its sliver is
    snapped = centres.copy()
    out = centres[at_ring, :2] - origin[:2]
    snapped[at_ring, :2] = origin[:2] + ring * out / np.linalg.norm(out, axis=1, keepdims=True)
    extra = _ring_spheres_in_colour(ring_centres, snapped, view, content_pixels, r)
    centres = np.vstack([centres, extra])
    at_ring = np.append(at_ring, np.ones(len(extra), dtype=bool))
    share = _floor_visible(origin, layer, inner_radius - r, view, r)
    hidden_at = _ring_hidden(centre, ring, view, r)
    angles = np.arctan2(centres[at_ring, 1] - origin[1], centres[at_ring, 0] - origin[0])
    hidden = _hidden_in_gaps(angles, hidden_at, 2 * math.asin(min(1.0, r / ring)))
    return SphereCount(
        container=model.name,
        count=len(centres) + hidden,
        visible=len(centres),
        hidden=hidden,
        floor_visible=share,
        ring_visible=1.0 - float(np.mean(hidden_at)),
        points=len(match),
    )


def _refine_centres(surface: Array, centres: Array, r: float, iterations: int = 5) -> Array:
    """``centres`` (K × 3, m) moved horizontally to fit, by Gauss–Newton least squares, the
    ``surface`` points (M × 3, m) within ``SURFACE_BAND`` × r of their sphere's surface
    (radius ``r``; the height stays the layer's), jointly: at each step a point counts for the
    sphere whose surface it lies nearest to. The Hough grid's 2 mm steps and its neighbours'
    points bias a centre by a few mm, more for a sphere along the near wall of which only
    the top shows, next to a neighbour of which much shows."""
    out = centres.copy()
    if len(out) == 0:
        return out
    for _ in range(iterations):
        off = np.abs(np.linalg.norm(surface[:, None, :] - out[None, :, :], axis=2) - r)
        owner = np.argmin(off, axis=1)
        fits = off[np.arange(len(surface)), owner] <= SURFACE_BAND * r
        for k, c in enumerate(out):
            near = surface[fits & (owner == k)]
            if len(near) < MIN_SPHERE_POINTS:
                continue
            v = near - c
            n = np.maximum(np.linalg.norm(v, axis=1), 1e-9)
            jacobian = -v[:, :2] / n[:, None]
            delta, *_ = np.linalg.lstsq(jacobian, r - n, rcond=None)
            c[:2] += delta
    return out


def _wall_radius(model: ObjectModel, z: float, band: float = 0.003) -> float:
    """Distance (m) of the container's inner wall from its axis at height ``z`` (m, object
    frame): the smallest horizontal distance of the model's points within ``band`` of it.
    Raises ``ValueError`` when the model has no surface there."""
    p = model.points
    at = np.abs(p[:, 2] - z) < band
    if not np.any(at):
        raise ValueError(f"{model.name} has no surface at height {z:.3f} m")
    return float(np.min(np.hypot(p[at, 0], p[at, 1])))


def _ring_radius(model: ObjectModel, layer: float, r: float) -> float:
    """Distance (m) from the axis of the centre of a sphere of radius ``r`` whose centre is at
    height ``layer`` (object frame) and which touches the inner wall: the wall's radius there
    less r / cos(flare), the flare from the wall's radius 5 mm below and above."""
    dz = 0.005
    slope = (_wall_radius(model, layer + dz) - _wall_radius(model, layer - dz)) / (2 * dz)
    return _wall_radius(model, layer) - r * math.sqrt(1.0 + slope**2)


def _ring_hidden(
    centre: Array,
    ring: float,
    view: DepthView,
    r: float,
) -> npt.NDArray[np.bool_]:
    """Per ``RING_STEP_DEG`` of angle about the vertical axis through ``centre`` (3,) m (the
    layer's centre, world), whether a sphere of radius ``r`` centred ``ring`` m from the axis
    there would be out of view: fewer than ``MIN_SPHERE_POINTS`` pixels of its silhouette
    are not behind something nearer in ``depth`` (``_silhouette_pixels``), fewer than a
    sphere found takes, so ``spheres_on_layer`` could not find it, and no more than
    ``SEE_THROUGH_SHARE`` of those few show a depth beyond it (where they do, the camera sees
    the place empty). Returns a boolean array
    of 360 / ``RING_STEP_DEG`` entries, entry k for the angle k · ``RING_STEP_DEG`` (° from
    the world's x axis)."""
    theta = np.radians(np.arange(0.0, 360.0, RING_STEP_DEG))
    at = centre + ring * np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    past, on = _silhouette_pixels(at, view, r, 1.0)
    return np.asarray((past + on < MIN_SPHERE_POINTS) & (past <= SEE_THROUGH_SHARE * (past + on)))


def _seen_through(
    centres: Array,
    view: DepthView,
    r: float,
) -> npt.NDArray[np.bool_]:
    """Whether the camera sees past a sphere of radius ``r`` m centred at each of ``centres``
    (K × 3, m, world): more than ``SEE_THROUGH_SHARE`` of the pixels of its core
    (``SEE_THROUGH_CORE``) not hidden behind something nearer show a depth beyond its
    surface, so no sphere is there (arguments as ``_silhouette_pixels``; (K,) mask)."""
    past, on = _silhouette_pixels(centres, view, r, SEE_THROUGH_CORE)
    return np.asarray(past > SEE_THROUGH_SHARE * (past + on))


def _silhouette_pixels(
    centres: Array,
    view: DepthView,
    r: float,
    core: float,
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """For spheres of radius ``r`` m centred at ``centres`` (K × 3, m, world) in ``view``:
    among the pixels of its depth image whose ray passes within ``core`` · r of a sphere's centre,
    how many show a depth beyond its front surface by more than ``CAP_DEPTH_TOLERANCE``
    (the camera sees past it) and how many show a depth within that of it (its own surface,
    or something just in front). Pixels whose depth is nearer (hidden behind something),
    missing or outside the image count in neither. Returns two (K,) arrays."""
    s = _silhouettes(centres, view, r, core)
    if s is None:
        return np.zeros(len(centres), dtype=np.int64), np.zeros(len(centres), dtype=np.int64)
    with np.errstate(invalid="ignore"):
        past = s.within & (s.seen > s.front + CAP_DEPTH_TOLERANCE)
        on = s.within & (np.abs(s.seen - s.front) <= CAP_DEPTH_TOLERANCE)
    return past.sum(axis=1).astype(np.int64), on.sum(axis=1).astype(np.int64)


@dataclass(frozen=True)
class _Silhouettes:
    """Per sphere (rows, K) the pixels of a square window about its image (columns, P):
    ``u``, ``v`` (K × P, px), ``within`` (K × P) whether the pixel lies in the image and its ray
    passes within the asked share of the radius of the centre, ``front`` (K × P, m along the
    optical axis) where that ray meets the sphere's front surface (its closest approach where
    it misses), ``seen`` (K × P, m) the depth image there (NaN missing or outside the image),
    ``ray`` (K × P × 3) the pixel rays (optical frame, z = 1), ``miss`` (K × P, m) how far
    each passes from the centre."""

    u: npt.NDArray[np.int64]
    v: npt.NDArray[np.int64]
    within: npt.NDArray[np.bool_]
    front: npt.NDArray[np.float64]
    seen: npt.NDArray[np.float64]
    ray: npt.NDArray[np.float64]
    miss: npt.NDArray[np.float64]


def _silhouettes(centres: Array, view: DepthView, r: float, core: float) -> _Silhouettes | None:
    """The image windows of spheres of radius ``r`` m at ``centres`` (K × 3, m, world) in
    ``view`` (``_Silhouettes``, rays within ``core`` · r of a centre); None when there are no
    centres or one lies within r of the camera's plane."""
    c = view.optical(centres)
    if len(c) == 0 or float(np.min(c[:, 2])) <= r:
        return None
    fx, cx, cy, depth = view.fx, view.cx, view.cy, view.depth
    reach = math.ceil(fx * r / float(np.min(c[:, 2]) - r)) + 1
    du, dv = (g.ravel() for g in np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1)))
    u0, v0 = view.pixel(c)
    u, v = u0[:, None] + du[None, :], v0[:, None] + dv[None, :]
    inside = view.in_image(u, v)
    ray = np.stack([(u + 0.5 - cx) / fx, (v + 0.5 - cy) / fx, np.ones(u.shape)], axis=2)  # z = 1
    sq = np.sum(ray * ray, axis=2)
    closest = np.sum(ray * c[:, None, :], axis=2) / sq  # depth of the ray's closest approach
    miss2 = np.sum((closest[..., None] * ray - c[:, None, :]) ** 2, axis=2)
    within = inside & (miss2 <= (core * r) ** 2)
    front = closest - np.sqrt(np.maximum(r * r - miss2, 0.0) / sq)
    seen = np.full(u.shape, np.nan)
    seen[inside] = depth[v[inside], u[inside]]
    return _Silhouettes(u, v, within, front, seen, ray, np.sqrt(miss2))


GRAZING_SHARE = 0.8
"""Share of a sphere's radius: a pixel without depth shows the sphere's own outline when its
ray passes at least this far from the centre, where the surface turns from the ray by more
than the Kinect returns depth for (velma/perception/noise.py ``MAX_INCIDENCE``, 75°: from
0.97 r on; a pixel is ≈ 0.15 r wide at the pour view's ≈ 0.8 m)."""


def _ring_spheres_in_colour(
    ring_centres: Array,
    found: Array,
    view: DepthView,
    content_pixels: npt.NDArray[np.bool_],
    r: float,
) -> Array:
    """Spheres of the wall ring that show in colour but barely in depth (``count_spheres``
    step 4): of a sphere along the near wall only a sliver over the rim shows, seen at a
    grazing angle, where the Kinect returns no depth (velma/perception/noise.py
    ``MAX_INCIDENCE``), so its few points are missing from the cloud, or are within the
    surface band of its inner neighbour, whose peak takes them.

    ``ring_centres`` (C × 3, m, world): the ring's positions (``_ring_radius``, every
    ``RING_STEP_DEG``); ``found`` (K × 3, m): the sphere centres found; ``content_pixels``
    (H × W): the pixels of ``view``'s colour image with the content's colour. A position is a
    sphere when it lies at least 1.6 r from every sphere found (as ``spheres_on_layer``
    suppresses), and among the pixels whose ray passes within r of its centre and not within
    (1 + ``SURFACE_BAND``) r of a sphere found less than r behind its surface (in front of
    it, or beside it: that sphere shows there): at least ``MIN_SPHERE_POINTS`` have the
    content's colour and either its surface's depth (within ``CAP_DEPTH_TOLERANCE``) where
    the ray passes less than sin(``MAX_INCIDENCE``) r from the centre (further out the sphere
    returns no depth, so a depth there is something else's) or no depth where it passes
    ``GRAZING_SHARE`` r or more from it (its outline), and no more than ``SEE_THROUGH_SHARE``
    of those and the ones showing a depth beyond it show that depth. Best first, each one
    found joining ``found``. Returns the centres (J × 3, m, world). An empty place along the
    near wall, through which the top of an inner sphere shows, is what these rules tell from
    a sphere (tests/velma/perception/test_content_count.py)."""
    s = _silhouettes(ring_centres, view, r, 1.0)
    if s is None:
        return np.zeros((0, 3))
    h, w = content_pixels.shape
    coloured = s.within & content_pixels[np.clip(s.v, 0, h - 1), np.clip(s.u, 0, w - 1)]
    with np.errstate(invalid="ignore"):
        past = s.within & (s.seen > s.front + CAP_DEPTH_TOLERANCE)
        grazing = np.isnan(s.seen) & (s.miss >= GRAZING_SHARE * r)
        # past sin(MAX_INCIDENCE) r from the centre the sphere returns no depth: a depth there is another's
        faced = (np.abs(s.seen - s.front) <= CAP_DEPTH_TOLERANCE) & (s.miss < math.sin(MAX_INCIDENCE) * r)
        shows = coloured & (grazing | faced)
    sq = np.sum(s.ray * s.ray, axis=2)
    reach = (1.0 + SURFACE_BAND) * r

    def in_front(centre: Array) -> npt.NDArray[np.bool_]:
        """Pixels whose ray passes within ``reach`` of ``centre`` less than r behind the
        candidate's front (its sphere is in front, or beside it)."""
        c = view.optical(centre[None, :])[0]
        closest = s.ray @ c / sq
        miss2 = np.sum((closest[..., None] * s.ray - c) ** 2, axis=2)
        return np.asarray((miss2 <= reach * reach) & (closest < s.front + r))

    taken = np.zeros(s.within.shape, dtype=bool)
    for c in found:
        taken |= in_front(c)
    alive = np.ones(len(ring_centres), dtype=bool)
    for c in found:
        alive &= np.sum((ring_centres[:, :2] - c[:2]) ** 2, axis=1) >= (1.6 * r) ** 2
    out: list[Array] = []
    while alive.any():
        score = np.sum(shows & ~taken, axis=1)
        beyond = np.sum(past & ~taken, axis=1)
        fits = alive & (score >= MIN_SPHERE_POINTS) & (beyond <= SEE_THROUGH_SHARE * (score + beyond))
        if not fits.any():
            break
        best = int(np.argmax(np.where(fits, score, -1)))
        out.append(ring_centres[best])
        taken |= in_front(ring_centres[best])
        alive &= np.sum((ring_centres[:, :2] - ring_centres[best, :2]) ** 2, axis=1) >= (1.6 * r) ** 2
    return np.array(out).reshape(-1, 3)


def _hidden_in_gaps(angles: Array, hidden_at: npt.NDArray[np.bool_], step: float) -> int:
    """Spheres inferred in the ring's hidden positions (``count_spheres`` step 5): ``angles``
    (rad) of the ring's spheres in view, ``hidden_at`` the ``_ring_hidden`` mask, ``step``
    (rad) the angle between touching neighbours. With no sphere of the ring in view nothing
    is inferred."""
    if len(angles) == 0 or not np.any(hidden_at):
        return 0
    a = np.sort(np.mod(angles, 2 * math.pi))
    gaps = np.diff(np.append(a, a[0] + 2 * math.pi))
    close = gaps[gaps < 1.5 * step]
    spacing = float(np.median(close)) if len(close) else step
    bin_rad = math.radians(RING_STEP_DEG)
    total = 0
    for start, gap in zip(a, gaps, strict=True):
        # centre positions inside the gap at least a touching spacing from both neighbours
        inside = np.arange(start + step, start + gap - step + 1e-9, bin_rad)
        if len(inside) == 0:
            continue
        hidden = hidden_at[np.floor(np.mod(inside, 2 * math.pi) / bin_rad).astype(np.int64) % len(hidden_at)]
        if not np.any(hidden):
            continue
        fits = max(0, round(gap / spacing) - 1)
        holds = int(np.count_nonzero(hidden) * bin_rad // step) + 1
        total += min(fits, holds)
    return total


SURFACE_BAND = 0.35
"""A point is on a candidate sphere's surface when its distance from the centre is within
this share of the radius of it (noise at ≈ 1 m: a few mm, velma/perception/noise.py)."""
GRID_STEP = 0.002  # m, candidate centres on the layer


def spheres_on_layer(
    surface: Array,
    centre: Array,
    reach: float,
    r: float,
    ruled_out: Callable[[Array], npt.NDArray[np.bool_]] | None = None,
) -> tuple[Array, npt.NDArray[np.int64]]:
    """Count spheres of radius ``r`` resting in one layer: their centres lie on the horizontal
    plane through ``centre`` (3,) within ``reach`` of it (m), and ``surface`` (M × 3, m) are
    the visible points of their surfaces. A Hough transform with the radius and the height
    known: every candidate centre on a ``GRID_STEP`` grid scores the points within
    ``SURFACE_BAND`` × r of its sphere's surface; the best is a sphere, candidates closer
    than 1.6 r to it are suppressed (touching spheres' centres are 2 r apart), until the best
    scores fewer than ``MIN_SPHERE_POINTS``. ``ruled_out`` (candidate centres, C × 3 m, to a
    (C,) mask) removes candidates that cannot be spheres beforehand (``count_spheres``: the
    camera sees through them). A sphere on a second layer is not counted. Returns the
    centres found (K × 3, m) and the points each took (K,)."""
    if len(surface) < MIN_SPHERE_POINTS:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    steps = np.arange(-reach, reach + 1e-12, GRID_STEP)
    gx, gy = np.meshgrid(steps, steps)
    inside = gx**2 + gy**2 <= reach**2
    cand = np.stack([gx[inside], gy[inside], np.zeros(int(inside.sum()))], axis=1) + centre
    dist = np.linalg.norm(surface[None, :, :] - cand[:, None, :], axis=2)
    on = np.abs(dist - r) <= SURFACE_BAND * r
    score = on.sum(axis=1).astype(np.int64)
    alive = np.ones(len(cand), dtype=bool) if ruled_out is None else ~ruled_out(cand)
    found: list[int] = []
    taken: list[int] = []
    while alive.any():
        best = int(np.argmax(np.where(alive, score, -1)))
        if score[best] < MIN_SPHERE_POINTS:
            break
        found.append(best)
        taken.append(int(score[best]))
        near = np.sum((cand[:, :2] - cand[best, :2]) ** 2, axis=1) < (1.6 * r) ** 2
        alive &= ~near
        score = score - on[:, on[best]].sum(axis=1)  # a point belongs to one sphere
        on[:, on[best]] = False
    return cand[found], np.asarray(taken, dtype=np.int64)


def _floor_visible(
    origin: Array,
    layer_z: float,
    radius: float,
    view: DepthView,
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
    optical = view.optical(world)
    z = optical[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u, v = view.pixel(np.where(z[:, None] > 0, optical, 1.0))
    inside = (z > 0) & view.in_image(u, v)
    if not np.any(inside):
        return 0.0
    seen_depth = np.full(len(z), np.nan)
    seen_depth[inside] = view.depth[v[inside], u[inside]]
    known = ~inside | np.isfinite(seen_depth)  # missing depth says nothing: left out
    with np.errstate(invalid="ignore"):
        clear = inside & (seen_depth >= z - 3 * r)
    return float(np.count_nonzero(clear)) / max(int(np.count_nonzero(known)), 1)


def _inner_bottom(model: ObjectModel) -> float:
    """Height (m) of the container's inner bottom: the model's highest point on its axis."""
    axis_pts = model.points[np.hypot(model.points[:, 0], model.points[:, 1]) < 0.005]
    return float(axis_pts[:, 2].max()) if len(axis_pts) else 0.0
