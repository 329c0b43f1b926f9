"""Offscreen rendering of the kitchen scene: ``python -m velma.render out.png [camera]``.

Renders with the off-screen GL platform velma/gl.py chooses (software EGL: ≈ 0.1 s per
640×480 frame on a 2-core VM). ``camera`` is one of the scene's cameras (``overview`` by default,
``pour_view``, ``head_camera``) or ``free`` for a default free camera.

``SceneCamera`` renders one camera again and again from whole simulation states (``qpos``)
with one reused renderer, for a viewer (services/viewer/camera.py).
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np
import numpy.typing as npt


def render(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    camera: str = "overview",
    width: int = 960,
    height: int = 720,
) -> npt.NDArray[np.uint8]:
    """An RGB image (height × width × 3, uint8) of ``data`` seen from ``camera``."""
    renderer = mujoco.Renderer(model, height=height, width=width)
    try:
        if camera == "free":
            cam: mujoco.MjvCamera | str = mujoco.MjvCamera()
            assert isinstance(cam, mujoco.MjvCamera)
            mujoco.mjv_defaultFreeCamera(model, cam)
            renderer.update_scene(data, camera=cam)
        else:
            renderer.update_scene(data, camera=camera)
        image: npt.NDArray[np.uint8] = renderer.render()
        return image
    finally:
        renderer.close()


class SceneCamera:
    """Renders the camera ``camera`` of ``model`` from whole simulation states, reusing one
    ``mujoco.Renderer`` (``width`` × ``height`` px) and an MjData of its own.

    Shadows, reflections and the skybox are off: in software EGL on the development VM a
    320×240 frame of the kitchen then takes ≈ 36 ms instead of ≈ 200 ms. The renderer is made
    at the first ``render`` and its GL context belongs to the thread that made it: call
    ``render`` and ``close`` from one thread. Raises ``KeyError`` for an unknown camera."""

    def __init__(
        self, model: mujoco.MjModel, camera: str = "head_camera", width: int = 320, height: int = 240
    ) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.camera_id = int(model.camera(camera).id)
        self.width = width
        self.height = height
        self.fovy = float(model.cam_fovy[self.camera_id])
        """Vertical field of view (degrees)."""
        self._renderer: mujoco.Renderer | None = None

    @property
    def focal_length(self) -> float:
        """Focal length (px) of the pinhole this camera is: (height / 2) / tan(fovy / 2)."""
        return 0.5 * self.height / float(np.tan(np.radians(self.fovy) / 2))

    def render(
        self, qpos: npt.NDArray[np.float64]
    ) -> tuple[npt.NDArray[np.uint8], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The image (height × width × 3, uint8 RGB) seen with the scene in ``qpos`` (shape
        ``(model.nq,)``), the camera's world position (3,) m and orientation (3 × 3, columns
        = the camera's x right, y up, z backwards: MuJoCo looks along −z). Raises
        ``ValueError`` for a ``qpos`` of another shape and whatever MuJoCo raises when no GL
        context can be made (e.g. no EGL)."""
        qpos = np.asarray(qpos, dtype=np.float64)
        if qpos.shape != (self.model.nq,):
            raise ValueError(f"qpos has shape {qpos.shape}, the model needs ({self.model.nq},)")
        m, d = self.model, self.data
        d.qpos[:] = qpos
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_camlight(m, d)
        if self._renderer is None:
            renderer = mujoco.Renderer(m, height=self.height, width=self.width)
            for flag in (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION):
                renderer.scene.flags[flag] = False
            renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SKYBOX] = False
            self._renderer = renderer
        self._renderer.update_scene(d, camera=self.camera_id)
        image: npt.NDArray[np.uint8] = self._renderer.render()
        i = self.camera_id
        return image, d.cam_xpos[i].copy(), d.cam_xmat[i].reshape(3, 3).copy()

    def close(self) -> None:
        """Free the renderer (idempotent; from the thread that rendered)."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def save_png(image: npt.NDArray[np.uint8], path: Path) -> None:
    """Write an RGB uint8 image as PNG (stdlib zlib; no imaging library needed)."""
    import struct
    import zlib

    h, w, _ = image.shape
    raw = b"".join(b"\x00" + image[r].tobytes() for r in range(h))

    def chunk(tag: bytes, payload: bytes) -> bytes:
        body = tag + payload
        return struct.pack(">I", len(payload)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    path.write_bytes(png)


def main(argv: list[str] | None = None) -> int:
    """Render the scene in its initial state to the given PNG path."""
    from velma.model.scene import initial_state, load_kitchen

    args = sys.argv[1:] if argv is None else argv
    if not args:
        print("usage: python -m velma.render out.png [camera]", file=sys.stderr)
        return 2
    model = load_kitchen()
    data = initial_state(model)
    save_png(render(model, data, args[1] if len(args) > 1 else "overview"), Path(args[0]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
