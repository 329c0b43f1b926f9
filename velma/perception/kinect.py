"""The head's depth camera: a first-generation Microsoft Kinect, simulated with MuJoCo.

The sensor (velma/model/README.md "Head Kinect"): 640 × 480 depth at 30 Hz, field of view
≈ 57° × 43°, range ≈ 0.5–4 m. It is the model's camera ``head_camera`` (velma/model/robot_mjcf.py
``HEAD_CAMERA_FOVY`` = 43°, the vertical field of view). MuJoCo renders square pixels, so at
4 : 3 the horizontal field of view is 2·atan(4/3 · tan 21.5°) = 55.4°, not 57°: the data
sheet's 57° × 43° pair is not one of square pixels at 4 : 3 (the Kinect's published depth
intrinsics, f ≈ 580 px at 640 × 480, give 58° × 45°), and the model keeps the vertical 43°.

``HeadKinect.capture`` renders RGB and metric depth (``mujoco.Renderer`` with
``enable_depth_rendering``: the distance along the optical axis) off-screen with
the GL platform velma/gl.py chooses, then applies velma/perception/noise.py. The camera pose is
``data.cam_xpos`` / ``data.cam_xmat`` of ``head_camera``: the robot's own head kinematics
(a real robot has it from its joint encoders), not a measurement of the scene.

Named simplifications: the colour and depth images share one pinhole (a real Kinect's colour
camera sits 2.5 cm beside the depth camera and is registered to it); MuJoCo writes depth for
transparent geoms, so the glass jar returns depth as if it were opaque (a real Kinect loses
much of it on clear glass); shadows, reflections and the skybox are off (as in
velma/render.py ``SceneCamera``), which costs nothing to depth and speeds up software EGL.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import numpy.typing as npt

from velma.perception import noise
from velma.perception.cloud import Array, Intrinsics, incidence_angles, world_cloud

KINECT_WIDTH = 640
KINECT_HEIGHT = 480
"""The Kinect v1 depth image (px)."""
OPTICAL_FROM_MUJOCO = np.diag([1.0, -1.0, -1.0])
"""MuJoCo's camera frame (x right, y up, looking along −z) to the optical frame (x right, y
down, z forward)."""


@dataclass(frozen=True)
class DepthFrame:
    """One capture of the head camera.

    ``rgb``: H × W × 3 uint8; ``depth``: H × W float32, m along the optical axis, NaN where the
    sensor returns nothing; ``intrinsics``: the pinhole (px); ``position`` (3,) m and
    ``rotation`` (3 × 3, world-from-optical, see velma/perception/cloud.py) the camera's world
    pose at capture; ``stamp``: simulation time (s)."""

    rgb: npt.NDArray[np.uint8]
    depth: npt.NDArray[np.float32]
    intrinsics: Intrinsics
    position: Array
    rotation: Array
    stamp: float

    def cloud(self) -> tuple[Array, npt.NDArray[np.uint8], npt.NDArray[np.int64]]:
        """The valid pixels as world points (N × 3, m), their colours (N × 3, uint8) and flat
        pixel indices (N,): velma/perception/cloud.py ``world_cloud``."""
        return world_cloud(self.depth, self.rgb, self.intrinsics, self.position, self.rotation)


class HeadKinect:
    """Renders ``camera`` (default ``head_camera``) of ``model`` as the Kinect sees it, at
    ``width`` × ``height`` px (default the sensor's 640 × 480; a smaller size keeps the field of
    view and costs less). One ``mujoco.Renderer`` is made at the first capture and reused; its
    GL context belongs to the thread that made it: capture and close from one thread. Raises
    ``KeyError`` for an unknown camera; ``ValueError`` if the size exceeds the model's
    off-screen buffer (``<visual><global offwidth offheight>``)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int = KINECT_WIDTH,
        height: int = KINECT_HEIGHT,
        camera: str = "head_camera",
    ) -> None:
        self.model = model
        self.camera_id = int(model.camera(camera).id)
        if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
            raise ValueError(f"{width}×{height} px exceeds the model's off-screen buffer")
        self.intrinsics = Intrinsics.from_fovy(float(model.cam_fovy[self.camera_id]), width, height)
        self._renderer: mujoco.Renderer | None = None

    def _render(self, data: mujoco.MjData) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float32]]:
        if self._renderer is None:
            r = self._make_renderer()
            for flag in (
                mujoco.mjtRndFlag.mjRND_SHADOW,
                mujoco.mjtRndFlag.mjRND_REFLECTION,
                mujoco.mjtRndFlag.mjRND_SKYBOX,
            ):
                r.scene.flags[flag] = False
            self._renderer = r
        r = self._renderer
        r.update_scene(data, camera=self.camera_id)
        rgb: npt.NDArray[np.uint8] = r.render().copy()
        r.enable_depth_rendering()
        try:
            depth = np.asarray(r.render(), dtype=np.float32).copy()
        finally:
            r.disable_depth_rendering()
        return rgb, depth

    def _make_renderer(self) -> mujoco.Renderer:
        """A renderer whose GL buffers are only as large as the frame: MuJoCo sizes the
        off-screen buffer by ``<visual><global offwidth offheight>`` (1280 × 960 in the kitchen,
        for the viewer) and the shadow map by ``<quality shadowsize>`` (2048², unused: shadows
        are off), whatever the renderer's size. Sized here (the model's values restored after),
        the same pixels cost ≈ 69 MiB less (docs/benchmarks.md)."""
        vis = self.model.vis
        kept = (vis.global_.offwidth, vis.global_.offheight, vis.quality.shadowsize)
        vis.global_.offwidth, vis.global_.offheight = self.intrinsics.width, self.intrinsics.height
        vis.quality.shadowsize = 0
        try:
            return mujoco.Renderer(self.model, height=self.intrinsics.height, width=self.intrinsics.width)
        finally:
            vis.global_.offwidth, vis.global_.offheight, vis.quality.shadowsize = kept

    def ideal(self, data: mujoco.MjData) -> DepthFrame:
        """The frame without sensor errors (depth as rendered, up to MuJoCo's far plane): for
        tests and for measuring what the noise does. ``data`` must have its kinematics computed
        (``mj_forward`` or ``mj_kinematics`` + ``mj_camlight``)."""
        rgb, depth = self._render(data)
        return self._frame(data, rgb, depth)

    def capture(self, data: mujoco.MjData, rng: np.random.Generator, frames: int = 1) -> DepthFrame:
        """The Kinect's frame of ``data`` (kinematics computed, see ``ideal``): rendered, then
        velma/perception/noise.py ``apply_noise`` with incidence angles from the ideal depth
        image's normals; draws from ``rng``. ``frames`` > 1: the per-pixel mean of that many
        noisy depth images of the same (static) scene, as a driver averaging consecutive
        frames at 30 Hz does (a pixel missing in any of them is missing). Raises
        ``ValueError`` for ``frames`` < 1."""
        if frames < 1:
            raise ValueError(f"frames must be ≥ 1, not {frames}")
        rgb, depth = self._render(data)
        incidence = incidence_angles(depth, self.intrinsics)
        noisy = noise.apply_noise(depth, incidence, rng)
        if frames > 1:
            total = noisy.astype(np.float64)
            for _ in range(frames - 1):
                total += noise.apply_noise(depth, incidence, rng)
            noisy = (total / frames).astype(np.float32)  # NaN (missing) anywhere stays NaN
        return self._frame(data, rgb, noisy)

    def _frame(
        self, data: mujoco.MjData, rgb: npt.NDArray[np.uint8], depth: npt.NDArray[np.float32]
    ) -> DepthFrame:
        i = self.camera_id
        rotation = data.cam_xmat[i].reshape(3, 3) @ OPTICAL_FROM_MUJOCO
        return DepthFrame(
            rgb=rgb,
            depth=depth,
            intrinsics=self.intrinsics,
            position=data.cam_xpos[i].copy(),
            rotation=rotation,
            stamp=float(data.time),
        )

    def close(self) -> None:
        """Free the renderer (idempotent; from the thread that captured)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def aim_head(model: mujoco.MjModel, data: mujoco.MjData, point: Array, iterations: int = 3) -> None:
    """Set the head's pan and tilt joints in ``data.qpos`` so that ``head_camera`` looks at
    ``point`` (3,) m, world, and recompute the kinematics (``mj_forward``): for tests and
    benchmarks that pose the robot directly (the executor aims the head with its LookAt
    primitive). A few fixed-point passes correct for the camera's offset from the joints.
    Raises ``KeyError`` if the model has no such joints or camera."""
    pan = model.joint("head_pan_joint")
    tilt = model.joint("head_tilt_joint")
    cam = model.camera("head_camera").id
    target = np.asarray(point, dtype=np.float64)
    mujoco.mj_forward(model, data)
    for _ in range(iterations):
        view = data.cam_xmat[cam].reshape(3, 3) @ OPTICAL_FROM_MUJOCO
        rel = view.T @ (target - data.cam_xpos[cam])  # in the optical frame
        data.qpos[pan.qposadr[0]] += math.atan2(-rel[0], rel[2])
        data.qpos[tilt.qposadr[0]] += math.atan2(rel[1], math.hypot(rel[0], rel[2]))
        mujoco.mj_forward(model, data)
