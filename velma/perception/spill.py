"""Content seen outside every container: spheres lying on a support plane (the table, a shelf,
the floor) in view, e.g. spilled by a pour.

The content is conserved: a sphere that left the jar and is seen on the table is not in the
bowl. ag_ex's Observation (velma/executor/observer.py) reports the count as
``particles_outside`` and caps each container's count at ``total_particles`` less it, so a
spill that lands in view fails the pour's content check even when the bowl's count infers
spheres behind its near wall (velma/perception/content.py ``count_spheres``).

Method: the points of the content's colour (``colour_match``, opaque) that lie within a sphere
diameter (+ ``LAYER_MARGIN``) above the support plane below them (``segment.clusters``), away
from every container seen (``CONTAINER_MARGIN`` beyond its radius from its axis), grouped in
touching voxels; in each group the spheres resting on that plane are found by the Hough
transform of ``content.spheres_on_layer`` (centres one radius above the plane).

Named simplifications: only spheres resting on a support in view are counted (one on the floor
behind the table, or hidden by the robot's arm, is not seen); a sphere lying on another sphere
is not counted; a container that is not seen (held, out of view) is not excluded, but its
content lies higher than a sphere diameter above any plane below it and is not taken.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from velma.perception.cloud import Array
from velma.perception.content import CONTENT_TOLERANCE, MIN_SPHERE_POINTS, spheres_on_layer
from velma.perception.localise import ObjectEstimate
from velma.perception.objects import ObjectModel
from velma.perception.segment import clusters, colour_match

LAYER_MARGIN = 0.003
"""m: above a sphere's top on its support (the Kinect's noise at ≈ 1 m is a few mm,
velma/perception/noise.py)."""
CONTAINER_MARGIN = 0.01
"""m: points within a container's radius and this of its axis are the container's."""


@dataclass(frozen=True)
class Spill:
    """``count`` content spheres seen resting on support planes outside every container, their
    ``centres`` (count × 3, m, world) and the content-coloured ``points`` considered."""

    count: int
    centres: Array
    points: int


def count_outside(
    points: Array,
    colours: npt.NDArray[np.uint8],
    supports: list[float],
    containers: Iterable[tuple[ObjectEstimate, ObjectModel]],
    content_rgba: Array,
    particle_radius: float,
) -> Spill:
    """The content spheres (radius ``particle_radius`` m, colour ``content_rgba`` (4,)) lying
    on the ``supports`` (plane heights, m; segment.py ``support_heights``) in the cloud
    ``points`` (N × 3, m, world, z up) with ``colours`` (N × 3, uint8), outside the
    ``containers`` (estimate and model; those not seen are ignored). See the module
    docstring."""
    r = particle_radius
    match = colour_match(colours, content_rgba, CONTENT_TOLERANCE)
    for e, model in containers:
        if not e.seen or e.position is None:
            continue
        d = np.hypot(points[:, 0] - e.position[0], points[:, 1] - e.position[1])
        match &= d > model.radius + CONTAINER_MARGIN
    candidates = np.flatnonzero(match)
    found: list[Array] = []
    for c in clusters(points, candidates, supports, 2 * r + LAYER_MARGIN, MIN_SPHERE_POINTS):
        p = points[c.index]
        mid = (p[:, :2].min(axis=0) + p[:, :2].max(axis=0)) / 2
        centres, _ = spheres_on_layer(p, np.array([*mid, c.support + r]), c.extent / 2 + r, r)
        found.extend(centres)
    out = np.asarray(found, dtype=np.float64).reshape(-1, 3)
    return Spill(count=len(out), centres=out, points=len(candidates))
