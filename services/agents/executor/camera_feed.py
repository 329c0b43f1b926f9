"""ag_ex's head-camera images on Zenoh for ``roco ros2 --camera`` (docs/ros2.md): a publisher on
``roco/state/ag_ex/camera`` (services/runtime/keys.py ``camera_key``) whose matching status
(Zenoh: whether any subscriber matches its key) switches the feed (velma/executor/camera_feed.py)
on and off, so that ag_ex renders only while someone subscribes, at most ``ROCO_CAMERA_HZ``
frames per wall second. Source of the matching API: zenoh-python 1.x
``Publisher.matching_status`` and ``Publisher.declare_matching_listener``.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import zenoh

from services.runtime.agent import keys
from velma.executor.camera_feed import Camera, CameraFeed, State, kitchen_camera

log = logging.getLogger(__name__)


class CameraPublisher:
    """The feed of ``world()`` (the executor's latest whole simulation state) on ``session``,
    rendered by ``make_camera()`` (default: the loop's kitchen of ``seed``, ``pose_seed``) at most
    ``rate_hz`` a wall second while a subscriber matches. :meth:`close` ends it."""

    def __init__(
        self,
        session: zenoh.Session,
        world: Callable[[], State | None],
        rate_hz: float,
        *,
        seed: int = 0,
        pose_seed: int | None = None,
        make_camera: Callable[[], Camera] | None = None,
    ) -> None:
        self.key = keys.camera_key("ag_ex")
        self._pub = session.declare_publisher(self.key, congestion_control=zenoh.CongestionControl.DROP)
        make = make_camera or (lambda: kitchen_camera(seed, pose_seed))
        self.feed = CameraFeed(world, self._pub.put, make, rate_hz)
        self._listener: Any = self._pub.declare_matching_listener(self._changed)
        # zenoh-python 1.10 returns a MatchingStatus (its stub says bool)
        self.feed.want(bool(getattr(self._pub.matching_status, "matching", False)))

    def _changed(self, status: zenoh.MatchingStatus) -> None:  # Zenoh's thread
        log.info("camera feed %s", "on: a subscriber matches" if status.matching else "off: no subscriber")
        self.feed.want(bool(status.matching))

    def close(self) -> None:
        """Stop the feed (a frame in progress ends first), then undeclare."""
        self.feed.stop()
        self._listener.undeclare()
        self._pub.undeclare()
