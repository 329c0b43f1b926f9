"""What a process may be given to report to a viewer, without importing it (an agent receives
tool hooks by injection and never imports a tool: tests/architecture/test_import_graph.py).

The runtime knows only these protocols. The implementation is a plug-in named by a string, as
the specification names each agent's implementation: ``ROCO_HOOKS`` (``module:attribute`` of
a :class:`Hooks`), by default :data:`DEFAULT_HOOKS` (Rerun, services/viewer/hooks.py) when
``ROCO_RERUN`` is ``1``; with neither, a process gets no hooks and imports nothing for them.
:class:`~services.runtime.agent.Agent` loads them once (``Engine.hooks``); the traffic recorder
calls :func:`load_hooks` itself.

Every method of a sink must return quickly and never raise: a viewer is never a reason to
lose traffic, to stop the robot or to stop coordinating.
"""

from __future__ import annotations

import importlib
import logging
from pathlib import Path
from typing import Any, Protocol

from shared.settings import Settings

DEFAULT_HOOKS = "services.viewer.hooks:HOOKS"
log = logging.getLogger(__name__)


class QueueSink(Protocol):
    """a_co's side: its command queue (an L_HC ``Status``), logged when it changed."""

    def queue(self, status: Any) -> None: ...
    def close(self) -> None: ...


class RobotSink(Protocol):
    """ag_ex's side: robot snapshots (``velma.executor.state.RobotSnapshot``), observations
    (L_SD ``Observation``) and the head camera, which reads the executor's whole simulation
    state from ``source``."""

    def start_camera(self, source: Any, *, seed: int = 0, pose_seed: int | None = None) -> None: ...
    def stop_camera(self, timeout: float = 10.0) -> None: ...
    def snapshot(self, snap: Any) -> None: ...
    def observation(self, obs: Any) -> None: ...
    def close(self) -> None: ...


class TrafficSink(Protocol):
    """The traffic recorder's side: one call per communicate written (its record, with the
    fields of ``services.recorder.record.TrafficRecord``, and its bytes); ``finish`` closes the
    recording when the recorder stops."""

    def communicate(self, record: Any, payload: bytes) -> None: ...
    def finish(self) -> Path | None: ...


class Hooks(Protocol):
    """A provider of sinks; each returns None when it has nothing to log to."""

    def traffic(self, process: str, run_dir: Path | None = None) -> TrafficSink | None: ...
    def robot(self, process: str) -> RobotSink | None: ...
    def queue(self, process: str) -> QueueSink | None: ...
    def camera_wanted(self) -> bool: ...


def hooks_name() -> str | None:
    """The ``module:attribute`` of the hooks this process is to load, or None (the
    environment read now)."""
    read = Settings.from_env(only=("hooks", "rerun"))
    if read.hooks is not None:
        return read.hooks
    return DEFAULT_HOOKS if read.rerun else None


def load_hooks() -> Hooks | None:
    """The hooks :func:`hooks_name` names, or None when none are named or they cannot be
    loaded (logged once: the process goes on without them)."""
    named = hooks_name()
    if named is None:
        return None
    module, _, attribute = named.partition(":")
    try:
        found: Hooks = getattr(importlib.import_module(module), attribute)
    except (ImportError, AttributeError) as exc:
        log.error(
            "%s=%s cannot be loaded (%s); going on without a viewer", Settings.env_name("hooks"), named, exc
        )
        return None
    return found
