"""Pinhole geometry of a depth image: intrinsics, rays, surface normals and incidence angles,
and back-projection to a coloured world-frame point cloud.

Frames: the optical frame is x right, y down (image rows), z forward along the optical axis
(the usual computer-vision convention); a pixel (row v, column u) has its centre at
(u + ½, v + ½) px. Depth is the z coordinate in that frame (m), as MuJoCo's depth rendering
gives it (distance along the optical axis, not along the ray).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Intrinsics:
    """A pinhole camera: focal lengths ``fx``, ``fy`` and principal point ``cx``, ``cy`` (px),
    image ``width`` × ``height`` (px)."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    @classmethod
    def from_fovy(cls, fovy_deg: float, width: int, height: int) -> Intrinsics:
        """Square pixels, principal point at the image centre, vertical field of view
        ``fovy_deg`` (degrees), as MuJoCo renders a camera. Raises ``ValueError`` for a size
        or field of view that makes no image."""
        if width <= 0 or height <= 0 or not 0.0 < fovy_deg < 180.0:
            raise ValueError(f"no pinhole for {width}×{height} px, fovy {fovy_deg}°")
        f = 0.5 * height / float(np.tan(np.radians(fovy_deg) / 2))
        return cls(fx=f, fy=f, cx=0.5 * width, cy=0.5 * height, width=width, height=height)

    @property
    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view (degrees)."""
        h = 2 * np.degrees(np.arctan(0.5 * self.width / self.fx))
        v = 2 * np.degrees(np.arctan(0.5 * self.height / self.fy))
        return float(h), float(v)

    def rays(self) -> Array:
        """Per pixel the ray direction scaled to unit depth, (x/z, y/z, 1): H × W × 3."""
        u = (np.arange(self.width) + 0.5 - self.cx) / self.fx
        v = (np.arange(self.height) + 0.5 - self.cy) / self.fy
        uu, vv = np.meshgrid(u, v)
        return np.stack([uu, vv, np.ones_like(uu)], axis=-1)


def camera_points(depth: npt.NDArray[np.floating], intrinsics: Intrinsics) -> Array:
    """The 3-D point of each pixel in the optical frame (H × W × 3, m; NaN where depth is NaN).
    Raises ``ValueError`` when ``depth`` is not H × W of ``intrinsics``."""
    if depth.shape != (intrinsics.height, intrinsics.width):
        raise ValueError(f"depth {depth.shape} is not {intrinsics.height}×{intrinsics.width}")
    out: Array = intrinsics.rays() * depth.astype(np.float64)[..., None]
    return out


def incidence_angles(depth: npt.NDArray[np.floating], intrinsics: Intrinsics) -> Array:
    """Angle (rad, H × W) between each pixel's ray and the surface normal estimated from the
    depth image (cross product of central differences along rows and columns). NaN on the
    image border and next to missing depth; near π/2 across depth discontinuities (a
    neighbour on another surface), so silhouettes count as grazing too."""
    p = camera_points(depth, intrinsics)
    du = np.full_like(p, np.nan)
    dv = np.full_like(p, np.nan)
    du[:, 1:-1] = p[:, 2:] - p[:, :-2]
    dv[1:-1, :] = p[2:, :] - p[:-2, :]
    n = np.cross(du, dv)
    ray = intrinsics.rays()
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.abs(np.sum(n * ray, axis=-1)) / (np.linalg.norm(n, axis=-1) * np.linalg.norm(ray, axis=-1))
        out: Array = np.arccos(np.clip(cos, 0.0, 1.0))
    return out


def world_cloud(
    depth: npt.NDArray[np.floating],
    rgb: npt.NDArray[np.uint8],
    intrinsics: Intrinsics,
    position: Array,
    rotation: Array,
) -> tuple[Array, npt.NDArray[np.uint8], npt.NDArray[np.int64]]:
    """Back-project the valid pixels of ``depth`` (H × W, m, NaN = missing) to world points.

    ``position`` (3,) m and ``rotation`` (3 × 3, world-from-optical: columns are the optical
    x, y, z axes in the world) are the camera's pose. Returns the points (N × 3, m, world),
    their colours from ``rgb`` (N × 3, uint8) and their flat pixel indices (N,, row-major)
    so that a caller can go back to the image. Raises ``ValueError`` on mismatched shapes."""
    if rgb.shape[:2] != depth.shape:
        raise ValueError(f"rgb {rgb.shape} and depth {depth.shape} differ")
    p = camera_points(depth, intrinsics).reshape(-1, 3)
    index = np.flatnonzero(np.isfinite(p[:, 2]))
    points: Array = p[index] @ np.asarray(rotation, dtype=np.float64).T + np.asarray(
        position, dtype=np.float64
    )
    colours: npt.NDArray[np.uint8] = rgb.reshape(-1, 3)[index]
    return points, colours, index.astype(np.int64)
