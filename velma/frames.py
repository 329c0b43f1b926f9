"""Poses, frames and rotations, stated once (issue 17): rigid-body helpers on the codec's
``Pose`` (position in m, orientation as a unit quaternion w, x, y, z, in a named frame) using
Pinocchio's SE3, and the quaternion ↔ rotation-matrix conversions the controller, the MJCF
generator (velma/model/generate.py) and the scripted experiment (velma/scenario.py) use.
Quaternions are (w, x, y, z), MuJoCo's order; rotation matrices (3, 3) act on column vectors."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from shared.fipa_codec.languages.common import Pose, Vec3


def to_se3(pose: Pose) -> pin.SE3:
    """SE3 of ``pose`` (quaternion w, x, y, z; metres)."""
    w, x, y, z = pose.orientation
    q = pin.Quaternion(w, x, y, z)
    q.normalize()
    return pin.SE3(q.matrix(), np.asarray(pose.position, dtype=float))


def from_se3(m: pin.SE3, frame: str = "world") -> Pose:
    """Pose of an SE3 (quaternion w, x, y, z with w ≥ 0)."""
    q = pin.Quaternion(m.rotation)
    q.normalize()
    wxyz = (float(q.w), float(q.x), float(q.y), float(q.z))
    if wxyz[0] < 0:
        wxyz = (-wxyz[0], -wxyz[1], -wxyz[2], -wxyz[3])
    p = m.translation
    return Pose(position=(float(p[0]), float(p[1]), float(p[2])), orientation=wxyz, frame=frame)


def translated(pose: Pose, offset: Vec3) -> Pose:
    """``pose`` moved by ``offset`` (world axes, m)."""
    x, y, z = pose.position
    return Pose(
        position=(x + offset[0], y + offset[1], z + offset[2]), orientation=pose.orientation, frame=pose.frame
    )


def compose(a: Pose, b: Pose) -> Pose:
    """a ∘ b: the pose ``b`` (given in a's frame) in a's parent frame."""
    return from_se3(to_se3(a) * to_se3(b), a.frame)


def inverse(a: Pose) -> Pose:
    return from_se3(to_se3(a).inverse(), a.frame)


def rotate(vector: Vec3, pose: Pose) -> Vec3:
    """``vector`` (in the pose's frame) expressed in the parent frame."""
    v = to_se3(pose).rotation @ np.asarray(vector, dtype=float)
    return (float(v[0]), float(v[1]), float(v[2]))


def upright(pose: Pose) -> Pose:
    """``pose`` with only its rotation about the world z axis kept (objects stand upright)."""
    r = to_se3(pose).rotation
    yaw = float(np.arctan2(r[1, 0], r[0, 0]))
    m = pin.SE3(pin.rpy.rpyToMatrix(0.0, 0.0, yaw), np.asarray(pose.position, dtype=float))
    return from_se3(m, pose.frame)


# ---- quaternions (w, x, y, z) and rotation matrices ------------------------------------------


def quat_wxyz(rot: npt.NDArray[np.float64]) -> tuple[float, float, float, float]:
    """Unit quaternion (w, x, y, z) of a rotation matrix (3, 3), with w ≥ 0 (Shepperd's method:
    the largest of w, x, y, z is computed from the diagonal, the others from it)."""
    r = rot
    tr = float(np.trace(r))
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = (0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s)
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]) * 2
        q = ((r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s)
    elif r[1, 1] > r[2, 2]:
        s = math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]) * 2
        q = ((r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s)
    else:
        s = math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]) * 2
        q = ((r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s)
    w, x, y, z = (float(v) for v in q)
    if w < 0:
        w, x, y, z = -w, -x, -y, -z
    return (w, x, y, z)


def rot_from_wxyz(q: tuple[float, float, float, float]) -> npt.NDArray[np.float64]:
    """Rotation matrix of a (w, x, y, z) quaternion (normalised first; Pinocchio's conversion).

    Raises ``ValueError`` for a zero quaternion."""
    arr = np.asarray(q, dtype=float)
    n = float(np.linalg.norm(arr))
    if n < 1e-9:
        raise ValueError("zero quaternion")
    w, x, y, z = arr / n
    out: npt.NDArray[np.float64] = pin.Quaternion(w, x, y, z).toRotationMatrix()
    return out


def rpy_to_quat(rpy: tuple[float, float, float]) -> tuple[float, float, float, float]:
    """URDF roll-pitch-yaw (fixed axes X, Y, Z; R = Rz·Ry·Rx) → MuJoCo quaternion (w, x, y, z)."""
    r, p, y = rpy
    cr, sr = math.cos(r / 2), math.sin(r / 2)
    cp, sp = math.cos(p / 2), math.sin(p / 2)
    cy, sy = math.cos(y / 2), math.sin(y / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def quat_mul(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    """Hamilton product of two (w, x, y, z) quaternions."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_matrix(q: tuple[float, ...]) -> npt.NDArray[np.float64]:
    """Rotation matrix (3, 3) of unit quaternion ``q`` (w, x, y, z), not normalised (the MJCF
    generator's exact arithmetic)."""
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_to_rot(q: tuple[float, ...]) -> npt.NDArray[np.float64]:
    """Rotation matrix (3, 3) of quaternion ``q`` (w, x, y, z), normalised first."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return quat_matrix((w, x, y, z))


def quat_rotate(q: tuple[float, ...], v: tuple[float, float, float]) -> tuple[float, float, float]:
    """Rotate vector ``v`` by unit quaternion ``q`` (w, x, y, z)."""
    out = quat_matrix(q) @ np.asarray(v, dtype=float)
    return (float(out[0]), float(out[1]), float(out[2]))
