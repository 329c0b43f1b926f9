"""Whether what a hand holds passes clear of the objects standing in the kitchen while the
torso turns or the hand carries it (a_pl's check of a plan's torso turns and carries).

Every object is taken as an upright cylinder: its frame is its bottom centre (O_RoCo, L_WM
``GraspAffordance``), its radius half the larger horizontal extent of its bounding ``size``, its
height the vertical extent. A turn moves a held object on an arc about the torso axis (world z
through the origin); a carry on the straight line between its two poses (ag_ex's Cartesian
moves interpolate the grip frame linearly). Both are checked at samples no farther apart than
``STEP_M``. Simplifications: the hands and arms themselves, and a held object's tilt, are not
checked; only objects a_km knows a pose and a size of are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from shared.fipa_codec.languages.common import Vec3

GAP_M = 0.02
"""Horizontal gap (m) kept between a held object and a standing one."""
ABOVE_M = 0.03
"""Height (m) a held object's bottom keeps above a standing object's top when it passes over
it: under Cartesian impedance the held object lags and sags during a turn or a carry."""
STEP_M = 0.01
"""Largest distance (m) between two samples of a sweep."""


@dataclass(frozen=True)
class Body:
    """An upright cylinder: ``name``, bottom centre ``at`` (world, m), ``radius`` and
    ``height`` (m)."""

    name: str
    at: Vec3
    radius: float
    height: float

    @classmethod
    def of(cls, name: str, position: Vec3, size: Vec3) -> Body:
        """The cylinder of an object standing at ``position`` with bounding ``size`` (x, y, z
        extents, m)."""
        return cls(name, position, max(size[0], size[1]) / 2.0, size[2])

    def moved(self, at: Vec3) -> Body:
        """The same cylinder with its bottom centre at ``at`` (world, m)."""
        return Body(self.name, at, self.radius, self.height)


def _meets(held: Body, other: Body) -> bool:
    x, y, z = held.at
    ox, oy, oz = other.at
    if z >= oz + other.height + ABOVE_M or oz >= z + held.height:
        return False  # passes above it, or below
    return math.hypot(x - ox, y - oy) < held.radius + other.radius + GAP_M


def _first_met(path: list[Vec3], held: Body, standing: list[Body]) -> str | None:
    for at in path:
        for other in standing:
            if _meets(held.moved(at), other):
                return other.name
    return None


def turn_meets(held: Body, angle: float, standing: list[Body]) -> str | None:
    """The name of the first standing body ``held`` meets while the torso turns by ``angle``
    (rad, about world z through the origin), None when it passes clear of all."""
    x, y, z = held.at
    radius, start = math.hypot(x, y), math.atan2(y, x)
    n = max(1, math.ceil(abs(angle) * radius / STEP_M))
    path = [
        (radius * math.cos(start + angle * i / n), radius * math.sin(start + angle * i / n), z)
        for i in range(n + 1)
    ]
    return _first_met(path, held, standing)


def carry_meets(held: Body, to: Vec3, standing: list[Body]) -> str | None:
    """The name of the first standing body ``held`` meets on the straight line from where it
    is to ``to`` (its bottom centre, world, m), None when it passes clear of all."""
    a = held.at
    n = max(1, math.ceil(math.dist(a, to) / STEP_M))
    path = [
        (a[0] + (to[0] - a[0]) * i / n, a[1] + (to[1] - a[1]) * i / n, a[2] + (to[2] - a[2]) * i / n)
        for i in range(n + 1)
    ]
    return _first_met(path, held, standing)
