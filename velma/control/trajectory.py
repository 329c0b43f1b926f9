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

from velma.control.joints import Array


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
    # what every sample shares, computed once (the cycle's budget)
    _rotvec: Array = field(init=False, repr=False, compare=False)
    _omega: Array = field(init=False, repr=False, compare=False)
    _delta: Array = field(init=False, repr=False, compare=False)
    _p0: Array = field(init=False, repr=False, compare=False)
    _r0: Array = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # pin.SE3's .rotation and .translation copy on every read: read them once
        r0, p0 = self.start.rotation, self.start.translation
        axis, angle = axis_angle(r0.T @ self.goal.rotation)
        object.__setattr__(self, "_rotvec", axis * angle)  # the relative rotation, rad
        object.__setattr__(self, "_omega", r0 @ axis * angle)  # world ω per unit ds
        object.__setattr__(self, "_delta", self.goal.translation - p0)
        object.__setattr__(self, "_p0", p0)
        object.__setattr__(self, "_r0", r0)

    def sample(self, t: float) -> tuple[pin.SE3, Array]:
        """Pose and world twist (6,) = (v, ω) at time ``t`` (s)."""
        s, ds = min_jerk(t, self.duration)
        twist = np.empty(6)
        np.multiply(self._delta, ds, out=twist[:3])
        np.multiply(self._omega, ds, out=twist[3:])
        return pin.SE3(self._r0 @ pin.exp3(self._rotvec * s), self._p0 + s * self._delta), twist


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
    _arm: Array = field(init=False, repr=False, compare=False)
    _r0: Array = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        unit = self.axis / np.linalg.norm(self.axis)
        object.__setattr__(self, "_rotvec", unit * self.angle)  # the whole rotation, rad
        # read pin.SE3's copies once: the start's lever arm about the pivot and its rotation
        object.__setattr__(self, "_arm", self.start.translation - self.pivot)
        object.__setattr__(self, "_r0", self.start.rotation)

    def sample(self, t: float) -> tuple[pin.SE3, Array]:
        """Pose and world twist (6,) at time ``t`` (s)."""
        s, ds = min_jerk(t, self.duration)
        rot = pin.exp3(self._rotvec * s)
        lever = rot @ self._arm  # pos − pivot
        wx, wy, wz = (float(w) * ds for w in self._rotvec)
        lx, ly, lz = (float(x) for x in lever)
        # (ω × lever, ω)
        twist = np.array([wy * lz - wz * ly, wz * lx - wx * lz, wx * ly - wy * lx, wx, wy, wz])
        return pin.SE3(rot @ self._r0, self.pivot + lever), twist

    @property
    def goal(self) -> pin.SE3:
        """The pose at the end of the rotation."""
        return self.sample(self.duration)[0]


def rotation_error(a: Array, b: Array) -> float:
    """Angle (rad) of the rotation between rotation matrices ``a`` and ``b``."""
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, float(c))))
