"""``roco ros2`` in the foreground: open a Zenoh session to the fleet's router as the identity
``ros2`` (with the fleet's credentials when it has access control), run the face
(services/ros2/face.py) until stopped. One line when ready, one line of counters when it stops;
its log is one line per event on stderr. The manual: docs/ros2.md.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from pathlib import Path

from services.ros2.face import ROS2, FaceConfig, Ros2Face, summary
from services.ros2.rmw import RmwError
from services.runtime.foreground import run_until_stopped
from services.runtime.session import refusal
from services.runtime.transport import ZenohTransport
from services.security.context import security_for
from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, load


class LiveError(Exception):
    """``roco ros2`` cannot start; the message is one line."""


@dataclass(frozen=True)
class LiveConfig:
    """The router ``endpoint``, the face's ``face`` options and the specification ``spec``."""

    endpoint: str
    face: FaceConfig
    spec: Path = DEFAULT_SPEC


def _spec(config: LiveConfig) -> SystemSpec:
    """The specification; LiveError when it does not load, or has no role for ROS 2 callers
    while the service is asked for."""
    try:
        spec = load(config.spec)
    except SpecError as exc:
        raise LiveError(str(exc)) from None
    if config.face.say and not any(e.platform == ROS2 for e in spec.externals):
        raise LiveError(f"{config.spec}: no external role of platform {ROS2}: no ROS 2 node may ask")
    return spec


def _transport(endpoint: str) -> ZenohTransport:
    """The face's session as ``ros2``; LiveError when there are no credentials for it or the
    router does not answer (or refuses them)."""
    try:
        return ZenohTransport([endpoint], wait_for_router=False, identity=ROS2)
    except ValueError as exc:  # CredentialError: no credentials for ros2 in the folder
        raise LiveError(str(exc)) from None
    except Exception:  # zenoh.ZError
        raise LiveError(refusal(endpoint, ROS2, security_for([endpoint]))) from None


def serve(config: LiveConfig, stop: threading.Event, ready: threading.Event | None = None) -> dict[str, int]:
    """Run the face until ``stop`` is set; set ``ready`` once it is declared. Returns its
    counters. Raises LiveError when the specification does not load, the router does not
    answer (or refuses the credentials of ``ros2``), or the domain or namespace is bad."""
    spec = _spec(config)
    transport = _transport(config.endpoint)
    try:
        face = Ros2Face(transport, spec, config.face)
        face.bind()
    except (RmwError, ValueError) as exc:
        transport.close()
        raise LiveError(str(exc)) from None
    face.start()
    f = config.face
    shown = ", ".join(sorted(f.topics)) or "no topics"
    print(
        f"roco ros2: node /roco on domain {f.domain}, namespace {f.namespace} ↔ {config.endpoint} "
        f"({shown}{'; service roco/say' if f.say else ''})",
        flush=True,
    )
    if ready is not None:
        ready.set()
    try:
        while not stop.wait(0.5):
            pass
    finally:
        face.stop()
        transport.close()
    return dict(face.counters)


def main(config: LiveConfig) -> int:
    """Run ``roco ros2`` until SIGINT or SIGTERM; 0 when it ran, 1 (one ``roco:`` line on
    stderr) when it could not start."""
    return run_until_stopped("ros2", lambda stop: serve(config, stop), (LiveError,), summary)
