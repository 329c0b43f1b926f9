"""The few calls the traffic recorder, ag_ex and a_co make to log to Rerun, guarded. They reach
them through the runtime's hooks (services/runtime/hooks.py: :data:`HOOKS` is named by string,
never imported by them).

:func:`traffic_hook`, :func:`robot_hook` and :func:`queue_hook` return None when logging is
off (``ROCO_RERUN`` is not ``1``), without importing rerun. A hook that raises logs the error
once and switches itself off: a viewer is never a reason to lose traffic, to stop the robot
or to stop coordinating. ag_ex's head camera (services/viewer/camera.py) runs in a thread of
its own; ``ROCO_RERUN_CAMERA=0`` leaves it off.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from shared.settings import Settings

if TYPE_CHECKING:
    from services.runtime.hooks import Hooks
    from services.viewer.camera import HeadCamera, WorldSource
    from services.viewer.recording import Recording
    from services.viewer.robot import RobotLogger
    from services.viewer.tasks import QueueLogger
    from services.viewer.traffic import TrafficLogger, TrafficRow
    from shared.fipa_codec.languages.l_hc import Status
    from shared.fipa_codec.languages.l_sd import Observation
    from velma.executor.state import RobotSnapshot

log = logging.getLogger(__name__)
MERGE_WAIT = 8.0  # s the recorder waits for the other parts before merging (the launcher gives it 10)


def _on() -> bool:
    return Settings.from_env(only=("rerun",)).rerun


def camera_wanted() -> bool:
    """Whether ag_ex should render its head camera: Rerun logging on and
    ``ROCO_RERUN_CAMERA`` not ``0`` (read now)."""
    read = Settings.from_env(only=("rerun", "rerun_camera"))
    return read.rerun and read.rerun_camera


class _Hook:
    def __init__(self, recording: Recording) -> None:
        self.recording = recording
        self.failed = False

    def _fail(self, what: str) -> None:
        log.exception("Rerun logging (%s) failed; switched off for this process", what)
        self.failed = True

    def close(self) -> None:
        """Close this process's part of the recording."""
        try:
            self.recording.close()
        except Exception:
            self._fail("close")


class TrafficHook(_Hook):
    """The recorder's side: communicates, the layout, and merging the parts at the end."""

    def __init__(self, recording: Recording, logger: TrafficLogger) -> None:
        super().__init__(recording)
        self.logger = logger

    def communicate(self, record: TrafficRow, payload: bytes) -> None:
        """Log one communicate (see services/viewer/traffic.py)."""
        if self.failed:
            return
        try:
            self.logger.communicate(record, payload)
        except Exception:
            self._fail("communicate")

    def finish(self, wait: float = MERGE_WAIT) -> Path | None:
        """Close the recorder's part and merge all parts into ``<run>/recording.rrd``."""
        from services.viewer.recording import merge_parts

        self.close()
        try:
            return merge_parts(self.recording.run_dir, wait=wait)
        except Exception:
            self._fail("merge")
            return None


class RobotHook(_Hook):
    """ag_ex's side: robot snapshots (with the loop's timing), observations and the head
    camera."""

    def __init__(self, recording: Recording, logger: RobotLogger) -> None:
        super().__init__(recording)
        self.logger = logger
        self.camera: HeadCamera | None = None

    def start_camera(self, source: WorldSource, *, seed: int = 0, pose_seed: int | None = None) -> None:
        """Start the head camera's thread (services/viewer/camera.py) on ``source``, the
        executor's latest whole simulation state; ``seed`` and ``pose_seed`` are the
        executor's scene. Does nothing when the hook failed or the camera already runs."""
        if self.failed or self.camera is not None:
            return
        try:
            from services.viewer.camera import HeadCamera

            self.camera = HeadCamera(self.recording, source, seed=seed, pose_seed=pose_seed)
            self.camera.start()
        except Exception:
            log.exception("head camera could not start; going on without it")
            self.camera = None

    def stop_camera(self, timeout: float = 10.0) -> None:
        """Stop the head camera's thread and wait for it (call before the executor's
        world state goes away); idempotent."""
        if self.camera is not None:
            self.camera.stop(timeout)

    def close(self) -> None:
        """Stop the camera, then close ag_ex's part of the recording."""
        self.stop_camera()
        super().close()

    def snapshot(self, snap: RobotSnapshot) -> None:
        """Log one robot state (see services/viewer/robot.py)."""
        if self.failed:
            return
        try:
            self.logger.snapshot(snap)
        except Exception:
            self._fail("snapshot")

    def observation(self, obs: Observation) -> None:
        """Log one observation of the scene."""
        if self.failed:
            return
        try:
            self.logger.observation(obs)
        except Exception:
            self._fail("observation")


class QueueHook(_Hook):
    """a_co's side: its command queue (services/viewer/tasks.py)."""

    def __init__(self, recording: Recording, logger: QueueLogger) -> None:
        super().__init__(recording)
        self.logger = logger

    def queue(self, status: Status) -> None:
        """Log a_co's queue (its ``Status``) if it changed since the last call."""
        if self.failed:
            return
        try:
            self.logger.queue(status)
        except Exception:
            self._fail("queue")


H = TypeVar("H")


def _start(process: str, run_dir: Path | None, make: Callable[[Recording], H]) -> H | None:
    """Start ``process``'s recording and wrap it with ``make``; None when logging is off or
    cannot start (logged; the process goes on without it)."""
    if not _on():
        return None
    try:
        from services.viewer.recording import start

        recording = start(process, run_dir=run_dir)
        return make(recording) if recording is not None else None
    except Exception:
        log.exception("Rerun logging for %s could not start; going on without it", process)
        return None


def traffic_hook(process: str = "recorder", run_dir: Path | None = None) -> TrafficHook | None:
    """The recorder's Rerun logging, or None when off or when it cannot start."""

    def make(recording: Recording) -> TrafficHook:
        from services.viewer import blueprint
        from services.viewer.traffic import TrafficLogger

        blueprint.send(recording.stream)
        return TrafficHook(recording, TrafficLogger(recording))

    return _start(process, run_dir, make)


def robot_hook(process: str = "ag_ex", run_dir: Path | None = None) -> RobotHook | None:
    """ag_ex's Rerun logging, or None when off or when it cannot start."""

    def make(recording: Recording) -> RobotHook:
        from services.viewer.robot import RobotLogger

        logger = RobotLogger(recording)
        logger.initial_objects()
        return RobotHook(recording, logger)

    return _start(process, run_dir, make)


def queue_hook(process: str = "a_co", run_dir: Path | None = None) -> QueueHook | None:
    """a_co's Rerun logging, or None when off or when it cannot start."""

    def make(recording: Recording) -> QueueHook:
        from services.viewer.tasks import QueueLogger

        return QueueHook(recording, QueueLogger(recording))

    return _start(process, run_dir, make)


class RerunHooks:
    """The Rerun hooks as the runtime's :class:`~services.runtime.hooks.Hooks` (named by
    ``services.runtime.hooks.DEFAULT_HOOKS``): each sink None unless ``ROCO_RERUN=1``."""

    def traffic(self, process: str, run_dir: Path | None = None) -> TrafficHook | None:
        return traffic_hook(process, run_dir)

    def robot(self, process: str) -> RobotHook | None:
        return robot_hook(process)

    def queue(self, process: str) -> QueueHook | None:
        return queue_hook(process)

    def camera_wanted(self) -> bool:
        return camera_wanted()


HOOKS: Hooks = RerunHooks()
"""Named by ``services.runtime.hooks.DEFAULT_HOOKS``; typed so that mypy checks it is one."""
