"""Velma's head camera in the Rerun recording: a thread of ag_ex's communication side renders
the MJCF camera ``head_camera`` about once a second and logs the image.

Entity ``world/robot/head_camera`` (timelines ``wall`` and ``sim_time``, as in
services/viewer/robot.py):

- ``Pinhole`` (static): the MJCF camera's vertical field of view (43°), ``WIDTH`` × ``HEIGHT``
  px, camera axes RUB (MuJoCo's camera looks along −z with y up), so the image also appears
  as a frustum in the 3D view;
- per frame: ``Transform3D`` (the camera's world pose at the frame's simulation time) and
  the image as JPEG (``EncodedImage``, quality ``JPEG_QUALITY``, ≈ 8–10 kB).

Never on the control loop's path: the loop process only copies its ``qpos`` into shared
memory every ``WORLD_PERIOD`` cycles (velma/executor/loop_process.py, ``world_state=True``); this
thread, in the other process, reads the latest copy, puts it into an MjData of its own
(``velma.render.SceneCamera``: the same kitchen model, one reused renderer, closed when the
thread ends) and renders. The thread runs at the lowest CPU priority (nice ``NICE``, this
thread only) and software rendering stays in it (``LP_NUM_THREADS=0``: Mesa's llvmpipe
starts no rasteriser threads of its own), so that it only takes CPU time nobody else wants
(its cost: docs/viewer.md, "The head camera stays out of the control loop"). Frames are
skipped, never queued: a tick comes every ``PERIOD`` s, a tick that finds no new state is
skipped, and ticks missed while a render was slow are dropped. Rendering off-screen needs EGL
or OSMesa (velma/gl.py); when it cannot start, one warning is logged and the recording goes on
without images.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr

from services.viewer.robot import SIM, WALL

if TYPE_CHECKING:
    from services.viewer.recording import Recording
    from velma.executor.loop_wire import WorldState
    from velma.render import SceneCamera

ENTITY = "world/robot/head_camera"
CAMERA = "head_camera"  # the MJCF camera (velma/model/robot_mjcf.py)
PERIOD = 1.0  # s between frames (wall time)
WIDTH, HEIGHT = 320, 240  # px
JPEG_QUALITY = 80
IMAGE_PLANE = 0.3  # m: where the 3D view draws the image in front of the camera
NICE = 19  # the camera thread's nice value (lowest priority)

log = logging.getLogger(__name__)

WorldSource = Callable[[], "WorldState | None"]


class HeadCamera:
    """The camera thread (see module docstring): ``start`` it, ``stop`` it before the world
    state's source goes away.

    ``source()`` returns the latest whole simulation state or None (nothing yet); ``seed``
    and ``pose_seed`` select the same kitchen model as the loop's
    (``velma.model.scene.load_kitchen``). Counters for tests and measurements: ``frames``
    logged, ``skipped`` ticks (no new state, or dropped while a render was slow),
    ``render_s`` the last 100 render durations (s, model update + render + JPEG); ``failed``
    says why the thread stopped early (None while it runs or after a normal stop)."""

    def __init__(
        self,
        recording: Recording,
        source: WorldSource,
        *,
        seed: int = 0,
        pose_seed: int | None = None,
        period: float = PERIOD,
        width: int = WIDTH,
        height: int = HEIGHT,
    ) -> None:
        self.stream = recording.stream
        self.source = source
        self.seed = seed
        self.pose_seed = pose_seed
        self.period = period
        self.width = width
        self.height = height
        self.frames = 0
        self.skipped = 0
        self.render_s: deque[float] = deque(maxlen=100)
        self.failed: str | None = None
        self._finished = False
        self._stop = threading.Event()
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="head-camera", daemon=True)

    def start(self) -> None:
        """Start the thread (once)."""
        self._thread.start()

    def stop(self, timeout: float = 10.0) -> None:
        """Ask the thread to end and wait up to ``timeout`` s (a render in progress finishes
        first); the renderer is closed by the thread itself."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout)

    @property
    def running(self) -> bool:
        """True while the thread runs."""
        return self._thread.is_alive() and not self._finished

    def wait_frames(self, n: int, timeout: float) -> bool:
        """Block until ``n`` frames were logged (True), the thread ended or ``timeout`` s
        passed (False)."""
        with self._changed:
            self._changed.wait_for(lambda: self.frames >= n or self._finished, timeout)
            return self.frames >= n

    # ------------------------------------------------------------------ the thread
    def _open(self) -> SceneCamera:
        # this thread only (Linux: a thread id in setpriority); threads it starts inherit it
        try:
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), NICE)
        except (OSError, AttributeError):
            log.info("head camera: could not lower the thread's priority")
        os.environ.setdefault("LP_NUM_THREADS", "0")  # llvmpipe renders in this thread
        import velma.render
        from velma.model.scene import N_PARTICLES, load_kitchen

        model = load_kitchen(N_PARTICLES, self.seed, self.pose_seed)
        return velma.render.SceneCamera(model, CAMERA, self.width, self.height)

    def _run(self) -> None:
        camera: SceneCamera | None = None
        try:
            try:
                camera = self._open()
                camera.render(camera.model.qpos0)  # makes the GL context: fails here without EGL
            except Exception as exc:
                self.failed = f"{type(exc).__name__}: {exc}"
                log.warning(
                    "head camera off: cannot render off-screen (%s); the recording goes on without images",
                    self.failed,
                )
                return
            self.stream.log(
                ENTITY,
                rr.Pinhole(
                    focal_length=camera.focal_length,
                    width=self.width,
                    height=self.height,
                    camera_xyz=rr.ViewCoordinates.RUB,
                    image_plane_distance=IMAGE_PLANE,
                ),
                static=True,
            )
            self._frames(camera)
        except Exception as exc:
            self.failed = f"{type(exc).__name__}: {exc}"
            log.exception("head camera failed; switched off for this process")
        finally:
            if camera is not None:
                try:
                    camera.close()
                except Exception:
                    log.exception("head camera: closing the renderer failed")
            with self._changed:
                self._finished = True
                self._changed.notify_all()

    def _frames(self, camera: SceneCamera) -> None:
        last: float | None = None
        next_tick = time.monotonic()
        while not self._stop.wait(max(0.0, next_tick - time.monotonic())):
            state = self.source()
            if state is None or state.sim_time == last:
                self.skipped += 1
            else:
                last = state.sim_time
                self._frame(camera, state)
            next_tick += self.period
            now = time.monotonic()
            if next_tick <= now:  # the render was slow: drop the ticks it missed
                missed = int((now - next_tick) // self.period) + 1
                self.skipped += missed
                next_tick += missed * self.period

    def _frame(self, camera: SceneCamera, state: WorldState) -> None:
        t0 = time.perf_counter()
        image, position, rotation = camera.render(state.qpos)
        encoded = rr.Image(np.ascontiguousarray(image)).compress(jpeg_quality=JPEG_QUALITY)
        self.render_s.append(time.perf_counter() - t0)
        s = self.stream
        s.set_time(WALL, timestamp=time.time())
        s.set_time(SIM, duration=state.sim_time)
        s.log(ENTITY, rr.Transform3D(translation=position, mat3x3=rotation), encoded)
        with self._changed:
            self.frames += 1
            self._changed.notify_all()
