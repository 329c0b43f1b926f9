"""ag_ex's camera feed: head-camera images for a live viewer (``roco ros2 --camera``,
services/agents/executor/camera_feed.py), rendered only while someone wants them.

One thread of the communication side, never the loop: as the watch (velma/executor/watch.py)
and Rerun's head camera (services/viewer/camera.py) do, it reads the latest whole simulation
state the loop copies into shared memory (``ExecutorProcess.world``) and renders the MJCF
camera ``head_camera`` with ``velma.render.SceneCamera`` (shadows, reflections and skybox off)
at :data:`SIZE`, at the lowest CPU priority (nice :data:`NICE`, llvmpipe in this thread). While
nobody wants frames (:meth:`CameraFeed.want`) it sleeps and renders nothing; while someone
does, at most ``rate_hz`` frames per wall second, a state already rendered is skipped, never
queued. The renderer is made at the first wanted frame and kept until :meth:`CameraFeed.stop`.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any, Protocol

import msgspec
import numpy as np
import numpy.typing as npt

log = logging.getLogger(__name__)

SIZE = (320, 240)
"""Frame (w, h px): a watch frame's (velma/executor/observer.py ``WATCH_SIZE``) and Rerun's head
camera's: a quarter of the Kinect's 640 × 480, so a quarter of the software renderer's work
(≈ 36 ms a frame on the development VM, velma/render.py) and 230,400 octets of rgb8."""
MAX_RATE_HZ = 30.0
"""The most frames per wall second a feed renders, whatever is asked (the Kinect's own rate)."""
MAX_FRAME_OCTETS = 640 * 480 * 3 + 4096
"""The largest :class:`CameraFrame` (msgpack) a reader decodes: a Kinect-sized rgb8 image and
its fields."""
NICE = 19
"""The feed thread's nice value (lowest priority, as Rerun's head camera)."""


class CameraFrame(msgspec.Struct, frozen=True, kw_only=True):
    """One head-camera image on ``roco/state/ag_ex/camera``: ``stamp`` (robot time, s, of the
    state rendered), ``width`` × ``height`` px, the pinhole ``fx``, ``fy``, ``cx``, ``cy`` (px,
    velma/perception/cloud.py ``Intrinsics.from_fovy`` of the MJCF camera's vertical field of
    view), ``encoding`` (ROS 2 sensor_msgs/Image's ``rgb8``) and ``data`` (rows top to bottom,
    ``3 · width`` octets each)."""

    stamp: float
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    encoding: str = "rgb8"
    data: bytes


class State(Protocol):
    """The world state read: ``sim_time`` (s) and MuJoCo's ``qpos`` (velma/executor/process.py
    ``WorldState``)."""

    @property
    def sim_time(self) -> float: ...

    @property
    def qpos(self) -> npt.NDArray[np.float64]: ...


class Camera(Protocol):
    """What renders (``velma.render.SceneCamera``): ``render(qpos)`` → (image H × W × 3 uint8,
    position, rotation); ``fovy`` (degrees), ``width``, ``height`` (px); ``close()``."""

    fovy: float
    width: int
    height: int

    def render(self, qpos: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.uint8], Any, Any]: ...

    def close(self) -> None: ...


def kitchen_camera(seed: int, pose_seed: int | None) -> Camera:
    """``SceneCamera`` of ``head_camera`` at :data:`SIZE` in the loop's kitchen (velma/model/
    scene.py ``load_kitchen`` with the loop's seeds). Takes ≈ 0.7 s (the kitchen's model)."""
    import velma.render
    from velma.model.scene import N_PARTICLES, load_kitchen

    model = load_kitchen(N_PARTICLES, seed, pose_seed)
    return velma.render.SceneCamera(model, "head_camera", *SIZE)


class CameraFeed:
    """The feed's thread (module docstring): frames of the states ``world()`` gives (None: none
    yet) rendered by ``make_camera()`` (in the thread), each put (msgpack :class:`CameraFrame`)
    with ``put``, at most ``rate_hz`` a wall second while :meth:`want` was last told True.
    Raises ``ValueError`` for a rate that is not > 0. Counters: ``frames`` put, ``skipped``
    (no new state), ``render_s`` (the last 100 renders, s); ``failed`` says why it stopped
    early (the camera could not be made, e.g. no off-screen GL)."""

    def __init__(
        self,
        world: Callable[[], State | None],
        put: Callable[[bytes], None],
        make_camera: Callable[[], Camera],
        rate_hz: float,
    ) -> None:
        if not 0.0 < rate_hz < float("inf"):
            raise ValueError(f"a camera rate is > 0 Hz, not {rate_hz}")
        self.period_s = 1.0 / min(rate_hz, MAX_RATE_HZ)
        self._world = world
        self._put = put
        self._make_camera = make_camera
        self._encode = msgspec.msgpack.Encoder().encode
        self._cond = threading.Condition()
        self._wanted = False
        self._stopping = False
        self.frames = 0
        self.skipped = 0
        self.render_s: deque[float] = deque(maxlen=100)
        self.failed: str | None = None
        self.idle = threading.Event()
        """Set while the thread waits for someone to want frames (it renders nothing then)."""
        self._thread = threading.Thread(target=self._run, name="camera-feed", daemon=True)
        self._thread.start()

    def want(self, wanted: bool) -> None:
        """Someone wants frames (True) or nobody does any more (False); any thread."""
        with self._cond:
            self._wanted = wanted
            self._cond.notify_all()

    def stop(self, timeout: float = 10.0) -> None:
        """End the thread (a render in progress finishes first) and wait up to ``timeout`` s;
        the camera is closed by the thread."""
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def _run(self) -> None:
        camera: Camera | None = None
        last: float | None = None
        try:
            while self._wait_wanted():
                t0 = time.monotonic()
                camera = camera or self._open()
                if camera is None:
                    return
                last = self._tick(camera, last)
                self._rest(t0)
        except Exception as exc:
            self.failed = f"{type(exc).__name__}: {exc}"
            log.exception("the camera feed failed; no frames from now on")
        finally:
            if camera is not None:
                camera.close()

    def _wait_wanted(self) -> bool:
        """Wait (:attr:`idle`) until frames are wanted (True) or the feed stops (False)."""
        with self._cond:
            if not (self._wanted or self._stopping):
                self.idle.set()
                self._cond.wait_for(lambda: self._wanted or self._stopping)
            self.idle.clear()
            return not self._stopping

    def _tick(self, camera: Camera, last: float | None) -> float | None:
        """Render and put the latest state unless it is ``last`` (then skipped); its time."""
        state = self._world()
        if state is None or state.sim_time == last:
            self.skipped += 1
            return last
        self._frame(camera, state)
        return state.sim_time

    def _rest(self, t0: float) -> None:
        """Wait until one period after ``t0`` (monotonic s), or until the feed stops."""
        with self._cond:
            rest = t0 + self.period_s - time.monotonic()
            if rest > 0:
                self._cond.wait_for(lambda: self._stopping, rest)

    def _open(self) -> Camera | None:
        try:  # this thread only (Linux: a thread id); software GL renders in it
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), NICE)
        except (OSError, AttributeError):
            log.info("camera feed: could not lower the thread's priority")
        os.environ.setdefault("LP_NUM_THREADS", "0")
        try:
            return self._make_camera()
        except Exception as exc:
            self.failed = f"{type(exc).__name__}: {exc}"
            log.warning("camera feed off: the head camera cannot render (%s)", self.failed)
            return None

    def _frame(self, camera: Camera, state: State) -> None:
        from velma.perception.cloud import Intrinsics

        t0 = time.perf_counter()
        image, _, _ = camera.render(state.qpos)
        k = Intrinsics.from_fovy(camera.fovy, camera.width, camera.height)
        frame = CameraFrame(
            stamp=state.sim_time,
            width=camera.width,
            height=camera.height,
            fx=k.fx,
            fy=k.fy,
            cx=k.cx,
            cy=k.cy,
            data=np.ascontiguousarray(image, dtype=np.uint8).tobytes(),
        )
        self.render_s.append(time.perf_counter() - t0)
        self._put(self._encode(frame))
        self.frames += 1
