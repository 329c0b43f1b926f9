"""Offscreen rendering of the kitchen scene: ``python -m velma.render out.png [camera]``.

Uses ``MUJOCO_GL=egl`` (software EGL works on these machines, ≈ 0.1 s per 640×480 frame,
platform-notes.md). ``camera`` is one of the scene's cameras (``overview`` by default,
``pour_view``, ``head_camera``) or ``free`` for a default free camera.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

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
