"""Poses and frames, stated once (issue 17): rigid-body helpers on the codec's ``Pose``
(position in m, orientation as a unit quaternion w, x, y, z, in a named frame) using
Pinocchio's SE3, and the quaternion → rotation matrix conversion the controller uses. The
numpy-only quaternion helpers are in velma/rotations.py."""

from __future__ import annotations

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
