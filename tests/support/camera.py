"""A stand-in head camera and world state for ag_ex's camera feed (velma/executor/camera_feed.py):
no GL, renders counted."""

from __future__ import annotations

import threading
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from velma.executor.camera_feed import SIZE


class _State(NamedTuple):
    sim_time: float
    qpos: npt.NDArray[np.float64]


class StandInCamera:
    """Renders a 320 × 240 gradient whose first octet is the render's number (mod 256)."""

    fovy = 43.0
    width, height = SIZE

    def __init__(self) -> None:
        self.renders = 0
        self.closed = False

    def render(self, qpos: npt.NDArray[np.float64]) -> tuple[npt.NDArray[np.uint8], Any, Any]:
        self.renders += 1
        image = np.zeros((self.height, self.width, 3), dtype=np.uint8)
        image[..., 0] = np.arange(self.width, dtype=np.uint8)[None, :]
        image[0, 0, 0] = self.renders % 256
        return image, np.zeros(3), np.eye(3)

    def close(self) -> None:
        self.closed = True


class World:
    """A world state whose simulation time moves 0.05 s each time it is read."""

    def __init__(self) -> None:
        self.reads = 0
        self.times: list[float] = []
        """Every simulation time given (s)."""
        self._lock = threading.Lock()

    def __call__(self) -> _State:
        with self._lock:
            self.reads += 1
            self.times.append(0.05 * self.reads)
            return _State(self.times[-1], np.zeros(3))


class Made:
    def __init__(self) -> None:
        self.cameras: list[StandInCamera] = []

    def __call__(self) -> StandInCamera:
        self.cameras.append(StandInCamera())
        return self.cameras[-1]
