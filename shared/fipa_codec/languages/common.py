"""Types shared by several content languages: poses and object states in SI units."""

from __future__ import annotations

import msgspec

Vec3 = tuple[float, float, float]
"""A point or vector in metres (or a unit axis), in the frame named alongside it."""

Quat = tuple[float, float, float, float]
"""A unit quaternion (w, x, y, z)."""


class Pose(msgspec.Struct, frozen=True, array_like=True):
    """A rigid pose: ``position`` in metres, ``orientation`` as a unit quaternion (w, x, y, z),
    expressed in ``frame`` (default ``world``, the kitchen frame: z up, origin under Velma)."""

    position: Vec3
    orientation: Quat = (1.0, 0.0, 0.0, 0.0)
    frame: str = "world"
