"""The few calls the traffic recorder and ag_ex make to log to Rerun, guarded.

:func:`traffic_hook` and :func:`robot_hook` return None when logging is off
(``ROCO_RERUN`` is not ``1``), without importing rerun. A hook that raises logs the error
once and switches itself off: a viewer is never a reason to lose traffic or to stop the robot.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from services.viewer import ENV_ON

if TYPE_CHECKING:
    from services.recorder.record import TrafficRecord
    from services.viewer.recording import Recording
    from services.viewer.robot import RobotLogger
    from services.viewer.traffic import TrafficLogger
    from shared.fipa_codec.languages.l_sd import Observation
    from velma.executor.state import RobotSnapshot

log = logging.getLogger(__name__)
MERGE_WAIT = 8.0  # s the recorder waits for the other parts before merging (the launcher gives it 10)


def _on() -> bool:
    return os.environ.get(ENV_ON, "0") == "1"


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

    def communicate(self, record: TrafficRecord, payload: bytes) -> None:
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
    """ag_ex's side: robot snapshots and observations."""

    def __init__(self, recording: Recording, logger: RobotLogger) -> None:
        super().__init__(recording)
        self.logger = logger

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
