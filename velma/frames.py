"""Poses and frames, stated once: rigid-body helpers on the codec's ``Pose``
(position in m, orientation as a unit quaternion w, x, y, z, in a named frame), and the
quaternion → rotation matrix conversion the controller uses.

Pure Python (``math`` only), so that a process that only reasons about poses (a_pl) loads
neither Pinocchio nor numpy (lean processes). The arithmetic is Eigen's, as
Pinocchio's ``SE3`` and ``Quaternion`` did it before: a quaternion is normalised, turned into a
rotation matrix (``Quaternion::toRotationMatrix``), matrices are multiplied, and a matrix is
turned back into a quaternion by Shepperd's method (``Quaternion(Matrix3)``), normalised, with
w ≥ 0. The numpy-only quaternion helpers are in velma/rotations.py."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from shared.fipa_codec.languages.common import Pose, Quat, Vec3

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

Matrix = tuple[Vec3, Vec3, Vec3]
"""A rotation matrix (3, 3) as rows, acting on column vectors."""


def _normalised(q: Quat) -> Quat:
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n)


def matrix_of(q: Quat) -> Matrix:
    """Rotation matrix of the unit quaternion ``q`` (w, x, y, z; not normalised here)."""
    w, x, y, z = q
    tx, ty, tz = 2 * x, 2 * y, 2 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    return (
        (1 - (tyy + tzz), txy - twz, txz + twy),
        (txy + twz, 1 - (txx + tzz), tyz - twx),
        (txz - twy, tyz + twx, 1 - (txx + tyy)),
    )


def quat_of(m: Matrix) -> Quat:
    """Unit quaternion (w, x, y, z) of rotation matrix ``m``, with w ≥ 0 (Shepperd's method as
    Eigen implements it, then normalised)."""
    trace = m[0][0] + m[1][1] + m[2][2]
    if trace > 0:
        t = math.sqrt(trace + 1.0)
        w = 0.5 * t
        t = 0.5 / t
        q = [w, (m[2][1] - m[1][2]) * t, (m[0][2] - m[2][0]) * t, (m[1][0] - m[0][1]) * t]
    else:
        i = 0
        if m[1][1] > m[0][0]:
            i = 1
        if m[2][2] > m[i][i]:
            i = 2
        j, k = (i + 1) % 3, (i + 2) % 3
        t = math.sqrt(m[i][i] - m[j][j] - m[k][k] + 1.0)
        q = [0.0, 0.0, 0.0, 0.0]
        q[1 + i] = 0.5 * t
        t = 0.5 / t
        q[0] = (m[k][j] - m[j][k]) * t
        q[1 + j] = (m[j][i] + m[i][j]) * t
        q[1 + k] = (m[k][i] + m[i][k]) * t
    w, x, y, z = _normalised((q[0], q[1], q[2], q[3]))
    if w < 0:
        return (-w, -x, -y, -z)
    return (w, x, y, z)


def _mul(a: Matrix, b: Matrix) -> Matrix:
    return (
        (
            a[0][0] * b[0][0] + a[0][1] * b[1][0] + a[0][2] * b[2][0],
            a[0][0] * b[0][1] + a[0][1] * b[1][1] + a[0][2] * b[2][1],
            a[0][0] * b[0][2] + a[0][1] * b[1][2] + a[0][2] * b[2][2],
        ),
        (
            a[1][0] * b[0][0] + a[1][1] * b[1][0] + a[1][2] * b[2][0],
            a[1][0] * b[0][1] + a[1][1] * b[1][1] + a[1][2] * b[2][1],
            a[1][0] * b[0][2] + a[1][1] * b[1][2] + a[1][2] * b[2][2],
        ),
        (
            a[2][0] * b[0][0] + a[2][1] * b[1][0] + a[2][2] * b[2][0],
            a[2][0] * b[0][1] + a[2][1] * b[1][1] + a[2][2] * b[2][1],
            a[2][0] * b[0][2] + a[2][1] * b[1][2] + a[2][2] * b[2][2],
        ),
    )


def _apply(m: Matrix, v: Vec3) -> Vec3:
    return (
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    )


def _transposed(m: Matrix) -> Matrix:
    return ((m[0][0], m[1][0], m[2][0]), (m[0][1], m[1][1], m[2][1]), (m[0][2], m[1][2], m[2][2]))


def rotation(pose: Pose) -> Matrix:
    """The rotation matrix of ``pose``'s orientation (normalised first)."""
    return matrix_of(_normalised(pose.orientation))


def about_z(angle: float, frame: str = "world") -> Pose:
    """The pose at the origin turned by ``angle`` (rad) about z."""
    c, s = math.cos(angle), math.sin(angle)
    turn = ((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0))
    return Pose(position=(0.0, 0.0, 0.0), orientation=quat_of(turn), frame=frame)


def translated(pose: Pose, offset: Vec3) -> Pose:
    """``pose`` moved by ``offset`` (world axes, m)."""
    x, y, z = pose.position
    return Pose(
        position=(x + offset[0], y + offset[1], z + offset[2]), orientation=pose.orientation, frame=pose.frame
    )


def compose(a: Pose, b: Pose) -> Pose:
    """a ∘ b: the pose ``b`` (given in a's frame) in a's parent frame."""
    ra = rotation(a)
    p = _apply(ra, b.position)
    position = (p[0] + a.position[0], p[1] + a.position[1], p[2] + a.position[2])
    return Pose(position=position, orientation=quat_of(_mul(ra, rotation(b))), frame=a.frame)


def inverse(a: Pose) -> Pose:
    """The pose of ``a``'s parent frame in ``a``."""
    rt = _transposed(rotation(a))
    p = _apply(rt, a.position)
    return Pose(position=(-p[0], -p[1], -p[2]), orientation=quat_of(rt), frame=a.frame)


def rotate(vector: Vec3, pose: Pose) -> Vec3:
    """``vector`` (in the pose's frame) expressed in the parent frame."""
    return _apply(rotation(pose), vector)


def upright(pose: Pose) -> Pose:
    """``pose`` with only its rotation about the world z axis kept (objects stand upright)."""
    r = rotation(pose)
    yaw = math.atan2(r[1][0], r[0][0])
    x, y, z = pose.position
    return Pose(
        position=(float(x), float(y), float(z)), orientation=about_z(yaw).orientation, frame=pose.frame
    )


def rot_from_wxyz(q: tuple[float, float, float, float]) -> npt.NDArray[np.float64]:
    """Rotation matrix (numpy, 3 × 3) of a (w, x, y, z) quaternion, normalised first (the
    controller's conversion; numpy is imported here, by the processes that compute with it).

    Raises ``ValueError`` for a zero quaternion."""
    import numpy as np

    w, x, y, z = (float(v) for v in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if n < 1e-9:
        raise ValueError("zero quaternion")
    return np.array(matrix_of((w / n, x / n, y / n, z / n)), dtype=float)
