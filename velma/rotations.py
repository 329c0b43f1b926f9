"""Quaternions (w, x, y, z; MuJoCo's order) and rotation matrices (3, 3, acting on column
vectors), in numpy alone: what the MJCF writers (velma/model/robot_mjcf.py, kitchen_mjcf.py), the scripted
experiment (velma/scenario.py) and the robot-state snapshot (velma/executor/state.py, built on
the communication side, which loads neither Pinocchio nor MuJoCo) share. Pose ↔ SE3 helpers
are in velma/frames.py (Pinocchio)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt


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
