"""Setpoint generators: minimum-jerk time scaling, straight-line + slerp pose paths, and
rotations of a pose about a fixed axis (pouring).

Poses are ``pinocchio.SE3`` (metres, rotation matrices); twists are (linear m/s, angular
rad/s) in the world frame. Source: Flash & Hogan (1985) minimum-jerk profile.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from velma.control.robot_model import Array


def min_jerk(t: float, duration: float) -> tuple[float, float]:
    """Phase ``s`` ∈ [0, 1] and its rate ``ds/dt`` (1/s) of the minimum-jerk profile at time
    ``t`` (s) of a motion lasting ``duration`` (s); (1, 0) for ``duration`` ≤ 0 or t ≥ end."""
    if duration <= 0.0 or t >= duration:
        return 1.0, 0.0
    if t <= 0.0:
        return 0.0, 0.0
    x = t / duration
    s = x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
    ds = 30.0 * x * x * (1.0 - x) ** 2 / duration
    return s, ds


MIN_JERK_PEAK_RATE = 1.875
"""max ds/dt × duration of the minimum-jerk profile (peak velocity = 1.875 Δ / T)."""


def axis_angle(rot: Array) -> tuple[Array, float]:
    """Unit axis (3,) and angle (rad, in [0, π]) of a rotation matrix; axis x for angle 0."""
    w = pin.log3(rot)
    angle = float(np.linalg.norm(w))
    if angle < 1e-12:
        return np.array([1.0, 0.0, 0.0]), 0.0
    return w / angle, angle


@dataclass(frozen=True)
class PosePath:
    """Straight line from ``start`` to ``goal`` (positions) and a slerp of orientations,
    timed by a minimum-jerk profile of ``duration`` seconds."""

    start: pin.SE3
    goal: pin.SE3
    duration: float
    # what every sample shares, computed once (issue 18: the cycle's budget)
    _rotvec: Array = field(init=False, repr=False, compare=False)
    _omega: Array = field(init=False, repr=False, compare=False)
    _delta: Array = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        axis, angle = axis_angle(self.start.rotation.T @ self.goal.rotation)
        object.__setattr__(self, "_rotvec", axis * angle)  # the relative rotation, rad
        object.__setattr__(self, "_omega", self.start.rotation @ axis * angle)  # world ω per unit ds
        object.__setattr__(self, "_delta", self.goal.translation - self.start.translation)

    def sample(self, t: float) -> tuple[pin.SE3, Array]:
        """Pose and world twist (6,) = (v, ω) at time ``t`` (s)."""
        s, ds = min_jerk(t, self.duration)
        rot = self.start.rotation @ pin.exp3(self._rotvec * s)
        delta = self._delta
        pos = self.start.translation + s * delta
        omega = self._omega * ds
        return pin.SE3(rot, pos), np.concatenate([delta * ds, omega])


@dataclass(frozen=True)
class RotationPath:
    """Rotation of ``start`` by ``angle`` rad about the world ``axis`` through ``pivot``
    (world, m), timed by a minimum-jerk profile of ``duration`` seconds (the pour)."""

    start: pin.SE3
    pivot: Array
    axis: Array
    angle: float
    duration: float
    _rotvec: Array = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        unit = self.axis / np.linalg.norm(self.axis)
        object.__setattr__(self, "_rotvec", unit * self.angle)  # the whole rotation, rad

    def sample(self, t: float) -> tuple[pin.SE3, Array]:
        """Pose and world twist (6,) at time ``t`` (s)."""
        s, ds = min_jerk(t, self.duration)
        rot = pin.exp3(self._rotvec * s)
        pos = self.pivot + rot @ (self.start.translation - self.pivot)
        omega = self._rotvec * ds
        vel = np.cross(omega, pos - self.pivot)
        return pin.SE3(rot @ self.start.rotation, pos), np.concatenate([vel, omega])

    @property
    def goal(self) -> pin.SE3:
        """The pose at the end of the rotation."""
        return self.sample(self.duration)[0]


def rotation_error(a: Array, b: Array) -> float:
    """Angle (rad) of the rotation between rotation matrices ``a`` and ``b``."""
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, float(c))))
