"""Types shared by several content languages: poses and object states in SI units."""

from __future__ import annotations

import math

import msgspec

Vec3 = tuple[float, float, float]
"""A point or vector in metres (or a unit axis), in the frame named alongside it."""

Quat = tuple[float, float, float, float]
"""A unit quaternion (w, x, y, z)."""

CLOCK = msgspec.Meta(extra={"clock": True})
"""Marks a field its sender reads from its clock (``Annotated[float, CLOCK]``): a duration or a
time left, in s, that differs from run to run with the machine's speed, not a fact of the task.
``roco replay`` (services/replay) does not compare such fields."""


class Pose(msgspec.Struct, frozen=True, array_like=True):
    """A rigid pose: ``position`` in metres, ``orientation`` as a unit quaternion (w, x, y, z),
    expressed in ``frame`` (default ``world``, the kitchen frame: z up, origin under Velma)."""

    position: Vec3
    orientation: Quat = (1.0, 0.0, 0.0, 0.0)
    frame: str = "world"

    def tilt(self) -> float:
        """Angle (rad, 0..π) between this pose's z axis and its frame's: how far an object
        leans from standing upright (the quaternion is normalised first). Raises ValueError
        for a zero quaternion."""
        w, x, y, z = self.orientation
        n = w * w + x * x + y * y + z * z
        if n == 0.0:
            raise ValueError("a zero quaternion has no orientation")
        return math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (x * x + y * y) / n)))
